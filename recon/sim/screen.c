/* screen.c - see screen.h. */
#include "screen.h"

#include <fftw3.h>
#include <math.h>
#include <stdlib.h>

#include "base/rng.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* Gamma(11/6)^2 / (2 pi^(11/3)) * (24/5 Gamma(6/5))^(5/6): with it,
 * 2 int Phi (1 - cos 2 pi f.r) d^2f = 6.8838771823 (r/r0)^(5/3). */
#define KOLMO_C 0.0228955871

/* rng stream ids ("SCRNFFT", "SCRNSHA", "SCRNSHB"), distinct from other
 * modules' so that the screen does not change when they draw more. */
#define STREAM_FFT 0x5343524e464654ULL
#define STREAM_TERMS_A 0x5343524e534841ULL
#define STREAM_TERMS_B 0x5343524e534842ULL

/* Snapping tolerances of screen_sample (see screen.h). */
#define SNAP_PX 1e-6
#define SNAP_PITCH 1e-12
/* Largest |coordinate| in pixels: beyond it a double cannot resolve the
 * bilinear fraction to better than 1e-3 pixel. */
#define MAX_COORD_PX 4e12

struct screen {
    int n;
    double dx_m;
    float *grid;      /* n*n periodic part, rad, grid[y*n + x] */
    int nterms;       /* analytic sinusoids */
    double *nu_x;     /* frequencies, cycles per pixel; one block of 4 */
    double *nu_y;
    double *a_re;     /* complex amplitudes, rad: term = Re(a e^{i2pi nu.u}) */
    double *a_im;
    double tilt_x;    /* rad per pixel */
    double tilt_y;
    double piston;    /* analytic part's mean over the base window, rad */
};

/* 8-point Gauss-Legendre on [-1, 1]: nodes +-GL_X[i], weights GL_W[i]. */
static const double GL_X[4] = {0.1834346424956498, 0.5255324099163290,
                               0.7966664774136267, 0.9602898564975363};
static const double GL_W[4] = {0.3626837833783620, 0.3137066458778873,
                               0.2223810344533745, 0.1012285362903763};

/* Phase spectrum model: k (f^2 + a2)^(-11/6), k = KOLMO_C r0^(-5/3),
 * a2 = 1/L0^2 (0 for Kolmogorov). */
typedef struct psd_model {
    double k;
    double a2;
} psd_model;

static double psd(const psd_model *m, double fx, double fy)
{
    return m->k * pow(fx * fx + fy * fy + m->a2, -11.0 / 6.0);
}

/* 16-point composite Gauss-Legendre nodes/weights on [lo, hi] (2 panels):
 * applied per axis to a cell whose nearest singularity (f = 0, or +-i a in
 * the other axis) is at least half a cell width away, the error is below
 * 1e-9 relative. */
static void gl16(double lo, double hi, double *x, double *w)
{
    double half = 0.25 * (hi - lo);
    for (int p = 0; p < 2; p++) {
        double mid = lo + half * (2 * p + 1);
        for (int i = 0; i < 4; i++) {
            x[p * 8 + 2 * i] = mid - half * GL_X[i];
            x[p * 8 + 2 * i + 1] = mid + half * GL_X[i];
            w[p * 8 + 2 * i] = w[p * 8 + 2 * i + 1] = half * GL_W[i];
        }
    }
}

/* int Phi d^2f over the square cell centred at (cx, cy) of width d. */
static double cell_power(const psd_model *m, double cx, double cy, double d)
{
    double xs[16], wx[16], ys[16], wy[16], sum = 0;
    gl16(cx - 0.5 * d, cx + 0.5 * d, xs, wx);
    gl16(cy - 0.5 * d, cy + 0.5 * d, ys, wy);
    for (int i = 0; i < 16; i++)
        for (int j = 0; j < 16; j++)
            sum += wx[i] * wy[j] * psd(m, xs[i], ys[j]);
    return sum;
}

static double clampd(double v, double lo, double hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}

/* A frequency in the cell with density ~ Phi, by rejection from the
 * uniform density (Phi is largest at the cell point nearest f = 0).  For
 * the ring cells Phi varies at most ~70x, so ~10 proposals on average; the
 * cap only guards against a pathological model. */
static void draw_in_cell(const psd_model *m, rng *r, double cx, double cy,
                         double d, double *fx, double *fy)
{
    double nx = clampd(0, cx - 0.5 * d, cx + 0.5 * d);
    double ny = clampd(0, cy - 0.5 * d, cy + 0.5 * d);
    double pmax = psd(m, nx, ny);
    for (int tries = 0; tries < 100000; tries++) {
        *fx = cx + (rng_uniform(r) - 0.5) * d;
        *fy = cy + (rng_uniform(r) - 0.5) * d;
        if (rng_uniform(r) * pmax <= psd(m, *fx, *fy))
            return;
    }
    *fx = cx;
    *fy = cy;
}

/* int_0^rho (t^2 + a2)^(-11/6) t^3 dt, closed form; the series for
 * rho^2 << a2 avoids cancelling 3 s^(1/6) against 3.6 a^(1/3). */
static double radial_tilt_integral(double rho, double a2)
{
    double q = rho * rho / a2; /* inf for a2 = 0 */
    if (q < 1e-3)
        return pow(a2, -11.0 / 6.0) * pow(rho, 4) *
               (0.25 - 11.0 / 36.0 * q);
    double s = rho * rho + a2;
    return 3 * pow(s, 1.0 / 6.0) + 0.6 * a2 * pow(s, -5.0 / 6.0) -
           3.6 * pow(a2, 1.0 / 6.0);
}

/* Variance (rad^2/m^2) of each tilt component standing for the square
 * |fx|, |fy| <= eps: 4 pi^2 int Phi fx^2 d^2f.  By the square's symmetry
 * int Phi fx^2 = 1/2 int Phi f^2 = 4 k int_0^{pi/4} G(eps / cos t) dt, with G
 * the radial integral above; 4 panels of 8-point Gauss-Legendre. */
static double tilt_variance(const psd_model *m, double eps)
{
    double sum = 0, lo = 0, pw = M_PI / 16; /* panel width */
    for (int p = 0; p < 4; p++, lo += pw)
        for (int i = 0; i < 4; i++)
            for (int sgn = -1; sgn <= 1; sgn += 2) {
                double t = lo + 0.5 * pw * (1 + sgn * GL_X[i]);
                sum += 0.5 * pw * GL_W[i] *
                       radial_tilt_integral(eps / cos(t), m->a2);
            }
    return 4 * M_PI * M_PI * 4 * m->k * sum;
}

/* Mean of e^{i 2 pi nu j} over j = 0..n-1 (Dirichlet kernel). */
static void window_mean(double nu, int n, double *re, double *im)
{
    double s1 = sin(M_PI * nu);
    double amp = fabs(s1) < 1e-300 ? 1.0 : sin(M_PI * nu * n) / (n * s1);
    *re = amp * cos(M_PI * nu * (n - 1));
    *im = amp * sin(M_PI * nu * (n - 1));
}

/* The analytic part: level 0 (the 8 lattice cells of width df around
 * f = 0) and levels 1..P (width df/3^p), each cell one term of exact power
 * at a frequency drawn within it, then the tilt for the last centre cell,
 * then the piston over the base window.  Fails only on allocation. */
static int make_terms(screen *s, const screen_opts *o, const psd_model *m,
                      uint64_t stream, sl_err *err)
{
    int levels = o->subharmonic_levels;
    s->nterms = levels > 0 ? 8 * (levels + 1) : 0;
    if (!s->nterms)
        return SL_OK;
    s->nu_x = malloc(sizeof(double) * 4 * (size_t)s->nterms);
    if (!s->nu_x)
        return sl_seterr(err, SL_ENOMEM, "screen: no memory for %d terms",
                         s->nterms);
    s->nu_y = s->nu_x + s->nterms;
    s->a_re = s->nu_y + s->nterms;
    s->a_im = s->a_re + s->nterms;

    rng r;
    rng_init(&r, o->seed, stream);
    double d = 1.0 / (o->n * o->dx_m); /* cell width, cycles/m */
    int t = 0;
    for (int p = 0; p <= levels; p++, d /= 3)
        for (int j = -1; j <= 1; j++)
            for (int i = -1; i <= 1; i++) {
                if (!i && !j)
                    continue;
                double fx, fy, amp = sqrt(cell_power(m, i * d, j * d, d));
                draw_in_cell(m, &r, i * d, j * d, d, &fx, &fy);
                s->nu_x[t] = fx * o->dx_m;
                s->nu_y[t] = fy * o->dx_m;
                /* Re(c amp e^{i theta}), c = N + iN: variance amp^2 */
                s->a_re[t] = amp * rng_normal(&r);
                s->a_im[t] = amp * rng_normal(&r);
                t++;
            }
    /* d is now df/3^(levels+1): the last centre cell has half-width 1.5 d */
    double sig_px = sqrt(tilt_variance(m, 1.5 * d)) * o->dx_m;
    s->tilt_x = sig_px * rng_normal(&r);
    s->tilt_y = sig_px * rng_normal(&r);

    double pist = 0.5 * (o->n - 1) * (s->tilt_x + s->tilt_y);
    for (t = 0; t < s->nterms; t++) {
        double xr, xi, yr, yi;
        window_mean(s->nu_x[t], o->n, &xr, &xi);
        window_mean(s->nu_y[t], o->n, &yr, &yi);
        double mr = xr * yr - xi * yi, mi = xr * yi + xi * yr;
        pist += s->a_re[t] * mr - s->a_im[t] * mi;
    }
    s->piston = pist;
    return SL_OK;
}

static int check_opts(const screen_opts *o, sl_err *err)
{
    if (!o)
        return sl_seterr(err, SL_EINVAL, "screen: NULL options");
    if (o->n < SCREEN_MIN_N || o->n > SCREEN_MAX_N)
        return sl_seterr(err, SL_EINVAL, "screen: n = %d outside [%d, %d]",
                         o->n, SCREEN_MIN_N, SCREEN_MAX_N);
    if (!isfinite(o->dx_m) || o->dx_m <= 0)
        return sl_seterr(err, SL_EINVAL, "screen: dx_m = %g is not > 0",
                         o->dx_m);
    if (!isfinite(o->r0_m) || o->r0_m <= 0)
        return sl_seterr(err, SL_EINVAL, "screen: r0_m = %g is not > 0",
                         o->r0_m);
    if (isnan(o->L0_m))
        return sl_seterr(err, SL_EINVAL, "screen: L0_m is NaN");
    if (o->subharmonic_levels < 0 ||
        o->subharmonic_levels > SCREEN_MAX_LEVELS)
        return sl_seterr(err, SL_EINVAL,
                         "screen: subharmonic_levels = %d outside [0, %d]",
                         o->subharmonic_levels, SCREEN_MAX_LEVELS);
    return SL_OK;
}

static screen *alloc_screen(const screen_opts *o)
{
    screen *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->grid = malloc(sizeof(float) * (size_t)o->n * (size_t)o->n);
    if (!s->grid) {
        free(s);
        return NULL;
    }
    s->n = o->n;
    s->dx_m = o->dx_m;
    return s;
}

/* Fill buf with complex noise times sqrt(Phi) df on the lattice, zero at
 * the cells the analytic part holds.  The noise is drawn for every cell in
 * a fixed order, so the lattice values do not depend on which cells are
 * zeroed. */
static void fill_spectrum(fftw_complex *buf, const screen_opts *o,
                          const psd_model *m)
{
    int n = o->n, hole = o->subharmonic_levels > 0 ? 1 : 0;
    double df = 1.0 / (n * o->dx_m);
    rng r;
    rng_init(&r, o->seed, STREAM_FFT);
    for (int iy = 0; iy < n; iy++) {
        int ky = iy < (n + 1) / 2 ? iy : iy - n;
        for (int ix = 0; ix < n; ix++) {
            int kx = ix < (n + 1) / 2 ? ix : ix - n;
            double nr = rng_normal(&r), ni = rng_normal(&r);
            fftw_complex *c = &buf[(size_t)iy * n + ix];
            if (abs(kx) <= hole && abs(ky) <= hole) {
                (*c)[0] = (*c)[1] = 0;
                continue;
            }
            double amp = sqrt(psd(m, kx * df, ky * df)) * df;
            (*c)[0] = amp * nr;
            (*c)[1] = amp * ni;
        }
    }
}

static int generate(screen **a, screen **b, const screen_opts *o,
                    sl_err *err)
{
    int rc = check_opts(o, err);
    *a = NULL;
    if (b)
        *b = NULL;
    if (rc != SL_OK)
        return rc;
    psd_model m = {KOLMO_C * pow(o->r0_m, -5.0 / 3.0), 0};
    if (isfinite(o->L0_m) && o->L0_m > 0)
        m.a2 = 1.0 / (o->L0_m * o->L0_m);

    size_t nn = (size_t)o->n * (size_t)o->n;
    screen *sa = NULL, *sb = NULL;
    fftw_plan plan = NULL;
    fftw_complex *buf = fftw_malloc(sizeof(fftw_complex) * nn);
    if (!buf) {
        rc = sl_seterr(err, SL_ENOMEM, "screen: no memory for a %d^2 FFT",
                       o->n);
        goto done;
    }
    plan = fftw_plan_dft_2d(o->n, o->n, buf, buf, FFTW_BACKWARD,
                            FFTW_ESTIMATE);
    if (!plan) {
        rc = sl_seterr(err, SL_ENOMEM, "screen: no FFTW plan for %d^2",
                       o->n);
        goto free_buf;
    }
    sa = alloc_screen(o);
    sb = b ? alloc_screen(o) : NULL;
    if (!sa || (b && !sb)) {
        rc = sl_seterr(err, SL_ENOMEM, "screen: no memory for a %d^2 grid",
                       o->n);
        goto free_screens;
    }
    fill_spectrum(buf, o, &m);
    /* Unnormalised backward transform: phase(x) = sum_k c_k e^{+i2pi f.x},
     * whose real and imaginary parts are independent screens. */
    fftw_execute(plan);
    for (size_t i = 0; i < nn; i++)
        sa->grid[i] = (float)buf[i][0];
    if (sb)
        for (size_t i = 0; i < nn; i++)
            sb->grid[i] = (float)buf[i][1];
    if ((rc = make_terms(sa, o, &m, STREAM_TERMS_A, err)) != SL_OK ||
        (sb && (rc = make_terms(sb, o, &m, STREAM_TERMS_B, err)) != SL_OK))
        goto free_screens;
    *a = sa;
    if (b)
        *b = sb;
    sa = sb = NULL;
free_screens:
    screen_free(sa);
    screen_free(sb);
    fftw_destroy_plan(plan);
free_buf:
    fftw_free(buf);
done:
    if (rc == SL_OK)
        sl_clearerr(err);
    return rc;
}

void screen_opts_defaults(screen_opts *o)
{
    o->n = 256;
    o->dx_m = 0.02;
    o->r0_m = 0.2;
    o->L0_m = INFINITY;
    o->subharmonic_levels = 3;
    o->seed = 1;
}

int screen_new(screen **out, const screen_opts *o, sl_err *err)
{
    if (!out)
        return sl_seterr(err, SL_EINVAL, "screen_new: NULL out");
    return generate(out, NULL, o, err);
}

int screen_new_pair(screen **a, screen **b, const screen_opts *o,
                    sl_err *err)
{
    if (!a || !b)
        return sl_seterr(err, SL_EINVAL, "screen_new_pair: NULL out");
    return generate(a, b, o, err);
}

void screen_free(screen *s)
{
    if (!s)
        return;
    free(s->grid);
    free(s->nu_x);
    free(s);
}

int screen_n(const screen *s) { return s->n; }
double screen_dx_m(const screen *s) { return s->dx_m; }
int screen_nterms(const screen *s) { return s->nterms; }

/* Per-axis sampling plan: for sample j, the grid cells i0, i1 (wrapped)
 * and the bilinear fraction t, from u_j = u0 + j * step pixels. */
static double axis_coord(double u0, double step, int j)
{
    return step == 1.0 ? u0 + j : u0 + j * step;
}

static void axis_cell(double u, int n, int *i0, int *i1, double *t)
{
    double fl = floor(u);
    long long m = (long long)fl % n;
    if (m < 0)
        m += n;
    *i0 = (int)m;
    *i1 = *i0 + 1 == n ? 0 : *i0 + 1;
    *t = u - fl;
}

static double snap(double u)
{
    double r = nearbyint(u);
    return fabs(u - r) <= SNAP_PX ? r : u;
}

int screen_sample(const screen *s, float *phase_rad, int w, int h,
                  double x0_m, double y0_m, double dx_m)
{
    if (!s || !phase_rad || w < 1 || h < 1 || !isfinite(x0_m) ||
        !isfinite(y0_m) || !isfinite(dx_m) || dx_m <= 0)
        return SL_EINVAL;
    double step = dx_m / s->dx_m;
    if (fabs(step - 1) <= SNAP_PITCH)
        step = 1;
    double u0 = snap(x0_m / s->dx_m), v0 = snap(y0_m / s->dx_m);
    if (fabs(u0) + w * step > MAX_COORD_PX ||
        fabs(v0) + h * step > MAX_COORD_PX)
        return SL_ERANGE;

    /* Scratch, one block: per column the two grid cells and fraction, the
     * tilt, and each term's phasor; per row the accumulator.  Allocated per
     * call (O((w + h) terms), small next to the O(w h terms) work) because
     * the screen is const and may be shared between threads. */
    int nt = s->nterms, n = s->n;
    size_t W = (size_t)w, per_col = 2 * (size_t)nt + 3;
    double *blk = malloc(sizeof(double) * W * per_col + sizeof(int) * 2 * W);
    if (!blk)
        return SL_ENOMEM;
    double *acc = blk, *ctx = acc + W, *ctilt = ctx + W;
    double *pre = ctilt + W, *pim = pre + W * (size_t)nt;
    int *ci0 = (int *)(pim + W * (size_t)nt), *ci1 = ci0 + W;

    for (int j = 0; j < w; j++) {
        double u = axis_coord(u0, step, j);
        axis_cell(u, n, &ci0[j], &ci1[j], &ctx[j]);
        ctilt[j] = s->tilt_x * u;
        for (int t = 0; t < nt; t++) {
            double ph = 2 * M_PI * s->nu_x[t] * u;
            pre[(size_t)t * W + j] = cos(ph);
            pim[(size_t)t * W + j] = sin(ph);
        }
    }
    for (int y = 0; y < h; y++) {
        double v = axis_coord(v0, step, y), ty;
        int r0, r1;
        axis_cell(v, n, &r0, &r1, &ty);
        const float *g0 = s->grid + (size_t)r0 * n;
        const float *g1 = s->grid + (size_t)r1 * n;
        /* At integer positions t = 0 and each line reduces exactly to the
         * grid value: (1 - 0) * a + 0 * b == a. */
        for (int j = 0; j < w; j++) {
            double tx = ctx[j];
            double top = (1 - tx) * g0[ci0[j]] + tx * g0[ci1[j]];
            double bot = (1 - tx) * g1[ci0[j]] + tx * g1[ci1[j]];
            acc[j] = (1 - ty) * top + ty * bot;
        }
        /* Re(a e^{i2pi(nu_x u + nu_y v)}) = Re(b e^{i2pi nu_x u}), b = a
         * e^{i2pi nu_y v}: one complex multiply per pixel and term. */
        for (int t = 0; t < nt; t++) {
            double ph = 2 * M_PI * s->nu_y[t] * v, c = cos(ph), sn = sin(ph);
            double br = s->a_re[t] * c - s->a_im[t] * sn;
            double bi = s->a_re[t] * sn + s->a_im[t] * c;
            const double *xr = pre + (size_t)t * W, *xi = pim + (size_t)t * W;
            for (int j = 0; j < w; j++)
                acc[j] += br * xr[j] - bi * xi[j];
        }
        double rowc = s->tilt_y * v - s->piston;
        float *out = phase_rad + (size_t)y * W;
        for (int j = 0; j < w; j++)
            out[j] = (float)(acc[j] + ctilt[j] + rowc);
    }
    free(blk);
    return SL_OK;
}
