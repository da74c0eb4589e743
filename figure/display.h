/* display.h - how a sky image's values become levels for the colour map:
 * the cut [lo, hi] and the stretch between them.
 *
 * A reconstruction's background is not its noise: speckle methods leave
 * artifacts around the object (TSM's radial streaks, the residual halo) at
 * 5-20 % of the peak, far above the sky's scatter, and a cut from the sky
 * noise shows those artifacts as loudly as the stars.  The artifacts are
 * many peaks of similar height; stars are few and higher.  So the
 * "artifacts" cut measures them: among the significant local maxima
 * (pixels above their eight neighbours and DISPLAY_SIGNIFICANT sky sigmas
 * above the background), lo is the level under which nine in ten lie, and
 * hi is the peak.  Measured: the demo's TSM-Fourier binaries (dm 1, three
 * screens) cut at 0.13-0.19 of the peak, the companion of the worst
 * screen's at 0.59; direct, TSM and TSM-Fourier
 * on a 0.3", dm 1.5 binary cut at 0.11-0.12 with the halo's artifacts at
 * 0.15-0.2 and the companion at 0.2-0.25.  With fewer than
 * DISPLAY_MIN_MAXIMA such maxima (a noiseless truth image, a few stars)
 * there are no artifacts to measure and lo is the background.
 *
 * The sky: the median (background) and 1.4826 x the median absolute
 * deviation (noise) of the finite pixels, those exactly 0 left out (TSM
 * leaves 0 outside the disc it reconstructs; they are not samples of the
 * sky) unless fewer than a quarter are non-zero (stars drawn on 0: then
 * the zeros are the sky).  "full" is the quick-look range, minimum to
 * maximum: nothing hidden.
 *
 * The stretch is preview.h's curve (linear, sqrt, asinh) on
 * t = (v - lo) / (hi - lo), clamped to [0, 1].
 */
#ifndef SL_DISPLAY_H
#define SL_DISPLAY_H

#include "status.h"
#include "io/preview.h"

#define DISPLAY_MIN_MAXIMA 16
#define DISPLAY_SIGNIFICANT 5.0
#define DISPLAY_ARTIFACT_QUANTILE 0.9

typedef enum display_cut {
    DISPLAY_CUT_ARTIFACTS,
    DISPLAY_CUT_FULL
} display_cut;

typedef struct display {
    double lo, hi;          /* values drawn at level 0 and 1 */
    double background;      /* the sky's median (see above) */
    double noise;           /* the sky's robust sigma */
    double peak;            /* largest finite value */
    int nmaxima;            /* local maxima above the background */
    display_cut cut;        /* as asked */
    int cut_from_artifacts; /* 1 when lo came from the maxima */
    preview_stretch stretch;
} display;

/* "artifacts" or "full" -> *out; SL_EINVAL otherwise. */
int display_cut_parse(const char *name, display_cut *out);
const char *display_cut_name(display_cut cut);

/* Measure img (w x h, pixel (x, y) at [y*w + x]) and fill d.  SL_EINVAL
 * for bad arguments, SL_EDATA when no pixel is finite, SL_ENOMEM.  A
 * constant image gets hi = lo + 1 so that every level is defined. */
int display_fit(display *d, const float *img, int w, int h, display_cut cut,
                preview_stretch stretch, sl_err *err);
/* The level in [0, 1] of v; NAN for a non-finite v. */
double display_level(const display *d, double v);
/* The value drawn at level in [0, 1] (the inverse: colour-bar ticks). */
double display_value(const display *d, double level);

#endif
