/* cube_write.c - metadata and the streaming FITS cube writer; see cube.h.
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
 */
#include "cube.h"

#include <ctype.h>
#include <errno.h>
#include <fitsio.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

/* ---- metadata ---------------------------------------------------------- */

/* Keywords that describe the HDU's structure, not the observation: never
 * extras (a stale NAXIS3 or DATASUM copied to another file would lie). */
static int is_structural(const char *key)
{
    static const char *const names[] = {
        "SIMPLE", "BITPIX", "NAXIS", "EXTEND", "BSCALE", "BZERO", "BLANK",
        "PCOUNT", "GCOUNT", "XTENSION", "EXTNAME", "COMMENT", "HISTORY",
        "END", "CONTINUE", "CHECKSUM", "DATASUM"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (strcmp(key, names[i]) == 0)
            return 1;
    if (strncmp(key, "NAXIS", 5) == 0 && key[5] != '\0')
        return strspn(key + 5, "0123456789") == strlen(key + 5);
    return 0;
}

static int is_standard(const char *key)
{
    static const char *const names[] = {"DATE-OBS", "EXPTIME", "INSTRUME",
                                        "OBJECT", "BUNIT", "PLTSCALE",
                                        "WAVELEN"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (strcmp(key, names[i]) == 0)
            return 1;
    return 0;
}

/* Upper-case key into out; 0 when it is not a usable extra name. */
static int normalise_key(const char *key, char out[CUBE_KEY_MAX])
{
    size_t n = key ? strlen(key) : 0;
    if (n == 0 || n > CUBE_KEY_MAX - 1)
        return 0;
    for (size_t i = 0; i <= n; i++)
        out[i] = (char)toupper((unsigned char)key[i]);
    if (strspn(out, "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-") != n)
        return 0;
    return !is_structural(out) && !is_standard(out);
}

void cube_meta_init(cube_meta *m)
{
    memset(m, 0, sizeof *m);
    m->exptime_s = NAN;
    m->plate_scale_arcsec = NAN;
    m->wavelength_m = NAN;
}

static cube_kv *find_kv(const cube_meta *m, const char *key)
{
    char k[CUBE_KEY_MAX];
    size_t n = key ? strlen(key) : 0;
    if (n == 0 || n >= CUBE_KEY_MAX)
        return NULL;
    for (size_t i = 0; i <= n; i++)
        k[i] = (char)toupper((unsigned char)key[i]);
    for (int i = 0; i < m->nextra; i++)
        if (strcmp(m->extra[i].key, k) == 0)
            return (cube_kv *)&m->extra[i];
    return NULL;
}

/* The slot for key (existing or new), NULL when the list is full. */
static cube_kv *slot_kv(cube_meta *m, const char *key)
{
    cube_kv *kv = find_kv(m, key);
    if (kv || m->nextra >= CUBE_META_MAX_EXTRA)
        return kv;
    kv = &m->extra[m->nextra++];
    memset(kv, 0, sizeof *kv);
    return kv;
}

static int set_kv(cube_meta *m, const char *key, cube_kv_type type,
                  double num, const char *str, const char *comment)
{
    char k[CUBE_KEY_MAX];
    if (!m || !normalise_key(key, k))
        return SL_EINVAL;
    if (type == CUBE_KV_STR && strlen(str) >= CUBE_STR_MAX)
        return SL_ERANGE;
    cube_kv *kv = slot_kv(m, k);
    if (!kv)
        return SL_ERANGE;
    memcpy(kv->key, k, sizeof k);
    kv->type = type;
    kv->num = num;
    snprintf(kv->str, sizeof kv->str, "%s", str ? str : "");
    snprintf(kv->comment, sizeof kv->comment, "%s", comment ? comment : "");
    return SL_OK;
}

int cube_meta_set_num(cube_meta *m, const char *key, double value,
                      const char *comment)
{
    if (!isfinite(value))
        return SL_EINVAL;
    return set_kv(m, key, CUBE_KV_NUM, value, NULL, comment);
}

int cube_meta_set_str(cube_meta *m, const char *key, const char *value,
                      const char *comment)
{
    if (!value)
        return SL_EINVAL;
    return set_kv(m, key, CUBE_KV_STR, 0.0, value, comment);
}

int cube_meta_get_num(const cube_meta *m, const char *key, double *out)
{
    const cube_kv *kv = find_kv(m, key);
    if (!kv)
        return SL_EINVAL;
    if (kv->type == CUBE_KV_STR)
        return SL_EDATA;
    *out = kv->num;
    return SL_OK;
}

int cube_meta_get_str(const cube_meta *m, const char *key, const char **out)
{
    const cube_kv *kv = find_kv(m, key);
    if (!kv)
        return SL_EINVAL;
    if (kv->type != CUBE_KV_STR)
        return SL_EDATA;
    *out = kv->str;
    return SL_OK;
}

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

/* Shortest %G precision that reads back as v exactly. */
static int round_trip_digits(double v)
{
    char buf[40];
    for (int d = 1; d < 17; d++) {
        snprintf(buf, sizeof buf, "%.*G", d, v);
        if (strtod(buf, NULL) == v)
            return d;
    }
    return 17;
}

static void put_num(fitsfile *fp, const char *key, double v,
                    const char *comment, int *st)
{
    if (v == floor(v) && fabs(v) < 9.0e15)
        fits_update_key_lng(fp, key, (LONGLONG)v, comment, st);
    else
        fits_update_key_dbl(fp, key, v, -round_trip_digits(v), comment, st);
}

static void put_str(fitsfile *fp, const char *key, const char *s,
                    const char *comment, int *st)
{
    if (s[0] != '\0')
        fits_update_key_str(fp, key, s, comment, st);
}

/* DATE-OBS for "now": ISO-8601 UTC with milliseconds. */
static void now_iso(char *out, size_t n)
{
    struct timespec ts;
    struct tm tm;
    char sec[32];
    clock_gettime(CLOCK_REALTIME, &ts);
    gmtime_r(&ts.tv_sec, &tm);
    strftime(sec, sizeof sec, "%Y-%m-%dT%H:%M:%S", &tm);
    snprintf(out, n, "%s.%03ld", sec, ts.tv_nsec / 1000000L);
}

/* The standard keywords (when set), then the extras, into the current
 * HDU.  with_date: write DATE-OBS even when meta lacks one (primary). */
static void put_meta(fitsfile *fp, const cube_meta *m, int with_date,
                     int *st)
{
    char date[CUBE_STR_MAX];
    if (m && m->date_obs[0])
        snprintf(date, sizeof date, "%s", m->date_obs);
    else
        now_iso(date, sizeof date);
    if (with_date || (m && m->date_obs[0]))
        put_str(fp, "DATE-OBS", date, "[UTC] start of the observation", st);
    if (!m)
        return;
    if (isfinite(m->exptime_s))
        put_num(fp, "EXPTIME", m->exptime_s, "[s] exposure time", st);
    put_str(fp, "INSTRUME", m->instrume, "instrument / camera", st);
    put_str(fp, "OBJECT", m->object, "target", st);
    put_str(fp, "BUNIT", m->bunit, "physical unit of the pixel values", st);
    if (isfinite(m->plate_scale_arcsec))
        put_num(fp, "PLTSCALE", m->plate_scale_arcsec,
                "[arcsec/pixel] plate scale", st);
    if (isfinite(m->wavelength_m))
        put_num(fp, "WAVELEN", m->wavelength_m, "[m] wavelength", st);
    for (int i = 0; i < m->nextra && i < CUBE_META_MAX_EXTRA; i++) {
        const cube_kv *kv = &m->extra[i];
        const char *c = kv->comment[0] ? kv->comment : NULL;
        if (kv->type == CUBE_KV_STR)
            fits_update_key_str(fp, kv->key, kv->str, c, st);
        else if (kv->type == CUBE_KV_BOOL)
            fits_update_key_log(fp, kv->key, kv->num != 0.0, c, st);
        else
            put_num(fp, kv->key, kv->num, c, st);
    }
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
    put_meta(w->fp, meta, 1, &st);
    if (st)
        return fits_fail(w, "writing the header", st, errno);
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
    int rc = SL_OK;
    if (int_range(bitpix, &lo, &hi) &&
        !(w->rounded = malloc((size_t)width * (size_t)height * sizeof(float))))
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
    w->nframes++;
    return SL_OK;
}

int cube_writer_flush(cube_writer *w)
{
    int st = 0, rc = writable(w);
    if (rc != SL_OK)
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
    errno = 0;
    fits_create_imgll(w->fp, FLOAT_IMG, 2, naxes, &st);
    fits_update_key_str(w->fp, "EXTNAME", extname, NULL, &st);
    put_meta(w->fp, meta_or_NULL, 0, &st);
    fits_write_pixll(w->fp, TFLOAT, first, (LONGLONG)width * height,
                     (void *)img, &st);
    w->has_ext = 1;
    if (st)
        return fits_fail(w, "writing extension", st, errno);
    return SL_OK;
}

int cube_writer_nframes(const cube_writer *w) { return w->nframes; }
const char *cube_writer_errmsg(const cube_writer *w) { return w->err.msg; }

int cube_writer_close(cube_writer *w)
{
    int st = 0;
    if (!w->fp)
        return w->failed;
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
