/* test_pipeline.c - end to end: a simulated FITS cube of a binary goes in,
 * every method gives back an image whose binary matches the truth. */
#include <stdlib.h>
#include <unistd.h>

#include <fftw3.h>

#include "io/cube.h"
#include "measure/metrics.h"
#include "pipeline/pipeline.h"
#include "sim/sim.h"
#include "tcheck.h"
#include "tsm/tsm.h"

#define N 96

/* What write_sim's camera adds: CAM_GAIN_HDR the photon statistics as a
 * camera's GAIN alone, as specklabd writes them (2 e-/ADU: the frames
 * are the photon counts halved), not the simulator's SIMPHOT/SIMGAIN;
 * CAM_DEFECTS a bias, a 12-bit ADC, hot and dead pixels and an
 * off-centre star. */
enum { CAM_GAIN_HDR = 1, CAM_DEFECTS = 2 };

/* Write a simulated cube (and its cophased image) to path. */
static int write_sim(const char *path, const char *scene_name, double photons,
                     uint64_t seed, int turbulence, unsigned camera)
{
    int camera_hdr = camera & CAM_GAIN_HDR;
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    cube_writer *w = NULL;
    sim_opts o;
    sim_opts_defaults(&o);
    o.width = o.height = N;
    o.nframes = 60;
    o.photons_per_frame = photons;
    o.seed = seed;
    o.turbulence = turbulence;
    o.fftw_flags = FFTW_ESTIMATE;
    if (camera & CAM_DEFECTS) {
        o.bias_adu = 100, o.adc_bits = 12, o.hot_pixels = 12, o.dead_pixels = 4;
        o.offset_x_px = 7, o.offset_y_px = -5;
    }
    int rc = mask_named(&m, "nrm17", &e);
    if (rc == SL_OK)
        rc = scene_named(&sc, scene_name, 0.45, 250, 1.0, &e);
    if (rc == SL_OK)
        rc = sim_new(&s, &o, m, sc, &e);
    cube_meta md;
    cube_meta_init(&md);
    md.plate_scale_arcsec = rc == SL_OK ? sim_plate_scale_arcsec(s) : 0;
    /* the camera: 2 e- per ADU, so ADU = photons / 2 */
    float adu = photons > 0 && camera_hdr ? 0.5f : 1.0f;
    if (photons > 0 && camera_hdr) {
        cube_meta_set_num(&md, "GAIN", 1 / adu, NULL);
    } else if (photons > 0) {
        cube_meta_set_num(&md, "SIMPHOT", photons, NULL);
        cube_meta_set_num(&md, "SIMGAIN", 1, NULL);
    }
    if (rc == SL_OK)
        rc = cube_writer_open(&w, path, N, N, -32, &md, &e);
    float *f = malloc(sizeof(float) * N * N);
    for (int k = 0; rc == SL_OK && k < o.nframes; k++)
        if ((rc = sim_frame(s, k, f)) == SL_OK) {
            for (int i = 0; adu != 1 && i < N * N; i++)
                f[i] *= adu;
            rc = cube_writer_append(w, f);
        }
    if (rc == SL_OK && (rc = sim_cophased(s, f)) == SL_OK)
        rc = cube_writer_add_image(w, "COPHASED", f, N, N, NULL);
    if (rc == SL_OK)
        rc = cube_writer_close(w);
    if (rc != SL_OK)
        fprintf(stderr, "write_sim: %s / %s\n", e.msg, w ? cube_writer_errmsg(w) : "");
    free(f);
    cube_writer_free(w);
    sim_free(s);
    scene_free(sc);
    mask_free(m);
    return rc;
}

/* Simulated cubes in a fresh temporary directory, removed by tmp_clean:
 * tmp_sim adds one (path[n++]); SL_OK or the error. */
typedef struct tmp_cubes {
    char dir[24], path[2][64];
    int n;
    unsigned camera;  /* the next tmp_sim's CAM_* */
} tmp_cubes;

static int tmp_sim(tmp_cubes *cubes, const char *scene_name, double photons, uint64_t seed)
{
    int i = cubes->n;
    if (i >= 2)
        return SL_EINVAL;
    if (i == 0) {
        snprintf(cubes->dir, sizeof cubes->dir, "/tmp/sl_pipeXXXXXX");
        if (!mkdtemp(cubes->dir))
            return SL_EIO;
    }
    char dir[sizeof cubes->dir];
    memcpy(dir, cubes->dir, sizeof dir);
    snprintf(cubes->path[i], sizeof cubes->path[i], "%s/%d.fits", dir, i);
    cubes->n++;
    return write_sim(cubes->path[i], scene_name, photons, seed, 1, cubes->camera);
}

static void tmp_clean(tmp_cubes *cubes)
{
    for (int i = 0; i < cubes->n; i++)
        unlink(cubes->path[i]);
    if (cubes->n > 0)
        rmdir(cubes->dir);
}

/* The binary is 0.45" at PA 250 deg, dm 1: measured within the issue's
 * bounds (0.1 px, 0.5 deg, 0.1 mag) by direct; TSM within 0.1 px and 0.5
 * deg, dm within 0.15 (read 1.08 Fourier, 1.13 spatial; 1.20-1.21 before
 * step 3's angular average was capped by the object's diameter,
 * tsm_extent.c). */
static void check_method(tc *t, const char *cube, const char *ref, int method,
                         double tol_sep, double tol_pa, double tol_dm)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = method;
    o.ref_path = ref;
    o.fftw_measure = 0;
    pipeline_result r;
    sl_err e;
    const char *paths[] = {cube};
    CHECK(pipeline_run(paths, 1, &o, &r, &e) == SL_OK, "%s: %s", pipeline_method_name(method), e.msg);
    binary_result b;
    int rc = metrics_binary(r.image, r.width, r.height, &b);
    double sep_px = 0.45 / r.plate_scale_arcsec;
    const char *meth;
    double v;
    int ok = rc == SL_OK && cube_meta_get_str(&r.meta, "RECMETH", &meth) == SL_OK &&
             cube_meta_get_num(&r.meta, "RECNFRM", &v) == SL_OK && v == 60;
    pipeline_result_clear(&r);
    CHECK(ok, "%s: no binary found or header incomplete", pipeline_method_name(method));
    CHECK(fabs(b.sep_px - sep_px) < tol_sep, "%s: sep %.3f px, truth %.3f", pipeline_method_name(method), b.sep_px, sep_px);
    CHECK(fabs(b.pa_deg - 250) < tol_pa, "%s: PA %.2f deg, truth 250", pipeline_method_name(method), b.pa_deg);
    CHECK(fabs(b.dm_mag - 1) < tol_dm, "%s: dm %.3f, truth 1", pipeline_method_name(method), b.dm_mag);
}

TEST(every_method_measures_the_binary)
{
    tmp_cubes cubes = {0};
    int rc = tmp_sim(&cubes, "binary", 0, 1);
    if (rc == SL_OK)
        rc = tmp_sim(&cubes, "point", 0, 77);
    if (rc == SL_OK)
        check_method(t, cubes.path[0], cubes.path[1], PIPE_DIRECT, 0.1, 0.5, 0.1);
    if (rc == SL_OK && !t->failed)
        check_method(t, cubes.path[0], cubes.path[1], PIPE_TSM_FOURIER, 0.1, 0.5, 0.15);
    if (rc == SL_OK && !t->failed)
        check_method(t, cubes.path[0], cubes.path[1], PIPE_TSM, 0.1, 0.5, 0.15);
    tmp_clean(&cubes);
    CHECK(rc == SL_OK, "simulating the binary and the reference");
}

/* Photon-counting frames (1000 per frame, the lab level): the header's
 * SIMPHOT switches on the bias correction and the binary's position is
 * still measured within 0.25 px and 2 deg (issue 6's bound).  The flux
 * ratio is NOT right at this level (dm 0.81 direct, 2.15 TSM for a true
 * 1.0, 60 frames of 128^2: an open item of issue 3).  TSM's phases come
 * from the raw bispectrum, whose real photon bias shrinks the closure
 * phases so that the companion reads faint (tsm.h, Bias; the corrected
 * ones lose dm 2 companions at this level); so dm is only held to 0.7 mag
 * (direct) and 1.3 (TSM) here. */
TEST(photon_counting_cube)
{
    tmp_cubes cubes = {0};
    int rc = tmp_sim(&cubes, "binary", 1000, 3);
    if (rc == SL_OK)
        rc = tmp_sim(&cubes, "point", 1000, 78);
    if (rc != SL_OK)
        tmp_clean(&cubes);
    CHECK(rc == SL_OK, "simulating the binary and the reference");
    const char *cube = cubes.path[0], *ref = cubes.path[1];
    check_method(t, cube, ref, PIPE_DIRECT, 0.25, 2, 0.7);
    if (!t->failed)
        check_method(t, cube, ref, PIPE_TSM_FOURIER, 0.25, 2, 1.3);
    tmp_clean(&cubes);
}

/* tsm-fourier on cube with the given options; the header's keyword key
 * copied into val ("" when absent).  SL_OK or the pipeline's status. */
static int run_tsmf(const char *cube, int nangles, int inverse, int corrected,
                    const char *key, char *val, size_t nval, pipeline_result *r)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = PIPE_TSM_FOURIER;
    o.nangles = nangles;
    o.tsm_inverse = inverse;
    o.tsm_corrected_phases = corrected;
    o.fftw_measure = 0;
    sl_err e;
    const char *paths[] = {cube}, *k;
    snprintf(val, nval, "%s", "");
    int rc = pipeline_run(paths, 1, &o, r, &e);
    if (rc != SL_OK)
        fprintf(stderr, "tsm-fourier: %s\n", e.msg);
    else if (cube_meta_get_str(&r->meta, key, &k) == SL_OK)
        snprintf(val, nval, "%s", k);
    return rc;
}

/* TSM phases from the photon-bias-corrected bispectrum (--tsm-phases
 * corrected) at 1e4 photons per frame: the raw bispectrum's real photon
 * bias shrinks the closure phases and the companion reads faint (here dm
 * 1.30 for a true 1.0; `specklab sim` seeds 3, 4, 5 of this binary: 1.47,
 * 1.46, 1.23); the corrected ones read 1.07 (1.21, 1.09, 1.04), with the
 * position unchanged. */
static double tsm_dm(const char *cube, int corrected, char *phases, size_t n)
{
    pipeline_result r;
    binary_result b;
    if (run_tsmf(cube, 180, 0, corrected, "RECTPHAS", phases, n, &r) != SL_OK)
        return NAN;
    int rc = metrics_binary(r.image, r.width, r.height, &b);
    double sep_px = 0.45 / r.plate_scale_arcsec;
    pipeline_result_clear(&r);
    if (rc != SL_OK || fabs(b.sep_px - sep_px) > 0.25 || fabs(b.pa_deg - 250) > 1.5)
        return NAN;
    return b.dm_mag;
}

TEST(tsm_corrected_phases)
{
    tmp_cubes cubes = {0};
    int rc = tmp_sim(&cubes, "binary", 1e4, 3);
    char kr[16] = "", kc[16] = "";
    double dm_raw = NAN, dm_cor = NAN;
    if (rc == SL_OK) {
        dm_raw = tsm_dm(cubes.path[0], 0, kr, sizeof kr);
        dm_cor = tsm_dm(cubes.path[0], 1, kc, sizeof kc);
    }
    tmp_clean(&cubes);
    CHECK(rc == SL_OK, "simulating");
    printf("    1e4 photons, dm 1: raw phases %.3f, corrected %.3f\n", dm_raw, dm_cor);
    CHECK(!strcmp(kr, "raw") && !strcmp(kc, "corrected"), "RECTPHAS %s / %s", kr, kc);
    CHECK(fabs(dm_cor - 1) < 0.25, "corrected: dm %.3f (NAN: binary lost)", dm_cor);
    CHECK(dm_raw - dm_cor > 0.15, "raw %.3f vs corrected %.3f: no gain", dm_raw, dm_cor);
}

/* Without photon statistics (no SIMPHOT: camera data) corrected phases
 * cannot be had: the request changes nothing, bit for bit, and the header
 * says the phases are raw. */
TEST(tsm_corrected_phases_need_photons)
{
    tmp_cubes cubes = {0};
    int rc = tmp_sim(&cubes, "binary", 0, 4);
    pipeline_result r[2];
    char k[2][16];
    int ok = 0, run = 0;
    for (; rc == SL_OK && run < 2; run++)
        rc = run_tsmf(cubes.path[0], 36, 0, run, "RECTPHAS", k[run], sizeof k[run], &r[run]);
    if (rc == SL_OK)
        ok = r[0].width == r[1].width && r[0].height == r[1].height &&
             !memcmp(r[0].image, r[1].image, sizeof(float) * r[0].width * r[0].height);
    for (int i = 0; i < run - (rc != SL_OK); i++)
        pipeline_result_clear(&r[i]);
    tmp_clean(&cubes);
    CHECK(rc == SL_OK, "simulating or reconstructing");
    CHECK(!strcmp(k[0], "raw") && !strcmp(k[1], "raw"), "RECTPHAS %s / %s", k[0], k[1]);
    CHECK(ok, "the image changed with --tsm-phases corrected and no photon statistics");
}

/* Camera cubes carry the detector's gain (GAIN, e-/ADU, written by
 * specklabd from [camera] gain_e_per_adu) and no photon count: the
 * pipeline measures the mean flux of the cleaned frames and divides.  The
 * same frames with the simulator's SIMPHOT/SIMGAIN and with GAIN alone
 * must give the same photon count (to the Poisson scatter of the mean
 * and what prep takes as sky), corrected TSM phases on both, and the same
 * dm. */
TEST(camera_gain_gives_photon_statistics)
{
    tmp_cubes cubes = {0};
    int rc = tmp_sim(&cubes, "binary", 1e4, 3);
    cubes.camera = CAM_GAIN_HDR;
    if (rc == SL_OK)
        rc = tmp_sim(&cubes, "binary", 1e4, 3);
    double dm[2] = {NAN, NAN}, phot[2] = {NAN, NAN};
    char ph[2][16] = {"", ""}, src[2][16] = {"", ""};
    for (int i = 0; rc == SL_OK && i < 2; i++) {
        pipeline_result r;
        binary_result b;
        const char *k;
        if ((rc = run_tsmf(cubes.path[i], 180, 0, 1, "RECTPHAS", ph[i], sizeof ph[i], &r)) != SL_OK)
            break;
        cube_meta_get_num(&r.meta, "RECPHOT", &phot[i]);
        if (cube_meta_get_str(&r.meta, "RECPHSRC", &k) == SL_OK)
            snprintf(src[i], sizeof src[i], "%s", k);
        if (metrics_binary(r.image, r.width, r.height, &b) == SL_OK)
            dm[i] = b.dm_mag;
        pipeline_result_clear(&r);
    }
    /* The caller's "not photon counts" (photons < 0) overrides GAIN. */
    char src_neg[16] = "", ph_neg[16] = "";
    if (rc == SL_OK) {
        pipeline_opts o;
        pipeline_opts_defaults(&o);
        o.method = PIPE_TSM_FOURIER;
        o.nangles = 36;
        o.tsm_corrected_phases = 1;
        o.photons_per_frame = -1;
        o.fftw_measure = 0;
        pipeline_result r;
        sl_err e;
        const char *paths[] = {cubes.path[1]}, *k;
        if ((rc = pipeline_run(paths, 1, &o, &r, &e)) == SL_OK) {
            if (cube_meta_get_str(&r.meta, "RECPHSRC", &k) == SL_OK)
                snprintf(src_neg, sizeof src_neg, "%s", k);
            if (cube_meta_get_str(&r.meta, "RECTPHAS", &k) == SL_OK)
                snprintf(ph_neg, sizeof ph_neg, "%s", k);
            pipeline_result_clear(&r);
        }
    }
    tmp_clean(&cubes);
    CHECK(rc == SL_OK, "simulating or reconstructing");
    CHECK(!strcmp(src_neg, "none") && !strcmp(ph_neg, "raw"),
          "--photons -1 with GAIN: RECPHSRC %s, RECTPHAS %s", src_neg, ph_neg);
    printf("    SIMPHOT: %.0f photons, dm %.3f; GAIN: %.0f photons, dm %.3f\n",
           phot[0], dm[0], phot[1], dm[1]);
    CHECK(!strcmp(src[0], "SIMPHOT") && !strcmp(src[1], "GAIN"), "RECPHSRC %s / %s",
          src[0], src[1]);
    CHECK(fabs(phot[1] / 1e4 - 1) < 0.03, "photons from GAIN and the flux: %.0f, truth 1e4",
          phot[1]);
    CHECK(!strcmp(ph[1], "corrected"), "RECTPHAS %s with GAIN", ph[1]);
    CHECK(fabs(dm[1] - dm[0]) < 0.02, "dm %.3f with GAIN, %.3f with SIMPHOT", dm[1], dm[0]);
}

/* TSM's iterative inverse (tsm_inverse = TSM_INV_ITER, `recon
 * --tsm-inverse iter`) at 18 angles, the six-star group, noiseless:
 * filtered back projection's streaks cap c (0.70 here), the non-negative
 * iterative inverse reaches 0.88. */
static double six_star_c(const char *cube, int inverse, char *inv, size_t n)
{
    pipeline_result r;
    sl_err e;
    seq *cop = NULL;
    double c = NAN, dx, dy;
    if (run_tsmf(cube, 18, inverse, 0, "RECTINV", inv, n, &r) != SL_OK)
        return NAN;
    if (cube_read_ext(&cop, cube, "COPHASED", &e) == SL_OK)
        metrics_corr_registered(seq_frame(cop, 0), r.image, r.width, r.height, &c, &dx, &dy);
    seq_free(cop);
    pipeline_result_clear(&r);
    return c;
}

TEST(few_angles_iterative_inverse)
{
    tmp_cubes cubes = {0};
    int rc = tmp_sim(&cubes, "six-star", 0, 2);
    char kf[16] = "", ki[16] = "";
    double c_fbp = NAN, c_it = NAN;
    if (rc == SL_OK) {
        c_fbp = six_star_c(cubes.path[0], TSM_INV_AUTO, kf, sizeof kf);
        c_it = six_star_c(cubes.path[0], TSM_INV_ITER, ki, sizeof ki);
    }
    tmp_clean(&cubes);
    CHECK(rc == SL_OK, "simulating");
    printf("    six-star, 18 angles: c %.3f FBP, %.3f iterative\n", c_fbp, c_it);
    CHECK(!strcmp(kf, "fbp") && !strcmp(ki, "iterative"), "RECTINV %s / %s", kf, ki);
    CHECK(c_it > 0.78 && c_it > c_fbp + 0.15, "c %.3f iterative vs %.3f FBP", c_it, c_fbp);
}

/* The direct method's default R2 under a memory bound: on 96^2 (R2 13
 * by default) a 2 MB bound takes R2 down, says so (RECR2MEM), keeps the
 * bispectrum within 1.25 of the bound (18 bytes a triple plus ~350 a
 * support frequency) and the binary within the bounds; an R2 the
 * user gives is kept. */
TEST(r2_bounded_by_memory)
{
    tmp_cubes cubes = {0};
    CHECK(tmp_sim(&cubes, "binary", 0, 31) == SL_OK, "simulating");
    int r2[3] = {0, 0, 0};
    double mem[3] = {0, 0, 0}, sep[3] = {0}, dm[3] = {0};
    long ntri[3] = {0};
    int nsup = 0;
    for (int k = 0; k < 3 && !t->failed; k++) {
        pipeline_opts o;
        pipeline_opts_defaults(&o);
        o.method = PIPE_DIRECT, o.fftw_measure = 0;
        o.bispec_mem_mb = k ? 2 : 0;
        o.r2_px = k == 2 ? 13 : 0;
        pipeline_result r;
        sl_err e;
        const char *paths[] = {cubes.path[0]};
        CHECK(pipeline_run(paths, 1, &o, &r, &e) == SL_OK, "%s", e.msg);
        binary_result b;
        int rc = metrics_binary(r.image, r.width, r.height, &b);
        r2[k] = r.report.r2_px, mem[k] = r.report.r2_bound_mb, ntri[k] = r.report.ntriples;
        nsup = (int)(M_PI * r.report.rcut_px * r.report.rcut_px / 2);
        sep[k] = b.sep_px * r.plate_scale_arcsec, dm[k] = b.dm_mag;
        pipeline_result_clear(&r);
        CHECK(rc == SL_OK, "run %d: no binary", k);
    }
    tmp_clean(&cubes);
    CHECK(!t->failed, "%s", t->msg);
    CHECK(r2[0] == 13 && mem[0] == 0, "unbounded: R2 %d, bound %g MB", r2[0], mem[0]);
    CHECK(r2[1] < r2[0] && r2[1] >= 4 && mem[1] == 2, "2 MB: R2 %d, bound %g MB", r2[1], mem[1]);
    double bytes = 18.0 * ntri[1] + 350.0 * nsup;
    CHECK(bytes <= 1.25 * 2 * 1048576, "2 MB: %ld triples, ~%.2f MB", ntri[1], bytes / 1048576);
    CHECK(r2[2] == 13 && mem[2] == 0, "--r2-px 13 under 2 MB: R2 %d, bound %g", r2[2], mem[2]);
    CHECK(fabs(sep[1] - 0.45) < 0.1 * 0.45 && fabs(dm[1] - 1) < 0.1,
          "bounded R2 %d: sep %.3f\", dm %.3f; truth 0.45\", 1", r2[1], sep[1], dm[1]);
}

/* Runs cube with method on each of nt thread counts; img[k] the image
 * (malloc'd), det[k] the detector learnt, fit[k] direct's closure fit.
 * 0 (noted) when a run fails. */
static int run_threads(tc *t, const char *cube, int method, const int *threads, int nt,
                       float **img, pipeline_detector_report *det, double (*fit)[6],
                       size_t *npx)
{
    for (int k = 0; k < nt; k++) {
        pipeline_opts o;
        pipeline_opts_defaults(&o);
        o.method = method, o.fftw_measure = 0, o.nthreads = threads[k];
        o.closure_binary = method == PIPE_DIRECT;
        pipeline_result r;
        sl_err e;
        const char *paths[] = {cube};
        if (pipeline_run(paths, 1, &o, &r, &e) != SL_OK) {
            tc_note(t, 0, __FILE__, __LINE__, "pipeline_run", "%s, %d threads: %s",
                    pipeline_method_name(method), threads[k], e.msg);
            return 0;
        }
        *npx = (size_t)r.width * r.height;
        img[k] = malloc(*npx * sizeof *img[k]);
        memcpy(img[k], r.image, *npx * sizeof *img[k]);
        det[k] = r.report.detector;
        const binary_result *c = &r.binary.closure;
        double v[6] = {c->sep_px, c->pa_deg, c->dm_mag, r.binary.sep_err_px,
                       r.binary.pa_err_deg, r.binary.dm_err_mag};
        memcpy(fit[k], v, sizeof v);
        pipeline_result_clear(&r);
    }
    return 1;
}

/* 1, 2 and 9 threads give the same image bit for bit: the frames read
 * ahead by one reader thread (2 threads) or three (9: pipeline_ahead.c)
 * against the serial pass, and each estimator's own threads; and direct's
 * closure-phase fit the same binary. */
TEST(images_equal_on_one_and_more_threads)
{
    tmp_cubes cubes = {0};
    CHECK(tmp_sim(&cubes, "binary", 2000, 7) == SL_OK, "simulating");
    static const int methods[] = {PIPE_DIRECT, PIPE_TSM, PIPE_TSM_FOURIER};
    static const int threads[] = {1, 2, 9};
    for (int m = 0; m < 3 && !t->failed; m++) {
        float *img[3] = {NULL, NULL, NULL};
        double fit[3][6] = {{0}};
        pipeline_detector_report det[3];
        size_t npx = 0;
        run_threads(t, cubes.path[0], methods[m], threads, 3, img, det, fit, &npx);
        for (int k = 1; k < 3; k++) {
            int same = img[0] && img[k] && memcmp(img[0], img[k], npx * sizeof *img[0]) == 0;
            CHECK(same || t->failed, "%s: %d threads' image differs from 1 thread's",
                  pipeline_method_name(methods[m]), threads[k]);
            CHECK(memcmp(fit[0], fit[k], sizeof fit[0]) == 0, "%s: closure fit %.9g px on "
                  "1 thread, %.9g on %d", pipeline_method_name(methods[m]), fit[0][0],
                  fit[k][0], threads[k]);
        }
        CHECK(methods[m] != PIPE_DIRECT || fit[0][0] > 0, "direct: no closure fit to compare");
        for (int k = 0; k < 3; k++)
            free(img[k]);
    }
    tmp_clean(&cubes);
}

/* A camera's cube (bias, 12-bit ADC, hot and dead pixels, the star off
 * centre, no simulator keywords): the cleaning's repairs and sky, made by
 * three readers each with its own copy of the cleaning (9 threads), give
 * the serial pass's image and detector. */
TEST(camera_cube_equal_on_one_and_many_readers)
{
    tmp_cubes cubes = {.camera = CAM_GAIN_HDR | CAM_DEFECTS};
    CHECK(tmp_sim(&cubes, "binary", 5000, 11) == SL_OK, "simulating");
    static const int threads[] = {1, 9};
    float *img[2] = {NULL, NULL};
    double fit[2][6];
    pipeline_detector_report det[2];
    size_t npx = 0;
    if (run_threads(t, cubes.path[0], PIPE_TSM_FOURIER, threads, 2, img, det, fit, &npx)) {
        CHECK(det[0].learnt && det[0].nhot + det[0].ndead + det[0].nstuck > 0,
              "no bad pixel learnt (hot %d dead %d stuck %d): the test cleans nothing",
              det[0].nhot, det[0].ndead, det[0].nstuck);
        CHECK(memcmp(&det[0], &det[1], sizeof det[0]) == 0, "detector: %d hot, sky %.9g "
              "ADU on 1 thread; %d, %.9g on 9", det[0].nhot, det[0].sky_adu, det[1].nhot,
              det[1].sky_adu);
        CHECK(memcmp(img[0], img[1], npx * sizeof *img[0]) == 0,
              "9 threads' image differs from 1 thread's");
    }
    free(img[0]);
    free(img[1]);
    tmp_clean(&cubes);
}

/* A frame the reader refuses mid-pass (NaN, cleaning off) stops the run
 * with the reader's message, read ahead or not, and nothing hangs; with
 * frames 9 and 10 refused by different readers (9 threads: 3), the
 * message is the first's, as in the serial pass. */
TEST(reader_error_mid_pass_is_named)
{
    char dir[] = "/tmp/sl_pipeXXXXXX", path[64];
    CHECK(mkdtemp(dir), "mkdtemp");
    snprintf(path, sizeof path, "%s/nan.fits", dir);
    cube_writer *w = NULL;
    float fr[N * N];
    CHECK(cube_writer_open(&w, path, N, N, -32, NULL, NULL) == SL_OK, "open %s", path);
    for (int k = 0; k < 12; k++) {
        for (int i = 0; i < N * N; i++)
            fr[i] = (float)((i * 7 + k * 13) % 29);
        if (k == 9 || k == 10)
            fr[5] = NAN;
        cube_writer_append(w, fr);
    }
    cube_writer_close(w);
    cube_writer_free(w);
    static const int threads[] = {1, 2, 9};
    for (int i = 0; i < 3; i++) {
        int k = threads[i];
        pipeline_opts o;
        pipeline_opts_defaults(&o);
        o.method = PIPE_TSM_FOURIER, o.fftw_measure = 0, o.nthreads = k, o.prep = 0;
        pipeline_result r;
        sl_err e = {0};
        const char *paths[] = {path};
        int rc = pipeline_run(paths, 1, &o, &r, &e);
        if (rc == SL_OK)
            pipeline_result_clear(&r);
        CHECK(rc != SL_OK && strstr(e.msg, "nan.fits") && strstr(e.msg, "in frame 9;"),
              "%d threads: rc %d, \"%s\"", k, rc, e.msg);
    }
    unlink(path);
    rmdir(dir);
}

TEST(bad_inputs_are_named)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    pipeline_result r;
    sl_err e;
    const char *paths[] = {"/nonexistent/cube.fits"};
    CHECK(pipeline_run(paths, 1, &o, &r, &e) != SL_OK && strstr(e.msg, "/nonexistent/cube.fits"), "%s", e.msg);
    int m;
    CHECK(pipeline_method_parse("bogus", &m) == SL_EINVAL, "bogus method accepted");
    CHECK(pipeline_method_parse("tsm-fourier", &m) == SL_OK && m == PIPE_TSM_FOURIER, "parse");
}

TC_MAIN(TC_CASE(every_method_measures_the_binary), TC_CASE(photon_counting_cube),
        TC_CASE(r2_bounded_by_memory),
        TC_CASE(tsm_corrected_phases), TC_CASE(tsm_corrected_phases_need_photons),
        TC_CASE(camera_gain_gives_photon_statistics),
        TC_CASE(few_angles_iterative_inverse),
        TC_CASE(images_equal_on_one_and_more_threads),
        TC_CASE(camera_cube_equal_on_one_and_many_readers), TC_CASE(reader_error_mid_pass_is_named),
        TC_CASE(bad_inputs_are_named))
