/* fringe.c - see fringe.h. */
#include "fringe.h"

#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/stats.h"

/* The samples of Q: frequency (cycles/px), Q, weight, ring. */
typedef struct samples {
    int n, nbin;
    double *kx, *ky, *q, *wt;
    int *bin;
    int *lo;            /* ring means at a sample: sum_j wq[3 i + j] X[lo + j] */
    double *wq;
    double *ring_n;     /* samples per ring */
    double *tmp;        /* n scratch */
    double *acc;        /* 3 nbin scratch */
} samples;

static void samples_free(samples *s)
{
    free(s->kx);
    free(s->ky);
    free(s->q);
    free(s->wt);
    free(s->bin);
    free(s->lo);
    free(s->wq);
    free(s->ring_n);
    free(s->tmp);
    free(s->acc);
}

static int samples_alloc(samples *s, int n, int nbin)
{
    memset(s, 0, sizeof *s);
    s->nbin = nbin;
    s->kx = malloc(sizeof(double) * (size_t)n);
    s->ky = malloc(sizeof(double) * (size_t)n);
    s->q = malloc(sizeof(double) * (size_t)n);
    s->wt = malloc(sizeof(double) * (size_t)n);
    s->bin = malloc(sizeof(int) * (size_t)n);
    s->lo = malloc(sizeof(int) * (size_t)n);
    s->wq = malloc(3 * sizeof(double) * (size_t)n);
    s->tmp = malloc(sizeof(double) * (size_t)n);
    s->ring_n = calloc((size_t)nbin, sizeof(double));
    s->acc = calloc(3 * (size_t)nbin, sizeof(double));
    if (!s->kx || !s->ky || !s->q || !s->wt || !s->bin || !s->lo || !s->wq || !s->tmp ||
        !s->ring_n || !s->acc) {
        samples_free(s);
        return SL_ENOMEM;
    }
    return SL_OK;
}

/* A pixel integrates light over its square, which multiplies the power
 * spectrum by sinc^2(kx) sinc^2(ky): 0.41 at Nyquist along an axis, 0.66
 * on the diagonal at the same radius, an anisotropy the ring
 * normalisation would read as fringes.  Divided out here. */
static double pixel_mtf(double kx, double ky)
{
    double sx = kx != 0 ? sin(M_PI * kx) / (M_PI * kx) : 1;
    double sy = ky != 0 ? sin(M_PI * ky) / (M_PI * ky) : 1;
    return sx * sx * sy * sy;
}

static void samples_add(samples *s, double kx, double ky, double p, int bin)
{
    p /= pixel_mtf(kx, ky);
    s->kx[s->n] = kx, s->ky[s->n] = ky, s->q[s->n] = p, s->bin[s->n] = bin;
    s->n++;
}

/* A ring's mean X at sample i's own radius: the quadratic through the
 * means of rings lo[i] .. lo[i] + 2 (Lagrange weights wq), or fewer where
 * neighbours are missing.  Power means (logv) are interpolated in their
 * logarithm when all are positive: a seeing-like transfer function is
 * near Gaussian, whose log is quadratic in radius. */
static double ring_at(const samples *s, const double *X, int i, int logv)
{
    const double *w = s->wq + 3 * (size_t)i;
    const double *x = X + s->lo[i];
    int n = w[2] != 0 ? 3 : w[1] != 0 ? 2 : 1;
    int lg = logv;
    for (int j = 0; j < n && lg; j++)
        lg = x[j] > 0;
    double v = 0;
    for (int j = 0; j < n; j++)
        v += w[j] * (lg ? log(x[j]) : x[j]);
    return lg ? exp(v) : v;
}

/* Each sample's interpolation between its ring's mean radius and its
 * neighbours'.  Why: a ring is one grid step wide, and on a small crop
 * (30 px: 0.033 cycles/px) the transfer function falls across it by tens
 * of per cent; the plain ring mean leaves a radial slope in Q that the
 * fit reads as misfit (reduced chi^2 3.6-4.1 on a resolved pair's 30 px
 * crop, 0.95 on its 128 px frame).  Rings without samples are not
 * bridged. */
static void samples_interp(samples *s)
{
    double *rbar = s->acc;
    memset(rbar, 0, sizeof(double) * (size_t)s->nbin);
    memset(s->ring_n, 0, sizeof(double) * (size_t)s->nbin);
    for (int i = 0; i < s->n; i++)
        rbar[s->bin[i]] += hypot(s->kx[i], s->ky[i]), s->ring_n[s->bin[i]]++;
    for (int b = 0; b < s->nbin; b++)
        rbar[b] = s->ring_n[b] > 0 ? rbar[b] / s->ring_n[b] : 0;
    for (int i = 0; i < s->n; i++) {
        int b = s->bin[i], lo = b, n = 1;
        double r = hypot(s->kx[i], s->ky[i]), *w = s->wq + 3 * (size_t)i;
        int has_lo = b > 0 && s->ring_n[b - 1] > 0;
        int has_hi = b + 1 < s->nbin && s->ring_n[b + 1] > 0;
        if (has_lo && has_hi)
            lo = b - 1, n = 3;
        else if (has_lo)
            lo = b - 1, n = 2;
        else if (has_hi)
            n = 2;
        w[0] = 1, w[1] = w[2] = 0;
        if (fabs(r - rbar[b]) > 1e-12 && n > 1)
            for (int j = 0; j < n; j++) {
                double l = 1;
                for (int k = 0; k < n; k++)
                    if (k != j)
                        l *= (r - rbar[lo + k]) / (rbar[lo + j] - rbar[lo + k]);
                w[j] = l;
            }
        else if (n > 1)  /* exactly at the ring's mean radius */
            lo = b;
        s->lo[i] = lo;
    }
}

/* The fraction of the well-measured rings' samples (mean above 5 sigma
 * of one sample's noise) below a tenth of their ring's mean: a mask's
 * gaps make it 0.5 or more; a binary's fringe minima (c = 1) 0.14. */
static double dark_fraction(const samples *s, const double *mean,
                            double noise, double nframes)
{
    double dark = 0, all = 0, sigma = (noise + 1e-300) / sqrt(nframes);
    for (int i = 0; i < s->n; i++) {
        double m = ring_at(s, mean, i, 1);
        if (m > 5 * sigma) {
            all++;
            dark += s->q[i] < 0.1 * m;
        }
    }
    return all > 0 ? dark / all : 1;
}

/* P -> Q = P / ring mean, and the weights (fringe.h).  Rings whose mean
 * is not positive (noise only) are dropped. */
static void samples_normalise(samples *s, double noise, double nframes,
                              double *dark)
{
    samples_interp(s);
    double *mean = s->acc;
    memset(mean, 0, sizeof(double) * (size_t)s->nbin);
    memset(s->ring_n, 0, sizeof(double) * (size_t)s->nbin);
    for (int i = 0; i < s->n; i++)
        mean[s->bin[i]] += s->q[i], s->ring_n[s->bin[i]]++;
    for (int b = 0; b < s->nbin; b++)
        mean[b] = s->ring_n[b] > 0 ? mean[b] / s->ring_n[b] : 0;
    *dark = dark_fraction(s, mean, noise, nframes);
    int k = 0;
    for (int i = 0; i < s->n; i++) {
        double m = ring_at(s, mean, i, 1), p = s->q[i];
        if (!(mean[s->bin[i]] > 0))
            continue;
        m = m > 0 ? m : mean[s->bin[i]];
        /* white noise is flat before the pixel MTF is divided out */
        double den = fmax(p, 0) + noise / pixel_mtf(s->kx[i], s->ky[i]);
        den = fmax(den, 1e-3 * m);
        s->kx[k] = s->kx[i], s->ky[k] = s->ky[i], s->bin[k] = s->bin[i];
        s->q[k] = p / m;
        s->wt[k] = nframes * m * m / (den * den);
        k++;
    }
    s->n = k;
    samples_interp(s);   /* over the rings kept; sets ring_n */
}

/* chi^2 at d with c solved linearly (Q (1 + c J) = 1 + c cos, residual
 * y - c a with y = Q - 1, a = cos - Q J), c clipped to [0, 1].  cosv:
 * cos(2 pi k.d) per sample. */
static double chi2_linear(samples *s, const double *cosv, double *c_out)
{
    double *J = s->acc;
    memset(J, 0, sizeof(double) * (size_t)s->nbin);
    for (int i = 0; i < s->n; i++)
        J[s->bin[i]] += cosv[i];
    for (int b = 0; b < s->nbin; b++)
        J[b] = s->ring_n[b] > 0 ? J[b] / s->ring_n[b] : 0;
    double sya = 0, saa = 0, syy = 0;
    for (int i = 0; i < s->n; i++) {
        double y = s->q[i] - 1, a = cosv[i] - s->q[i] * ring_at(s, J, i, 0);
        sya += s->wt[i] * y * a, saa += s->wt[i] * a * a, syy += s->wt[i] * y * y;
    }
    double c = saa > 0 ? sya / saa : 0;
    c = c < 0 ? 0 : c > 1 ? 1 : c;
    *c_out = c;
    return syy - 2 * c * sya + c * c * saa;
}

/* Grid over d (half plane, step 0.5 px, 0.5 .. max_sep): the best d and
 * c.  Phasors stepped along x: one complex multiply per sample and step. */
static double grid_search(samples *s, double max_sep, double *dx_o,
                          double *dy_o, double *c_o)
{
    const double step = 0.5;
    int nx = (int)floor(max_sep / step);
    double best = INFINITY;
    double complex *z = malloc(sizeof *z * (size_t)s->n);
    double complex *st = malloc(sizeof *st * (size_t)s->n);
    if (!z || !st)
        goto free_all;
    for (int i = 0; i < s->n; i++)
        st[i] = cexp(2 * M_PI * I * s->kx[i] * step);
    for (int iy = 0; iy <= nx; iy++) {
        double dy = iy * step;
        int x0 = iy == 0 ? 1 : -nx;
        for (int i = 0; i < s->n; i++)
            z[i] = cexp(2 * M_PI * I * (s->kx[i] * x0 * step + s->ky[i] * dy));
        for (int ix = x0; ix <= nx; ix++) {
            double dx = ix * step, r = hypot(dx, dy);
            if (r >= 0.5 && r <= max_sep) {
                for (int i = 0; i < s->n; i++)
                    s->tmp[i] = creal(z[i]);
                double c, chi = chi2_linear(s, s->tmp, &c);
                if (chi < best)
                    best = chi, *dx_o = dx, *dy_o = dy, *c_o = c;
            }
            for (int i = 0; i < s->n; i++)
                z[i] *= st[i];
        }
    }
free_all:
    free(z);
    free(st);
    return best;
}

/* The exact model's chi^2 at t = (dx, dy, c) and, when A and g are given,
 * the Gauss-Newton normal equations J^T W J and J^T W r. */
static double model_chi2(samples *s, const double t[3], double A[3][3],
                         double g[3])
{
    double *J = s->acc, *Jx = J + s->nbin, *Jy = Jx + s->nbin;
    memset(J, 0, sizeof(double) * 3 * (size_t)s->nbin);
    for (int i = 0; i < s->n; i++) {
        double ph = 2 * M_PI * (s->kx[i] * t[0] + s->ky[i] * t[1]);
        double sn = sin(ph);
        s->tmp[i] = cos(ph);
        J[s->bin[i]] += s->tmp[i];
        Jx[s->bin[i]] -= 2 * M_PI * s->kx[i] * sn;
        Jy[s->bin[i]] -= 2 * M_PI * s->ky[i] * sn;
    }
    for (int b = 0; b < s->nbin; b++)
        if (s->ring_n[b] > 0)
            J[b] /= s->ring_n[b], Jx[b] /= s->ring_n[b], Jy[b] /= s->ring_n[b];
    double c = t[2], chi = 0;
    if (A)
        memset(A, 0, sizeof(double) * 9), memset(g, 0, sizeof(double) * 3);
    for (int i = 0; i < s->n; i++) {
        double Ji = ring_at(s, J, i, 0), Jxi = ring_at(s, Jx, i, 0), Jyi = ring_at(s, Jy, i, 0);
        double cs = s->tmp[i], den = 1 + c * Ji, num = 1 + c * cs;
        double res = s->q[i] - num / den;
        chi += s->wt[i] * res * res;
        if (!A)
            continue;
        double ph = 2 * M_PI * (s->kx[i] * t[0] + s->ky[i] * t[1]), sn = sin(ph);
        double dcx = -2 * M_PI * s->kx[i] * sn, dcy = -2 * M_PI * s->ky[i] * sn;
        double d2 = den * den, jac[3];
        jac[0] = (c * dcx * den - num * c * Jxi) / d2;
        jac[1] = (c * dcy * den - num * c * Jyi) / d2;
        jac[2] = (cs - Ji) / d2;
        for (int a = 0; a < 3; a++) {
            g[a] += s->wt[i] * jac[a] * res;
            for (int e = 0; e < 3; e++)
                A[a][e] += s->wt[i] * jac[a] * jac[e];
        }
    }
    return chi;
}

/* Levenberg-Marquardt on (dx, dy, c) from t; cov gets (J^T W J)^-1. */
static double refine(samples *s, double t[3], double cov[3][3])
{
    double A[3][3], g[3], lambda = 1e-3;
    double chi = model_chi2(s, t, A, g);
    for (int it = 0; it < 30; it++) {
        double M[3][3], step[3], trial[3];
        memcpy(M, A, sizeof M);
        for (int a = 0; a < 3; a++)
            M[a][a] *= 1 + lambda;
        if (!stats_solve(3, &M[0][0], g, step))
            break;
        for (int a = 0; a < 3; a++)
            trial[a] = t[a] + step[a];
        trial[2] = fmin(fmax(trial[2], 1e-6), 1);
        double At[3][3], gt[3], ct = model_chi2(s, trial, At, gt);
        if (ct < chi) {
            double gain = chi - ct;
            memcpy(t, trial, sizeof trial);
            memcpy(A, At, sizeof A);
            memcpy(g, gt, sizeof gt);
            chi = ct;
            lambda *= 0.3;
            if (gain < 1e-9 * chi)
                break;
        } else {
            lambda *= 10;
            if (lambda > 1e8)
                break;
        }
    }
    double e[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (int k = 0; k < 3; k++)
        if (!stats_solve(3, &A[0][0], e[k], cov[k]))
            memset(cov[k], 0, sizeof cov[k]);
    return chi;
}

static double ratio_of_contrast(double c)
{
    return c > 1e-12 ? (1 - sqrt(fmax(1 - c * c, 0))) / c : 0;
}

static void describe(double t[3], double cov[3][3], double chi, double chi0,
                     int n, fringe_result *o)
{
    double dx = t[0], dy = t[1];
    if (dy < 0 || (dy == 0 && dx < 0))
        dx = -dx, dy = -dy;
    double red = n > 3 ? chi / (n - 3) : 1;
    red = red > 0 ? red : 1;
    o->dx_px = dx, o->dy_px = dy;
    o->sep_px = hypot(dx, dy);
    o->pa_deg = fmod(atan2(-dx, dy) * 180 / M_PI + 360, 180);
    o->contrast = t[2];
    o->flux_ratio = ratio_of_contrast(t[2]);
    o->dm_mag = o->flux_ratio > 0 ? -2.5 * log10(o->flux_ratio) : INFINITY;
    double sxx = cov[0][0] * red, syy = cov[1][1] * red, sxy = cov[0][1] * red;
    double s2 = o->sep_px * o->sep_px;
    o->sep_err_px = s2 > 0 ? sqrt(fmax(dx * dx * sxx + 2 * dx * dy * sxy + dy * dy * syy, 0) / s2) : INFINITY;
    o->pa_err_deg = s2 > 0 ? sqrt(fmax(dy * dy * sxx - 2 * dx * dy * sxy + dx * dx * syy, 0)) / s2 * 180 / M_PI : INFINITY;
    /* dm(c): numerical derivative */
    double c = t[2], h = 1e-6, sc = sqrt(fmax(cov[2][2] * red, 0));
    double r1 = ratio_of_contrast(fmin(c + h, 1)), r0 = ratio_of_contrast(fmax(c - h, 1e-9));
    double ddm = r1 > 0 && r0 > 0 ? -2.5 * (log10(r1) - log10(r0)) / (fmin(c + h, 1) - fmax(c - h, 1e-9)) : INFINITY;
    o->dm_err_mag = fabs(ddm) * sc;
    o->chi2_red = red;
    o->significance = (chi0 - chi) / red;
    o->nsamples = n;
    o->detected = o->significance > FRINGE_DETECT && red < FRINGE_MAX_CHI2;
}

/* The samples at frequencies (p, q) with p and q multiples of m (frame
 * w x h) into *sub, ring-interpolated over themselves: the grid search's
 * share of a large frame.  SL_ENOMEM. */
static int on_grid(const samples *s, int i, int m, int w, int h)
{
    return lround(s->kx[i] * w) % m == 0 && lround(s->ky[i] * h) % m == 0;
}

static int decimated(const samples *s, int m, int w, int h, samples *sub)
{
    int n = 0;
    for (int i = 0; i < s->n; i++)
        n += on_grid(s, i, m, w, h);
    if (samples_alloc(sub, n > 0 ? n : 1, s->nbin) != SL_OK)
        return SL_ENOMEM;
    n = 0;
    for (int i = 0; i < s->n; i++) {
        if (!on_grid(s, i, m, w, h))
            continue;
        sub->kx[n] = s->kx[i], sub->ky[n] = s->ky[i], sub->q[n] = s->q[i];
        sub->wt[n] = s->wt[i], sub->bin[n] = s->bin[i];
        n++;
    }
    sub->n = n;
    samples_interp(sub);
    return SL_OK;
}

/* The grid search on every m-th frequency along each axis (m = 1: all),
 * its best (dx, dy, c) into t; its chi^2 (not finite: out of memory). */
static double grid_on(samples *s, int m, int w, int h, double max_sep, double t[3])
{
    if (m <= 1)
        return grid_search(s, max_sep, &t[0], &t[1], &t[2]);
    samples sub;
    if (decimated(s, m, w, h, &sub) != SL_OK)
        return INFINITY;
    double chi = sub.n >= 32 ? grid_search(&sub, max_sep, &t[0], &t[1], &t[2])
                             : grid_search(s, max_sep, &t[0], &t[1], &t[2]);
    samples_free(&sub);
    return chi;
}

/* m, w, h: the grid search's decimation (grid_on). */
static int fit(samples *s, int m, int w, int h, double noise, double nframes, double max_sep,
               fringe_result *out, sl_err *err)
{
    memset(out, 0, sizeof *out);
    double dark;
    samples_normalise(s, noise, nframes, &dark);
    if (s->n < 32)
        return sl_seterr(err, SL_EDATA, "fringe fit: %d usable frequencies "
                         "(need 32)", s->n);
    double chi0 = 0;
    for (int i = 0; i < s->n; i++)
        chi0 += s->wt[i] * (s->q[i] - 1) * (s->q[i] - 1);
    double t[3] = {0, 0, 0}, cov[3][3];
    if (!isfinite(grid_on(s, m, w, h, fmax(max_sep, 1), t)))
        return sl_seterr(err, SL_ENOMEM, "fringe fit: out of memory");
    t[2] = fmax(t[2], 1e-3);
    double chi = refine(s, t, cov);
    describe(t, cov, chi, chi0, s->n, out);
    out->dark_fraction = dark;
    out->detected &= dark < FRINGE_MAX_DARK;
    return SL_OK;
}

int fringe_fit_2d(const double *ps, int w, int h, double noise,
                  double nframes, double rcut_px, double max_sep_px,
                  fringe_result *out, sl_err *err)
{
    int L = w > h ? w : h, nbin = (int)ceil(rcut_px) + 2;
    samples s;
    if (samples_alloc(&s, w * h / 2 + 1, nbin) != SL_OK)
        return sl_seterr(err, SL_ENOMEM, "fringe fit: out of memory");
    for (int q = 0; q < h; q++)
        for (int p = 0; p < w; p++) {
            int fp = p <= w / 2 ? p : p - w, fq = q <= h / 2 ? q : q - h;
            if ((w % 2 == 0 && p == w / 2) || (h % 2 == 0 && q == h / 2))
                continue;
            if (fq < 0 || (fq == 0 && fp <= 0))
                continue;
            double kx = (double)fp / w, ky = (double)fq / h;
            int b = (int)lround(hypot(kx, ky) * L);
            if (b >= 2 && b <= rcut_px && b < nbin)
                samples_add(&s, kx, ky, ps[(size_t)q * w + p], b);
        }
    /* The grid only has to find the basin: at the largest separation a
     * fringe spans L / max_sep frequencies, and 8 per fringe are enough,
     * so a large frame's grid runs on every m-th along each axis (1024^2
     * with max_sep 16: m 8, the grid 5.5 s -> ~0.1 s); the
     * Levenberg-Marquardt that follows uses them all. */
    int m = (int)(L / (8 * fmax(max_sep_px, 1)));
    int rc = fit(&s, m > 1 ? m : 1, w, h, noise, nframes, max_sep_px, out, err);
    samples_free(&s);
    return rc;
}

int fringe_fit_polar(const double *ps, int nang, int nf, int nproj,
                     double noise, double nframes, double max_sep_px,
                     fringe_result *out, sl_err *err)
{
    samples s;
    if (samples_alloc(&s, nang * nf, nf) != SL_OK)
        return sl_seterr(err, SL_ENOMEM, "fringe fit: out of memory");
    for (int a = 0; a < nang; a++) {
        double th = a * M_PI / nang, ca = cos(th), sa = sin(th);
        for (int j = 2; j < nf; j++)
            samples_add(&s, (double)j / nproj * ca, (double)j / nproj * sa,
                        ps[(size_t)a * nf + j], j);
    }
    int rc = fit(&s, 1, 0, 0, noise, nframes, max_sep_px, out, err);
    samples_free(&s);
    return rc;
}
