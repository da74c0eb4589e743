/* closure_int.h - what the closure fit (closure.c) and its choice of
 * triples (closure_select.c) share.  Not a public header. */
#ifndef SL_CLOSURE_INT_H
#define SL_CLOSURE_INT_H

#include "closure.h"

#define CLOSURE_JK 8  /* jackknife groups: sectors of u_j's angle */

/* A triple the fit uses. */
typedef struct kept {
    int32_t l1, l2, j; /* legs (phasor.h) and target */
    float ph, wt;      /* arg B and |B| */
    int32_t grp;       /* jackknife group: the sector of u_j's angle */
} kept;

/* g's triples with |B| >= rel_min (<= 0: CLOSURE_REL_MIN) x the largest,
 * at most cap of them (the strongest, cut at a 1/64 octave step of |B|:
 * maybe fewer), in storage order, into *out (malloc'd, *n of them), in passes on g->pool's
 * threads: the same triples on any count.  SL_EDATA fewer than 16,
 * SL_ENOMEM. */
int closure_keep(const phasor_graph *g, const int32_t *fp, const int32_t *fq, double rel_min,
                 long cap, kept **out, long *n, sl_err *err);

/* The same for TSM's 1-D bispectra (closure_fit_binary_1d's arguments). */
int closure_keep_1d(int nang, int nf, const int *off, const int *len, int np,
                    const double *bre, const double *bim, double rel_min, kept **out, long *n,
                    sl_err *err);

#endif
