/* probe_spectrum.c - the probe's measurements on the crop's mean power
 * spectrum (probe.h): support, noise, SNR, cumulative profile and the
 * image's diameter from the autocorrelation. */
#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "probe_int.h"
#include "spectra/powspec.h"

void probe_crop_copy(const probe_scene *sc, int w, const float *f, float *out)
{
    for (int y = 0; y < sc->crop_h; y++)
        memcpy(out + (size_t)y * sc->crop_w,
               f + (size_t)(y + sc->crop_y0) * w + sc->crop_x0,
               sizeof(float) * sc->crop_w);
}

/* Diameter of the image: the largest lag at which the autocorrelation
 * (inverse FFT of the power on its support) stays above the threshold,
 * with a 4-neighbour above too (ringing spikes do not count). */
static double autocorr_extent(const double *ps, const double *spk,
                              const unsigned char *mask, int w, int h,
                              double level, int nframes)
{
    size_t n = (size_t)w * h;
    fftw_complex *a = fftw_alloc_complex(n);
    double *re = malloc(n * sizeof *re);
    double d = NAN;
    if (!a || !re)
        goto free_all;
    fftw_plan pl = fftw_plan_dft_2d(h, w, a, a, FFTW_BACKWARD, FFTW_ESTIMATE);
    if (!pl)
        goto free_all;
    /* Noise: a frame's |F(u)|^2 scatters about the mean by its speckle
     * part spk(u) = <|F|^2> - |<F>|^2 plus the white noise (exponential
     * statistics), so a lag of the sum over the support scatters by
     * sqrt(sum spk^2 / nframes). */
    double var = 0;
    for (size_t i = 0; i < n; i++) {
        a[i] = mask[i] ? ps[i] : 0;
        var += mask[i] ? spk[i] * spk[i] : 0;
    }
    fftw_execute(pl);
    fftw_destroy_plan(pl);
    for (size_t i = 0; i < n; i++)
        re[i] = creal(a[i]);
    double thr = fmax(level * re[0], 5 * sqrt(var / nframes));
    d = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            if (!(re[(size_t)y * w + x] > thr))
                continue;
            int nb = (re[(size_t)y * w + (x + 1) % w] > thr) +
                     (re[(size_t)y * w + (x + w - 1) % w] > thr) +
                     (re[(size_t)((y + 1) % h) * w + x] > thr) +
                     (re[(size_t)((y + h - 1) % h) * w + x] > thr);
            int dx = x <= w / 2 ? x : x - w, dy = y <= h / 2 ? y : y - h;
            if (nb >= 1)
                d = fmax(d, hypot(dx, dy));
        }
free_all:
    fftw_free(a);
    free(re);
    return d;
}

/* The crop's mean power spectrum: support, noise, SNR, profile, extent. */
/* The support's radius and fraction, the SNR and the cumulative power
 * profile of the crop's spectrum pw (mask: its support). */
static void spectrum_numbers(probe_scene *sc, const double *pw,
                             const unsigned char *mask, int cw, int ch)
{
    double acc[PROBE_NBIN] = {0}, sup = 0, fmax_ = 0, tot = 0;
    int nsup = 0;
    for (int q = 0; q < ch; q++)
        for (int u = 0; u < cw; u++) {
            size_t i = (size_t)q * cw + u;
            double fx = (double)(u <= cw / 2 ? u : u - cw) / cw;
            double fy = (double)(q <= ch / 2 ? q : q - ch) / ch;
            double f = hypot(fx, fy);
            if (mask[i]) {
                fmax_ = fmax(fmax_, f);
                if (i) {
                    sup += pw[i];
                    nsup++;
                }
            }
            int bin = (int)(f / 0.5 * PROBE_NBIN);
            if (i && bin < PROBE_NBIN && pw[i] > 0)
                acc[bin] += pw[i], tot += pw[i];
        }
    sc->support_cyc_px = fmax_;
    sc->support_frac = (double)(nsup + 1) / ((double)cw * ch);
    double c = 0;
    for (int i = 0; i < PROBE_NBIN; i++) {
        c += acc[i];
        sc->pcum[i] = tot > 0 ? c / tot : 1;
    }
    double lv = sc->noise_level, sm = nsup ? sup / nsup : 0;
    sc->snr = lv > 1e-12 * pw[0] ? fmin(sqrt(fmax(sm, 0) / lv), 1e6) : 1e6;
}

/* The image's diameter from the speckle-averaged autocorrelation; the
 * noise of each lag from the frames' speckle part. */
static int spectrum_extent(probe *p, powspec *ps, const double *pw,
                           const unsigned char *mask, int cw, int ch)
{
    probe_scene *sc = &p->sc;
    size_t n = (size_t)cw * ch;
    double complex *mft = malloc(n * sizeof *mft);
    double *spk = malloc(n * sizeof *spk);
    int rc = SL_OK;
    if (!mft || !spk || powspec_mean_ft(ps, mft) != SL_OK) {
        rc = sl_seterr(&p->err, SL_ENOMEM, "probe: out of memory");
    } else {
        for (size_t i = 0; i < n; i++) /* pw's bias is already out: add it back */
            spk[i] = fmax(pw[i] - creal(mft[i] * conj(mft[i])), 0) + sc->noise_level;
        sc->extent_px = autocorr_extent(pw, spk, mask, cw, ch, p->o.extent_level,
                                        sc->nprobed_kept);
    }
    free(mft);
    free(spk);
    return rc;
}

/* The crop's mean power spectrum: support, noise, SNR, profile, extent. */
int probe_measure_spectrum(probe *p)
{
    probe_scene *sc = &p->sc;
    int cw = sc->crop_w, ch = sc->crop_h;
    size_t n = (size_t)cw * ch;
    powspec_opts po;
    powspec_opts_defaults(&po);
    po.window = p->o.window;
    po.tukey_alpha = 0.25;
    po.bias = POWSPEC_BIAS_FLOOR;
    po.measure = 0;
    sl_err e = {0};
    powspec *ps = powspec_new(cw, ch, &po, &e);
    double *pw = malloc(n * sizeof *pw);
    float *crop = malloc(n * sizeof *crop);
    unsigned char *mask = malloc(n);
    int rc = SL_ENOMEM;
    if (!ps || !pw || !crop || !mask) {
        sl_seterr(&p->err, ps ? SL_ENOMEM : e.code, "probe: %s",
                  ps ? "out of memory" : e.msg);
        goto free_all;
    }
    for (int k = 0; k < p->n; k++)
        if (p->verdict[k] == PROBE_KEEP) {
            probe_crop_copy(sc, p->w, probe_stored(p, k), crop);
            if ((rc = powspec_add(ps, crop)) != SL_OK) {
                sl_seterr(&p->err, rc, "probe: %s", powspec_errmsg(ps));
                goto free_all;
            }
        }
    if ((rc = powspec_result(ps, pw)) != SL_OK ||
        (rc = powspec_support(pw, cw, ch, 5, 1e-6, 1.0,
                              powspec_bias(ps) / sqrt(fmax(sc->nprobed_kept, 1)),
                              mask, NULL)) != SL_OK) {
        sl_seterr(&p->err, rc, "probe: power spectrum of the crop failed");
        goto free_all;
    }
    sc->noise_level = powspec_bias(ps);
    spectrum_numbers(sc, pw, mask, cw, ch);
    rc = spectrum_extent(p, ps, pw, mask, cw, ch);
free_all:
    powspec_free(ps);
    free(pw);
    free(crop);
    free(mask);
    return rc;
}

