/* rawstats.c - see rawstats.h. */
#include "rawstats.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "base/stats.h"
#include "nbr8.h"

/* rawstats_add's unit of work: a band of rows, each summed whole by one
 * thread, so the per-pixel sums are the same bits on any thread count. */
enum { RS_BANDS = 16 };

static int band_row(int h, int b) { return (int)((long)h * b / RS_BANDS); }

struct rawstats {
    int w, h, nframes, finished;
    double code_max;
    sl_err err;
    /* per pixel: minus the frames where it was not finite (frames of it:
     * nfull + cnt[i]), sum, sum of squares and the extremes */
    int *cnt;
    int nfull;
    double *s1, *s2;
    float *vmin, *vmax;
    /* the largest value so far, the pixel-frames at it and the frames
     * flat-topped at it */
    double gmax;
    long n_at_gmax;
    int nflat_at_gmax;
    int integer_valued;
    double quantum;
    uint8_t *bad, *sky;
    tpool *pool;          /* rawstats_set_pool; NULL: the caller alone */
    rawstats_result res;
};

static void *alloc_n(size_t n, size_t size) { return calloc(n ? n : 1, size); }

int rawstats_new(rawstats **out, int w, int h, double code_max, sl_err *err)
{
    *out = NULL;
    if (w < 3 || h < 3)
        return sl_seterr(err, SL_EINVAL, "rawstats: frame %dx%d is too small",
                         w, h);
    rawstats *r = calloc(1, sizeof *r);
    if (!r)
        return sl_seterr(err, SL_ENOMEM, "rawstats: out of memory");
    size_t n = (size_t)w * h;
    r->w = w, r->h = h;
    r->code_max = code_max > 0 ? code_max : 0;
    r->gmax = -INFINITY;
    r->integer_valued = 1;
    r->cnt = alloc_n(n, sizeof *r->cnt);
    r->s1 = alloc_n(n, sizeof *r->s1);
    r->s2 = alloc_n(n, sizeof *r->s2);
    r->vmin = alloc_n(n, sizeof *r->vmin);
    r->vmax = alloc_n(n, sizeof *r->vmax);
    r->bad = alloc_n(n, 1);
    r->sky = alloc_n(n, 1);
    if (!r->cnt || !r->s1 || !r->s2 || !r->vmin || !r->vmax || !r->bad ||
        !r->sky) {
        rawstats_free(r);
        return sl_seterr(err, SL_ENOMEM, "rawstats: out of memory for %dx%d "
                         "frames", w, h);
    }
    for (size_t i = 0; i < n; i++)
        r->vmin[i] = INFINITY, r->vmax[i] = -INFINITY;
    *out = r;
    return SL_OK;
}

void rawstats_free(rawstats *r)
{
    if (!r)
        return;
    free(r->cnt);
    free(r->s1);
    free(r->s2);
    free(r->vmin);
    free(r->vmax);
    free(r->bad);
    free(r->sky);
    free(r);
}

const char *rawstats_errmsg(const rawstats *r) { return r ? r->err.msg : "no rawstats"; }
int rawstats_nframes(const rawstats *r) { return r->nframes; }
const uint8_t *rawstats_badmap(const rawstats *r) { return r->bad; }
const uint8_t *rawstats_skymask(const rawstats *r) { return r->sky; }

static double gcd_d(double a, double b)
{
    while (b > 0.5) {
        double t = fmod(a, b);
        a = b;
        b = t;
    }
    return a;
}

/* Rows [y0, y1)'s maximum, the pixels at it, and whether two 4-adjacent
 * pixels share it (the pixel below may lie past y1: it is read only). */
static void band_peak(const rawstats *r, const float *f, int y0, int y1, float *vmax,
                      long *nat, int *flat)
{
    int w = r->w, h = r->h;
    float m = -INFINITY;
    for (size_t i = (size_t)y0 * w, n = (size_t)y1 * w; i < n; i++)
        if (f[i] > m)
            m = f[i];
    long c = 0;
    int fl = 0;
    for (int y = y0; y < y1; y++)
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            if (f[i] != m)
                continue;
            c++;
            fl |= (x + 1 < w && f[i + 1] == m) || (y + 1 < h && f[i + w] == m);
        }
    *vmax = m, *nat = c, *flat = fl;
}

/* 1 when v is an integer; exact for |v| < 2^31, and larger floats are
 * integers anyway. */
static int is_integer(float v)
{
    return fabsf(v) >= 0x1p31f || (float)(int32_t)v == v;
}

/* Pixels [i0, i1) of a finite frame: moments, extremes, and 1 when some
 * value is not an integer.  Four pixels at a time in GCC's vector types
 * (GCC 12 at -O2 vectorises none of the mixed widths, and the scalar
 * loop's float sum of fractions was an add's latency a pixel: 64 us a
 * 200^2 frame); the same IEEE operations per pixel as the scalar tail
 * (no contraction in ISO C mode), so the same sums. */
typedef float v4f __attribute__((vector_size(16)));
typedef int32_t v4i __attribute__((vector_size(16)));
typedef double v4d __attribute__((vector_size(32)));

/* 1 where a float is not an integer (|v| of 2^23 or more always is). */
static inline v4i v4_nonint(v4f v)
{
    const v4i absmask = {0x7fffffff, 0x7fffffff, 0x7fffffff, 0x7fffffff};
    const v4f big = {0x1p23f, 0x1p23f, 0x1p23f, 0x1p23f};
    v4f a = (v4f)((v4i)v & absmask);
    v4i small = a < big;
    v4f c = (v4f)((small & (v4i)a) | (~small & (v4i)big));
    return (v4i)(__builtin_convertvector(__builtin_convertvector(c, v4i), v4f) != c);
}

static int add_finite(rawstats *r, const float *f, size_t i0, size_t i1)
{
    double *s1 = r->s1, *s2 = r->s2;
    float *mn = r->vmin, *mx = r->vmax;
    v4i nonint = {0, 0, 0, 0};
    size_t i = i0;
    for (; i + 4 <= i1; i += 4) {
        v4f v, lo, hi;
        v4d a1, a2;
        memcpy(&v, f + i, sizeof v);
        memcpy(&lo, mn + i, sizeof lo), memcpy(&hi, mx + i, sizeof hi);
        memcpy(&a1, s1 + i, sizeof a1), memcpy(&a2, s2 + i, sizeof a2);
        v4d x = __builtin_convertvector(v, v4d);
        a1 += x;
        a2 += x * x;
        v4i lt = v < lo, gt = v > hi;
        lo = (v4f)((lt & (v4i)v) | (~lt & (v4i)lo));
        hi = (v4f)((gt & (v4i)v) | (~gt & (v4i)hi));
        memcpy(mn + i, &lo, sizeof lo), memcpy(mx + i, &hi, sizeof hi);
        memcpy(s1 + i, &a1, sizeof a1), memcpy(s2 + i, &a2, sizeof a2);
        nonint |= v4_nonint(v);
    }
    int any = nonint[0] | nonint[1] | nonint[2] | nonint[3];
    for (; i < i1; i++) {
        float v = f[i];
        double x = v;
        s1[i] += x;
        s2[i] += x * x;
        mn[i] = v < mn[i] ? v : mn[i];
        mx[i] = v > mx[i] ? v : mx[i];
        any |= !is_integer(v);
    }
    return any != 0;
}

/* Pixels [i0, i1) with some not finite: those are counted against their
 * pixel's frames; 1 when some finite value is not an integer. */
static int add_partial(rawstats *r, const float *f, size_t i0, size_t i1)
{
    int nonint = 0;
    for (size_t i = i0; i < i1; i++) {
        float v = f[i];
        if (!isfinite(v)) {
            r->cnt[i]--;   /* counted against the frames without */
            continue;
        }
        r->s1[i] += v, r->s2[i] += (double)v * v;
        r->vmin[i] = v < r->vmin[i] ? v : r->vmin[i];
        r->vmax[i] = v > r->vmax[i] ? v : r->vmax[i];
        nonint |= !is_integer(v);
    }
    return nonint;
}

/* One frame's bands, shared by the threads, and what each band found. */
typedef struct add_job {
    rawstats *r;
    const float *f;
    int nonint[RS_BANDS], flat[RS_BANDS];
    float peak[RS_BANDS];
    long nat[RS_BANDS];
    atomic_int next;
} add_job;

/* The sums' pixels i0..i1-1 zeroed before the first frame is added.
 * Why: calloc leaves big buffers to the kernel, the add's first read
 * mapped the shared zero page, and the write after took a copy-on-write
 * fault and a TLB flush on every CPU of the process (an interrupt per
 * page, a trap to the host here): ~15 ms of CPU at 512^2.  Written
 * first, each page faults once, on the thread that owns its band. */
static void first_touch(rawstats *r, size_t i0, size_t i1)
{
    memset(r->cnt + i0, 0, (i1 - i0) * sizeof *r->cnt);
    memset(r->s1 + i0, 0, (i1 - i0) * sizeof *r->s1);
    memset(r->s2 + i0, 0, (i1 - i0) * sizeof *r->s2);
}

/* tpool job (or the caller alone): the bands claimed. */
static void add_run(void *ctx, int tid, int nthr)
{
    add_job *j = ctx;
    rawstats *r = j->r;
    (void)tid, (void)nthr;
    for (int b; (b = atomic_fetch_add(&j->next, 1)) < RS_BANDS;) {
        int y0 = band_row(r->h, b), y1 = band_row(r->h, b + 1);
        size_t i0 = (size_t)y0 * r->w, i1 = (size_t)y1 * r->w, bad = 0;
        if (r->nfull == 0) /* see first_touch */
            first_touch(r, i0, i1);
        for (size_t i = i0; i < i1; i++)
            bad += !isfinite(j->f[i]);
        j->nonint[b] = bad ? add_partial(r, j->f, i0, i1) : add_finite(r, j->f, i0, i1);
        band_peak(r, j->f, y0, y1, &j->peak[b], &j->nat[b], &j->flat[b]);
    }
}

void rawstats_set_pool(rawstats *r, tpool *pool) { r->pool = pool; }

/* A job over the bands on the pool, or on the caller alone. */
static void run_bands(const rawstats *r, tpool_fn fn, void *ctx)
{
    if (r->pool && tpool_size(r->pool) > 1)
        tpool_run(r->pool, fn, ctx);
    else
        fn(ctx, 0, 1);
}

/* The frame's maximum, the pixel-frames at it and whether it is flat
 * there, from its bands': the same as one pass over the frame. */
static void frame_peak(const add_job *j, double *vmax, long *nat, int *flat)
{
    float m = -INFINITY;
    for (int b = 0; b < RS_BANDS; b++)
        m = j->peak[b] > m ? j->peak[b] : m;
    long c = 0;
    int fl = 0;
    for (int b = 0; b < RS_BANDS; b++)
        if (j->peak[b] == m)
            c += j->nat[b], fl |= j->flat[b];
    *vmax = m, *nat = c, *flat = fl;
}

/* The frame's bands on the pool (or the caller), then what needs the
 * whole frame: the data's step from the first frame, the running peak. */
int rawstats_add(rawstats *r, const float *f)
{
    if (r->finished)
        return sl_seterr(&r->err, SL_EINVAL, "rawstats_add after finish");
    size_t n = (size_t)r->w * r->h;
    add_job j = {.r = r, .f = f};
    atomic_init(&j.next, 0);
    run_bands(r, add_run, &j);
    r->nfull++;
    for (int b = 0; b < RS_BANDS; b++)
        if (j.nonint[b])
            r->integer_valued = 0;
    /* the data's step, from the first frame (exact while < 2^24) */
    if (r->nframes == 0 && r->integer_valued) {
        float first = NAN;
        /* integer steps: once 1, the step stays 1 (2 fmods a pixel
         * otherwise: 10 ms of a 512^2 frame) */
        for (size_t i = 0; i < n && r->quantum != 1; i++)
            if (isfinite(f[i]) && fabsf(f[i]) < 0x1p24f) {
                if (isnan(first))
                    first = f[i];
                r->quantum = gcd_d(r->quantum, fabs((double)f[i] - first));
            }
    }
    double vm;
    long nat;
    int flat;
    frame_peak(&j, &vm, &nat, &flat);
    if (vm > r->gmax)
        r->gmax = vm, r->n_at_gmax = 0, r->nflat_at_gmax = 0;
    if (vm == r->gmax)
        r->n_at_gmax += nat, r->nflat_at_gmax += flat;
    r->nframes++;
    return SL_OK;
}

static int is_adc_max(double v, double quantum)
{
    double q = quantum >= 1 ? quantum : 1;
    for (int k = 8; k <= 16; k++) {
        double top = ldexp(1.0, k) - 1;
        if (v == top || v == top * q)
            return 1;
    }
    return 0;
}

static void find_saturation(rawstats *r)
{
    rawstats_result *s = &r->res;
    double v = r->gmax;
    if (!isfinite(v) || !(v > 0))
        return;
    if (r->code_max > 0 && v >= r->code_max)
        s->sat_level = r->code_max, s->sat_source = RAWSTATS_SAT_TYPE;
    else if (r->integer_valued && r->n_at_gmax >= 2 && is_adc_max(v, r->quantum))
        s->sat_level = v, s->sat_source = RAWSTATS_SAT_ADC;
    else if (r->integer_valued && r->nflat_at_gmax >= 2)
        s->sat_level = v, s->sat_source = RAWSTATS_SAT_FLAT;
}

/* Pixels [i0, i1)'s long exposure M and temporal rms S. */
static void moments(const rawstats *r, float *M, float *S, size_t i0, size_t i1)
{
    for (size_t i = i0; i < i1; i++) {
        double c = r->nfull + r->cnt[i];
        double m = c > 0 ? r->s1[i] / c : 0;
        M[i] = (float)m;
        S[i] = c > 0 ? (float)sqrt(fmax(r->s2[i] / c - m * m, 0)) : 0.0f;
    }
}

/* rawstats_finish's per-pixel passes, over the bands of rows: the long
 * exposure and rms (pass 0), then their neighbours' median and mean
 * (pass 1, which reads the rows either side of a band).  Serially they
 * were half of finish: 14 of 23 ms at 512^2. */
typedef struct finish_job {
    const rawstats *r;
    float *M, *S, *mloc, *sloc;
    int pass;
    atomic_int next;
} finish_job;

static void finish_run(void *ctx, int tid, int nthr)
{
    finish_job *j = ctx;
    const rawstats *r = j->r;
    (void)tid, (void)nthr;
    for (int b; (b = atomic_fetch_add(&j->next, 1)) < RS_BANDS;) {
        int y0 = band_row(r->h, b), y1 = band_row(r->h, b + 1);
        if (j->pass == 0) {
            moments(r, j->M, j->S, (size_t)y0 * r->w, (size_t)y1 * r->w);
        } else {
            nbr8_median(j->M, r->w, r->h, y0, y1, j->mloc);
            nbr8_mean(j->S, r->w, r->h, y0, y1, j->sloc);
        }
    }
}

/* Median of the values of a[] where sel[] (or every value when sel is
 * NULL) lies at or below `below`; scratch holds n floats. */
static float median_sel(const float *a, const float *key, double below,
                        size_t n, float *scratch)
{
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        if (!key || key[i] <= below)
            scratch[k++] = a[i];
    return stats_median_inplace(scratch, k);
}

/* The finish's per-pixel passes in bands of rows (run_bands). */
typedef struct band_job {
    rawstats *r;
    const float *M, *S, *mloc, *sloc;
    double bg, sigma_t, thr;
    int nstuck[RS_BANDS], nhot[RS_BANDS], ndead[RS_BANDS];
    atomic_int next;
} band_job;

/* tpool job: rows of the bands claimed marked sky (a pixel's own test,
 * the same on any thread). */
static void sky_run(void *ctx, int tid, int nthr)
{
    band_job *j = ctx;
    rawstats *r = j->r;
    int w = r->w, h = r->h;
    (void)tid, (void)nthr;
    for (int b; (b = atomic_fetch_add(&j->next, 1)) < RS_BANDS;)
        for (int y = band_row(h, b); y < band_row(h, b + 1); y++)
            for (int x = 0; x < w; x++) {
                double s = 0;
                int c = 0;
                for (int dy = -1; dy <= 1; dy++)
                    for (int dx = -1; dx <= 1; dx++) {
                        int xx = x + dx, yy = y + dy;
                        if (xx >= 0 && yy >= 0 && xx < w && yy < h)
                            s += j->M[(size_t)yy * w + xx], c++;
                    }
                size_t i = (size_t)y * w + x;
                r->sky[i] = !r->bad[i] && s / c <= j->thr;
            }
}

/* Sky: pixels whose 3x3-smoothed long exposure is within the background's
 * noise; their mean level and temporal rms.  bg is the long exposure's
 * 25th percentile, sigma_t the temporal rms of the dimmer half. */
static void find_sky(rawstats *r, const float *M, const float *S, double bg,
                     double sigma_t, float *scratch)
{
    int K = r->nframes;
    band_job j = {.r = r, .M = M, .thr = bg + 5 * sigma_t / sqrt(9.0 * K) + 0.5 * r->quantum};
    atomic_init(&j.next, 0);
    run_bands(r, sky_run, &j);
    double sum = 0;   /* in pixel order, as before the marks were banded */
    int ns = 0;
    for (size_t i = 0, n = (size_t)r->w * r->h; i < n; i++)
        if (r->sky[i])
            scratch[ns++] = S[i], sum += M[i];
    r->res.nsky = ns;
    r->res.sky_level = ns ? sum / ns : bg;
    r->res.sky_rms = ns ? stats_median_inplace(scratch, (size_t)ns) : sigma_t;
}

/* 1 when no bright pixel fluctuates beyond the noise: the median, over
 * the pixels above 10 % of the brightest (as levels above background), of
 * rms / level is below 0.1 (speckle gives 0.3 to 1).  Pixels that never
 * change are left out, so that a stuck pixel never sets the scale. */
static int is_static(const rawstats *r, const float *M, const float *S,
                     double bg, double sigma_t, float *scratch)
{
    size_t n = (size_t)r->w * r->h, k = 0;
    double top = -INFINITY;
    for (size_t i = 0; i < n; i++)
        if (r->vmin[i] != r->vmax[i])
            top = fmax(top, M[i]);
    double thr = bg + fmax(10 * sigma_t, 0.1 * (top - bg));
    for (size_t i = 0; i < n; i++)
        if (r->vmin[i] != r->vmax[i] && M[i] > thr && M[i] > bg)
            scratch[k++] = (float)(S[i] / (M[i] - bg));
    return k == 0 || stats_median_inplace(scratch, k) < 0.1f;
}

/* Stuck, hot and dead pixels (see rawstats.h).  A pixel's residual from
 * its neighbours' median is judged against its own standard error,
 * sqrt(S^2 + sloc^2 / 8) / sqrt(K), so that a pixel of real, strongly
 * fluctuating signal is never an outlier merely for being bright; and a
 * hot pixel's dark current is a floor under every frame (its minimum
 * stands above the background by half its excess at least), while a
 * dead pixel's maximum stays below its neighbours' level.  A real image
 * moves: its bright pixels go dark and its dark ones bright.  These tests
 * need 20 frames: even a pixel no different from its neighbours lies on
 * one side of their median in all of K frames with probability 2^-K,
 * about one pixel of a 1024^2 frame at K = 20 (clipped or quantised
 * noise is far from Gaussian, so the standard errors alone do not say). */
static void bad_run(void *ctx, int tid, int nthr)
{
    band_job *j = ctx;
    rawstats *r = j->r;
    const float *M = j->M, *S = j->S, *mloc = j->mloc, *sloc = j->sloc;
    double bg = j->bg, sigma_t = j->sigma_t;
    int K = r->nframes, stat = r->res.static_scene;
    double qn = r->quantum / sqrt(12.0);
    (void)tid, (void)nthr;
    for (int b; (b = atomic_fetch_add(&j->next, 1)) < RS_BANDS;) {
        size_t i0 = (size_t)band_row(r->h, b) * r->w, i1 = (size_t)band_row(r->h, b + 1) * r->w;
        for (size_t i = i0; i < i1; i++) {
            double res = M[i] - mloc[i], local = fabs(mloc[i] - bg);
            double se = sqrt(((double)S[i] * S[i] + (double)sloc[i] * sloc[i] / 8 +
                              qn * qn + 1e-30) / K);
            int stuck = K >= 4 && r->vmin[i] == r->vmax[i] && sloc[i] > 0 &&
                        fabs(res) > fmax(fmax(5 * sigma_t, 2 * r->quantum), 0.1 * local);
            int odd = !stat && K >= 20 && fabs(res) > 8 * se && fabs(res) > 0.3 * local;
            int hot = odd && res > 0 && r->vmin[i] - bg > 0.5 * res;
            int dead = odd && res < 0 && r->vmax[i] < mloc[i] + 0.5 * res;
            if (stuck)
                j->nstuck[b]++;
            else if (hot)
                j->nhot[b]++;
            else if (dead)
                j->ndead[b]++;
            r->bad[i] = (uint8_t)(stuck || hot || dead);
        }
    }
}

/* Every pixel's own test, in bands on the pool; the counts summed. */
static void mark_bad(rawstats *r, const float *M, const float *S,
                     const float *mloc, const float *sloc, double bg,
                     double sigma_t)
{
    band_job j = {.r = r, .M = M, .S = S, .mloc = mloc, .sloc = sloc, .bg = bg,
                  .sigma_t = sigma_t};
    atomic_init(&j.next, 0);
    run_bands(r, bad_run, &j);
    for (int b = 0; b < RS_BANDS; b++) {
        r->res.nstuck += j.nstuck[b];
        r->res.nhot += j.nhot[b];
        r->res.ndead += j.ndead[b];
    }
}

/* Centroid and radius of the long exposure above the sky (see .h). */
static void find_cloud(rawstats *r, const float *M, double sigma_t)
{
    rawstats_result *s = &r->res;
    int w = r->w, h = r->h;
    double thr = s->sky_level + 5 * sigma_t / sqrt((double)r->nframes);
    double sw = 0, sx = 0, sy = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            double v = M[i] - thr;
            if (v > 0 && !r->bad[i] && !r->sky[i])
                sw += v, sx += v * x, sy += v * y;
        }
    s->cx_px = sw > 0 ? sx / sw : w / 2.0;
    s->cy_px = sw > 0 ? sy / sw : h / 2.0;
    enum { NR = 512 };
    double acc[NR] = {0}, tot = 0;
    double scale = hypot(w, h) / (NR - 1);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            double v = M[i] - thr;
            if (v > 0 && !r->bad[i] && !r->sky[i]) {
                acc[(int)(hypot(x - s->cx_px, y - s->cy_px) / scale)] += v;
                tot += v;
            }
        }
    double c = 0, rad = 0;
    for (int k = 0; k < NR && tot > 0; k++)
        if ((c += acc[k]) >= 0.95 * tot) {
            rad = (k + 1) * scale;
            break;
        }
    s->cloud_radius_px = fmax(1.5 * rad, 8);
}

int rawstats_finish(rawstats *r, rawstats_result *out)
{
    if (r->finished) {
        if (out)
            *out = r->res;
        return SL_OK;
    }
    size_t n = (size_t)r->w * r->h;
    rawstats_result *s = &r->res;
    memset(s, 0, sizeof *s);
    s->nframes = r->nframes;
    s->integer_valued = r->integer_valued && r->nframes > 0;
    s->quantum = s->integer_valued ? (r->quantum > 0 ? r->quantum : 1) : 0;
    r->quantum = s->quantum;
    find_saturation(r);
    float *M = calloc(n, sizeof *M), *S = calloc(n, sizeof *S);
    float *mloc = malloc(n * sizeof *mloc);
    float *sloc = malloc(n * sizeof *sloc), *tmp = malloc(n * sizeof *tmp);
    int rc = SL_OK;
    if (!M || !S || !mloc || !sloc || !tmp) {
        rc = sl_seterr(&r->err, SL_ENOMEM, "rawstats: out of memory");
        goto free_all;
    }
    if (r->nframes > 0) {
        finish_job fj = {.r = r, .M = M, .S = S, .mloc = mloc, .sloc = sloc};
        for (fj.pass = 0; fj.pass < 2; fj.pass++) {
            atomic_store(&fj.next, 0);
            run_bands(r, finish_run, &fj);
        }
        double med = median_sel(M, NULL, 0, n, tmp);
        double bg = median_sel(M, M, med, n, tmp);      /* 25th percentile */
        double sigma_t = median_sel(S, M, med, n, tmp);  /* dimmer half */
        s->static_scene = is_static(r, M, S, bg, sigma_t, tmp);
        mark_bad(r, M, S, mloc, sloc, bg, sigma_t);
        find_sky(r, M, S, bg, sigma_t, tmp);
        find_cloud(r, M, sigma_t);
    }
    r->finished = 1;
    if (out)
        *out = *s;
free_all:
    free(M);
    free(S);
    free(mloc);
    free(sloc);
    free(tmp);
    return rc;
}
