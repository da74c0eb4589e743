/* binary.h - binary-star astrometry and photometry on an image, by a model
 * fit that needs no PSF model.
 *
 * Conventions (see seq.h): pixel (x, y) is img[y*w + x]; +y north, -x east;
 * position angles run from +y towards -x.
 *
 * Model.  img = PSF (*) (F1 delta(x1) + F2 delta(x2)) + background, the PSF
 * unknown but centro-symmetric with a non-negative transfer function P
 * (real by symmetry).  With r = F2/F1 and d = x2 - x1 the spectrum is
 *     I(u) = F1 P(u) e^{-i k.x1} g(u),   g(u) = 1 + r e^{-i k.d},
 * so z(u) = I(u) e^{+i k.x1} conj(g(u)) = F1 P |g|^2 is real and >= 0:
 * its phase phi(u) is zero at every frequency.  The fit minimises
 *     sum_u (2 |I(u)| sin(phi(u)/2))^2
 * over (x1, d, ln r) by Levenberg-Marquardt in double precision, on one
 * half plane of the frequencies whose |I| is over 3 noise sigmas.  Near the
 * solution a term is |I| phi, the component of I's noise perpendicular to
 * the model: white noise makes all terms equally uncertain, so unit
 * weights are the maximum-likelihood ones.  This is exact for any
 * symmetric PSF however much the two images overlap and however strong
 * the sidelobes (a 17-hole mask's reach ~20% of the peak): on the
 * simulator's cophased images (FFT-made, so periodic) sep, PA and dm come
 * out to float rounding, ~1e-7.  Four odd cubic terms of the transfer
 * function's phase are fitted too (binary_fit.h): a reconstruction keeps
 * such a smooth asymmetry, which a real P cannot absorb; a cophased image
 * fits them at zero.
 *
 * Why P >= 0 and not only P real.  With P merely real only phi mod pi is
 * constrained, and at r = 1 nothing fixes d: an equal pair convolved with
 * a symmetric PSF is itself symmetric about its midpoint, so any d with
 * the right midpoint fits.  P >= 0 holds for every cophased image (the OTF
 * is the autocorrelation of a non-negative pupil) and for speckle
 * reconstructions (moduli from a power spectrum); it makes the sign flips
 * of g carry d, but only where they cross a frequency with signal.
 *
 * Identifiability.  (x1, d, r) and (x1 + d, -d, 1/r) are the same model;
 * the result is always stated with r <= 1 (companion = fainter).  As r ->
 * 1 the fit loses d (its error grows as 1/(1 - r)), so d is taken from the
 * interpolated peaks when that is expected to be better (below); when r
 * is within 2 sigma of 1 (or 1e-6), which star is brighter is unknown, the
 * PA may be off by 180 deg, and pa_ambiguous is set.  The binary must be
 * resolved: the companion is sought beyond the core's first minimum + 1
 * px.
 *
 * Candidates.  x1 starts at the brightest pixel; companion candidates are
 * the brightest local maxima outside the core and the maxima of the
 * antisymmetric part about x1, I(x1 + x) - I(x1 - x) = F2 (PSF(x - d) -
 * PSF(x + d)), where the primary and all its sidelobes cancel.  Each gets
 * a short fit; the brightest maximum's is kept unless another fits
 * clearly better (binary.c: choose).  The winner is fitted to convergence.
 *
 * d: fit or peaks.  The fit is unbiased but pays for not knowing the PSF:
 * its d is noisier than the interpolated peaks' (measured at 5 lambda/D,
 * white noise 1% of the peak per pixel: sep scatter 0.074 px at dm 1, 0.18
 * px at dm 0.3, against 0.027 and 0.02 px for the peaks), while the
 * peaks are biased by the other star's wing (its gradient over the core's
 * curvature: up to 0.14 px through the mask).  That bias is measured on
 * the fitted model itself (the data projected on the model's phases is a
 * symmetric-PSF binary at the fitted positions), and d comes from
 * whichever has the smaller expected squared error: fit covariance
 * against peak noise + bias^2.  Noiseless images always take the fit
 * (d_from_peaks = 0) unless r ~ 1; the midpoint always comes from the fit.
 *
 * Uncertainties.  Fit: the Gauss-Newton covariance (J^T J)^-1 scaled by
 * the residual variance cost / (m - 9), so misfit from anything the model
 * does not describe (noise, phase errors, artefacts) counts, but as if
 * independent between frequencies.  A reconstruction's artefacts are
 * not: they sit in a few hundred pixels around the object, so the stated
 * errors take the sandwich covariance A^-1 (J^T Sigma J) A^-1 with Sigma
 * modelled from the residual image's local power (binary.c,
 * residual_cov), never below the independent ones (err_inflation: the
 * factor on the separation's variance).  On white noise confined to a
 * 3 px envelope (test_binary) the independent errors are 7.4x too small,
 * these 1.8x.  Measured on the 200^2 bench binaries (noiseless, 100
 * frames, direct): at 5 lambda/D, dm 2 (4 seeds) the stated sep error
 * went 0.008-0.015 -> 0.043-0.055 px against errors of 0.024-0.081 px (rms
 * error/sigma 1.1), dm 0.008-0.013 -> 0.036-0.043 against 0.03-0.11 (the
 * dm errors there also carry a +0.06 bias); at 15-20 lambda/D the factor
 * is 1-2 and the errors (0.008-0.013 px) cover the measured ones.  Peaks:
 * the gradient noise of the band-limited interpolant, with the same
 * residual variance (or the noise, if larger), plus the squared bias
 * unless r ~ 1, scaled like the fit's.  On white noise the scatter
 * matches them (rms error/sigma 0.9-1.2 in test_binary, factor ~1).
 * Noiseless images give errors at rounding level; at r ~ 1 they exclude
 * the peaks' wing bias.  Systematic errors of a reconstruction (TSM's
 * photon-biased dm, its PA at 5 lambda/D) are not in them.
 *
 * Limits.  A reconstruction's transfer function is only symmetric if its
 * phases are right.  Phases that are systematically shrunk towards the
 * symmetric (zero closure phase) solution make r come out low: TSM's raw
 * bispectrum at 1000 photons reads a dm 1 companion as dm 1.5-2.0 (tsm.h,
 * Bias).  Random phase errors turn the mask's bright sidelobes
 * asymmetric, which the fit can take for a faint companion (a dm 2.5-3.5
 * "companion" 7-8 px from a reconstructed point source, README).  The
 * direct bispectrum's own triples measure a binary better than its image
 * does: closure.h fits them, starting from this fit.
 *
 * binary_plan holds double-precision FFTW plans (FFTW_ESTIMATE: one
 * measurement per image, measuring plans would cost more) and every
 * buffer, so measuring allocates nothing.  Cost: two real FFTs of w x h,
 * ~8 candidate fits of 12 Levenberg-Marquardt steps, each O(m), m <= wh/2
 * kept frequencies.  FFTW's planner is not thread-safe: create plans from
 * one thread.
 */
#ifndef SL_BINARY_H
#define SL_BINARY_H

#include "status.h"

/* A binary star measured on an image.  The companion is the fainter
 * component; dx_px, dy_px are its offset from the brighter one, sep_px =
 * hypot(dx, dy), pa_deg = atan2(-dx, dy) in degrees in [0, 360).
 * flux_ratio = F2/F1 <= 1, dm_mag = -2.5 log10(flux_ratio) >= 0.  The
 * *_err fields are 1-sigma estimates (see above). */
typedef struct binary_result {
    double x1_px, y1_px;     /* brighter component */
    double x2_px, y2_px;     /* fainter component */
    double dx_px, dy_px;
    double sep_px, pa_deg, flux_ratio, dm_mag;
    double sep_err_px, pa_err_deg, flux_ratio_err, dm_err_mag;
    double background;       /* median of the image */
    double noise;            /* white pixel noise, from the spectrum beyond
                                0.5 cycle/px (empty at Nyquist sampling) */
    double fit_rms;          /* rms fit residual over the noise's: ~1 when
                                only noise is left (NAN without noise) */
    int nfreq;               /* frequencies fitted */
    double err_inflation;    /* factor >= 1 on the separation's variance
                                for residuals correlated between
                                frequencies (see Uncertainties; 1: white) */
    int pa_ambiguous;        /* r within 2 sigma of 1: PA +- 180 deg */
    int d_from_peaks;        /* d from the interpolated peaks, not the fit */
    int core_radius_px;      /* the primary's core: a companion within
                                core + 1 px cannot be told from it here */
} binary_result;

typedef struct binary_plan binary_plan;

/* SL_EINVAL (in err) below 8 x 8, SL_ENOMEM. */
binary_plan *binary_plan_new(int w, int h, sl_err *err);
void binary_plan_free(binary_plan *p);
const char *binary_errmsg(const binary_plan *p);

/* Measure the binary in img (w x h of the plan).  SL_EDATA when a pixel is
 * not finite (named), when there is no signal or no second component
 * beyond the core, or when the fitted companion is not significant (r <
 * 3 sigma_r or dm > 10); out is then partly filled. */
int binary_plan_measure(binary_plan *p, const float *img, binary_result *out);
/* The same with a temporary plan; err may be NULL. */
int binary_measure(const float *img, int w, int h, binary_result *out,
                   sl_err *err);

#endif
