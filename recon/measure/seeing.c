/* seeing.c - see seeing.h. */
#include "seeing.h"


#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/stats.h"

#define ARCSEC_PER_RAD (180.0 * 3600.0 / M_PI)

/* One-axis G-tilt variance of a disk, in (lambda/D)^2 (D/r0)^(5/3):
 * pi^(2/3) KOLMO_C I with KOLMO_C = 0.0228955871 (sim/screen.c) and
 * I = int_0^inf x^(-2/3) (2 J1(x)/x)^2 dx = 3.457494. */
#define GTILT_COEF 0.16980

/* delta(x) at x = 10^(-2 + i/16), i = 0..48 (see seeing.h): computed by
 * quadrature (x' = t^3 on [0, 1], composite Gauss-Legendre beyond, steps
 * below 1/30 of the shortest oscillation, to x' = 4000, then the tail's
 * mean); test_seeing checks points of it against its own quadrature. */
#define TS_N 49
#define TS_X0 0.01
#define TS_PER_DECADE 16
static const double TS[TS_N] = {
    7.42e-05,   9.866e-05,  0.00013112, 0.00017422, 0.0002314,  0.00030722,
    0.00040768, 0.00054072, 0.00071672, 0.00094942, 0.00125676, 0.00166224,
    0.00219652, 0.00289956, 0.0038232,  0.00503452, 0.00661984, 0.00868976,
    0.0113851,  0.0148838,  0.0194084,  0.0252346,  0.0326981,  0.0421998,
    0.0542056,  0.0692355,  0.0878345,  0.110513,   0.137642,   0.169271,
    0.204867,   0.242961,   0.280879,   0.316251,   0.349343,   0.380529,
    0.410029,   0.437998,   0.464555,   0.489799,   0.513813,   0.536667,
    0.558427,   0.579152,   0.598893,   0.617701,   0.635623,   0.6527,
    0.668975};
/* 1 - delta -> Gamma(1/6) / (2 Gamma(5/6) I) x^(-1/3) for x >> 1 (the
 * x^(-2/3) J0 integral; the next term is O(x^(-7/3))). */
#define TS_ASYM 0.713124
#define TS_XMAX 10.0

/* Bounds of the frozen-flow shift per frame u (pupil diameters). */
#define U_MIN 1e-3
#define U_MAX 1e6
#define U_ITER 40

struct seeing {
    int w, h;
    double ps_arcsec, lambda_m, d_m;
    float *scratch;          /* for the median (a copy of one frame) */
    int n;
    double x0, y0;           /* first centroid: sums are taken about it */
    double sx, sy, sxx, syy; /* centroid sums */
    double lx, ly;           /* last centroid */
    double sdd;              /* sum of squared steps, both axes */
};

double seeing_tilt_structure(double x)
{
    if (!(x > 0))
        return 0;
    if (x >= TS_XMAX)
        return 1 - TS_ASYM / cbrt(x);
    if (x <= TS_X0)
        return TS[0] * (x / TS_X0) * (x / TS_X0);
    double p = log10(x / TS_X0) * TS_PER_DECADE;
    int i = (int)p;
    if (i > TS_N - 2)
        i = TS_N - 2;
    return TS[i] * pow(TS[i + 1] / TS[i], p - i);
}

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
    if (s->n == 0) {
        s->x0 = cx;
        s->y0 = cy;
    } else {
        double dx = cx - s->lx, dy = cy - s->ly;
        s->sdd += dx * dx + dy * dy;
    }
    s->lx = cx;
    s->ly = cy;
    cx -= s->x0;
    cy -= s->y0;
    s->sx += cx;
    s->sy += cy;
    s->sxx += cx * cx;
    s->syy += cy * cy;
    s->n++;
    return SL_OK;
}

/* K(u, n): the expected variance about the mean of n frames u D apart, in
 * units of the ensemble variance (seeing.h).  O(n). */
static double tilt_kept(double u, int n)
{
    double sum = 0;
    for (int l = 1; l < n; l++)
        sum += (double)(n - l) * seeing_tilt_structure(l * u);
    return 2 * sum / ((double)n * n);
}

/* The u whose expected S1 / V, 2 delta(u) / K(u, n), is q: bisection in
 * log u (the ratio increases with u), clamped to [U_MIN, U_MAX]. */
static double solve_shift(double q, int n)
{
    double lo = log(U_MIN), hi = log(U_MAX);
    for (int it = 0; it < U_ITER; it++) {
        double mid = 0.5 * (lo + hi), u = exp(mid);
        if (2 * seeing_tilt_structure(u) / tilt_kept(u, n) < q)
            lo = mid;
        else
            hi = mid;
    }
    return exp(0.5 * (lo + hi));
}

/* Independent samples of the variance about the mean for n frames u D
 * apart, both axes: 2 tr(B)^2 / tr(B^2) with B the centred covariance of
 * one axis, B = -1/2 P Dm P (P = I - 11'/n, Dm_ij = d_|i-j| = 2 delta(|i-j|
 * u)).  With a_i = (1/n) sum_j d_ij and abar their mean, tr B = n abar / 2
 * and tr B^2 = (sum_ij d_ij^2 - 2 n sum_i a_i^2 + n^2 abar^2) / 4; a_i =
 * (F_i + F_{n-1-i}) / n with F_m = sum_{l=1}^m d_l, kept as a forward and
 * a backward running sum: O(n), no allocation. */
static double model_neff(double u, int n)
{
    double ftot = 0, sdd = 0;
    for (int l = 1; l < n; l++) {
        double d = 2 * seeing_tilt_structure(l * u);
        ftot += d;
        sdd += 2.0 * (n - l) * d * d;
    }
    double fwd = 0, bwd = ftot, sa = 0, saa = 0;
    for (int i = 0; i < n; i++) {
        if (i > 0) {
            fwd += 2 * seeing_tilt_structure(i * u);
            bwd -= 2 * seeing_tilt_structure((n - i) * u);
        }
        double a = (fwd + bwd) / n;
        sa += a;
        saa += a * a;
    }
    double abar = sa / n, trb2 = sdd - 2.0 * n * saa + (double)n * n * abar * abar;
    if (!(trb2 > 0))
        return 1;
    return 2 * (double)n * n * abar * abar / trb2;
}

int seeing_result_get(const seeing *s, seeing_result *r)
{
    memset(r, 0, sizeof *r);
    r->nframes = s->n;
    r->wavelength_m = s->lambda_m;
    if (s->n < 3)
        return SL_EDATA;
    int nf = s->n;
    double n = nf, mx = s->sx / n, my = s->sy / n;
    double vx = s->sxx / n - mx * mx, vy = s->syy / n - my * my;
    double var_px = 0.5 * (vx + vy);        /* V, per axis */
    double step_px = s->sdd / (2 * (n - 1)); /* S1, per axis */
    r->tilt_rms_arcsec = sqrt(var_px > 0 ? var_px : 0) * s->ps_arcsec;
    double var_rad = var_px * pow(s->ps_arcsec / ARCSEC_PER_RAD, 2);
    if (!(var_rad > 0) || !(step_px >= 0))
        return SL_EDATA;
    /* Frozen flow (seeing.h): u from S1 / V, then the ensemble variance. */
    double u = solve_shift(step_px / var_px, nf);
    r->shift_d = u;
    r->tilt_kept = tilt_kept(u, nf);
    r->n_eff = model_neff(u, nf);
    double sigma2 = var_rad / r->tilt_kept;
    double ld = s->lambda_m / s->d_m;
    r->r0_m = s->d_m * pow(GTILT_COEF * ld * ld / sigma2, 0.6);
    /* Error of log sigma2 = log V - log K(u(S1 / V)): with kappa = dlog K /
     * dlog u and rho = dlog(2 delta / K) / dlog u (> 0), it is (1 + g) log V
     * - g log S1, g = kappa / rho: a run with little slow tilt also reads a
     * larger u, and g (0.125 for the demo) carries that.  Var log V = 2 /
     * n_eff; S1's steps count as 2 (n - 1) independent samples. */
    double h = 0.05, up = u * exp(h), um = u * exp(-h);
    double kp = tilt_kept(up, nf), km = tilt_kept(um, nf);
    double kappa = log(kp / km) / (2 * h);
    double rho = log(seeing_tilt_structure(up) / kp * km /
                     seeing_tilt_structure(um)) / (2 * h);
    double g = rho > 0 && kappa > 0 ? kappa / rho : 0;
    double var_log = (1 + g) * (1 + g) * 2 / (r->n_eff > 1 ? r->n_eff : 1) +
                     g * g * 2 / (2 * (n - 1));
    r->r0_err_m = r->r0_m * 0.6 * sqrt(var_log);
    r->seeing_fwhm_arcsec = 0.98 * s->lambda_m / r->r0_m * ARCSEC_PER_RAD;
    return SL_OK;
}
