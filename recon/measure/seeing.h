/* seeing.h - the seeing of a run, measured from its own frames.
 *
 * Estimator: image motion.  The centroid of a short exposure moves with
 * the wavefront tilt averaged over the pupil (G-tilt).  For Kolmogorov
 * turbulence over a circular pupil of diameter D the one-axis variance is
 *     sigma^2 = 0.170 (lambda / D)^2 (D / r0)^(5/3)   [rad^2],
 * so r0 = D (0.170 (lambda/D)^2 / sigma^2)^(3/5).  Both axes are averaged.
 * It needs no knowledge of the object (its centroid is fixed) and works
 * through any pupil; for a sparse aperture mask, D is the mask's outer
 * extent and the estimate is an effective r0 (holes average the tilt less
 * than a filled pupil does, which biases r0 low by a factor that depends
 * only on the mask): runs through the SAME mask compare exactly, which is
 * what screen characterisation needs.  Frames are correlated by frozen
 * flow (the screen moves v dt per frame), so the variance of 100 frames
 * carries ~ D / (v dt) fewer independent samples: the relative error of
 * r0 is reported as 0.6 * sqrt(2 / n_eff) with n_eff estimated from the
 * lag-1 autocorrelation of the centroid series.
 * Centroids use pixels above the frame median (background removed), so
 * a bias or sky level does not pull them to the frame centre.
 * Cost: O(pixels) per frame, one pass, no allocation after seeing_new.
 */
#ifndef SL_SEEING_H
#define SL_SEEING_H

#include "base/status.h"

typedef struct seeing seeing;

typedef struct seeing_result {
    int nframes;               /* frames with flux */
    double tilt_rms_arcsec;    /* one-axis centroid rms */
    double r0_m;               /* at wavelength_m */
    double r0_err_m;           /* 1-sigma, from n_eff */
    double seeing_fwhm_arcsec; /* 0.98 lambda / r0 */
    double n_eff;              /* independent samples estimated */
} seeing_result;

int seeing_new(seeing **out, int w, int h, double plate_scale_arcsec,
               double wavelength_m, double pupil_diameter_m, sl_err *err);
void seeing_free(seeing *s);
/* Add one frame (w*h).  Frames without positive flux are skipped. */
int seeing_add(seeing *s, const float *frame);
/* SL_EDATA with fewer than 3 usable frames. */
int seeing_result_get(const seeing *s, seeing_result *r);

#endif
