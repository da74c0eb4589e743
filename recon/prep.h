/* prep.h - pre-processing of real frames before any reconstruction.
 *
 * Real cubes carry a bias and sky background, hot or dead pixels,
 * saturation, sometimes NaN/Inf from upstream software, and a sharp frame
 * edge that leaks power across the spectrum.  prep cleans one frame at a
 * time, in place, in this order:
 *   1. dark/bias: subtract a dark frame when given one;
 *   2. flat: divide by the flat (normalised to mean 1) when given one;
 *   3. bad pixels: non-finite pixels, pixels in the bad-pixel map and
 *      saturated pixels (>= saturation_adu in the RAW frame) are replaced by
 *      the median of their good 8-neighbours (or the sky when none);
 *   4. sky: unless a dark was given and sky is PREP_SKY_AUTO, or sky is
 *      PREP_SKY_BORDER, subtract the median of the frame's border pixels
 *      (a band of border_px pixels on each side, where speckle clouds of a
 *      centred object do not reach);
 *   5. window: multiply by an apodisation window (none, Hann, or Tukey with
 *      taper fraction alpha), which tapers the edge to zero.
 * The bad-pixel map can be learnt from the sequence itself: feed frames to
 * prep_learn, then prep_learn_finish marks pixels whose mean is an outlier
 * against its 3x3 neighbourhood (hot or dead: |mean - median| > nsigma *
 * robust sigma).  prep_describe writes every choice into a header.
 * Cost: O(pixels) per frame, plus O(bad pixels * 9).  No allocation after
 * prep_new.
 */
#ifndef SL_PREP_H
#define SL_PREP_H

#include <stdint.h>

#include "cube.h"
#include "status.h"

typedef struct prep prep;

enum prep_sky { PREP_SKY_AUTO = 0, PREP_SKY_NONE, PREP_SKY_BORDER };
enum prep_window { PREP_WIN_NONE = 0, PREP_WIN_HANN, PREP_WIN_TUKEY };

typedef struct prep_opts {
    const float *dark;      /* w*h dark/bias frame, or NULL */
    const float *flat;      /* w*h flat field, or NULL */
    int sky;                /* enum prep_sky */
    int border_px;          /* sky band width; 0 = max(2, min(w, h)/16) */
    double saturation_adu;  /* raw values >= this are bad; 0 = no limit */
    int window;             /* enum prep_window */
    double tukey_alpha;     /* taper fraction of each axis, (0, 1] */
    double badpix_nsigma;   /* threshold for prep_learn_finish; 0 = 8 */
} prep_opts;

/* Per-frame report of what prep_frame did. */
typedef struct prep_stats {
    double sky;         /* level subtracted (after dark and flat) */
    int nonfinite;      /* NaN/Inf pixels replaced */
    int saturated;      /* pixels at or above saturation replaced */
    int badmap;         /* pixels replaced from the bad-pixel map */
    double flux;        /* sum of the cleaned frame before windowing */
} prep_stats;

void prep_opts_defaults(prep_opts *o);
int prep_new(prep **out, int w, int h, const prep_opts *o, sl_err *err);
void prep_free(prep *p);
const char *prep_errmsg(const prep *p);

/* Learn the bad-pixel map from raw frames (optional). */
int prep_learn(prep *p, const float *raw);
/* Finish learning: returns the number of pixels marked bad (>= 0). */
int prep_learn_finish(prep *p);
/* Mark pixel (x, y) bad by hand (e.g. from a bad-pixel file). */
void prep_mark_bad(prep *p, int x, int y);
int prep_nbad(const prep *p);

/* Clean one frame in place.  stats may be NULL. */
int prep_frame(prep *p, float *frame, prep_stats *stats);
/* The apodisation window (w*h, 1 where flat), for callers that must
 * account for it (e.g. photon-noise bias: sum of window^2). */
const float *prep_window(const prep *p);
/* Record the choices (PREPDARK, PREPFLAT, PREPSKY, PREPBORD, PREPSAT,
 * PREPNBAD, PREPWIN, PREPALPH) in a header. */
void prep_describe(const prep *p, cube_meta *m);

#endif
