/* bench_blind.h - `specklab bench --blind`: the reconstructor with default
 * options on camera-like cubes it did not make.
 *
 * Every cube of the matrix is written blind (bench_sim_write: no SIM*,
 * BIN*, MASK*, NYQUIST, LODPX, PLTSCALE or WAVELEN keyword, no extension;
 * the truth in a sidecar), with the detector on.  A baseline (128^2, 100
 * frames, binary 6 lambda/D at PA 57 and dm 1, 2e4 photons, gain 2 e-/ADU,
 * read noise 3 e-, bias 100 ADU, 12 bits, nrm17, screen phases, r0 0.2 m,
 * Nyquist, centred) is varied one factor at a time, then a few combined
 * camera conditions (blind_matrix lists them).  Gain: the baseline's 2
 * e-/ADU unless the brightest noiseless pixel of the first 16 frames
 * would pass half the codes above the bias; then raised until it lands
 * there (bench_sim_fit_gain), as an operator would.  Bias: 100 ADU of
 * 4095, scaled with the converter's range (8 bits: 6 ADU; 16: 1600).
 *
 * Each condition is reconstructed by each method (direct, tsm-fourier,
 * tsm, auto) with pipeline_opts_defaults plus closure_binary, in a forked
 * child (bench_measure), and scored: c against the sidecar's cophased
 * image (bench_score_image), the binary verdict's errors
 * (bench_verdict_errors: PA modulo 180 when ambiguous), auto's predicted
 * and achieved 1 - c.  bench_blind.c runs the matrix; bench_blind_report.c
 * prints the table and the summary and writes the CSV.
 */
#ifndef SL_BENCH_BLIND_H
#define SL_BENCH_BLIND_H

#include <stdint.h>

#include "bench/bench.h"
#include "cli.h"

/* The summary's bounds on a binary verdict. */
#define BLIND_SEP_TOL_PX 0.15
#define BLIND_PA_TOL_DEG 0.5
#define BLIND_DM_TOL_MAG 0.1
/* auto "missed": its c below this while a fixed method reached the other. */
#define BLIND_AUTO_LOW_C 0.85
#define BLIND_FIXED_GOOD_C 0.95
/* Gain: the brightest pixel at this fraction of the codes above the bias. */
#define BLIND_PEAK_FILL 0.5
#define BLIND_MAX_CONDITIONS 40
#define BLIND_NAME_MAX 24

typedef struct blind_cond {
    char name[BLIND_NAME_MAX]; /* one token: "baseline", "photons-1e3" */
    int quick;                 /* in --quick's subset */
    bench_sim sim;             /* blind; gain before bench_sim_fit_gain */
} blind_cond;

/* The matrix in table order into out[0..max); returns the count.  quick:
 * only the --quick subset (baseline, hot10+offset32, full+adc8,
 * six-star-piston).  Every condition uses seed. */
int blind_matrix(int quick, uint64_t seed, blind_cond *out, int max);

typedef struct blind_opts {
    int quick;
    const char *csv;        /* NULL: out/bench/blind.csv (quick:
                             * out/bench/blind-quick.csv); "none": no CSV */
    const char *dir;        /* keep the cubes and sidecars here; NULL: a
                             * temporary directory, removed */
    const char *methods;    /* NULL: "direct,tsm-fourier,tsm,auto" */
    const char *conditions; /* NULL: every condition of the preset */
    const char *target;     /* auto's target 1 - c; NULL: the default 0.1 */
    int repeat, threads, estimate;
    uint64_t seed;
    int other_options;      /* options of the other presets were given:
                             * refused */
    int overwrite;          /* replace an existing CSV (cli/outfile.h) */
} blind_opts;

/* One condition x method. */
typedef struct blind_row {
    char cond[BLIND_NAME_MAX];
    bench_sim sim;          /* as simulated (gain fitted) */
    double peak_adu;        /* the fitted gain's expected brightest code */
    int truth_binary;
    double true_sep_px, true_pa_deg, true_dm_mag;
    double plate_scale_arcsec, sampling_nyq;
    int method;             /* enum pipeline_method, as requested */
    double target;          /* auto's target 1 - c (0.1 by default) */
    bench_timing t;
    bench_score s;          /* c, c_hp and the image fit (metrics_binary) */
    double dsep_px, dpa_deg, ddm_mag; /* the verdict's errors, or NAN */
    int within, oriented;   /* within the bounds; and measured (PA right,
                             * not taken modulo 180) */
    int status;             /* SL_OK or the failure's code */
    char msg[SL_ERRMSG_MAX];
} blind_row;

/* Run the matrix: the table on stdout, then the summary, then the CSV.
 * Failed points are rows with their status, not an early exit.  0 when it
 * ran, 1 when the CSV or the work directory could not be written, 2 for
 * bad options (printed). */
int blind_run(const blind_opts *o);

/* bench_blind_report.c */
void blind_print_header(void);
void blind_print_row(const blind_row *r);
/* Per method: binary within the bounds / PA right, not flipped, over the
 * conditions with a binary; median 1 - c; for auto the target met and
 * the misses where a fixed method did well; then which conditions each
 * method got wrong. */
void blind_print_summary(const blind_row *rows, int n, const int *methods,
                         int nmethods);
/* One header line, one line per row; strings with ',' replaced by ';' so
 * every line splits on commas.  0, or 1 after printing why. */
int blind_write_csv(const char *path, const blind_row *rows, int n);

#endif
