/* probe.h - measure a speckle scene on its first frames, so that the
 * reconstruction can skip what the scene does not need.
 *
 * The probe sees the first nframes cleaned frames of a sequence (probe_add
 * keeps them, so the reconstruction replays them from memory instead of
 * reading them twice), then probe_finish measures:
 *  - frame quality: per frame the flux (sum), the sharpness
 *    sum(I^2) / (sum I)^2 and the saturation plateau (pixels at the
 *    frame's maximum, or repaired by prep as saturated); their medians and
 *    MADs over the probed frames are the reference every frame is judged
 *    against (probe_select): empty (max <= 0 or flux < 5% of the median),
 *    saturated (plateau of >= 4 pixels beyond median + k MAD), flux or
 *    sharpness beyond median +- k MAD (MAD floored at 1% of the median,
 *    because noiseless frames have almost no spread);
 *  - the speckle cloud: the long-exposure image (mean of the probed
 *    frames), its centroid and, at two levels (5e-3 and 3e-2 of the peak
 *    of its azimuthal mean profile, above 5 sigma of the border's noise),
 *    the radius beyond which the profile stays below the level; each
 *    crop is the smallest FFT-friendly square (2^a 3^b 5^c, even) holding
 *    that disc plus a margin for image motion, kept inside the frame, or
 *    none when it would save less than a third of the pixels.  The loose
 *    crop (5e-3) is the default; probe_set_crop takes the tight one;
 *  - on the crop, the mean power spectrum (Tukey window, floor bias): its
 *    measured support radius (powspec_support, in cycles/px), its noise
 *    level and SNR, the cumulative power profile (what the angular model
 *    of autoconf.h integrates) and the image's diameter from the
 *    speckle-averaged autocorrelation (the power spectrum's inverse FFT)
 *    thresholded at extent_level x its peak and 5 sigma of its noise.
 * Cost: the probed frames are stored (nframes x w x h floats; nframes is
 * cut so that they stay under 64 MB), plus one crop-sized FFT per kept
 * probed frame and one inverse FFT.  At 200^2 and 32 probed frames that is
 * ~5 MB and ~2 ms.
 *
 * After probe_finish, probe_select judges frame k (the probed ones were
 * judged by probe_finish), counts the rejections by reason, and copies the
 * crop of a kept frame out; verdicts are remembered, so a second pass over
 * the sequence skips the same frames without recounting.  probe_place puts
 * a crop-sized reconstruction (object at its centre) back at the centre of
 * a frame-sized image.
 */
#ifndef SL_PROBE_H
#define SL_PROBE_H

#include "io/cube.h"
#include "pipeline.h"
#include "prep.h"
#include "status.h"

/* Cumulative power profile: bins of width 0.5 / PROBE_NBIN cycles/px. */
#define PROBE_NBIN 64
/* Crop levels: 0 loose (the default), 1 tight. */
#define PROBE_NCROP 2

enum probe_verdict {
    PROBE_KEEP = 0,
    PROBE_EMPTY,        /* no light: max <= 0 or flux < 5% of the median */
    PROBE_SATURATED,    /* a saturation plateau far beyond the usual */
    PROBE_FLUX,         /* flux beyond median +- k MAD */
    PROBE_SHARP,        /* sharpness beyond median +- k MAD */
    PROBE_NVERDICT
};

typedef struct probe_opts {
    int nframes;          /* frames probed (the first ones); 0: 32 */
    double reject_mad;    /* k of median +- k MAD; 0: 8; < 0: keep all */
    int crop;             /* 1: choose a crop; 0: the whole frame */
    double margin_px;     /* added to the cloud radius; 0: 4 */
    double extent_level;  /* autocorrelation threshold x peak; 0: 0.05 */
    int window;           /* POWSPEC_WIN_*; default TUKEY */
    int spectrum;         /* 1 (default): measure the power spectrum
                           * (support, SNR, profile, extent); 0: only
                           * quality and cloud (saves 1 FFT per frame) */
} probe_opts;

/* What the probe measured; lengths in pixels of the frame, frequencies
 * in cycles per pixel. */
typedef struct probe_scene {
    int width, height, nframes;      /* the sequence (nframes: as read) */
    int nprobed, nprobed_kept;
    /* quality reference over the probed frames */
    double flux_med, flux_mad, sharp_med, sharp_mad, plateau_med, plateau_mad;
    /* the long exposure and the crop */
    double cx_px, cy_px;             /* centroid of the long exposure */
    double cloud_radius_px[PROBE_NCROP];
    int crop_side[PROBE_NCROP];      /* 0: no crop pays at that level */
    int crop_level;                  /* the crop in use */
    int crop_x0, crop_y0, crop_w, crop_h; /* the whole frame: no crop */
    double crop_flux_frac;           /* long-exposure flux inside the crop */
    /* the mean power spectrum of the crop */
    double support_cyc_px;           /* largest radius above the noise */
    double support_frac;             /* fraction of the crop's frequencies
                                      * in the support */
    double noise_level;              /* floor (white noise) power per frame */
    double snr;                      /* sqrt(mean power in the support /
                                      * noise level); 1e6 when noiseless */
    double extent_px;                /* image diameter (autocorrelation) */
    /* pcum[i]: fraction of the power (DC excluded) at radii below
     * (i + 1) * 0.5 / PROBE_NBIN cycles/px */
    double pcum[PROBE_NBIN];
} probe_scene;

typedef struct probe probe;

void probe_opts_defaults(probe_opts *o);
/* w x h frames, nframes_total in the sequence (for the verdicts). */
probe *probe_new(int w, int h, int nframes_total, const probe_opts *o,
                 sl_err *err);
void probe_free(probe *p);
const char *probe_errmsg(const probe *p);

/* Frames the probe still wants (0 once it has nframes). */
int probe_wants(const probe *p);
/* Keep one cleaned frame and its prep report (st may be NULL). */
int probe_add(probe *p, const float *frame, const prep_stats *st);
/* Measure (see above).  SL_EDATA when every probed frame is rejected. */
int probe_finish(probe *p, probe_scene *sc);
/* Switch to crop level (0 loose, 1 tight; crop_side 0 = no crop) and
 * judge the probed frames again on it; only before probe_select has seen
 * a frame beyond the probed ones.  The spectral numbers stay those of the
 * loose crop. */
int probe_set_crop(probe *p, int level);
const probe_scene *probe_result(const probe *p);

int probe_nstored(const probe *p);
const float *probe_stored(const probe *p, int i);

/* Frame k (0-based in the sequence): the verdict, counted once per k; a
 * kept frame's crop goes to out (crop_w x crop_h).  st may be NULL. */
int probe_select(probe *p, int k, const float *frame, const prep_stats *st,
                 float *out);
/* Rejections so far by verdict (counts[PROBE_KEEP] = frames kept). */
void probe_counts(const probe *p, int counts[PROBE_NVERDICT]);
const char *probe_verdict_name(int v);

/* Copy a crop_w x crop_h image, centred, into a zeroed w x h image. */
void probe_place(const probe_scene *sc, const float *crop, float *full);
/* The scene, the crop and the rejections, for the pipeline's report. */
void probe_report_fill(const probe *p, pipeline_probe_report *r);

#endif
