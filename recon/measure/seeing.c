/* seeing.c - see seeing.h. */
#include "seeing.h"


#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/stats.h"

#define ARCSEC_PER_RAD (180.0 * 3600.0 / M_PI)

struct seeing {
    int w, h;
    double ps_arcsec, lambda_m, d_m;
    float *scratch;          /* for the median (a copy of one frame) */
    int n;
    double sx, sy, sxx, syy; /* centroid sums */
    double lx, ly, sxl, syl; /* last centroid and lag-1 products */
};

int seeing_new(seeing **out, int w, int h, double plate_scale_arcsec,
               double wavelength_m, double pupil_diameter_m, sl_err *err)
{
    *out = NULL;
    if (w < 4 || h < 4)
        return sl_seterr(err, SL_EINVAL, "frame %dx%d too small", w, h);
    if (!(plate_scale_arcsec > 0 && wavelength_m > 0 && pupil_diameter_m > 0))
        return sl_seterr(err, SL_EINVAL, "seeing needs a plate scale, a "
                         "wavelength and a pupil diameter > 0 (got %g arcsec/px, "
                         "%g m, %g m)", plate_scale_arcsec, wavelength_m,
                         pupil_diameter_m);
    seeing *s = calloc(1, sizeof *s);
    if (!s || !(s->scratch = malloc(sizeof(float) * w * h))) {
        free(s);
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    }
    s->w = w;
    s->h = h;
    s->ps_arcsec = plate_scale_arcsec;
    s->lambda_m = wavelength_m;
    s->d_m = pupil_diameter_m;
    *out = s;
    return SL_OK;
}

void seeing_free(seeing *s)
{
    if (!s)
        return;
    free(s->scratch);
    free(s);
}

/* Threshold for the centroid: pixels more than max(5 noise sigma, 5 % of
 * the peak) above the median.  Without it, read and photon noise over the
 * whole frame pull every centroid towards the frame centre and the image
 * motion (hence r0) comes out wrong by a seeing-dependent factor. */
static float centroid_threshold(seeing *s, const float *f, size_t n,
                                float *med_out)
{
    size_t m = 0;
    float peak = -INFINITY;
    for (size_t i = 0; i < n; i++)
        if (isfinite(f[i])) {
            s->scratch[m++] = f[i];
            peak = f[i] > peak ? f[i] : peak;
        }
    if (m < 4)
        return NAN;
    float med = stats_median_inplace(s->scratch, m);
    for (size_t i = 0; i < m; i++)
        s->scratch[i] = fabsf(s->scratch[i] - med);
    float sigma = 1.4826f * stats_median_inplace(s->scratch, m);
    float t = 5 * sigma, t2 = 0.05f * (peak - med);
    *med_out = med;
    return t > t2 ? t : t2;
}

int seeing_add(seeing *s, const float *f)
{
    size_t n = (size_t)s->w * s->h;
    float med = 0, thr = centroid_threshold(s, f, n, &med);
    if (!isfinite(thr))
        return SL_OK;
    double sw = 0, sx = 0, sy = 0;
    for (int y = 0; y < s->h; y++)
        for (int x = 0; x < s->w; x++) {
            float v = f[(size_t)y * s->w + x] - med - thr;
            if (v > 0 && isfinite(v)) {
                sw += v;
                sx += v * x;
                sy += v * y;
            }
        }
    if (!(sw > 0))
        return SL_OK;
    double cx = sx / sw, cy = sy / sw;
    if (s->n > 0) {
        s->sxl += cx * s->lx;
        s->syl += cy * s->ly;
    }
    s->lx = cx;
    s->ly = cy;
    s->sx += cx;
    s->sy += cy;
    s->sxx += cx * cx;
    s->syy += cy * cy;
    s->n++;
    return SL_OK;
}

int seeing_result_get(const seeing *s, seeing_result *r)
{
    memset(r, 0, sizeof *r);
    r->nframes = s->n;
    if (s->n < 3)
        return SL_EDATA;
    double n = s->n, mx = s->sx / n, my = s->sy / n;
    double vx = s->sxx / n - mx * mx, vy = s->syy / n - my * my;
    double var_px = 0.5 * (vx + vy);
    /* Lag-1 autocorrelation rho: n_eff = n (1 - rho) / (1 + rho). */
    double cxl = s->sxl / (n - 1) - mx * mx, cyl = s->syl / (n - 1) - my * my;
    double rho = var_px > 0 ? 0.5 * (cxl + cyl) / var_px : 0;
    if (rho > 0.99)
        rho = 0.99;
    if (rho < 0)
        rho = 0;
    r->n_eff = n * (1 - rho) / (1 + rho);
    r->tilt_rms_arcsec = sqrt(var_px) * s->ps_arcsec;
    double var_rad = var_px * pow(s->ps_arcsec / ARCSEC_PER_RAD, 2);
    if (!(var_rad > 0))
        return SL_EDATA;
    double ld = s->lambda_m / s->d_m;
    r->r0_m = s->d_m * pow(0.170 * ld * ld / var_rad, 0.6);
    r->r0_err_m = r->r0_m * 0.6 * sqrt(2.0 / (r->n_eff > 1 ? r->n_eff : 1));
    r->seeing_fwhm_arcsec = 0.98 * s->lambda_m / r->r0_m * ARCSEC_PER_RAD;
    return SL_OK;
}
