/* bench_cli.h - `specklab bench` internals shared by cmd_bench.c (the
 * sweeps and measurements) and bench_report.c (table, CSV, chart,
 * catalogue rows, the paper's Table 2 and the scaling summary). */
#ifndef SL_BENCH_CLI_H
#define SL_BENCH_CLI_H

#include "bench/bench.h"
#include "cli.h"

/* A configuration to measure on a data set. */
typedef struct bcli_config {
    int method, param, ref; /* param: R2 (direct) or projections (TSM) */
    int skips;              /* PIPE_SKIP_* bits; -1: the method's default */
    double target;          /* auto: the 1 - c wanted; 0: the default */
    int inverse;            /* TSM: TSM_INV_* (0: FBP) */
} bcli_config;

/* Option lists (bench_args.c): append the parsed values to out; 0, or 2
 * after printing what is wrong.  Sizes go in as (w, h) pairs; skip sets
 * are "crop,support/none/all/default" (NULL: one set, the default -1). */
int bcli_parse_ints(const char *what, const char *s, int lo, int hi,
                    GArray *out);
int bcli_parse_doubles(const char *what, const char *s, GArray *out);
int bcli_parse_sizes(const char *s, GArray *out);
int bcli_parse_skip_sets(const char *s, GArray *out);

/* The sweep runner's state (cmd_bench.c). */
typedef struct bcli_ctx bcli_ctx;

/* Simulate data set d (once) and measure each configuration on it that
 * was not measured before; block tags the rows (see bcli_row).  0 or 1
 * (failed: counted and reported). */
int bcli_run_dataset(bcli_ctx *c, const bench_sim *d, const bcli_config *cf,
                     int ncf, int block);

/* One measured point: a data set, a configuration, what was measured. */
typedef struct bcli_row {
    char scene[16];
    int width, height, frames;
    double photons;            /* per frame; 0 = noiseless */
    double sep_lod, pa_deg, dm_mag; /* binary scenes */
    int method;                /* enum pipeline_method */
    int nangles, r2;           /* as requested (0 = the pipeline's default) */
    int inverse;               /* TSM: TSM_INV_* as requested (0: FBP) */
    int ref;                   /* 1: reference sequence + cophased target */
    int skips;                 /* requested PIPE_SKIP_* bits, -1: default */
    double target;             /* auto: requested target 1 - c (0: 0.1) */
    int inject;                /* data set with injected bad frames */
    double oversample;         /* data set sampled this x finer than Nyquist */
    int repeat, threads;
    int block;                 /* 0 main sweep, 1 paper Table 2, 2 paper
                                  binaries, 3 scaling, 4 skips report */
    bench_timing t;
    bench_score s;
    bench_score floor;         /* the cophased image itself: the metric's
                                  own error, a floor for every method */
    int status;                /* SL_OK or the failure's code */
    char msg[SL_ERRMSG_MAX];
    int group;                 /* data set index: the Pareto front's scope */
    int front;
} bcli_row;

/* Label of a row's configuration: "direct R2=16", "tsm 180", ... (the
 * values the pipeline reported, else the requested ones). */
void bcli_config_label(const bcli_row *r, char *buf, size_t n);
void bcli_print_header(void);
void bcli_print_row(const bcli_row *r);

/* Number the data sets (scene, size, frames, photons, binary geometry)
 * and mark each one's Pareto front of (median wall time, 1 - c). */
void bcli_mark_fronts(GArray *rows);
void bcli_print_fronts(GArray *rows);
/* Log-log slopes of time against frames, pixels and projections, where a
 * sweep varies one of them with the rest fixed, beside the cost model. */
void bcli_print_scaling(GArray *rows);
/* The paper's Table 2 layout (block 1 rows) and the binaries table
 * (block 2 rows). */
void bcli_print_paper(GArray *rows);

/* The speed targets (loose: TSM-180 <= 1 s, direct R2 = 28 <= 5 s,
 * peak <= 256 MB; tight: TSM-180 <= 0.2 s, TSM-18 <= 0.03 s, direct
 * <= 2 s) against the 200^2, 100-frame binary rows. */
void bcli_print_targets(GArray *rows);

/* The skips preset (bench_skips.c): data sets and configurations, then
 * the report of each skip on/off (time saved, error cost) and where auto
 * lands against the Pareto front. */
int bcli_run_skips(bcli_ctx *c);
void bcli_print_skips(GArray *rows);
/* For every auto row: on its data set's front, or the front point that
 * dominates it. */
void bcli_print_auto(GArray *rows);

int bcli_write_csv(const char *path, GArray *rows, double base_rss_mb);
int bcli_write_png(const char *path, GArray *rows);
/* The streamed table in Markdown (bench_md.c): the command that wrote it,
 * then one row per point, as in the CSV. */
int bcli_write_md(const char *path, GArray *rows, const char *command);
/* Rows into the catalogue's benchmarks table (schema/catalog.h). */
int bcli_write_catalog(const char *path, GArray *rows, double base_rss_mb);

#endif
