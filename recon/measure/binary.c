/* binary.c - see binary.h.  The fit itself (cost, Levenberg-Marquardt,
 * covariance, band-limited peaks) is binary_fit.c; this file finds the
 * signal, the candidates, and chooses and states the result.
 *
 * Frequencies live in FFTW's r2c half spectrum: column i = 0..w/2, row j =
 * 0..h-1.  The half plane used is i > 0 plus (i = 0, 0 < j < h/2); Nyquist
 * rows and columns are dropped (their sign is ambiguous), and so is u = 0
 * (the background).
 */
#include <complex.h>
#include <fftw3.h>

#include "binary.h"
#include "binary_fit.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NPAR BINARY_FIT_NPAR

enum {
    NCAND = 4,       /* candidates per search (raw maxima, antisymmetric) */
    CAND_ITERS = 12, /* LM iterations per candidate before the choice */
    FINAL_ITERS = 200
};

struct binary_plan {
    int w, h, nx;            /* nx = w/2 + 1 half-spectrum columns */
    double *img;             /* w*h: image minus background */
    double *anti;            /* w*h: antisymmetric part about x1 */
    fftw_complex *spec;      /* h*nx: spectrum of img */
    fftw_complex *work;      /* h*nx: c2r input (destroyed) */
    fftw_plan fwd, inv;
    float *scratch;          /* w*h: medians */
    double *rimg, *jimg;     /* w*h, NPAR w*h: residual and sensitivity
                              * images (residual_cov) */
    binary_fit f;            /* frequencies and the fit's workspace */
    sl_err err;
};

static int sfreq(int i, int n) { return i <= (n - 1) / 2 ? i : i - n; }

binary_plan *binary_plan_new(int w, int h, sl_err *err)
{
    if (w < 8 || h < 8) {
        sl_seterr(err, SL_EINVAL, "binary: image %dx%d too small", w, h);
        return NULL;
    }
    binary_plan *p = calloc(1, sizeof *p);
    if (!p)
        goto fail_struct;
    size_t n = (size_t)w * h, nh = (size_t)h * (w / 2 + 1);
    p->w = w;
    p->h = h;
    p->nx = w / 2 + 1;
    p->img = fftw_alloc_real(n);
    p->anti = fftw_alloc_real(n);
    p->spec = fftw_alloc_complex(nh);
    p->work = fftw_alloc_complex(nh);
    p->scratch = malloc(n * sizeof *p->scratch);
    p->rimg = malloc(n * sizeof *p->rimg);
    p->jimg = malloc(NPAR * n * sizeof *p->jimg);
    if (!p->img || !p->anti || !p->spec || !p->work || !p->scratch || !p->rimg || !p->jimg ||
        binary_fit_init(&p->f, w, h) != SL_OK)
        goto fail_alloc;
    p->fwd = fftw_plan_dft_r2c_2d(h, w, p->img, p->spec, FFTW_ESTIMATE);
    p->inv = fftw_plan_dft_c2r_2d(h, w, p->work, p->anti, FFTW_ESTIMATE);
    if (!p->fwd || !p->inv)
        goto fail_alloc;
    return p;
fail_alloc:
    binary_plan_free(p);
fail_struct:
    sl_seterr(err, SL_ENOMEM, "binary: out of memory for %dx%d plan", w, h);
    return NULL;
}

void binary_plan_free(binary_plan *p)
{
    if (!p)
        return;
    if (p->fwd)
        fftw_destroy_plan(p->fwd);
    if (p->inv)
        fftw_destroy_plan(p->inv);
    fftw_free(p->img);
    fftw_free(p->anti);
    fftw_free(p->spec);
    fftw_free(p->work);
    free(p->scratch);
    free(p->rimg);
    free(p->jimg);
    binary_fit_clear(&p->f);
    free(p);
}

const char *binary_errmsg(const binary_plan *p)
{
    return p ? p->err.msg : "no binary plan";
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
static int core_radius(const double *img, int w, int h, int cx, int cy)
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

/* Noise power per frequency E|n|^2 from the spectrum beyond 0.5 cycle/px
 * (empty for any pupil sampled at Nyquist or finer): the median of |I|^2
 * there / ln 2 (exponentially distributed power).  Then the half-plane
 * frequencies into p->f: first those with |I| over 3 sigma and over 1e-6
 * of the largest (float rounding), then the rest. */
static double select_freqs(binary_plan *p)
{
    int w = p->w, h = p->h, nx = p->nx;
    binary_fit *f = &p->f;
    size_t nc = 0;
    double amax = 0;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < nx; i++) {
            double fx = (double)i / w, fy = (double)sfreq(j, h) / h;
            double complex v = p->spec[(size_t)j * nx + i];
            double a2 = creal(v) * creal(v) + cimag(v) * cimag(v);
            if (i || j)
                amax = a2 > amax ? a2 : amax;
            if (fx * fx + fy * fy > 0.25)
                p->scratch[nc++] = (float)a2;
        }
    double noise2 = nc >= 16 ? median(p->scratch, nc) / M_LN2 : 0.0;
    double thr2 = fmax(9.0 * noise2, 1e-12 * amax);
    f->m = f->nall = 0;
    for (int pass = 0; pass < 2; pass++) {
        for (int j = 0; j < h; j++) {
            if (h % 2 == 0 && j == h / 2)
                continue;
            for (int i = 0; i < nx; i++) {
                if ((w % 2 == 0 && i == w / 2) || (i == 0 && sfreq(j, h) <= 0))
                    continue;
                double complex v = p->spec[(size_t)j * nx + i];
                double a = cabs(v);
                if ((a * a > thr2 && a > 0) != (pass == 0))
                    continue;
                f->bi[f->nall] = i;
                f->bj[f->nall] = j;
                f->bs[f->nall] = v;
                f->bmag[f->nall] = a;
                f->nall++;
            }
        }
        if (pass == 0)
            f->m = f->nall;
    }
    return noise2;
}

/* Sub-pixel offset of a peak at integer (x, y) of a periodic w x h image:
 * a parabola through each axis' three samples. */
static void parabolic(const double *v, int w, int h, int x, int y,
                      double *ox, double *oy)
{
    double c = v[(size_t)y * w + x];
    double l = v[(size_t)y * w + (x + w - 1) % w];
    double r = v[(size_t)y * w + (x + 1) % w];
    double d = v[(size_t)((y + h - 1) % h) * w + x];
    double u = v[(size_t)((y + 1) % h) * w + x];
    double cx = l - 2 * c + r, cy = d - 2 * c + u;
    *ox = cx < 0 ? fmax(-0.5, fmin(0.5, 0.5 * (l - r) / cx)) : 0.0;
    *oy = cy < 0 ? fmax(-0.5, fmin(0.5, 0.5 * (d - u) / cy)) : 0.0;
}

typedef struct cand {
    double x, y, v; /* position (px) and peak value above the background */
} cand;

/* The NCAND largest 8-neighbour local maxima of the periodic image v that
 * lie farther than rmin from (cx, cy) (periodic distance), appended to c
 * (n in/out) unless within 1.5 px of one already there. */
static void find_maxima(const double *v, int w, int h, double cx, double cy,
                        double rmin, cand *c, int *n)
{
    cand best[NCAND];
    int nb = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double val = v[(size_t)y * w + x];
            if (nb == NCAND && val <= best[NCAND - 1].v)
                continue;
            double ddx = remainder(x - cx, w), ddy = remainder(y - cy, h);
            if (hypot(ddx, ddy) <= rmin)
                continue;
            int ismax = 1;
            for (int j = -1; j <= 1 && ismax; j++)
                for (int i = -1; i <= 1; i++)
                    if ((i || j) && v[(size_t)((y + j + h) % h) * w +
                                      (x + i + w) % w] > val) {
                        ismax = 0;
                        break;
                    }
            if (!ismax)
                continue;
            int k = nb < NCAND ? nb++ : NCAND - 1;
            while (k > 0 && best[k - 1].v < val) {
                best[k] = best[k - 1];
                k--;
            }
            double ox, oy;
            parabolic(v, w, h, x, y, &ox, &oy);
            best[k] = (cand){x + ox, y + oy, val};
        }
    for (int k = 0; k < nb; k++) {
        int dup = 0;
        for (int q = 0; q < *n && !dup; q++)
            dup = hypot(remainder(c[q].x - best[k].x, w),
                        remainder(c[q].y - best[k].y, h)) < 1.5;
        if (!dup)
            c[(*n)++] = best[k];
    }
}

/* p->anti = I(x1 + x) - I(x1 - x) (x1 fractional), from the spectrum:
 * its transform is 2i Im(I(u) e^{i k.x1}); scaled to image units. */
static void antisymmetric(binary_plan *p, double x1, double y1)
{
    int w = p->w, h = p->h, nx = p->nx;
    double complex *ex = p->f.e1x, *ey = p->f.e1y;
    for (int i = 0; i < nx; i++)
        ex[i] = cexp(I * p->f.kx[i] * x1);
    for (int j = 0; j < h; j++)
        ey[j] = cexp(I * p->f.ky[j] * y1);
    double sc = 1.0 / ((double)w * h);
    for (int j = 0; j < h; j++)
        for (int i = 0; i < nx; i++) {
            size_t k = (size_t)j * nx + i;
            int nyq = (w % 2 == 0 && i == w / 2) || (h % 2 == 0 && j == h / 2);
            double im = cimag(p->spec[k] * ex[i] * ey[j]);
            p->work[k] = nyq ? 0 : 2.0 * I * im * sc;
        }
    fftw_execute(p->inv);
}

/* The companion among the candidates: each gets a short fit from (x1,
 * candidate, peak ratio); fits that fall into the core are dropped.  The
 * brightest raw maximum's fit is kept unless another candidate's excess
 * cost over the noise floor is lower by more than 10%.  Brightness is the
 * more robust test on poor reconstructions, where artefacts everywhere
 * give every candidate about the same cost (measured: 0.96 of the
 * brightest's for a wrong one); the cost is what sees past sidelobes
 * brighter than the companion (17-hole mask, dm > 1.8: the companion's
 * fit costs 0.55 of the sidelobe's on noiseless and 1000-photon direct
 * reconstructions, and ~1e-12 of it on a cophased image).  Returns the
 * cost, INFINITY when every fit merged into the core. */
static double choose(binary_plan *p, const cand *c, int nc, int nraw,
                     double x1, double y1, double peak, int rc,
                     double floor_cost, double *best)
{
    int w = p->w, h = p->h;
    double bcost = INFINITY, first[NPAR], fcost = INFINITY;
    for (int k = 0; k < nc; k++) {
        double r0 = fmax(1e-3, fmin(1.0, c[k].v / peak));
        double th[NPAR] = {x1, y1, remainder(c[k].x - x1, w),
                           remainder(c[k].y - y1, h), log(r0)};
        double cost = binary_fit_lm(&p->f, th, CAND_ITERS);
        if (hypot(remainder(th[2], w), remainder(th[3], h)) <= rc + 1)
            continue; /* merged into the core: not a companion */
        if (k < nraw && !isfinite(fcost)) {
            fcost = cost;
            memcpy(first, th, sizeof first);
        }
        if (cost < bcost) {
            bcost = cost;
            memcpy(best, th, sizeof first);
        }
    }
    if (isfinite(fcost) && bcost - floor_cost > 0.9 * (fcost - floor_cost)) {
        bcost = fcost;
        memcpy(best, first, sizeof first);
    }
    return bcost;
}

/* The covariance of th when the residuals are correlated between
 * frequencies.  binary_fit_cov's s^2 (J^T J)^-1 treats the m kept
 * frequencies as independent: right for white noise, not for a
 * reconstruction's artefacts, which sit in a few hundred pixels around the
 * object (the mask's sidelobes turned asymmetric by phase errors) and so
 * are correlated over the whole spectrum.  Model: the residual image r(x)
 * (data less the projected model, transformed back) estimates a field
 * of independent pixels with local power S(x) (below); then J^T Sigma J =
 * 1/4 sum_x S(x) j_a(x) j_b(x), j_a the image of parameter a's
 * perturbation (c2r of f->perp), and C = A^-1 (J^T Sigma J) A^-1
 * (binary_fit_sandwich).  For
 * white noise this is s^2 A^-1 again; where the artefacts sit far from
 * both stars they hardly count (measured in binary.h, Uncertainties).
 * 0 and C untouched when A is singular.
 * Cost: NPAR + 1 inverse FFTs of w x h and NPAR (NPAR + 1) / 2 w h
 * multiply-adds. */
static int residual_cov(binary_plan *p, const double *th, double *C)
{
    binary_fit *f = &p->f;
    size_t nh = (size_t)p->h * p->nx, n = (size_t)p->w * p->h;
    memset(p->work, 0, nh * sizeof *p->work);
    for (int q = 0; q < f->m; q++)
        p->work[(size_t)f->bj[q] * p->nx + f->bi[q]] = f->bs[q] - f->bmod[q];
    fftw_execute(p->inv);
    for (size_t i = 0; i < n; i++)
        p->rimg[i] = p->anti[i] * p->anti[i] / ((double)n * n);
    binary_fit_perp(f, th);
    for (int a = 0; a < NPAR; a++) {
        memset(p->work, 0, nh * sizeof *p->work);
        for (int q = 0; q < f->m; q++)
            p->work[(size_t)f->bj[q] * p->nx + f->bi[q]] = f->perp[(size_t)q * NPAR + a];
        fftw_execute(p->inv);
        memcpy(p->jimg + (size_t)a * n, p->anti, n * sizeof *p->anti);
    }
    /* r(x)^2 estimates the local power of the residual's part that lies
     * on the kept frequencies (a fraction fk = 2 m / (w h) of the half
     * plane) and perpendicular to the model (half of it), so the field's
     * own power is 2 r^2 / fk; J^T Sigma J = 1/4 sum_x (that) j_a j_b. */
    double norm = 0.25 * 2.0 / (2.0 * f->m / (double)n), M[NPAR * NPAR];
    for (int a = 0; a < NPAR; a++)
        for (int b = 0; b <= a; b++) {
            const double *ja = p->jimg + (size_t)a * n, *jb = p->jimg + (size_t)b * n;
            double s = 0;
            for (size_t i = 0; i < n; i++)
                s += p->rimg[i] * ja[i] * jb[i];
            M[a * NPAR + b] = M[b * NPAR + a] = norm * s;
        }
    return binary_fit_sandwich(f, th, M, C);
}

/* Fill out's geometry from the companion offset d, the midpoint (cx, cy)
 * and d's covariance cd (xx, xy, yy). */
static void state(binary_result *out, const double d[2], double cx,
                  double cy, const double cd[3], int w, int h)
{
    out->x1_px = cx - 0.5 * d[0];
    out->y1_px = cy - 0.5 * d[1];
    out->x1_px -= w * floor(out->x1_px / w);
    out->y1_px -= h * floor(out->y1_px / h);
    out->dx_px = d[0];
    out->dy_px = d[1];
    out->x2_px = out->x1_px + d[0];
    out->y2_px = out->y1_px + d[1];
    out->sep_px = hypot(d[0], d[1]);
    double pa = atan2(-d[0], d[1]) * 180.0 / M_PI;
    out->pa_deg = pa < 0 ? pa + 360.0 : pa;
    double ex = d[0] / out->sep_px, ey = d[1] / out->sep_px;
    out->sep_err_px =
        sqrt(fmax(0, ex * ex * cd[0] + 2 * ex * ey * cd[1] + ey * ey * cd[2]));
    out->pa_err_deg =
        sqrt(fmax(0, ey * ey * cd[0] - 2 * ex * ey * cd[1] + ex * ex * cd[2])) /
        out->sep_px * 180.0 / M_PI;
}

/* The image less its median in p->img, the brightest pixel's
 * interpolated position and the core radius, the spectrum's kept
 * frequencies; SL_EDATA when no signal. */
typedef struct primary {
    double bg, peak, x1, y1, noise2;
    int rc;
} primary;

static int find_primary(binary_plan *p, const float *img, primary *q)
{
    int w = p->w, h = p->h;
    size_t n = (size_t)w * h;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(img[i]))
            return sl_seterr(&p->err, SL_EDATA,
                             "binary_measure: pixel (%zu, %zu) is not finite",
                             i % (size_t)w, i / (size_t)w);
    memcpy(p->scratch, img, n * sizeof *img);
    q->bg = median(p->scratch, n);
    size_t i1 = 0;
    for (size_t i = 0; i < n; i++) {
        p->img[i] = img[i] - q->bg;
        if (img[i] > img[i1])
            i1 = i;
    }
    int cx = (int)(i1 % (size_t)w), cy = (int)(i1 / (size_t)w);
    q->rc = core_radius(p->img, w, h, cx, cy);
    double ox, oy;
    q->peak = p->img[i1];
    parabolic(p->img, w, h, cx, cy, &ox, &oy);
    q->x1 = cx + ox, q->y1 = cy + oy;
    fftw_execute(p->fwd);
    q->noise2 = select_freqs(p);
    if (p->f.m < 4 * NPAR || !(q->peak > 0))
        return sl_seterr(&p->err, SL_EDATA, "binary_measure: no signal above the noise");
    return SL_OK;
}

/* Candidates (the image's maxima and the antisymmetric part's), the best
 * one fitted to convergence with the fainter as companion: th, cost. */
static int fit_companion(binary_plan *p, const primary *q, double th[NPAR],
                         double *cost)
{
    int w = p->w, h = p->h;
    binary_fit *f = &p->f;
    cand c[2 * NCAND];
    int nc = 0;
    find_maxima(p->img, w, h, q->x1, q->y1, q->rc, c, &nc);
    int nraw = nc;
    antisymmetric(p, q->x1, q->y1);
    find_maxima(p->anti, w, h, 0, 0, q->rc, c, &nc);
    for (int k = nraw; k < nc; k++) { /* offsets -> positions */
        c[k].x = q->x1 + remainder(c[k].x, w);
        c[k].y = q->y1 + remainder(c[k].y, h);
    }
    memset(th, 0, NPAR * sizeof *th);
    f->odd = 0;
    if (!isfinite(choose(p, c, nc, nraw, q->x1, q->y1, q->peak, q->rc,
                         0.5 * q->noise2 * f->m, th)))
        return sl_seterr(&p->err, SL_EDATA, "binary_measure: no second "
                         "component beyond the core (%d px)", q->rc);
    f->odd = 1;
    *cost = binary_fit_lm(f, th, FINAL_ITERS);
    if (th[4] > 0) { /* state it with the fainter as the companion */
        th[0] += th[2];
        th[1] += th[3];
        th[2] = -th[2];
        th[3] = -th[3];
        th[4] = -th[4];
    }
    return SL_OK;
}

/* d: the fit's, or the interpolated peaks' (all frequencies), whichever
 * has the smaller expected squared error: the fit's covariance trace
 * against the peaks' noise plus their squared bias, the bias being the
 * projected model's peaks less its true (the fitted) positions.  At r ~ 1
 * the fit has no d and its model no meaningful bias: peaks, noise only.
 * d and cd (its covariance xx, xy, yy) in, replaced when the peaks win. */
static int choose_d(binary_plan *p, const primary *q, const double th[NPAR],
                    double cost, int ambiguous, double d[2], double cd[3])
{
    binary_fit *f = &p->f;
    double s1[2] = {th[0], th[1]}, H1[3], c1[3];
    double s2[2] = {th[0] + d[0], th[1] + d[1]}, H2[3], c2[3], Hm[3];
    double m1[2] = {s1[0], s1[1]}, m2[2] = {s2[0], s2[1]};
    binary_fit_peak(f, f->bs, f->nall, s1, H1);
    binary_fit_peak(f, f->bs, f->nall, s2, H2);
    binary_fit_project(f, th);
    binary_fit_peak(f, f->bmod, f->m, m1, Hm);
    binary_fit_peak(f, f->bmod, f->m, m2, Hm);
    double var_i = fmax(q->noise2, f->m > NPAR ? 2 * cost / (f->m - NPAR) : 0);
    binary_fit_peak_cov(f, f->nall, H1, var_i, c1);
    binary_fit_peak_cov(f, f->nall, H2, var_i, c2);
    double bx = (m2[0] - m1[0]) - d[0], by = (m2[1] - m1[1]) - d[1];
    double pk[3] = {c1[0] + c2[0], c1[1] + c2[1], c1[2] + c2[2]};
    double dp[2] = {s2[0] - s1[0], s2[1] - s1[1]};
    if (!ambiguous) {
        pk[0] += bx * bx;
        pk[1] += bx * by;
        pk[2] += by * by;
    }
    if (hypot(dp[0], dp[1]) > q->rc + 1 &&
        (ambiguous || !(cd[0] + cd[2] <= pk[0] + pk[2]))) {
        memcpy(d, dp, 2 * sizeof *d);
        memcpy(cd, pk, 3 * sizeof *cd);
        return 1;
    }
    return 0;
}

int binary_plan_measure(binary_plan *p, const float *img, binary_result *out)
{
    if (!p || !img || !out)
        return sl_seterr(p ? &p->err : NULL, SL_EINVAL,
                         "binary_measure: NULL argument");
    int w = p->w, h = p->h, rc;
    binary_fit *f = &p->f;
    memset(out, 0, sizeof *out);
    primary q = {0};
    double th[NPAR] = {0}, cost = 0;
    if ((rc = find_primary(p, img, &q)) != SL_OK || (rc = fit_companion(p, &q, th, &cost)) != SL_OK)
        return rc;
    double C[NPAR * NPAR];
    binary_fit_cov(f, th, C);
    double r = exp(th[4]), sr = r * sqrt(C[4 * NPAR + 4]);
    out->pa_ambiguous = !(1.0 - r > fmax(2.0 * sr, 1e-6));
    /* The model is periodic (frequencies j / w): d and d + (w, 0) are one
     * fit, and only the principal offset is a separation. */
    double d[2] = {remainder(th[2], w), remainder(th[3], h)};
    double cd[3] = {C[2 * NPAR + 2], C[2 * NPAR + 3], C[3 * NPAR + 3]};
    double mx = th[0] + 0.5 * d[0], my = th[1] + 0.5 * d[1];
    out->d_from_peaks = choose_d(p, &q, th, cost, out->pa_ambiguous, d, cd);
    /* The stated errors take the residuals' correlation (residual_cov),
     * never below the white-noise ones; the choices above (ambiguity, d's
     * source) and the significance test below keep the white-noise ones,
     * so the measurement itself does not change. */
    double Cs[NPAR * NPAR], kd = 1, kr = 1;
    if (residual_cov(p, th, Cs)) {
        double tw = C[2 * NPAR + 2] + C[3 * NPAR + 3], ts = Cs[2 * NPAR + 2] + Cs[3 * NPAR + 3];
        kd = tw > 0 && ts > tw ? ts / tw : 1;
        kr = C[4 * NPAR + 4] > 0 && Cs[4 * NPAR + 4] > C[4 * NPAR + 4]
                 ? Cs[4 * NPAR + 4] / C[4 * NPAR + 4] : 1;
    }
    double cdk[3] = {cd[0] * kd, cd[1] * kd, cd[2] * kd};
    state(out, d, mx, my, cdk, w, h);
    out->flux_ratio = r;
    out->dm_mag = -2.5 * log10(r);
    out->flux_ratio_err = sr * sqrt(kr);
    out->dm_err_mag = 2.5 / M_LN10 * sqrt(C[4 * NPAR + 4] * kr);
    out->err_inflation = kd;
    out->background = q.bg;
    out->core_radius_px = q.rc;
    out->noise = sqrt(q.noise2 / ((double)w * h));
    out->nfreq = f->m;
    out->fit_rms = q.noise2 > 0 ? sqrt(cost / f->m / (0.5 * q.noise2)) : NAN;
    if (out->sep_px <= q.rc + 1)   /* the fit walked into the core */
        return sl_seterr(&p->err, SL_EDATA, "binary_measure: the companion "
                         "converged into the core (%.1f px, core %d px)", out->sep_px, q.rc);
    if (r < 1e-4 || r < 3.0 * sr)   /* sr: the uninflated error */
        return sl_seterr(&p->err, SL_EDATA, "binary_measure: no significant "
                         "companion (flux ratio %.3g +- %.2g)", r, sr);
    return SL_OK;
}

int binary_measure(const float *img, int w, int h, binary_result *out,
                   sl_err *err)
{
    binary_plan *p = binary_plan_new(w, h, err);
    if (!p)
        return err ? err->code : SL_ENOMEM;
    int rc = binary_plan_measure(p, img, out);
    if (rc != SL_OK)
        sl_seterr(err, rc, "%s", p->err.msg);
    binary_plan_free(p);
    return rc;
}
