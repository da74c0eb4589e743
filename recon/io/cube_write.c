/* cube_write.c - the streaming FITS cube writer; see cube.h.
 *
 * Crash safety: the cube is created with NAXIS3 = 0 and every append first
 * sets NAXIS3 = n+1 and has cfitsio re-derive the HDU's size
 * (fits_set_hdustruc), then writes frame n; as the cube is the last HDU
 * the data simply run on past the old end of file.  fits_resize_img would
 * do the same but first writes the new frame as zeros: twice the bytes
 * (measured with strace: 2.0x vs 1.0x the frame size per append).
 * fits_flush_file closes out the HDU (header, fill to a 2880-byte block)
 * and pushes cfitsio's buffers to the OS, so the file left by a crash
 * after a flush is a valid cube of the frames appended.  Nothing here calls
 * fsync: surviving a power cut as well as a process crash is the caller's
 * choice (and cost).
 *
 * Checksums: CHECKSUM and DATASUM are made with the header (so the header
 * never grows for them later) and brought up to date ("sealed") before
 * every flush, before an extension and at close.  The cube's DATASUM is
 * summed frame by frame as frames are appended (datasum.h), so sealing
 * costs a sum over the header only (fits_update_chksum); fits_write_chksum
 * would read the whole data unit back at every flush.  Measured, CPU time
 * for 1000 frames of 256^2 flushed after each frame: 16-bit 0.43 s (0.36 s
 * without checksums; 27 s with fits_write_chksum at each flush), float
 * 0.20 s (0.15 s; 59 s).  Image extensions are small and written at once:
 * fits_write_chksum sums them.
 */
#include "cube.h"
#include "cube_header.h"
#include "datasum.h"

#include <errno.h>
#include <fitsio.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---- the writer ------------------------------------------------------- */

struct cube_writer {
    fitsfile *fp;      /* NULL once closed */
    char *path;
    int width, height;
    int bitpix;        /* as given: 8, 16, 32, -32, -64, U16, U32 */
    int naxis;         /* 3 (streaming) or 2 (a one-frame cube_write) */
    int nframes;
    int has_ext;       /* an image extension follows the cube: frozen */
    int failed;        /* SL_EIO once a cfitsio call failed: sticky */
    float *rounded;    /* integer bitpix: one frame rounded (cfitsio would
                        * truncate); allocated once at open */
    unsigned char *stored; /* one frame as the file stores it, for sum */
    datasum sum;       /* the cube's DATASUM over the frames appended */
    int sealed;        /* the current HDU's CHECKSUM, DATASUM are right */
    sl_err err;
};

/* Record a cfitsio failure; errno is kept when the OS said why (a full
 * disk is ENOSPC or EFBIG, which cfitsio reports only as a write error). */
static int fits_fail(cube_writer *w, const char *what, int st, int os_errno)
{
    char msg[FLEN_STATUS];
    fits_get_errstatus(st, msg);
    fits_clear_errmsg();
    w->failed = SL_EIO;
    return sl_seterr(&w->err, SL_EIO, "%s: %s failed (cfitsio: %s%s%s)",
                     w->path, what, msg, os_errno ? "; " : "",
                     os_errno ? strerror(os_errno) : "");
}

/* Range of an integer bitpix after cfitsio's round-to-nearest; 0 for the
 * float types (which store NaN/Inf and any float as is). */
static int int_range(int bitpix, double *lo, double *hi)
{
    switch (bitpix) {
    case 8: *lo = 0.0; *hi = 255.0; return 1;
    case 16: *lo = -32768.0; *hi = 32767.0; return 1;
    case 32: *lo = -2147483648.0; *hi = 2147483647.0; return 1;
    case CUBE_BITPIX_U16: *lo = 0.0; *hi = 65535.0; return 1;
    case CUBE_BITPIX_U32: *lo = 0.0; *hi = 4294967295.0; return 1;
    default: return 0;
    }
}

static int valid_bitpix(int b)
{
    return b == 8 || b == 16 || b == 32 || b == -32 || b == -64 ||
           b == CUBE_BITPIX_U16 || b == CUBE_BITPIX_U32;
}

/* Create path with an empty image of naxis axes and the header. */
static int create_file(cube_writer *w, const cube_meta *meta)
{
    LONGLONG naxes[3] = {w->width, w->height, 0};
    int st = 0;
    if (unlink(w->path) != 0 && errno != ENOENT)
        return sl_seterr(&w->err, SL_EIO, "cannot replace %s: %s", w->path,
                         strerror(errno));
    errno = 0;
    if (fits_create_diskfile(&w->fp, w->path, &st)) {
        w->fp = NULL;
        return fits_fail(w, "create", st, errno);
    }
    fits_create_imgll(w->fp, w->bitpix, w->naxis, naxes, &st);
    cube_header_write(w->fp, meta, w->width, w->height, 1, &st);
    fits_write_chksum(w->fp, &st);
    if (st)
        return fits_fail(w, "writing the header", st, errno);
    w->sealed = 1;
    return SL_OK;
}

/* Bring the current HDU's DATASUM (kept by append) and CHECKSUM (a sum
 * over the header) up to date. */
static int seal(cube_writer *w)
{
    char v[16];
    int st = 0;
    if (w->sealed || w->failed)
        return w->failed;
    snprintf(v, sizeof v, "%lu", (unsigned long)datasum_value(&w->sum));
    errno = 0;
    fits_modify_key_str(w->fp, "DATASUM", v, "&", &st);
    fits_update_chksum(w->fp, &st);
    if (st)
        return fits_fail(w, "updating CHECKSUM", st, errno);
    w->sealed = 1;
    return SL_OK;
}

static int writer_open(cube_writer **out, const char *path, int width,
                       int height, int bitpix, int naxis,
                       const cube_meta *meta, sl_err *err)
{
    *out = NULL;
    if (!path || width < 1 || height < 1 || !valid_bitpix(bitpix))
        return sl_seterr(err, SL_EINVAL, "cube_writer_open(%s, %d x %d, "
                         "bitpix %d): bad argument", path ? path : "NULL",
                         width, height, bitpix);
    cube_writer *w = calloc(1, sizeof *w);
    if (!w || !(w->path = strdup(path))) {
        free(w);
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    }
    w->width = width;
    w->height = height;
    w->bitpix = bitpix;
    w->naxis = naxis;
    double lo, hi;
    size_t npx = (size_t)width * (size_t)height;
    int rc = SL_OK;
    datasum_init(&w->sum);
    if ((int_range(bitpix, &lo, &hi) &&
         !(w->rounded = malloc(npx * sizeof(float)))) ||
        !(w->stored = malloc(npx * datasum_pixel_bytes(bitpix))))
        rc = sl_seterr(&w->err, SL_ENOMEM, "out of memory for a frame");
    if (rc == SL_OK)
        rc = create_file(w, meta);
    if (rc != SL_OK) {
        sl_seterr(err, rc, "%s", w->err.msg);
        cube_writer_free(w);
        return rc;
    }
    *out = w;
    return SL_OK;
}

int cube_writer_open(cube_writer **out, const char *path, int width,
                     int height, int bitpix, const cube_meta *meta,
                     sl_err *err)
{
    return writer_open(out, path, width, height, bitpix, 3, meta, err);
}

/* For integer bitpix: round img half away from zero into w->rounded
 * (cfitsio truncates) and refuse a frame the type cannot hold (cfitsio
 * would clip it, and casting NaN is undefined).  One pass over the frame,
 * cheap beside the I/O.  *data is what to hand to cfitsio. */
static int round_frame(cube_writer *w, const float *img, const float **data)
{
    double lo, hi;
    size_t n = (size_t)w->width * (size_t)w->height, bad = 0, first = 0;
    *data = img;
    if (!int_range(w->bitpix, &lo, &hi))
        return SL_OK;
    for (size_t i = 0; i < n; i++) {
        double v = img[i], r = lo - 1.0; /* v + 0.5 is exact in double */
        if (v > lo - 1.0 && v < hi + 1.0) /* false for NaN: no UB cast */
            r = v >= 0.0 ? (double)(int64_t)(v + 0.5)
                         : -(double)(int64_t)(0.5 - v);
        w->rounded[i] = (float)r;
        if (!(r >= lo && r <= hi) && bad++ == 0)
            first = i;
    }
    *data = w->rounded;
    if (bad == 0)
        return SL_OK;
    return sl_seterr(&w->err, SL_ERANGE, "%s: frame %d has %zu values "
                     "outside [%.0f, %.0f] (bitpix %d); first %g at (%zu, "
                     "%zu); frame not written", w->path, w->nframes, bad, lo,
                     hi, w->bitpix, (double)img[first], first % (size_t)w->width,
                     first / (size_t)w->width);
}

static int writable(cube_writer *w)
{
    if (!w->fp)
        return sl_seterr(&w->err, SL_EINVAL, "%s: writer is closed", w->path);
    return w->failed;
}

int cube_writer_append(cube_writer *w, const float *frame)
{
    LONGLONG first[3] = {1, 1, (LONGLONG)w->nframes + 1};
    int st = 0, rc = writable(w);
    if (rc != SL_OK)
        return rc;
    if (w->has_ext || (w->naxis == 2 && w->nframes == 1))
        return sl_seterr(&w->err, SL_EINVAL, "%s: cannot append a frame %s",
                         w->path, w->has_ext ? "after an image extension"
                                             : "to a 2-D image");
    const float *data;
    rc = round_frame(w, frame, &data);
    if (rc != SL_OK)
        return rc;
    errno = 0;
    if (w->naxis == 3) { /* grow first, so the header never lags */
        fits_modify_key_lng(w->fp, "NAXIS3", first[2], "&", &st);
        fits_set_hdustruc(w->fp, &st);
    }
    fits_write_pixll(w->fp, TFLOAT, first, (LONGLONG)w->width * w->height,
                     (void *)data, &st);
    if (st)
        return fits_fail(w, "appending a frame", st, errno);
    datasum_add_pixels(&w->sum, data, (size_t)w->width * (size_t)w->height,
                       w->bitpix, w->stored);
    w->sealed = 0;
    w->nframes++;
    return SL_OK;
}

int cube_writer_flush(cube_writer *w)
{
    int st = 0, rc = writable(w);
    if (rc != SL_OK)
        return rc;
    if ((rc = seal(w)) != SL_OK)
        return rc;
    errno = 0;
    if (fits_flush_file(w->fp, &st))
        return fits_fail(w, "flush", st, errno);
    return SL_OK;
}

int cube_writer_add_image(cube_writer *w, const char *extname,
                          const float *img, int width, int height,
                          const cube_meta *meta_or_NULL)
{
    LONGLONG naxes[2] = {width, height}, first[2] = {1, 1};
    int st = 0, rc = writable(w);
    if (rc != SL_OK)
        return rc;
    if (!extname || !img || width < 1 || height < 1)
        return sl_seterr(&w->err, SL_EINVAL, "%s: bad image extension "
                         "arguments", w->path);
    if ((rc = seal(w)) != SL_OK)
        return rc;
    errno = 0;
    fits_create_imgll(w->fp, FLOAT_IMG, 2, naxes, &st);
    fits_update_key_str(w->fp, "EXTNAME", extname, NULL, &st);
    cube_header_write(w->fp, meta_or_NULL, width, height, 0, &st);
    fits_write_pixll(w->fp, TFLOAT, first, (LONGLONG)width * height,
                     (void *)img, &st);
    fits_write_chksum(w->fp, &st);
    w->has_ext = 1;
    if (st)
        return fits_fail(w, "writing extension", st, errno);
    w->sealed = 1;
    return SL_OK;
}

int cube_writer_nframes(const cube_writer *w) { return w->nframes; }
const char *cube_writer_errmsg(const cube_writer *w) { return w->err.msg; }

int cube_writer_close(cube_writer *w)
{
    int st = 0;
    if (!w->fp)
        return w->failed;
    seal(w);
    errno = 0;
    fits_close_file(w->fp, &st);
    w->fp = NULL;
    if (st && !w->failed)
        fits_fail(w, "close", st, errno);
    return w->failed;
}

void cube_writer_free(cube_writer *w)
{
    if (!w)
        return;
    if (w->fp)
        cube_writer_close(w);
    free(w->rounded);
    free(w->stored);
    free(w->path);
    free(w);
}

int cube_write(const char *path, const seq *s, const cube_meta *meta,
               sl_err *err)
{
    cube_writer *w = NULL;
    if (!s)
        return sl_seterr(err, SL_EINVAL, "cube_write: NULL seq");
    int rc = writer_open(&w, path, s->width, s->height, -32,
                         s->nframes == 1 ? 2 : 3, meta, err);
    for (int k = 0; rc == SL_OK && k < s->nframes; k++)
        rc = cube_writer_append(w, seq_frame(s, k));
    if (rc == SL_OK)
        rc = cube_writer_close(w);
    if (rc != SL_OK && w)
        sl_seterr(err, rc, "%s", w->err.msg);
    cube_writer_free(w);
    return rc;
}
