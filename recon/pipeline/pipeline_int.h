/* pipeline_int.h - internals shared by pipeline.c (the estimators) and
 * pipeline_selection.c (the scene probe, frame selection and crop).  Not a public header. */
#ifndef SL_PIPELINE_INT_H
#define SL_PIPELINE_INT_H

#include "autoconf.h"
#include "spectra/bispec.h"
#include "spectra/powspec.h"
#include "io/cube.h"
#include "pipeline.h"
#include "prep.h"
#include "probe.h"
#include "rawstats.h"
#include "tsm/tsm.h"

typedef int (*add_fn)(void *h, const float *frame);

/* One input sequence being streamed: reader, cleaning, frame buffer.
 * With a probe (the skips), frames are selected and cropped: w x h is the
 * crop, fw x fh the frame (see skip_feed). */
typedef struct stream {
    cube_reader *rd;
    prep *pp;
    float *frame;
    int w, h, n;
    probe *pb;            /* NULL: every frame, whole */
    int fw, fh;
    float *sel;           /* one cropped frame */
    float *cache;         /* the kept crops, when they fit; else NULL */
    int ncache, ncache_max, passes;
    /* Frames are multiplied by scale on reading (stream_next): a power of
     * two, 1 unless the first frame's peak lies outside 2^-24..2^24, when
     * it brings the peak to [0.5, 1).  Why: the bispectra are triple
     * products in float (|B| ~ peak^3 N^3), so data in other units (pixels
     * of 1e-40 or 1e28) would underflow or overflow; a power of two is
     * exact, so the result is the same image, scaled back by 1/scale.
     * Quantities in ADU (saturation, read noise, ADU per photon) are scaled
     * with the frames. */
    double scale;
    rawstats_result det;  /* what the raw frames said (det_learnt) */
    int det_learnt;
    /* pipeline_opts.progress: frames fed so far and the estimate of all */
    void (*progress)(void *ctx, double done, double total, const char *what);
    void *progress_ctx;
    double fed, feed_total;
    /* pipeline_opts.share: this process feeds frames [k0, k1) (all of
     * them without share); the probe's verdicts over every process once
     * the first pass has counted them (counts_whole). */
    const pipeline_share *share;
    int k0, k1;
    int has_ref;          /* a reference sequence is reduced after this */
    /* wall time in stream_feed: reading and cleaning frames (read_s) and
     * the estimator's add (frame_s); pipeline_report.stage_s */
    double read_s, frame_s;
    int ahead;            /* read ahead on threads of their own (more than
                             one thread allowed) */
    int readers;          /* those threads: 1 + (threads - 1) / 4 */
    int ahead_want;       /* frames the next pass's add may take between
                             returns (0: a few); pipeline_ahead.c */
    float *ring;          /* the read-ahead ring, ring_slots frames */
    int ring_slots;
    struct ahead *pre;    /* readers already reading the next pass
                             (stream_prefetch), or NULL */
    int counts[PROBE_NVERDICT], counts_whole;
} stream;

/* Open paths for streaming; with o->prep, frames are cleaned as the
 * options and the detector learnt from the raw frames say
 * (pipeline_stream.c). */
int stream_open(stream *s, const char *const *paths, int npaths,
                const pipeline_opts *o, sl_err *err);
void stream_close(stream *s);
/* The cleaning and the detector learnt, for the report. */
void stream_report(const stream *s, pipeline_report *r);

/* Read the next frame of s into s->frame, scaled; cube_reader_next's
 * status (SL_EEND at the end). */
int stream_next(stream *s);
/* Feed every (cleaned) frame of s to add(h, frame).  Cost: one read and
 * one prep per frame; allocation-free. */
int stream_feed(stream *s, add_fn add, void *h, const char *what, sl_err *err);
/* CLOCK_MONOTONIC in seconds. */
double stream_now_s(void);
/* A pass over frames [k0, k1) whole (s's range, or the first frames for
 * the detector's learning), read and cleaned on s->readers threads of
 * their own while add runs, added in order (pipeline_ahead.c); s->frame
 * is not used.  *ran 0 (and SL_OK)
 * when there was no thread or ring to be had: the caller reads serially. */
int stream_feed_ahead(stream *s, int k0, int k1, add_fn add, void *h, const char *what,
                      sl_err *err, int *ran);
/* Start reading the next pass over s's range on the readers now, while
 * the caller plans its estimator (the plan is mostly serial: the readers
 * fill the ring meanwhile, and the pass's first frames wait no more);
 * the next stream_feed takes them over.  Nothing when s reads serially
 * or through a probe.  stream_close (or stream_prefetch_cancel) stops
 * readers no pass took. */
void stream_prefetch(stream *s);
void stream_prefetch_cancel(stream *s);
/* Expect passes more feeds of every frame (for the progress estimate). */
void stream_expect_passes(stream *s, int passes);

/* A run split over processes (pipeline_share.c; pipeline.h,
 * pipeline_share): stream_share_range sets s's frame range from share
 * (may be NULL: every frame); has_ref: a reference's sums follow this
 * stream's.  The others make an accumulator's sums whole (reduce), or buf
 * rank 0's (agree); the bispectrum's and TSM's are the last without a
 * reference, after which the hook may end a process's part (SL_EEND).
 * Without share they do nothing. */
void stream_share_range(stream *s, const pipeline_share *share, int has_ref);
int stream_share_powspec(stream *s, powspec *p, sl_err *err);
int stream_share_bispec(stream *s, bispec *b, sl_err *err);
int stream_share_tsm(stream *s, tsm *t, sl_err *err);
int stream_share_doubles(stream *s, double *v, size_t n, sl_err *err);
int stream_agree(stream *s, void *buf, size_t bytes, sl_err *err);
/* What each process measured from the first frames alone (the scale, the
 * detector and, once probed, the crop and the frame-quality reference)
 * against rank 0's: SL_EDATA naming the rank when they differ, since the
 * sums would then not add up to one run's. */
int stream_check_agreed(stream *s, sl_err *err);
/* 1 when this process takes the decisions: rank 0, or no share. */
int stream_leads(const stream *s);

/* Photon statistics (pipeline_photons.c).  stream_photon_stats: photons
 * per frame and g (ADU per photon, in s's scaled units) from the options,
 * else the header (SIMPHOT/SIMGAIN; a camera's GAIN alone: the photons
 * are the cleaned frames' mean flux over g, one extra read of the cube);
 * both 0 when unknown or when the caller says the frames are not photon
 * counts.  *src says where they came from (PHOT_*, header RECPHSRC).  A
 * photon count without a gain leaves g = 0 (sequence_powspec measures it).
 * stream_read_noise_adu: the read noise per pixel in s's scaled units
 * (the header's, else the sky's temporal rms), 0 when unknown or when the
 * frames are not photon counts; stream_read_noise also says which
 * (PIPE_RDN_*). */
enum { PHOT_NONE, PHOT_OPTION, PHOT_SIMPHOT, PHOT_GAIN };
int stream_photon_stats(stream *s, const pipeline_opts *o, double *photons,
                        double *g, int *src, sl_err *err);
double stream_read_noise_adu(const stream *s, double photons);
double stream_read_noise(const stream *s, double photons, int *source);

/* The PIPE_SKIP_* bits a run applies (o->skips, or its default). */
int skip_effective(const pipeline_opts *o);
/* Probe the first frames of s (read and cleaned once, kept for replay),
 * then set up selection and crop (s->w x s->h becomes the crop) and, for
 * PIPE_AUTO or the TSM skips, choose the configuration: eo is o with the
 * choice applied, ch what autoconf chose.  photons (per frame) is scaled
 * to the flux inside the crop. */
int skip_apply(stream *s, int has_ref, const pipeline_opts *o, int skips,
               pipeline_opts *eo, autoconf_choice *ch, double *photons,
               sl_err *err);
/* stream_feed for a probed stream: the first pass replays the probed
 * frames and reads on; later passes come from the cache of kept crops, or
 * read again (same verdicts).  Rejected frames are never fed. */
int skip_feed(stream *s, add_fn add, void *h, const char *what, sl_err *err);
/* Frames fed per pass (the kept ones). */
int skip_nkept(const stream *s);
/* The probe, the skips and the choice, for the report. */
void skip_report(const stream *s, const pipeline_opts *o, int skips,
                 const autoconf_choice *ch, pipeline_probe_report *r);
/* A crop-sized image placed, centred, in a new frame-sized one: *img is
 * replaced (and freed). */
int skip_place(const stream *s, float **img, sl_err *err);

/* What the binary measurement sees (pipeline_binary.c): the estimator's
 * spectra (direct: b and the 2-D power spectrum; TSM: t and its polar
 * power spectra), their white-noise level and frame count. */
typedef struct pipe_binary_in {
    bispec *b;
    tsm *t;
    const double *ps2d;      /* w x h, FFT order, bias subtracted */
    double rcut_px;
    const double *ps_polar;  /* tsm_power's layout */
    int nang, nf, nproj;
    double noise, nframes;
} pipe_binary_in;

/* The filled-pupil modulus (pipeline_stf.c): the power spectrum ps and
 * the aligned long exposure's power le (powspec_aligned_power), both
 * w x h, bias-free, with their support and frame count; nthreads (1..64)
 * evaluate the model, the bispectrum's (the result does not depend on
 * it). */
typedef struct pipe_stf_in {
    const double *ps, *le;
    const unsigned char *support;
    int w, h, nframes, nthreads;
} pipe_stf_in;

/* 1 and the corrected modulus in mod when the support is a filled pupil
 * the model can describe, 0 (mod untouched) otherwise; rep->stf_fill and
 * rep->stf_d_r0 say which and why. */
int pipe_stf_modulus(const pipe_stf_in *in, double *mod, pipeline_report *rep);

/* The direct method's default R2: the largest <= 0.14 x the side whose
 * bispectrum (modelled from the support and the cut-off) fits budget_mb;
 * *bounded = 1 when that is smaller (pipeline_r2.c).  snr: the SNR
 * accumulators are kept; batch_bytes: bispec_opts.batch_bytes. */
int pipe_direct_r2(int w, int h, const unsigned char *support, double rcut_px,
                   int snr, double budget_mb, size_t batch_bytes, int *bounded);
/* r2 again when the bispectrum built holds bytes over 1.25 budget: the
 * model was short; r2 itself when it fits. */
int pipe_direct_r2_shrink(int r2, size_t bytes, double budget_mb);

/* Measure the binary on img (w x h, the estimator's own size) with every
 * fit and judge what the data support (pipeline.h, pipeline_binary). */
void pipe_binary_measure(const pipe_binary_in *in, const float *img, int w,
                         int h, pipeline_binary *r);
/* Every keyword of the image header from the typed result, in one place
 * (pipeline_describe.c): the input's keywords (in), then REC*, PREP*,
 * DET*, MEAS*, FR*, CP*.  SL_ERANGE naming the first keyword that did not
 * fit. */
int pipeline_describe(const pipeline_opts *o, const cube_meta *in,
                      pipeline_result *r, sl_err *err);
/* The image's HISTORY: how it was made (the method that ran, the frames
 * used), the inputs (paths, reference, target, bad-pixel map) and the
 * options as asked (`specklab recon`'s names).  SL_ERANGE when it does
 * not fit beside the input's HISTORY. */
int pipeline_history(const char *const *paths, int npaths,
                     const pipeline_opts *asked, pipeline_result *r, sl_err *err);

#endif
