/* preview.h - quick-look 8-bit greyscale PNG of one image (libpng).
 *
 * Black is the minimum and white the maximum of the finite pixels; NaN and
 * Inf are drawn black.  The stretch maps t = (v - min) / (max - min) in
 * [0, 1] to grey 255 * f(t), rounded:
 *   linear  f(t) = t
 *   sqrt    f(t) = sqrt(t)                 (lifts faint companions)
 *   asinh   f(t) = asinh(t / s) / asinh(1 / s), softening s = 1/10 of the
 *           range: linear below ~s, logarithmic above, so a bright primary
 *           and a faint secondary both stay visible.
 * A constant image (or one whose only finite value repeats) is written
 * mid-grey (128) so it is not mistaken for an all-NaN image (black).
 * Orientation: the PNG's top row is the image's highest y (north up) and x
 * runs left to right, so east (-x) is left, as on the sky.
 */
#ifndef SL_PREVIEW_H
#define SL_PREVIEW_H

#include "status.h"

typedef enum preview_stretch {
    PREVIEW_LINEAR,
    PREVIEW_SQRT,
    PREVIEW_ASINH
} preview_stretch;

/* "linear", "sqrt" or "asinh" -> *out; SL_EINVAL for anything else. */
int preview_stretch_parse(const char *name, preview_stretch *out);

/* f(t) of the stretch above for t in [0, 1] (clamped there); the figures
 * (figure/) draw with the same curves. */
double preview_stretch_curve(preview_stretch stretch, double t);

/* Write img (width x height, pixel (x, y) = img[y*width + x]) to path,
 * creating or overwriting it.  SL_EINVAL for bad arguments, SL_EIO when the
 * file cannot be written (message names the path), SL_ENOMEM. */
int preview_write_png(const char *path, const float *img, int width,
                      int height, preview_stretch stretch, sl_err *err);

#endif
