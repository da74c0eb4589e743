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

typedef struct fx {
    char dir[64];
    char buf[4][192]; /* scratch paths */
} fx;

static inline int stress_full(void)
{
    const char *v = getenv("SL_STRESS_FULL");
    return v && *v && strcmp(v, "0") != 0;
}

static inline int fx_open(fx *f)
{
    snprintf(f->dir, sizeof f->dir, "/tmp/sl_stressXXXXXX");
    return mkdtemp(f->dir) ? 0 : -1;
}

/* Remove every file in the directory (it holds only our flat files). */
static inline void fx_close(fx *f)
{
    DIR *d = opendir(f->dir);
    struct dirent *e;
    char p[512];
    while (d && (e = readdir(d)))
        if (e->d_name[0] != '.') {
            snprintf(p, sizeof p, "%s/%s", f->dir, e->d_name);
            unlink(p);
        }
    if (d)
        closedir(d);
    rmdir(f->dir);
}

/* f->buf[slot] = dir/name. */
static inline const char *fx_path(fx *f, int slot, const char *name)
{
    snprintf(f->buf[slot], sizeof f->buf[slot], "%s/%s", f->dir, name);
    return f->buf[slot];
}

/* A binary of sep 6 lambda/D, PA 30, dm 1 (bench_sim_defaults) with the
 * given size, frames and photons. */
static inline bench_sim fx_binary(int w, int h, int n, double photons)
{
    bench_sim s;
    bench_sim_defaults(&s);
    s.width = w;
    s.height = h;
    s.nframes = n;
    s.photons = photons;
    return s;
}

static inline int fx_sim(const bench_sim *s, const char *path,
                         const char *psf)
{
    sl_err e = {0};
    int rc = bench_sim_write(s, path, psf, &e);
    if (rc != SL_OK)
        fprintf(stderr, "fx_sim %s: %s\n", path, e.msg);
    return rc;
}

/* Reconstruct with FFTW_ESTIMATE (the stress cases test numbers, not
 * speed); ref/target may be NULL. */
static inline int fx_recon(const char *cube, int method, int nangles,
                           const char *ref, const char *target,
                           pipeline_result *r, sl_err *e)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = method;
    o.nangles = nangles;
    o.ref_path = ref;
    o.target_path = target;
    o.fftw_measure = 0;
    const char *paths[] = {cube};
    return pipeline_run(paths, 1, &o, r, e);
}

static inline int fx_finite(const float *img, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(img[i]))
            return 0;
    return 1;
}

/* Binary errors (measured - true) of img against the truth in cube's
 * header; SL_EDATA when no companion is found. */
static inline int fx_binary_err(const char *cube, const float *img,
                                double *dsep, double *dpa, double *ddm)
{
    bench_truth tr;
    bench_score s;
    sl_err e = {0};
    *dsep = *dpa = *ddm = NAN;
    int rc = bench_truth_read(&tr, cube, &e);
    if (rc != SL_OK)
        return rc;
    rc = bench_score_image(img, &tr, BENCH_HP_SIGMA_PX, &s, &e);
    bench_truth_clear(&tr);
    if (rc != SL_OK)
        return rc;
    if (!s.binary_found)
        return SL_EDATA;
    *dsep = s.sep_err_px;
    *dpa = s.pa_err_deg;
    *ddm = s.dm_err_mag;
    return SL_OK;
}

/* Position is "measurable" within these (looser than the lab bound). */
#define MEAS_SEP_PX 0.5
#define MEAS_PA_DEG 3.0

/* Rewrite cube in to out through fn (keeping the header, dropping the
 * extensions; NaN/Inf allowed in, written as they are). */
static inline int fx_rewrite(const char *in, const char *out,
                             void (*fn)(seq *s, void *u), void *u)
{
    seq *s = NULL;
    cube_meta m;
    sl_err e = {0};
    const char *paths[] = {in};
    int rc = cube_read(&s, &m, paths, 1, CUBE_ALLOW_NONFINITE, &e);
    if (rc == SL_OK) {
        fn(s, u);
        rc = cube_write(out, s, &m, &e);
    }
    if (rc != SL_OK)
        fprintf(stderr, "fx_rewrite %s: %s\n", out, e.msg);
    seq_free(s);
    return rc;
}

/* Every method, for the loops of the edge-case tests. */
static const int fx_methods[] = {PIPE_DIRECT, PIPE_TSM, PIPE_TSM_FOURIER};

#endif
