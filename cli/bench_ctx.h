/* bench_ctx.h - the state `specklab bench` carries through a run, shared
 * by cmd_bench.c (options, sweeps, outputs) and bench_dataset.c (one data
 * set simulated and every configuration measured on it).  Not a public
 * header. */
#ifndef SL_BENCH_CTX_H
#define SL_BENCH_CTX_H

#include <glib.h>

#include "bench_cli.h"

typedef struct bench_args {
    gboolean quick, paper, speed, skips_report, estimate, keep_data, blind, overwrite, mpi;
    gboolean scaling;
    char *scenes, *sizes, *frames, *photons, *methods, *projections, *r2;
    char *seps, *dms, *ref, *csv, *png, *catalog, *dir, *targets, *skips;
    char *conditions, *md;
    char *command;        /* the command line, for --md's heading */
    int repeat, threads;
    gint64 seed;
    double interval_ms;   /* 0: the simulator's */
} bench_args;

/* A point-source reference sequence (and its cophased PSF) simulated once
 * per geometry and reused by every configuration with --ref. */
typedef struct refset {
    int w, h, n;
    double photons;
    char *cube, *psf;
} refset;

struct bcli_ctx {
    const bench_args *a;
    char *dir;
    GArray *rows;      /* bcli_row */
    GArray *refs;      /* refset */
    int ndata;         /* data sets simulated (file names) */
    int failures;
};

#endif
