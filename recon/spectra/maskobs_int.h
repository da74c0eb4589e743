/* maskobs_int.h - internals shared by maskobs.c (the frames) and
 * maskobs_plan.c (where each observable is sampled).  Not a public header. */
#ifndef SL_MASKOBS_INT_H
#define SL_MASKOBS_INT_H

/* complex.h first: fftwf_complex is then C99's float complex */
#include <complex.h>
#include <fftw3.h>

#include "maskobs.h"

/* A sample of the r2c half plane: index into it, and whether the value is
 * the conjugate of the one stored (the frequency is in the other half). */
typedef struct mo_tap {
    int idx, conj;
} mo_tap;

struct maskobs {
    sl_err err;
    maskobs_opts o;
    int w, h, wc, nholes;
    /* the plan: geometry of every row measured (values filled by
     * maskobs_result_get), one tap per V2 row and three per triangle */
    int nvis2, nt3, nvis2_lost, nt3_lost;
    maskobs_vis2 *vis2;
    maskobs_t3 *t3;
    double *t3_transfer;  /* nt3: T1 T2 T3 */
    mo_tap *vtap, *ttap;
    /* sums over frames: V2 (sum, sum of squares); B (re, im, re^2, im^2,
     * re im) */
    double *vacc, *tacc;
    /* the same over blocks of o.block_frames frames: the running block
     * (V2: sum; B: re, im) and the moments of the block means */
    double *vblk, *tblk, *vbacc, *tbacc;
    int block, inblock, nblocks;
    int nframes, nskipped;
    float *in;
    fftwf_complex *out;
    fftwf_plan plan;
};

/* Choose the sampled pixels (maskobs.h, Where) and fill m's plan: vis2,
 * t3 (geometry), t3_transfer, vtap, ttap and the counts.  SL_ENOMEM,
 * SL_EDATA when no triangle is left (message in m->err). */
int maskobs_plan(maskobs *m, const double *x_m, const double *y_m,
                 double hole_diameter_m);
/* The half-plane tap of FFT frequency (p, q) on a w x h frame, wrapped;
 * 0 when it falls on the Nyquist row or column or at DC (not usable). */
int maskobs_tap(int w, int h, int p, int q, mo_tap *tap);

#endif
