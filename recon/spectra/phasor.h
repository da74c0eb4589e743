/* phasor.h - Fourier phase recovery from a stored bispectrum: the unit-
 * amplitude phasor recursion (Lohmann, Weigelt & Wirnitzer 1983; the
 * unit-phasor form of Sridharan) and a weighted least-squares refinement.
 *
 * This is the solver half of bispec: bispec builds the triple graph and
 * accumulates, then hands the solver a read-only view of it
 * (phasor_graph).  The view is generic in how a triple's legs are found
 * (a lookup table of the frequency plane plus a "disk" of u2 offsets), so
 * any lattice of frequencies sorted by radius can use it.
 *
 * Frequencies: the nfreq half-plane frequencies u_j, j = 0 (DC) first, in
 * the visiting order (increasing |u|).  A leg l in [0, 2 nfreq) is +u_l
 * for l < nfreq and -u_(l - nfreq) otherwise, so phi(leg) = +-phi_j and
 * I(-u) = conj I(u).  Triple t of target j (tstart[j] <= t < tstart[j+1])
 * is u_j = u1 + u2 with legs
 *   l2 = dleg[tk[t]],  l1 = lut[ubase[j] - doff[tk[t]]],
 * both of lower rank than j (so known when j is visited), and bispectrum
 *   B_t = <I(u1) I(u2) conj I(u_j)>,  arg B_t = phi(u1) + phi(u2) - phi(u_j).
 */
#ifndef SL_PHASOR_H
#define SL_PHASOR_H

#include <stddef.h>
#include <stdint.h>

#include "status.h"

enum {
    PHASOR_WEIGHT_MOD = 0,  /* |<B>|: strong triples dominate (default) */
    PHASOR_WEIGHT_SNR = 1,  /* |<B>| / (std(B)/sqrt(n)): needs acc2 */
    PHASOR_WEIGHT_UNIT = 2  /* every triple alike (the plain recursion) */
};

typedef struct phasor_graph {
    int nfreq;
    const int64_t *tstart;     /* nfreq + 1 */
    const uint16_t *tk;        /* per triple: disk entry of u2 */
    const int32_t *ubase;      /* per target: lut index of u_j */
    const int32_t *doff;       /* per disk entry: lut offset of u2 */
    const int32_t *dleg;       /* per disk entry: leg of u2 */
    const int32_t *lut;        /* lut index -> leg, -1 outside support */
    const unsigned char *seed; /* per frequency: phase fixed at 0 */
    /* Accumulated sums over frames (exactly one of accd/accf set): b_t =
     * sum I1 I2 conj I3 as (re, im) pairs; acc2: sum |I1 I2 conj I3|^2
     * (only for PHASOR_WEIGHT_SNR). */
    const double *accd;
    const float *accf;
    const double *acc2d;
    const float *acc2f;
    double nframes;
    /* Photon bias (Wirnitzer 1985), NULL xsum = none: the mean B minus
     * xscale * (X(l1) + X(l2) + conj X(j)) plus bconst, with xsum the
     * summed pair term X per frequency as (re, im) pairs; bispec passes
     * xscale = gain / nframes and bconst = 2 gain^2 <sum w^3 I> (plus
     * 3 gain rn^2 sum w^3: read noise's part of the three X, see
     * bispec_opts.read_noise_adu). */
    const double *xsum;
    double xscale, bconst;
    struct tpool *pool;        /* phasor_solve's threads (NULL: this one) */
    int weight;                /* PHASOR_WEIGHT_* of the recursion */
    int refine_weight;         /* PHASOR_WEIGHT_* of the refinement: SNR
                                * weights are the inverse phase errors a
                                * least-squares fit wants (six-star at 1000
                                * photons: c 0.825 with |B|, 0.886), while
                                * the greedy recursion does best with |B| */
    size_t refine_bytes;       /* the refinement's memory at most (0: no
                                * bound; phasor_refine.c) */
    size_t *refine_used;       /* when set: gets the bytes the refinement
                                * took (0: it did not run) */
} phasor_graph;

/* The legs, the bias-corrected mean bispectrum and the weight of triple
 * t of target j. */
void phasor_triple(const phasor_graph *g, int j, int64_t t, int *l1, int *l2,
                   double *bre, double *bim, double *wt);

/* Scratch the solver needs: doubles for 6 * nfreq. */
size_t phasor_work_doubles(int nfreq);

/* Recover phi[0..nfreq) (radians, in (-pi, pi]).  Seeds and DC are 0.
 * Recursion: for j in order, phi_j = arg sum_t w_t exp(i(phi(l1) +
 * phi(l2) - beta_t)); a frequency none of whose triples has known legs
 * stays unknown (known[j] = 0, phi 0).  *misfit_out (may be NULL) gets
 * its closure misfit weighted by |B| (whatever the weights), sum |B| (1 -
 * cos(residual)) / sum |B|: 0.002 to 0.05 on the bench's data, 0.07
 * where the recursion went astray (a piston-phase mask's disjoint
 * splodges).  Then up to `iters` rounds
 * (iters < 0: PHASOR_AUTO_ITERS when the misfit exceeds
 * PHASOR_AUTO_MISFIT, else none) of weighted least squares in phasor
 * form (Jacobi) over each target's triples of weight >= PHASOR_REFINE_REL
 * x its largest (listed once, 16 bytes each, allocated here; within
 * g->refine_bytes each target keeps at most a common number, its
 * strongest): every
 * triple proposes a phasor for each of its three legs from the other
 * two, phi_j = arg of the sum of the proposals, seeds held; a round that
 * does not lower the weighted closure misfit is undone and ends it, as
 * does one that lowers it by less than 1e-3 of itself.  Cost: the recursion one
 * pass over the triples; refining two more to count and list them, then
 * one pass over the strong triples per round (~0.04 s per round at
 * 200^2, R2 = 28, on two threads).
 * Threads (pool): the recursion prepares its next block of triples on
 * the workers while the caller walks the current one (phasor_recur.c);
 * the refinement sums fixed chunks (phasor_refine.c).  The phases do not
 * depend on the thread count. */
#define PHASOR_REFINE_REL 0.01
#define PHASOR_AUTO_MISFIT 0.05
#define PHASOR_AUTO_ITERS 40
int phasor_solve(const phasor_graph *g, int iters, double *work, double *phi,
                 unsigned char *known, double *misfit_out);

/* Write phi/known of the half-plane frequencies u_j = (fp[j], fq[j]) to
 * full w*h planes in FFT order, mirrored: phi(-u) = -phi(u).  Elsewhere
 * 0.  Either output may be NULL. */
void phasor_export(int nfreq, const int32_t *fp, const int32_t *fq,
                   const double *phi, const unsigned char *known, int w,
                   int h, double *phase, unsigned char *known_full);

/* The half spectrum (h rows of w/2+1 complex values, interleaved re/im:
 * FFTW's c2r input) of the image with modulus mod[j] and phase phi[j] at
 * the known u_j, zero elsewhere, times a raised-cosine taper that is 1 up
 * to (1 - taper_frac) r_max and reaches 0 at r_max + 1 (r_max the largest
 * known |u|, so the outermost ring keeps a little weight), times
 * exp(-i k.c) which puts the phase origin at c = (w/2, h/2).  On the
 * pool's threads (NULL: this one), each frequency by one thread: the same
 * bits on any thread count. */
void phasor_halfspec(struct tpool *pool, int nfreq, const int32_t *fp, const int32_t *fq,
                     const double *phi, const unsigned char *known,
                     const double *mod, double taper_frac, int w, int h,
                     double *cin);

#endif
