/* test_fringe.c - the power-spectrum fringe fit (fringe.h) against
 * analytic binaries: the mean power spectrum T(|u|) |V(u)|^2, with T a
 * transfer function steep enough to fall by a large factor across one
 * frequency bin of a small crop (30 px: the size `auto` crops a close
 * pair to), noiseless and with speckle statistics. */
#include <math.h>
#include <stdlib.h>

#include "base/rng.h"
#include "spectra/fringe.h"
#include "tcheck.h"

#define W 30
#define NFRAMES 40

/* The pixels' own transfer function, which the fit divides out. */
static double pixel_mtf(double kx, double ky)
{
    double sx = kx != 0 ? sin(M_PI * kx) / (M_PI * kx) : 1;
    double sy = ky != 0 ? sin(M_PI * ky) / (M_PI * ky) : 1;
    return sx * sx * sy * sy;
}

/* A speckle transfer function: the seeing peak (1/e at 0.05 cycles/px)
 * over the speckle plateau falling to the cut-off at 0.55; across one
 * 1/30 cycles/px ring it falls by up to 40 %. */
static double transfer(double k)
{
    double pl = k < 0.55 ? (1 - k / 0.55) * (1 - k / 0.55) : 0;
    return 0.9 * exp(-(k / 0.05) * (k / 0.05)) + 0.1 * pl;
}

/* The mean spectrum of a binary (d, flux ratio r) in FFT order; with g,
 * each frequency a mean of NFRAMES exponential (speckle) variables,
 * Hermitian. */
static void binary_spectrum(double *ps, double dx, double dy, double r, rng *g)
{
    for (int q = 0; q < W; q++)
        for (int p = 0; p < W; p++) {
            int fp = p <= W / 2 ? p : p - W, fq = q <= W / 2 ? q : q - W;
            double kx = (double)fp / W, ky = (double)fq / W;
            double v2 = 1 + r * r + 2 * r * cos(2 * M_PI * (kx * dx + ky * dy));
            ps[q * W + p] = transfer(hypot(kx, ky)) * pixel_mtf(kx, ky) * v2 / ((1 + r) * (1 + r));
        }
    if (!g)
        return;
    for (int q = 0; q < W; q++)
        for (int p = 0; p < W; p++) {
            int pm = (W - p) % W, qm = (W - q) % W;
            if (q * W + p > qm * W + pm)
                continue;  /* the mirror sample was drawn */
            double m = 0;
            for (int f = 0; f < NFRAMES; f++)
                m += -log(1 - rng_uniform(g));
            ps[q * W + p] *= m / NFRAMES;
            ps[qm * W + pm] = ps[q * W + p];
        }
}

static double pa_diff_180(double a, double b)
{
    double d = fmod(fabs(a - b), 180);
    return d > 90 ? 180 - d : d;
}

/* Noiseless: the fit recovers d and r, and nothing is left over.  With
 * each ring normalised by its plain mean, the transfer function's fall
 * across the ring was left in the normalised spectrum as a radial slope
 * that the fit took for misfit. */
TEST(noiseless_pair_on_a_small_crop)
{
    static const double ds[][3] = {{1.2, -1.3, 0.56}, {-0.8, 2.9, 0.3}, {4.1, 1.7, 0.8}};
    double *ps = malloc(sizeof(double) * W * W);
    CHECK(ps, "allocation");
    for (int i = 0; i < 3 && !t->failed; i++) {
        binary_spectrum(ps, ds[i][0], ds[i][1], ds[i][2], NULL);
        fringe_result f;
        sl_err e = {0};
        int rc = fringe_fit_2d(ps, W, W, 1e-9, NFRAMES, W / 2, 7.5, &f, &e);
        double sep = hypot(ds[i][0], ds[i][1]);
        double pa = fmod(atan2(-ds[i][0], ds[i][1]) * 180 / M_PI + 360, 180);
        double dm = -2.5 * log10(ds[i][2]);
        CHECK(rc == SL_OK && f.detected, "pair %d: rc %d detected %d chi2 %.3f sep %.3f dm %.3f (%s)", i, rc,
              f.detected, f.chi2_red, f.sep_px, f.dm_mag, e.msg);
        CHECK(fabs(f.sep_px - sep) < 0.02 && pa_diff_180(f.pa_deg, pa) < 0.5 &&
                  fabs(f.dm_mag - dm) < 0.03,
              "pair %d: sep %.4f PA %.3f dm %.4f; truth %.4f %.3f %.4f", i, f.sep_px,
              f.pa_deg, f.dm_mag, sep, pa, dm);
        CHECK(f.chi2_red < 0.05, "pair %d: reduced chi2 %.4f on a noiseless spectrum", i,
              f.chi2_red);
    }
    free(ps);
}

/* Speckle statistics (each frequency the mean of 40 exponential
 * variables): the reduced chi^2 is about 1, the pair detected, and the
 * truth within 4 of the stated sigmas, on ten draws. */
TEST(speckle_noise_errors_on_a_small_crop)
{
    double *ps = malloc(sizeof(double) * W * W);
    CHECK(ps, "allocation");
    rng g;
    rng_init(&g, 7, 3);
    double chi_max = 0, chi_min = 1e9;
    for (int k = 0; k < 10 && !t->failed; k++) {
        binary_spectrum(ps, 1.2, -1.3, 0.56, &g);
        fringe_result f;
        sl_err e = {0};
        int rc = fringe_fit_2d(ps, W, W, 1e-9, NFRAMES, W / 2, 7.5, &f, &e);
        CHECK(rc == SL_OK && f.detected, "draw %d: rc %d detected %d chi2 %.2f (%s)", k,
              rc, f.detected, f.chi2_red, e.msg);
        chi_max = fmax(chi_max, f.chi2_red), chi_min = fmin(chi_min, f.chi2_red);
        double sep = hypot(1.2, -1.3), dm = -2.5 * log10(0.56);
        CHECK(fabs(f.sep_px - sep) < 4 * f.sep_err_px + 0.01 &&
                  fabs(f.dm_mag - dm) < 4 * f.dm_err_mag + 0.01,
              "draw %d: sep %.4f +- %.4f dm %.4f +- %.4f; truth %.4f %.4f", k, f.sep_px,
              f.sep_err_px, f.dm_mag, f.dm_err_mag, sep, dm);
    }
    CHECK(chi_min > 0.6 && chi_max < 1.6, "reduced chi2 %.3f .. %.3f over ten draws",
          chi_min, chi_max);
    free(ps);
}

/* A noiseless binary's mean spectrum on an n x n frame, FFT order. */
static void binary_spectrum_n(double *ps, int n, double dx, double dy, double r)
{
    for (int q = 0; q < n; q++)
        for (int p = 0; p < n; p++) {
            int fp = p <= n / 2 ? p : p - n, fq = q <= n / 2 ? q : q - n;
            double kx = (double)fp / n, ky = (double)fq / n;
            double v2 = 1 + r * r + 2 * r * cos(2 * M_PI * (kx * dx + ky * dy));
            ps[(size_t)q * n + p] = transfer(hypot(kx, ky)) * pixel_mtf(kx, ky) * v2 /
                                    ((1 + r) * (1 + r));
        }
}

/* A 512^2 frame, whose grid search runs on every 4th frequency along
 * each axis (fringe.c, grid_on): pairs up to the largest separation
 * searched (16 px, the fastest fringes: 32 frequencies each) are found
 * as on the small crop, the fit over every frequency. */
TEST(noiseless_pairs_on_a_large_frame)
{
    static const double ds[][3] = {{9.3, -5.2, 0.5}, {-2.1, 15.3, 0.7}, {15.4, 1.1, 0.3}};
    int n = 512;
    double *ps = malloc(sizeof(double) * (size_t)n * n);
    CHECK(ps, "allocation");
    for (int i = 0; i < 3 && !t->failed; i++) {
        binary_spectrum_n(ps, n, ds[i][0], ds[i][1], ds[i][2]);
        fringe_result f;
        sl_err e = {0};
        int rc = fringe_fit_2d(ps, n, n, 1e-9, NFRAMES, n / 2 - 1, 16, &f, &e);
        double sep = hypot(ds[i][0], ds[i][1]);
        double pa = fmod(atan2(-ds[i][0], ds[i][1]) * 180 / M_PI + 360, 180);
        double dm = -2.5 * log10(ds[i][2]);
        CHECK(rc == SL_OK && f.detected, "pair %d: rc %d detected %d chi2 %.3f (%s)", i, rc,
              f.detected, f.chi2_red, e.msg);
        CHECK(fabs(f.sep_px - sep) < 0.02 && pa_diff_180(f.pa_deg, pa) < 0.5 &&
                  fabs(f.dm_mag - dm) < 0.03,
              "pair %d: sep %.4f PA %.3f dm %.4f; truth %.4f %.3f %.4f", i, f.sep_px,
              f.pa_deg, f.dm_mag, sep, pa, dm);
    }
    free(ps);
}

TC_MAIN(TC_CASE(noiseless_pair_on_a_small_crop), TC_CASE(speckle_noise_errors_on_a_small_crop),
        TC_CASE(noiseless_pairs_on_a_large_frame))
