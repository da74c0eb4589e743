/* rawstats.c - see rawstats.h. */
#include "rawstats_int.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>


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

/* Floats of f[i0, i1) that are not finite (exponent bits all ones). */
static size_t count_nonfinite(const float *f, size_t i0, size_t i1)
{
    const v4i exp = {0x7f800000, 0x7f800000, 0x7f800000, 0x7f800000};
    v4i acc = {0, 0, 0, 0};
    size_t i = i0;
    for (; i + 4 <= i1; i += 4) {
        v4i v;
        memcpy(&v, f + i, sizeof v);
        acc -= (v & exp) == exp;   /* true is -1 */
    }
    size_t bad = (size_t)acc[0] + (size_t)acc[1] + (size_t)acc[2] + (size_t)acc[3];
    for (; i < i1; i++)
        bad += !isfinite(f[i]);
    return bad;
}

/* The largest value of f[i0, i1) as the scan "if (f[i] > m) m = f[i]"
 * finds it: four lanes, then the lanes' largest; NaN never wins either
 * way.  Only a maximum of zero can differ (which zero came first): that
 * one scan is redone. */
static float band_max(const float *f, size_t i0, size_t i1)
{
    v4f mv = {-INFINITY, -INFINITY, -INFINITY, -INFINITY};
    size_t i = i0;
    for (; i + 4 <= i1; i += 4) {
        v4f v;
        memcpy(&v, f + i, sizeof v);
        v4i gt = v > mv;
        mv = (v4f)((gt & (v4i)v) | (~gt & (v4i)mv));
    }
    float m = -INFINITY;
    for (int l = 0; l < 4; l++)
        m = mv[l] > m ? mv[l] : m;
    for (; i < i1; i++)
        m = f[i] > m ? f[i] : m;
    if (m == 0)
        for (m = -INFINITY, i = i0; i < i1; i++)
            m = f[i] > m ? f[i] : m;
    return m;
}

/* Rows [y0, y1)'s maximum, the pixels at it, and whether two 4-adjacent
 * pixels share it (the pixel below may lie past y1: it is read only).
 * Four pixels a test, each group of four at x = 0 mod 4 skipped whole
 * when none is at the maximum: the two scalar passes were 40 % of the
 * learning's time a frame.  The same answers. */
static void band_peak(const rawstats *r, const float *f, int y0, int y1, float *vmax,
                      long *nat, int *flat)
{
    int w = r->w, h = r->h;
    float m = band_max(f, (size_t)y0 * w, (size_t)y1 * w);
    const v4f mm = {m, m, m, m};
    long c = 0;
    int fl = 0;
    for (int y = y0; y < y1; y++) {
        const float *row = f + (size_t)y * w;
        for (int x = 0; x < w; x++) {
            if (x + 4 <= w && x % 4 == 0) {
                v4f v;
                memcpy(&v, row + x, sizeof v);
                v4i eq = v == mm;
                if (!(eq[0] | eq[1] | eq[2] | eq[3])) {
                    x += 3;
                    continue;
                }
            }
            if (row[x] != m)
                continue;
            c++;
            fl |= (x + 1 < w && row[x + 1] == m) || (y + 1 < h && row[x + w] == m);
        }
    }
    *vmax = m, *nat = c, *flat = fl;
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
        size_t i0 = (size_t)y0 * r->w, i1 = (size_t)y1 * r->w;
        if (r->nfull == 0) /* see first_touch */
            first_touch(r, i0, i1);
        size_t bad = count_nonfinite(j->f, i0, i1);
        j->nonint[b] = bad ? add_partial(r, j->f, i0, i1) : add_finite(r, j->f, i0, i1);
        band_peak(r, j->f, y0, y1, &j->peak[b], &j->nat[b], &j->flat[b]);
    }
}

void rawstats_set_pool(rawstats *r, tpool *pool) { r->pool = pool; }

void rawstats_run_bands(const rawstats *r, tpool_fn fn, void *ctx)
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
    rawstats_run_bands(r, add_run, &j);
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
