/* metrics.c - see metrics.h.
 *
 * Everything sub-pixel here uses one tool: Newton's method on a
 * band-limited function given by its DFT X,
 *   f(s) = (1/wh) Re sum_u X(u) exp(+i k(u).s),
 * (the cross-correlation for registration, the image itself for binary
 * astrometry).  The Fourier series is the exact continuous function behind
 * the samples, so the maximum is found without interpolation bias; one
 * evaluation with gradient and Hessian costs O(wh) using separable
 * exponentials (row sums, then one pass over rows).
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
    float *scratch;             /* w*h: median, registered copy */
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

static int cmp_float(const void *x, const void *y)
{
    float a = *(const float *)x, b = *(const float *)y;
    return (a > b) - (a < b);
}

/* Median of v[0..n) (reorders v). */
static double median(float *v, size_t n)
{
    qsort(v, n, sizeof *v, cmp_float);
    return n % 2 ? v[n / 2] : 0.5 * ((double)v[n / 2 - 1] + v[n / 2]);
}

/* First minimum of the azimuthal profile around pixel (cx, cy): the
 * radius that separates the core from the rest (>= 2 px). */
static int core_radius(const float *img, int w, int h, int cx, int cy)
{
    enum { RMAX = 64 };
    double sum[RMAX + 2] = {0};
    int cnt[RMAX + 2] = {0};
    int rmax = (w < h ? w : h) / 4;
    if (rmax > RMAX)
        rmax = RMAX;
    for (int y = cy - rmax - 1; y <= cy + rmax + 1; y++)
        for (int x = cx - rmax - 1; x <= cx + rmax + 1; x++) {
            if (x < 0 || y < 0 || x >= w || y >= h)
                continue;
            int r = (int)lround(hypot(x - cx, y - cy));
            if (r <= rmax + 1) {
                sum[r] += img[(size_t)y * w + x];
                cnt[r]++;
            }
        }
    for (int r = 1; r <= rmax; r++) {
        double here = cnt[r] ? sum[r] / cnt[r] : 0;
        double next = cnt[r + 1] ? sum[r + 1] / cnt[r + 1] : here;
        if (next >= here)
            return r < 2 ? 2 : r;
    }
    return rmax < 2 ? 2 : rmax;
}

/* Position covariance of a peak from white noise sigma: cov = sg2 H^-2,
 * sg2 = sigma^2 pi^2/3 the variance of the interpolant's gradient. */
static void peak_cov(const double H[3], double sigma, double cov[3])
{
    double det = H[0] * H[2] - H[1] * H[1];
    double sg2 = sigma * sigma * M_PI * M_PI / 3.0;
    if (det == 0) {
        cov[0] = cov[1] = cov[2] = INFINITY;
        return;
    }
    double i0 = H[2] / det, i1 = -H[1] / det, i2 = H[0] / det;
    cov[0] = sg2 * (i0 * i0 + i1 * i1);
    cov[1] = sg2 * (i0 * i1 + i1 * i2);
    cov[2] = sg2 * (i1 * i1 + i2 * i2);
}

int metrics_plan_binary(metrics_plan *p, const float *img, binary_result *out)
{
    if (!p || !img || !out)
        return sl_seterr(p ? &p->err : NULL, SL_EINVAL,
                         "metrics_binary: NULL argument");
    int w = p->w, h = p->h;
    size_t n = (size_t)w * (size_t)h;
    memset(out, 0, sizeof *out);
    for (size_t i = 0; i < n; i++)
        if (!isfinite(img[i]))
            return sl_seterr(&p->err, SL_EDATA,
                             "metrics_binary: pixel %zu is not finite", i);
    memcpy(p->scratch, img, n * sizeof *img);
    double bg = median(p->scratch, n);
    fft_real(p, img, p->ba);

    size_t i1 = 0;
    for (size_t i = 1; i < n; i++)
        if (img[i] > img[i1])
            i1 = i;
    int cx = (int)(i1 % (size_t)w), cy = (int)(i1 / (size_t)w);
    int rc = core_radius(img, w, h, cx, cy);
    long i2 = -1;
    for (int y = 1; y < h - 1; y++)
        for (int x = 1; x < w - 1; x++) {
            float v = img[(size_t)y * w + x];
            if (hypot(x - cx, y - cy) <= rc || (i2 >= 0 && v <= img[i2]))
                continue;
            int ismax = 1;
            for (int dy = -1; dy <= 1 && ismax; dy++)
                for (int dx = -1; dx <= 1; dx++)
                    if (img[(size_t)(y + dy) * w + x + dx] > v) {
                        ismax = 0;
                        break;
                    }
            if (ismax)
                i2 = (long)y * w + x;
        }
    if (i2 < 0)
        return sl_seterr(&p->err, SL_EDATA,
                         "metrics_binary: no second peak beyond %d px", rc);
    double s1[2] = {cx, cy}, s2[2] = {(double)(i2 % w), (double)(i2 / w)};
    double H1[3], H2[3];
    double f1 = bl_peak(p, p->ba, s1, H1) - bg;
    double f2 = bl_peak(p, p->ba, s2, H2) - bg;
    if (hypot(s2[0] - s1[0], s2[1] - s1[1]) <= 0.5 * rc || f2 <= 0 || f1 <= 0)
        return sl_seterr(&p->err, SL_EDATA,
                         "metrics_binary: second peak merged with the first "
                         "or not above the background");
    if (f2 > f1) { /* the interpolated heights decide which is brighter */
        double t;
        for (int k = 0; k < 2; k++) {
            t = s1[k]; s1[k] = s2[k]; s2[k] = t;
        }
        for (int k = 0; k < 3; k++) {
            t = H1[k]; H1[k] = H2[k]; H2[k] = t;
        }
        t = f1; f1 = f2; f2 = t;
    }

    /* Robust noise away from both cores (|v - bg|, MAD -> sigma). */
    size_t m = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            if (hypot(x - s1[0], y - s1[1]) > 2 * rc &&
                hypot(x - s2[0], y - s2[1]) > 2 * rc)
                p->scratch[m++] = fabsf(img[(size_t)y * w + x] - (float)bg);
    double sigma = m > 8 ? 1.4826 * median(p->scratch, m) : 0.0;

    out->x1_px = s1[0];
    out->y1_px = s1[1];
    out->x2_px = s2[0];
    out->y2_px = s2[1];
    out->dx_px = s2[0] - s1[0];
    out->dy_px = s2[1] - s1[1];
    out->sep_px = hypot(out->dx_px, out->dy_px);
    double pa = atan2(-out->dx_px, out->dy_px) * 180.0 / M_PI;
    out->pa_deg = pa < 0 ? pa + 360.0 : pa;
    out->flux_ratio = f2 / f1;
    out->dm_mag = -2.5 * log10(out->flux_ratio);
    out->background = bg;
    out->noise = sigma;

    double c1[3], c2[3];
    peak_cov(H1, sigma, c1);
    peak_cov(H2, sigma, c2);
    double cov[3] = {c1[0] + c2[0], c1[1] + c2[1], c1[2] + c2[2]};
    double ex = out->dx_px / out->sep_px, ey = out->dy_px / out->sep_px;
    out->sep_err_px = sqrt(ex * ex * cov[0] + 2 * ex * ey * cov[1] +
                           ey * ey * cov[2]);
    double tt = ey * ey * cov[0] - 2 * ex * ey * cov[1] + ex * ex * cov[2];
    out->pa_err_deg = sqrt(tt) / out->sep_px * 180.0 / M_PI;
    out->flux_ratio_err =
        out->flux_ratio * sigma * sqrt(1.0 / (f1 * f1) + 1.0 / (f2 * f2));
    out->dm_err_mag = 2.5 / log(10.0) * out->flux_ratio_err / out->flux_ratio;
    return SL_OK;
}

int metrics_binary(const float *img, int w, int h, binary_result *out)
{
    metrics_plan *p = metrics_plan_new(w, h, NULL);
    if (!p)
        return SL_ENOMEM;
    int rc = metrics_plan_binary(p, img, out);
    metrics_plan_free(p);
    return rc;
}
