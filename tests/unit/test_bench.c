/* test_bench.c - the benchmark helpers: Pareto front, the Gaussian
 * high-pass, scores against a known image, a measured child run that
 * reproduces the in-process result, blind cubes and their sidecars, the
 * fitted gain and the binary verdict's errors (the chart: tests/figure). */
#include <fitsio.h>
#include <stdlib.h>
#include <unistd.h>

#include "bench/bench.h"
#include "sim/sim_file.h"
#include "io/cube.h"
#include "measure/metrics.h"
#include "pipeline/pipeline.h"
#include "tcheck.h"

TEST(pareto_front_is_the_non_dominated_set)
{
    /* (1,5) (2,3) (3,4) dominated by (2,3); (4,1); (5,1) dominated by
     * (4,1); (2,3) twice: both stay; NaN never. */
    double x[] = {1, 2, 3, 4, 5, 2, NAN};
    double y[] = {5, 3, 4, 1, 1, 3, 0};
    unsigned char f[7];
    bench_pareto(x, y, 7, f);
    unsigned char want[] = {1, 1, 0, 1, 0, 1, 0};
    for (int i = 0; i < 7; i++)
        CHECK(f[i] == want[i], "point %d: front %d, want %d", i, f[i], want[i]);
}

TEST(highpass_removes_constants_and_keeps_fine_detail)
{
    enum { W = 64, H = 48 };
    float a[W * H], b[W * H];
    for (int i = 0; i < W * H; i++)
        a[i] = 7.5f;
    CHECK(bench_highpass(a, b, W, H, 2.0) == SL_OK, "highpass");
    for (int i = 0; i < W * H; i++)
        CHECK(fabsf(b[i]) < 1e-5f, "constant leaks: %g at %d", b[i], i);
    /* A period-2 pattern along x passes: the Gaussian's response there is
     * exp(-2 pi^2 sigma^2 / 4) ~ 5e-9 of it.  A period-64 wave is mostly
     * removed: its response is exp(-2 pi^2 (2/64)^2) = 0.981. */
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            a[y * W + x] = (x % 2 ? 1.0f : -1.0f) + (float)sin(2 * M_PI * x / W);
    CHECK(bench_highpass(a, b, W, H, 2.0) == SL_OK, "highpass");
    for (int x = 0; x < W; x++) {
        double want = (x % 2 ? 1.0 : -1.0) + (1 - 0.98091) * sin(2 * M_PI * x / W);
        CHECK_NEAR(b[5 * W + x], want, 1e-4);
    }
    CHECK(bench_highpass(a, b, W, H, 0) == SL_EINVAL, "sigma 0 accepted");
}

/* A small cube: the score of its own cophased image is perfect, and a
 * child-measured reconstruction equals the in-process one bit for bit
 * (FFTW_ESTIMATE: same plans in both processes). */
TEST(measure_in_a_child_and_score)
{
    char dir[] = "/tmp/sl_benchXXXXXX", cube[64];
    CHECK(mkdtemp(dir), "mkdtemp");
    snprintf(cube, sizeof cube, "%s/b.fits", dir);
    bench_sim s;
    bench_sim_defaults(&s);
    s.width = s.height = 64;
    s.nframes = 8;
    sl_err e = {0};
    bench_truth tr = {0};
    bench_score sc;
    bench_timing tm;
    float *img = malloc(sizeof(float) * 64 * 64);
    int rc = bench_sim_write(&s, cube, NULL, &e);
    if (rc == SL_OK)
        rc = bench_truth_read(&tr, cube, &e);
    if (rc == SL_OK)
        rc = bench_score_image(tr.cophased, &tr, BENCH_HP_SIGMA_PX, &sc, &e);
    binary_result b = {0};
    int rbin = rc == SL_OK ? metrics_binary(tr.cophased, 64, 64, &b) : rc;
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = PIPE_TSM_FOURIER;
    o.fftw_measure = 0;
    pipeline_result r = {0};
    const char *paths[] = {cube};
    int rm = rc == SL_OK ? bench_measure(cube, &o, 2, img, 64, 64, &tm, &e) : rc;
    int rp = rm == SL_OK ? pipeline_run(paths, 1, &o, &r, &e) : rm;
    int same = rp == SL_OK && memcmp(img, r.image, sizeof(float) * 64 * 64) == 0;
    bench_timing bad;
    int rb = bench_measure("/nonexistent.fits", &o, 1, img, 64, 64, &bad, &e);
    pipeline_result_clear(&r);
    bench_truth_clear(&tr);
    free(img);
    unlink(cube);
    rmdir(dir);
    CHECK(rc == SL_OK, "%s", e.msg);
    CHECK(tr.binary && fabs(tr.sep_px - 12.0) < 0.01 && tr.pa_deg == 30 && tr.dm_mag == 1,
          "truth: binary %d sep %.3f px pa %g dm %g", tr.binary, tr.sep_px, tr.pa_deg, tr.dm_mag);
    CHECK(fabs(sc.c - 1) < 1e-9 && fabs(sc.c_hp - 1) < 1e-9, "self c %.9f, c_hp %.9f", sc.c, sc.c_hp);
    /* The binary errors are metrics_binary's measurement minus the truth
     * (on the cophased image itself they are the metric's own floor). */
    CHECK(rbin == SL_OK && sc.binary_found && sc.sep_err_px == b.sep_px - tr.sep_px &&
          sc.dm_err_mag == b.dm_mag - tr.dm_mag && fabs(sc.sep_err_px) < 0.5 &&
          fabs(sc.pa_err_deg - (b.pa_deg - tr.pa_deg)) < 1e-9,
          "cophased binary: dsep %.3f dPA %.2f", sc.sep_err_px, sc.pa_err_deg);
    CHECK(rm == SL_OK && rp == SL_OK, "measure %d, run %d", rm, rp);
    CHECK(tm.repeat == 2 && tm.nframes == 8 && tm.wall_s > 0 && tm.cpu_s > 0 &&
          tm.peak_rss_mb > 1 && tm.wall_first_s > 0 && isfinite(tm.nangles),
          "timing: %d runs, %d frames, wall %g, cpu %g, rss %g, nangles %g",
          tm.repeat, tm.nframes, tm.wall_s, tm.cpu_s, tm.peak_rss_mb, tm.nangles);
    CHECK(same, "child image differs from the in-process one");
    CHECK(rb != SL_OK && strstr(e.msg, "/nonexistent.fits"), "bad path: %d %s", rb, e.msg);
}

/* Every pixel of every frame: the largest, and how many reach full. */
static int cube_peak(const char *path, double full, float *mx, int *nfull,
                     int *integral)
{
    cube_reader *r = NULL;
    sl_err e;
    int rc = cube_reader_open(&r, &path, 1, 0, &e);
    if (rc != SL_OK)
        return rc;
    size_t n = (size_t)cube_reader_width(r) * (size_t)cube_reader_height(r);
    float *f = malloc(sizeof(float) * n);
    *mx = -INFINITY;
    *nfull = 0;
    *integral = 1;
    while (f && (rc = cube_reader_next(r, f)) == SL_OK)
        for (size_t i = 0; i < n; i++) {
            *mx = fmaxf(*mx, f[i]);
            *nfull += f[i] >= full;
            *integral &= f[i] == floorf(f[i]) && f[i] >= 0;
        }
    free(f);
    cube_reader_free(r);
    return rc == SL_EEND ? SL_OK : rc;
}

static int count_hdus(const char *path)
{
    fitsfile *fp = NULL;
    int st = 0, n = -1;
    if (fits_open_diskfile(&fp, path, READONLY, &st) == 0)
        fits_get_num_hdus(fp, &n, &st);
    if (fp) {
        int st2 = 0;
        fits_close_file(fp, &st2);
    }
    return st ? -1 : n;
}

/* A blind cube says only what a camera says, in one HDU; its sidecar holds
 * the binary's geometry in px and a cophased image of unit flux.  At 2x
 * Nyquist lambda/D is 1 px, so 6 lambda/D is 6 px whatever the mask. */
TEST(blind_cube_and_its_sidecar)
{
    char dir[] = "/tmp/sl_blindXXXXXX", cube[64];
    CHECK(mkdtemp(dir), "mkdtemp");
    snprintf(cube, sizeof cube, "%s/cam.fits", dir);
    bench_sim s;
    bench_sim_defaults(&s);
    s.width = s.height = 64;
    s.nframes = 6;
    s.pa_deg = 57;
    s.sampling_nyq = 2;
    s.photons = 2e4;
    s.gain_e_per_adu = 2;
    s.read_noise_e = 3;
    s.bias_adu = 100;
    s.adc_bits = 12;
    s.hot_pixels = 3;
    s.offset_x_px = 5;
    s.offset_y_px = -3;
    s.jitter_px = 1;
    s.blind = 1;
    sl_err e = {0}, eb = {0};
    bench_truth tr = {0}, none = {0};
    int rc = bench_sim_write(&s, cube, NULL, &e);
    cube_meta m;
    cube_meta_init(&m);
    cube_reader *r = NULL;
    const char *paths[] = {cube};
    int ro = rc == SL_OK ? cube_reader_open(&r, paths, 1, 0, &e) : rc;
    if (ro == SL_OK)
        m = *cube_reader_meta(r);
    int nframes = ro == SL_OK ? cube_reader_nframes(r) : -1;
    cube_reader_free(r);
    int hdus = count_hdus(cube);
    char *side = sim_file_sidecar_path(cube);
    int side_hdus = count_hdus(side);
    int rb = bench_truth_read(&none, cube, &eb);
    int rt = rc == SL_OK ? bench_truth_read_sidecar(&tr, cube, &e) : rc;
    float mx;
    int nfull, integral;
    int rp = rc == SL_OK ? cube_peak(cube, 4095, &mx, &nfull, &integral) : rc;
    double sum = 0;
    for (int i = 0; rt == SL_OK && i < tr.width * tr.height; i++)
        sum += tr.cophased[i];
    int shape = tr.width == 64 && tr.height == 64;
    bench_truth_clear(&tr);
    unlink(cube);
    unlink(side);
    rmdir(dir);
    CHECK(rc == SL_OK && ro == SL_OK && rt == SL_OK && rp == SL_OK, "%s", e.msg);
    CHECK(nframes == 6 && hdus == 1 && side_hdus == 3, "cube: %d frames, %d HDUs; "
          "sidecar %d HDUs", nframes, hdus, side_hdus);
    CHECK(m.nextra == 0, "the blind cube has %d extra keywords, first %s", m.nextra,
          m.nextra ? m.extra[0].key : "");
    CHECK(isnan(m.plate_scale_arcsec) && isnan(m.wavelength_m) && m.instrume[0] &&
          !strstr(m.instrume, "bench") && !strstr(m.instrume, "sim"),
          "camera header: PLTSCALE %g WAVELEN %g INSTRUME '%s'", m.plate_scale_arcsec,
          m.wavelength_m, m.instrume);
    CHECK(integral && mx <= 4095 && nfull == 3 * 6, "12-bit codes: integral %d, max %g, "
          "%d at full scale (3 hot pixels x 6 frames)", integral, mx, nfull);
    CHECK(rb == SL_EFORMAT && strstr(eb.msg, side), "the cube read as truth: %d %s", rb,
          eb.msg);
    free(side);
    CHECK(tr.binary && fabs(tr.sep_px - 6) < 1e-9 && tr.pa_deg == 57 && tr.dm_mag == 1,
          "sidecar truth: binary %d, sep %.6f px, PA %g, dm %g", tr.binary, tr.sep_px,
          tr.pa_deg, tr.dm_mag);
    CHECK(shape && fabs(sum - 1) < 1e-3, "cophased %s, flux %.6f", shape ? "64x64" : "size?",
          sum);
}

/* The fitted gain puts the brightest pixel at half the codes above the
 * bias: an 8-bit converter at 1e5 photons does not saturate with it, where
 * the nominal 2 e-/ADU would; a gain that already fits is kept. */
TEST(fitted_gain_keeps_the_peak_in_range)
{
    char dir[] = "/tmp/sl_gainXXXXXX", cube[64];
    CHECK(mkdtemp(dir), "mkdtemp");
    snprintf(cube, sizeof cube, "%s/g.fits", dir);
    bench_sim s;
    bench_sim_defaults(&s);
    s.width = s.height = 64;
    s.nframes = 16;
    s.photons = 1e5;
    s.gain_e_per_adu = 2;
    s.bias_adu = 6;
    s.adc_bits = 8;
    s.blind = 1;
    bench_sim dim = s, dark = s;
    dim.photons = 300;
    dark.photons = 0;
    sl_err e = {0};
    double peak = 0, peak_dim = 0, peak_dark = 0;
    int rc = bench_sim_fit_gain(&s, 0.5, &peak, &e);
    int rd = bench_sim_fit_gain(&dim, 0.5, &peak_dim, &e);
    int rz = bench_sim_fit_gain(&dark, 0.5, &peak_dark, &e);
    int rw = rc == SL_OK ? bench_sim_write(&s, cube, NULL, &e) : rc;
    float mx = 0;
    int nfull = -1, integral = 0;
    int rp = rw == SL_OK ? cube_peak(cube, 255, &mx, &nfull, &integral) : rw;
    char *side = sim_file_sidecar_path(cube);
    unlink(cube);
    unlink(side);
    free(side);
    rmdir(dir);
    CHECK(rc == SL_OK && rd == SL_OK && rz == SL_OK && rw == SL_OK && rp == SL_OK, "%s",
          e.msg);
    CHECK(s.gain_e_per_adu > 2 && fabs(peak - (6 + 0.5 * 249)) < 1e-6,
          "gain %g, expected brightest code %g", s.gain_e_per_adu, peak);
    /* the frames' own brightest code: the pilot's peak plus noise */
    CHECK(nfull == 0 && mx > 0.8 * peak && mx < 1.5 * peak && integral,
          "8-bit frames: max %g (expected ~%g), %d at 255", mx, peak, nfull);
    CHECK(dim.gain_e_per_adu == 2 && peak_dim < 6 + 0.5 * 249, "dim: gain %g, peak %g",
          dim.gain_e_per_adu, peak_dim);
    CHECK(isnan(peak_dark) && dark.gain_e_per_adu == 2, "noiseless: gain %g, peak %g",
          dark.gain_e_per_adu, peak_dark);
    s.bias_adu = 300;
    CHECK(bench_sim_fit_gain(&s, 0.5, NULL, &e) == SL_EINVAL && strstr(e.msg, "bias"),
          "a bias above full scale: %s", e.msg);
}

/* Measured: the PA on the full circle, so the mirrored companion is 180
 * off; ambiguous: modulo 180.  No verdict, no errors. */
TEST(verdict_errors_take_the_pa_modulo_180_only_when_ambiguous)
{
    bench_truth tr = {0};
    tr.binary = 1;
    tr.sep_px = 12;
    tr.pa_deg = 57;
    tr.dm_mag = 1;
    bench_verdict v = {0};
    v.status = PIPE_BIN_MEASURED;
    v.sep_px = 12.1;
    v.pa_deg = 237.2;
    v.dm_mag = 0.95;
    double ds, dp, dd;
    CHECK(bench_verdict_errors(&v, &tr, &ds, &dp, &dd) == 1, "measured");
    CHECK(fabs(ds - 0.1) < 1e-9 && fabs(dp - (-179.8)) < 1e-9 && fabs(dd + 0.05) < 1e-9,
          "measured, flipped: %g %g %g", ds, dp, dd);
    v.status = PIPE_BIN_AMBIGUOUS;
    CHECK(bench_verdict_errors(&v, &tr, &ds, &dp, &dd) == 1 && fabs(dp - 0.2) < 1e-9,
          "ambiguous, flipped: dPA %g", dp);
    v.pa_deg = 56.5 - 360;
    CHECK(bench_verdict_errors(&v, &tr, &ds, &dp, &dd) == 1 && fabs(dp + 0.5) < 1e-9,
          "ambiguous, unflipped: dPA %g", dp);
    v.status = PIPE_BIN_UNRESOLVED;
    CHECK(bench_verdict_errors(&v, &tr, &ds, &dp, &dd) == 0 && isnan(ds) && isnan(dp) &&
          isnan(dd), "unresolved: %g %g %g", ds, dp, dd);
    v.status = PIPE_BIN_MEASURED;
    tr.binary = 0;
    CHECK(bench_verdict_errors(&v, &tr, &ds, &dp, &dd) == 0 && isnan(ds),
          "no binary in the truth: %g", ds);
}

TC_MAIN(TC_CASE(pareto_front_is_the_non_dominated_set),
        TC_CASE(highpass_removes_constants_and_keeps_fine_detail),
        TC_CASE(measure_in_a_child_and_score),
        TC_CASE(blind_cube_and_its_sidecar),
        TC_CASE(fitted_gain_keeps_the_peak_in_range),
        TC_CASE(verdict_errors_take_the_pa_modulo_180_only_when_ambiguous))
