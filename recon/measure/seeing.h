/* seeing.h - the seeing of a run, measured from its own frames.
 *
 * Estimator: image motion.  The intensity centroid of a short exposure is
 * the pupil-averaged wavefront gradient (G-tilt), for a filled pupil and
 * for a hole mask alike.  For Kolmogorov turbulence (infinite outer scale)
 * over a circular pupil of diameter D its ensemble variance per axis is
 *     sigma^2 = 0.1698 (lambda / D)^2 (D / r0)^(5/3)   [rad^2]
 * (pi^(2/3) 0.0228956 int x^(-2/3) (2 J1(x) / x)^2 dx, with the constant of
 * sim/screen.h; Tyler's "0.170"), so r0 = D (0.1698 (lambda/D)^2 /
 * sigma^2)^(3/5).  Both axes are averaged.  A hole mask's G-tilt is the
 * mean of its holes' tilts: for nrm17 (17 holes of 0.1 m in 1.079 m) its
 * variance is 0.993 times the filled disk's of the same extent (from the
 * holes' separations and the structure function below), so D is the
 * mask's outer extent and the r0 is the pupil's to 0.5 %.
 *
 * Frozen flow.  A run does not sample that ensemble variance: its frames
 * are one stretch of screen moved u D per frame, and the variance about
 * the run's own mean misses every tilt slower than the run.  Kolmogorov
 * tilt has much power there (its covariance falls only as (s/D)^(-1/3)):
 * 100 frames 0.46 D apart keep 65 % of sigma^2 (1000 frames: 84 %), and
 * the plain variance read r0 1.36x high on the demo's geometry.
 * The expected fraction kept is, exactly for any wind direction,
 *     K(u, n) = 2/n^2 sum_{l=1}^{n-1} (n - l) delta(l u),
 * with delta(s/D) = D_tilt(s) / (2 sigma^2) the G-tilt structure function
 * of a disk averaged over the two axes (seeing_tilt_structure).  u is not
 * known to the daemon (the screen's speed is not configured), so it is
 * read from the run: the mean squared frame-to-frame step S1 over the
 * variance V has expectation 2 delta(u) / K(u, n), increasing in u; that
 * is solved for u, and sigma^2 = V / K(u, n).  u is clamped to [0.001,
 * 1e6] (a still or an independent-frame sequence).
 *
 * Accuracy, demo geometry (nrm17, 128^2 at Nyquist, 633 nm, 100 frames,
 * 0.5 m per frame, 1e4 photons), 150 simulated runs at r0 = 0.18 m through
 * the frames: r0 reads 1.075x on average (median 1.06x; the old plain
 * variance 1.36x; 1.06x for the filled pupil, 100 runs), with a run-to-run
 * scatter of 17 % (1 sigma) that no image-motion estimator of 100 such
 * frames avoids: the run holds ~40 independent samples of the tilt (even
 * the phase the simulator rendered over one run, measured directly by its
 * structure function at 0.07 m, scatters 6 % about the screen's r0).  The
 * bias: ~3 % is the skew of a variance of ~40 samples through r0 ~
 * V^(-3/5) (the G-tilt of the rendered phase with the true u: 1.04x mean,
 * 1.03x median over 400 runs); reading u from the run adds ~1.5 % for
 * nrm17 (its holes decorrelate faster than a disk at shifts below D, so u
 * reads 0.55-0.6 for 0.46), nothing for the filled pupil; the centroids
 * add nothing measurable (1.075x against 1.086x from the phase's own
 * G-tilt on the same 150 runs), though photon and read noise through the
 * threshold put 0.08-0.44 px^2 of white noise per axis on them.
 * Not modelled: a finite outer scale (real turbulence, L0 ~ 20 m, has less
 * tilt, so tilt reads r0 high: the figure is the Kolmogorov r0 with the
 * run's tilt), and frames that are not one evenly moving stretch.
 *
 * Error: r0_err_m = 0.6 r0 sqrt(var log sigma^2), from n_eff (the
 * independent samples of V for the model at the estimated u: tr(B)^2 /
 * tr(B^2) per axis, B the run's centred tilt covariance, both axes) and
 * the spread u adds (seeing.c).  It reads 14 % for the demo geometry
 * against the 17 % measured: 60 / 91 / 97 % of runs fall within 1 / 2 / 3
 * of it.
 *
 * Wavelength: r0 and the seeing FWHM are at wavelength_m, the wavelength
 * given to seeing_new (r0 scales as lambda^(6/5)); the result repeats it.
 * Centroids use pixels above the frame median (background removed), so
 * a bias or sky level does not pull them to the frame centre.
 * Cost: seeing_add O(pixels) per frame, no allocation after seeing_new;
 * seeing_result_get ~50 n structure-function evaluations (0.13 ms for 100
 * frames, 15 ms for 10^4), no allocation.
 */
#ifndef SL_SEEING_H
#define SL_SEEING_H

#include "status.h"

typedef struct seeing seeing;

typedef struct seeing_result {
    int nframes;               /* frames with flux */
    double wavelength_m;       /* r0 and FWHM are at this wavelength */
    double tilt_rms_arcsec;    /* one-axis centroid rms about the run mean */
    double r0_m;               /* at wavelength_m */
    double r0_err_m;           /* 1-sigma, from n_eff */
    double seeing_fwhm_arcsec; /* 0.98 lambda / r0 */
    double n_eff;              /* independent samples of the variance */
    double shift_d;            /* u: frozen-flow shift per frame / D */
    double tilt_kept;          /* K(u, n): variance kept about the mean */
} seeing_result;

int seeing_new(seeing **out, int w, int h, double plate_scale_arcsec,
               double wavelength_m, double pupil_diameter_m, sl_err *err);
void seeing_free(seeing *s);
/* Add one frame (w*h).  Frames without positive flux are skipped.  Frames
 * are taken as consecutive, evenly spaced in time. */
int seeing_add(seeing *s, const float *frame);
/* SL_EDATA with fewer than 3 usable frames or no motion. */
int seeing_result_get(const seeing *s, seeing_result *r);

/* delta(x) = D_tilt(x D) / (2 sigma^2): the one-axis G-tilt structure
 * function of a disk of diameter D in Kolmogorov turbulence, averaged over
 * the axes along and across the shift, at shift x D: (1/I) int t^(-2/3)
 * (2 J1(t)/t)^2 (1 - J0(2 x t)) dt, I = 3.457494.  0 at x <= 0, ~0.74 x^2
 * below x = 0.01 (1 % at 0.005), tabulated every 1/16 decade on [0.01, 10]
 * and interpolated log-log (within 0.25 %), 1 - 0.713124 x^(-1/3) beyond
 * (within 4e-5). */
double seeing_tilt_structure(double x);

#endif
