/* closure_select.c - the triples a closure fit uses (closure_int.h).
 *
 * The strongest |B| only (closure.h): the largest first, then those above
 * rel_min of it, counted; past the cap a higher threshold
 * from a histogram taken in the same count, and a recount; then the
 * copy.  Each pass reads every stored triple (phasor_triple: bias and
 * modulus), ~12 M of them at 200^2 and R2 = 28, so the passes run on the
 * graph's threads: KEEP_CHUNKS fixed blocks of targets, claimed by
 * whichever thread is free, their counts and histograms added and their
 * copies placed in block order, so the kept array is the serial one on
 * any thread count.
 */
#include "closure_int.h"
#include "phasor_int.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#define KEEP_CHUNKS 16
/* Histogram bins of |B| / max in 1/64 octave (a float's exponent and six
 * mantissa bits: monotone, no log per triple), down to 2^-16. */
#define BIN_BITS 6
#define CAP_BINS (16 << BIN_BITS)

typedef enum { PASS_MAX, PASS_COUNT, PASS_FILL } keep_pass;

typedef struct keep_ctx {
    const phasor_graph *g;
    const int32_t *fp, *fq;
    keep_pass pass;
    double thr, mx;
    long (*hist)[CAP_BINS];     /* PASS_COUNT: per block, or NULL */
    double bmax[KEEP_CHUNKS];   /* PASS_MAX: per block */
    long cnt[KEEP_CHUNKS];      /* PASS_COUNT: per block; PASS_FILL: offsets */
    kept *out;
    atomic_int next;
} keep_ctx;

/* First target of block k (targets 1..nfreq-1). */
static int block_start(int n, int k) { return 1 + (int)((int64_t)(n - 1) * k / KEEP_CHUNKS); }

static uint32_t float_key(float x)
{
    uint32_t u;
    memcpy(&u, &x, sizeof u);
    return u >> (23 - BIN_BITS);
}

/* The histogram bin of r = |B| / max in (0, 1]: 0 at 1, one per 1/64
 * octave below, the last for everything under 2^-16. */
static int bin_of(double r)
{
    int64_t b = (int64_t)float_key(1.0f) - (int64_t)float_key((float)r);
    return b < 0 ? 0 : b >= CAP_BINS ? CAP_BINS - 1 : (int)b;
}

/* The ratio where bin b begins from above: every r >= it lies in bins
 * before b. */
static double bin_top(int b)
{
    uint32_t u = (float_key(1.0f) - (uint32_t)b + 1) << (23 - BIN_BITS);
    float x;
    memcpy(&x, &u, sizeof x);
    return x;
}

static kept record(const keep_ctx *c, int j, int l1, int l2, double br, double bi, double m)
{
    /* half-plane angle in [0, pi) -> CLOSURE_JK sectors */
    double ang = atan2(c->fq[j], c->fp[j]);
    if (ang < 0)
        ang += M_PI;
    int grp = (int)(ang / M_PI * CLOSURE_JK) % CLOSURE_JK;
    return (kept){l1, l2, j, (float)atan2(bi, br), (float)m, grp};
}

/* tpool job: one pass over each claimed block. */
static void keep_job(void *ctx, int tid, int nthr)
{
    keep_ctx *c = ctx;
    const phasor_graph *g = c->g;
    (void)tid, (void)nthr;
    double inv = phasor_inv_nframes(g);
    for (int k; (k = atomic_fetch_add(&c->next, 1)) < KEEP_CHUNKS;) {
        double mx = 0;
        long n = c->pass == PASS_FILL ? c->cnt[k] : 0, *hist = c->hist ? c->hist[k] : NULL;
        if (hist)
            memset(hist, 0, sizeof *c->hist);
        for (int j = block_start(g->nfreq, k); j < block_start(g->nfreq, k + 1); j++)
            for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++) {
                int l1, l2;
                double br, bi, w, m = phasor_triple_mod_inv(g, inv, j, t, &l1, &l2, &br, &bi, &w);
                if (c->pass == PASS_MAX) {
                    mx = m > mx ? m : mx;
                    continue;
                }
                if (!(m >= c->thr))
                    continue;
                if (hist)
                    hist[bin_of(m / c->mx)]++;
                if (c->pass == PASS_FILL)
                    c->out[n] = record(c, j, l1, l2, br, bi, m);
                n++;
            }
        if (c->pass == PASS_MAX)
            c->bmax[k] = mx;
        else if (c->pass == PASS_COUNT)
            c->cnt[k] = n;
    }
}

static long run_pass(keep_ctx *c, keep_pass pass)
{
    c->pass = pass;
    atomic_store(&c->next, 0);
    if (c->g->pool)
        tpool_run(c->g->pool, keep_job, c);
    else
        keep_job(c, 0, 1);
    long n = 0;
    for (int k = 0; k < KEEP_CHUNKS; k++)
        n += c->cnt[k];
    return n;
}

/* The threshold that keeps at most about cap triples, the strongest: the
 * top of the first bin whose triples would pass cap. */
static double cap_threshold(long (*hist)[CAP_BINS], double mx, double thr, long cap)
{
    long n = 0;
    for (int b = 0; b < CAP_BINS; b++) {
        long in = 0;
        for (int k = 0; k < KEEP_CHUNKS; k++)
            in += hist[k][b];
        if (n + in > cap)   /* b = 0: the strongest bin alone is too many */
            return b == 0 ? mx : fmax(mx * bin_top(b), thr);
        n += in;
    }
    return thr;
}

int closure_keep(const phasor_graph *g, const int32_t *fp, const int32_t *fq, double rel_min,
                 long cap, kept **out, long *nout, sl_err *err)
{
    keep_ctx c = {.g = g, .fp = fp, .fq = fq};
    *out = NULL;
    run_pass(&c, PASS_MAX);
    for (int k = 0; k < KEEP_CHUNKS; k++)
        c.mx = c.bmax[k] > c.mx ? c.bmax[k] : c.mx;
    c.thr = (rel_min > 0 ? rel_min : CLOSURE_REL_MIN) * c.mx;
    if (!(c.hist = malloc(sizeof *c.hist * KEEP_CHUNKS)))
        return sl_seterr(err, SL_ENOMEM, "closure fit: out of memory");
    long n = run_pass(&c, PASS_COUNT);
    if (n > cap) {
        c.thr = cap_threshold(c.hist, c.mx, c.thr, cap);
        free(c.hist), c.hist = NULL;
        n = run_pass(&c, PASS_COUNT);
    }
    free(c.hist), c.hist = NULL;
    if (n < 16)
        return sl_seterr(err, SL_EDATA, "closure fit: only %ld triples above %.3g of the "
                         "strongest", n, c.thr);
    if (!(c.out = malloc((size_t)n * sizeof *c.out)))
        return sl_seterr(err, SL_ENOMEM, "closure fit: out of memory (%ld triples)", n);
    for (long k = 0, at = 0, len; k < KEEP_CHUNKS; k++)
        len = c.cnt[k], c.cnt[k] = at, at += len;
    run_pass(&c, PASS_FILL);
    *out = c.out, *nout = n;
    return SL_OK;
}

/* TSM's pairs at or above thr (counts when out is NULL; *mx: the largest). */
static long keep_1d(int nang, int nf, const int *off, const int *len, int np,
                    const double *bre, const double *bim, double thr, kept *out, double *mx)
{
    long n = 0;
    for (int k = 0; k < nang; k++)
        for (int u1 = 1; u1 < nf; u1++)
            for (int u2 = 1; u2 <= len[u1]; u2++) {
                size_t q = (size_t)k * np + off[u1] + u2 - 1;
                double m = sqrt(bre[q] * bre[q] + bim[q] * bim[q]);
                if (mx && m > *mx)
                    *mx = m;
                if (!(m >= thr))
                    continue;
                if (out) {
                    int b = k * nf;
                    out[n] = (kept){b + u1, b + u2, b + u1 + u2, (float)atan2(bim[q], bre[q]),
                                    (float)m, k * CLOSURE_JK / nang};
                }
                n++;
            }
    return n;
}

int closure_keep_1d(int nang, int nf, const int *off, const int *len, int np,
                    const double *bre, const double *bim, double rel_min, kept **out, long *nout,
                    sl_err *err)
{
    double mx = 0;
    *out = NULL;
    keep_1d(nang, nf, off, len, np, bre, bim, INFINITY, NULL, &mx);
    double thr = (rel_min > 0 ? rel_min : CLOSURE_REL_MIN) * mx;
    long n = keep_1d(nang, nf, off, len, np, bre, bim, thr, NULL, NULL);
    if (n < 16)
        return sl_seterr(err, SL_EDATA, "closure fit: only %ld pairs above %.3g of the "
                         "strongest", n, thr);
    if (!(*out = malloc((size_t)n * sizeof **out)))
        return sl_seterr(err, SL_ENOMEM, "closure fit: out of memory (%ld pairs)", n);
    keep_1d(nang, nf, off, len, np, bre, bim, thr, *out, NULL);
    *nout = n;
    return SL_OK;
}
