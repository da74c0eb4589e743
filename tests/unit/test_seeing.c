/* test_seeing.c - r0 from image motion, against the simulator's truth. */
#include <stdlib.h>

#include <fftw3.h>

#include "measure/seeing.h"
#include "sim/sim.h"
#include "tcheck.h"

/* Run the estimator on a simulated sequence with r0_m; returns r0 found. */
static double estimate(const char *maskname, double r0_m, int nframes,
                       seeing_result *res, double bias_adu)
{
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    seeing *se = NULL;
    sim_opts o;
    sim_opts_defaults(&o);
    o.width = o.height = 64;
    o.nframes = nframes;
    o.r0_m = r0_m;
    o.frame_interval_s = 0.05; /* 0.5 m per frame: 0.45 D */
    o.fftw_flags = FFTW_ESTIMATE;
    o.seed = 5;
    double r0 = NAN;
    if (mask_named(&m, maskname, &e) || scene_named(&sc, "binary", 0.3, 60, 1, &e) ||
        sim_new(&s, &o, m, sc, &e) ||
        seeing_new(&se, 64, 64, sim_plate_scale_arcsec(s), o.wavelength_m,
                   mask_extent_m(m), &e))
        goto done;
    float f[64 * 64];
    for (int k = 0; k < nframes; k++) {
        sim_frame(s, k, f);
        for (int i = 0; i < 64 * 64; i++)
            f[i] = f[i] * 1000 + (float)bias_adu;
        seeing_add(se, f);
    }
    if (seeing_result_get(se, res) == SL_OK)
        r0 = res->r0_m;
done:
    seeing_free(se);
    sim_free(s);
    scene_free(sc);
    mask_free(m);
    return r0;
}

/* Full aperture: the G-tilt formula holds, so r0 comes back within its
 * own stated error (x3) of the simulated value. */
TEST(full_aperture_r0_matches_truth)
{
    seeing_result r;
    for (int i = 0; i < 2; i++) {
        double truth = i ? 0.25 : 0.12;
        double got = estimate("full", truth, 200, &r, 0);
        CHECK(isfinite(got), "no estimate");
        CHECK(fabs(got - truth) < 3 * r.r0_err_m + 0.1 * truth,
              "r0 %.3f +- %.3f m, truth %.3f (n_eff %.0f)", got, r.r0_err_m, truth, r.n_eff);
    }
}

/* Through the 17-hole mask the estimate orders screens: worse seeing,
 * smaller r0 - also on a bias pedestal. */
TEST(mask_orders_screens)
{
    seeing_result r;
    double a = estimate("nrm17", 0.40, 150, &r, 200);
    double b = estimate("nrm17", 0.15, 150, &r, 200);
    double c = estimate("nrm17", 0.06, 150, &r, 200);
    CHECK(a > b && b > c, "r0 estimates %.3f, %.3f, %.3f for 0.40, 0.15, 0.06 m", a, b, c);
}

/* The demo's bench (scripts/demo, mocks/camsrc/fakecam.h): 128^2
 * frames at Nyquist for 1.1 m at 633 nm, 17-hole mask, 10 m/s and 50 ms
 * per frame (0.46 D), 100 frames, 1e4 photons, 2 e- read noise, bias 100.
 * r0 read from the frames, against the r0 the screen was made with. */
static int demo_run(double r0_m, uint64_t seed, seeing_result *res, sl_err *e)
{
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    seeing *se = NULL;
    float *f = NULL;
    sim_opts o;
    sim_opts_defaults(&o);
    o.width = o.height = 128;
    o.nframes = 100;
    o.wavelength_m = 633e-9;
    o.plate_scale_arcsec = 633e-9 / 2.2 * 206264.80624709636;
    o.r0_m = r0_m;
    o.wind_mps = 10;
    o.frame_interval_s = 0.05;
    o.seed = seed;
    o.photons_per_frame = 1e4;
    o.read_noise_e = 2;
    o.gain_e_per_adu = 1;
    o.bias_adu = 100;
    o.saturation_adu = 65535;
    o.fftw_flags = FFTW_ESTIMATE;
    int rc = mask_named(&m, "nrm17", e);
    if (!rc)
        rc = scene_binary(&sc, 0.7, 30, 1, e);
    if (!rc)
        rc = sim_new(&s, &o, m, sc, e);
    if (!rc)
        rc = seeing_new(&se, 128, 128, o.plate_scale_arcsec, o.wavelength_m,
                        mask_extent_m(m), e);
    if (!rc && !(f = malloc(sizeof(float) * 128 * 128)))
        rc = SL_ENOMEM;
    for (int k = 1; !rc && k <= o.nframes; k++)
        if (!(rc = sim_frame(s, k, f)))
            rc = seeing_add(se, f);
    if (!rc)
        rc = seeing_result_get(se, res);
    free(f);
    seeing_free(se);
    sim_free(s);
    scene_free(sc);
    mask_free(m);
    return rc;
}

/* The property issue 17 asked for: on the demo's screens the measured r0
 * is the screens' r0, not 1.3-1.6x it.  A plain variance of 100 frames
 * keeps ~65 % of the tilt (the run is 50 m of Kolmogorov screen; the rest
 * is slower) and read r0 1.36x high over 150 simulated runs; the
 * frozen-flow correction brings that to 1.06x (geometric mean).  One run
 * scatters by ~17 % (1 sigma: ~40 independent tilt samples), so the 15 %
 * bound is on the geometric mean of 6 runs (3 r0 x 2 seeds, its own
 * scatter ~7 %: the old estimator reads 1.31x on these, the new 1.04x),
 * and each run must be within 3 of its stated errors. */
TEST(demo_geometry_r0_within_15_percent)
{
    static const double r0s[3] = {0.30, 0.18, 0.10};
    double slog = 0;
    int n = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 2; j++) {
            /* a seed of its own per run: one seed at another r0 is the
             * same screen scaled, and reads the same ratio */
            uint64_t seed = 11 + 2 * (uint64_t)i + (uint64_t)j;
            seeing_result r;
            sl_err e = {0};
            int rc = demo_run(r0s[i], seed, &r, &e);
            CHECK(rc == SL_OK, "r0 %.2f seed %d: %s (%s)", r0s[i], (int)seed,
                  sl_strstatus(rc), e.msg);
            CHECK(fabs(r.wavelength_m - 633e-9) < 1e-15, "r0 stated at %g m",
                  r.wavelength_m);
            CHECK(fabs(r.r0_m - r0s[i]) < 3 * r.r0_err_m,
                  "r0 %.2f seed %d: %.3f +- %.3f m (u %.2f, K %.2f, n_eff %.0f)",
                  r0s[i], (int)seed, r.r0_m, r.r0_err_m, r.shift_d, r.tilt_kept,
                  r.n_eff);
            /* 0.5 m per frame over 1.079 m; a mask reads u somewhat high */
            CHECK(r.shift_d > 0.3 && r.shift_d < 1.0, "u = %.3f, true 0.46",
                  r.shift_d);
            slog += log(r.r0_m / r0s[i]);
            n++;
        }
    double gm = exp(slog / n);
    CHECK(gm > 0.85 && gm < 1.15, "r0 read %.3fx the screens' r0 (geometric "
          "mean of %d runs)", gm, n);
}

/* delta(x) = (1/I) int t^(-2/3) (2 J1(t)/t)^2 (1 - J0(2 x t)) dt by its
 * own quadrature (x = 0: I itself): t = v^3 on [0, 1], 8-point
 * Gauss-Legendre panels below half the shortest period beyond, to 4000,
 * then the tail's mean 3/(2 pi) 4000^(-8/3). */
static double gtilt_integral(double x)
{
    static const double gx[4] = {0.1834346424956498, 0.5255324099163290,
                                 0.7966664774136267, 0.9602898564975363};
    static const double gw[4] = {0.3626837833783620, 0.3137066458778873,
                                 0.2223810344533745, 0.1012285362903763};
    double sum = 0;
    int nv = 64 + (int)(8 * x);
    for (int p = 0; p < nv; p++)
        for (int i = 0; i < 8; i++) {
            double v = (p + 0.5 + 0.5 * (i & 1 ? gx[i / 2] : -gx[i / 2])) / nv;
            double t = v * v * v, a = t > 1e-6 ? 2 * j1(t) / t : 1;
            sum += gw[i / 2] * 0.5 / nv * 3 * a * a * (1 - (x > 0 ? j0(2 * x * t) : 0));
        }
    double h = fmin(0.5, 1.5 / (x > 0 ? x : 1));
    for (double lo = 1; lo < 4000; lo += h)
        for (int i = 0; i < 8; i++) {
            double t = lo + 0.5 * h * (1 + (i & 1 ? gx[i / 2] : -gx[i / 2]));
            double a = 2 * j1(t) / t;
            sum += gw[i / 2] * 0.5 * h * pow(t, -2.0 / 3) * a * a *
                   (1 - (x > 0 ? j0(2 * x * t) : 0));
        }
    return sum + 3 / (2 * M_PI) * pow(4000, -8.0 / 3);
}

/* The table behind the frozen-flow correction, and the variance constant:
 * pi^(2/3) 0.0228956 I = 0.1698 (Tyler's 0.170) for the screen's spectrum. */
TEST(tilt_structure_function)
{
    double I = gtilt_integral(0);
    CHECK_NEAR(I, 3.457494, 2e-5);
    CHECK_NEAR(pow(M_PI, 2.0 / 3) * 0.0228955871 * I, 0.16980, 5e-5);
    static const double xs[] = {0.013, 0.1, 0.37, 1, 2.5, 9, 30};
    for (size_t k = 0; k < sizeof xs / sizeof xs[0]; k++) {
        double want = gtilt_integral(xs[k]) / I, got = seeing_tilt_structure(xs[k]);
        CHECK(fabs(got - want) < 0.004 * want, "delta(%g) = %.6g, quadrature %.6g",
              xs[k], got, want);
    }
    CHECK(seeing_tilt_structure(0) == 0 && seeing_tilt_structure(-1) == 0, "delta(<= 0)");
    double prev = 0;
    for (double x = 1e-3; x < 1e5; x *= 1.07) {
        double d = seeing_tilt_structure(x);
        CHECK(d > prev && d < 1, "delta not increasing in (0, 1) at %g: %g", x, d);
        prev = d;
    }
}

TEST(bad_input)
{
    seeing *s = NULL;
    sl_err e;
    CHECK(seeing_new(&s, 64, 64, 0, 5e-7, 1, &e) == SL_EINVAL && strstr(e.msg, "plate scale"), "%s", e.msg);
    CHECK(seeing_new(&s, 64, 64, 0.05, 5e-7, 1, &e) == SL_OK, "%s", e.msg);
    float f[64 * 64] = {0};
    seeing_add(s, f);
    seeing_result r;
    CHECK(seeing_result_get(s, &r) == SL_EDATA, "empty frames gave an r0");
    seeing_free(s);
}

TC_MAIN(TC_CASE(full_aperture_r0_matches_truth), TC_CASE(mask_orders_screens),
        TC_CASE(demo_geometry_r0_within_15_percent), TC_CASE(tilt_structure_function),
        TC_CASE(bad_input))
