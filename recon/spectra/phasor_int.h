/* phasor_int.h - what phasor.c (the solver, the refinement) and
 * phasor_recur.c (the recursion) share.  Not a public header. */
#ifndef SL_PHASOR_INT_H
#define SL_PHASOR_INT_H

#include "base/tpool.h"
#include "phasor.h"

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
