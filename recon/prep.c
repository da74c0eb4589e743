/* prep.c - see prep.h. */
#include "prep.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stats.h"

struct prep {
    int w, h;
    prep_opts o;
    sl_err err;
    float *dark;       /* copy, or NULL */
    float *invflat;    /* 1/normalised flat, or NULL */
    float *win;        /* window, or NULL when none */
    uint8_t *bad;      /* bad-pixel map */
    int nbad;
    double *learn;     /* running sum of raw frames, or NULL */
    int nlearn;
    float *border;     /* scratch for the sky median */
};

void prep_opts_defaults(prep_opts *o)
{
    memset(o, 0, sizeof *o);
    o->sky = PREP_SKY_AUTO;
    o->window = PREP_WIN_TUKEY;
    o->tukey_alpha = 0.25;
    o->badpix_nsigma = 8;
}

const char *prep_errmsg(const prep *p) { return p ? p->err.msg : "no prep"; }
int prep_nbad(const prep *p) { return p->nbad; }
const float *prep_window(const prep *p) { return p->win; }

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Median by sorting a scratch copy: O(n log n), n is a border band. */
static float median(float *v, int n)
{
    if (n <= 0)
        return 0;
    qsort(v, (size_t)n, sizeof *v, cmp_float);
    return n % 2 ? v[n / 2] : 0.5f * (v[n / 2 - 1] + v[n / 2]);
}

static double taper(int i, int n, int kind, double alpha)
{
    double t = (i + 0.5) / n; /* (0, 1) */
    if (kind == PREP_WIN_HANN)
        return 0.5 - 0.5 * cos(2 * M_PI * t);
    double e = alpha / 2; /* Tukey: cosine ramps of alpha/2 at each end */
    if (t < e)
        return 0.5 - 0.5 * cos(M_PI * t / e);
    if (t > 1 - e)
        return 0.5 - 0.5 * cos(M_PI * (1 - t) / e);
    return 1;
}

static int make_window(prep *p)
{
    if (p->o.window == PREP_WIN_NONE)
        return SL_OK;
    p->win = malloc(sizeof(float) * p->w * p->h);
    if (!p->win)
        return sl_seterr(&p->err, SL_ENOMEM, "out of memory for the window");
    for (int y = 0; y < p->h; y++) {
        double wy = taper(y, p->h, p->o.window, p->o.tukey_alpha);
        for (int x = 0; x < p->w; x++)
            p->win[(size_t)y * p->w + x] =
                (float)(wy * taper(x, p->w, p->o.window, p->o.tukey_alpha));
    }
    return SL_OK;
}

static int copy_calibrations(prep *p, const prep_opts *o)
{
    size_t n = (size_t)p->w * p->h;
    if (o->dark) {
        p->dark = malloc(n * sizeof(float));
        if (!p->dark)
            return sl_seterr(&p->err, SL_ENOMEM, "out of memory");
        for (size_t i = 0; i < n; i++) {
            if (!isfinite(o->dark[i]))
                return sl_seterr(&p->err, SL_EDATA, "dark frame pixel (%zu, "
                                 "%zu) is not finite", i % p->w, i / p->w);
            p->dark[i] = o->dark[i];
        }
    }
    if (o->flat) {
        double sum = 0;
        size_t good = 0;
        for (size_t i = 0; i < n; i++)
            if (isfinite(o->flat[i]) && o->flat[i] > 0) {
                sum += o->flat[i];
                good++;
            }
        if (good < n / 2)
            return sl_seterr(&p->err, SL_EDATA, "flat field has %zu of %zu "
                             "pixels positive and finite", good, n);
        p->invflat = malloc(n * sizeof(float));
        if (!p->invflat)
            return sl_seterr(&p->err, SL_ENOMEM, "out of memory");
        double mean = sum / good;
        for (size_t i = 0; i < n; i++) {
            float f = o->flat[i];
            /* A dead flat pixel becomes a bad pixel, not a division by 0. */
            if (isfinite(f) && f > 0.05 * mean) {
                p->invflat[i] = (float)(mean / f);
            } else {
                p->invflat[i] = 1;
                prep_mark_bad(p, (int)(i % p->w), (int)(i / p->w));
            }
        }
    }
    return SL_OK;
}

int prep_new(prep **out, int w, int h, const prep_opts *o, sl_err *err)
{
    *out = NULL;
    if (w < 4 || h < 4)
        return sl_seterr(err, SL_EINVAL, "frame %dx%d is too small to clean",
                         w, h);
    if (o->window == PREP_WIN_TUKEY && !(o->tukey_alpha > 0 && o->tukey_alpha <= 1))
        return sl_seterr(err, SL_EINVAL, "Tukey alpha %g must lie in (0, 1]",
                         o->tukey_alpha);
    if (o->saturation_adu < 0)
        return sl_seterr(err, SL_EINVAL, "saturation %g must be >= 0",
                         o->saturation_adu);
    prep *p = calloc(1, sizeof *p);
    if (!p)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    p->w = w;
    p->h = h;
    p->o = *o;
    p->o.dark = p->o.flat = NULL; /* never keep the caller's pointers */
    if (p->o.border_px <= 0) {
        int m = (w < h ? w : h) / 16;
        p->o.border_px = m < 2 ? 2 : m;
    }
    if (p->o.badpix_nsigma <= 0)
        p->o.badpix_nsigma = 8;
    int rc = SL_OK;
    p->bad = calloc((size_t)w * h, 1);
    int b = p->o.border_px, nb = 2 * b * w + 2 * b * (h - 2 * b);
    p->border = malloc(sizeof(float) * (size_t)(nb > 0 ? nb : 1));
    if (!p->bad || !p->border) {
        rc = sl_seterr(err, SL_ENOMEM, "out of memory");
        goto free_prep;
    }
    if ((rc = copy_calibrations(p, o)) != SL_OK ||
        (rc = make_window(p)) != SL_OK) {
        sl_seterr(err, rc, "%s", p->err.msg);
        goto free_prep;
    }
    *out = p;
    return SL_OK;
free_prep:
    prep_free(p);
    return rc;
}

void prep_free(prep *p)
{
    if (!p)
        return;
    free(p->dark);
    free(p->invflat);
    free(p->win);
    free(p->bad);
    free(p->learn);
    free(p->border);
    free(p);
}

void prep_mark_bad(prep *p, int x, int y)
{
    if (x < 0 || y < 0 || x >= p->w || y >= p->h)
        return;
    uint8_t *b = &p->bad[(size_t)y * p->w + x];
    if (!*b) {
        *b = 1;
        p->nbad++;
    }
}

int prep_learn(prep *p, const float *raw)
{
    size_t n = (size_t)p->w * p->h;
    if (!p->learn) {
        p->learn = calloc(n, sizeof(double));
        if (!p->learn)
            return sl_seterr(&p->err, SL_ENOMEM, "out of memory");
    }
    for (size_t i = 0; i < n; i++)
        if (isfinite(raw[i]))
            p->learn[i] += raw[i];
    p->nlearn++;
    return SL_OK;
}

/* Hot/dead pixels stand out of their 3x3 neighbourhood in the MEAN frame,
 * where speckle has averaged into a smooth halo.  Robust sigma: 1.4826 x
 * the median absolute residual over the frame. */
int prep_learn_finish(prep *p)
{
    if (!p->learn || p->nlearn == 0)
        return 0;
    int w = p->w, h = p->h, before = p->nbad;
    size_t n = (size_t)w * h;
    float *res = malloc(n * sizeof(float)), *tmp = malloc(n * sizeof(float));
    if (!res || !tmp) {
        free(res);
        free(tmp);
        return sl_seterr(&p->err, SL_ENOMEM, "out of memory");
    }
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float nb[8];
            int k = 0;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int xx = x + dx, yy = y + dy;
                    if ((dx || dy) && xx >= 0 && yy >= 0 && xx < w && yy < h)
                        nb[k++] = (float)p->learn[(size_t)yy * w + xx];
                }
            float med = median(nb, k);
            res[(size_t)y * w + x] = (float)(p->learn[(size_t)y * w + x] - med);
        }
    for (size_t i = 0; i < n; i++)
        tmp[i] = fabsf(res[i]);
    float sigma = 1.4826f * median(tmp, (int)n);
    /* Two tests, both required: a noise outlier (nsigma robust sigmas) and
     * a gross one (off by > 30 % of the local level), so that the smooth
     * curvature of a noiseless halo is never taken for a bad pixel. */
    for (size_t i = 0; i < n; i++) {
        double local = p->learn[i] - res[i];
        if (fabsf(res[i]) > p->o.badpix_nsigma * sigma &&
            fabs(res[i]) > 0.3 * fabs(local))
            prep_mark_bad(p, (int)(i % w), (int)(i / w));
    }
    free(res);
    free(tmp);
    free(p->learn);
    p->learn = NULL;
    p->nlearn = 0;
    return p->nbad - before;
}

static float sky_level(prep *p, const float *f)
{
    int w = p->w, h = p->h, b = p->o.border_px, k = 0;
    const uint8_t *restrict bad = p->bad;
    float *restrict out = p->border;
    /* the band only: whole rows at the top and bottom, b pixels at each
     * end of the rows between (the median does not depend on the order) */
    for (int y = 0; y < h; y++) {
        int rowband = y < b || y >= h - b;
        for (int x = 0; x < w; x++) {
            if (!rowband && x == b && w - b > b)
                x = w - b;
            float v = f[(size_t)y * w + x];
            if (isfinite(v) && !bad[(size_t)y * w + x])
                out[k++] = v;
        }
    }
    return stats_median_inplace(out, (size_t)k);
}

/* Replace flagged pixels (flag[i] != 0) by their good neighbours' median. */
static void repair(prep *p, float *f, const uint8_t *flag, float fallback)
{
    int w = p->w, h = p->h;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            if (!flag[(size_t)y * w + x])
                continue;
            float nb[8];
            int k = 0;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int xx = x + dx, yy = y + dy;
                    size_t j = (size_t)yy * w + xx;
                    if ((dx || dy) && xx >= 0 && yy >= 0 && xx < w && yy < h &&
                        !flag[j] && isfinite(f[j]))
                        nb[k++] = f[j];
                }
            f[(size_t)y * w + x] = k ? median(nb, k) : fallback;
        }
}

/* 1 if every pixel is finite: x * 0 is 0 unless x is NaN or Inf, so a
 * branch-free sum on 4 chains decides (0.01 ms per 200^2 frame). */
static int all_finite(const float *f, size_t n)
{
    float z[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        for (int k = 0; k < 8; k++)
            z[k] += f[i + k] * 0.0f;
    for (; i < n; i++)
        z[0] += f[i] * 0.0f;
    float t = 0;
    for (int k = 0; k < 8; k++)
        t += z[k];
    return t == 0.0f;
}

int prep_frame(prep *p, float *f, prep_stats *st)
{
    size_t n = (size_t)p->w * p->h;
    prep_stats s = {0};
    /* Per-frame flags live in the map's bytes (bit 0 = map, bit 1 =
     * non-finite, bit 2 = saturated) so that no frame allocates; they are
     * cleared back to bit 0 before returning.  Without dark, flat or
     * saturation limit, a finite frame sets no flag: skip the pass. */
    uint8_t *flag = p->bad;
    int plain = !p->dark && !p->invflat && !(p->o.saturation_adu > 0) && all_finite(f, n);
    if (plain)
        s.badmap = p->nbad;
    else
        for (size_t i = 0; i < n; i++) {
            uint8_t fl = flag[i] & 1;
            if (!isfinite(f[i])) {
                fl |= 2;
                s.nonfinite++;
            } else if (p->o.saturation_adu > 0 && f[i] >= p->o.saturation_adu) {
                fl |= 4;
                s.saturated++;
            }
            if (fl == 1)
                s.badmap++;
            flag[i] = fl;
            if (!(fl & 2)) {
                if (p->dark)
                    f[i] -= p->dark[i];
                if (p->invflat)
                    f[i] *= p->invflat[i];
            }
        }
    int subtract = p->o.sky == PREP_SKY_BORDER ||
                   (p->o.sky == PREP_SKY_AUTO && !p->dark);
    float sky = sky_level(p, f);
    if (s.nonfinite + s.saturated + s.badmap > 0)
        repair(p, f, flag, sky);
    if (s.nonfinite + s.saturated > 0)
        for (size_t i = 0; i < n; i++)
            flag[i] &= 1; /* back to the map alone */
    s.sky = subtract ? sky : 0;
    /* x - 0 is x for every value left (the frame is finite now); blocks
     * of 8 have a constant trip count, which the compiler vectorises */
    float fs = (float)s.sky;
    size_t i8 = n - n % 8;
    if (fs != 0.0f) {
        for (size_t i = 0; i < i8; i += 8)
            for (int k = 0; k < 8; k++)
                f[i + k] -= fs;
        for (size_t i = i8; i < n; i++)
            f[i] -= fs;
    }
    if (st) {
        double flux = 0;
        for (size_t i = 0; i < n; i++)
            flux += f[i];
        s.flux = flux;
    }
    if (p->win) {
        for (size_t i = 0; i < i8; i += 8)
            for (int k = 0; k < 8; k++)
                f[i + k] *= p->win[i + k];
        for (size_t i = i8; i < n; i++)
            f[i] *= p->win[i];
    }
    if (st)
        *st = s;
    return SL_OK;
}

void prep_describe(const prep *p, cube_meta *m)
{
    static const char *sky[] = {"auto", "none", "border"};
    static const char *win[] = {"none", "hann", "tukey"};
    cube_meta_set_num(m, "PREPDARK", p->dark != NULL, "1 = dark/bias subtracted");
    cube_meta_set_num(m, "PREPFLAT", p->invflat != NULL, "1 = flat-fielded");
    cube_meta_set_str(m, "PREPSKY",
                      p->o.sky == PREP_SKY_AUTO ? (p->dark ? "none (dark given)" : "border median")
                                                : sky[p->o.sky],
                      "sky estimate subtracted per frame");
    cube_meta_set_num(m, "PREPBORD", p->o.border_px, "[px] sky border band");
    cube_meta_set_num(m, "PREPSAT", p->o.saturation_adu, "[adu] saturation, 0 = none");
    cube_meta_set_num(m, "PREPNBAD", p->nbad, "pixels in the bad-pixel map");
    cube_meta_set_str(m, "PREPWIN", win[p->o.window], "apodisation window");
    if (p->o.window == PREP_WIN_TUKEY)
        cube_meta_set_num(m, "PREPALPH", p->o.tukey_alpha, "Tukey taper fraction");
}
