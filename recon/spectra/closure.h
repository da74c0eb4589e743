/* closure.h - a binary star fitted to a bispectrum's closure phases.
 *
 * Why.  A binary measured on a reconstructed image inherits the image's
 * phase errors, and the phasor recursion spreads each triple's error over
 * every frequency built on it.  At 5 lambda/D and dm 2 with 100 frames of
 * 10 m/s wind (about 9 independent crossings of the 1.1 m mask) that left
 * the image fit outside 0.1 px / 0.5 deg / 0.1 mag on 5 of 8 seeds, while
 * the strongest triples' closure phases are far cleaner than the average:
 * on a point source their rms is 0.03 rad over the top 0.1% by |B|, 0.05
 * over the top 1% and 0.31 over all (|B|-weighted).  The three binary
 * parameters fitted straight to those triples, as aperture-masking
 * astronomers fit closure phases, meet the bounds on 8 of 8 of the same
 * seeds (README, Binaries).
 *
 * Model.  The binary's visibility, up to a phase ramp and a real factor,
 * is V(u) = 1 + r e^{-i k.d} with k = 2 pi (p/w, q/h) and d = x2 - x1 in
 * pixels (p along x, q along y, the FFT's sign).  A triple's model phase
 * is arg V(u1) + arg V(u2) - arg V(u1 + u2): the position x1, any linear
 * ramp and every real transfer function cancel, so nothing else is
 * fitted.  The cost is sum_t |B_t| wrap(arg B_t - model_t)^2 over the
 * triples with |B| >= rel_min max|B| (photon-bias-corrected B), minimised
 * over (dx, dy, ln r) by Levenberg-Marquardt from the image fit's d and
 * from -d; the lower cost wins.  (d, r) and (-d, 1/r) give the same
 * closure phases, so the result is stated with r <= 1 like binary.h's.
 *
 * Limits.  At r = 1 closure phases cannot tell d from -d: an equal pair
 * (init->pa_ambiguous) is refused with SL_EDATA.  The cost has a local
 * minimum about every pixel of d, so the fit needs a start within a few
 * pixels: LM steps of d are capped at 1 px, and a fit that leaves 0.5 px
 * .. half the field is refused (SL_EDATA).  A start taken from the
 * closure-phase detection map (sum_f c_f sin(k.d), one FFT) was tried:
 * on noisy strong-turbulence data (r0 0.1 m, 1e4 photons) its peaks were
 * spurious wide "companions" at 60 px that fitted better than the true
 * one, so only the image fit's d and -d are used.
 *
 * Errors.  The triples share a few turbulence realisations, so they are
 * far from independent: the Gauss-Newton covariance (scaled by the
 * residual variance and by triples / distinct frequencies) was 5-11x too
 * small on the 8 seeds.  The stated errors add a delete-a-group
 * jackknife over 8 sectors of the target frequency's angle (8 refits of
 * a few LM steps): rms error/sigma 1.4 (sep), 1.0 (PA), 1.6 (dm) on
 * those seeds, still ~1.5x small because the sectors share frequencies
 * through the triples' other legs.
 *
 * Cost.  Three passes over the stored triples to select them
 * (phasor_triple; four when over CLOSURE_MAX_TRIPLES), on the graph's
 * threads, then per LM step one pass over the kept ones with the model
 * evaluated once per frequency: ~90 passes per start.  On a noisy
 * 200^2 x 100 camera-style cube (R2 = 28, 12 M triples, 2.1 M kept)
 * about 1.2 s on two threads.  Allocates 24 bytes per kept triple and 6
 * doubles per frequency.
 */
#ifndef SL_CLOSURE_H
#define SL_CLOSURE_H

#include <stdint.h>

#include "measure/binary.h"
#include "phasor.h"
#include "status.h"

#define CLOSURE_REL_MIN 1e-4 /* triples kept: |B| >= this x max |B| */
/* ... and at most about this many, the strongest: every LM step and
 * jackknife refit (~120 in all) passes over the kept triples, 24 bytes
 * each, and a bright 256^2 bench cube kept all 17.4 M of them (a 58 s
 * run; 16 s capped).  The weakest add least: the errors count distinct
 * frequencies, not triples (Errors, below), and the capped fit's errors
 * grow where it sees fewer of them. */
#define CLOSURE_MAX_TRIPLES (1L << 21)
#define CLOSURE_MAX_STARTS 8 /* starts of one fit (closure_fit_binary) */

typedef struct closure_fit_info {
    long ntriples;           /* triples fitted */
    int nfreq;               /* distinct frequencies among them */
    double rms_rad;          /* |B|-weighted rms closure residual */
    int iterations;          /* LM steps of the winning start */
    double sign_chi2;        /* how much worse the mirrored binary (-d,
                              * same r) fits, in chi^2 units of
                              * independent frequencies (residual
                              * variance x triples per frequency): below
                              * ~25 the data hardly tell d from -d, the PA
                              * is known modulo 180 deg */
    double detect_chi2;      /* how much worse no companion fits, in the
                              * same units: the companion's significance */
} closure_fit_info;

/* Fit the binary to g's triples (frequencies fp, fq of g's nfreq, w x h
 * frame) from each of nstart starts init[] (fits of the same data: their
 * d and flux_ratio; x1 is copied; 1 to CLOSURE_MAX_STARTS): the triples are chosen
 * once, and the start whose fit leaves the smaller weighted rms residual
 * wins.  A start within 0.5 px of a binary fitted from an earlier one
 * (or of its mirror) is not fitted again: it would end in the same
 * minimum.
 * rel_min <= 0 means CLOSURE_REL_MIN.  out gets d, sep, PA, flux ratio,
 * dm and their 1-sigma errors (its other fields are the winning start's,
 * except nfreq: the frequencies used, err_inflation: triples /
 * frequencies, fit_rms: NAN); info (may be NULL) what was fitted.
 * SL_EDATA when every start is an equal pair or leaves the field, or
 * fewer than 16 triples are kept (the message: the last start's reason),
 * SL_EINVAL for a start count out of range, SL_ENOMEM. */
int closure_fit_binary(const phasor_graph *g, const int32_t *fp,
                       const int32_t *fq, int w, int h, double rel_min,
                       int nstart, const binary_result *init, binary_result *out,
                       closure_fit_info *info, sl_err *err);

/* The same on TSM's 1-D bispectra (tsm_accum.h's sums): nang angles
 * theta_a = a 180/nang deg from +x towards +y, nf frequencies j/nproj
 * cycles/px along n = (cos, sin) (radon.h), and per angle np pairs q =
 * off[u1] + u2 - 1 (u2 = 1..len[u1]) of P(u1) P(u2) conj P(u1 + u2)
 * summed in bre/bim (nang x np; any positive scale).  By the Fourier-slice
 * theorem each pair is a triple of the 2-D spectrum on the line at
 * theta_a, so the model is the same; the jackknife groups are sectors of
 * theta.  The sums are raw: with photon noise their bias shrinks the
 * closure phases and the companion reads faint (tsm.h, Bias). */
int closure_fit_binary_1d(int nang, int nf, int nproj, const int *off,
                          const int *len, int np, const double *bre,
                          const double *bim, double rel_min, int nstart,
                          const binary_result *init, binary_result *out,
                          closure_fit_info *info, sl_err *err);

#endif
