/* screen.h - random atmospheric phase screens (Kolmogorov / von Karman) as
 * continuous functions of position, for frozen-flow speckle simulation.
 *
 * Model.  The phase power spectrum (f in cycles/m) is
 *     Phi(f) = 0.022896 r0^(-5/3) (f^2 + 1/L0^2)^(-11/6)   [rad^2 m^2],
 * the "0.023" of the literature unrounded so that for L0 = infinity the
 * structure function is exactly D(r) = 6.8839 (r/r0)^(5/3).  The phase is in
 * radians at the wavelength where r0 is given; scaling it to another
 * wavelength (phase ~ 1/lambda, r0 ~ lambda^(6/5)) is the caller's business.
 *
 * A screen is phase(x, y) for every real (x, y), the sum of two parts:
 *   - a periodic part: an n x n grid (period n*dx) made by the FFT method,
 *     complex Gaussian white noise times sqrt(Phi) df, one inverse FFT,
 *     read with bilinear interpolation and wrap-around (continuous, since
 *     the grid is periodic), holding every frequency of the FFT lattice
 *     outside the 3x3 block around f = 0 (outside f = 0 only, with
 *     subharmonic_levels = 0);
 *   - an analytic, non-periodic part: 8 (levels + 1) sinusoids plus a tilt,
 *     evaluated exactly at any coordinate, holding the low frequencies:
 *     level 0 is the 8 lattice cells around f = 0 (width df = 1/(n dx)),
 *     level p = 1..levels the 8 cells of width df/3^p around f = 0 that
 *     tile the centre cell of level p-1 (Lane, Glindemann & Dainty 1992;
 *     Johansson & Gavel 1994), and the tilt stands for the last centre cell
 *     (width df/3^levels), whose effect at separations r << 3^levels/df is
 *     a random gradient of variance 4 pi^2 int Phi fx^2 over that cell.
 * Unlike Lane et al., who put each cell's power Phi(centre) * area at the
 * cell centre (3 levels, n = 256: D is 11-45% low from 2 pixels to
 * 0.8 n), each term here carries the cell's exact power int Phi
 * (Gauss-Legendre) at a frequency drawn within the cell with density
 * ~ Phi, so that the ensemble mean of D(r) is the integral of
 * 2 Phi (1 - cos 2 pi f.r) over the cell for every r.  What remains is
 * the power beyond the grid's Nyquist frequency and the midpoint rule of
 * the lattice cells: the expected D is 8% low at r = 1 px, 2.5% at 2 px
 * and within 1% from 4 px to 0.94 n (computed for n = 128 and 256).
 * The analytic part's mean over the base window (pixels 0..n-1 in x and
 * y) is subtracted, so that window has zero mean; phase far from it
 * wanders, as Kolmogorov phase does.
 *
 * Because the analytic part is not periodic, the screen never repeats
 * exactly; frozen flow is sampling at shifted coordinates, with no seam.
 * Sampling at integer-pixel offsets at the screen pitch returns grid values
 * (no interpolation), so the window at x0 + k dx is exactly (bit for bit)
 * the window at x0 shifted by k pixels.
 *
 * Pair.  The inverse FFT of complex noise gives two independent screens,
 * its real and imaginary parts; screen_new keeps the real part,
 * screen_new_pair both (screen_new's screen is the pair's first, bit for
 * bit).  Each screen has its own analytic terms.
 *
 * Cost and memory.  screen_new: n^2 normal deviates and power-law values
 * plus one n x n complex double FFT (FFTW_ESTIMATE; 2048^2 in 0.4 s, 4096^2
 * in 1.8 s on one core), peak memory n^2 * 20 bytes (16 for the FFT
 * buffer, freed before return, 4 for the kept float grid; a pair keeps 8:
 * 2048^2 peaks at 80 MiB and keeps 16 MiB).  The FFTW
 * planner is not thread-safe: do not run screen_new concurrently with other
 * FFTW planning.  screen_sample: O(w h (1 + 8 (levels + 1))) multiply-adds
 * with trig only per row and per column; it reads but never writes the
 * screen, so several threads may sample one screen at once.
 *
 * Random numbers: rng streams derived from seed, one for the FFT noise and
 * one per screen of a pair for the analytic terms, all ids private here.
 */
#ifndef SL_SCREEN_H
#define SL_SCREEN_H

#include <stdint.h>

#include "status.h"

typedef struct screen screen;

/* Limits checked by screen_new. */
#define SCREEN_MIN_N 16
#define SCREEN_MAX_N 32768
#define SCREEN_MAX_LEVELS 12

typedef struct screen_opts {
    int n;          /* periodic grid size, pixels; any n in [16, 32768]
                     * (FFTW handles every size; powers of 2 are fastest) */
    double dx_m;    /* grid pitch, metres, > 0 */
    double r0_m;    /* Fried parameter at the phase's wavelength, > 0 */
    double L0_m;    /* outer scale, metres; INFINITY or <= 0: Kolmogorov */
    int subharmonic_levels; /* 0: plain periodic FFT screen; default 3 */
    uint64_t seed;  /* same seed and options: bit-identical screen */
} screen_opts;

/* n = 256, dx_m = 0.02, r0_m = 0.2, L0_m = INFINITY, 3 levels, seed 1. */
void screen_opts_defaults(screen_opts *o);

/* Generate one screen.  SL_EINVAL (n out of range, non-finite or
 * non-positive dx_m or r0_m, NaN L0_m, levels outside
 * [0, SCREEN_MAX_LEVELS]) or SL_ENOMEM, with err set; *out is NULL then. */
int screen_new(screen **out, const screen_opts *o, sl_err *err);
/* Two independent screens from one FFT (real and imaginary parts); *a is
 * screen_new's screen for the same options.  Both NULL on error. */
int screen_new_pair(screen **a, screen **b, const screen_opts *o,
                    sl_err *err);
void screen_free(screen *s);

/* Fill phase_rad[y * w + x] (radians), x < w, y < h, with the screen at
 * (x0_m + x dx_m, y0_m + y dx_m).  An origin within 1e-6 pixel of a grid
 * point is snapped onto it, and a pitch within 1e-12 of the screen's is
 * taken as equal, so frozen-flow offsets computed in metres (v t) that are
 * whole pixels give exact shifts.  SL_EINVAL for a NULL pointer, w or h
 * < 1, non-finite origin, non-finite or non-positive dx_m; SL_ERANGE for
 * coordinates beyond 4e12 pixels (the bilinear fraction would be lost);
 * SL_ENOMEM if the O((w + h) * terms) scratch cannot be allocated.  No
 * message is kept (the screen is const so that threads may share it):
 * sl_strstatus names the code. */
int screen_sample(const screen *s, float *phase_rad, int w, int h,
                  double x0_m, double y0_m, double dx_m);

int screen_n(const screen *s);
double screen_dx_m(const screen *s);
/* Number of analytic sinusoids: 8 (levels + 1), or 0 without levels. */
int screen_nterms(const screen *s);

#endif
