/* maskobs.h - an aperture mask's interferometric observables: squared
 * visibilities per baseline and closure phases per hole triangle, measured
 * on speckle frames one at a time (what OIFITS carries: io/oifits.h).
 *
 * Geometry.  Holes at (x_m, y_m) in the mask's frame (sim/mask.h) form
 * baselines b = c_j - c_i (i < j).  With a plate scale s (rad/px) and
 * wavelength lambda, baseline b falls at the frame's spatial frequency
 * b s / lambda cycles/px, +x_m along the image's +x as the simulator's
 * propagation has it (sim.h): FFT index p = b_x s w / lambda, q = b_y s h /
 * lambda on a w x h frame (square pixels).  The image's -x is east, so on
 * the sky the baseline is (east, north) = (-b_x, b_y): a hole's sky
 * position is (-x_m, y_m).  With the FFT's sign the complex visibility at
 * index (p, q) is the OIFITS one at (u, v) = (-p / w, q / h) / s rad^-1,
 * V(u, v) = sum I(alpha, beta) exp(-2 pi i (u alpha + v beta)), alpha east.
 *
 * Where each observable is sampled.  The splodge of baseline b is the
 * disk |u - b| < d (d the hole diameter, in pupil metres); there the
 * mask's own transfer is the overlap of two holes offset by u - b, over
 * nholes hole areas (1/nholes at the centre, DC normalised to 1).  A
 * baseline is sampled at ONE FFT pixel, and its uv is that pixel's exact
 * frequency: a sum over the splodge would average V over a patch in which
 * a 0.2 arcsec binary's phase turns by ~1 rad at 128^2 Nyquist (the
 * splodge radius is 0.045 cycles/px there), so closure phases from it
 * would not be those of any uv point a model could be evaluated at.  The
 * pixel is the one with the largest own transfer among the CLEAN ones:
 * where the other baselines' splodges (both signs, DC, and their aliases
 * when the frame undersamples the mask) add less than clean_max of the
 * own transfer.  Redundant masks need this: nrm17 has 60 baseline pairs
 * closer than d, whose splodges overlap and mix two turbulent phases.  A
 * triangle (i, j, k) takes u1 in b_ij's splodge, u2 in b_jk's and u3 = u1
 * + u2, which must be clean in b_ik's (so the three legs close exactly on
 * the FFT grid and the atmosphere's piston phases cancel); among those
 * the largest product of the three transfers wins.  Pixels whose own
 * transfer is below MASKOBS_MIN_TRANSFER of the splodge's peak are never
 * used; a baseline or triangle with no clean pixel is not measured
 * (maskobs_result counts them).  The Nyquist row and column are never
 * used (real data have no phase there).
 *
 * Estimators (per frame k, F the frame's FFT, F0 = F(0) its flux, g ADU
 * per photon, rn the read noise in ADU, npix pixels):
 *   V2_k = (|F(u)|^2 - g F0 - npix rn^2) / (F0^2 - g F0) / T(u)^2
 * where T is the mask's transfer at u, so a point source through a
 * cophased mask reads 1; turbulence, the pixels' response and optics
 * lower it (a calibrator's V2 divides them out: these are raw).  Without
 * photon statistics (g = 0) the bias is left in.  VIS2 = mean of V2_k,
 * VIS2ERR = their standard error of the mean.
 *   B_k = [F(u1) F(u2) conj F(u3) - g (|F1|^2 + |F2|^2 + |F3|^2) + 2 g^2 F0]
 *         / F0^3
 * (Wirnitzer's unbiased triple product for photon counts), T3 = mean B_k
 * / (T1 T2 T3), T3PHI = arg mean B_k (the sign of closure.h's arg B: the
 * closure phases of the same frequencies agree with its fit), T3AMP =
 * |T3|.  Frames with F0 <= 0 are skipped.
 *
 * Errors: from the frames' scatter, the standard error of the mean (for
 * T3 of the components perpendicular to the mean, over |mean|: the phase
 * in rad, and parallel to it: the amplitude), times a correlation factor.
 * Consecutive frames see the same frozen screen: on a point source
 * through nrm17 (128^2, 1e5 photons, 10 m/s, 10 ms) the frames' standard
 * errors gave closure phases a chi^2/n of 2.97 over 100 frames and 1.71
 * over 400, 0.77 with piston-only phases (the screen's slope across each
 * hole is what varies slowly).  So the frames are also averaged in blocks
 * of block_frames, and each row's variance of the block means times the
 * block length over its frames' variance (1 for independent frames) is
 * pooled over the rows by its median: the factor (>= 1) on every row's
 * variance, V2, T3 phase and T3 amplitude separately.  It needs 4 whole
 * blocks, else it is 1 (maskobs_result says which).  Measured on that
 * point source: over 400 frames chi^2/n 1.0-1.2 for blocks of 10-50
 * (factors 1.5-1.9); over 100 frames (one crossing of the pupil) 2.4 with
 * a factor of only 1.25: the slowest part can be neither averaged nor
 * measured in so short a sequence, and the errors stay ~1.5x small.
 *
 * Cost.  maskobs_new: the selection, O(splodge pixels x nearby splodges)
 * per baseline plus a bounded search per triangle (nrm17 at Nyquist: 18
 * ms at 128^2, 45 ms at 256^2, 0.8 s at 1024^2), and one FFTW r2c plan.
 * maskobs_add: one r2c FFT of w x h and ~3 complex reads per triangle, no
 * allocation (0.06 ms at 128^2, 11 ms at 1024^2).  Memory: the plan's
 * buffers (w h floats, h (w/2+1) complex) and ~100 bytes per triangle. */
#ifndef SL_MASKOBS_H
#define SL_MASKOBS_H

#include "status.h"

#define MASKOBS_CLEAN_MAX 0.01      /* other splodges / own transfer */
#define MASKOBS_MIN_TRANSFER 0.15   /* of the splodge's peak (1/nholes) */
#define MASKOBS_BLOCK 10            /* frames per block (Errors) */

typedef struct maskobs_opts {
    double wavelength_m;
    double plate_scale_arcsec; /* arcsec per pixel (x = y pitch) */
    double adu_per_photon;     /* > 0: remove the photon bias; 0: keep it */
    double read_noise_adu;     /* per pixel, with adu_per_photon > 0 */
    double clean_max;          /* <= 0: MASKOBS_CLEAN_MAX */
    int block_frames;          /* <= 0: MASKOBS_BLOCK */
    int measure;               /* 1: FFTW_MEASURE, 0: FFTW_ESTIMATE */
} maskobs_opts;

void maskobs_opts_defaults(maskobs_opts *o); /* 500 nm, NAN plate scale,
                                               no photons, MEASURE */

/* One baseline's squared visibility.  sta: hole indices, i < j. */
typedef struct maskobs_vis2 {
    int sta[2];
    int p, q;              /* frequency sampled, FFT index (may exceed
                            * the frame's Nyquist when it undersamples) */
    double u_m, v_m;       /* projected baseline east, north [m] */
    double transfer;       /* the mask's transfer there, DC = 1 */
    double vis2, vis2_err;
} maskobs_vis2;

/* One hole triangle's triple product: legs u1 (sta[0] -> sta[1]), u2
 * (sta[1] -> sta[2]) and u1 + u2, as OIFITS's OI_T3. */
typedef struct maskobs_t3 {
    int sta[3];
    int p1, q1, p2, q2;
    double u1_m, v1_m, u2_m, v2_m;
    double amp, amp_err, phi_deg, phi_err_deg;
} maskobs_t3;

typedef struct maskobs_result {
    int nholes, nframes, nskipped; /* frames used, frames with F0 <= 0 */
    int nvis2, nt3;
    int nvis2_lost, nt3_lost;      /* baselines, triangles without a clean
                                    * pixel: not measured */
    int nblocks;                   /* whole blocks of block_frames */
    double corr_vis2, corr_phi, corr_amp; /* variance factors (Errors);
                                    * 1 below 4 blocks */
    maskobs_vis2 *vis2;
    maskobs_t3 *t3;
} maskobs_result;

typedef struct maskobs maskobs;

/* Plan the sampling of nholes holes of hole_diameter_m at (x_m, y_m) on w
 * x h frames.  NULL with err set: SL_EINVAL (fewer than 3 holes, a frame
 * below 8 x 8, a wavelength or plate scale that is not finite and > 0),
 * SL_EDATA (no triangle can be sampled: every splodge is covered or
 * beyond what the frame holds), SL_ENOMEM. */
maskobs *maskobs_new(const double *x_m, const double *y_m, int nholes,
                     double hole_diameter_m, int w, int h,
                     const maskobs_opts *o, sl_err *err);
void maskobs_free(maskobs *m);
const char *maskobs_errmsg(const maskobs *m);

/* Accumulate one frame (w*h floats).  SL_EDATA on a NaN/Inf pixel. */
int maskobs_add(maskobs *m, const float *frame);
/* Averages and errors so far into out (owned by the caller: free with
 * maskobs_result_clear).  SL_EDATA before two usable frames. */
int maskobs_result_get(maskobs *m, maskobs_result *out);
void maskobs_result_clear(maskobs_result *r);

#endif
