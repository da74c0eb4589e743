/* radon_spatial.h - the image-space half of radon.h: the ray-driven
 * bilinear projector behind radon_project and the filtered back projection
 * behind radon_fbp.  Internal to recon/: radon.c owns one handle and
 * forwards to it; geometry, angles and options are radon.h's.
 *
 * Projector.  Angle theta_k samples the bilinearly interpolated frame
 * (zero outside) at the points C + a n + b m of a unit lattice rotated by
 * theta_k (C the frame centre, n = (cos, sin), m = (-sin, cos), a, b
 * integers) and sums each ray over b into proj[k][a]: the definition of
 * the original ray-by-ray loop, kept (test_radon_spatial checks it against
 * that loop).  The lattice of theta + 90 deg is the same point set
 * (n' = m, m' = -n), so one pass over the lattice gives both projections:
 * its line sums one way and its column sums the other.  With an even
 * number of angles each angle below 90 deg is paired with its partner,
 * halving the interpolations; with an odd number each angle is a pass of
 * its own.  A pass walks the lattice line by line along whichever of n, m
 * is nearer the x axis (memory order), stepping the points in 32.32 fixed
 * point (within 4e-8 px of exact over a line, so the float weights are
 * exact to their rounding).  The frame is stored as row pairs, so the four
 * taps of a sample are one 16-byte load; eight samples go at a time with
 * AVX2 (chosen at run time), four with SSE2, one in portable C: all sum in
 * the same order and give the same bits.  Passes split over `threads`
 * (each projection is written by one pass: same bits for any count).
 * Line tables (start, length, fixed-point start) are built at _new.
 * Cost at 200^2, 180 angles: 3.6e6 interpolations per frame; per frame on
 * one core of the shared 2-core EPYC VM (min of 40, CPU time): AVX2
 * 2.9 ms, SSE2 4.5 ms, portable 8.5 ms (the ray-by-ray loop in double it
 * replaces: 40 ms).  Memory ~1 MB (row pairs 0.33 MB, lines 0.6 MB).
 *
 * FBP: ramp filter (the Ram-Lak kernel sampled in space, zero-padded to
 * 2 nproj so the convolution is not circular) times the window, optional
 * band-limited upsampling, then back projection over the disc of diameter
 * nproj with linear or Keys-cubic interpolation: nangles * (pi nproj^2/4)
 * taps.  Cubic goes four pixels at a time with SSE2 (t in 32.32 fixed
 * point; same bits as the portable loop): 200^2, 180 angles, 2x upsampled
 * ~10 ms (was 48 ms).  The angles are filtered first, then the image's
 * rows are claimed by the threads, each pixel summing the angles in order
 * (radon_backproject.c: same bits on any count; 512^2 77 -> 43 ms on 2).
 *
 * Not re-entrant (scratch buffers); creating one plans FFTW (one thread).
 */
#ifndef SL_RADON_SPATIAL_H
#define SL_RADON_SPATIAL_H

#include "radon.h"

typedef struct radon_spatial radon_spatial;

/* Handle for w x h frames, nangles angles with cos/sin cs[k], sn[k],
 * projections of ns samples; o gives the FBP window, cut-off,
 * interpolation and upsampling (resolved: bp_upsample 1, 2 or 4), the
 * FFTW flags, and o->spatial != 0 builds the projector.  xlo, xhi (per row:
 * the pixels inside the disc of diameter ns) are borrowed: they and cs, sn
 * must outlive the handle. */
radon_spatial *radon_spatial_new(int w, int h, int nangles, int ns, const radon_opts *o,
                                 const double *cs, const double *sn,
                                 const int *xlo, const int *xhi, sl_err *err);
void radon_spatial_free(radon_spatial *sp);

/* Code path of the projector: 0 portable C, 1 SSE2, 2 AVX2 (x86-64; all
 * give the same bits).  level < 0 or above what the CPU has: the best it
 * has (the default).  Returns the level set. */
int radon_spatial_set_simd(radon_spatial *sp, int level);
/* 1 if the projector was built. */
int radon_spatial_can_project(const radon_spatial *sp);
/* img (w*h) -> proj (nangles*ns); needs the projector. */
void radon_spatial_project(radon_spatial *sp, const float *img, float *proj);
/* The same projection on the calling thread alone, with its own scratch
 * (from radon_spatial_scratch_new, NULL without the projector; free()
 * it): several threads may project different frames with one handle at
 * once.  Same bits as radon_spatial_project. */
float *radon_spatial_scratch_new(const radon_spatial *sp);
void radon_spatial_project_with(const radon_spatial *sp, float *scratch, const float *img,
                                float *proj);
/* proj (nangles*ns) -> img (w*h), 0 outside the disc. */
void radon_spatial_fbp(radon_spatial *sp, const float *proj, float *img);

/* The FBP windows' gain at f cycles/px, cut-off fc (both inverses). */
double radon_window_gain(radon_window win, double f, double fc);

#endif
