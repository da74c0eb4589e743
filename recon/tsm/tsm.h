/* tsm.h - tomographic speckle masking (Surya & Saha): the bispectrum
 * reconstruction done on 1-D projections of the frames.
 *
 * The six steps, for a stream of frames:
 *  tsm_add, per frame:
 *   (1) projection spectra at nangles angles (radon.h): TSM_FOURIER takes
 *       them as radial slices of one 2-D FFT (Fourier-slice theorem, exact
 *       up to ~1e-4), TSM_SPATIAL projects with the bilinear ray-driven
 *       Radon transform and FFTs each projection (the paper's way; ~6x
 *       slower at 180 angles and damps high frequencies);
 *   (2) per angle, accumulate in double the power |P(u)|^2, the mean
 *       spectrum P(u) and the 1-D bispectrum B(u1,u2) = P(u1) P(u2)
 *       conj(P(u1+u2)) over 1 <= u2 <= u1, u2 <= r2, u1+u2 <= cut-off.
 *       Frames are buffered in blocks of `batch` (tsm_accum.h) so that
 *       each angle's bispectrum stays in cache while a block is added (the
 *       accumulators exceed the cache at 180 angles); a full block goes
 *       to the threads while tsm_add returns and the caller reads the next
 *       frames; memory does not depend on the number of frames, and
 *       tsm_add allocates nothing.
 *  tsm_result:
 *   (3) 1-D phases per angle (tsm_phase.c): the bispectrum is first
 *       averaged over the neighbouring angles whose lines pass within
 *       arc_bins of each other at the pair's largest frequency (the slices
 *       are lines through one 2-D spectrum; closure phases need no common
 *       origin, so the average is plain), the arc capped by the object's
 *       diameter from the power's autocorrelation so that no feature's
 *       phase turns by more than 0.4 rad over it (tsm_extent.c: a fixed
 *       1.5 bins read a dm 1 companion 40 px out 0.25 mag faint); then
 *       phi(0) = phi(1) = 0 (phi(1) is the unknown shift), the
 *       unit-phasor recursion phi(u1+u2) = phi(u1) + phi(u2) -
 *       beta(u1,u2) weighted per tsm_weight, then
 *       refine_iters steps of an exact weighted solver (majorise-minimise
 *       with one Cholesky factor per angle, accelerated), which moves whole
 *       bands beyond spectral gaps where the recursion left them rotated.
 *       Measured on the bench binary (17-hole mask, 128^2, D/r0 ~ 11, 100
 *       frames, 24 seeds; with the white-noise bias below): binary found
 *       18/24 -> 24/24 noiseless, 0/24 -> 24/24 at 1e4 photons + 2 e- read
 *       noise, mean c 0.76 -> 0.86 and 0.63 -> 0.86; at D/r0 ~ 4 the same
 *       noise 7/24 -> 23/24, noiseless unchanged (24/24, c 0.91);
 *   (4) modulus sqrt(<|P|^2> - bias) (see Bias below), optionally divided
 *       by a reference star's power spectrum with a Wiener regulariser;
 *       on the spatial path also divided by the bilinear projector's
 *       signal transfer sinc^2(rho cos) sinc^2(rho sin) up to nangles / pi
 *       bins, where the slices sample the plane densely (tsm_result.c);
 *   (5) projections rebuilt and each centred on its own centroid (of the
 *       part above centroid_frac of its peak): the centroid of a
 *       projection is the projection of the object's centroid, so this is
 *       one consistent 2-D shift.  With >= 2 neighbours within align_deg,
 *       each projection is then aligned (cross-correlation on its whole
 *       profile) to the sum of its neighbours; then reproj_iters rounds
 *       align every projection to the slice of one 2-D template (the FBP
 *       image above reproj_frac of its peak), which removes the shift
 *       errors that vary slowly with angle and that neighbours share; and
 *       the object is re-centred by one least-squares 2-D shift.
 *       Measured (64^2, D/r0 ~ 8, 100 frames, 180 angles): plain
 *       positive-part centroids give c 0.935 on a binary, the 5% threshold
 *       0.967, plus neighbours 0.976.  On the 200^2 bench six-star (100
 *       frames, seeds 1-4) the reprojection takes the shift error against
 *       the true slices from ~0.2 to ~0.09 px rms and c from 0.952 to 0.984
 *       with a reference, 0.924 to 0.954 without (Fourier path);
 *   (6) inversion: gridding FBP of the slices (TSM_FOURIER), spatial FBP
 *       (TSM_SPATIAL), or the iterative non-negative inverse (TSM_INV_ITER,
 *       for few angles).
 * The image has the object's centroid at pixel (w/2, h/2).  Angles and
 * projection coordinates follow radon.h (theta from +x towards +y; the
 * projection axis at theta points to position angle theta - 90 deg).
 *
 * Bias.  White noise (photon, read, dark) adds to every |P(u)|^2 a level
 * L times the projector's noise transfer T(a, u): T = 1 on the Fourier
 * path (a slice sample is the exact DFT of the pixels), while the spatial
 * path's bilinear rays damp it (from ~1 at u = 0 to ~0.35 at Nyquist,
 * by angle), so there T is measured once at tsm_new from projections of
 * white noise (tsm.c; the floor level then comes out within ~1-2%).
 * Modes (opts.bias):
 *  - TSM_BIAS_PHOTON (photons_per_frame > 0): frames are photon counts
 *    times a gain g = <frame sum> / photons_per_frame; L = g <S> +
 *    w h read_noise_adu^2, and Wirnitzer's (1985) unbiased bispectrum
 *    B - g(|P(u1)|^2 + |P(u2)|^2 + |P(u1+u2)|^2) + 2 g^2 <S>, with |P|^2
 *    less its non-photon white part (L - g <S>) T: Gaussian read noise
 *    adds nothing to the bispectrum.  The Wirnitzer terms are approximate
 *    at high u on the spatial path;
 *  - TSM_BIAS_FLOOR: L measured, |P|^2 / T over the outermost shells
 *    u > J - max(2, J/16) (as powspec's POWSPEC_BIAS_FLOOR uses the
 *    corners beyond the pupil): it covers every white source, and is
 *    linear in the data (streaming and per-frame results add up).  It
 *    assumes those shells hold no signal: true for Nyquist-sampled pupils
 *    with the default cut-off 0.5 cycles/px; undersampled frames (aliased
 *    speckle) or a cut-off inside the pupil bias it high.  The bispectrum
 *    is corrected only when the gain is known (photons_per_frame > 0);
 *  - TSM_BIAS_AUTO (default): PHOTON when photons_per_frame > 0, else
 *    FLOOR (real camera data, photon statistics unknown);
 *  - TSM_BIAS_NONE.
 * Left in, L flattens the modulus wherever the signal is below it: the
 * bench binary at 1e4 photons + 2 e- read noise is found in 9/24 seeds
 * without the read-noise part, 24/24 with it.  The modulus always uses
 * the corrected power; the phases by default use the raw bispectrum
 * (bispec_bias_phase = 0, tsm_result.c), whose real photon bias shrinks the
 * closure phases: a companion reads faint.  Measured on the 200^2 bench
 * binary (100 frames, tsm-fourier 180, dm 1 and 2 at 5-40 px): raw
 * phases read dm +0.4..+1.0 at 1000 photons/frame, +0.05..+0.30 at 1e4;
 * corrected ones with TSM_WEIGHT_SNR2 read dm 1 within 0.05 at 1e4 (and
 * at 1000 photons from 20 px out), but the noisier phases enlarge the
 * 17-hole PSF's sidelobe asymmetry (a lobe at 7-8 px) until it beats a
 * dm 2 companion: lost at 1000-4000 photons (raw phases keep it, faint),
 * found at 1e4 except 10 px.  Hence raw by default, corrected on request
 * (pipeline's tsm_corrected_phases, `recon --tsm-phases corrected`).
 *
 * Sizes: nproj (projection length, 1-D FFT size) defaults to the even
 * number >= max(w, h): the object must lie in the disc of that diameter
 * (projections are periodic with period nproj).  With J = cut-off bins the
 * bispectrum holds about J^2/4 pairs per angle (r2 unlimited); at 200^2,
 * 180 angles that is 2500 pairs, 7 MB of accumulators.
 *
 * Threads (opts.threads; 0: the online CPUs, at most 4): steps (1)-(2)
 * run on a pool per block (a frame is sliced whole by one thread; each
 * angle's sums are added by one thread, frames in order), step (3) per
 * angle (each angle solved whole by one thread).  Nothing is reduced
 * across threads, so the image is bit-identical for any thread count
 * and run to run (tests/stress/test_stress_edge.c).
 *
 * Cost model, per run of F frames of w x h, K angles, J bins (np ~ J^2/4
 * pairs per angle), grid g and kernel kw (radon.h: g = 256, kw = 8 for
 * 200^2 below 60 angles; g = 400, kw = 4 at 60 and more):
 *   tsm_new     K J 2 kw kernel taps + FFTW plans (from wisdom) + touching
 *               ~K np 16 bytes of sums: 1 ms at K = 18, 7 ms at K = 180;
 *   per frame   caller: a finite check and copy (w h); pool: one g x g
 *               real 2-D FFT (~2.5 g^2 log2 g flops: 0.09 ms at 256,
 *               0.17 ms at 400) plus K J kw^2 complex taps (0.03 ms at
 *               18 angles, 0.15 ms at 180), then K (14 np + 6 J) double
 *               flops of sums (0.035 and 0.34 ms; 4 frames per pass over
 *               the sums, AVX2 when the CPU has it);
 *   tsm_result  per angle one (J-1)^3/6 Cholesky and refine_iters steps of
 *               ~25 np + 2 J^2 flops (~0.2 ms at J = 100), over the pool;
 *               then K J + one gridding FBP (K J kw^2 + g^2 log g).
 * Measured end to end (pipeline_run from a FITS cube, 100 frames of 200^2,
 * 17-hole binary, warm plans; CPU time, one thread / wall with 2 threads,
 * idle machine): K = 18 34 / 23 ms, K = 180 158 / 98 ms (it was 88 and
 * 302 ms); of which reading the FITS frames ~5 ms and prep ~5 ms.
 *
 * Not re-entrant: one handle per caller thread (it runs its own pool);
 * create handles from one thread (FFTW planner).
 */
#ifndef SL_TSM_H
#define SL_TSM_H

#include <stddef.h>

#include "spectra/closure.h"
#include "radon.h"
#include "status.h"
#include "base/tpool.h"

typedef enum tsm_variant { TSM_FOURIER = 0, TSM_SPATIAL = 1 } tsm_variant;

typedef enum tsm_weight {
    TSM_WEIGHT_MODULUS = 0, /* |B|: measured best (tsm.c, phase_inputs) */
    TSM_WEIGHT_SNR,      /* |B| / sqrt(<|P1|^2><|P2|^2><|P3|^2>) */
    TSM_WEIGHT_SNR2,     /* its square (inverse phase variance) */
    TSM_WEIGHT_UNIT      /* plain unit phasors */
} tsm_weight;

typedef enum tsm_apod {
    TSM_APOD_NONE = 0,
    TSM_APOD_HANN,       /* (1 + cos(pi u/J)) / 2 */
    TSM_APOD_COSINE      /* cos(pi u / 2J) */
} tsm_apod;

typedef enum tsm_bias {
    TSM_BIAS_AUTO = 0,   /* PHOTON if photons_per_frame > 0, else FLOOR */
    TSM_BIAS_NONE,
    TSM_BIAS_PHOTON,     /* needs photons_per_frame > 0 */
    TSM_BIAS_FLOOR
} tsm_bias;

typedef enum tsm_inverse {
    TSM_INV_AUTO = 0,    /* gridding FBP (Fourier), spatial FBP (spatial) */
    TSM_INV_FBP_GRID,
    TSM_INV_FBP_SPATIAL,
    TSM_INV_ITER         /* radon_invert_iter, non-negative */
} tsm_inverse;

typedef struct tsm_opts {
    int nangles;               /* 0: 180 */
    tsm_variant variant;
    int nproj;                 /* 0: even >= max(w, h) */
    double cutoff_cyc_px;      /* 0: 0.5 (Nyquist) */
    int r2_bins;               /* max u2; 0: unlimited */
    tsm_weight weight;
    int refine_iters;          /* exact-solver steps; < 0: none; 0: 10 */
    double arc_bins;           /* bispectrum averaged over angles within this
                                * arc; 0: 1.5 capped by the measured
                                * diameter (tsm_extent.c), < 0: off */
    double centroid_frac;      /* centroid of the part above this x max;
                                * 0: 0.05, < 0: positive part */
    double align_deg;          /* align to neighbours within; 0: 8, < 0: off */
    int reproj_iters;          /* alignment to the reprojected image (step
                                * 5); 0: 3, < 0: off */
    double reproj_frac;        /* its template: the image above this x max;
                                * 0: 0.2 */
    tsm_apod apod;
    tsm_bias bias;             /* see Bias above */
    double photons_per_frame;  /* > 0: photon statistics known */
    double read_noise_adu;     /* per pixel rms, for TSM_BIAS_PHOTON */
    int bispec_bias_phase;     /* 1: phases from the bias-corrected
                                * bispectrum too (0: raw, see tsm_result.c) */
    radon_window window;       /* FBP window */
    tsm_inverse inverse;
    int inv_iters;             /* TSM_INV_ITER iterations; 0: 40 */
    int batch;                 /* frames per accumulation block; 0: 8 */
    int threads;               /* 0: online CPUs, at most 4 (tpool.h); also
                                * the TSM_SPATIAL projector's (radon.h); the
                                * result is bit-identical for any count */
    double oversamp;           /* Fourier-slice grid; 0: radon default */
    int kernel_bins;           /* Fourier-slice kernel; 0: radon default */
    unsigned fftw_flags;       /* 0: FFTW_MEASURE */
} tsm_opts;

void tsm_opts_defaults(tsm_opts *o);   /* all zero = the defaults above */

typedef struct tsm tsm;

tsm *tsm_new(int w, int h, const tsm_opts *opts, sl_err *err);
void tsm_free(tsm *t);
const char *tsm_errmsg(const tsm *t);
/* Forget all frames (keeps plans and any reference). */
void tsm_reset(tsm *t);

int tsm_nangles(const tsm *t);
int tsm_nproj(const tsm *t);
int tsm_nfreq(const tsm *t);          /* J + 1 */
int tsm_npairs(const tsm *t);         /* bispectrum elements per angle */
int tsm_nframes(const tsm *t);

/* Add one w*h frame.  SL_EDATA on NaN/Inf. */
int tsm_add(tsm *t, const float *frame);
/* Steps 3-6 into img (w*h).  SL_EDATA without frames.  May be called
 * again after more tsm_add calls. */
int tsm_result(tsm *t, float *img);

/* Bias-corrected mean power spectra, nangles*nfreq doubles (u = 0..J). */
int tsm_power(tsm *t, double *ps);
/* The white-noise level L subtracted from the power (see Bias; 0 for
 * TSM_BIAS_NONE), per unit noise transfer: at angle a, u the bias is
 * L T(a, u). */
int tsm_noise_level(tsm *t, double *level);
/* Mean projections (nangles*nproj, band-limited to the cut-off): the
 * projections of the long-exposure image. */
int tsm_mean_projection(tsm *t, float *proj);
/* Bias-corrected mean bispectrum element at angle k; u2 <= u1. */
int tsm_bispectrum(tsm *t, int k, int u1, int u2, double *re, double *im);
/* A binary fitted to every angle's closure phases (closure.h, the 1-D
 * form), on the bias-corrected mean bispectrum, from each of nstart
 * starts init[] (binary_measure on the result, a fringe fit), the best
 * kept.  Allocates 16 bytes per stored pair for the corrected copy.
 * SL_EDATA when every start is an equal pair or fails, or too few strong
 * pairs. */
int tsm_binary(tsm *t, int nstart, const binary_result *init, binary_result *out,
               closure_fit_info *info);
/* Transfer-function calibration: ps_ref is a point source's tsm_power
 * (same geometry, same seeing statistics); ps_target (may be NULL) the
 * power of the PSF wanted in the result, e.g. tsm_power of the
 * diffraction-limited PSF.  The modulus becomes
 *     flux * sqrt(Pn Rn / (Rn^2 + wiener) * Tn)
 * with Pn, Rn, Tn the object's, reference's and target's power normalised
 * at u = 0 (Tn = 1 without a target: the result is then the object
 * itself, band-limited by the cut-off).  The regulariser is relative:
 * wiener times the median of Rn^2 over u >= 1, because Rn spans decades
 * with the seeing (its plateau is ~(r0/D)^2); 0.01..0.1 is typical.
 * ps_ref NULL removes both. */
int tsm_set_reference(tsm *t, const double *ps_ref, const double *ps_target,
                      double wiener);
/* After tsm_result: the recovered, centred projections (nangles*nproj,
 * s = i - nproj/2) and their 1-D phases (nangles*nfreq, radians). */
int tsm_projections(tsm *t, float *proj);
int tsm_phases(tsm *t, double *phase);

/* The arc step 3 used and the object diameter (px) it was capped by
 * (tsm_extent.c); both 0 before tsm_result or when the arc was given. */
void tsm_arc(const tsm *t, double *arc_bins, double *extent_px);

/* ---- the object's extent (tsm_extent.c), used by tsm_result -----------
 * tsm_extent_px: diameter in px from the mean power ps (nangles*nfreq,
 * bias-corrected): the largest autocorrelation lag above level x its
 * peak, over the angles (NAN: out of memory), on pool's threads (NULL:
 * the caller's; the same number on any).  tsm_arc_cap: the largest arc
 * (bins) that turns a feature extent_px away by <= 0.4 rad. */
double tsm_extent_px(const double *ps, int nang, int nf, int ns, double level, tpool *pool);
double tsm_arc_cap(double extent_px, int ns);

/* ---- the 1-D phases (tsm_phase.c), used by tsm_result -----------------
 * Pairs are stored row by row: for u1 = 1..J-1 the row holds u2 = 1..len
 * with len = min(u1, J - u1, r2), at index rowoff[u1] + u2 - 1. */
typedef struct tsm_phase tsm_phase;

tsm_phase *tsm_phase_new(int nangles, int nfreq, int r2, sl_err *err);
void tsm_phase_free(tsm_phase *p);
/* Run tsm_phase_inputs, tsm_phase_solve and tsm_phase_align_all on pool's
 * threads (NULL: the caller's alone): each thread claims angles as it
 * frees up and computes each whole with its own scratch, so the results
 * do not depend on the count.  The pool is kept by reference.  SL_ENOMEM. */
int tsm_phase_set_pool(tsm_phase *p, tpool *pool);
int tsm_phase_npairs(const tsm_phase *p);
const int *tsm_phase_rowoff(const tsm_phase *p);   /* nfreq entries */
const int *tsm_phase_rowlen(const tsm_phase *p);   /* nfreq entries */
/* Inputs: unit phasors exp(i beta) as (re, im) pairs, nangles*npairs*2
 * floats, and weights >= 0, nangles*npairs; filled by tsm_phase_inputs or
 * directly by the caller. */
float *tsm_phase_phasors(tsm_phase *p);
float *tsm_phase_weights(tsm_phase *p);
/* The inputs from bispectrum sums bre, bim (nangles*npairs) over nframes
 * frames and mean powers pm (nangles*nfreq: the SNR weights' model).
 * g > 0: Wirnitzer's photon bias removed with gain g, mean frame sum sbar
 * and pb (nangles*nfreq, the photon part of the mean power; NULL when
 * g = 0).  arc_bins > 0: each element averaged over the angles a +- k
 * whose lines pass within arc_bins of each other at its largest frequency
 * u3 (k = floor(arc_bins nangles / (pi u3)), at most nangles / 8; across
 * theta = 180 deg the line reverses, B conjugated); weights per
 * tsm_weight from the averaged B.  Cost: npairs per angle times the
 * window (~4.4 npairs at J = 100, 180 angles, 1.5 bins). */
void tsm_phase_inputs(tsm_phase *p, const double *bre, const double *bim, double nframes,
                      const double *pm, const double *pb, double g, double sbar,
                      tsm_weight weight, double arc_bins);
/* Phases (nangles*nfreq radians), phi(0) = phi(1) = 0: the recursion,
 * then `iters` steps of the exact (majorise-minimise) solver of
 * tsm_phase.c, each angle on its own. */
int tsm_phase_solve(tsm_phase *p, int iters, double *phase);
/* The unknown shift of each projection (step 5): centroid of the part of
 * projection p (ns samples, s = i - ns/2) above frac x its maximum; the
 * shift d (|d| <= range px) maximising C(d) = Re sum_j o(j) conj(ref(j))
 * exp(2 pi i j d / ns) over j = 1..nf-1 (scr: 2 nf doubles; cost ~ nf (4
 * range + 5)); and spectrum sp moved so that s = c goes to s = 0. */
double tsm_phase_centroid(const float *p, int ns, double frac);
double tsm_phase_align(const float complex *o, const float complex *ref, int nf, int ns,
                       double range, double *scr);
void tsm_phase_shift(float complex *sp, int nf, int ns, double c);
/* Every angle a of spec (nangles x nfreq) aligned to ref's angle a
 * (tsm_phase_align within range px) and shifted by it, on p's threads;
 * dsum (nangles floats, or NULL) gets each shift added. */
void tsm_phase_align_all(tsm_phase *p, float complex *spec, const float complex *ref, int ns,
                         double range, float *dsum);
/* Step 5's alignment to the reprojected image, on spectra spec (nangles of
 * rad x nf, s = 0 reference as above): up to iters rounds of gridding FBP
 * into img (npix pixels), template = the part above frac x its maximum,
 * its slices into tmpl (nangles x nf), every angle aligned to its slice
 * (tsm_phase_align_all on p's threads); all undone unless the FBP's
 * negative energy went down.  dsum: nangles floats (scratch). */
int tsm_phase_reproj(tsm_phase *p, radon *rad, float complex *spec, size_t npix, int iters,
                     double frac, float *img, float complex *tmpl, float *dsum);

/* The sums of steps (1)-(2) as flat doubles (the frame count among
 * them), for a sequence split over processes: tsm_partial writes them to buf
 * (NULL: none) and returns how many; tsm_partial_load replaces this handle's
 * with buf's (e.g. the element-wise sum over every part; same options on
 * every part, so the layouts agree). */
size_t tsm_partial(tsm *t, double *buf);
void tsm_partial_load(tsm *t, const double *buf);

#endif
