/* bench.h - measuring reconstructions against known truth: simulated data
 * sets on disk, one end-to-end pipeline_run per forked child (wall, CPU,
 * peak memory), error scores and the Pareto front (the time/error chart
 * is drawn by the figure room, figure/chart.h).
 *
 * Why a child per measurement: a process's peak RSS (ru_maxrss) only ever
 * grows, so measuring several configurations in one process would report
 * the largest so far.  Each bench_measure forks, runs the pipeline there
 * and reads the child's own ru_maxrss from wait4(2).  The child first
 * forgets any FFTW wisdom it inherited, so its first run plans from scratch
 * as a fresh `specklab recon` would; later repeats in the same child reuse
 * the in-process wisdom (FFTW_MEASURE then costs nothing), which is what the
 * median of several repeats reports.  A fork copies the parent's page-table
 * entries, so the child's RSS starts at the parent's: bench_baseline_rss_mb
 * measures that floor (a child that does nothing), to be read beside it.
 *
 * Errors of a reconstruction (bench_score_image), against the COPHASED
 * image of the simulation (the object seen through the same pupil without
 * turbulence: what a perfect speckle reconstruction can reach):
 *   c      the paper's correlation coefficient after sub-pixel registration
 *          (metrics_plan_corr_registered); the error is 1 - c;
 *   c_hp   the same registration, then both images high-passed by
 *          subtracting a copy smoothed with a periodic Gaussian of sigma
 *          hp_sigma_px (2 px: about one resolution element at Nyquist
 *          sampling, where lambda/D = 2 px), then c.  It weighs the fine
 *          structure (star cores, bands, fringes) that 1 - c, dominated by
 *          the low-frequency envelope, hardly sees;
 *   binary metrics_binary on the image against the header's BINSEPPX,
 *          BINPA and BINDM: measured minus true separation (px), position
 *          angle (deg, wrapped to (-180, 180]) and dm (mag).
 *
 * Separations are given in lambda/D with D the mask's outer extent (1.1 m
 * for nrm17 at 500 nm: lambda/D = 0.094 arcsec = 2 px at Nyquist).
 */
#ifndef SL_BENCH_H
#define SL_BENCH_H

#include <stdint.h>

#include "pipeline/pipeline.h"
#include "status.h"

/* ---- simulated data sets ---------------------------------------------- */

typedef struct bench_sim {
    const char *scene;          /* point, binary, six-star, extended */
    int width, height, nframes;
    double photons;             /* per frame; 0 = noiseless */
    double sep_lod;             /* binary separation in lambda/D */
    double sep_arcsec;          /* > 0: the separation in arcsec instead */
    double pa_deg, dm_mag;      /* binary position angle and dm */
    uint64_t seed;
    double plate_scale_arcsec;  /* 0 = Nyquist for the mask */
    double r0_m;                /* Fried parameter at the wavelength */
    double wind_mps;
    double frame_interval_s;    /* 0: the simulator's (10 ms) */
    double exposure_s;          /* EXPTIME; 0: the simulator's (10 ms) */
    double saturation_adu;      /* detector clip level (photon frames) */
    double oversample;          /* > 1: sampled this x finer than Nyquist
                                 * (when plate_scale_arcsec is 0) */
    double sampling_nyq;        /* > 0: plate scale = this x Nyquist (0.5
                                 * oversampled, 2 undersampled); wins over
                                 * oversample, loses to plate_scale_arcsec */
    int bad_frames;             /* > 0: that many frames made empty and as
                                 * many saturated (frames 5, 15, 25, ...
                                 * alternately), to exercise rejection */
    /* The pupil: NULL or "nrm17" (the 17-hole mask) or "full", a filled
     * aperture of aperture_m (0: 1.1 m, nrm17's outer extent) with a
     * central obstruction (fraction of the diameter). */
    const char *mask;
    double aperture_m, obstruction;
    int phase_model;            /* SIM_PHASE_SCREEN (0) or SIM_PHASE_PISTON */
    double wavelength_m;        /* 0: 500 nm */
    /* The detector (detector.h; with photons > 0).  0 keeps the
     * simulator's default: gain 1, no read noise, bias, ADC or defects. */
    double read_noise_e, gain_e_per_adu, bias_adu;
    int adc_bits, hot_pixels, dead_pixels;
    /* Pointing (sim.h): scene offset and per-frame jitter rms, px. */
    double offset_x_px, offset_y_px, jitter_px;
    int blind;                  /* write the cube as a camera would (see
                                 * bench_sim_write) */
} bench_sim;

/* The paper's setting: 100 frames of 128^2, 17-hole mask, r0 0.2 m, wind
 * 10 m/s, 500 nm, Nyquist, noiseless; binary 6 lambda/D, PA 30, dm 1;
 * saturation 1e9 ADU (no clipping unless asked for); everything else off. */
void bench_sim_defaults(bench_sim *s);

/* Simulate s into cube_path: the frames (with bad_frames: an empty frame
 * is all zeros, a saturated one the frame x 20 clipped at its own peak,
 * a detector driven far past full well) in the BITPIX the detector asks
 * for (sim_output_bitpix), then the TRUTH and COPHASED image extensions,
 * with a header as `specklab sim` writes it (PLTSCALE, WAVELEN, SIMPHOT,
 * SIMGAIN, SIMSEED, SIMR0, SIMWIND, SIMMASK, NYQUIST, LODPX and, for a
 * binary, BINSEP, BINSEPPX, BINPA, BINDM).
 * Blind (s->blind), as `specklab sim --blind`: the cube holds only the
 * frames under DATE-OBS, EXPTIME and INSTRUME (no SIM*, BIN*, MASK*,
 * NYQUIST, LODPX, PLTSCALE or WAVELEN, no extensions); everything else
 * goes to the sidecar sim_file_sidecar_path(cube_path) (sim_file.h): its primary image is
 * the truth under every keyword above (and SIMADC, SIMNHOT, SIMNDEAD,
 * SIMOFFX/Y, SIMJITT, SIMPHMOD), then TRUTH and COPHASED.
 * psf_path (may be NULL) also receives the COPHASED image alone as a 2-D
 * FITS, which is what pipeline_opts.target_path takes.  Plans with
 * FFTW_ESTIMATE: simulation time is not what is measured.  Frames are
 * streamed to disk. */
int bench_sim_write(const bench_sim *s, const char *cube_path,
                    const char *psf_path, sl_err *err);


/* Set s->gain_e_per_adu so that a camera's operator would not saturate:
 * the brightest pixel of the first 16 frames rendered noiseless (a pilot
 * simulation, same seed) times the photons lands at fill (0..1] of the
 * codes above the bias, full scale being 2^adc_bits - 1 (or the
 * saturation, when lower).  The gain only goes up: a nominal gain that
 * already fits is kept.  No-op for noiseless frames.  *peak_adu (may be
 * NULL) receives that pixel's expected code with the chosen gain. */
int bench_sim_fit_gain(bench_sim *s, double fill, double *peak_adu,
                       sl_err *err);

/* What a reconstruction is scored against, read back from a cube written
 * by bench_sim_write or `specklab sim`, or from a blind cube's sidecar. */
typedef struct bench_truth {
    int width, height;
    float *cophased;            /* width*height, owned */
    int binary;                 /* BINSEPPX, BINPA and BINDM present */
    double sep_px, pa_deg, dm_mag;
    double plate_scale_arcsec;  /* NAN when absent */
    double nyquist_arcsec;      /* NYQUIST; NAN when absent */
} bench_truth;

/* path: a cube with its extensions, or a sidecar.  A blind cube itself is
 * refused (SL_EFORMAT naming its sidecar). */
int bench_truth_read(bench_truth *t, const char *path, sl_err *err);
/* The truth of the blind cube cube_path, from its sidecar. */
int bench_truth_read_sidecar(bench_truth *t, const char *cube_path,
                             sl_err *err);
void bench_truth_clear(bench_truth *t);

/* ---- measurement ------------------------------------------------------- */

#define BENCH_MAX_REPEAT 32

/* The binary verdict of the last run (pipeline_result.binary, copied out
 * of the child): status PIPE_BIN_NONE without closure_binary. */
typedef struct bench_verdict {
    int status, source;         /* enum pipeline_binary_status, _source */
    double sep_px, sep_err_px, pa_deg, pa_err_deg, dm_mag, dm_err_mag;
    char why[96];
} bench_verdict;

typedef struct bench_timing {
    int repeat;                 /* runs made */
    double wall_s, cpu_s;       /* medians over the runs */
    double wall_first_s;        /* the first (cold) run */
    double cpu_first_s;
    double peak_rss_mb;         /* the child's ru_maxrss */
    int nframes, width, height; /* of the reconstruction */
    /* What the pipeline chose, from its header (NAN when absent):
     * RECR2, RECNANG, RECNTRI (direct: closure triangles stored), and
     * with skips (pipeline.h) RECCROPW, RECCUT, RECREJ, RECPRED and the
     * method that ran (RECMETH, enum pipeline_method) and RECCHOSE. */
    double r2_px, nangles, ntriples;
    double crop_px, cutoff_cyc_px, rejected, pred_error;
    int method_run;             /* -1 when unknown */
    /* The closure-phase binary fit (pipeline_opts.closure_binary: CPSEP,
     * CPPA, CPDM); NAN when it did not run or found no binary. */
    double cp_sep_px, cp_pa_deg, cp_dm_mag;
    char chosen[64];            /* "" when nothing was chosen */
    bench_verdict binary;
} bench_timing;

/* Run pipeline_run on cube with o, repeat (1..BENCH_MAX_REPEAT) times in
 * one forked child, timing each run (CLOCK_MONOTONIC; getrusage CPU of
 * all threads).  img (w*h floats, w x h the cube's frame size) receives
 * the last run's image.  Returns SL_OK; the pipeline's own status with its
 * message; SL_EFORMAT when the image is not w x h; SL_EIO when the child
 * could not be started or died ("killed by signal N").  Flushes stdio
 * before forking (buffered output would otherwise be written twice). */
int bench_measure(const char *cube, const pipeline_opts *o, int repeat,
                  float *img, int w, int h, bench_timing *t, sl_err *err);
/* ru_maxrss (MB) of a forked child that exits at once: the floor that
 * every bench_measure peak includes.  NAN if fork fails. */
double bench_baseline_rss_mb(void);

/* ---- scores ------------------------------------------------------------ */

#define BENCH_HP_SIGMA_PX 2.0

typedef struct bench_score {
    double c, c_hp;             /* see the header comment; NAN on failure */
    double shift_x_px, shift_y_px; /* registration shift of img onto truth */
    int binary_found;           /* metrics_binary found two components */
    double sep_px, pa_deg, dm_mag;          /* measured; NAN if none */
    double sep_err_px, pa_err_deg, dm_err_mag; /* measured - truth; NAN
                                                 when not a binary/none */
} bench_score;

/* Every score NAN, binary_found 0 (what a failed run reports). */
void bench_score_init(bench_score *s);
/* Score img (t->width x t->height) against t.  SL_EDATA for non-finite
 * pixels (scores stay NAN); a binary that is not found leaves the binary
 * fields NAN and is not an error. */
int bench_score_image(const float *img, const bench_truth *t,
                      double hp_sigma_px, bench_score *s, sl_err *err);
/* The verdict v against the truth t: measured minus true separation
 * (px), PA (deg) and dm (mag).  Measured: the PA wrapped to (-180, 180],
 * so a companion put on the wrong side reads about 180.  Ambiguous (the PA
 * known modulo 180): wrapped to (-90, 90].  Returns 1 with the three set,
 * or 0 with them NAN (no binary in t, or a verdict of none, unresolved or
 * inconsistent). */
int bench_verdict_errors(const bench_verdict *v, const bench_truth *t,
                         double *dsep_px, double *dpa_deg, double *ddm_mag);

/* out = in - (in smoothed by a periodic Gaussian of sigma_px), separable,
 * truncated at 4 sigma.  in and out may alias.  Cost 2 w h (8 sigma + 1)
 * multiply-adds; allocates one w*h scratch.  SL_EINVAL for sigma <= 0. */
int bench_highpass(const float *in, float *out, int w, int h,
                   double sigma_px);

/* ---- Pareto front ------------------------------------------------------ */

/* front[i] = 1 when no other point is at least as good in both x and y
 * and better in one (smaller is better in both); points with a non-finite
 * coordinate are never on the front and dominate nothing.  Equal points
 * are all on the front.  O(n^2). */
void bench_pareto(const double *x, const double *y, int n,
                  unsigned char *front);

#endif
