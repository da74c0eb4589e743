/* binary_fit.h - the Fourier-domain model of binary.h on a set of
 * frequencies: its cost, Levenberg-Marquardt, covariance, and the
 * band-limited peaks the measurement compares it with.  Internal to
 * binary.c; see binary.h for the model and why.
 *
 * Parameters th[BINARY_FIT_NPAR]: x1, y1 (brighter star, px), dx, dy
 * (companion offset, px), ln r (r = F2/F1), then four odd cubic phase terms
 * a_k of the transfer function, psi(u) = sum a_k b_k(u) with b = (ux^3,
 * ux^2 uy, ux uy^2, uy^3), u = k / pi in [-1, 1]: the smooth asymmetry
 * (coma-like) a reconstruction's transfer function keeps and a real one
 * cannot absorb.  A cophased image fits them at 0.
 *
 * Frequencies are FFTW r2c half-spectrum indices: column i (kx = 2 pi i /
 * w), row j (ky = 2 pi sfreq(j) / h), one of each conjugate pair.  The
 * first m are the kept ones (|I| above the noise), the rest up to nall are
 * the remaining half plane.  Cost per evaluation: O(w + h) complex
 * exponentials (separable phasors) and ~80 flops per kept frequency.
 */
#ifndef SL_BINARY_FIT_H
#define SL_BINARY_FIT_H

#include <complex.h>

#define BINARY_FIT_NPAR 9

typedef struct binary_fit {
    int w, h, nx;            /* image size; nx = w/2 + 1 columns */
    int m, nall;             /* kept frequencies, then the rest */
    int *bi, *bj;            /* column, row of each */
    double complex *bs;      /* the image spectrum there */
    double complex *bmod;    /* the projected model (binary_fit_project) */
    double *bmag;            /* |bs| */
    double complex *perp;    /* m x NPAR: binary_fit_perp */
    double *kx, *ky;         /* 2 pi f per column (nx) / row (h) */
    double complex *e1x, *e1y, *edx, *edy; /* workspace: phasors */
    int odd;                 /* 0: psi held at 0 (a sincos per frequency
                                less: the candidates' short fits) */
} binary_fit;

/* Allocate for w x h (all h * nx frequencies); 0 or SL_ENOMEM.  clear
 * frees (a zeroed or cleared struct is fine). */
int binary_fit_init(binary_fit *f, int w, int h);
void binary_fit_clear(binary_fit *f);

/* sum over kept frequencies of (2 |I| sin(phi/2))^2, phi the phase of
 * I e^{i k.x1} (1 + r e^{i k.d}) e^{-i psi}; with A and g (may be NULL)
 * also J^T J (NPAR x NPAR, row-major) and J^T res. */
double binary_fit_cost(binary_fit *f, const double *th, double *A,
                       double *g);
/* Levenberg-Marquardt from th (in/out), at most maxit steps, each clamped
 * to 0.5 (px, ln r, rad) so a start near one solution stays there.
 * Returns the cost. */
double binary_fit_lm(binary_fit *f, double *th, int maxit);
/* C = (J^T J)^-1 cost / (m - NPAR).  When J^T J is singular (r = 1: d then
 * moves nothing but what x1 moves) the (x1, y1, ln r) block is inverted
 * alone with d and psi held, and the rest of C is INFINITY. */
void binary_fit_cov(binary_fit *f, const double *th, double *C);

/* Maximum, from s (in/out), of the band-limited function whose spectrum
 * is v[0..nv) at the first nv frequencies (and their conjugates): Newton
 * steps clamped to 0.5 px, gradient steps where it is not concave.  H gets
 * the Hessian there (xx, xy, yy); returns the value (mean excluded). */
double binary_fit_peak(binary_fit *f, const double complex *v, int nv,
                       double s[2], double H[3]);
/* Covariance (xx, xy, yy) of such a peak's position under noise of
 * variance var_i = E|n|^2 per frequency: the gradient scatters with
 * G = 2 var_i / (wh)^2 sum k k^T, the position with H^-1 G H^-1. */
void binary_fit_peak_cov(const binary_fit *f, int nv, const double H[3],
                         double var_i, double cov[3]);
/* f->bmod[0..m) = the data projected on the model th: at each kept
 * frequency I's component along the model's phase, clipped at 0 (P >= 0).
 * Its transform is exactly P^ (*) (F1 delta(x1) + F2 delta(x2)) with a
 * symmetric PSF P^: the model's own peaks are the fit's positions plus
 * the interpolated-peak bias. */
void binary_fit_project(binary_fit *f, const double *th);

/* f->perp[b NPAR + a] = J_a(b) i m_b, the Jacobian of the residual at
 * kept frequency b times the unit m_b perpendicular to the model there:
 * parameter a's perturbation of the data, as a spectrum. */
void binary_fit_perp(binary_fit *f, const double *th);
/* C = A^-1 Mx A^-1 with A = J^T J at th (the sandwich covariance for
 * residuals of covariance Mx = J^T Sigma J); 0 when A is singular. */
int binary_fit_sandwich(binary_fit *f, const double *th, const double *Mx, double *C);

#endif
