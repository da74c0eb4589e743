/* test_tsm_extent.c - step 3's angular average capped by the object's
 * diameter (recon/tsm/tsm_extent.c).
 *
 * extent_analytic: projection power spectra of a binary of Gaussian stars
 * (sigma 1.5 px, r = 1, projected separation d |cos theta|): the
 * autocorrelation is exp(-x^2 / 4 sigma^2) at 0 and half that at +-d, so
 * the largest lag above 0.05 of the peak is d + floor(2 sigma sqrt(ln 10))
 * = d + 4 (a single star: floor(2 sigma sqrt(ln 20)) = 5), exactly.
 * wide_binary_dm: the simulator's 17-hole binary, noiseless, 30 px apart
 * at 128^2 (15 lambda/D), dm 1: the capped average reads dm within 0.05,
 * the old fixed 1.5-bin average reads it faint by over 0.1 (measured
 * 1.16 / 1.25 on the 200^2 bench at 30 / 40 px). */
#include <fftw3.h>
#include <stdlib.h>
#include <string.h>

#include "sim/mask.h"
#include "measure/metrics.h"
#include "sim/scene.h"
#include "sim/sim.h"
#include "tcheck.h"
#include "tsm/tsm.h"

static void binary_power(double *ps, int nang, int nf, int ns, double d, double r)
{
    const double sigma = 1.5;
    for (int a = 0; a < nang; a++) {
        double da = d * fabs(cos(M_PI * a / nang));
        for (int u = 0; u < nf; u++) {
            double k = 2 * M_PI * u / ns;
            double g = exp(-k * k * sigma * sigma);          /* |Gaussian|^2 */
            ps[(size_t)a * nf + u] = g * (1 + r * r + 2 * r * cos(k * da));
        }
    }
}

TEST(extent_analytic)
{
    int ns = 128, nf = ns / 2 + 1, nang = 18;
    double *ps = malloc(sizeof(double) * nang * nf);
    CHECK(ps, "malloc");
    binary_power(ps, nang, nf, ns, 0, 0);
    double e0 = tsm_extent_px(ps, nang, nf, ns, 0.05, NULL);
    const int seps[] = {10, 30};
    double e[2];
    tpool *pool[2] = {tpool_new(2, NULL), tpool_new(3, NULL)};
    CHECK(pool[0] && pool[1], "tpool_new");
    for (int i = 0; i < 2; i++) {
        binary_power(ps, nang, nf, ns, seps[i], 1);
        e[i] = tsm_extent_px(ps, nang, nf, ns, 0.05, NULL);
        /* the maximum, whoever scans what: the widest angle moved to
         * every task of the pools' (rows rotated by rot) */
        double *rp = malloc(sizeof(double) * nang * nf);
        CHECK(rp, "malloc");
        for (int rot = 0; rot < nang; rot++) {
            for (int a = 0; a < nang; a++)
                memcpy(rp + (size_t)((a + rot) % nang) * nf, ps + (size_t)a * nf,
                       sizeof(double) * nf);
            for (int p = 0; p < 2; p++) {
                double ep = tsm_extent_px(rp, nang, nf, ns, 0.05, pool[p]);
                CHECK(ep == e[i], "%d px, rotated %d: extent %g on %d threads, %g on one",
                      seps[i], rot, ep, tpool_size(pool[p]), e[i]);
            }
        }
        free(rp);
    }
    tpool_free(pool[0]), tpool_free(pool[1]);
    free(ps);
    CHECK(e0 == 5, "single star: extent %g px, want 5", e0);
    CHECK(e[0] == 14 && e[1] == 34, "binary: extent %g / %g px, want 14 / 34", e[0], e[1]);
    /* the cap turns the farthest feature by 0.4 rad at the arc's end */
    double cap = tsm_arc_cap(34, ns);
    CHECK(fabs(2 * M_PI * 34 * cap / ns - 0.4) < 1e-12, "arc cap %g bins", cap);
    CHECK(isinf(tsm_arc_cap(0, ns)), "no extent: no cap");
}

/* Noiseless frames of a binary sep_px apart at PA 30 through the 17-hole
 * mask (Nyquist sampling of its extent E: lambda / 2E per pixel). */
static float *sim_binary(int n, int nfr, double sep_px, double dm)
{
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    sim_opts o;
    sim_opts_defaults(&o);
    o.width = o.height = n;
    o.nframes = nfr;
    o.fftw_flags = FFTW_ESTIMATE;
    float *fr = malloc(sizeof(float) * n * n * nfr);
    int rc = fr ? mask_named(&m, "nrm17", &e) : SL_ENOMEM;
    double px_arcsec = rc == SL_OK ? o.wavelength_m / (2 * mask_extent_m(m)) * 180 * 3600 / M_PI : 0;
    if (rc == SL_OK)
        rc = scene_binary(&sc, sep_px * px_arcsec, 30, dm, &e);
    if (rc == SL_OK)
        rc = sim_new(&s, &o, m, sc, &e);
    for (int k = 0; rc == SL_OK && k < nfr; k++)
        rc = sim_frame(s, k, fr + (size_t)k * n * n);
    sim_free(s), scene_free(sc), mask_free(m);
    if (rc != SL_OK) {
        free(fr);
        return NULL;
    }
    return fr;
}

static double tsm_dm(const float *fr, int n, int nfr, double arc, double *arc_used)
{
    tsm_opts o;
    tsm_opts_defaults(&o);
    o.nangles = 180;
    o.arc_bins = arc;
    o.fftw_flags = FFTW_ESTIMATE;
    tsm *ts = tsm_new(n, n, &o, NULL);
    float *img = malloc(sizeof(float) * n * n);
    binary_result b;
    double dm = NAN, ext;
    if (ts && img) {
        for (int k = 0; k < nfr; k++)
            tsm_add(ts, fr + (size_t)k * n * n);
        if (tsm_result(ts, img) == SL_OK && metrics_binary(img, n, n, &b) == SL_OK &&
            fabs(b.sep_px - 30) < 0.1 && fabs(b.pa_deg - 30) < 0.5)
            dm = b.dm_mag;
        tsm_arc(ts, arc_used, &ext);
    }
    tsm_free(ts);
    free(img);
    return dm;
}

TEST(wide_binary_dm)
{
    int n = 128, nfr = 60;
    float *fr = sim_binary(n, nfr, 30, 1);
    CHECK(fr, "simulation failed");
    double arc_capped, arc_fixed;
    double dm_capped = tsm_dm(fr, n, nfr, 0, &arc_capped);
    double dm_fixed = tsm_dm(fr, n, nfr, 1.5, &arc_fixed);
    free(fr);
    printf("    dm 1 at 30 px: capped arc %.2f bins reads %.3f, 1.5 bins %.3f\n", arc_capped,
           dm_capped, dm_fixed);
    CHECK(arc_capped > 0 && arc_capped < 1.5 && arc_fixed == 1.5, "arcs %g, %g", arc_capped,
          arc_fixed);
    CHECK(fabs(dm_capped - 1) < 0.05, "capped: dm %.3f (or the binary was lost)", dm_capped);
    CHECK(dm_fixed - 1 > 0.1, "fixed 1.5 bins: dm %.3f, expected faint", dm_fixed);
}

TC_MAIN(TC_CASE(extent_analytic), TC_CASE(wide_binary_dm))
