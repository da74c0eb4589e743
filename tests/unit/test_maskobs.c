/* test_maskobs.c - an aperture mask's V2 and closure phases (maskobs.h)
 * on the simulator's frames: a cophased point source reads V2 1 and
 * closure phase 0; a cophased binary's closure phases are its model's at
 * the sampled uv (OIFITS's sign and orientation: east = -x); turbulent
 * photon-noise frames give closure phases consistent with 0 within their
 * errors; redundant baselines are not measured; bad arguments refused. */
#include <fftw3.h>
#include <stdlib.h>

#include "sim/mask.h"
#include "sim/scene.h"
#include "sim/sim.h"
#include "spectra/maskobs.h"
#include "tcheck.h"

#define RAD_ARCSEC (180.0 * 3600.0 / M_PI)

typedef struct run {
    int n, nframes, turbulence;
    double photons, sep_arcsec, pa_deg, dm;
} run;

/* Simulate r through nrm17 into maskobs; the result in out, the plate
 * scale in *ps.  SL_OK or the first error (message in e). */
static int observe(const run *r, maskobs_result *out, double *ps, sl_err *e)
{
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    maskobs *mo = NULL;
    sim_opts o;
    sim_opts_defaults(&o);
    o.width = o.height = r->n;
    o.nframes = r->nframes;
    o.turbulence = r->turbulence;
    o.photons_per_frame = r->photons;
    o.fftw_flags = FFTW_ESTIMATE;
    float *f = malloc(sizeof(float) * r->n * r->n);
    int rc = f ? mask_named(&m, "nrm17", e) : SL_ENOMEM;
    if (rc == SL_OK)
        rc = r->sep_arcsec > 0 ? scene_binary(&sc, r->sep_arcsec, r->pa_deg, r->dm, e)
                               : scene_named(&sc, "point", 0, 0, 0, e);
    if (rc == SL_OK)
        rc = sim_new(&s, &o, m, sc, e);
    if (rc == SL_OK) {
        int nh = mask_nholes(m);
        double x[MASK_MAX_HOLES], y[MASK_MAX_HOLES];
        for (int i = 0; i < nh; i++)
            mask_hole(m, i, &x[i], &y[i]);
        maskobs_opts mop;
        maskobs_opts_defaults(&mop);
        mop.wavelength_m = o.wavelength_m;
        mop.plate_scale_arcsec = *ps = sim_plate_scale_arcsec(s);
        mop.adu_per_photon = r->photons > 0 ? 1.0 / o.gain_e_per_adu : 0;
        mop.measure = 0;
        if (!(mo = maskobs_new(x, y, nh, mask_hole_diameter_m(m), r->n, r->n, &mop, e)))
            rc = e->code;
    }
    for (int k = 0; rc == SL_OK && k < r->nframes; k++)
        if ((rc = sim_frame(s, k, f)) == SL_OK && (rc = maskobs_add(mo, f)) != SL_OK)
            sl_seterr(e, rc, "%s", maskobs_errmsg(mo));
    if (rc == SL_OK && (rc = maskobs_result_get(mo, out)) != SL_OK)
        sl_seterr(e, rc, "%s", maskobs_errmsg(mo));
    maskobs_free(mo);
    sim_free(s);
    scene_free(sc);
    mask_free(m);
    free(f);
    return rc;
}

TEST(cophased_point_source)
{
    /* 256^2: the simulator's holes are 12 pupil pixels across there; at
     * 128^2 (6 pixels) their autocorrelation near a splodge's centre is
     * rounder than true disks' and V2 reads 1.05-1.45 */
    run r = {256, 2, 0, 0, 0, 0, 0};
    maskobs_result res;
    double ps;
    sl_err e = {0};
    CHECK(observe(&r, &res, &ps, &e) == SL_OK, "%s", e.msg);
    double worst_v2 = 0, worst_cp = 0;
    for (int i = 0; i < res.nvis2; i++)
        worst_v2 = fmax(worst_v2, fabs(res.vis2[i].vis2 - 1));
    for (int i = 0; i < res.nt3; i++)
        worst_cp = fmax(worst_cp, fabs(res.t3[i].phi_deg));
    int nv = res.nvis2, nt = res.nt3, lv = res.nvis2_lost, lt = res.nt3_lost;
    maskobs_result_clear(&res);
    printf("  nrm17 256^2: %d V2 (%d redundant: not measured), %d triangles (%d lost); "
           "|V2 - 1| <= %.4f, |CP| <= %.2e deg\n", nv, lv, nt, lt, worst_v2, worst_cp);
    CHECK(nv + lv == 136 && nt + lt == 680, "%d + %d baselines, %d + %d triangles",
          nv, lv, nt, lt);
    /* nrm17's 85 baselines with another within a hole diameter (78 within
     * a quarter of one) have no clean pixel */
    CHECK(nv >= 50 && nt >= 35, "only %d V2 and %d triangles measured", nv, nt);
    CHECK(worst_v2 < 0.2, "V2 of a cophased point source off by %.4f", worst_v2);
    CHECK(worst_cp < 1e-3, "closure phase of a point source %.3g deg", worst_cp);
}

/* The binary's closure phase at the OIFITS uv of row t (east, north
 * metres): arg V(u1) V(u2) conj V(u1 + u2), V = 1 + r exp(-2 pi i u.a /
 * lambda) with a the companion's offset (east, north) in radians. */
static double model_cp_deg(const maskobs_t3 *t, double sep_rad, double pa_deg,
                           double r, double lambda)
{
    double ae = sep_rad * sin(pa_deg * M_PI / 180), an = sep_rad * cos(pa_deg * M_PI / 180);
    double u[3] = {t->u1_m, t->u2_m, t->u1_m + t->u2_m};
    double v[3] = {t->v1_m, t->v2_m, t->v1_m + t->v2_m}, cp = 0;
    for (int k = 0; k < 3; k++) {
        double ph = -2 * M_PI * (u[k] * ae + v[k] * an) / lambda;
        double a = atan2(r * sin(ph), 1 + r * cos(ph));
        cp += k < 2 ? a : -a;
    }
    return remainder(cp, 2 * M_PI) * 180 / M_PI;
}

TEST(cophased_binary_closure_phases_are_the_model)
{
    run r = {128, 2, 0, 0, 0.2, 30, 1};
    maskobs_result res;
    double ps;
    sl_err e = {0};
    CHECK(observe(&r, &res, &ps, &e) == SL_OK, "%s", e.msg);
    double worst = 0, rms = 0, mirror = 0;
    for (int i = 0; i < res.nt3; i++) {
        double m = model_cp_deg(&res.t3[i], 0.2 / RAD_ARCSEC, 30, pow(10, -0.4), 500e-9);
        double mm = model_cp_deg(&res.t3[i], 0.2 / RAD_ARCSEC, -30, pow(10, -0.4), 500e-9);
        worst = fmax(worst, fabs(remainder(res.t3[i].phi_deg - m, 360)));
        rms += m * m;
        mirror = fmax(mirror, fabs(remainder(res.t3[i].phi_deg - mm, 360)));
    }
    int nt = res.nt3;
    maskobs_result_clear(&res);
    printf("  binary 0.2\" PA 30 dm 1: %d closure phases (rms %.1f deg) within %.2e deg "
           "of the model; the mirrored sky (PA -30) off by up to %.1f deg\n", nt,
           sqrt(rms / nt), worst, mirror);
    CHECK(sqrt(rms / nt) > 5, "the binary's closure phases are too small to test (%.2f deg)",
          sqrt(rms / nt));
    CHECK(worst < 0.01, "a closure phase off its model by %.4f deg", worst);
    CHECK(mirror > 5, "east-west mirrored binary fits as well (%.2f deg)", mirror);
}

TEST(turbulent_point_source_closes)
{
    run r = {128, 100, 1, 1e5, 0, 0, 0};
    maskobs_result res;
    double ps;
    sl_err e = {0};
    CHECK(observe(&r, &res, &ps, &e) == SL_OK, "%s", e.msg);
    double chi2 = 0, mean = 0, v2max = 0, errmin = INFINITY;
    for (int i = 0; i < res.nt3; i++) {
        double z = res.t3[i].phi_deg / res.t3[i].phi_err_deg;
        chi2 += z * z;
        mean += res.t3[i].phi_deg / res.nt3;
        errmin = fmin(errmin, res.t3[i].phi_err_deg);
    }
    for (int i = 0; i < res.nvis2; i++) {
        v2max = fmax(v2max, res.vis2[i].vis2);
        errmin = fmin(errmin, res.vis2[i].vis2_err);
    }
    int nt = res.nt3, nf = res.nframes;
    double cv = res.corr_vis2, cp = res.corr_phi, ca = res.corr_amp;
    maskobs_result_clear(&res);
    printf("  turbulent point source, 100 frames, 1e5 photons: chi2/n %.2f over %d "
           "closure phases (mean %.2f deg), V2 <= %.3f; correlation factors V2 %.2f, "
           "phase %.2f, amplitude %.2f\n", chi2 / nt, nt, mean, v2max, cv, cp, ca);
    CHECK(nf == 100, "%d frames used", nf);
    CHECK(errmin > 0, "an error <= 0 (%g)", errmin);
    /* 100 frames of 10 m/s see one pupil crossing: the slow part of the
     * holes' slopes is neither averaged nor measurable (maskobs.h, Errors:
     * 2.4 here, 1.0-1.2 over 400 frames) */
    CHECK(chi2 / nt < 3, "closure phases of a point source: chi2/n %.2f", chi2 / nt);
    CHECK(v2max < 1.2, "V2 %.3f above 1 through turbulence", v2max);
}

TEST(redundant_baselines_not_measured)
{
    /* 0-1 and 1-2 are the same baseline: neither has a clean pixel, and
     * the three triangles using one of them are lost; (0, 2, 3) is not */
    double x[] = {-0.3, 0.0, 0.3, 0.05}, y[] = {0.0, 0.0, 0.0, 0.45};
    maskobs_opts o;
    maskobs_opts_defaults(&o);
    o.plate_scale_arcsec = 500e-9 / (2 * 0.85) * RAD_ARCSEC;
    o.measure = 0;
    sl_err e = {0};
    maskobs *m = maskobs_new(x, y, 4, 0.1, 64, 64, &o, &e);
    CHECK(m, "%s", e.msg);
    float *f = calloc(64 * 64, sizeof *f);
    f[32 * 64 + 32] = 1;
    maskobs_add(m, f);
    maskobs_add(m, f);
    maskobs_result res;
    int rc = maskobs_result_get(m, &res);
    maskobs_free(m);
    free(f);
    CHECK(rc == SL_OK, "result");
    int nv = res.nvis2, lv = res.nvis2_lost, nt = res.nt3, lt = res.nt3_lost;
    int has01 = 0;
    for (int i = 0; i < nv; i++)
        has01 |= res.vis2[i].sta[0] == 0 && res.vis2[i].sta[1] == 1;
    maskobs_result_clear(&res);
    CHECK(nv == 4 && lv == 2 && !has01, "%d V2 measured, %d lost", nv, lv);
    CHECK(nt == 1 && lt == 3, "%d triangles measured, %d lost", nt, lt);
}

TEST(bad_arguments_refused)
{
    double x[] = {0, 0.3, 0.1}, y[] = {0, 0, 0.4};
    maskobs_opts o;
    maskobs_opts_defaults(&o);
    sl_err e = {0};
    CHECK(!maskobs_new(x, y, 3, 0.1, 64, 64, &o, &e) && e.code == SL_EINVAL &&
          strstr(e.msg, "plate scale"), "NAN plate scale: %s", e.msg);
    o.plate_scale_arcsec = 0.05;
    CHECK(!maskobs_new(x, y, 2, 0.1, 64, 64, &o, &e) && strstr(e.msg, "3 holes"),
          "2 holes: %s", e.msg);
    o.wavelength_m = -1;
    CHECK(!maskobs_new(x, y, 3, 0.1, 64, 64, &o, &e) && strstr(e.msg, "wavelength"),
          "negative wavelength: %s", e.msg);
    o.wavelength_m = 500e-9;
    maskobs *m = maskobs_new(x, y, 3, 0.1, 64, 64, &o, &e);
    CHECK(m, "%s", e.msg);
    float f[64 * 64] = {0};
    f[100] = NAN;
    int rc = maskobs_add(m, f);
    maskobs_result res;
    int rc2 = maskobs_result_get(m, &res);
    maskobs_free(m);
    CHECK(rc == SL_EDATA && rc2 == SL_EDATA, "NaN frame %d, result of none %d", rc, rc2);
}

TC_MAIN(TC_CASE(cophased_point_source), TC_CASE(cophased_binary_closure_phases_are_the_model),
        TC_CASE(turbulent_point_source_closes), TC_CASE(redundant_baselines_not_measured),
        TC_CASE(bad_arguments_refused))
