/* prep.c - see prep.h. */
#include "prep.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/finite.h"
#include "base/stats.h"

struct prep {
    int w, h;
    prep_opts o;
    sl_err err;
    float *dark;       /* copy, or NULL */
    float *invflat;    /* 1/normalised flat, or NULL */
    float *win;        /* window, or NULL when none */
    uint8_t *bad;      /* bad-pixel map */
    int nbad;
    float *border;     /* scratch for the sky median */
    int *skyidx;       /* sky pixels (prep_set_sky), or NULL */
    int nsky;
    float *shifted;    /* scratch for recentring, or NULL */
    double cx, cy, crad; /* the cloud's long-exposure centre and radius */
};

void prep_opts_defaults(prep_opts *o)
{
    memset(o, 0, sizeof *o);
    o->sky = PREP_SKY_AUTO;
    o->window = PREP_WIN_TUKEY;
    o->tukey_alpha = 0.25;
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

/* The sky median's scratch: the border band's pixels (at least one). */
static size_t border_bytes(const prep *p)
{
    int b = p->o.border_px, nb = 2 * b * p->w + 2 * b * (p->h - 2 * b);
    return sizeof(float) * (size_t)(nb > 0 ? nb : 1);
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
    int rc = SL_OK;
    p->bad = calloc((size_t)w * h, 1);
    p->border = malloc(border_bytes(p));
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
    free(p->border);
    free(p->skyidx);
    free(p->shifted);
    free(p);
}

/* A copy of n bytes of src (NULL for NULL); *ok = 0 when out of memory. */
static void *dup_block(const void *src, size_t n, int *ok)
{
    void *d = src ? malloc(n ? n : 1) : NULL;
    if (d)
        memcpy(d, src, n);
    else if (src)
        *ok = 0;
    return d;
}

int prep_dup(prep **out, const prep *p, sl_err *err)
{
    *out = NULL;
    prep *d = malloc(sizeof *d);
    if (!d)
        return sl_seterr(err, SL_ENOMEM, "out of memory for a copy of the cleaning");
    *d = *p;
    size_t n = (size_t)p->w * p->h, f = sizeof(float);
    int ok = 1;
    d->dark = dup_block(p->dark, n * f, &ok);
    d->invflat = dup_block(p->invflat, n * f, &ok);
    d->win = dup_block(p->win, n * f, &ok);
    d->bad = dup_block(p->bad, n, &ok);
    d->border = dup_block(p->border, border_bytes(p), &ok);
    d->skyidx = dup_block(p->skyidx, sizeof(int) * (size_t)p->nsky, &ok);
    d->shifted = dup_block(p->shifted, n * f, &ok);
    if (!ok) {
        prep_free(d);
        return sl_seterr(err, SL_ENOMEM, "out of memory for a copy of the cleaning");
    }
    *out = d;
    return SL_OK;
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

/* Mean of the sky pixels, clipped twice at 4 rms about the mean (a
 * speckle that strays onto the sky, a cosmic ray).  Pixel k is summed on
 * chain k mod 4 and the chains are joined in a fixed order: on one chain
 * each add waited for the last (~30 us a 200^2 frame, on the reader's
 * path).  A pixel outside the clip adds +0, which changes no sum. */
static float sky_masked(const prep *p, const float *f)
{
    const int *idx = p->skyidx;
    int n = p->nsky, n4 = n - n % 4;
    double mean = 0, rms = INFINITY;
    for (int pass = 0; pass < 3; pass++) {
        double a0 = 0, a1 = 0, a2 = 0, a3 = 0, q0 = 0, q1 = 0, q2 = 0, q3 = 0;
        double lim = 4 * rms;
        long c = 0;
#define SKY_IN(v) ((fabs(v) <= DBL_MAX) & (fabs((v) - mean) <= lim))
        for (int k = 0; k < n4; k += 4) {
            double v0 = f[idx[k]], v1 = f[idx[k + 1]], v2 = f[idx[k + 2]], v3 = f[idx[k + 3]];
            int i0 = SKY_IN(v0), i1 = SKY_IN(v1), i2 = SKY_IN(v2), i3 = SKY_IN(v3);
            v0 = i0 ? v0 : 0, v1 = i1 ? v1 : 0, v2 = i2 ? v2 : 0, v3 = i3 ? v3 : 0;
            a0 += v0, a1 += v1, a2 += v2, a3 += v3;
            q0 += v0 * v0, q1 += v1 * v1, q2 += v2 * v2, q3 += v3 * v3;
            c += i0 + i1 + i2 + i3;
        }
        for (int k = n4; k < n; k++) {
            double v = f[idx[k]];
            if (SKY_IN(v))
                a0 += v, q0 += v * v, c++;
        }
#undef SKY_IN
        if (c < 1)
            break;
        double s1 = (a0 + a1) + (a2 + a3), s2 = (q0 + q1) + (q2 + q3);
        mean = s1 / (double)c;
        rms = sqrt(fmax(s2 / (double)c - mean * mean, 0)) + 1e-30;
    }
    return (float)mean;
}

static float sky_level(prep *p, const float *f)
{
    if (p->skyidx)
        return sky_masked(p, f);
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

/* 1 when one of the 8 neighbours of (x, y) is saturated (flag bit 2). */
static int saturated_neighbour(const uint8_t *flag, int w, int h, int x, int y)
{
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
            int xx = x + dx, yy = y + dy;
            if ((dx || dy) && xx >= 0 && yy >= 0 && xx < w && yy < h &&
                (flag[(size_t)yy * w + xx] & 4))
                return 1;
        }
    return 0;
}

/* Replace flagged pixels (flag[i] != 0) by their good neighbours' median;
 * a saturated pixel of a plateau (flag 4 alone, a saturated neighbour)
 * keeps its clip level. */
static void repair(prep *p, float *f, const uint8_t *flag, float fallback)
{
    int w = p->w, h = p->h;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            uint8_t fl = flag[(size_t)y * w + x];
            if (!fl || (fl == 4 && saturated_neighbour(flag, w, h, x, y)))
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

void prep_set_badmap(prep *p, const uint8_t *map)
{
    for (int y = 0; y < p->h; y++)
        for (int x = 0; x < p->w; x++)
            if (map[(size_t)y * p->w + x])
                prep_mark_bad(p, x, y);
}

int prep_set_sky(prep *p, const uint8_t *sky)
{
    size_t n = (size_t)p->w * p->h, count = 0;
    free(p->skyidx);
    p->skyidx = NULL;
    p->nsky = 0;
    for (size_t i = 0; sky && i < n; i++)
        count += sky[i] && !p->bad[i];
    if (count < 64)
        return SL_OK;
    /* every stride-th sky pixel: at most 8192, ~0.02 ms per frame */
    size_t stride = (count + 8191) / 8192, k = 0;
    if (!(p->skyidx = malloc(sizeof(int) * (count / stride + 1))))
        return sl_seterr(&p->err, SL_ENOMEM, "out of memory for the sky mask");
    for (size_t i = 0; i < n; i++)
        if (sky[i] && !p->bad[i] && k++ % stride == 0)
            p->skyidx[p->nsky++] = (int)i;
    return SL_OK;
}

int prep_set_centre(prep *p, double cx, double cy, double radius_px)
{
    if (!p->shifted &&
        !(p->shifted = malloc(sizeof(float) * (size_t)p->w * p->h)))
        return sl_seterr(&p->err, SL_ENOMEM, "out of memory for recentring");
    p->cx = cx, p->cy = cy, p->crad = radius_px > 2 ? radius_px : 2;
    return SL_OK;
}

/* The columns xa..xb of x0..x1 with (x - cx)^2 + dy2 <= r2, the test
 * itself deciding the ends (the square root only finds them): 0 when
 * none. */
static int chord(double cx, double dy2, double r2, int x0, int x1, int *xa, int *xb)
{
    if (!(dy2 <= r2))
        return 0;
    double h = sqrt(r2 - dy2);
    int a = (int)ceil(cx - h), b = (int)floor(cx + h);
#define CHORD_IN(x) (((x) - cx) * ((x) - cx) + dy2 <= r2)
    while (a > x0 && CHORD_IN(a - 1))
        a--;
    while (a <= b && !CHORD_IN(a))
        a++;
    while (b < x1 && CHORD_IN(b + 1))
        b++;
    while (b >= a && !CHORD_IN(b))
        b--;
#undef CHORD_IN
    *xa = a < x0 ? x0 : a, *xb = b > x1 ? x1 : b;
    return *xa <= *xb;
}

/* Sums of v, v x and v y over the pixels x0..x1, y0..y1 with v > 0
 * within crad of the cloud's centre (m[0..2]).  Pixel x of a row is
 * summed on chain (x - x0) mod 4, the chains joined in a fixed order:
 * three chains of dependent adds had bound it (~40 us a 200^2 frame).
 * A pixel left out adds +0, which changes no sum. */
static void cloud_moments(const prep *p, const float *f, int x0, int x1, int y0, int y1,
                          double m[3])
{
    double r2 = p->crad * p->crad, cx = p->cx;
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0, sx0 = 0, sx1 = 0, sx2 = 0, sx3 = 0;
    double sy0 = 0, sy1 = 0, sy2 = 0, sy3 = 0;
    for (int y = y0; y <= y1; y++) {
        const float *row = f + (size_t)y * p->w;
        double dy = y - p->cy, dy2 = dy * dy;
        int xa, xb;
        if (!chord(cx, dy2, r2, x0, x1, &xa, &xb))
            continue;
        int x = xa;
        for (; x + 3 <= xb; x += 4) {
            double v0 = row[x], v1 = row[x + 1], v2 = row[x + 2], v3 = row[x + 3];
            v0 = v0 > 0 ? v0 : 0, v1 = v1 > 0 ? v1 : 0, v2 = v2 > 0 ? v2 : 0, v3 = v3 > 0 ? v3 : 0;
            s0 += v0, s1 += v1, s2 += v2, s3 += v3;
            sx0 += v0 * x, sx1 += v1 * (x + 1), sx2 += v2 * (x + 2), sx3 += v3 * (x + 3);
            sy0 += v0 * y, sy1 += v1 * y, sy2 += v2 * y, sy3 += v3 * y;
        }
        for (; x <= xb; x++) {
            double v = row[x];
            if (v > 0)
                s0 += v, sx0 += v * x, sy0 += v * y;
        }
    }
    m[0] = (s0 + s1) + (s2 + s3);
    m[1] = (sx0 + sx1) + (sx2 + sx3);
    m[2] = (sy0 + sy1) + (sy2 + sy3);
}

/* The circular shift by whole pixels that brings (cx, cy) to (w/2, h/2):
 * the long exposure's centre, or the frame's own centroid of positive
 * flux within crad of it when that strays by more than tol = max(3,
 * crad / 10) pixels (a drift that would take the cloud out of a crop).
 * Smaller per-frame moves are left alone, and so is a long exposure
 * within tol of the centre: one shift for all frames, or none, keeps
 * their sub-pixel positions on the grid, which a spatial Radon
 * transform's interpolation sees (spatial TSM's dm moved by 0.06 under a
 * 2 px shift). */
static void recentre(prep *p, float *f, int *sx, int *sy)
{
    int w = p->w, h = p->h;
    int x0 = (int)floor(p->cx - p->crad), x1 = (int)ceil(p->cx + p->crad);
    int y0 = (int)floor(p->cy - p->crad), y1 = (int)ceil(p->cy + p->crad);
    double m[3];
    cloud_moments(p, f, x0 < 0 ? 0 : x0, x1 < w ? x1 : w - 1, y0 < 0 ? 0 : y0,
                  y1 < h ? y1 : h - 1, m);
    double s = m[0], sxw = m[1], syw = m[2];
    double tol = fmax(3, p->crad / 10), cx = p->cx, cy = p->cy;
    if (s > 0 && hypot(sxw / s - p->cx, syw / s - p->cy) > tol)
        cx = sxw / s, cy = syw / s;
    else if (hypot(cx - w / 2, cy - h / 2) <= tol)
        cx = w / 2, cy = h / 2;   /* centred already: leave it */
    int dx = (w / 2 - (int)lround(cx)) % w, dy = (h / 2 - (int)lround(cy)) % h;
    dx = dx < 0 ? dx + w : dx;
    dy = dy < 0 ? dy + h : dy;
    *sx = dx > w / 2 ? dx - w : dx;
    *sy = dy > h / 2 ? dy - h : dy;
    if (!dx && !dy)
        return;
    for (int y = 0; y < h; y++) {
        const float *src = f + (size_t)y * w;
        float *dst = p->shifted + (size_t)((y + dy) % h) * w;
        memcpy(dst + dx, src, sizeof(float) * (size_t)(w - dx));
        memcpy(dst, src + (w - dx), sizeof(float) * (size_t)dx);
    }
    memcpy(f, p->shifted, sizeof(float) * (size_t)w * h);
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
    int plain = !p->dark && !p->invflat && !(p->o.saturation_adu > 0) && (finite_scan(f, n) == n);
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
    if (p->shifted)
        recentre(p, f, &s.shift_x, &s.shift_y);
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

void prep_report_fill(const prep *p, pipeline_prep_report *r)
{
    memset(r, 0, sizeof *r);
    r->on = 1;
    r->dark = p->dark != NULL;
    r->flat = p->invflat != NULL;
    r->sky = p->o.sky == PREP_SKY_NONE ? 0 : p->skyidx ? 2
           : p->o.sky == PREP_SKY_AUTO && p->dark ? 3 : 1;
    r->border_px = p->o.border_px;
    r->saturation_adu = p->o.saturation_adu;
    r->nbad = p->nbad;
    r->recentred = p->shifted != NULL;
}
