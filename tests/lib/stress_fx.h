/* stress_fx.h - fixtures shared by the stress tests (tests/stress): a
 * temporary directory per test, simulated cubes with known truth
 * (bench_sim_write), reconstructions and binary errors.
 *
 * SL_STRESS_FULL=1 (make stress) turns on the slower variants.  Each test
 * body takes the fixture and may CHECK-return early; its TEST wrapper then
 * removes the directory, so a failing case leaves nothing behind.
 */
#ifndef SL_STRESS_FX_H
#define SL_STRESS_FX_H

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench/bench.h"
#include "io/cube.h"
#include "measure/metrics.h"
#include "pipeline/pipeline.h"
#include "tcheck.h"
#include "tmpdir_fx.h"

/* The test's scratch directory: tmpdir_fx.h's, under the stress suite's
 * names. */
typedef tmpdir fx;

int stress_full(void);

/* 0, or -1 when mkdtemp failed. */
int fx_open(fx *f);

/* Remove every file in the directory (it holds only our flat files). */
void fx_close(fx *f);

/* f->path[slot] = dir/name. */
const char *fx_path(fx *f, int slot, const char *name);

/* A binary of sep 6 lambda/D, PA 30, dm 1 (bench_sim_defaults) with the
 * given size, frames and photons. */
bench_sim fx_binary(int w, int h, int n, double photons);

int fx_sim(const bench_sim *s, const char *path, const char *psf);

/* Reconstruct with FFTW_ESTIMATE (the stress cases test numbers, not
 * speed); ref/target may be NULL. */
int fx_recon(const char *cube, int method, int nangles, const char *ref, const char *target,
             pipeline_result *r, sl_err *e);

int fx_finite(const float *img, size_t n);

/* Binary errors (measured - true) of img against the truth in cube's
 * header; SL_EDATA when no companion is found. */
int fx_binary_err(const char *cube, const float *img, double *dsep, double *dpa, double *ddm);

/* Position is "measurable" within these (looser than the lab bound). */
#define MEAS_SEP_PX 0.5
#define MEAS_PA_DEG 3.0

/* Rewrite cube in to out through fn (keeping the header, dropping the
 * extensions; NaN/Inf allowed in, written as they are). */
int fx_rewrite(const char *in, const char *out, void (*fn)(seq *s, void *u), void *u);

/* Every method, for the loops of the edge-case tests. */
static const int fx_methods[] = {PIPE_DIRECT, PIPE_TSM, PIPE_TSM_FOURIER};

#endif
