/* pipeline_stream.c - one input sequence being streamed (pipeline_int.h):
 * the reader, the scale that keeps float sums in range, and the frame
 * cleaning, set up from what the raw frames say about the detector
 * (rawstats.h) before the first frame is cleaned.
 *
 * Why learn the detector by default: stuck, hot and dead pixels, an ADC
 * that clips and an off-centre cloud each break every estimator on camera
 * data, and no header need say so.  The learning reads the first
 * DETECT_FRAMES raw frames once more (every frame with learn_badpix); on
 * a 200^2 cube that is ~0.2 ms per frame.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "pipeline_int.h"
#include "rawstats.h"
#include "base/tpool.h"

#define DETECT_FRAMES 32

void stream_close(stream *s)
{
    stream_prefetch_cancel(s); /* its readers use rd, pp and the ring */
    cube_reader_free(s->rd);
    prep_free(s->pp);
    free(s->frame);
    free(s->ring);
    probe_free(s->pb);
    free(s->sel);
    free(s->cache);
    memset(s, 0, sizeof *s);
}

int stream_next(stream *s)
{
    int rc = cube_reader_next(s->rd, s->frame);
    if (rc == SL_OK && s->scale != 1.0)
        for (size_t i = 0, n = (size_t)s->w * s->h; i < n; i++)
            s->frame[i] = (float)(s->frame[i] * s->scale);
    return rc;
}

/* The power of two that brings the first frame's peak |pixel| into
 * [0.5, 1) when it lies outside 2^-24..2^24 (see stream.scale), else 1.
 * Cost: one extra frame read. */
static int stream_pick_scale(stream *s)
{
    s->scale = 1.0;
    int rc = cube_reader_next(s->rd, s->frame);
    if (rc != SL_OK)    /* the reader keeps its message for the caller */
        return rc == SL_EEND ? SL_OK : rc;
    cube_reader_rewind(s->rd);
    double peak = 0;
    for (size_t i = 0, n = (size_t)s->w * s->h; i < n; i++) {
        double a = fabs((double)s->frame[i]);
        if (isfinite(a) && a > peak)
            peak = a;
    }
    if (peak > 0 && (peak > 0x1p24 || peak < 0x1p-24))
        s->scale = ldexp(1.0, -(ilogb(peak) + 1));
    return SL_OK;
}

/* Does the frame carry light: at least two different finite pixels?
 * *nonfinite counts the frames with no finite pixel at all. */
static int frame_lit(const float *f, size_t n, int *nonfinite)
{
    size_t i = 0;
    while (i < n && !isfinite(f[i]))
        i++;
    if (i == n) {
        (*nonfinite)++;
        return 0;
    }
    for (float v0 = f[i]; i < n; i++)
        if (isfinite(f[i]) && f[i] != v0)
            return 1;
    return 0;
}

/* A sequence with no light in any frame (all NaN/Inf, or constant) has
 * nothing to reconstruct: every estimator would return zeros or a flat
 * image with exit status 0.  Reads until the first lit frame, so a normal
 * cube costs one frame read. */
static int stream_check_light(stream *s, const char *what, sl_err *err)
{
    cube_reader_rewind(s->rd);
    int rc, k = 0, nonfinite = 0, lit = 0;
    while (!lit && (rc = stream_next(s)) == SL_OK) {
        lit = frame_lit(s->frame, (size_t)s->w * s->h, &nonfinite);
        k++;
    }
    cube_reader_rewind(s->rd);
    if (lit)
        return SL_OK;
    if (rc != SL_EEND)
        return sl_seterr(err, rc, "%s", cube_reader_errmsg(s->rd));
    return sl_seterr(err, SL_EDATA, "no light in %s: of its %d frames %d "
                     "hold only NaN/Inf and %d are constant", what, k,
                     nonfinite, k - nonfinite);
}

static int learn_add(void *h, const float *frame) { return rawstats_add(h, frame); }

/* Learn the detector from the first raw frames (all of them with
 * learn_badpix) into *out; *rs stays NULL when there are too few.  With
 * threads, the frames are read ahead on a thread of their own, and each
 * frame's statistics and the decision's per-pixel passes are shared by a
 * pool of the run's threads: the open stage was serial, 0.06 s at 512^2
 * x 400 and 0.010 s at 200^2 x 100. */
static int learn_detector(stream *s, const pipeline_opts *o, rawstats **rs,
                          sl_err *err)
{
    int want = o->learn_badpix ? s->n : DETECT_FRAMES < s->n ? DETECT_FRAMES : s->n;
    int rc = rawstats_new(rs, s->w, s->h, cube_reader_code_max(s->rd) * s->scale, err);
    if (rc != SL_OK)
        return rc;
    int nthr = o->nthreads > 0 ? o->nthreads : tpool_default_threads();
    tpool *pool = nthr > 1 ? tpool_new(nthr, NULL) : NULL; /* none: serial */
    rawstats_set_pool(*rs, pool);
    cube_reader_rewind(s->rd);
    int ran = 0;
    if (s->ahead) /* s->pp is not made yet: the reader only scales */
        rc = stream_feed_ahead(s, 0, want, learn_add, *rs, "detector learning", err, &ran);
    for (int k = 0; !ran && k < want && (rc = stream_next(s)) == SL_OK; k++)
        rawstats_add(*rs, s->frame);
    cube_reader_rewind(s->rd);
    if (!ran && rc == SL_EEND) /* fewer frames than wanted */
        rc = SL_OK;
    else if (!ran && rc != SL_OK) /* the ahead pass set its own message */
        rc = sl_seterr(err, rc, "%s", cube_reader_errmsg(s->rd));
    if (rc == SL_OK && (rc = rawstats_finish(*rs, &s->det)) != SL_OK)
        rc = sl_seterr(err, rc, "%s", rawstats_errmsg(*rs));
    rawstats_set_pool(*rs, NULL);
    tpool_free(pool);
    s->det_learnt = rc == SL_OK;
    return rc;
}

/* A bad-pixel map file: a 2-D FITS image of the frame size, nonzero =
 * bad. */
static int read_badpix(stream *s, const char *path, sl_err *err)
{
    seq *m = NULL;
    const char *paths[] = {path};
    int rc = cube_read(&m, NULL, paths, 1, CUBE_ALLOW_NONFINITE, err);
    if (rc != SL_OK)
        return rc;
    if (m->width != s->w || m->height != s->h || m->nframes != 1) {
        rc = sl_seterr(err, SL_EFORMAT, "bad-pixel map %s is %dx%d x %d "
                       "frames; the frames are %dx%d (want one image)", path,
                       m->width, m->height, m->nframes, s->w, s->h);
    } else {
        for (int y = 0; y < s->h; y++)
            for (int x = 0; x < s->w; x++) {
                float v = m->data[(size_t)y * s->w + x];
                if (v != 0 || !isfinite(v))
                    prep_mark_bad(s->pp, x, y);
            }
    }
    seq_free(m);
    return rc;
}

/* A calibration frame: the mean of every frame in path (one image or a
 * stack), times the stream's scale; *out is w*h floats (free it).
 * Streams the stack, so a long one costs one frame and one double sum. */
static int read_calibration(const stream *s, const char *path, const char *what,
                            float **out, sl_err *err)
{
    cube_reader *rd = NULL;
    const char *paths[] = {path};
    size_t n = (size_t)s->w * s->h;
    sl_err e = {0};
    int rc = cube_reader_open(&rd, paths, 1, 0, &e);
    if (rc != SL_OK)
        return sl_seterr(err, rc, "%s frame: %s", what, e.msg);
    double *sum = calloc(n, sizeof *sum);
    float *f = malloc(n * sizeof *f);
    int k = 0;
    if (cube_reader_width(rd) != s->w || cube_reader_height(rd) != s->h) {
        rc = sl_seterr(err, SL_EFORMAT, "%s frame %s is %dx%d; the frames are "
                       "%dx%d", what, path, cube_reader_width(rd),
                       cube_reader_height(rd), s->w, s->h);
        goto free_all;
    }
    if (!sum || !f) {
        rc = sl_seterr(err, SL_ENOMEM, "out of memory for the %s frame", what);
        goto free_all;
    }
    for (; (rc = cube_reader_next(rd, f)) == SL_OK; k++)
        for (size_t i = 0; i < n; i++)
            sum[i] += f[i];
    if (rc != SL_EEND) {
        rc = sl_seterr(err, rc, "%s frame: %s", what, cube_reader_errmsg(rd));
        goto free_all;
    }
    for (size_t i = 0; i < n; i++)
        f[i] = (float)(sum[i] / k * s->scale);
    *out = f;
    f = NULL;
    rc = SL_OK;
free_all:
    free(f);
    free(sum);
    cube_reader_free(rd);
    return rc;
}

/* Frame cleaning, from the options and the detector learnt. */
static int stream_prep(stream *s, const pipeline_opts *o, sl_err *err)
{
    rawstats *rs = NULL;
    int rc = SL_OK;
    if (o->detect && (rc = learn_detector(s, o, &rs, err)) != SL_OK)
        goto free_rs;
    prep_opts po;
    prep_opts_defaults(&po);
    po.window = PREP_WIN_NONE;   /* the estimators apodise themselves */
    po.saturation_adu = o->saturation_adu > 0 ? o->saturation_adu * s->scale
                                              : s->det.sat_level;
    float *dark = NULL, *flat = NULL, *flat_dark = NULL;
    if ((o->dark_path && (rc = read_calibration(s, o->dark_path, "dark", &dark, err)) != SL_OK) ||
        (o->flat_path && (rc = read_calibration(s, o->flat_path, "flat", &flat, err)) != SL_OK) ||
        (o->flat_dark_path &&
         (rc = read_calibration(s, o->flat_dark_path, "flat's dark", &flat_dark, err)) != SL_OK))
        goto free_cal;
    for (size_t i = 0; flat && flat_dark && i < (size_t)s->w * s->h; i++)
        flat[i] -= flat_dark[i];
    po.dark = dark;
    po.flat = flat;
    rc = prep_new(&s->pp, s->w, s->h, &po, err); /* copies them */
free_cal:
    free(dark);
    free(flat);
    free(flat_dark);
    if (rc != SL_OK)
        goto free_rs;
    if (rs)
        prep_set_badmap(s->pp, rawstats_badmap(rs));
    if (o->badpix_path && (rc = read_badpix(s, o->badpix_path, err)) != SL_OK)
        goto free_rs;
    if (rs) {
        if ((rc = prep_set_sky(s->pp, rawstats_skymask(rs))) == SL_OK && o->recentre)
            rc = prep_set_centre(s->pp, s->det.cx_px, s->det.cy_px,
                                 s->det.cloud_radius_px);
        if (rc != SL_OK)
            sl_seterr(err, rc, "%s", prep_errmsg(s->pp));
    }
free_rs:
    rawstats_free(rs);
    return rc;
}

int stream_open(stream *s, const char *const *paths, int npaths,
                const pipeline_opts *o, sl_err *err)
{
    memset(s, 0, sizeof *s);
    int rc = cube_reader_open(&s->rd, paths, npaths,
                              o->prep ? CUBE_ALLOW_NONFINITE : 0, err);
    if (rc != SL_OK)
        return rc;
    s->w = cube_reader_width(s->rd);
    s->h = cube_reader_height(s->rd);
    s->n = cube_reader_nframes(s->rd);
    stream_share_range(s, o->share, o->ref_path != NULL);
    s->progress = o->progress;
    s->progress_ctx = o->progress_ctx;
    s->ahead = o->nthreads != 1;
    s->readers = o->nthreads > 1 ? 1 + (o->nthreads - 1) / 4 : 1;
    s->feed_total = 2.0 * s->n; /* until the plan is known */
    s->frame = malloc(sizeof(float) * s->w * s->h);
    if (!s->frame) {
        rc = sl_seterr(err, SL_ENOMEM, "out of memory for a %dx%d frame",
                       s->w, s->h);
        goto close_stream;
    }
    if ((rc = stream_pick_scale(s)) != SL_OK) {
        rc = sl_seterr(err, rc, "%s", cube_reader_errmsg(s->rd));
        goto close_stream;
    }
    if ((rc = stream_check_light(s, paths[0], err)) != SL_OK)
        goto close_stream;
    if ((o->prep && (rc = stream_prep(s, o, err)) != SL_OK) ||
        (rc = stream_check_agreed(s, err)) != SL_OK)
        goto close_stream;
    return SL_OK;
close_stream:
    stream_close(s);
    return rc;
}

void stream_expect_passes(stream *s, int passes)
{
    s->feed_total = s->fed + (double)passes * (s->k1 - s->k0);
}

/* add, counted for the progress callback. */
typedef struct counted {
    stream *s;
    add_fn add;
    void *h;
    const char *what;
} counted;

static int counted_add(void *ctx, const float *frame)
{
    counted *c = ctx;
    stream *s = c->s;
    if (s->progress) {
        if (++s->fed > s->feed_total)
            s->feed_total = s->fed + (s->k1 - s->k0); /* one more pass than planned */
        s->progress(s->progress_ctx, s->fed, s->feed_total, c->what);
    }
    double t0 = stream_now_s();
    int rc = c->add ? c->add(c->h, frame) : SL_OK;
    s->frame_s += stream_now_s() - t0;
    return rc;
}

double stream_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* The pass, its time split between reading (and cleaning) and add. */
static int feed(stream *s, add_fn add, void *h, const char *what, sl_err *err)
{
    if (s->pb) {
        stream_prefetch_cancel(s); /* none is made with a probe; never two readers of rd */
        return skip_feed(s, add, h, what, err);
    }
    int ran = 0;
    if (s->ahead) {
        int rc = stream_feed_ahead(s, s->k0, s->k1, add, h, what, err, &ran);
        if (ran)
            return rc;
    }
    int rc = cube_reader_seek(s->rd, s->k0), k = s->k0;
    while (rc == SL_OK && (rc = k < s->k1 ? stream_next(s) : SL_EEND) == SL_OK) {
        if (s->pp)
            prep_frame(s->pp, s->frame, NULL);
        if (add && (rc = add(h, s->frame)) != SL_OK)
            return sl_seterr(err, rc, "frame %d: %s", k, what);
        k++;
    }
    if (rc != SL_EEND)
        return sl_seterr(err, rc, "%s", cube_reader_errmsg(s->rd));
    return SL_OK;
}

int stream_feed(stream *s, add_fn add, void *h, const char *what,
                sl_err *err)
{
    counted c = {s, add, h, what};
    double t0 = stream_now_s(), f0 = s->frame_s;
    int rc = feed(s, counted_add, &c, what, err);
    s->read_s += stream_now_s() - t0 - (s->frame_s - f0);
    return rc;
}

void stream_report(const stream *s, pipeline_report *r)
{
    r->stage_s[PIPE_STAGE_READ] = s->read_s;
    r->stage_s[PIPE_STAGE_FRAME] = s->frame_s;
    memset(&r->prep, 0, sizeof r->prep);
    memset(&r->detector, 0, sizeof r->detector);
    if (s->pp)
        prep_report_fill(s->pp, &r->prep);
    if (!s->det_learnt)
        return;
    const rawstats_result *d = &s->det;
    pipeline_detector_report *o = &r->detector;
    o->learnt = 1;
    o->nframes = d->nframes;
    o->nstuck = d->nstuck, o->nhot = d->nhot, o->ndead = d->ndead;
    o->sat_level_adu = d->sat_level / s->scale;
    o->sat_source = d->sat_source;
    o->quantum_adu = d->quantum / s->scale;
    o->sky_adu = d->sky_level / s->scale;
    o->sky_rms_adu = d->sky_rms / s->scale;
    o->cx_px = d->cx_px, o->cy_px = d->cy_px;
}
