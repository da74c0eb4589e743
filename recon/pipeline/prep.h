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
 *      PREP_SKY_BORDER, subtract the sky level: with a sky mask
 *      (prep_set_sky: pixels the speckle cloud never reaches, wherever it
 *      sits), the clipped mean of those pixels, which unlike a median is
 *      not stuck on an integer step of quantised data; otherwise the
 *      median of the frame's border pixels (a band of border_px pixels on
 *      each side, where the cloud of a centred object does not reach);
 *   5. recentre (after prep_set_centre): shift the frame circularly by
 *      whole pixels so that the cloud's centroid lands at (w/2, h/2).  The
 *      power spectrum and bispectrum do not change under a shift, but an
 *      off-centre cloud is cut by a crop and tapered by the window.  The
 *      centroid is measured in a disc around the long exposure's centre,
 *      so noise pulls it towards that centre, never away;
 *   6. window: multiply by an apodisation window (none, Hann, or Tukey with
 *      taper fraction alpha), which tapers the edge to zero.
 * A saturated pixel is repaired only when isolated (a hot pixel, or a
 * single clipped peak); a plateau of them keeps the clip level, the best
 * lower bound there is, where its neighbours' median would be sky.
 * The bad-pixel map comes from rawstats.h (learnt from the raw frames),
 * a map file or prep_mark_bad.  prep_report_fill says what it does.
 * Cost: O(pixels) per frame, plus O(bad pixels * 9).  No allocation after
 * prep_new.
 */
#ifndef SL_PREP_H
#define SL_PREP_H

#include <stdint.h>

#include "io/cube.h"
#include "pipeline.h"
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
} prep_opts;

/* Per-frame report of what prep_frame did. */
typedef struct prep_stats {
    double sky;         /* level subtracted (after dark and flat) */
    int nonfinite;      /* NaN/Inf pixels replaced */
    int saturated;      /* pixels at or above saturation replaced */
    int badmap;         /* pixels replaced from the bad-pixel map */
    double flux;        /* sum of the cleaned frame before windowing */
    int shift_x, shift_y; /* recentring shift applied, pixels */
} prep_stats;

void prep_opts_defaults(prep_opts *o);
int prep_new(prep **out, int w, int h, const prep_opts *o, sl_err *err);
void prep_free(prep *p);
/* A copy of p, calibrations, maps and scratch included: prep_frame writes
 * p's scratch, so threads cleaning frames at once each need their own.
 * SL_ENOMEM. */
int prep_dup(prep **out, const prep *p, sl_err *err);
const char *prep_errmsg(const prep *p);

/* Mark pixel (x, y) bad by hand (e.g. from a bad-pixel file). */
void prep_mark_bad(prep *p, int x, int y);
int prep_nbad(const prep *p);

/* OR map (w*h, nonzero = bad) into the bad-pixel map. */
void prep_set_badmap(prep *p, const uint8_t *map);
/* Take the sky level from the pixels where sky (w*h) is nonzero, when
 * there are at least 64 of them (up to 8192 are used, evenly spread);
 * NULL returns to the border median.  SL_ENOMEM. */
int prep_set_sky(prep *p, const uint8_t *sky);
/* Recentre every frame (step 5) on its centroid within radius_px of
 * (cx, cy), raw pixel coordinates.  SL_ENOMEM. */
int prep_set_centre(prep *p, double cx, double cy, double radius_px);

/* Clean one frame in place.  stats may be NULL. */
int prep_frame(prep *p, float *frame, prep_stats *stats);
/* The apodisation window (w*h, 1 where flat), for callers that must
 * account for it (e.g. photon-noise bias: sum of window^2). */
const float *prep_window(const prep *p);
/* What the cleaning does, for the pipeline's report (pipeline.h). */
void prep_report_fill(const prep *p, pipeline_prep_report *r);

#endif
