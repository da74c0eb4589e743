/* test_probe.c - the scene probe and the skips of issue 6 item 4: the
 * measured extent of a known object, frame rejection of injected bad
 * frames, the crop against the whole frame, auto against its target. */
#include <stdlib.h>
#include <unistd.h>

#include "bench/bench.h"
#include "io/cube.h"
#include "measure/metrics.h"
#include "pipeline/pipeline.h"
#include "pipeline/probe.h"
#include "base/rng.h"
#include "tcheck.h"

/* A binary of Gaussian stars (sigma 1.5 px), primary 1, companion 0.4, at
 * sep_px along x, jittered as a whole by image motion (+-3 px) and lit by
 * a faint flat background: no speckle, so its autocorrelation is exactly
 * the binary's (peaks at 0 and +-sep, widened to sigma sqrt 2). */
static void gauss_binary(float *f, int w, int h, double sep_px, double jx,
                         double jy)
{
    const double s2 = 2 * 1.5 * 1.5;
    double x1 = w / 2.0 - 0.3 * sep_px + jx, y1 = h / 2.0 + jy;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double a = ((x - x1) * (x - x1) + (y - y1) * (y - y1)) / s2;
            double b = ((x - x1 - sep_px) * (x - x1 - sep_px) + (y - y1) * (y - y1)) / s2;
            f[y * w + x] = (float)(exp(-a) + 0.4 * exp(-b));
        }
}

static double probe_extent(double sep_px)
{
    enum { W = 96, H = 96, NF = 32 };
    probe_opts po;
    probe_opts_defaults(&po);
    po.crop = 0;
    sl_err e;
    probe *p = probe_new(W, H, NF, &po, &e);
    float *f = malloc(sizeof(float) * W * H);
    rng r;
    rng_init(&r, 7, 1);
    double ext = NAN;
    for (int k = 0; p && f && k < NF; k++) {
        gauss_binary(f, W, H, sep_px, 6 * rng_uniform(&r) - 3, 6 * rng_uniform(&r) - 3);
        probe_add(p, f, NULL);
    }
    probe_scene sc;
    if (p && f && probe_finish(p, &sc) == SL_OK)
        ext = sc.extent_px;
    probe_free(p);
    free(f);
    return ext;
}

/* The autocorrelation of a binary of separation d reaches d plus the
 * side peak's half width at the 5% level: 1.5 sqrt 2 sqrt(2 ln(0.34 /
 * 0.05)) = 4.1 px; a point source only its own core (~3.7 px). */
TEST(extent_is_separation_plus_core)
{
    double e0 = probe_extent(0), e10 = probe_extent(10), e20 = probe_extent(20);
    CHECK(e0 > 2 && e0 < 6, "point source: extent %.2f px, want ~3.7", e0);
    CHECK(e10 > 10 + 2.5 && e10 < 10 + 5.5, "sep 10: extent %.2f px, want ~14.1", e10);
    CHECK(e20 > 20 + 2.5 && e20 < 20 + 5.5, "sep 20: extent %.2f px, want ~24.1", e20);
    CHECK_NEAR(e20 - e10, 10, 1.5);
}

/* Small simulated cube with known truth. */
static int sim_cube(const char *path, int n, int nframes, int bad,
                    uint64_t seed)
{
    bench_sim s;
    bench_sim_defaults(&s);
    s.width = s.height = n;
    s.nframes = nframes;
    s.bad_frames = bad;
    s.seed = seed;
    sl_err e;
    int rc = bench_sim_write(&s, path, NULL, &e);
    if (rc != SL_OK)
        fprintf(stderr, "sim_cube: %s\n", e.msg);
    return rc;
}

static double key(const pipeline_result *r, const char *k)
{
    double v = NAN;
    cube_meta_get_num(&r->meta, k, &v);
    return v;
}

/* Frames 5, 25 emptied and 15, 35 saturated (x 20, clipped at the peak):
 * the first three among the 32 probed frames, the last one after them.
 * Exactly those four go, for the right reasons, and the header says so;
 * the binary comes out as from the clean frames. */
TEST(rejection_drops_injected_frames)
{
    char dir[] = "/tmp/sl_probeXXXXXX", cube[64];
    CHECK(mkdtemp(dir), "mkdtemp");
    snprintf(cube, sizeof cube, "%s/bad.fits", dir);
    CHECK(sim_cube(cube, 96, 48, 2, 3) == SL_OK, "simulating");
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = PIPE_TSM_FOURIER;
    o.nangles = 90;
    o.fftw_measure = 0;
    o.skips = PIPE_SKIP_REJECT;
    pipeline_result r;
    sl_err e;
    const char *paths[] = {cube};
    CHECK(pipeline_run(paths, 1, &o, &r, &e) == SL_OK, "%s", e.msg);
    double rej = key(&r, "RECREJ"), emp = key(&r, "RECREJE"), sat = key(&r, "RECREJS");
    double other = key(&r, "RECREJF") + key(&r, "RECREJQ"), nf = key(&r, "RECNFRM");
    const char *sk = "";
    cube_meta_get_str(&r.meta, "RECSKIPS", &sk);
    int skips_ok = !strcmp(sk, "reject");
    bench_truth tr;
    bench_score s;
    bench_score_init(&s);
    if (bench_truth_read(&tr, cube, &e) == SL_OK) {
        bench_score_image(r.image, &tr, BENCH_HP_SIGMA_PX, &s, &e);
        bench_truth_clear(&tr);
    }
    pipeline_result_clear(&r);
    unlink(cube);
    rmdir(dir);
    CHECK(emp == 2 && sat == 2 && other == 0 && rej == 4,
          "rejected %g: empty %g, saturated %g, other %g (want 2, 2, 0)", rej, emp, sat, other);
    CHECK(nf == 44 && r.nframes == 44, "frames reconstructed %g/%d, want 44", nf, r.nframes);
    CHECK(skips_ok, "RECSKIPS '%s'", sk);
    CHECK(s.binary_found && fabs(s.sep_err_px) < 0.3 && fabs(s.pa_err_deg) < 2,
          "binary: found %d, dsep %.3f px, dPA %.2f deg", s.binary_found,
          s.sep_err_px, s.pa_err_deg);
}

/* A compact object (the bench binary, 128^2): reconstructed on the crop
 * that holds its speckle cloud and put back, the image matches the one
 * from the whole frame to c > 0.99, for direct and tsm-fourier. */
TEST(crop_matches_the_whole_frame)
{
    char dir[] = "/tmp/sl_probeXXXXXX", cube[64];
    CHECK(mkdtemp(dir), "mkdtemp");
    snprintf(cube, sizeof cube, "%s/bin.fits", dir);
    CHECK(sim_cube(cube, 128, 48, 0, 5) == SL_OK, "simulating");
    const char *paths[] = {cube};
    static const int methods[] = {PIPE_DIRECT, PIPE_TSM_FOURIER};
    double c[2] = {NAN, NAN}, side[2] = {NAN, NAN};
    sl_err e = {0};
    int rc = SL_OK;
    for (int m = 0; m < 2 && rc == SL_OK; m++) {
        pipeline_opts o;
        pipeline_opts_defaults(&o);
        o.method = methods[m];
        o.fftw_measure = 0;
        pipeline_result whole, crop;
        if ((rc = pipeline_run(paths, 1, &o, &whole, &e)) != SL_OK)
            break;
        o.skips = PIPE_SKIP_CROP;
        if ((rc = pipeline_run(paths, 1, &o, &crop, &e)) == SL_OK) {
            double dx, dy;
            side[m] = key(&crop, "RECCROPW");
            if (crop.width == 128 && crop.height == 128)
                metrics_corr_registered(whole.image, crop.image, 128, 128, &c[m], &dx, &dy);
            pipeline_result_clear(&crop);
        }
        pipeline_result_clear(&whole);
    }
    unlink(cube);
    rmdir(dir);
    CHECK(rc == SL_OK, "%s", e.msg);
    CHECK(side[0] < 128 && side[0] == side[1], "crop %g / %g of 128: no crop taken",
          side[0], side[1]);
    CHECK(c[0] > 0.99, "direct: cropped vs whole c = %.5f", c[0]);
    CHECK(c[1] > 0.99, "tsm-fourier: cropped vs whole c = %.5f", c[1]);
}

/* auto on a noiseless binary: the configuration it picks meets the
 * target against the cophased image, and the header records the choice. */
TEST(auto_meets_the_target)
{
    char dir[] = "/tmp/sl_probeXXXXXX", cube[64];
    CHECK(mkdtemp(dir), "mkdtemp");
    snprintf(cube, sizeof cube, "%s/bin.fits", dir);
    CHECK(sim_cube(cube, 128, 60, 0, 9) == SL_OK, "simulating");
    const char *paths[] = {cube};
    static const double targets[] = {0.1, 0.25};
    bench_truth tr;
    sl_err e = {0};
    CHECK(bench_truth_read(&tr, cube, &e) == SL_OK, "%s", e.msg);
    for (int i = 0; i < 2 && !t->failed; i++) {
        pipeline_opts o;
        pipeline_opts_defaults(&o);
        o.method = PIPE_AUTO;
        o.target_error = targets[i];
        o.fftw_measure = 0;
        pipeline_result r;
        bench_score s;
        bench_score_init(&s);
        int rc = pipeline_run(paths, 1, &o, &r, &e);
        const char *chosen = "", *meth = "";
        double pred = NAN;
        if (rc == SL_OK) {
            bench_score_image(r.image, &tr, BENCH_HP_SIGMA_PX, &s, &e);
            cube_meta_get_str(&r.meta, "RECCHOSE", &chosen);
            cube_meta_get_str(&r.meta, "RECMETH", &meth);
            pred = key(&r, "RECPRED");
            fprintf(stderr, "  auto, target %g: %s (%s), predicted %.3f, 1 - c "
                    "%.4f, dsep %+.3f px, dPA %+.2f deg\n", targets[i], chosen,
                    meth, pred, 1 - s.c, s.sep_err_px, s.pa_err_deg);
        }
        int named = rc == SL_OK && chosen[0] && strcmp(meth, "auto");
        if (rc == SL_OK)
            pipeline_result_clear(&r);
        CHECK(rc == SL_OK, "%s", e.msg);
        CHECK(named, "the choice is not recorded (RECCHOSE '%s', RECMETH '%s')", chosen, meth);
        CHECK(pred <= targets[i], "predicted %.3f above the target %g", pred, targets[i]);
        CHECK(1 - s.c <= targets[i], "target %g: 1 - c = %.4f", targets[i], 1 - s.c);
        CHECK(s.binary_found && fabs(s.sep_err_px) < 0.3 && fabs(s.pa_err_deg) < 2,
              "binary: found %d, dsep %.3f px, dPA %.2f deg", s.binary_found,
              s.sep_err_px, s.pa_err_deg);
    }
    bench_truth_clear(&tr);
    unlink(cube);
    rmdir(dir);
}

TEST(skip_lists_parse_and_print)
{
    int k = 0;
    char buf[64];
    CHECK(pipeline_skips_parse("crop,angles", &k) == SL_OK &&
          k == (PIPE_SKIP_CROP | PIPE_SKIP_ANGLES), "crop,angles -> %d", k);
    pipeline_skips_name(k, buf, sizeof buf);
    CHECK(!strcmp(buf, "crop,angles"), "name '%s'", buf);
    CHECK(pipeline_skips_parse("all", &k) == SL_OK && k == PIPE_SKIP_ALL, "all");
    CHECK(pipeline_skips_parse("none", &k) == SL_OK && k == 0, "none");
    CHECK(pipeline_skips_parse("crop,bogus", &k) == SL_EINVAL, "bogus accepted");
    int m;
    CHECK(pipeline_method_parse("auto", &m) == SL_OK && m == PIPE_AUTO, "auto");
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    CHECK(o.skips == -1, "default skips %d", o.skips);
}

/* probe_place: the crop's centre lands on the frame's centre. */
TEST(place_centres_the_crop)
{
    probe_scene sc;
    memset(&sc, 0, sizeof sc);
    sc.width = 10, sc.height = 8, sc.crop_w = 4, sc.crop_h = 2;
    float crop[8] = {0}, full[80];
    crop[1 * 4 + 2] = 1; /* the crop's centre (2, 1) */
    probe_place(&sc, crop, full);
    for (int i = 0; i < 80; i++)
        CHECK(full[i] == (i == 4 * 10 + 5), "pixel (%d, %d) = %g", i % 10, i / 10, full[i]);
}

TC_MAIN(TC_CASE(extent_is_separation_plus_core), TC_CASE(rejection_drops_injected_frames),
        TC_CASE(crop_matches_the_whole_frame), TC_CASE(auto_meets_the_target),
        TC_CASE(skip_lists_parse_and_print), TC_CASE(place_centres_the_crop))
