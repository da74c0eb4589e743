/* framefeed.h - a sequence's frames cleaned as pipeline_run cleans them,
 * handed one at a time to the caller's accumulator (e.g. the mask
 * observables of spectra/maskobs.h), with their photon statistics.
 *
 * The cleaning is pipeline.h's, from the same options (prep, detect,
 * recentre, learn_badpix, badpix_path, saturation_adu; the skips and the
 * estimators' options are not used): the detector learnt from the raw
 * frames (rawstats.h: stuck, hot and dead pixels, the clip level, the
 * sky region), then per frame the bad pixels repaired, the sky
 * subtracted and the cloud recentred (prep.h), no window.
 *
 * Units: frames are multiplied by a power of two when their peak is far
 * from 1 (pipeline_int.h, stream.scale); the photon gain and read noise
 * below are in those units, so ratios (visibilities, closure phases) and
 * photon-bias corrections need no scale at all.
 * Memory: one frame and what the cleaning keeps (pipeline.h). */
#ifndef SL_FRAMEFEED_H
#define SL_FRAMEFEED_H

#include "io/cube.h"
#include "pipeline.h"
#include "status.h"

typedef struct framefeed framefeed;

typedef struct framefeed_photons {
    double photons;          /* per frame; 0 unknown (not photon counts) */
    double adu_per_photon;   /* in the fed frames' units; 0 unknown */
    double read_noise_adu;   /* per pixel, same units; 0 unknown */
    int source;              /* enum pipeline_photon_source */
} framefeed_photons;

/* Open paths (as pipeline_run takes them) and learn the detector.  Errors
 * name the file. */
int framefeed_open(framefeed **out, const char *const *paths, int npaths,
                   const pipeline_opts *o, sl_err *err);
void framefeed_free(framefeed *f);
int framefeed_width(const framefeed *f);
int framefeed_height(const framefeed *f);
int framefeed_nframes(const framefeed *f);
/* The first file's header. */
const cube_meta *framefeed_meta(const framefeed *f);
/* Photon statistics as pipeline_run takes them (options, else SIMPHOT,
 * SIMGAIN, SIMRDN, else a camera's GAIN and RDNOISE).  When photons are
 * known but not the gain, the gain is the cleaned frames' mean flux over
 * the photons: one more read of the sequence. */
int framefeed_photons_get(framefeed *f, const pipeline_opts *o,
                          framefeed_photons *ph, sl_err *err);
/* Every cleaned frame to add(h, frame) (w*h floats), in order; stops at
 * the first error add returns, named with what and the frame. */
int framefeed_run(framefeed *f, int (*add)(void *h, const float *frame),
                  void *h, const char *what, sl_err *err);
/* What the cleaning did and the detector learnt (pipeline.h's report). */
void framefeed_report(const framefeed *f, pipeline_report *r);

#endif
