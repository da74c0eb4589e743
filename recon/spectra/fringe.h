/* fringe.h - a binary star fitted to the fringes of a speckle power
 * spectrum (Labeyrie's speckle interferometry), needing no image.
 *
 * Why.  The image fit (binary.h) needs the companion resolved from the
 * primary's core, and the closure fit (closure.h) needs a start within a
 * few pixels.  A pair at about lambda/D, or one seen through few frames of
 * a real camera, gives neither, yet its power spectrum carries the
 * fringes |V(u)|^2 = 1 + r^2 + 2 r cos(2 pi u.d) plainly.
 * Model.  The mean power spectrum is P(u) = T(|u|) |V(u)|^2 with T the
 * speckle transfer function, isotropic for a filled (or any circular)
 * pupil and isotropic turbulence.  Dividing P by its mean over each
 * annulus removes T, so with c = 2 r / (1 + r^2)
 *     Q(u) = P(u) / <P>_ring = (1 + c cos(2 pi u.d)) / (1 + c <cos>_ring)
 * depends on d (up to its sign: the power spectrum is symmetric) and c
 * alone.  An aperture mask's transfer function is not isotropic (its
 * splodges), so the fit is only meaningful for filled pupils: a spectrum
 * whose well-measured rings are dark (below a tenth of the ring's mean)
 * over FRINGE_MAX_DARK of their samples is a mask's, and no companion is
 * detected in it.
 * Fit.  Weighted least squares over the half plane of frequencies from 2
 * bins to the cut-off, weights N P^2 / (P + noise)^2 / Q^2 (speckle
 * statistics: the relative error of a mean of N exponential variables,
 * plus white noise).  A grid over d in steps of 0.5 px (half plane, 0.5
 * px to max_sep) with c solved linearly at each point, then
 * Levenberg-Marquardt on (dx, dy, c).  Errors: the Gauss-Newton
 * covariance scaled by the reduced chi^2 (turbulence makes neighbouring
 * frequencies correlated; the scaling keeps the errors honest about it).
 * Detection.  significance = (chi^2 without companion - chi^2 of the fit)
 * / reduced chi^2; a companion is detected above FRINGE_DETECT, and only
 * when the model explains the anisotropy (reduced chi^2 below
 * FRINGE_MAX_CHI2): an aperture mask's splodges leave it at 40 or more.
 * The pixels' own transfer function, sinc^2(kx) sinc^2(ky), is anisotropic
 * and divided out first.
 * Limits.  d and -d fit equally: the PA is known modulo 180 deg (the
 * bispectrum's phases decide).  At separations below lambda/D the fringe
 * is a quadrupole whose amplitude is c |d|^2: sep and dm trade off and
 * their errors say so.
 * Cost: the grid is 8 max_sep^2 points, each one pass over the samples
 * (a complex multiply-add per sample, phasors stepped along x); on 128^2
 * with max_sep 16 about 20 ms.  On frames over 16 max_sep px the grid
 * passes over every m-th frequency along each axis, m = L / (8 max_sep),
 * at least 8 per fringe of the largest separation (1024^2: 5.5 s ->
 * ~0.1 s); the fit that follows uses every one.  Allocates 7 doubles per
 * sample (and per sample of the grid's share).
 */
#ifndef SL_FRINGE_H
#define SL_FRINGE_H

#include "status.h"

#define FRINGE_DETECT 50.0
#define FRINGE_MAX_CHI2 4.0
#define FRINGE_MAX_DARK 0.3

typedef struct fringe_result {
    double dx_px, dy_px;      /* d with dy > 0 (or dy = 0, dx > 0); -d fits
                               * equally */
    double sep_px, pa_deg;    /* pa_deg of d in [0, 180); or + 180 */
    double contrast;          /* c = 2 r / (1 + r^2) */
    double flux_ratio, dm_mag;/* r <= 1 and -2.5 log10 r */
    double sep_err_px, pa_err_deg, dm_err_mag;
    double significance;      /* see above */
    double chi2_red;          /* reduced chi^2 of the fit */
    int nsamples;
    double dark_fraction;     /* well-measured samples below 0.1 x their
                               * ring's mean */
    int detected;             /* significance > FRINGE_DETECT, chi2_red <
                               * FRINGE_MAX_CHI2, dark_fraction <
                               * FRINGE_MAX_DARK */
} fringe_result;

/* Fit the 2-D mean power spectrum ps (w x h, FFT order, white-noise bias
 * subtracted; noise: the bias that was subtracted, per frame) of nframes
 * frames, over radii 2 .. rcut_px frequency bins, for separations 0.5 ..
 * max_sep_px.  SL_EDATA with fewer than 32 usable frequencies, SL_ENOMEM. */
int fringe_fit_2d(const double *ps, int w, int h, double noise,
                  double nframes, double rcut_px, double max_sep_px,
                  fringe_result *out, sl_err *err);

/* The same on polar samples, TSM's projection power spectra (tsm_power's
 * layout): nang angles theta_a = a 180/nang deg from +x towards +y, nf
 * frequencies j/nproj cycles/px, ps[a * nf + j]; radii 2 .. nf - 1. */
int fringe_fit_polar(const double *ps, int nang, int nf, int nproj,
                     double noise, double nframes, double max_sep_px,
                     fringe_result *out, sl_err *err);

#endif
