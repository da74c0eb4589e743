/* test_bispec_noise.c - the bispectrum's read-noise bias (bispec_opts.
 * read_noise_adu): Gaussian read noise adds nothing to the mean bispectrum
 * by itself, but Wirnitzer's photon terms read |F|^2 (X), which it
 * inflates by rn^2 sum w^3, and with a window it correlates neighbouring
 * frequencies (rn^2 FFT(w^2)), which adds rn^2 S(u) conj W2(u) per leg.
 * Frames: Poisson counts of a Gaussian blob (sigma 2 px, 2000 photons,
 * gain 1) plus read noise 5 ADU, 32^2, Tukey window.  At triples whose
 * legs all lie where the blob's spectrum is ~0 (|u1|, |u3| > 9 px), the
 * corrected mean bispectrum must average to 0; left uncorrected it sits
 * near -3 rn^2 sum w^3 (the over-subtracted X). */
#include <math.h>
#include <stdlib.h>

#include "spectra/bispec.h"
#include "spectra/powspec.h"
#include "base/rng.h"
#include "tcheck.h"

/* Mean real and imaginary part of the corrected bispectrum over the
 * high-frequency triples, for nfr frames with read noise rn (corrected
 * as rn_fix). */
static int highfreq_mean(int window, double rn, double rn_fix, double *mre, double *mim,
                         double *w3)
{
    enum { n = 32, nfr = 3000 };
    double flux = 2000, s = 0;
    float *lam = malloc(n * n * sizeof *lam), *fr = malloc(n * n * sizeof *fr);
    float *win = malloc(n * n * sizeof *win);
    for (int y = 0; y < n; y++)
        for (int x = 0; x < n; x++) {
            double r2 = (x - n / 2) * (x - n / 2) + (y - n / 2) * (y - n / 2);
            s += lam[y * n + x] = (float)exp(-r2 / 8.0);
        }
    for (int i = 0; i < n * n; i++)
        lam[i] *= (float)(flux / s);
    bispec_opts o;
    bispec_opts_defaults(&o);
    o.r2_px = 6;
    o.adu_per_photon = 1;
    o.read_noise_adu = rn_fix;
    o.window = window;
    o.measure = 0;
    bispec *b = bispec_new(n, n, &o, NULL);
    int rc = b ? SL_OK : SL_ENOMEM;
    rng r;
    rng_init(&r, 23, 0);
    for (int k = 0; rc == SL_OK && k < nfr; k++) {
        for (int i = 0; i < n * n; i++)
            fr[i] = (float)(rng_poisson(&r, lam[i]) + rn * rng_normal(&r));
        rc = bispec_add(b, fr);
    }
    double sr = 0, si = 0;
    int m = 0;
    for (size_t t = 0; rc == SL_OK && t < bispec_ntriples(b); t++) {
        int u1[2], u2[2];
        double br, bi, wt;
        rc = bispec_triple(b, t, u1, u2, &br, &bi, &wt);
        if (hypot(u1[0], u1[1]) > 9 && hypot(u2[0], u2[1]) > 4 &&
            hypot(u1[0] + u2[0], u1[1] + u2[1]) > 9)
            sr += br, si += bi, m++;
    }
    powspec_window(window, o.tukey_alpha, n, n, win);
    *w3 = 0;
    for (int i = 0; i < n * n; i++)
        *w3 += (double)win[i] * win[i] * win[i];
    *mre = m ? sr / m : NAN;
    *mim = m ? si / m : NAN;
    bispec_free(b);
    free(lam);
    free(fr);
    free(win);
    return m > 1000 ? rc : SL_EDATA;
}

TEST(read_noise_bias_removed_from_bispectrum)
{
    double rn = 5, re, im, re0, im0, reh, imh, w3, w3h;
    int rc = highfreq_mean(POWSPEC_WIN_TUKEY, rn, rn, &re, &im, &w3);
    rc |= highfreq_mean(POWSPEC_WIN_TUKEY, rn, 0, &re0, &im0, &w3);
    rc |= highfreq_mean(POWSPEC_WIN_NONE, rn, rn, &reh, &imh, &w3h);
    double off = 3 * rn * rn * w3, offh = 3 * rn * rn * w3h;
    CHECK(rc == SL_OK, "status %d", rc);
    CHECK(fabs(re) < 0.2 * off && fabs(im) < 0.2 * off,
          "Tukey, corrected: mean B %g%+gi, should be ~0 (uncorrected offset %g)", re, im, off);
    CHECK(re0 < -0.5 * off, "Tukey, uncorrected: mean Re B %g, expected near %g", re0, -off);
    CHECK(fabs(reh) < 0.2 * offh && fabs(imh) < 0.2 * offh,
          "no window, corrected: mean B %g%+gi (offset %g)", reh, imh, offh);
}

TC_MAIN(TC_CASE(read_noise_bias_removed_from_bispectrum))
