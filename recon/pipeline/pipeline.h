/* pipeline.h - reconstruct a frame sequence on disk, end to end.
 *
 * The one entry point the CLI (`specklab recon`) and the daemon share:
 * FITS frames in, a centred 2-D image and its header out.  Frames are
 * streamed (cube_reader), cleaned (prep: sky, NaN/Inf, saturation, bad
 * pixels) and fed to the chosen estimator:
 *   direct       pass 1: power spectrum -> measured Fourier support;
 *                pass 2: direct bispectrum on that support (closure
 *                triangles with |u2| <= R2), phases by weighted phasor
 *                recursion, modulus from the bispectrum's own
 *                photon-corrected power spectrum, or divided by a
 *                reference (point-source) sequence's; optionally a
 *                binary fitted to the triples' closure phases (closure.h);
 *   tsm          Radon projections (spatial, the paper's way), 1-D
 *                bispectra per angle, filtered back projection;
 *   tsm-fourier  the same with projection spectra taken as radial slices
 *                of each frame's 2-D FFT (no spatial Radon);
 *   auto         a scene probe (probe.h) on the first frames measures the
 *                speckle cloud, the Fourier support, the image's extent,
 *                frame quality and SNR, then autoconf.h picks the cheapest
 *                configuration its calibrated model expects to meet
 *                target_error (1 - c), with every skip below on.
 * Skips (PIPE_SKIP_*, each usable with any method): drop
 * empty/saturated/outlier frames, reconstruct on an FFT-friendly crop
 * holding the speckle cloud (the result is placed back, centred, in a
 * frame-sized image), cut TSM's Fourier work at the measured support
 * radius when that is inside Nyquist, and take TSM's projection count from
 * the measured extent.  The probed frames are kept in memory and replayed,
 * so the probe costs no second read; the cropped, kept frames are cached
 * in memory (up to 128 MB) for the direct method's second pass.  With a
 * reference sequence there is no crop (the reference's cloud is
 * elsewhere).  What was measured and chosen goes into the header (RECPRB*,
 * RECCROP*, RECREJ*, RECSUPP, RECEXTNT, RECSNR, RECSKIPS, RECTGERR,
 * RECPRED, RECCHOSE).
 * Photon bias: frames known to be photon counts (SIMPHOT/SIMGAIN in the
 * header, or the caller's photons_per_frame / adu_per_photon) get
 * Wirnitzer's unbiased estimators; otherwise the power-spectrum bias is
 * estimated from the floor beyond the cut-off (direct) or left alone.
 * Memory: one frame plus the estimator's accumulators, independent of the
 * number of frames.
 */
#ifndef SL_PIPELINE_H
#define SL_PIPELINE_H

#include "measure/binary.h"
#include "spectra/closure.h"
#include "io/cube.h"
#include "spectra/fringe.h"
#include "status.h"

enum pipeline_method {
    PIPE_DIRECT = 0, PIPE_TSM = 1, PIPE_TSM_FOURIER = 2, PIPE_AUTO = 3
};

enum pipeline_skip {
    PIPE_SKIP_REJECT = 1,   /* drop empty, saturated and outlier frames */
    PIPE_SKIP_CROP = 2,     /* reconstruct on a crop of the speckle cloud */
    PIPE_SKIP_SUPPORT = 4,  /* TSM cut-off at the measured support */
    PIPE_SKIP_ANGLES = 8,   /* TSM projections from the measured extent */
    PIPE_SKIP_ALL = 15
};

/* A run split over processes, e.g. MPI ranks (pipeline_share.c).  Every
 * process calls pipeline_run with the same paths and options; process
 * rank of nranks accumulates only frames [n rank / nranks, n (rank + 1) /
 * nranks) of the n in the sequence (its own range: it reads no other),
 * and wherever an estimator's sums are complete the hooks make them whole:
 *   reduce: replace sums[0..n) on every process by the element-wise sum
 *           of every process's, added in rank order (pipeline_sums_merge,
 *           once per rank, 0 first) whatever order they arrive in, so the
 *           image depends on the ranges, not on timing.  last: these are
 *           the run's final sums and only rank 0 needs their total (the
 *           others' part is done: they may return SL_EEND, and their
 *           pipeline_run then stops with SL_EEND, having no image);
 *   agree:  replace buf on every process by rank 0's: decisions (auto's
 *           choice) are taken once, on rank 0.
 * Every process calls them at the same points in the same order; they
 * return SL_OK or an error code, with which the run stops.  What each
 * process computes from the first frames alone (the scale, the detector,
 * the scene probe's crop and frame-quality reference) is the same
 * deterministic function of the same frames everywhere, and is checked
 * against rank 0's (agree; SL_EDATA naming the rank when it differs).  Rank 0 ends
 * with the image and header; a process whose hook ends its part early
 * gets SL_EEND. */
typedef struct pipeline_share {
    int rank, nranks;
    int (*reduce)(void *ctx, double *sums, size_t n, int last);
    int (*agree)(void *ctx, void *buf, size_t bytes);
    void *ctx;
} pipeline_share;

/* acc[i] += part[i], i < n: the merge, called once per part in a fixed
 * (rank) order. */
void pipeline_sums_merge(double *acc, const double *part, size_t n);

/* The direct method's default memory bound for its bispectrum: 448 MB
 * keeps 1024^2 frames under 1 GB in all (pipeline_r2.c). */
#define PIPE_BISPEC_MEM_MB 448.0

typedef struct pipeline_opts {
    int method;               /* enum pipeline_method; default PIPE_AUTO */
    int nangles;              /* TSM projections; 0 = 180 */
    int r2_px;                /* direct: |u2| radius; 0 = 0.14 min(w, h),
                               * bounded by bispec_mem_mb */
    double bispec_mem_mb;     /* direct, default R2: the bispectrum's
                               * memory bound; 0 = PIPE_BISPEC_MEM_MB */
    int window;               /* POWSPEC_WIN_*; default TUKEY */
    double tukey_alpha;       /* default 0.25 */
    int prep;                 /* clean frames first (default 1) */
    int detect;               /* learn the detector from the raw frames
                               * (rawstats.h): bad pixels, saturation,
                               * sky, the cloud (default 1) */
    int learn_badpix;         /* learn from every frame, not the first 32 */
    int recentre;             /* recentre frames on the cloud (default 1;
                               * needs detect) */
    const char *badpix_path;  /* a bad-pixel map (FITS, nonzero = bad) */
    /* Calibration frames, each a FITS image or a cube (averaged): a dark
     * (or bias) in the frames' ADU, subtracted; a flat field, already
     * dark-subtracted, divided after normalising to mean 1.  NULL: none. */
    const char *dark_path;
    const char *flat_path;
    /* The flat's own dark (a flat run straight from the camera carries
     * the bias): subtracted from the flat before it is normalised.  NULL:
     * the flat is already dark-subtracted. */
    const char *flat_dark_path;
    double saturation_adu;    /* raw values >= this are repaired; 0 = none */
    /* Photon statistics: > 0 given; 0 = from the header (SIMPHOT,
     * SIMGAIN) when present; < 0 = treat the data as not photon counts. */
    double photons_per_frame;
    double adu_per_photon;
    const char *ref_path;     /* point-source reference sequence, or NULL */
    /* With a reference: the PSF wanted in the result (a 2-D FITS image,
     * e.g. a cophased point source), or NULL for the object itself
     * band-limited at the cut-off. */
    const char *target_path;
    double wiener;            /* reference regulariser; 0 = default */
    int nthreads;             /* threads: direct bispectrum, 0 = 2; TSM
                               * (tsm.h), 0 = online CPUs, at most 4 */
    int phase_weight;         /* direct: PHASOR_WEIGHT_* of the phase
                               * recursion and refinement; -1 (default):
                               * |B| for the recursion, and for the
                               * refinement SNR on noisy data (pipeline.c) */
    int refine_iters;         /* direct: least-squares passes after the
                               * recursion; -1 (default): as its misfit
                               * asks (phasor.h) */
    int fftw_measure;         /* 1 = FFTW_MEASURE (default), 0 = ESTIMATE */
    int skips;                /* PIPE_SKIP_* bits; -1 (default): all of them
                               * for PIPE_AUTO, none for the other methods */
    double target_error;      /* auto and PIPE_SKIP_ANGLES: the 1 - c wanted
                               * against the cophased image; 0: 0.1 */
    int tsm_inverse;          /* TSM_INV_* (tsm.h); 0: FBP */
    int tsm_corrected_phases; /* TSM phases from the photon-bias-corrected
                               * bispectrum, SNR^2-weighted (tsm.h, Bias:
                               * better dm at >= ~1e4 photons/frame, worse
                               * below); 0: the raw bispectrum */
    double cutoff_cyc_px;     /* TSM cut-off; 0: Nyquist, or the measured
                               * support with PIPE_SKIP_SUPPORT */
    int stf_model;            /* direct without a reference, on a filled
                               * pupil: divide a modelled speckle transfer
                               * function out of the modulus (default 1) */
    /* Progress, for a person waiting: called from pipeline_run's thread
     * with every frame fed to an estimator (done and an estimate of the
     * total, in frames fed; the total can grow as the run learns its plan,
     * so a display must not let the fraction go back) and what is being
     * accumulated ("power spectrum", "bispectrum", "projections").  NULL:
     * none.  Cost: one call per frame. */
    void (*progress)(void *ctx, double done, double total, const char *what);
    void *progress_ctx;
    int closure_binary;       /* also fit a binary to the closure phases of
                               * direct's bispectrum or TSM's 1-D ones
                               * (closure.h) into the header:
                               * CPSEP, CPPA, CPDM (+E: 1-sigma errors),
                               * CPAMBIG, CPNTRI, CPNFREQ, CPRMS, CPSTAT */
    const pipeline_share *share; /* NULL (default): one process */
} pipeline_opts;

/* The binary a reconstruction measured (closure_binary), and what the
 * data support of it (pipeline_binary.c): */
enum pipeline_binary_status {
    PIPE_BIN_NONE = 0,      /* not asked for */
    PIPE_BIN_MEASURED,      /* sep, PA and dm with their errors */
    PIPE_BIN_AMBIGUOUS,     /* the PA is known modulo 180 deg */
    PIPE_BIN_UNRESOLVED,    /* no companion above the noise */
    PIPE_BIN_INCONSISTENT   /* the fits disagree beyond their errors */
};
enum pipeline_binary_source {
    PIPE_BIN_SRC_NONE = 0, PIPE_BIN_SRC_CLOSURE, PIPE_BIN_SRC_IMAGE,
    PIPE_BIN_SRC_FRINGE
};

typedef struct pipeline_binary {
    int status, source;       /* enum pipeline_binary_status, _source */
    double sep_px, sep_err_px, pa_deg, pa_err_deg, dm_mag, dm_err_mag;
    char why[96];             /* what keeps it from "measured", or "" */
    int have_image, have_closure, have_fringe, fringe_ran;
    binary_result image, closure;     /* binary.h, closure.h */
    closure_fit_info closure_info;
    fringe_result fringe;             /* fringe.h */
} pipeline_binary;

const char *pipeline_binary_status_name(int status);
const char *pipeline_binary_source_name(int source);

/* What a run measured and chose, typed: pipeline_run fills it and writes
 * the image's keywords from it, in one place (pipeline_describe.c);
 * nobody needs to parse them back.  Fields that do not apply are 0. */
enum pipeline_photon_source {
    PIPE_PHOT_NONE = 0, PIPE_PHOT_OPTION, PIPE_PHOT_SIMPHOT, PIPE_PHOT_GAIN
};
/* Where the read noise of photon-count frames came from: none (the
 * frames are not photon counts, or nothing says), the header (SIMRDN,
 * RDNOISE), or the sky's temporal rms in the raw frames. */
enum pipeline_rdn_source { PIPE_RDN_NONE = 0, PIPE_RDN_HEADER, PIPE_RDN_SKY };
/* Where the detector's gain came from: the caller (--adu-per-photon), the
 * header (GAIN, SIMGAIN), the flux over a known photon count, or the
 * data alone: the power spectrum's white floor against the flux, less
 * the sky's white noise (powspec_floor_gain; direct only, Nyquist or
 * finer sampling). */
enum pipeline_gain_source {
    PIPE_GAIN_NONE = 0, PIPE_GAIN_OPTION, PIPE_GAIN_HEADER, PIPE_GAIN_FLUX,
    PIPE_GAIN_FLOOR
};
const char *pipeline_gain_source_name(int source);

typedef struct pipeline_prep_report {   /* the cleaning (prep.h) */
    int on;                   /* frames were cleaned at all */
    int dark, flat;           /* 1: subtracted, divided */
    int sky;                  /* 0 none, 1 border median, 2 sky-mask mean,
                               * 3 none because a dark was given */
    int border_px;            /* the border band of the median */
    double saturation_adu;    /* raw values >= this repaired; 0: none */
    int nbad;                 /* pixels in the bad-pixel map */
    int recentred;            /* frames shifted onto the cloud */
} pipeline_prep_report;

typedef struct pipeline_detector_report { /* learnt from raw frames */
    int learnt, nframes;      /* frames it learnt from */
    int nstuck, nhot, ndead;  /* bad pixels found, repaired */
    double sat_level_adu;     /* 0: no clip level found */
    int sat_source;           /* 0 none, 1 file type, 2 ADC 2^k-1, 3 flat top */
    double quantum_adu;       /* the data's step; 0 real-valued */
    double sky_adu, sky_rms_adu; /* raw sky level and temporal rms */
    double cx_px, cy_px;      /* the cloud's raw centre (0-based) */
} pipeline_detector_report;

typedef struct pipeline_probe_report {  /* the skips and auto */
    int skips;                /* PIPE_SKIP_* applied */
    int probed;               /* frames probed; 0: no probe ran */
    int crop_x0, crop_y0, crop_w, crop_h;
    double cloud_radius_px, cloud_level, crop_flux_frac;
    int spectrum;             /* the next four were measured */
    double support_cyc_px, support_frac, extent_px, snr;
    int rejected[5];          /* kept, empty, saturated, flux, sharpness */
    double reject_mad;        /* k of median +- k MAD; < 0 keep all */
    int chosen;               /* auto chose what follows */
    char chosen_label[64];
    double target_error, pred_error, pred_cost_s;
} pipeline_probe_report;

/* Where pipeline_run's wall time went (pipeline_report.stage_s; bench
 * --scaling prints it per thread count). */
enum pipeline_stage {
    PIPE_STAGE_OPEN = 0,  /* open, learn the detector, probe (auto, skips) */
    PIPE_STAGE_PLAN,      /* the estimator's FFT plans and tables (direct:
                           * R2, the triple list) */
    PIPE_STAGE_READ,      /* read and clean the frames, every pass */
    PIPE_STAGE_FRAME,     /* per frame: FFTs, projections, the sums
                           * (direct: less the triple kernel) */
    PIPE_STAGE_ACCUM,     /* direct: the bispectrum's triple kernel */
    PIPE_STAGE_SOLVE,     /* the image from the sums: phases, modulus,
                           * inverse */
    PIPE_STAGE_MEASURE,   /* the binary fits (--binary) */
    PIPE_NSTAGES
};
const char *pipeline_stage_name(int stage);

typedef struct pipeline_report {
    int method;               /* what ran: auto's choice applied */
    double stage_s[PIPE_NSTAGES]; /* wall seconds per enum pipeline_stage */
    int nframes_in;           /* frames in the sequence */
    double photons;           /* per frame for the bias; 0 unknown */
    int photon_source;        /* enum pipeline_photon_source */
    double read_noise_adu;    /* per pixel, for the photon bias; 0 none */
    int read_noise_source;    /* enum pipeline_rdn_source */
    double gain_e_per_adu;    /* detector gain (raw ADU); 0 unknown */
    int gain_source;          /* enum pipeline_gain_source */
    double scale;             /* frames x this (power of 2) for the sums */
    /* direct */
    int window;               /* POWSPEC_WIN_* */
    int r2_px;
    double r2_bound_mb;       /* R2 bounded by this memory (MB); 0 = not */
    double rcut_px;           /* measured Fourier cut-off */
    long ntriples;            /* closure triangles stored */
    double gain_adu;          /* photon-bias gain; 0 = floor */
    double misfit;            /* phase recursion's closure misfit */
    double support_snr;       /* power-spectrum SNR over the support */
    double stf_fill;          /* support's fill inside 0.8 of the cut-off */
    double stf_d_r0;          /* filled pupil: the D/r0 of the STF divided
                               * out (pipeline_stf.c); 0 = none */
    /* TSM */
    int nangles, npairs;
    double cutoff_cyc_px;
    int inverse;              /* TSM_INV_* */
    int corrected_phases;     /* phases from the corrected bispectrum */
    double arc_bins, tsm_extent_px;
    int bias_photon;          /* white-noise bias from photons, not floor */
    double noise_level;
    pipeline_prep_report prep;
    pipeline_detector_report detector;
    pipeline_probe_report probe;
} pipeline_report;

const char *pipeline_photon_source_name(int source);

typedef struct pipeline_result {
    int width, height;        /* the image: same size as a frame */
    int nframes;              /* frames used */
    float *image;             /* width*height, object centred at (w/2, h/2) */
    double elapsed_s;         /* wall time of pipeline_run */
    double plate_scale_arcsec;/* from the input header; NAN when unknown */
    cube_meta meta;           /* header for the image (input's + ours),
                               * written from report and binary */
    pipeline_report report;   /* what was measured and chosen */
    pipeline_binary binary;   /* with closure_binary; status NONE else */
} pipeline_result;

void pipeline_opts_defaults(pipeline_opts *o);
/* Options that cannot make sense, before any data is read: SL_EINVAL
 * naming the option and its value (pipeline_check.c gives the limits). */
int pipeline_opts_check(const pipeline_opts *o, sl_err *err);
/* The options against the data: what (a path, for the message) holds
 * nframes of width x height.  SL_EDATA for fewer than 2 frames, SL_EINVAL
 * for a bispectrum radius past Nyquist or more projections than the frame
 * resolves.  pipeline_run calls both. */
int pipeline_check_data(const pipeline_opts *o, const char *what, int width,
                        int height, int nframes, sl_err *err);
int pipeline_method_parse(const char *name, int *method);
const char *pipeline_method_name(int method);
/* One option by the CLI's long name without "--" ("skips", "r2-px",
 * "binary", ...) and its value as text ("" or "true" for a flag, "false"
 * leaves it): SL_EINVAL naming the option and the value, or the choices,
 * on bad syntax; ranges are pipeline_opts_check's.  Files (--ref, --dark,
 * ...) are not options here: they are paths on the caller's machine.
 * The CLI parses its command line through it, and specklabd a client's
 * options for a catalogued run (pipeline_optset.c). */
int pipeline_opts_set(pipeline_opts *o, const char *name, const char *value, sl_err *err);
/* The i-th name pipeline_opts_set knows (NULL past the last); *is_flag
 * (may be NULL) 1 for an option without a value. */
const char *pipeline_opts_name(int i, int *is_flag);
/* "crop,reject,support,angles", "all" or "none" -> PIPE_SKIP_* bits. */
int pipeline_skips_parse(const char *list, int *skips);
/* The bits as that list (buf of n >= 32 chars). */
void pipeline_skips_name(int skips, char *buf, int n);

/* Reconstruct paths[0..npaths) (a cube, a frame, or a list/glob of frames,
 * as cube_reader_open takes them).  On success out owns the image: free it
 * with pipeline_result_clear.  Errors name the file and the stage. */
int pipeline_run(const char *const *paths, int npaths,
                 const pipeline_opts *o, pipeline_result *out, sl_err *err);
void pipeline_result_clear(pipeline_result *r);

#endif
