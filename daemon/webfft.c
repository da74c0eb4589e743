/* webfft.c - radix-2 and Bluestein transforms, the power spectrum
 * accumulator; see webfft.h. */
#include "webfft.h"

#include <glib.h>
#include <math.h>
#include <string.h>

struct webfft {
    int n;              /* the transform's length */
    int m;              /* the power-of-two length run (n itself, or >= 2n-1) */
    double *tw;         /* m/2 twiddles e^(-2 pi i k/m), interleaved */
    int *rev;           /* bit reversal of 0..m-1 */
    double *chirp;      /* Bluestein: w_k = e^(-pi i k^2/n), n values */
    double *bf;         /* Bluestein: FFT of the conjugate chirp, m values */
    double *work;       /* m values */
};

static int is_pow2(int n)
{
    return n > 0 && (n & (n - 1)) == 0;
}

/* In place, length f->m, interleaved re/im. */
static void fft_pow2(const webfft *f, double *a)
{
    int m = f->m;
    for (int i = 0; i < m; i++) {
        int j = f->rev[i];
        if (i < j) {
            double r = a[2 * i], im = a[2 * i + 1];
            a[2 * i] = a[2 * j], a[2 * i + 1] = a[2 * j + 1];
            a[2 * j] = r, a[2 * j + 1] = im;
        }
    }
    for (int len = 2; len <= m; len <<= 1) {
        int half = len / 2, step = m / len;
        for (int i = 0; i < m; i += len)
            for (int k = 0; k < half; k++) {
                const double *w = f->tw + 2 * (k * step);
                double *u = a + 2 * (i + k), *v = a + 2 * (i + k + half);
                double vr = v[0] * w[0] - v[1] * w[1], vi = v[0] * w[1] + v[1] * w[0];
                v[0] = u[0] - vr, v[1] = u[1] - vi;
                u[0] += vr, u[1] += vi;
            }
    }
}

webfft *webfft_new(int n)
{
    if (n < 1 || n > (1 << 24))
        return NULL;
    webfft *f = g_new0(webfft, 1);
    f->n = n;
    f->m = 1;
    while (f->m < (is_pow2(n) ? n : 2 * n - 1))
        f->m <<= 1;
    int m = f->m, bits = 0;
    while ((1 << bits) < m)
        bits++;
    f->tw = g_new(double, m > 1 ? m : 2);
    f->rev = g_new(int, m);
    for (int k = 0; k < m / 2; k++) {
        f->tw[2 * k] = cos(-2 * G_PI * k / m);
        f->tw[2 * k + 1] = sin(-2 * G_PI * k / m);
    }
    for (int i = 0; i < m; i++) {
        int r = 0;
        for (int b = 0; b < bits; b++)
            r |= ((i >> b) & 1) << (bits - 1 - b);
        f->rev[i] = r;
    }
    if (!is_pow2(n)) {
        f->chirp = g_new(double, 2 * (size_t)n);
        f->bf = g_new0(double, 2 * (size_t)m);
        f->work = g_new(double, 2 * (size_t)m);
        for (long k = 0; k < n; k++) {
            /* k^2 mod 2n keeps the angle exact for large k */
            long q = (k * k) % (2L * n);
            double a = -G_PI * (double)q / n;
            f->chirp[2 * k] = cos(a), f->chirp[2 * k + 1] = sin(a);
            /* b_k = conj(w_k) at k and m - k */
            f->bf[2 * k] = cos(a), f->bf[2 * k + 1] = -sin(a);
            if (k > 0)
                f->bf[2 * (m - k)] = cos(a), f->bf[2 * (m - k) + 1] = -sin(a);
        }
        fft_pow2(f, f->bf);
    }
    return f;
}

void webfft_free(webfft *f)
{
    if (!f)
        return;
    g_free(f->tw);
    g_free(f->rev);
    g_free(f->chirp);
    g_free(f->bf);
    g_free(f->work);
    g_free(f);
}

/* X_k = w_k * IFFT(FFT(x w) * FFT(conj w))_k (Bluestein). */
static void bluestein(webfft *f, double *x)
{
    int n = f->n, m = f->m;
    double *a = f->work;
    memset(a, 0, 2 * (size_t)m * sizeof *a);
    for (int k = 0; k < n; k++) {
        const double *w = f->chirp + 2 * k;
        a[2 * k] = x[2 * k] * w[0] - x[2 * k + 1] * w[1];
        a[2 * k + 1] = x[2 * k] * w[1] + x[2 * k + 1] * w[0];
    }
    fft_pow2(f, a);
    /* multiply, then the inverse as conj(FFT(conj(.)))/m */
    for (int k = 0; k < m; k++) {
        double ar = a[2 * k], ai = a[2 * k + 1], br = f->bf[2 * k], bi = f->bf[2 * k + 1];
        a[2 * k] = ar * br - ai * bi;
        a[2 * k + 1] = -(ar * bi + ai * br);
    }
    fft_pow2(f, a);
    for (int k = 0; k < n; k++) {
        double cr = a[2 * k] / m, ci = -a[2 * k + 1] / m;
        const double *w = f->chirp + 2 * k;
        x[2 * k] = cr * w[0] - ci * w[1];
        x[2 * k + 1] = cr * w[1] + ci * w[0];
    }
}

void webfft_forward(webfft *f, double *re_im)
{
    if (f->chirp)
        bluestein(f, re_im);
    else
        fft_pow2(f, re_im);
}

/* ---- the power spectrum ------------------------------------------------------ */

struct webps {
    int w, h;
    webfft *fx, *fy;
    double *img;        /* w*h complex, interleaved */
    double *col;        /* h complex */
    double *acc;        /* w*h power sums */
    long n;
};

webps *webps_new(int w, int h)
{
    if (w < 2 || h < 2 || (double)w * h > WEBPS_MAX_PIXELS)
        return NULL;
    webps *p = g_new0(webps, 1);
    size_t npx = (size_t)w * (size_t)h;
    p->w = w, p->h = h;
    p->fx = webfft_new(w);
    p->fy = webfft_new(h);
    p->img = g_try_new(double, 2 * npx);
    p->col = g_try_new(double, 2 * (size_t)h);
    p->acc = g_try_new0(double, npx);
    if (!p->fx || !p->fy || !p->img || !p->col || !p->acc) {
        webps_free(p);
        return NULL;
    }
    return p;
}

void webps_free(webps *p)
{
    if (!p)
        return;
    webfft_free(p->fx);
    webfft_free(p->fy);
    g_free(p->img);
    g_free(p->col);
    g_free(p->acc);
    g_free(p);
}

void webps_reset(webps *p)
{
    memset(p->acc, 0, (size_t)p->w * (size_t)p->h * sizeof *p->acc);
    p->n = 0;
}

void webps_add(webps *p, const float *frame)
{
    int w = p->w, h = p->h;
    for (int y = 0; y < h; y++) {
        double *row = p->img + 2 * (size_t)y * w;
        for (int x = 0; x < w; x++)
            row[2 * x] = isfinite(frame[(size_t)y * w + x]) ? frame[(size_t)y * w + x] : 0,
            row[2 * x + 1] = 0;
        webfft_forward(p->fx, row);
    }
    for (int x = 0; x < w; x++) {
        for (int y = 0; y < h; y++)
            p->col[2 * y] = p->img[2 * ((size_t)y * w + x)],
            p->col[2 * y + 1] = p->img[2 * ((size_t)y * w + x) + 1];
        webfft_forward(p->fy, p->col);
        for (int y = 0; y < h; y++)
            p->acc[(size_t)y * w + x] += p->col[2 * y] * p->col[2 * y] +
                                         p->col[2 * y + 1] * p->col[2 * y + 1];
    }
    p->n++;
}

long webps_count(const webps *p)
{
    return p ? p->n : 0;
}

int webps_log_mean(const webps *p, float *out)
{
    if (!p || p->n == 0)
        return 0;
    int w = p->w, h = p->h;
    for (int y = 0; y < h; y++) {
        int sy = (y + h / 2) % h;    /* frequency 0 lands on row h/2 */
        for (int x = 0; x < w; x++) {
            int sx = (x + w / 2) % w;
            double v = p->acc[(size_t)y * w + x] / (double)p->n;
            out[(size_t)sy * w + sx] = (float)log10(v > 1e-30 ? v : 1e-30);
        }
    }
    return 1;
}
