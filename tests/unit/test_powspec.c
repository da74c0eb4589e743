/* test_powspec.c - the mean power spectrum against direct FFTs, its shift
 * invariance, photon-bias removal on Poisson frames, the support mask and
 * the reference-star transfer-function division. */
#include <complex.h>
#include <math.h>
#include <fftw3.h>

#include "spectra/powspec.h"
#include "base/rng.h"
#include "speckle_gen.h"
#include "tcheck.h"

#include <stdlib.h>
#include <string.h>


/* Speckle frame generator: circular pupil of diameter n/2 (Nyquist),
 * smoothed Gaussian random phase of rms `rms_rad`; object = point sources
 * placed with exact Fourier phase ramps.  Frame = IFFT(O * OTF) scaled to
 * `flux`; with `photons` the frame is g * Poisson(frame / g). */
static void gen_frame(gen *g, rng *r, double rms_rad, int np, const double *x,
                      const double *y, const double *f, double flux,
                      double gain, int photons, float *out)
{
    int n = g->n;
    size_t N = (size_t)n * n;
    /* Phase screen: white noise low-passed by a Gaussian of 1/e radius
     * n/10 in frequency, then scaled to the wanted rms over the pupil. */
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double q = hypot(sf(i, n), sf(j, n)) / (n / 10.0);
            g->b[(size_t)j * n + i] =
                (rng_normal(r) + I * rng_normal(r)) * exp(-q * q);
        }
    fftw_execute(g->fb);
    double s2 = 0;
    int np_in = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++)
            if (hypot(sf(i, n), sf(j, n)) < n / 4.0) {
                s2 += creal(g->b[(size_t)j * n + i]) *
                      creal(g->b[(size_t)j * n + i]);
                np_in++;
            }
    double sc = rms_rad > 0 ? rms_rad / sqrt(s2 / np_in) : 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            size_t k = (size_t)j * n + i;
            int in = hypot(sf(i, n), sf(j, n)) < n / 4.0;
            g->a[k] = in ? cexp(I * sc * creal(g->b[k])) : 0;
        }
    fftw_execute(g->fa);
    for (size_t k = 0; k < N; k++)
        g->a[k] = creal(g->a[k] * conj(g->a[k]));
    fftw_execute(g->fa);
    double norm = 1.0 / creal(g->a[0]);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double complex o = 0;
            for (int s = 0; s < np; s++)
                o += f[s] * cexp(-2.0 * M_PI * I *
                                 (sf(i, n) * x[s] + sf(j, n) * y[s]) / n);
            g->a[(size_t)j * n + i] *= o * norm;
        }
    fftw_execute(g->ba);
    for (size_t k = 0; k < N; k++) {
        double v = fmax(creal(g->a[k]) / N, 0.0) * flux;
        out[k] = photons ? (float)(gain * rng_poisson(r, v / gain)) : (float)v;
    }
}

TEST(single_frame_equals_fft)
{
    int n = 48;
    gen g;
    gen_init(&g, n);
    rng r;
    rng_init(&r, 11, 0);
    double x[2] = {20.3, 27.9}, y[2] = {22.2, 25.5}, f[2] = {1, 0.5};
    float *fr = malloc(n * n * sizeof *fr);
    double *ps = malloc(n * n * sizeof *ps);
    gen_frame(&g, &r, 2.0, 2, x, y, f, 1000.0, 1, 0, fr);
    powspec_opts o;
    powspec_opts_defaults(&o);
    o.measure = 0;
    powspec *p = powspec_new(n, n, &o, NULL);
    int rc = powspec_add(p, fr);
    rc |= powspec_result(p, ps);
    /* Independent double-precision full complex FFT. */
    for (int k = 0; k < n * n; k++)
        g.b[k] = fr[k];
    fftw_execute(g.fb);
    double worst = 0, peak = creal(g.b[0] * conj(g.b[0]));
    for (int k = 0; k < n * n; k++) {
        double d = fabs(ps[k] - creal(g.b[k] * conj(g.b[k])));
        worst = d > worst ? d : worst;
    }
    double complex ft0;
    double complex *ft = malloc(n * n * sizeof *ft);
    powspec_mean_ft(p, ft);
    ft0 = ft[5 * n + n - 3];
    double complex want = g.b[5 * n + n - 3];
    double flux = powspec_mean_flux(p);
    powspec_free(p);
    gen_done(&g);
    free(fr);
    free(ps);
    free(ft);
    CHECK(rc == SL_OK, "status %d", rc);
    CHECK(worst < 1e-5 * peak, "max |diff| %g vs peak %g", worst, peak);
    CHECK(cabs(ft0 - want) < 1e-4 * sqrt(peak), "mean ft %g%+gi vs %g%+gi",
          creal(ft0), cimag(ft0), creal(want), cimag(want));
    CHECK_NEAR(flux, 1500.0, 1e-2); /* object flux 1 + 0.5 */
}

TEST(shift_invariant)
{
    int n = 40;
    gen g;
    gen_init(&g, n);
    rng r;
    rng_init(&r, 12, 0);
    double x = 17.4, y = 21.1, f = 1;
    float *a = malloc(n * n * sizeof *a), *b = malloc(n * n * sizeof *b);
    double *pa = malloc(n * n * sizeof *pa), *pb = malloc(n * n * sizeof *pb);
    gen_frame(&g, &r, 3.0, 1, &x, &y, &f, 500.0, 1, 0, a);
    for (int j = 0; j < n; j++) /* circular shift by (5, -3) */
        for (int i = 0; i < n; i++)
            b[((j - 3 + n) % n) * n + (i + 5) % n] = a[j * n + i];
    powspec *p = powspec_new(n, n, NULL, NULL), *q = powspec_new(n, n, NULL, NULL);
    powspec_add(p, a);
    powspec_add(q, b);
    powspec_result(p, pa);
    powspec_result(q, pb);
    double worst = 0;
    for (int k = 0; k < n * n; k++)
        worst = fmax(worst, fabs(pa[k] - pb[k]));
    double peak = pa[0];
    powspec_free(p);
    powspec_free(q);
    gen_done(&g);
    free(a);
    free(b);
    free(pa);
    free(pb);
    CHECK(worst < 1e-5 * peak, "max |diff| %g, peak %g", worst, peak);
}

TEST(window_shapes)
{
    int n = 32;
    float *a = malloc(n * n * sizeof *a), *b = malloc(n * n * sizeof *b);
    int rc = powspec_window(POWSPEC_WIN_TUKEY, 1.0, n, n, a);
    rc |= powspec_window(POWSPEC_WIN_HANN, 0.0, n, n, b);
    double d = 0;
    for (int k = 0; k < n * n; k++)
        d = fmax(d, fabs(a[k] - b[k]));
    CHECK(rc == SL_OK && d < 1e-7, "tukey(1) vs hann: %g", d);
    CHECK_NEAR(b[0], 0.0, 1e-7);
    CHECK_NEAR(b[(n / 2) * n + n / 2], 1.0, 1e-7);
    CHECK_NEAR(b[3 * n + 5], b[(n - 3) * n + n - 5], 1e-7);
    powspec_window(POWSPEC_WIN_TUKEY, 0.0, n, n, a);
    for (int k = 0; k < n * n; k++)
        CHECK(a[k] == 1.0f, "tukey(0) pixel %d = %g", k, a[k]);
    powspec_window(POWSPEC_WIN_TUKEY, 0.5, n, n, a);
    CHECK(a[(n / 2) * n + n / 4 + 1] == 1.0f && a[n * 2 + 2] < 0.5f,
          "tukey(0.5) flat middle, tapered edge");
    CHECK(powspec_window(7, 0, n, n, a) == SL_EINVAL, "bad kind accepted");
    free(a);
    free(b);
}

/* Poisson frames (gain 2.5 ADU/photon, ~2000 photons/frame): the raw power
 * spectrum beyond the pupil cut-off sits at g * flux; after photon-bias
 * removal it averages to zero within its standard error, and the floor
 * estimate agrees with the photon bias.  The support mask stays inside the
 * pupil's cut-off and covers the low frequencies. */
TEST(photon_bias_removed)
{
    int n = 64, nfr = 40;
    double gain = 2.5, flux = 2000 * gain;
    gen g;
    gen_init(&g, n);
    rng r;
    rng_init(&r, 13, 0);
    double x[2] = {30.2, 36.0}, y[2] = {31.7, 29.0}, f[2] = {1, 0.6};
    float *fr = malloc(n * n * sizeof *fr);
    double *ps = malloc(n * n * sizeof *ps), *pf = malloc(n * n * sizeof *pf);
    unsigned char *mask = malloc(n * n);
    powspec_opts o;
    powspec_opts_defaults(&o);
    o.bias = POWSPEC_BIAS_PHOTON;
    o.adu_per_photon = gain;
    o.measure = 0;
    powspec *p = powspec_new(n, n, &o, NULL);
    o.bias = POWSPEC_BIAS_FLOOR;
    powspec *q = powspec_new(n, n, &o, NULL);
    for (int k = 0; k < nfr; k++) {
        gen_frame(&g, &r, 2.5, 2, x, y, f, flux, gain, 1, fr);
        powspec_add(p, fr);
        powspec_add(q, fr);
    }
    powspec_result(p, ps);
    powspec_result(q, pf);
    double bias = powspec_bias(p), bfloor = powspec_bias(q);
    double mflux = powspec_mean_flux(p);
    double s = 0, s2 = 0;
    int m = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++)
            if (hypot(sf(i, n), sf(j, n)) > n / 2.0 + 1) {
                double v = ps[j * n + i];
                s += v;
                s2 += v * v;
                m++;
            }
    double mean = s / m, se = sqrt((s2 / m - mean * mean) / m);
    double rcut = 0;
    int rc = powspec_support(ps, n, n, 5.0, 1e-6, 1.0, 0, mask, &rcut);
    int outside = 0, lowmiss = 0, nlow = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double rr = hypot(sf(i, n), sf(j, n));
            outside += mask[j * n + i] && rr > n / 2.0 + 1;
            lowmiss += !mask[j * n + i] && rr < n / 8.0;
            nlow += rr < n / 8.0;
        }
    powspec_free(p);
    powspec_free(q);
    gen_done(&g);
    free(fr);
    free(ps);
    free(pf);
    free(mask);
    CHECK_NEAR(bias, gain * mflux, 1e-6 * bias);
    CHECK(fabs(bfloor / bias - 1) < 0.05, "floor %g vs photon bias %g",
          bfloor, bias);
    CHECK(fabs(mean) < 4 * se + 1e-3 * bias,
          "corrected floor mean %g, se %g (bias %g)", mean, se, bias);
    /* Fringe minima of the binary can fall below 5 sigma: most, not all,
     * of the low frequencies must be in. */
    CHECK(rc == SL_OK && outside == 0 && lowmiss < nlow / 10,
          "support: %d outside the pupil cut-off, %d of %d missed low",
          outside, lowmiss, nlow);
    CHECK(rcut <= n / 2.0 + 1 && rcut > n / 8.0, "rcut %g", rcut);
}

/* Poisson frames plus Gaussian read noise (rn = 6 ADU, gain 2.5, ~2000
 * photons/frame: the read noise's flat rn^2 sum w^2 is ~0.5x the photon
 * bias), Tukey window: with read_noise_adu the corrected power beyond the
 * pupil cut-off averages to zero within its standard error; without it
 * that mean sits at rn^2 sum w^2, many standard errors away, which is the
 * level the read noise would leave in the modulus. */
TEST(read_noise_bias_removed)
{
    int n = 64, nfr = 40;
    double gain = 2.5, flux = 2000 * gain, rn = 6.0;
    gen g;
    gen_init(&g, n);
    rng r;
    rng_init(&r, 17, 0);
    double x[2] = {30.2, 36.0}, y[2] = {31.7, 29.0}, f[2] = {1, 0.6};
    float *fr = malloc(n * n * sizeof *fr), *win = malloc(n * n * sizeof *win);
    double *ps = malloc(n * n * sizeof *ps), *p0 = malloc(n * n * sizeof *p0);
    powspec_opts o;
    powspec_opts_defaults(&o);
    o.bias = POWSPEC_BIAS_PHOTON;
    o.adu_per_photon = gain;
    o.window = POWSPEC_WIN_TUKEY;
    o.measure = 0;
    powspec *q = powspec_new(n, n, &o, NULL);   /* photon bias only */
    o.read_noise_adu = rn;
    powspec *p = powspec_new(n, n, &o, NULL);
    o.read_noise_adu = -1;
    powspec *bad = powspec_new(n, n, &o, NULL);
    for (int k = 0; k < nfr; k++) {
        gen_frame(&g, &r, 2.5, 2, x, y, f, flux, gain, 1, fr);
        for (int i = 0; i < n * n; i++)
            fr[i] += (float)(rn * rng_normal(&r));
        powspec_add(p, fr);
        powspec_add(q, fr);
    }
    int rc = powspec_result(p, ps) | powspec_result(q, p0);
    powspec_window(POWSPEC_WIN_TUKEY, o.tukey_alpha, n, n, win);
    double w2 = 0;
    for (int i = 0; i < n * n; i++)
        w2 += (double)win[i] * win[i];
    double want = rn * rn * w2, dbias = powspec_bias(p) - powspec_bias(q);
    double s = 0, s2 = 0, s0 = 0;
    int m = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++)
            if (hypot(sf(i, n), sf(j, n)) > n / 2.0 + 1) {
                double v = ps[j * n + i];
                s += v, s2 += v * v, s0 += p0[j * n + i];
                m++;
            }
    double mean = s / m, se = sqrt((s2 / m - mean * mean) / m), mean0 = s0 / m;
    double bias = powspec_bias(p);
    powspec_free(p);
    powspec_free(q);
    gen_done(&g);
    free(fr);
    free(win);
    free(ps);
    free(p0);
    CHECK(rc == SL_OK && bad == NULL, "status %d, negative read noise accepted: %d", rc,
          bad != NULL);
    CHECK_NEAR(dbias, want, 1e-9 * want);
    CHECK(fabs(mean) < 4 * se + 1e-3 * bias,
          "corrected floor mean %g, se %g (read-noise bias %g)", mean, se, want);
    CHECK(fabs(mean0 - want) < 4 * se + 1e-3 * bias && want > 20 * se,
          "without read noise the floor sits at %g, want %g (se %g)", mean0, want, se);
}

/* The gain from the data alone (powspec_floor_gain): Poisson frames at
 * 2.5 ADU per photon with 1 ADU of white noise read from the floor
 * within 3 %; refused (not a wrong number) when the white noise owns the
 * floor (6 ADU: 90 %) and in another bias mode. */
TEST(gain_from_the_floor)
{
    int n = 64, nfr = 40;
    double gain = 2.5, flux = 2000 * gain;
    gen g;
    gen_init(&g, n);
    rng r;
    rng_init(&r, 23, 0);
    double x[2] = {30.2, 36.0}, y[2] = {31.7, 29.0}, f[2] = {1, 0.6};
    float *fr = malloc(n * n * sizeof *fr);
    powspec_opts o;
    powspec_opts_defaults(&o);
    o.bias = POWSPEC_BIAS_FLOOR;
    o.window = POWSPEC_WIN_TUKEY;
    o.measure = 0;
    powspec *p[2] = {powspec_new(n, n, &o, NULL), powspec_new(n, n, &o, NULL)};
    o.bias = POWSPEC_BIAS_PHOTON;
    powspec *ph = powspec_new(n, n, &o, NULL);
    const double rn[2] = {1.0, 6.0};
    for (int k = 0; k < nfr; k++) {
        gen_frame(&g, &r, 2.5, 2, x, y, f, flux, gain, 1, fr);
        powspec_add(ph, fr);
        for (int i = 0; i < n * n; i++)
            fr[i] += (float)(rn[k & 1] * rng_normal(&r));
        powspec_add(p[k & 1], fr);
    }
    double est[3] = {0, 0, 0};
    int rc[3] = {powspec_floor_gain(p[0], rn[0], &est[0]),
                 powspec_floor_gain(p[1], rn[1], &est[1]),
                 powspec_floor_gain(ph, 0, &est[2])};
    powspec_free(p[0]);
    powspec_free(p[1]);
    powspec_free(ph);
    gen_done(&g);
    free(fr);
    CHECK(rc[0] == SL_OK && fabs(est[0] / gain - 1) < 0.03,
          "gain %.4f (rc %d), truth %.4f", est[0], rc[0], gain);
    CHECK(rc[1] == SL_EDATA && est[1] == 0, "white noise owning the floor: rc %d gain %g",
          rc[1], est[1]);
    CHECK(rc[2] == SL_EDATA, "photon-bias mode: rc %d gain %g", rc[2], est[2]);
}

/* With a point-source reference the speckle transfer function divides
 * out: the binary's normalised modulus |cos| pattern is recovered far
 * better than by sqrt(PS) alone. */
TEST(reference_division)
{
    int n = 64, nfr = 60;
    gen g;
    gen_init(&g, n);
    rng r;
    rng_init(&r, 14, 0);
    double x[2] = {30.0, 37.3}, y[2] = {32.0, 35.1}, f[2] = {1, 0.5};
    double x0 = 32, y0 = 32, f0 = 1;
    float *fr = malloc(n * n * sizeof *fr);
    double *po = malloc(n * n * sizeof *po), *pr = malloc(n * n * sizeof *pr);
    double *m1 = malloc(n * n * sizeof *m1), *m0 = malloc(n * n * sizeof *m0);
    powspec *p = powspec_new(n, n, NULL, NULL), *q = powspec_new(n, n, NULL, NULL);
    for (int k = 0; k < nfr; k++) {
        gen_frame(&g, &r, 2.5, 2, x, y, f, 1.0, 1, 0, fr);
        powspec_add(p, fr);
        gen_frame(&g, &r, 2.5, 1, &x0, &y0, &f0, 1.0, 1, 0, fr);
        powspec_add(q, fr);
    }
    powspec_result(p, po);
    powspec_result(q, pr);
    int rc = powspec_modulus(po, pr, n, n, 1e-3, m1);
    rc |= powspec_modulus(po, NULL, n, n, 0, m0);
    double e1 = 0, e0 = 0;
    int m = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            if (hypot(sf(i, n), sf(j, n)) > n / 6.0)
                continue;
            double ph = 2 * M_PI * (sf(i, n) * (x[1] - x[0]) +
                                    sf(j, n) * (y[1] - y[0])) / n;
            double truth = cabs(1 + 0.5 * cexp(I * ph)) / 1.5;
            e1 += fabs(m1[j * n + i] / m1[0] - truth);
            e0 += fabs(m0[j * n + i] / m0[0] - truth);
            m++;
        }
    e1 /= m;
    e0 /= m;
    powspec_free(p);
    powspec_free(q);
    gen_done(&g);
    free(fr);
    free(po);
    free(pr);
    free(m1);
    free(m0);
    CHECK(rc == SL_OK, "status %d", rc);
    CHECK(e1 < 0.08, "mean |error| with reference %g", e1);
    CHECK(e0 > 2 * e1, "no-reference error %g should be worse than %g", e0,
          e1);
}

/* The sums (powspec_partial) equal bit for bit on 1, 2, 3 and 7 threads,
 * with a window, photon bias and the aligned spectrum, for a frame count
 * that leaves slots staged, and with a result asked for mid-stream (the
 * staged frames are summed then, and the stream goes on). */
TEST(sums_equal_on_any_thread_count)
{
    int n = 36, nfr = 21;
    rng r;
    rng_init(&r, 41, 0);
    float *fr = malloc((size_t)nfr * n * n * sizeof *fr);
    for (size_t k = 0; k < (size_t)nfr * n * n; k++)
        fr[k] = (float)(100 * rng_uniform(&r));
    double *ref = NULL, *mid = malloc((size_t)n * n * sizeof *mid);
    size_t len = 0;
    static const int thr[] = {1, 2, 3, 7};
    for (int ti = 0; ti < 4; ti++) {
        powspec_opts o;
        powspec_opts_defaults(&o);
        o.window = POWSPEC_WIN_TUKEY;
        o.bias = POWSPEC_BIAS_PHOTON;
        o.adu_per_photon = 2;
        o.aligned = 1;
        o.measure = 0;
        o.nthreads = thr[ti];
        powspec *p = powspec_new(n, n, &o, NULL);
        CHECK(p, "powspec_new on %d threads", thr[ti]);
        for (int f = 0; f < nfr; f++) {
            CHECK(powspec_add(p, fr + (size_t)f * n * n) == SL_OK, "add");
            if (f == 10)
                CHECK(powspec_result(p, mid) == SL_OK && powspec_nframes(p) == 11,
                      "mid-stream result on %d threads", thr[ti]);
        }
        CHECK(powspec_nframes(p) == nfr, "%d threads: %d frames counted", thr[ti],
              powspec_nframes(p));
        size_t m = powspec_partial(p, NULL);
        double *buf = malloc(m * sizeof *buf);
        powspec_partial(p, buf);
        powspec_free(p);
        if (!ref) {
            ref = buf, len = m;
            continue;
        }
        size_t diff = 0;
        for (size_t k = 0; k < m && m == len; k++)
            diff += memcmp(&buf[k], &ref[k], sizeof *buf) != 0;
        free(buf);
        CHECK(m == len && diff == 0, "%d threads: %zu of %zu sums differ from 1 thread",
              thr[ti], diff, len);
    }
    /* the frame count is among the sums, so a lost staged frame shows */
    free(ref);
    free(mid);
    free(fr);
}

/* A frame with a NaN or an Inf is refused by frame and pixel, leaves the
 * sums alone, and the stream goes on (staged frames included). */
TEST(non_finite_frame_refused_by_pixel)
{
    int n = 16;
    for (int thr = 1; thr <= 2; thr++) {
        powspec_opts o;
        powspec_opts_defaults(&o);
        o.measure = 0;
        o.nthreads = thr;
        powspec *p = powspec_new(n, n, &o, NULL);
        float *f = malloc((size_t)n * n * sizeof *f);
        for (int i = 0; i < n * n; i++)
            f[i] = 1.0f + (float)(i % 7);
        CHECK(powspec_add(p, f) == SL_OK, "good frame");
        f[77] = NAN;
        CHECK(powspec_add(p, f) == SL_EDATA && strstr(powspec_errmsg(p), "frame 1 pixel 77"),
              "NaN: %s", powspec_errmsg(p));
        f[77] = 1.0f;
        f[200] = -INFINITY;
        CHECK(powspec_add(p, f) == SL_EDATA && strstr(powspec_errmsg(p), "pixel 200"),
              "Inf: %s", powspec_errmsg(p));
        f[200] = 1.0f;
        CHECK(powspec_add(p, f) == SL_OK && powspec_nframes(p) == 2, "%d frames after the "
              "refusals (2 wanted)", powspec_nframes(p));
        double *ps = malloc((size_t)n * n * sizeof *ps);
        CHECK(powspec_result(p, ps) == SL_OK && isfinite(ps[0]), "result after refusals");
        free(ps);
        free(f);
        powspec_free(p);
    }
}

/* The floor's region in powspec_support is every frequency with
 * hypot(pf / (w/2), qf / (h/2)) > floor_rho, summed in pixel order: with
 * nsigma and rel_min 0 the threshold is that region's mean exactly, so a
 * pair of pixels a hair above it is kept and a pair a hair below is not.
 * Odd and even sizes, circles through lattice points and not, one that
 * leaves only the corners (rows with no frequency beyond), and none
 * (floor_rho < 0: every frequency). */
TEST(floor_region_is_the_per_frequency_test)
{
    static const int sz[][2] = {{64, 64}, {63, 50}, {128, 96}, {33, 33}};
    for (int c = 0; c < 4; c++)
        for (int r = 0; r < 5; r++) {
            int w = sz[c][0], h = sz[c][1];
            double rho0 = r == 0 ? 0.8 : r == 1 ? 0.95 : r == 2 ? -1 : r == 3 ? 1.2 /* corners */
                        : hypot(11 / (0.5 * w), 7 / (0.5 * h)); /* through (11, 7) */
            double *ps = malloc(sizeof *ps * w * h);
            unsigned char *mask = malloc((size_t)w * h);
            if (!ps || !mask) {
                CHECK(0, "out of memory");
                free(ps), free(mask);
                return;
            }
            double sum = 0;
            size_t m = 0;
            for (int j = 0; j < h; j++)
                for (int i = 0; i < w; i++) {
                    int pf = i <= (w - 1) / 2 ? i : i - w, qf = j <= (h - 1) / 2 ? j : j - h;
                    int in = rho0 < 0 || hypot(pf / (0.5 * w), qf / (0.5 * h)) > rho0;
                    double v = in ? 1 + (i * 7 + j * 13) % 17 : 0;
                    ps[(size_t)j * w + i] = v;
                    sum += v, m += in;
                }
            double fm = sum / m;
            /* probes, 4-neighbours in pairs, inside the circle (rows 2, 4) */
            size_t up = 2 * (size_t)w + 1, down = 4 * (size_t)w + 1;
            if (rho0 >= 0) {
                ps[up] = ps[up + 1] = fm * (1 + 1e-9);
                ps[down] = ps[down + 1] = fm * (1 - 1e-9);
            }
            CHECK(powspec_support(ps, w, h, 0, 0, rho0, 0, mask, NULL) == SL_OK, "support");
            if (rho0 >= 0)
                CHECK(mask[up] && mask[up + 1] && !mask[down] && !mask[down + 1],
                      "%dx%d, rho0 %.6g: the threshold is not the region's mean %.17g "
                      "(kept above %d %d, below %d %d)", w, h, rho0, fm, mask[up],
                      mask[up + 1], mask[down], mask[down + 1]);
            else /* every frequency the floor: only values above the mean kept */
                for (int k = 1; k < w * h; k++) {
                    int i = k % w, j = k / w;
                    int nyq = (w % 2 == 0 && i == w / 2) || (h % 2 == 0 && j == h / 2);
                    if (!nyq && ps[k] <= fm && mask[k]) {
                        CHECK(0, "%dx%d, no circle: pixel %d (%g) kept at mean %g", w, h, k,
                              ps[k], fm);
                        break;
                    }
                }
            free(ps), free(mask);
        }
}

TC_MAIN(TC_CASE(sums_equal_on_any_thread_count), TC_CASE(non_finite_frame_refused_by_pixel), TC_CASE(single_frame_equals_fft), TC_CASE(shift_invariant), TC_CASE(gain_from_the_floor),
        TC_CASE(window_shapes), TC_CASE(photon_bias_removed),
        TC_CASE(read_noise_bias_removed), TC_CASE(reference_division),
        TC_CASE(floor_region_is_the_per_frequency_test))
