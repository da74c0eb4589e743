/* metrics.h - how good is a reconstruction: correlation, registration and
 * (through binary.h) binary-star astrometry.
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

#include "binary.h"
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

/* Binary-star measurement: thin wrappers of binary.h's model fit (kept for
 * the callers that already hold a metrics plan).  The plan only lends its
 * size and error message; the fit plans its own transforms. */
int metrics_plan_binary(metrics_plan *p, const float *img,
                        binary_result *out);
int metrics_binary(const float *img, int w, int h, binary_result *out);

#endif
