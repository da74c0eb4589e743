/* sim_frame.c - rendering: the phase over the pupil (screen or piston),
 * PSF, convolution with the object, pointing shift, binning to output
 * pixels, detector.  Planning is sim.c; the physics is in sim.h. */
#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "sim_int.h"

/* Jitter of frame k is random stream JITTER_STREAM + k: apart from the
 * detector's noise streams (detector.c) for any frame index. */
#define JITTER_STREAM 0x717700000000ULL

/* Piston model: each pupil pixel of the window gets the hole whose centre
 * is nearest.  Holes never overlap (mask.h), so every pixel a hole covers
 * is nearer its own centre than any other; only pixels on the rim shared
 * by two touching holes could tie.  O(win^2 nholes), once. */
int sim_make_labels(sim *s, const mask *m)
{
    if (s->o.phase_model != SIM_PHASE_PISTON)
        return SL_OK;
    int nh = mask_nholes(m);
    if (nh == 0)
        return sl_seterr(&s->err, SL_EINVAL, "phase model 'piston' needs a "
                         "mask of holes: the filled %.3g m aperture has no "
                         "holes to piston (use the screen model)",
                         mask_extent_m(m));
    size_t n = (size_t)s->win * s->win;
    s->nholes = nh;
    s->hole = malloc(n * sizeof *s->hole);
    s->hsum = malloc(2 * (size_t)nh * sizeof *s->hsum);
    if (!s->hole || !s->hsum)
        return sl_seterr(&s->err, SL_ENOMEM, "out of memory for the hole "
                         "labels");
    for (int y = 0; y < s->win; y++)
        for (int x = 0; x < s->win; x++) {
            size_t i = (size_t)y * s->win + x;
            double px = (s->win0 + x - s->M / 2) * s->dx;
            double py = (s->win0 + y - s->M / 2) * s->dx, best = INFINITY;
            s->hole[i] = -1;
            for (int h = 0; h < nh && s->pupil[i] > 0; h++) {
                double hx, hy;
                mask_hole(m, h, &hx, &hy);
                double d2 = (px - hx) * (px - hx) + (py - hy) * (py - hy);
                if (d2 < best) {
                    best = d2;
                    s->hole[i] = h;
                }
            }
        }
    return SL_OK;
}

/* Replace the phase over each hole by its transmission-weighted mean. */
static void apply_piston(sim *s)
{
    size_t n = (size_t)s->win * s->win;
    double *sum = s->hsum, *wt = s->hsum + s->nholes;
    memset(s->hsum, 0, 2 * (size_t)s->nholes * sizeof *s->hsum);
    for (size_t i = 0; i < n; i++)
        if (s->hole[i] >= 0) {
            sum[s->hole[i]] += (double)s->pupil[i] * s->phase[i];
            wt[s->hole[i]] += s->pupil[i];
        }
    for (size_t i = 0; i < n; i++)
        s->phase[i] = s->hole[i] >= 0
                          ? (float)(sum[s->hole[i]] / wt[s->hole[i]])
                          : 0.0f;
}

int sim_phase_window(sim *s, int k, float *phase)
{
    size_t n = (size_t)s->win * s->win;
    if (!s->scr) {
        memset(phase, 0, n * sizeof *phase);
        return SL_OK;
    }
    /* Frozen flow along dir.  The screen's fine grid repeats every n dx
     * (22.5 m at 200^2 and Nyquist), so after each such lap of flow the
     * pupil moves sideways to a fresh lane (win + 2 px over): a long
     * sequence (more frames, a longer frame interval) sees new turbulence
     * for n / (win + 2) laps instead of the same frames again.  Within a
     * lap the flow is continuous; sequences shorter than one lap (the
     * default 100 frames at 10 ms, 10 m/s) are unchanged. */
    double t = k * s->o.frame_interval_s, dir = s->o.wind_dir_deg * M_PI / 180;
    double d = s->o.wind_mps * t, period = screen_n(s->scr) * s->dx;
    double lane = floor(d / period) * (s->win + 2) * s->dx;
    double x0 = (s->win0 - s->M / 2) * s->dx - d * cos(dir) + lane * sin(dir);
    double y0 = (s->win0 - s->M / 2) * s->dx - d * sin(dir) - lane * cos(dir);
    return screen_sample(s->scr, phase, s->win, s->win, x0, y0, s->dx);
}

/* PSF of frame k (k < 0: cophased) into s->psf, unit sum, origin at [0]. */
static int compute_psf(sim *s, int k)
{
    int rc = SL_OK;
    if (k >= 0)
        rc = sim_phase_window(s, k, s->phase);
    else
        memset(s->phase, 0, (size_t)s->win * s->win * sizeof *s->phase);
    if (rc != SL_OK)
        return rc;
    if (k >= 0 && s->hole)
        apply_piston(s);
    for (int y = 0; y < s->win; y++) {
        fftwf_complex *row = s->fin + (size_t)(s->win0 + y) * s->M + s->win0;
        const float *pu = s->pupil + (size_t)y * s->win;
        const float *ph = s->phase + (size_t)y * s->win;
        for (int x = 0; x < s->win; x++)
            row[x] = pu[x] * (cosf(ph[x]) + I * sinf(ph[x]));
    }
    fftwf_execute(s->p_field);
    size_t MM = (size_t)s->M * s->M;
    float sc = (float)s->psf_scale;
    for (size_t i = 0; i < MM; i++) {
        float re = crealf(s->fout[i]), im = cimagf(s->fout[i]);
        s->psf[i] = (re * re + im * im) * sc;
    }
    return SL_OK;
}

/* Sum the fine image s->img into out (w x h): k x k fine pixels per
 * output pixel, cropped from the grid's centre. */
static void bin_square(sim *s, float *out)
{
    int w = s->o.width, h = s->o.height, k = s->k;
    int ox = (s->M - k * w) / 2, oy = (s->M - k * h) / 2;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double sum = 0;
            for (int j = 0; j < k; j++) {
                const float *row = s->img + (size_t)(oy + y * k + j) * s->M +
                                   ox + x * k;
                for (int i = 0; i < k; i++)
                    sum += row[i];
            }
            out[(size_t)y * w + x] = (float)sum;
        }
}

/* Non-square pixels: output row y covers the fine rows between edges
 * oy + y ky and oy + (y + 1) ky; rows cut by an edge count by the fraction
 * inside, so each fine row's flux lands exactly once. */
static void bin_rect(sim *s, float *out)
{
    int w = s->o.width, h = s->o.height, k = s->k;
    int ox = (s->M - k * w) / 2;
    for (int y = 0; y < h; y++) {
        double a = s->oy + y * s->ky, b = a + s->ky;
        memset(s->acc, 0, (size_t)w * sizeof *s->acc);
        for (int j = (int)floor(a); j < b; j++) {
            double wt = fmin(b, j + 1.0) - fmax(a, j);
            if (wt <= 0)
                continue;
            const float *row = s->img + (size_t)j * s->M + ox;
            for (int x = 0; x < w; x++) {
                double sum = 0;
                for (int i = 0; i < k; i++)
                    sum += row[x * k + i];
                s->acc[x] += wt * sum;
            }
        }
        for (int x = 0; x < w; x++)
            out[(size_t)y * w + x] = (float)s->acc[x];
    }
}

/* Convolve s->psf with the object into s->img (fine grid), the scene moved
 * by (sx, sy) fine pixels when shift is set, then bin and crop into out.
 * The shift is separable, e^{-2 pi i (u sx + v sy) / M} = rx[u] ry[v]:
 * M + M/2 + 1 complex exponentials per frame, not M^2. */
static void convolve_bin(sim *s, float *out, int shift, double sx, double sy)
{
    int M = s->M, H = M / 2 + 1;
    size_t MH = (size_t)M * H;
    fftwf_execute(s->p_psf);
    if (!shift) {
        for (size_t i = 0; i < MH; i++)
            s->otf[i] *= s->obj[i];
    } else {
        for (int u = 0; u < H; u++)
            s->rx[u] = (float complex)cexp(-2 * M_PI * I * sx * u / M);
        for (int v = 0; v < M; v++)
            s->ry[v] = (float complex)cexp(-2 * M_PI * I * sy *
                                           (v <= M / 2 ? v : v - M) / M);
        for (int v = 0; v < M; v++)
            for (int u = 0; u < H; u++) {
                size_t i = (size_t)v * H + u;
                s->otf[i] *= s->obj[i] * (s->rx[u] * s->ry[v]);
            }
    }
    fftwf_execute(s->p_img); /* destroys otf, by FFTW's c2r contract */
    if (s->o.pixel_aspect == 1)
        bin_square(s, out);
    else
        bin_rect(s, out);
}

int sim_frame_offset_px(const sim *s, int k, double *dx_px, double *dy_px)
{
    if (k < 0)
        return SL_EINVAL;
    *dx_px = s->o.offset_x_px;
    *dy_px = s->o.offset_y_px;
    if (s->o.jitter_px > 0) {
        rng r;
        rng_init(&r, s->o.seed, JITTER_STREAM + (uint64_t)k);
        *dx_px += s->o.jitter_px * rng_normal(&r);
        *dy_px += s->o.jitter_px * rng_normal(&r);
    }
    return SL_OK;
}

int sim_frame(sim *s, int k, float *frame)
{
    if (k < 0)
        return sl_seterr(&s->err, SL_EINVAL, "frame index %d < 0", k);
    int rc = compute_psf(s, k);
    if (rc != SL_OK)
        return rc;
    double dx, dy;
    sim_frame_offset_px(s, k, &dx, &dy);
    /* output pixels to fine pixels: k columns, ky rows per pixel */
    convolve_bin(s, frame, dx != 0 || dy != 0, dx * s->k, dy * s->ky);
    if (s->det)
        detector_read(s->det, k, frame);
    return SL_OK;
}

int sim_cophased(sim *s, float *img)
{
    int rc = compute_psf(s, -1);
    if (rc == SL_OK)
        convolve_bin(s, img, 0, 0, 0);
    return rc;
}

int sim_psf(sim *s, int k, float *psf)
{
    int rc = compute_psf(s, k < 0 ? -1 : k), M = s->M;
    if (rc != SL_OK)
        return rc;
    for (int y = 0; y < M; y++)
        for (int x = 0; x < M; x++)
            psf[(size_t)((y + M / 2) % M) * M + (x + M / 2) % M] =
                s->psf[(size_t)y * M + x];
    return SL_OK;
}
