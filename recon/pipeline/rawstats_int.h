/* rawstats_int.h - the detector statistics' handle, shared by
 * rawstats.c (the per-frame sums) and rawstats_finish.c (the long
 * exposure's verdicts).  Not a public header. */
#ifndef SL_RAWSTATS_INT_H
#define SL_RAWSTATS_INT_H

#include "rawstats.h"

/* rawstats_add's unit of work: a band of rows, each summed whole by one
 * thread, so the per-pixel sums are the same bits on any thread count. */
enum { RS_BANDS = 16 };

static inline int band_row(int h, int b) { return (int)((long)h * b / RS_BANDS); }

struct rawstats {
    int w, h, nframes, finished;
    double code_max;
    sl_err err;
    /* per pixel: minus the frames where it was not finite (frames of it:
     * nfull + cnt[i]), sum, sum of squares and the extremes */
    int *cnt;
    int nfull;
    double *s1, *s2;
    float *vmin, *vmax;
    /* the largest value so far, the pixel-frames at it and the frames
     * flat-topped at it */
    double gmax;
    long n_at_gmax;
    int nflat_at_gmax;
    int integer_valued;
    double quantum;
    uint8_t *bad, *sky;
    tpool *pool;          /* rawstats_set_pool; NULL: the caller alone */
    rawstats_result res;
};

/* A job over the bands on the pool, or on the caller alone. */
void rawstats_run_bands(const rawstats *r, tpool_fn fn, void *ctx);

#endif
