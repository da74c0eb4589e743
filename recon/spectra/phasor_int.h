/* phasor_int.h - what phasor.c (the solver, the refinement) and
 * phasor_recur.c (the recursion) share.  Not a public header. */
#ifndef SL_PHASOR_INT_H
#define SL_PHASOR_INT_H

#include <math.h>

#include "base/tpool.h"
#include "phasor.h"

/* 1 / nframes, as the sums' mean takes it (0 without frames). */
static inline double phasor_inv_nframes(const phasor_graph *g)
{
    return g->nframes > 0 ? 1.0 / g->nframes : 0.0;
}

/* phasor_triple_mod with inv = phasor_inv_nframes(g) taken once by the
 * caller: inside a loop the compiler divided anew for every triple (the
 * conditional division may not be hoisted, and stores to doubles might
 * change g->nframes for all it knows). */
static inline double phasor_triple_mod_inv(const phasor_graph *g, double inv, int j,
                                           int64_t t, int *l1, int *l2, double *bre,
                                           double *bim, double *wt)
{
    int k = g->tk[t];
    int a = g->lut[g->ubase[j] - g->doff[k]], b = g->dleg[k];
    double re, im;
    if (g->accd) {
        re = g->accd[2 * t] * inv;
        im = g->accd[2 * t + 1] * inv;
    } else {
        re = g->accf[2 * t] * inv;
        im = g->accf[2 * t + 1] * inv;
    }
    double mre = re, mim = im; /* raw mean, for the variance */
    if (g->xsum) {
        /* X(-u) = conj X(u); the target enters conjugated. */
        int n = g->nfreq;
        int h1 = a % n, h2 = b % n;
        double x1r = g->xsum[2 * h1], x1i = g->xsum[2 * h1 + 1];
        double x2r = g->xsum[2 * h2], x2i = g->xsum[2 * h2 + 1];
        if (a >= n)
            x1i = -x1i;
        if (b >= n)
            x2i = -x2i;
        double x3r = g->xsum[2 * j], x3i = -g->xsum[2 * j + 1];
        re += g->bconst - g->xscale * (x1r + x2r + x3r);
        im -= g->xscale * (x1i + x2i + x3i);
    }
    double mod = sqrt(re * re + im * im); /* not hypot: 10x slower here */
    double w = mod;
    if (g->weight == PHASOR_WEIGHT_UNIT) {
        w = mod > 0 ? 1.0 : 0.0;
    } else if (g->weight == PHASOR_WEIGHT_SNR && g->nframes > 1 &&
               (g->acc2d || g->acc2f)) {
        double m2 = (g->acc2d ? g->acc2d[t] : g->acc2f[t]) * inv;
        double var = m2 - (mre * mre + mim * mim);
        double se = sqrt(fmax(var, 0.0) * inv);
        /* A triple with no scatter (noiseless data) gets the weight of
         * one with a standard error of 1e-6 of its modulus. */
        w = se > 1e-6 * mod ? mod / se : (mod > 0 ? 1e6 : 0.0);
    }
    *l1 = a;
    *l2 = b;
    *bre = re;
    *bim = im;
    *wt = w;
    return mod;
}

/* phasor_triple, returning |B| as well; inline, for the loops over every
 * stored triple (recursion, refinement, closure choice), which had taken
 * the square root twice and paid a call per triple. */
static inline double phasor_triple_mod(const phasor_graph *g, int j, int64_t t, int *l1,
                                       int *l2, double *bre, double *bim, double *wt)
{
    return phasor_triple_mod_inv(g, phasor_inv_nframes(g), j, t, l1, l2, bre, bim, wt);
}

/* Unit phasor of frequency j and of its mirror leg n + j. */
static inline void phasor_set(double *E, int n, int j, double re, double im)
{
    E[2 * j] = re;
    E[2 * j + 1] = im;
    E[2 * (n + j)] = re;
    E[2 * (n + j) + 1] = -im;
}

/* fn on the pool's threads, or inline as the only thread without one. */
static inline void tpool_run_or_inline(tpool *pool, tpool_fn fn, void *ctx)
{
    if (pool)
        tpool_run(pool, fn, ctx);
    else
        fn(ctx, 0, 1);
}

/* Up to iters rounds of the least-squares refinement (phasor.h) from the
 * recursion's E, on g->pool's threads (phasor_refine.c).  Z: scratch of
 * 2 nfreq doubles.  Out of memory: E is left as it was. */
void phasor_refine(const phasor_graph *g, int iters, double *E, double *Z,
                   const unsigned char *known);

/* The k-th largest of v[0..m) (1 <= k <= m, no NaN), v reordered: the
 * refinement's cut of a target to its k strongest triples. */
float phasor_kth_largest(float *v, int32_t m, int32_t k);

/* The recursion over targets 1..nfreq-1 in rank order on g->pool's
 * threads (phasor_recur.c): E and known start with DC known and every
 * phasor 1; *misfit gets the |B|-weighted closure misfit.  SL_ENOMEM. */
int phasor_recur(const phasor_graph *g, double *E, unsigned char *known, double *misfit);

#endif
