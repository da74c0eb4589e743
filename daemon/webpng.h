/* webpng.h - the web view's images: a float image to an 8-bit grey PNG in
 * memory, through a stretch.
 *
 * Black is lo and white hi; t = (v - lo) / (hi - lo) clamped to [0, 1] is
 * drawn as grey 255 f(t):
 *   linear  f(t) = t
 *   sqrt    f(t) = sqrt(t)
 *   log     f(t) = log10(1 + 1000 t) / log10(1001)   (three decades)
 *   asinh   f(t) = asinh(10 t) / asinh(10)          (recon/io/preview.h's)
 * NaN and Inf are black.  Orientation as every PNG of the project: the top
 * row is the image's highest y (north up), x runs left to right.
 */
#ifndef SL_DAEMON_WEBPNG_H
#define SL_DAEMON_WEBPNG_H

#include <glib.h>
#include <stddef.h>

typedef enum web_stretch {
    WEB_STRETCH_LINEAR,
    WEB_STRETCH_SQRT,
    WEB_STRETCH_LOG,
    WEB_STRETCH_ASINH,
    WEB_NSTRETCH
} web_stretch;

/* "linear", "sqrt", "log", "asinh" -> 0..3; -1 for anything else. */
int web_stretch_parse(const char *name);
const char *web_stretch_name(int s);

/* The frame's statistics and display range: lo the 0.5th percentile and
 * hi the maximum of the finite values (a speckle frame's peak matters:
 * alignment, saturation); mean of the finite values.  0 when none is
 * finite.  Percentiles on at most 65536 samples. */
int webpng_range(const float *img, size_t n, double lo_pct, double *lo, double *hi,
                 double *mean, double *min);

/* The PNG (NULL when out of memory or w, h < 1). */
GBytes *webpng_gray(const float *img, int w, int h, int stretch, double lo, double hi);

#endif
