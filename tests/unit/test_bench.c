/* test_bench.c - the benchmark helpers: Pareto front, the Gaussian
 * high-pass, scores against a known image, a measured child run that
 * reproduces the in-process result, and the chart canvas. */
#include <stdlib.h>
#include <unistd.h>

#include "bench.h"
#include "cube.h"
#include "metrics.h"
#include "pipeline.h"
#include "plot.h"
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

TEST(canvas_draws_clips_and_measures_text)
{
    sl_err e = {0};
    CHECK(plot_new(8, 8, &e) == NULL && e.code == SL_EINVAL, "tiny canvas accepted");
    plot *p = plot_new(64, 32, &e);
    CHECK(p, "%s", e.msg);
    const float *px = plot_pixels(p);
    plot_line(p, -100, 5, 500, 5, 0, 1);  /* clipped, not a crash */
    plot_marker(p, 10, 20, PLOT_SQUARE, 1, 2, 0.5f);
    int w = plot_text(p, 30, 10, "A1", 0, 1);
    int ok = w == plot_text_width("A1", 1) && w == 12 && px[5 * 64 + 0] == 0 &&
             px[5 * 64 + 63] == 0 && px[20 * 64 + 10] == 0.5f &&
             px[6 * 64 + 0] == 1 && plot_text_height(2) == 16;
    /* 'A' has its top row 01110: (31..33, 10 + 7). */
    ok = ok && px[17 * 64 + 31] == 0 && px[17 * 64 + 30] == 1;
    plot_free(p);
    plot_free(NULL);
    CHECK(ok, "canvas pixels or text metrics wrong");
}

TC_MAIN(TC_CASE(pareto_front_is_the_non_dominated_set),
        TC_CASE(highpass_removes_constants_and_keeps_fine_detail),
        TC_CASE(measure_in_a_child_and_score),
        TC_CASE(canvas_draws_clips_and_measures_text))
