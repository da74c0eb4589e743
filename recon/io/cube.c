/* cube.c - the streaming FITS reader; see cube.h.
 * The metadata is cube_meta.c's, the header's keywords cube_header.c's,
 * the writer cube_write.c. */
#include "cube.h"
#include "cube_guard.h"
#include "cube_header.h"

#include <errno.h>
#include <fitsio.h>
#include <glob.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- opening one file -------------------------------------------------- */

/* Why fits_open_diskfile failed, in words naming the file. */
static int open_error(const char *path, int st, sl_err *err)
{
    struct stat sb;
    char head[6] = {0}, msg[FLEN_STATUS];
    fits_get_errstatus(st, msg);
    fits_clear_errmsg();
    if (stat(path, &sb) != 0)
        return sl_seterr(err, SL_EIO, "cannot open %s: %s", path,
                         strerror(errno));
    FILE *f = fopen(path, "rb");
    size_t got = f ? fread(head, 1, sizeof head, f) : 0;
    if (f)
        fclose(f);
    if (got == sizeof head && memcmp(head, "SIMPLE", 6) == 0)
        return sl_seterr(err, SL_EFORMAT, "%s: truncated or corrupt FITS "
                         "header (%lld bytes; cfitsio: %s)", path,
                         (long long)sb.st_size, msg);
    return sl_seterr(err, SL_EFORMAT, "%s is not a FITS file (%lld bytes; "
                     "cfitsio: %s)", path, (long long)sb.st_size, msg);
}

/* Move fp to the image with data: the primary, or when it has NAXIS=0 the
 * first image extension with NAXIS>0.  *hdu gets its 1-based number. */
static int find_image(fitsfile *fp, const char *path, int *hdu, sl_err *err)
{
    int st = 0, naxis = 0, type = IMAGE_HDU;
    fits_get_img_dim(fp, &naxis, &st);
    while (!st && (type != IMAGE_HDU || naxis == 0)) {
        if (fits_movrel_hdu(fp, 1, &type, &st) == 0 && type == IMAGE_HDU)
            fits_get_img_dim(fp, &naxis, &st);
    }
    if (st) {
        fits_clear_errmsg();
        return sl_seterr(err, SL_EFORMAT, "%s: no image data (primary HDU "
                         "has NAXIS=0 and no image extension has data)", path);
    }
    fits_get_hdu_num(fp, hdu);
    return SL_OK;
}

/* Size of the image at the current HDU; axes must be 2 or 3. */
static int probe_axes(fitsfile *fp, const char *path, int *w, int *h,
                      int *nframes, sl_err *err)
{
    int st = 0, bitpix = 0, naxis = 0;
    LONGLONG n[3] = {0, 0, 1};
    if (fits_get_img_paramll(fp, 3, &bitpix, &naxis, n, &st))
        return sl_seterr(err, SL_EFORMAT, "%s: bad image header", path);
    if (naxis != 2 && naxis != 3)
        return sl_seterr(err, SL_EFORMAT, "%s: NAXIS = %d; expected 2 (one "
                         "frame) or 3 (a cube of frames)", path, naxis);
    if (n[0] < 1 || n[1] < 1 || n[0] > INT_MAX || n[1] > INT_MAX ||
        n[2] > INT_MAX)
        return sl_seterr(err, SL_EFORMAT, "%s: unusable image size %lld x "
                         "%lld x %lld", path, (long long)n[0],
                         (long long)n[1], (long long)n[2]);
    *w = (int)n[0];
    *h = (int)n[1];
    *nframes = naxis == 3 ? (int)n[2] : 1;
    return SL_OK;
}

/* ---- frames ------------------------------------------------------------ */

/* After a failed read: "truncated" when the file is shorter than its
 * header promises (cfitsio notices only when it reaches the end). */
static int read_error(fitsfile *fp, const char *path, int k, int nframes,
                      int st, sl_err *err)
{
    char msg[FLEN_STATUS];
    struct stat sb;
    LONGLONG head = 0, data = 0, end = 0;
    int bitpix = 0, s2 = 0;
    fits_get_errstatus(st, msg);
    fits_clear_errmsg();
    fits_get_hduaddrll(fp, &head, &data, &end, &s2);
    fits_get_img_type(fp, &bitpix, &s2);
    LONGLONG need = data;
    int w = 0, h = 0, n = 0;
    if (!s2 && probe_axes(fp, path, &w, &h, &n, NULL) == SL_OK)
        need += (LONGLONG)w * h * nframes * (bitpix < 0 ? -bitpix : bitpix) / 8;
    if (!s2 && stat(path, &sb) == 0 && (LONGLONG)sb.st_size < need)
        return sl_seterr(err, SL_EFORMAT, "%s is truncated: %lld bytes, the "
                         "header needs %lld (frame %d unreadable)", path,
                         (long long)sb.st_size, (long long)need, k);
    return sl_seterr(err, SL_EIO, "%s: cannot read frame %d (cfitsio: %s)",
                     path, k, msg);
}

static int check_finite(const float *img, int w, int h, const char *path,
                        int k, sl_err *err)
{
    size_t n = (size_t)w * (size_t)h, bad = 0, first = 0;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(img[i]) && bad++ == 0)
            first = i;
    if (bad == 0)
        return SL_OK;
    return sl_seterr(err, SL_EDATA, "%s: %zu non-finite pixels (NaN/Inf) in "
                     "frame %d; first at (x, y, frame) = (%zu, %zu, %d)",
                     path, bad, k, first % (size_t)w, first / (size_t)w, k);
}

/* Frame k (0-based, within the file) of the current HDU into out. */
static int read_plane(fitsfile *fp, const char *path, int w, int h, int k,
                      int nframes, float *out, sl_err *err)
{
    LONGLONG first[3] = {1, 1, (LONGLONG)k + 1};
    float nulval = NAN;
    int anynul = 0, st = 0, bitpix = 0;
    /* BLANK pixels of integer images become NaN.  Float images are read
     * without cfitsio's null check, which would turn Inf into NaN and
     * denormals into 0: they come back bit for bit. */
    fits_get_img_type(fp, &bitpix, &st);
    fits_read_pixll(fp, TFLOAT, first, (LONGLONG)w * h,
                    bitpix > 0 ? &nulval : NULL, out, &anynul, &st);
    if (st)
        return read_error(fp, path, k, nframes, st, err);
    return SL_OK;
}

/* ---- the reader -------------------------------------------------------- */

typedef struct cube_file {
    char *path;
    int hdu;      /* 1-based HDU holding the image */
    int nframes;
} cube_file;

struct cube_reader {
    cube_file *files;
    int nfiles;
    unsigned flags;
    int width, height, nframes;
    fitsfile *fp;      /* files[cur] when open, else NULL */
    int cur;           /* file of the next frame */
    int in_file;       /* next frame within files[cur] */
    int frame;         /* next frame of the sequence */
    cube_meta meta;
    double code_max;   /* cube_reader_code_max */
    sl_err err;
};

static int add_file(cube_reader *r, const char *path, sl_err *err)
{
    cube_file *f = &r->files[r->nfiles];
    f->path = strdup(path);
    if (!f->path)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    r->nfiles++;
    return SL_OK;
}

static int cmp_str(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

/* A pattern (one path with * ? [ that names no existing file) becomes its
 * matches, sorted; anything else is taken literally. */
static int collect_paths(cube_reader *r, const char *const *paths,
                         int npaths, sl_err *err)
{
    glob_t g = {0};
    int rc = SL_OK, globbed = npaths == 1 && strpbrk(paths[0], "*?[") &&
                              access(paths[0], F_OK) != 0;
    if (globbed && glob(paths[0], GLOB_NOSORT, NULL, &g) != 0) {
        rc = sl_seterr(err, SL_EIO, "no file matches %s", paths[0]);
        goto free_glob;
    }
    size_t n = globbed ? g.gl_pathc : (size_t)npaths;
    if (n > INT_MAX || !(r->files = calloc(n, sizeof *r->files))) {
        rc = sl_seterr(err, SL_ENOMEM, "out of memory for %zu paths", n);
        goto free_glob;
    }
    if (globbed)
        qsort(g.gl_pathv, n, sizeof *g.gl_pathv, cmp_str);
    for (size_t i = 0; i < n && rc == SL_OK; i++)
        rc = add_file(r, globbed ? g.gl_pathv[i] : paths[i], err);
free_glob:
    if (globbed)
        globfree(&g);
    return rc;
}

/* Open file i at its image HDU; returns its size. */
static int open_file(const cube_file *f, fitsfile **fp, int *w, int *h,
                     int *n, int *hdu, sl_err *err)
{
    int st = 0, rc;
    if ((rc = cube_guard_check(f->path, err)) != SL_OK)
        return rc;
    if (fits_open_diskfile(fp, f->path, READONLY, &st))
        return open_error(f->path, st, err);
    rc = find_image(*fp, f->path, hdu, err);
    if (rc == SL_OK)
        rc = probe_axes(*fp, f->path, w, h, n, err);
    if (rc != SL_OK) {
        st = 0;
        fits_close_file(*fp, &st);
        *fp = NULL;
    }
    return rc;
}

/* Read every file's header (one open at a time): sizes, frames, meta. */
/* The largest value the current HDU's integer type holds once BZERO is
 * applied (BITPIX 8: 255; 16 with BZERO 32768: 65535); 0 for floating
 * point or a BSCALE that makes the values real. */
static double type_code_max(fitsfile *fp)
{
    int t = 0, st = 0;
    if (fits_get_img_equivtype(fp, &t, &st)) {
        fits_clear_errmsg();
        return 0;
    }
    switch (t) {
    case BYTE_IMG: return 255;
    case SBYTE_IMG: return 127;
    case USHORT_IMG: return 65535;
    case SHORT_IMG: return 32767;
    case ULONG_IMG: return 4294967295.0;
    case LONG_IMG: return 2147483647.0;
    default: return 0;
    }
}

static int scan_files(cube_reader *r, sl_err *err)
{
    fitsfile *fp = NULL;
    int rc = SL_OK;
    long long total = 0;
    for (int i = 0; i < r->nfiles && rc == SL_OK; i++) {
        cube_file *f = &r->files[i];
        int w, h, st = 0;
        rc = open_file(f, &fp, &w, &h, &f->nframes, &f->hdu, err);
        if (rc != SL_OK)
            break;
        if (i == 0) {
            r->width = w;
            r->height = h;
            rc = cube_header_read(fp, &r->meta, f->path, err);
            r->code_max = type_code_max(fp);
        } else if (w != r->width || h != r->height) {
            rc = sl_seterr(err, SL_EFORMAT, "%s: frames are %d x %d but %s "
                           "has %d x %d", f->path, w, h, r->files[0].path,
                           r->width, r->height);
        }
        total += f->nframes;
        fits_close_file(fp, &st);
    }
    if (rc == SL_OK && (total == 0 || total > INT_MAX))
        rc = sl_seterr(err, SL_EDATA, "%s%s: %lld frames", r->files[0].path,
                       r->nfiles > 1 ? " ..." : "", total);
    r->nframes = (int)total;
    return rc;
}

int cube_reader_open(cube_reader **out, const char *const *paths,
                     int npaths, unsigned flags, sl_err *err)
{
    int rc;
    *out = NULL;
    if (!paths || npaths < 1)
        return sl_seterr(err, SL_EINVAL, "cube_reader_open: no paths");
    for (int i = 0; i < npaths; i++)
        if (!paths[i])
            return sl_seterr(err, SL_EINVAL, "cube_reader_open: path %d "
                             "is NULL", i);
    cube_reader *r = calloc(1, sizeof *r);
    if (!r)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    r->flags = flags;
    rc = collect_paths(r, paths, npaths, err);
    if (rc == SL_OK)
        rc = scan_files(r, err);
    if (rc != SL_OK)
        goto free_reader;
    *out = r;
    return SL_OK;
free_reader:
    cube_reader_free(r);
    return rc;
}

double cube_reader_code_max(const cube_reader *r) { return r->code_max; }
int cube_reader_width(const cube_reader *r) { return r->width; }
int cube_reader_height(const cube_reader *r) { return r->height; }
int cube_reader_nframes(const cube_reader *r) { return r->nframes; }
const cube_meta *cube_reader_meta(const cube_reader *r) { return &r->meta; }
const char *cube_reader_errmsg(const cube_reader *r) { return r->err.msg; }

static void close_current(cube_reader *r)
{
    int st = 0;
    if (r->fp)
        fits_close_file(r->fp, &st);
    r->fp = NULL;
}

/* Make r->fp the file holding the next frame (reopened lazily so that only
 * one file is ever open); the file must still match its scanned size. */
static int ensure_open(cube_reader *r)
{
    while (r->in_file >= r->files[r->cur].nframes) {
        close_current(r);
        r->cur++;
        r->in_file = 0;
    }
    if (r->fp)
        return SL_OK;
    const cube_file *f = &r->files[r->cur];
    int w, h, n, hdu, rc = open_file(f, &r->fp, &w, &h, &n, &hdu, &r->err);
    if (rc == SL_OK && (w != r->width || h != r->height || n != f->nframes ||
                        hdu != f->hdu)) {
        close_current(r);
        rc = sl_seterr(&r->err, SL_EFORMAT, "%s changed while being read",
                       f->path);
    }
    return rc;
}

int cube_reader_next(cube_reader *r, float *frame)
{
    if (r->frame >= r->nframes)
        return sl_seterr(&r->err, SL_EEND, "end of sequence");
    int rc = ensure_open(r);
    if (rc != SL_OK)
        return rc;
    const cube_file *f = &r->files[r->cur];
    rc = read_plane(r->fp, f->path, r->width, r->height, r->in_file,
                    f->nframes, frame, &r->err);
    if (rc == SL_OK && !(r->flags & CUBE_ALLOW_NONFINITE))
        rc = check_finite(frame, r->width, r->height, f->path, r->in_file,
                          &r->err);
    if (rc == SL_OK || rc == SL_EDATA) { /* a bad frame is consumed */
        r->in_file++;
        r->frame++;
    }
    return rc;
}

void cube_reader_rewind(cube_reader *r)
{
    close_current(r);
    r->cur = 0;
    r->in_file = 0;
    r->frame = 0;
    sl_clearerr(&r->err);
}

int cube_reader_seek(cube_reader *r, int k)
{
    if (k < 0 || k > r->nframes)
        return sl_seterr(&r->err, SL_ERANGE, "frame %d outside 0..%d", k, r->nframes);
    /* From the current file when k is not before it (frame - in_file is
     * its first frame): readers taking every n-th frame of a sequence of
     * many files seek per frame. */
    int cur = 0, first = 0;
    if (k >= r->frame - r->in_file)
        cur = r->cur, first = r->frame - r->in_file;
    while (cur < r->nfiles - 1 && first + r->files[cur].nframes <= k)
        first += r->files[cur++].nframes;
    if (cur != r->cur)
        close_current(r);
    r->cur = cur;
    r->in_file = k - first;
    r->frame = k;
    sl_clearerr(&r->err);
    return SL_OK;
}

int cube_reader_dup(cube_reader **out, const cube_reader *r, sl_err *err)
{
    *out = NULL;
    cube_reader *d = malloc(sizeof *d);
    if (!d)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    *d = *r;
    d->fp = NULL;
    d->cur = d->in_file = d->frame = 0;
    sl_clearerr(&d->err);
    d->nfiles = 0;
    if (!(d->files = calloc((size_t)r->nfiles, sizeof *d->files)))
        goto free_dup;
    for (; d->nfiles < r->nfiles; d->nfiles++) {
        d->files[d->nfiles] = r->files[d->nfiles];
        if (!(d->files[d->nfiles].path = strdup(r->files[d->nfiles].path)))
            goto free_dup;
    }
    *out = d;
    return SL_OK;
free_dup:
    cube_reader_free(d);
    return sl_seterr(err, SL_ENOMEM, "out of memory");
}

void cube_reader_free(cube_reader *r)
{
    if (!r)
        return;
    close_current(r);
    for (int i = 0; i < r->nfiles; i++)
        free(r->files[i].path);
    free(r->files);
    free(r);
}

/* ---- convenience ------------------------------------------------------- */

int cube_read(seq **out, cube_meta *meta_or_NULL, const char *const *paths,
              int npaths, unsigned flags, sl_err *err)
{
    cube_reader *r = NULL;
    seq *s = NULL;
    *out = NULL;
    int rc = cube_reader_open(&r, paths, npaths, flags, err);
    if (rc != SL_OK)
        return rc;
    s = seq_new(r->width, r->height, r->nframes);
    if (!s) {
        rc = sl_seterr(err, SL_ENOMEM, "out of memory for %d frames of "
                       "%d x %d", r->nframes, r->width, r->height);
        goto free_reader;
    }
    for (int k = 0; k < s->nframes && rc == SL_OK; k++)
        rc = cube_reader_next(r, seq_frame(s, k));
    if (rc != SL_OK) {
        sl_seterr(err, rc, "%s", r->err.msg);
        goto free_seq;
    }
    if (meta_or_NULL)
        *meta_or_NULL = r->meta;
    *out = s;
    s = NULL;
free_seq:
    seq_free(s);
free_reader:
    cube_reader_free(r);
    return rc;
}

int cube_read_ext(seq **out, const char *path, const char *extname,
                  sl_err *err)
{
    fitsfile *fp = NULL;
    seq *s = NULL;
    int st = 0, w, h, n, rc;
    *out = NULL;
    if (!path || !extname)
        return sl_seterr(err, SL_EINVAL, "cube_read_ext: NULL argument");
    if ((rc = cube_guard_check(path, err)) != SL_OK)
        return rc;
    if (fits_open_diskfile(&fp, path, READONLY, &st))
        return open_error(path, st, err);
    if (fits_movnam_hdu(fp, IMAGE_HDU, (char *)extname, 0, &st)) {
        fits_clear_errmsg();
        rc = sl_seterr(err, SL_EFORMAT, "%s: no image extension named %s",
                       path, extname);
        goto close_file;
    }
    rc = probe_axes(fp, path, &w, &h, &n, err);
    if (rc == SL_OK && n != 1)
        rc = sl_seterr(err, SL_EFORMAT, "%s[%s]: %d planes, expected a 2-D "
                       "image", path, extname, n);
    if (rc != SL_OK)
        goto close_file;
    if (!(s = seq_new(w, h, 1))) {
        rc = sl_seterr(err, SL_ENOMEM, "out of memory for %d x %d", w, h);
        goto close_file;
    }
    rc = read_plane(fp, path, w, h, 0, 1, s->data, err);
    if (rc == SL_OK)
        rc = check_finite(s->data, w, h, path, 0, err);
    if (rc == SL_OK) {
        *out = s;
        s = NULL;
    }
    seq_free(s);
close_file:
    st = 0;
    fits_close_file(fp, &st);
    return rc;
}
