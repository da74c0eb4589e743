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
    o.frame_interval_s = 0.05; /* 0.5 m per frame: nearly independent */
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

/* Through the 17-hole mask the estimate is an effective r0, but it orders
 * screens: worse seeing, smaller r0 - also on a bias pedestal. */
TEST(mask_orders_screens)
{
    seeing_result r;
    double a = estimate("nrm17", 0.40, 150, &r, 200);
    double b = estimate("nrm17", 0.15, 150, &r, 200);
    double c = estimate("nrm17", 0.06, 150, &r, 200);
    CHECK(a > b && b > c, "r0 estimates %.3f, %.3f, %.3f for 0.40, 0.15, 0.06 m", a, b, c);
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

TC_MAIN(TC_CASE(full_aperture_r0_matches_truth), TC_CASE(mask_orders_screens), TC_CASE(bad_input))
