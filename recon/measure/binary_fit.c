/* binary_fit.c - see binary_fit.h (and binary.h for the model). */
#include "binary_fit.h"

#include "status.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NPAR BINARY_FIT_NPAR

static int sfreq(int i, int n) { return i <= (n - 1) / 2 ? i : i - n; }

int binary_fit_init(binary_fit *f, int w, int h)
{
    memset(f, 0, sizeof *f);
    size_t nh = (size_t)h * (size_t)(w / 2 + 1);
    f->w = w;
    f->h = h;
    f->nx = w / 2 + 1;
    f->bi = malloc(nh * sizeof *f->bi);
    f->bj = malloc(nh * sizeof *f->bj);
    f->bs = malloc(nh * sizeof *f->bs);
    f->bmod = malloc(nh * sizeof *f->bmod);
    f->bmag = malloc(nh * sizeof *f->bmag);
    f->perp = malloc(nh * NPAR * sizeof *f->perp);
    f->kx = malloc((size_t)f->nx * sizeof *f->kx);
    f->ky = malloc((size_t)h * sizeof *f->ky);
    f->e1x = malloc((size_t)f->nx * sizeof *f->e1x);
    f->edx = malloc((size_t)f->nx * sizeof *f->edx);
    f->e1y = malloc((size_t)h * sizeof *f->e1y);
    f->edy = malloc((size_t)h * sizeof *f->edy);
    if (!f->bi || !f->bj || !f->bs || !f->bmod || !f->bmag || !f->perp || !f->kx ||
        !f->ky || !f->e1x || !f->edx || !f->e1y || !f->edy) {
        binary_fit_clear(f);
        return SL_ENOMEM;
    }
    for (int i = 0; i < f->nx; i++)
        f->kx[i] = 2.0 * M_PI * i / w;
    for (int j = 0; j < h; j++)
        f->ky[j] = 2.0 * M_PI * sfreq(j, h) / h;
    return SL_OK;
}

void binary_fit_clear(binary_fit *f)
{
    free(f->bi);
    free(f->bj);
    free(f->bs);
    free(f->bmod);
    free(f->bmag);
    free(f->perp);
    free(f->kx);
    free(f->ky);
    free(f->e1x);
    free(f->edx);
    free(f->e1y);
    free(f->edy);
    memset(f, 0, sizeof *f);
}

static void phasors(double complex *e, const double *k, int n, double x)
{
    for (int i = 0; i < n; i++)
        e[i] = cexp(I * k[i] * x);
}

/* The odd cubic basis at column i, row j. */
static void odd_basis(const binary_fit *f, int i, int j, double b[4])
{
    double ux = f->kx[i] / M_PI, uy = f->ky[j] / M_PI;
    b[0] = ux * ux * ux;
    b[1] = ux * ux * uy;
    b[2] = ux * uy * uy;
    b[3] = uy * uy * uy;
}

/* The model's phasor at kept frequency b, up to its real factor F1 P:
 * conj of e^{-i k.x1} g e^{i psi}, so that I times it is real >= 0.
 * Needs the phasors of th set; q gets r e^{ik.d} / (1 + r e^{ik.d}). */
static double complex model_conj(const binary_fit *f, const double *th,
                                 double r, int b, double complex *q,
                                 double bas[4])
{
    int i = f->bi[b], j = f->bj[b];
    double complex ed = f->edx[i] * f->edy[j];
    double complex cg = 1.0 + r * ed;
    /* q = r ed / cg without the library's careful complex division (cg
     * is never near overflow: |cg| <= 1 + r). */
    double cg2 = creal(cg) * creal(cg) + cimag(cg) * cimag(cg);
    *q = cg2 > 0 ? r * ed * conj(cg) / cg2 : 0;
    if (!f->odd) {
        bas[0] = bas[1] = bas[2] = bas[3] = 0;
        return f->e1x[i] * f->e1y[j] * cg;
    }
    odd_basis(f, i, j, bas);
    double psi = th[5] * bas[0] + th[6] * bas[1] + th[7] * bas[2] +
                 th[8] * bas[3];
    return f->e1x[i] * f->e1y[j] * cg * cexp(-I * psi);
}

static void set_phasors(binary_fit *f, const double *th)
{
    phasors(f->e1x, f->kx, f->nx, th[0]);
    phasors(f->e1y, f->ky, f->h, th[1]);
    phasors(f->edx, f->kx, f->nx, th[2]);
    phasors(f->edy, f->ky, f->h, th[3]);
}

/* The residual's Jacobian at kept frequency b: sc = |I| cos(phi/2), q and
 * bas from model_conj (see binary_fit_cost for the derivatives). */
static void jac_row(const binary_fit *f, int b, double sc, double complex q,
                    const double bas[4], double J[NPAR])
{
    double kx = f->kx[f->bi[b]], ky = f->ky[f->bj[b]];
    J[0] = sc * kx, J[1] = sc * ky;
    J[2] = sc * kx * creal(q), J[3] = sc * ky * creal(q), J[4] = sc * cimag(q);
    for (int k = 0; k < 4; k++)
        J[5 + k] = -sc * bas[k];
}

/* Residual 2 |I| sin(phi/2) (phi wrapped to (-pi, pi]; sin(phi/2) from
 * cos(phi) by the half-angle formulas, no atan2).  Derivatives: |I|
 * cos(phi/2) d phi, with d phi/d x1 = k, d phi/d d = k Re q, d phi/d ln r
 * = Im q, d phi/d a_k = -b_k. */
double binary_fit_cost(binary_fit *f, const double *th, double *A,
                       double *g)
{
    set_phasors(f, th);
    double r = exp(th[4]), cost = 0;
    if (A) {
        memset(A, 0, NPAR * NPAR * sizeof *A);
        memset(g, 0, NPAR * sizeof *g);
    }
    for (int b = 0; b < f->m; b++) {
        double complex q;
        double bas[4];
        double complex z = f->bs[b] * model_conj(f, th, r, b, &q, bas);
        double az = sqrt(creal(z) * creal(z) + cimag(z) * cimag(z));
        if (az == 0)
            continue;
        double c = creal(z) / az, mag = f->bmag[b];
        double hs = copysign(sqrt(fmax(0.0, 0.5 * (1.0 - c))), cimag(z));
        double res = 2.0 * mag * hs;
        cost += res * res;
        if (!A)
            continue;
        double J[NPAR];
        jac_row(f, b, mag * sqrt(fmax(0.0, 0.5 * (1.0 + c))), q, bas, J);
        for (int a = 0; a < NPAR; a++) {
            g[a] += J[a] * res;
            for (int e = 0; e <= a; e++)
                A[a * NPAR + e] += J[a] * J[e];
        }
    }
    if (A)
        for (int a = 0; a < NPAR; a++)
            for (int e = a + 1; e < NPAR; e++)
                A[a * NPAR + e] = A[e * NPAR + a];
    return cost;
}

/* Solve the symmetric positive definite n x n M x = b in place by
 * Cholesky (M is overwritten); 0 when M is not positive definite. */
static int chol_solve(double *M, double *x, int n)
{
    for (int j = 0; j < n; j++) {
        double s = M[j * n + j];
        for (int k = 0; k < j; k++)
            s -= M[j * n + k] * M[j * n + k];
        if (!(s > 0))
            return 0;
        M[j * n + j] = sqrt(s);
        for (int i = j + 1; i < n; i++) {
            double t = M[i * n + j];
            for (int k = 0; k < j; k++)
                t -= M[i * n + k] * M[j * n + k];
            M[i * n + j] = t / M[j * n + j];
        }
    }
    for (int i = 0; i < n; i++) {
        for (int k = 0; k < i; k++)
            x[i] -= M[i * n + k] * x[k];
        x[i] /= M[i * n + i];
    }
    for (int i = n - 1; i >= 0; i--) {
        for (int k = i + 1; k < n; k++)
            x[i] -= M[k * n + i] * x[k];
        x[i] /= M[i * n + i];
    }
    return 1;
}

double binary_fit_lm(binary_fit *f, double *th, int maxit)
{
    double A[NPAR * NPAR], g[NPAR], M[NPAR * NPAR], st[NPAR], tt[NPAR];
    double cost = binary_fit_cost(f, th, A, g), lam = 1e-3;
    for (int it = 0; it < maxit && cost > 0; it++) {
        double dmax = 0;
        for (int a = 0; a < NPAR; a++)
            dmax = fmax(dmax, A[a * NPAR + a]);
        memcpy(M, A, sizeof M);
        for (int a = 0; a < NPAR; a++) {
            /* Marquardt's scaling, plus a ridge for parameters that move
             * nothing (d as r -> 0, psi on a tiny band). */
            M[a * NPAR + a] += lam * A[a * NPAR + a] + 1e-12 * dmax;
            st[a] = -g[a];
        }
        if (!chol_solve(M, st, NPAR)) {
            lam *= 10;
            continue;
        }
        double len = 0;
        for (int a = 0; a < NPAR; a++)
            len = fmax(len, fabs(st[a]));
        double sc = len > 0.5 ? 0.5 / len : 1.0;
        for (int a = 0; a < NPAR; a++)
            tt[a] = th[a] + sc * st[a];
        double c2 = binary_fit_cost(f, tt, NULL, NULL);
        if (c2 < cost) {
            double drop = cost - c2;
            memcpy(th, tt, sizeof tt);
            cost = binary_fit_cost(f, th, A, g);
            lam = fmax(lam * 0.1, 1e-12);
            if (sc * len < 1e-10 || drop < 1e-15 * cost)
                break;
        } else if ((lam *= 10) > 1e12) {
            break;
        }
    }
    return cost;
}

void binary_fit_cov(binary_fit *f, const double *th, double *C)
{
    double A[NPAR * NPAR], g[NPAR], M[NPAR * NPAR];
    double cost = binary_fit_cost(f, th, A, g);
    double s2 = f->m > NPAR ? cost / (f->m - NPAR) : INFINITY;
    int singular = 0;
    for (int c = 0; c < NPAR && !singular; c++) {
        double e[NPAR] = {0};
        e[c] = 1;
        memcpy(M, A, sizeof M);
        singular = !chol_solve(M, e, NPAR);
        for (int a = 0; a < NPAR; a++)
            C[a * NPAR + c] = e[a] * s2;
    }
    if (!singular)
        return;
    static const int idx[3] = {0, 1, 4};
    for (int a = 0; a < NPAR * NPAR; a++)
        C[a] = INFINITY;
    for (int c = 0; c < 3; c++) {
        double B[9], e[3] = {0};
        e[c] = 1;
        for (int a = 0; a < 3; a++)
            for (int k = 0; k < 3; k++)
                B[a * 3 + k] = A[idx[a] * NPAR + idx[k]];
        if (!chol_solve(B, e, 3))
            return;
        for (int a = 0; a < 3; a++)
            C[idx[a] * NPAR + idx[c]] = e[a] * s2;
    }
}

double binary_fit_peak(binary_fit *f, const double complex *v, int nv,
                       double s[2], double H[3])
{
    double sc = 2.0 / ((double)f->w * f->h); /* each term and its conjugate */
    double val = 0;
    for (int it = 0; it < 40; it++) {
        phasors(f->e1x, f->kx, f->nx, s[0]);
        phasors(f->e1y, f->ky, f->h, s[1]);
        double v0 = 0, gx = 0, gy = 0, hxx = 0, hxy = 0, hyy = 0;
        for (int b = 0; b < nv; b++) {
            int i = f->bi[b], j = f->bj[b];
            double complex t = v[b] * f->e1x[i] * f->e1y[j];
            double kx = f->kx[i], ky = f->ky[j], re = creal(t), im = cimag(t);
            v0 += re;
            gx -= kx * im;
            gy -= ky * im;
            hxx -= kx * kx * re;
            hxy -= kx * ky * re;
            hyy -= ky * ky * re;
        }
        val = v0 * sc;
        gx *= sc;
        gy *= sc;
        H[0] = hxx * sc;
        H[1] = hxy * sc;
        H[2] = hyy * sc;
        double det = H[0] * H[2] - H[1] * H[1], st[2];
        if (H[0] < 0 && det > 0) {
            st[0] = -(H[2] * gx - H[1] * gy) / det;
            st[1] = -(-H[1] * gx + H[0] * gy) / det;
        } else {
            double gn = hypot(gx, gy);
            if (gn == 0)
                break;
            st[0] = 0.1 * gx / gn;
            st[1] = 0.1 * gy / gn;
        }
        double len = hypot(st[0], st[1]);
        double k = len > 0.5 ? 0.5 / len : 1.0;
        s[0] += k * st[0];
        s[1] += k * st[1];
        if (len < 1e-9)
            break;
    }
    return val;
}

void binary_fit_peak_cov(const binary_fit *f, int nv, const double H[3],
                         double var_i, double cov[3])
{
    double gxx = 0, gxy = 0, gyy = 0;
    for (int b = 0; b < nv; b++) {
        double kx = f->kx[f->bi[b]], ky = f->ky[f->bj[b]];
        gxx += kx * kx;
        gxy += kx * ky;
        gyy += ky * ky;
    }
    double wh = (double)f->w * f->h, sc = 2.0 * var_i / (wh * wh);
    gxx *= sc;
    gxy *= sc;
    gyy *= sc;
    double det = H[0] * H[2] - H[1] * H[1];
    double i0 = H[2] / det, i1 = -H[1] / det, i2 = H[0] / det;
    double a0 = i0 * gxx + i1 * gxy, a1 = i0 * gxy + i1 * gyy;
    double b0 = i1 * gxx + i2 * gxy, b1 = i1 * gxy + i2 * gyy;
    cov[0] = a0 * i0 + a1 * i1;
    cov[1] = a0 * i1 + a1 * i2;
    cov[2] = b0 * i1 + b1 * i2;
}

void binary_fit_project(binary_fit *f, const double *th)
{
    set_phasors(f, th);
    double r = exp(th[4]);
    for (int b = 0; b < f->m; b++) {
        double complex q;
        double bas[4];
        double complex e = model_conj(f, th, r, b, &q, bas);
        double a2 = creal(e) * creal(e) + cimag(e) * cimag(e);
        double re = creal(f->bs[b] * e);
        f->bmod[b] = a2 > 0 && re > 0 ? re / a2 * conj(e) : 0;
    }
}

void binary_fit_perp(binary_fit *f, const double *th)
{
    set_phasors(f, th);
    double r = exp(th[4]);
    for (int b = 0; b < f->m; b++) {
        double complex q, *P = f->perp + (size_t)b * NPAR;
        double bas[4];
        double complex e = model_conj(f, th, r, b, &q, bas);
        double complex z = f->bs[b] * e;
        double ae = cabs(e), az = cabs(z);
        if (!(ae > 0) || !(az > 0)) {
            for (int a = 0; a < NPAR; a++)
                P[a] = 0;
            continue;
        }
        double J[NPAR];
        jac_row(f, b, f->bmag[b] * sqrt(fmax(0.0, 0.5 * (1.0 + creal(z) / az))), q, bas, J);
        double complex u = I * conj(e) / ae;   /* perpendicular to the model */
        for (int a = 0; a < NPAR; a++)
            P[a] = J[a] * u;
    }
}

int binary_fit_sandwich(binary_fit *f, const double *th, const double *Mx, double *C)
{
    double A[NPAR * NPAR], g[NPAR], Ai[NPAR * NPAR], M[NPAR * NPAR];
    binary_fit_cost(f, th, A, g);
    for (int c = 0; c < NPAR; c++) {
        double e[NPAR] = {0};
        e[c] = 1;
        memcpy(M, A, sizeof M);
        if (!chol_solve(M, e, NPAR))
            return 0;
        for (int a = 0; a < NPAR; a++)
            Ai[a * NPAR + c] = e[a];
    }
    for (int a = 0; a < NPAR; a++)
        for (int b = 0; b < NPAR; b++) {
            double s = 0;
            for (int k = 0; k < NPAR; k++)
                for (int l = 0; l < NPAR; l++)
                    s += Ai[a * NPAR + k] * Mx[k * NPAR + l] * Ai[l * NPAR + b];
            C[a * NPAR + b] = s;
        }
    return 1;
}
