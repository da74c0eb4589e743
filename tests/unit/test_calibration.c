/* test_calibration.c - dark and flat frames through pipeline_run.
 *
 * Truth: a simulated binary cube S.  The raw cube is S x F + D with a
 * vignetting flat F (mean 1, +-30 %) and a dark D with a strong gradient,
 * both known exactly; the dark is given as a stack of two frames that
 * average to D, the flat as one image at 3x its scale (pipeline
 * normalises it).  Calibrated, the frames are S again up to float
 * rounding, so the image must equal S's (reconstructed with a zero dark,
 * so that neither run subtracts a sky) to c >= 0.99999; uncalibrated, the
 * gradient and the vignetting must cost visibly more (c 0.49 here).  Bad calibration
 * files are refused by name.
 */
#include <stdlib.h>
#include <unistd.h>

#include <fftw3.h>

#include "io/cube.h"
#include "measure/metrics.h"
#include "pipeline/pipeline.h"
#include "sim/sim.h"
#include "tcheck.h"

#define N 64
#define NF 24

typedef struct cal_fx {
    char dir[64], clean[96], raw[96], dark[96], flat[96], small[96], zero[96];
    char rawflat[96];   /* the flat as a camera gives it: with the dark */
} cal_fx;

static double flat_at(int x, int y)
{
    double r2 = ((x - N / 2.0) * (x - N / 2.0) + (y - N / 2.0) * (y - N / 2.0)) /
                (N * N / 4.0);
    return 1.3 - 0.6 * r2;
}

static double dark_at(int x, int y)
{
    return 50 + 2.0 * x + 0.5 * y;
}

/* The flat as written: 3 x the (unnormalised) profile. */
static int write_calibrations(cal_fx *f)
{
    sl_err e;
    cube_meta m;
    cube_meta_init(&m);
    seq *d = seq_new(N, N, 2), *fl = seq_new(N, N, 1), *sm = seq_new(N / 2, N / 2, 1);
    seq *z = seq_new(N, N, 1), *rf = seq_new(N, N, 1);
    for (int i = 0; i < N * N; i++)
        z->data[i] = 0;
    for (int y = 0; y < N; y++)
        for (int x = 0; x < N; x++) {
            double dv = dark_at(x, y), wob = ((x + y) % 3) - 1;
            d->data[y * N + x] = (float)(dv + wob);
            d->data[N * N + y * N + x] = (float)(dv - wob);
            fl->data[y * N + x] = (float)(3 * flat_at(x, y));
            rf->data[y * N + x] = (float)(3 * flat_at(x, y) + dv);
        }
    for (int i = 0; i < N * N / 4; i++)
        sm->data[i] = 1;
    int rc = cube_write(f->dark, d, &m, &e) | cube_write(f->flat, fl, &m, &e) |
             cube_write(f->small, sm, &m, &e) | cube_write(f->zero, z, &m, &e) |
             cube_write(f->rawflat, rf, &m, &e);
    seq_free(rf);
    seq_free(z);
    seq_free(d);
    seq_free(fl);
    seq_free(sm);
    return rc;
}

/* The clean cube and the raw one (S x F_normalised + D). */
static int write_cubes(cal_fx *f)
{
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    cube_writer *wc = NULL, *wr = NULL;
    sim_opts o;
    sim_opts_defaults(&o);
    o.width = o.height = N;
    o.nframes = NF;
    o.seed = 3;
    o.fftw_flags = FFTW_ESTIMATE;
    double fmean = 0;
    for (int y = 0; y < N; y++)
        for (int x = 0; x < N; x++)
            fmean += flat_at(x, y) / (N * N);
    cube_meta md;
    cube_meta_init(&md);
    int rc = mask_named(&m, "nrm17", &e);
    if (rc == SL_OK)
        rc = scene_named(&sc, "binary", 0.3, 60, 1.0, &e);
    if (rc == SL_OK)
        rc = sim_new(&s, &o, m, sc, &e);
    if (rc == SL_OK)
        rc = cube_writer_open(&wc, f->clean, N, N, -32, &md, &e);
    if (rc == SL_OK)
        rc = cube_writer_open(&wr, f->raw, N, N, -32, &md, &e);
    float *a = malloc(sizeof(float) * N * N), *b = malloc(sizeof(float) * N * N);
    for (int k = 0; rc == SL_OK && k < NF; k++) {
        if ((rc = sim_frame(s, k, a)) != SL_OK)
            break;
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++) {
                int i = y * N + x;
                a[i] *= 1e4f; /* ADU-like levels next to the dark */
                b[i] = (float)(a[i] * flat_at(x, y) / fmean + dark_at(x, y));
            }
        if ((rc = cube_writer_append(wc, a)) == SL_OK)
            rc = cube_writer_append(wr, b);
    }
    if (rc == SL_OK)
        rc = cube_writer_close(wc) | cube_writer_close(wr);
    free(a);
    free(b);
    cube_writer_free(wc);
    cube_writer_free(wr);
    sim_free(s);
    scene_free(sc);
    mask_free(m);
    return rc;
}

static int cal_start(cal_fx *f)
{
    snprintf(f->dir, sizeof f->dir, "/tmp/sl_cal_XXXXXX");
    if (!mkdtemp(f->dir))
        return -1;
    snprintf(f->clean, sizeof f->clean, "%s/clean.fits", f->dir);
    snprintf(f->raw, sizeof f->raw, "%s/raw.fits", f->dir);
    snprintf(f->dark, sizeof f->dark, "%s/dark.fits", f->dir);
    snprintf(f->flat, sizeof f->flat, "%s/flat.fits", f->dir);
    snprintf(f->small, sizeof f->small, "%s/small.fits", f->dir);
    snprintf(f->zero, sizeof f->zero, "%s/zero.fits", f->dir);
    snprintf(f->rawflat, sizeof f->rawflat, "%s/rawflat.fits", f->dir);
    return write_calibrations(f) == SL_OK && write_cubes(f) == SL_OK ? 0 : -1;
}

static void cal_stop(cal_fx *f)
{
    unlink(f->clean); unlink(f->raw); unlink(f->dark); unlink(f->flat); unlink(f->small); unlink(f->zero);
    unlink(f->rawflat);
    rmdir(f->dir);
}

/* Reconstruct path (tsm-fourier, no skips: the same geometry every run). */
static int recon_fd(const char *path, const char *dark, const char *flat,
                    const char *flat_dark, int detect, pipeline_result *r, sl_err *e)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = PIPE_TSM_FOURIER;
    o.skips = 0;
    o.fftw_measure = 0;
    o.detect = detect;
    o.dark_path = dark;
    o.flat_path = flat;
    o.flat_dark_path = flat_dark;
    const char *paths[] = {path};
    return pipeline_run(paths, 1, &o, r, e);
}

static int recon(const char *path, const char *dark, const char *flat, int detect,
                 pipeline_result *r, sl_err *e)
{
    return recon_fd(path, dark, flat, NULL, detect, r, e);
}

TEST(dark_and_flat_restore_the_frames)
{
    cal_fx f;
    CHECK(cal_start(&f) == 0, "fixture");
    pipeline_result a, b, c;
    sl_err e = {0};
    /* a zero dark: no sky subtracted from the clean cube either */
    int ra = recon(f.clean, f.zero, NULL, 0, &a, &e);
    int rb = ra == SL_OK ? recon(f.raw, f.dark, f.flat, 0, &b, &e) : ra;
    int rc = rb == SL_OK ? recon(f.raw, NULL, NULL, 0, &c, &e) : rb;
    double cab = NAN, cac = NAN;
    const char *kd = NULL;
    double dark = 0, flat = 0;
    if (rc == SL_OK) {
        cab = metrics_corr(a.image, b.image, N, N);
        cac = metrics_corr(a.image, c.image, N, N);
        cube_meta_get_num(&b.meta, "PREPDARK", &dark);
        cube_meta_get_num(&b.meta, "PREPFLAT", &flat);
        kd = "ok";
        pipeline_result_clear(&a);
        pipeline_result_clear(&b);
        pipeline_result_clear(&c);
    }
    cal_stop(&f);
    CHECK(kd, "%s", e.msg);
    CHECK(cab >= 0.99999, "calibrated c %.6f against the clean cube's image (uncalibrated %.6f)", cab, cac);
    CHECK(cac < cab - 0.001, "uncalibrated c %.6f, calibrated %.6f", cac, cab);
    CHECK(dark == 1 && flat == 1, "PREPDARK %g PREPFLAT %g", dark, flat);
}

/* A flat straight from the camera (bias and dark in it) with its own dark
 * calibrates as well as a dark-subtracted one; used without, it does not. */
TEST(a_raw_flat_with_its_dark)
{
    cal_fx f;
    CHECK(cal_start(&f) == 0, "fixture");
    pipeline_result a, b, c;
    sl_err e = {0};
    int ra = recon(f.clean, f.zero, NULL, 0, &a, &e);
    int rb = ra == SL_OK ? recon_fd(f.raw, f.dark, f.rawflat, f.dark, 0, &b, &e) : ra;
    int rc = rb == SL_OK ? recon_fd(f.raw, f.dark, f.rawflat, NULL, 0, &c, &e) : rb;
    double cab = NAN, cac = NAN;
    if (rc == SL_OK) {
        cab = metrics_corr(a.image, b.image, N, N);
        cac = metrics_corr(a.image, c.image, N, N);
        pipeline_result_clear(&a);
        pipeline_result_clear(&b);
        pipeline_result_clear(&c);
    }
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.flat_dark_path = f.dark;
    sl_err e2 = {0};
    int r2 = pipeline_opts_check(&o, &e2);
    cal_stop(&f);
    CHECK(rc == SL_OK, "%s", e.msg);
    CHECK(cab >= 0.99999, "raw flat with its dark: c %.6f (without: %.6f)", cab, cac);
    CHECK(cac < cab - 1e-4, "raw flat without its dark: c %.6f, with %.6f", cac, cab);
    CHECK(r2 == SL_EINVAL && strstr(e2.msg, "flat"), "a flat's dark without a flat: %s", e2.msg);
}

TEST(bad_calibration_files_are_named)
{
    cal_fx f;
    CHECK(cal_start(&f) == 0, "fixture");
    pipeline_result r;
    sl_err e1 = {0}, e2 = {0};
    char missing[128];
    snprintf(missing, sizeof missing, "%s/none.fits", f.dir);
    int r1 = recon(f.raw, f.small, NULL, 1, &r, &e1);
    int r2 = recon(f.raw, NULL, missing, 1, &r, &e2);
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.prep = 0;
    o.dark_path = f.dark;
    sl_err e3 = {0};
    int r3 = pipeline_opts_check(&o, &e3);
    cal_stop(&f);
    CHECK(r1 != SL_OK && strstr(e1.msg, "dark frame") && strstr(e1.msg, "32x32"),
          "a dark of the wrong size: %d %s", r1, e1.msg);
    CHECK(r2 != SL_OK && strstr(e2.msg, "flat frame") && strstr(e2.msg, "none.fits"),
          "a missing flat: %d %s", r2, e2.msg);
    CHECK(r3 == SL_EINVAL && strstr(e3.msg, "dark"), "a dark without cleaning: %s", e3.msg);
}

TC_MAIN(TC_CASE(dark_and_flat_restore_the_frames), TC_CASE(a_raw_flat_with_its_dark),
        TC_CASE(bad_calibration_files_are_named))
