/* metrics.h - how good is a reconstruction: correlation, registration and
 * binary-star astrometry.
 *
 * Conventions (see seq.h): pixel (x, y) is img[y*w + x]; +y north, -x east;
 * position angles run from +y towards -x.  Shifts are in pixels with the
 * meaning "b is a moved by (+dx, +dy)": b(x, y) = a(x - dx, y - dy).
 *
 * metrics_plan holds double-precision FFTW plans and buffers for one image
 * size (FFTW_ESTIMATE: these functions run once per reconstruction, so
 * measuring plans would cost more than it saves).  FFTW's planner is not
 * thread-safe: create plans from one thread; executing them is safe.
 */
#ifndef SL_METRICS_H
#define SL_METRICS_H

#include "status.h"

/* The paper's correlation coefficient c (Surya & Saha, eq. 14): Pearson's r
 * over all w*h pixels, computed in double.  Returns 0 when either image is
 * constant (c is undefined there). */
double metrics_corr(const float *a, const float *b, int w, int h);

typedef struct metrics_plan metrics_plan;

metrics_plan *metrics_plan_new(int w, int h, sl_err *err);
void metrics_plan_free(metrics_plan *p);
const char *metrics_errmsg(const metrics_plan *p);

/* Sub-pixel shift of b relative to a, b(x) ~ a(x - d).  The integer peak of
 * the FFT cross-correlation is refined by Newton's method on the
 * band-limited (Fourier-interpolated) cross-correlation itself, so the
 * result has no pixel-phase bias (parabolic fits do).  Images are treated
 * as periodic.  reg (w*h, may be NULL, may not alias a or b) receives b
 * moved by -d with a Fourier phase ramp, i.e. registered onto a. */
int metrics_register(metrics_plan *p, const float *a, const float *b,
                     float *reg, double *dx_px, double *dy_px);
/* c between a and b registered onto a (and the shift found). */
int metrics_plan_corr_registered(metrics_plan *p, const float *a,
                                 const float *b, double *c, double *dx_px,
                                 double *dy_px);
/* The same with a temporary plan (convenience for one-off use). */
int metrics_corr_registered(const float *a, const float *b, int w, int h,
                            double *c, double *dx_px, double *dy_px);

/* A binary star measured on a reconstructed image.  The companion is the
 * fainter component; dx_px, dy_px are its offset from the brighter one,
 * sep_px = hypot(dx, dy), pa_deg = atan2(-dx, dy) in degrees mapped to
 * [0, 360): no 180-degree ambiguity because the image carries phases.
 * flux_ratio = F2/F1 <= 1, dm_mag = -2.5 log10(flux_ratio) >= 0.  The
 * *_err fields are 1-sigma estimates (see metrics_binary). */
typedef struct binary_result {
    double x1_px, y1_px;     /* brighter component */
    double x2_px, y2_px;     /* fainter component */
    double dx_px, dy_px;
    double sep_px, pa_deg, flux_ratio, dm_mag;
    double sep_err_px, pa_err_deg, flux_ratio_err, dm_err_mag;
    double background;       /* median of the image, subtracted */
    double noise;            /* robust pixel noise away from the stars */
} binary_result;

/* Method: both components share one PSF shape (the image is object x
 * one transfer function), so with a symmetric PSF
 *  - each position is the maximum of the band-limited interpolant of the
 *    image (Newton on its Fourier series): exact for a symmetric core,
 *    whatever the pixel phase; the other component's wing biases it by
 *    (its gradient)/(core curvature), ~0.005 px at 5 lambda/D, dm = 2;
 *  - flux_ratio is the ratio of the interpolated peak heights above the
 *    median background (same shape => same peak-to-flux factor).
 * Candidates: the brighter is the brightest pixel; the fainter the
 * brightest local maximum outside the bright core's first minimum (radial
 * profile), so sidelobes brighter than the companion (sparse masks,
 * reconstruction artefacts) can be taken for it: check sep and dm.
 * Errors: noise = 1.4826 MAD of pixels outside both cores; white noise of
 * that level gives the interpolant's gradient a variance noise^2*pi^2/3,
 * so a position scatters by that over the core curvature (Hessian); peak
 * heights scatter by noise.  Correlated artefacts make these lower bounds.
 * Returns SL_EDATA when no second component is found. */
int metrics_plan_binary(metrics_plan *p, const float *img,
                        binary_result *out);
int metrics_binary(const float *img, int w, int h, binary_result *out);

#endif
