/* metrics.c - see metrics.h.
 *
 * Sub-pixel registration uses Newton's method on the band-limited
 * cross-correlation given by its DFT X,
 *   f(s) = (1/wh) Re sum_u X(u) exp(+i k(u).s).
 * The Fourier series is the exact continuous function behind the samples,
 * so the maximum is found without interpolation bias; one evaluation with
 * gradient and Hessian costs O(wh) using separable exponentials (row sums,
 * then one pass over rows).
 */
#include <complex.h>
#include <fftw3.h>

#include "metrics.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct metrics_plan {
    int w, h;
    fftw_complex *ba, *bb, *bx; /* w*h spectra and work */
    fftw_plan fwd;              /* in-place forward on ba (new-array exec) */
    fftw_plan inv;              /* in-place inverse on ba */
    double complex *ex, *ey;    /* separable exponentials, w and h */
    float *scratch;             /* w*h: registered copy */
    sl_err err;
};

double metrics_corr(const float *a, const float *b, int w, int h)
{
    size_t n = (size_t)w * (size_t)h;
    if (!a || !b || w <= 0 || h <= 0)
        return 0.0;
    double ma = 0, mb = 0;
    for (size_t i = 0; i < n; i++) {
        ma += a[i];
        mb += b[i];
    }
    ma /= (double)n;
    mb /= (double)n;
    double sab = 0, saa = 0, sbb = 0;
    for (size_t i = 0; i < n; i++) {
        double da = a[i] - ma, db = b[i] - mb;
        sab += da * db;
        saa += da * da;
        sbb += db * db;
    }
    if (saa <= 0 || sbb <= 0)
        return 0.0;
    return sab / sqrt(saa * sbb);
}

metrics_plan *metrics_plan_new(int w, int h, sl_err *err)
{
    if (w < 4 || h < 4) {
        sl_seterr(err, SL_EINVAL, "metrics: image %dx%d too small", w, h);
        return NULL;
    }
    metrics_plan *p = calloc(1, sizeof *p);
    if (!p)
        goto fail_struct;
    size_t n = (size_t)w * (size_t)h;
    p->w = w;
    p->h = h;
    p->ba = fftw_alloc_complex(n);
    p->bb = fftw_alloc_complex(n);
    p->bx = fftw_alloc_complex(n);
    p->ex = malloc((size_t)w * sizeof *p->ex);
    p->ey = malloc((size_t)h * sizeof *p->ey);
    p->scratch = malloc(n * sizeof *p->scratch);
    if (!p->ba || !p->bb || !p->bx || !p->ex || !p->ey || !p->scratch)
        goto fail_alloc;
    p->fwd = fftw_plan_dft_2d(h, w, p->ba, p->ba, FFTW_FORWARD, FFTW_ESTIMATE);
    p->inv = fftw_plan_dft_2d(h, w, p->ba, p->ba, FFTW_BACKWARD, FFTW_ESTIMATE);
    if (!p->fwd || !p->inv)
        goto fail_alloc;
    return p;
fail_alloc:
    metrics_plan_free(p);
fail_struct:
    sl_seterr(err, SL_ENOMEM, "metrics: out of memory for %dx%d plan", w, h);
    return NULL;
}

void metrics_plan_free(metrics_plan *p)
{
    if (!p)
        return;
    if (p->fwd)
        fftw_destroy_plan(p->fwd);
    if (p->inv)
        fftw_destroy_plan(p->inv);
    fftw_free(p->ba);
    fftw_free(p->bb);
    fftw_free(p->bx);
    free(p->ex);
    free(p->ey);
    free(p->scratch);
    free(p);
}

const char *metrics_errmsg(const metrics_plan *p)
{
    return p ? p->err.msg : "no metrics plan";
}

/* Forward FFT of a real float image into buf (new-array execute keeps one
 * plan for both buffers; both come from fftw_alloc so alignment matches). */
static void fft_real(metrics_plan *p, const float *img, fftw_complex *buf)
{
    size_t n = (size_t)p->w * (size_t)p->h;
    for (size_t i = 0; i < n; i++)
        buf[i] = img[i];
    fftw_execute_dft(p->fwd, buf, buf);
}

/* Signed frequency of FFT index i of n; the Nyquist bin (even n) is
 * reported so callers can drop it: its sign is ambiguous. */
static int sfreq(int i, int n) { return i <= (n - 1) / 2 ? i : i - n; }
static int is_nyq(int i, int n) { return (n % 2 == 0) && i == n / 2; }

/* f, gradient and Hessian of the band-limited function with spectrum X at
 * s = (sx, sy), scaled by 1/(wh).  Nyquist bins are skipped. */
static void bl_eval(metrics_plan *p, const fftw_complex *X, double sx,
                    double sy, double *f, double g[2], double H[3])
{
    int w = p->w, h = p->h;
    for (int i = 0; i < w; i++) {
        double k = 2.0 * M_PI * sfreq(i, w) / w;
        p->ex[i] = cexp(I * k * sx);
    }
    for (int j = 0; j < h; j++) {
        double k = 2.0 * M_PI * sfreq(j, h) / h;
        p->ey[j] = cexp(I * k * sy);
    }
    double F = 0, gx = 0, gy = 0, hxx = 0, hxy = 0, hyy = 0;
    for (int j = 0; j < h; j++) {
        if (is_nyq(j, h))
            continue;
        double kq = 2.0 * M_PI * sfreq(j, h) / h;
        double s0r = 0, s0i = 0, s1r = 0, s1i = 0, s2r = 0, s2i = 0;
        const fftw_complex *row = X + (size_t)j * w;
        for (int i = 0; i < w; i++) {
            if (is_nyq(i, w))
                continue;
            double kp = 2.0 * M_PI * sfreq(i, w) / w;
            double xr = creal(row[i]), xi = cimag(row[i]);
            double er = creal(p->ex[i]), ei = cimag(p->ex[i]);
            double tr = xr * er - xi * ei, ti = xr * ei + xi * er;
            s0r += tr;
            s0i += ti;
            s1r += tr * kp;
            s1i += ti * kp;
            s2r += tr * kp * kp;
            s2i += ti * kp * kp;
        }
        double er = creal(p->ey[j]), ei = cimag(p->ey[j]);
        double a0r = s0r * er - s0i * ei, a0i = s0r * ei + s0i * er;
        double a1r = s1r * er - s1i * ei, a1i = s1r * ei + s1i * er;
        double a2r = s2r * er - s2i * ei;
        F += a0r;
        gx += -a1i;
        gy += -a0i * kq;
        hxx += -a2r;
        hxy += -a1r * kq;
        hyy += -a0r * kq * kq;
    }
    double sc = 1.0 / ((double)w * h);
    *f = F * sc;
    g[0] = gx * sc;
    g[1] = gy * sc;
    H[0] = hxx * sc;
    H[1] = hxy * sc;
    H[2] = hyy * sc;
}

/* Maximise the band-limited function from the start point s (in/out).
 * Newton steps while the Hessian is negative definite, otherwise a
 * gradient step; every step is clamped to 0.5 px so the search cannot
 * jump to another peak.  Returns the value at the maximum; H gets the
 * Hessian there (for error estimates). */
static double bl_peak(metrics_plan *p, const fftw_complex *X, double s[2],
                      double H[3])
{
    double f = 0, g[2];
    for (int it = 0; it < 60; it++) {
        bl_eval(p, X, s[0], s[1], &f, g, H);
        double det = H[0] * H[2] - H[1] * H[1];
        double st[2];
        if (H[0] < 0 && det > 0) {
            st[0] = -(H[2] * g[0] - H[1] * g[1]) / det;
            st[1] = -(-H[1] * g[0] + H[0] * g[1]) / det;
        } else {
            double gn = hypot(g[0], g[1]);
            if (gn == 0)
                break;
            st[0] = 0.1 * g[0] / gn;
            st[1] = 0.1 * g[1] / gn;
        }
        double len = hypot(st[0], st[1]);
        if (len > 0.5) {
            st[0] *= 0.5 / len;
            st[1] *= 0.5 / len;
        }
        s[0] += st[0];
        s[1] += st[1];
        if (len < 1e-9)
            break;
    }
    bl_eval(p, X, s[0], s[1], &f, g, H);
    return f;
}

int metrics_register(metrics_plan *p, const float *a, const float *b,
                     float *reg, double *dx_px, double *dy_px)
{
    if (!p || !a || !b || !dx_px || !dy_px)
        return sl_seterr(p ? &p->err : NULL, SL_EINVAL,
                         "metrics_register: NULL argument");
    int w = p->w, h = p->h;
    size_t n = (size_t)w * (size_t)h;
    fft_real(p, a, p->ba);
    fft_real(p, b, p->bb);
    /* X = conj(A) B peaks at the shift d; keep B for the registered copy. */
    for (size_t i = 0; i < n; i++)
        p->ba[i] = conj(p->ba[i]) * p->bb[i];
    p->ba[0] = 0; /* the means do not locate anything */
    fftw_complex *X = p->bx;
    memcpy(X, p->ba, n * sizeof *X);
    fftw_execute(p->inv);
    size_t best = 0;
    for (size_t i = 1; i < n; i++)
        if (creal(p->ba[i]) > creal(p->ba[best]))
            best = i;
    double s[2] = {sfreq((int)(best % (size_t)w), w),
                   sfreq((int)(best / (size_t)w), h)};
    double H[3];
    bl_peak(p, X, s, H);
    *dx_px = s[0];
    *dy_px = s[1];
    if (reg) {
        /* b moved by -d: multiply B by exp(+i k.d). */
        for (int j = 0; j < h; j++) {
            double kq = 2.0 * M_PI * sfreq(j, h) / h;
            for (int i = 0; i < w; i++) {
                double kp = 2.0 * M_PI * sfreq(i, w) / w;
                size_t k = (size_t)j * w + i;
                p->ba[k] = p->bb[k] * cexp(I * (kp * s[0] + kq * s[1]));
            }
        }
        fftw_execute(p->inv);
        for (size_t i = 0; i < n; i++)
            reg[i] = (float)(creal(p->ba[i]) / (double)n);
    }
    return SL_OK;
}

int metrics_plan_corr_registered(metrics_plan *p, const float *a,
                                 const float *b, double *c, double *dx_px,
                                 double *dy_px)
{
    if (!p || !c)
        return sl_seterr(p ? &p->err : NULL, SL_EINVAL,
                         "metrics_corr_registered: NULL argument");
    double dx, dy;
    int rc = metrics_register(p, a, b, p->scratch, &dx, &dy);
    if (rc != SL_OK)
        return rc;
    *c = metrics_corr(a, p->scratch, p->w, p->h);
    if (dx_px)
        *dx_px = dx;
    if (dy_px)
        *dy_px = dy;
    return SL_OK;
}

int metrics_corr_registered(const float *a, const float *b, int w, int h,
                            double *c, double *dx_px, double *dy_px)
{
    metrics_plan *p = metrics_plan_new(w, h, NULL);
    if (!p)
        return SL_ENOMEM;
    int rc = metrics_plan_corr_registered(p, a, b, c, dx_px, dy_px);
    metrics_plan_free(p);
    return rc;
}

int metrics_plan_binary(metrics_plan *p, const float *img, binary_result *out)
{
    if (!p)
        return SL_EINVAL;
    return binary_measure(img, p->w, p->h, out, &p->err);
}

int metrics_binary(const float *img, int w, int h, binary_result *out)
{
    return binary_measure(img, w, h, out, NULL);
}
