/* bench_cli.h - `specklab bench` internals shared by cmd_bench.c (the
 * sweeps and measurements) and bench_report.c (table, CSV, chart,
 * catalogue rows, the paper's Table 2 and the scaling summary). */
#ifndef SL_BENCH_CLI_H
#define SL_BENCH_CLI_H

#include "bench.h"
#include "cli.h"

/* One measured point: a data set, a configuration, what was measured. */
typedef struct bcli_row {
    char scene[16];
    int width, height, frames;
    double photons;            /* per frame; 0 = noiseless */
    double sep_lod, pa_deg, dm_mag; /* binary scenes */
    int method;                /* enum pipeline_method */
    int nangles, r2;           /* as requested (0 = the pipeline's default) */
    int ref;                   /* 1: reference sequence + cophased target */
    int repeat, threads;
    int block;                 /* 0 main sweep, 1 paper Table 2, 2 paper
                                  binaries, 3 scaling */
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

/* The speed targets (issue 3: TSM-180 <= 1 s, direct R2 = 28 <= 5 s,
 * peak <= 256 MB; issue 6: TSM-180 <= 0.2 s, TSM-18 <= 0.03 s, direct
 * <= 2 s) against the 200^2, 100-frame binary rows. */
void bcli_print_targets(GArray *rows);

int bcli_write_csv(const char *path, GArray *rows, double base_rss_mb);
int bcli_write_png(const char *path, GArray *rows);
/* Rows into the catalogue's benchmarks table (schema/catalog.h). */
int bcli_write_catalog(const char *path, GArray *rows, double base_rss_mb);

#endif
