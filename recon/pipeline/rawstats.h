/* rawstats.h - what the raw frames of a sequence say about the detector:
 * bad pixels, the saturation level, the sky region and its noise.
 *
 * Real cameras bring stuck, hot and dead pixels, an ADC that clips, a
 * bias pedestal and quantisation; nothing in the header need say so.  A
 * full-scale stuck pixel outshines a whole 2e4-photon star by itself, and
 * in the power spectrum a fixed pattern of them is indistinguishable from
 * an object, so every reconstruction starts here by default.
 *
 * rawstats_add sees raw frames (before any cleaning); it keeps per pixel
 * the temporal moments and extremes.  rawstats_finish then decides:
 *  - stuck: the same value in every frame while the neighbours vary, at a
 *    level unlike theirs (hot at full scale, dead at 0, or anywhere);
 *  - hot or dead with noise: an outlier of the long exposure against its
 *    neighbours' median (8 of its own standard errors, and 30 % of the
 *    local signal) that never leaves that state: a hot pixel's dark
 *    current is a floor under every frame, a dead pixel never rises to
 *    its neighbours.  Through turbulence a real image moves, so its
 *    bright pixels also go dark.  This test is off when the scene is
 *    static (no fluctuation beyond the noise), where an undersampled
 *    star's core would look the same;
 *  - saturation: the largest value V seen is a clipping level when the
 *    file's integer type tops out there, when V = 2^k - 1 (k = 8..16: a
 *    12-bit ADC in a 16-bit file) in at least two pixel-frames, or when it
 *    is flat-topped (two 4-adjacent pixels at V) in at least two frames;
 *  - sky: the pixels whose long exposure stays within the noise of the
 *    background (the cloud, wherever it sits, excluded), their mean level
 *    and temporal rms (read noise, sky photons and quantisation together);
 *  - the cloud: the long exposure's centroid and radius (recentring);
 *  - quantum: the data's step (1 for plain integers, 16 for 12-bit data
 *    shifted into 16 bits, 0 for real-valued data).
 * Cost: 5 numbers per pixel (28 bytes), ~8 flops per pixel per frame;
 * finish sorts neighbourhoods of 8 and a few frame-sized arrays.
 */
#ifndef SL_RAWSTATS_H
#define SL_RAWSTATS_H

#include <stdint.h>

#include "status.h"
#include "base/tpool.h"

typedef struct rawstats rawstats;

enum rawstats_sat {
    RAWSTATS_SAT_NONE = 0,  /* no clipping level found */
    RAWSTATS_SAT_TYPE,      /* the file's integer type tops out at it */
    RAWSTATS_SAT_ADC,       /* 2^k - 1 reached in >= 2 pixel-frames */
    RAWSTATS_SAT_FLAT       /* flat-topped peaks in >= 2 frames */
};

typedef struct rawstats_result {
    int nframes;         /* frames learnt from */
    int nstuck, nhot, ndead; /* bad pixels by kind */
    int static_scene;    /* 1: no fluctuation beyond the noise (the
                          * hot/dead test was skipped; it also needs
                          * 20 frames) */
    double sat_level;    /* raw values >= this are clipped; 0: none */
    int sat_source;      /* enum rawstats_sat */
    int integer_valued;  /* every learnt pixel an integer */
    double quantum;      /* step of the data; 0 for real-valued data */
    int nsky;            /* pixels in the sky mask */
    double sky_level;    /* mean raw level of the sky pixels */
    double sky_rms;      /* their median temporal rms */
    /* the speckle cloud in the long exposure (bad and sky pixels out):
     * centroid, and 1.5 x the radius holding 95 % of its flux (>= 8) */
    double cx_px, cy_px, cloud_radius_px;
} rawstats_result;

/* w x h raw frames; code_max: the largest value the file's integer type
 * holds (255, 65535, ...), 0 for floating-point files. */
int rawstats_new(rawstats **out, int w, int h, double code_max, sl_err *err);
void rawstats_free(rawstats *r);
const char *rawstats_errmsg(const rawstats *r);

/* Learn from one raw frame (NaN/Inf pixels are skipped).  With a pool
 * (rawstats_set_pool, kept by reference; NULL: none) its bands of rows
 * are shared by the pool's threads: the same sums on any thread count. */
int rawstats_add(rawstats *r, const float *raw);
void rawstats_set_pool(rawstats *r, tpool *pool);
int rawstats_nframes(const rawstats *r);
/* Decide (see above); res may be NULL.  Idempotent. */
int rawstats_finish(rawstats *r, rawstats_result *res);
/* After finish: w*h maps, 1 = bad pixel / sky pixel. */
const uint8_t *rawstats_badmap(const rawstats *r);
const uint8_t *rawstats_skymask(const rawstats *r);

#endif
