/* display.c - cut and stretch of a sky image; see display.h. */
#include "display.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int display_cut_parse(const char *name, display_cut *out)
{
    if (name && !strcmp(name, "artifacts"))
        *out = DISPLAY_CUT_ARTIFACTS;
    else if (name && !strcmp(name, "full"))
        *out = DISPLAY_CUT_FULL;
    else
        return SL_EINVAL;
    return SL_OK;
}

const char *display_cut_name(display_cut cut)
{
    return cut == DISPLAY_CUT_FULL ? "full" : "artifacts";
}

static int by_value(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Value at quantile q of the sorted v[0..n). */
static double quantile(const float *v, size_t n, double q)
{
    size_t i = (size_t)floor(q * (double)(n - 1) + 0.5);
    return v[i < n ? i : n - 1];
}

/* Strictly above its (up to) eight finite neighbours. */
static int is_maximum(const float *img, int w, int h, int x, int y)
{
    float v = img[(size_t)y * (size_t)w + (size_t)x];
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
            int xx = x + dx, yy = y + dy;
            if ((dx || dy) && xx >= 0 && yy >= 0 && xx < w && yy < h &&
                !(v > img[(size_t)yy * (size_t)w + (size_t)xx]))
                return 0;
        }
    return 1;
}

/* The local maxima above floor into buf (sorted); their count. */
static size_t maxima(const float *img, int w, int h, double floor_v, float *buf)
{
    size_t m = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float v = img[(size_t)y * (size_t)w + (size_t)x];
            if (isfinite(v) && v > floor_v && is_maximum(img, w, h, x, y))
                buf[m++] = v;
        }
    qsort(buf, m, sizeof *buf, by_value);
    return m;
}

/* Median and 1.4826 x median absolute deviation of the sky samples: the
 * non-zero finite pixels, or every finite one when fewer than a quarter
 * are non-zero (stars on an exact 0: the zeros are the sky). */
static void sky(const float *img, size_t n, size_t nfinite, float *buf, display *d)
{
    size_t m = 0, nz = 0;
    for (size_t i = 0; i < n; i++)
        nz += isfinite(img[i]) && img[i] != 0.0f;
    int all = 4 * nz < nfinite;
    for (size_t i = 0; i < n; i++)
        if (isfinite(img[i]) && (all || img[i] != 0.0f))
            buf[m++] = img[i];
    if (m == 0)
        return; /* every pixel 0: background and noise 0 */
    qsort(buf, m, sizeof *buf, by_value);
    d->background = quantile(buf, m, 0.5);
    for (size_t i = 0; i < m; i++)
        buf[i] = fabsf(buf[i] - (float)d->background);
    qsort(buf, m, sizeof *buf, by_value);
    d->noise = 1.4826 * quantile(buf, m, 0.5);
}

/* Peak and minimum of the finite pixels; how many there are. */
static size_t extremes(const float *img, size_t n, double *peak, double *min)
{
    size_t m = 0;
    *peak = -INFINITY;
    *min = INFINITY;
    for (size_t i = 0; i < n; i++)
        if (isfinite(img[i])) {
            m++;
            *peak = fmax(*peak, img[i]);
            *min = fmin(*min, img[i]);
        }
    return m;
}

int display_fit(display *d, const float *img, int w, int h, display_cut cut,
                preview_stretch stretch, sl_err *err)
{
    if (!d || !img || w < 1 || h < 1 || (unsigned)stretch > PREVIEW_ASINH ||
        (cut != DISPLAY_CUT_ARTIFACTS && cut != DISPLAY_CUT_FULL))
        return sl_seterr(err, SL_EINVAL, "display_fit(%d x %d): bad argument", w, h);
    size_t n = (size_t)w * (size_t)h;
    float *buf = malloc(n * sizeof *buf);
    if (!buf)
        return sl_seterr(err, SL_ENOMEM, "display: out of memory for %d x %d", w, h);
    memset(d, 0, sizeof *d);
    d->cut = cut;
    d->stretch = stretch;
    double min;
    size_t nfinite = extremes(img, n, &d->peak, &min);
    if (nfinite == 0) {
        free(buf);
        return sl_seterr(err, SL_EDATA, "display: no finite pixel in %d x %d", w, h);
    }
    sky(img, n, nfinite, buf, d);
    size_t m = maxima(img, w, h, d->background + DISPLAY_SIGNIFICANT * d->noise, buf);
    d->nmaxima = (int)m;
    d->hi = d->peak;
    d->lo = cut == DISPLAY_CUT_FULL ? min : fmin(d->background, d->peak);
    if (cut == DISPLAY_CUT_ARTIFACTS && m >= DISPLAY_MIN_MAXIMA) {
        double q = quantile(buf, m, DISPLAY_ARTIFACT_QUANTILE);
        if (q < d->peak) {
            d->lo = q;
            d->cut_from_artifacts = 1;
        }
    }
    if (!(d->hi > d->lo))
        d->hi = d->lo + 1.0;
    free(buf);
    return SL_OK;
}

double display_level(const display *d, double v)
{
    if (!isfinite(v))
        return NAN;
    return preview_stretch_curve(d->stretch, (v - d->lo) / (d->hi - d->lo));
}

double display_value(const display *d, double level)
{
    double f = level < 0.0 ? 0.0 : level > 1.0 ? 1.0 : level, t = f;
    if (d->stretch == PREVIEW_SQRT)
        t = f * f;
    else if (d->stretch == PREVIEW_ASINH) /* preview.c: asinh(10 t) / asinh(10) */
        t = sinh(f * asinh(10.0)) / 10.0;
    return d->lo + t * (d->hi - d->lo);
}
