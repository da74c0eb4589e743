/* webfft.c - the power spectrum accumulator of webfft.h, on FFTW. */
#include "webfft.h"

#include <fftw3.h>
#include <glib.h>
#include <math.h>
#include <string.h>

struct webps {
    int w, h;
    long n;             /* frames added */
    double *in;         /* w*h, the frame as FFTW's input */
    fftw_complex *out;  /* h*(w/2+1): the half plane r2c gives */
    fftw_plan plan;
    double *acc;        /* h*(w/2+1) summed |F|^2 */
};

webps *webps_new(int w, int h)
{
    if (w < 2 || h < 2 || (double)w * h > WEBPS_MAX_PIXELS)
        return NULL;
    webps *p = g_new0(webps, 1);
    size_t nh = (size_t)h * (size_t)(w / 2 + 1);
    p->w = w, p->h = h;
    p->in = fftw_alloc_real((size_t)w * (size_t)h);
    p->out = fftw_alloc_complex(nh);
    p->acc = g_try_new0(double, nh);
    if (p->in && p->out)
        p->plan = fftw_plan_dft_r2c_2d(h, w, p->in, p->out, FFTW_ESTIMATE);
    if (!p->plan || !p->acc) {
        webps_free(p);
        return NULL;
    }
    return p;
}

void webps_free(webps *p)
{
    if (!p)
        return;
    if (p->plan)
        fftw_destroy_plan(p->plan);
    fftw_free(p->in);
    fftw_free(p->out);
    g_free(p->acc);
    g_free(p);
}

void webps_reset(webps *p)
{
    memset(p->acc, 0, (size_t)p->h * (size_t)(p->w / 2 + 1) * sizeof *p->acc);
    p->n = 0;
}

void webps_add(webps *p, const float *frame)
{
    size_t npx = (size_t)p->w * (size_t)p->h, nh = (size_t)p->h * (size_t)(p->w / 2 + 1);
    for (size_t i = 0; i < npx; i++)
        p->in[i] = isfinite(frame[i]) ? frame[i] : 0;
    fftw_execute(p->plan);
    for (size_t k = 0; k < nh; k++)
        p->acc[k] += p->out[k][0] * p->out[k][0] + p->out[k][1] * p->out[k][1];
    p->n++;
}

long webps_count(const webps *p)
{
    return p ? p->n : 0;
}

/* The summed power at frequency (fx, fy), 0 <= fx < w, 0 <= fy < h, from
 * the half plane: a real frame's spectrum is Hermitian, P(-f) = P(f). */
static double power_at(const webps *p, int fx, int fy)
{
    int half = p->w / 2 + 1;
    if (fx >= half) {
        fx = (p->w - fx) % p->w;
        fy = (p->h - fy) % p->h;
    }
    return p->acc[(size_t)fy * half + fx];
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
            double v = power_at(p, x, y) / (double)p->n;
            out[(size_t)sy * w + sx] = (float)log10(v > 1e-30 ? v : 1e-30);
        }
    }
    return 1;
}
