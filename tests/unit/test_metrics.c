/* test_metrics.c - correlation, sub-pixel registration and binary-star
 * astrometry against analytic truths (images built in Fourier space with
 * exact phase ramps, so positions are known to machine precision). */
#include <complex.h>
#include <fftw3.h>

#include "measure/metrics.h"
#include "base/rng.h"
#include "tcheck.h"

#include <stdlib.h>

static int sf(int i, int n) { return i <= (n - 1) / 2 ? i : i - n; }

/* Diffraction-limited image of point sources (x, y, flux) with a clear
 * circular pupil of diameter n/2 (Nyquist sampling): the OTF times the
 * sources' exact Fourier phase ramps, inverse FFT. */
static void points_image(int n, int np, const double *x, const double *y,
                         const double *f, float *img)
{
    size_t N = (size_t)n * n;
    fftw_complex *a = fftw_alloc_complex(N);
    fftw_plan fw = fftw_plan_dft_2d(n, n, a, a, FFTW_FORWARD, FFTW_ESTIMATE);
    fftw_plan bw = fftw_plan_dft_2d(n, n, a, a, FFTW_BACKWARD, FFTW_ESTIMATE);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double r = hypot(sf(i, n), sf(j, n));
            a[(size_t)j * n + i] = r < n / 4.0 ? 1.0 : 0.0;
        }
    fftw_execute(fw); /* pupil -> amplitude PSF */
    for (size_t k = 0; k < N; k++)
        a[k] = creal(a[k] * conj(a[k]));
    fftw_execute(fw); /* intensity PSF -> OTF (real: symmetric PSF) */
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double complex o = 0;
            for (int s = 0; s < np; s++)
                o += f[s] * cexp(-2.0 * M_PI * I *
                                 (sf(i, n) * x[s] + sf(j, n) * y[s]) / n);
            a[(size_t)j * n + i] *= o;
        }
    fftw_execute(bw);
    double peak = 0;
    for (size_t k = 0; k < N; k++)
        if (creal(a[k]) > peak)
            peak = creal(a[k]);
    for (size_t k = 0; k < N; k++)
        img[k] = (float)(creal(a[k]) / peak);
    fftw_destroy_plan(fw);
    fftw_destroy_plan(bw);
    fftw_free(a);
}

TEST(corr_identities)
{
    int n = 48;
    float *a = malloc(n * n * sizeof *a), *b = malloc(n * n * sizeof *b);
    rng r;
    rng_init(&r, 1, 0);
    for (int i = 0; i < n * n; i++)
        a[i] = (float)rng_normal(&r);
    double c1 = metrics_corr(a, a, n, n);
    for (int i = 0; i < n * n; i++)
        b[i] = -a[i];
    double c2 = metrics_corr(a, b, n, n);
    for (int i = 0; i < n * n; i++)
        b[i] = 3.0f * a[i] + 7.0f; /* c is affine-invariant */
    double c3 = metrics_corr(a, b, n, n);
    free(a);
    free(b);
    CHECK_NEAR(c1, 1.0, 1e-12);
    CHECK_NEAR(c2, -1.0, 1e-12);
    CHECK_NEAR(c3, 1.0, 1e-6);
}

TEST(corr_independent_noise)
{
    int n = 64;
    float *a = malloc(n * n * sizeof *a), *b = malloc(n * n * sizeof *b);
    rng r;
    rng_init(&r, 2, 0);
    double worst = 0;
    for (int rep = 0; rep < 5; rep++) {
        for (int i = 0; i < n * n; i++) {
            a[i] = (float)rng_normal(&r);
            b[i] = (float)rng_normal(&r) + 10.0f;
        }
        double c = fabs(metrics_corr(a, b, n, n));
        worst = c > worst ? c : worst;
    }
    free(a);
    free(b);
    CHECK(worst < 4.0 / n, "|c| = %g for independent noise", worst);
}

TEST(register_subpixel_shift)
{
    int n = 96;
    double x[3] = {40.3, 55.7, 47.0}, y[3] = {44.1, 50.2, 60.9};
    double f[3] = {1.0, 0.6, 0.3};
    double x2[3], y2[3], dx = 3.37, dy = -5.81;
    for (int k = 0; k < 3; k++) {
        x2[k] = x[k] + dx;
        y2[k] = y[k] + dy;
    }
    float *a = malloc(n * n * sizeof *a), *b = malloc(n * n * sizeof *b);
    float *reg = malloc(n * n * sizeof *reg);
    points_image(n, 3, x, y, f, a);
    points_image(n, 3, x2, y2, f, b);
    metrics_plan *p = metrics_plan_new(n, n, NULL);
    double ex = 0, ey = 0, c0 = metrics_corr(a, b, n, n), c = 0;
    int rc = metrics_register(p, a, b, reg, &ex, &ey);
    double creg = metrics_corr(a, reg, n, n);
    double ex2 = 0, ey2 = 0;
    int rc2 = metrics_corr_registered(a, b, n, n, &c, &ex2, &ey2);
    metrics_plan_free(p);
    free(a);
    free(b);
    free(reg);
    CHECK(rc == SL_OK && rc2 == SL_OK, "status %d %d", rc, rc2);
    CHECK_NEAR(ex, dx, 0.02);
    CHECK_NEAR(ey, dy, 0.02);
    CHECK_NEAR(ex2, dx, 0.02);
    CHECK(c0 < 0.5, "unregistered c = %g should be low", c0);
    CHECK(creg > 0.9999 && c > 0.9999, "registered c = %g, %g", creg, c);
}

/* Binary at several separations, PAs (all quadrants, near 0 and 180) and
 * magnitude differences; noiseless diffraction-limited, lambda/D = 2 px. */
TEST(binary_recovers_sep_pa_dm)
{
    int n = 128;
    static const double pa[] = {0.7, 45.0, 100.0, 179.6, 200.0, 275.0, 333.0};
    static const double sep[] = {10.3, 17.7, 25.0, 38.2};
    static const double dm[] = {0.3, 1.0, 2.0};
    float *img = malloc(n * n * sizeof *img);
    metrics_plan *p = metrics_plan_new(n, n, NULL);
    double wsep = 0, wpa = 0, wdm = 0;
    int cases = 0;
    for (int a = 0; a < 7; a++)
        for (int s = 0; s < 4; s++) {
            int d = (a + s) % 3;
            double x[2] = {64.37 - 0.2 * s, 63.81 + 0.3 * a}, y[2];
            y[0] = x[1];
            x[1] = x[0] - sep[s] * sin(pa[a] * M_PI / 180);
            y[1] = y[0] + sep[s] * cos(pa[a] * M_PI / 180);
            double f[2] = {1.0, pow(10.0, -0.4 * dm[d])};
            points_image(n, 2, x, y, f, img);
            binary_result br;
            int rc = metrics_plan_binary(p, img, &br);
            CHECK(rc == SL_OK, "case pa %g sep %g: %s", pa[a], sep[s],
                  metrics_errmsg(p));
            double e1 = fabs(br.sep_px - sep[s]);
            double e2 = fabs(remainder(br.pa_deg - pa[a], 360.0));
            double e3 = fabs(br.dm_mag - dm[d]);
            CHECK(e1 < 0.05 && e2 < 0.3 && e3 < 0.05,
                  "pa %g sep %g dm %g -> pa %g sep %g dm %g", pa[a], sep[s],
                  dm[d], br.pa_deg, br.sep_px, br.dm_mag);
            CHECK(br.pa_deg >= 0 && br.pa_deg < 360, "pa %g", br.pa_deg);
            wsep = e1 > wsep ? e1 : wsep;
            wpa = e2 > wpa ? e2 : wpa;
            wdm = e3 > wdm ? e3 : wdm;
            cases++;
        }
    metrics_plan_free(p);
    free(img);
    CHECK(cases == 28, "%d cases", cases);
    printf("  binary worst errors: sep %.4f px, pa %.4f deg, dm %.4f mag\n",
           wsep, wpa, wdm);
}

/* Noise propagates: the reported 1-sigma errors are finite, positive and
 * the measured values stay within a few of them. */
TEST(binary_noise_errors)
{
    int n = 96;
    double x[2] = {48.2, 48.2 + 12.0}, y[2] = {47.6, 47.6 + 5.0};
    double f[2] = {1.0, 0.4};
    float *img = malloc(n * n * sizeof *img);
    points_image(n, 2, x, y, f, img);
    rng r;
    rng_init(&r, 7, 0);
    for (int i = 0; i < n * n; i++)
        img[i] += (float)(0.01 * rng_normal(&r));
    binary_result br;
    int rc = metrics_binary(img, n, n, &br);
    free(img);
    CHECK(rc == SL_OK, "status %d", rc);
    double sep = 13.0, pa = atan2(-12.0, 5.0) * 180 / M_PI + 360;
    CHECK(br.noise > 0.005 && br.noise < 0.02, "noise %g", br.noise);
    CHECK(br.sep_err_px > 0 && br.sep_err_px < 0.1, "sep err %g",
          br.sep_err_px);
    CHECK(fabs(br.sep_px - sep) < 5 * br.sep_err_px + 0.01, "sep %g+-%g",
          br.sep_px, br.sep_err_px);
    CHECK(fabs(br.pa_deg - pa) < 5 * br.pa_err_deg + 0.05, "pa %g+-%g vs %g",
          br.pa_deg, br.pa_err_deg, pa);
    CHECK(fabs(br.dm_mag + 2.5 * log10(0.4)) < 5 * br.dm_err_mag + 0.01,
          "dm %g+-%g", br.dm_mag, br.dm_err_mag);
}

TEST(binary_single_star_fails)
{
    int n = 64;
    double x = 30.2, y = 33.9, f = 1.0;
    float *img = malloc(n * n * sizeof *img);
    points_image(n, 1, &x, &y, &f, img);
    for (int i = 0; i < n * n; i++)
        img[i] = img[i] > 0 ? img[i] : 0; /* no ringing minima */
    binary_result br;
    int rc = metrics_binary(img, n, n, &br);
    free(img);
    /* The Airy rings are local maxima: a "companion" may be found there,
     * but then only as a ring at <= 4 lambda/D and >= 4 mag fainter. */
    CHECK(rc == SL_EDATA || br.dm_mag > 4.0, "rc %d dm %g sep %g", rc,
          br.dm_mag, br.sep_px);
}

TC_MAIN(TC_CASE(corr_identities), TC_CASE(corr_independent_noise),
        TC_CASE(register_subpixel_shift), TC_CASE(binary_recovers_sep_pa_dm),
        TC_CASE(binary_noise_errors), TC_CASE(binary_single_star_fails))
