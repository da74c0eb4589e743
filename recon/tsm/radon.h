/* radon.h - Radon transform of an image and its inverses, planned once.
 *
 * Geometry.  Image pixel (x, y) is img[y*w + x]; coordinates are taken
 * relative to the image centre (w/2, h/2), 0-based (seq.h).  Angles are
 * theta_k = k*180/nangles degrees, k = 0..nangles-1, measured in the image
 * from +x towards +y.  The projection at theta is
 *     p_theta(s) = integral of f along the line x cos(theta) + y sin(theta) = s
 * so a point at (x0, y0) projects to s = x0 cos(theta) + y0 sin(theta): s
 * grows along the unit vector n = (cos theta, sin theta).  On the sky (+y
 * north, -x east, PA from north through east) n points at position angle
 * PA = theta - 90 deg: theta = 0 is west (PA 270), theta = 90 north (PA 0).
 * Projections are nproj samples, proj[k*nproj + i] at s = i - nproj/2.
 * When nproj is shorter than the frame diagonal the projection is wrapped
 * (periodic with period nproj); everything below then describes the disc of
 * diameter nproj about the centre, which is where objects must lie.
 *
 * Spectra.  The 1-D spectrum of a projection, with its phase referred to
 * s = 0, is P_theta(j) = sum_s p(s) exp(-2 pi i rho_j s), rho_j = j/nproj
 * cycles/px, j = 0..nfreq-1.  By the Fourier-slice theorem it equals the
 * 2-D spectrum F(u, v) = sum f(x,y) exp(-2 pi i (u x + v y)) on the radial
 * line (u, v) = rho_j n.  spec[k*nfreq + j] holds it.
 *
 * Two forward paths:
 *  - radon_project: spatial, ray-driven.  Each ray is sampled every pixel
 *    along its length with bilinear interpolation, which damps the highest
 *    frequencies (gain 0.4 at Nyquist).  Angles 90 deg apart share their
 *    samples, so a frame costs nangles*w*h/2 interpolations (3.6e6 at 180
 *    angles, 200^2: ~3 ms on one core with AVX2; radon_spatial.h).
 *  - radon_slices: Fourier slice.  One 2-D r2c FFT of the frame on a grid
 *    oversampled by sigma, then each slice sample is interpolated with a
 *    separable Kaiser-Bessel kernel of width kw bins (a type-2 non-uniform
 *    FFT: the frame is pre-divided by the kernel's transform so the result
 *    is the exact spectrum of the pixel values to ~1e-5 (few angles: the
 *    grid g >= 1.25 N of FFTW's fastest sizes, 2^k, 3 2^k or 5 2^k, kw 8)
 *    or 1e-4..3e-4 (sigma 2, kw 4; up to ~1.5e-3 on speckle frames whose
 *    light reaches the frame edge) of F(0), see test_radon).
 *    Cost: one g^2 real FFT (0.09 ms at g = 256, 0.17 ms at 400) plus
 *    nangles*nfreq*kw^2 complex multiply-adds; each sample's taps are one
 *    contiguous block of a padded spectrum (radon_slice.c, Forward layout).
 * Two inverses from the same data:
 *  - radon_fbp: filtered back projection in image space: ramp filter (the
 *    Ram-Lak kernel sampled in space, zero-padded to 2*nproj so the
 *    convolution is not circular) times a window, then back projection with
 *    linear or Keys-cubic interpolation, optionally on a band-limited
 *    (FFT-upsampled) copy of the filtered projection.  Cost nangles*w*h taps.
 *  - radon_fbp_slices: direct Fourier inversion by gridding: the slice
 *    spectra weighted by the polar area element |rho| drho dtheta (times the
 *    window) are spread onto the oversampled grid with the same kernel (the
 *    exact adjoint of radon_slices), then one c2r FFT.  Equivalent to FBP
 *    with exact interpolation, and much cheaper at many angles.
 *  - radon_invert_iter: for few angles, where FBP streaks (18 angles cap c
 *    at ~0.6): accelerated projected gradient (FISTA) on the same weighted
 *    least-squares fit of the slices, with non-negativity and the disc
 *    support as constraints.  Each iteration is one forward and one adjoint.
 *
 * All buffers and FFTW plans are made at radon_new; the transforms allocate
 * nothing.  A handle is not re-entrant (it owns scratch buffers): use one
 * per thread.  FFTW's planner is not thread-safe: create handles from one
 * thread.  Given a pool (radon_opts.pool), one image's radon_slices,
 * radon_fbp_slices, radon_invert_iter and radon_spec_to_proj, and
 * radon_new's tap tables, run on all its threads: each FFT batch in chunks of 16 transforms, the
 * gridding by chunks of 16 grid columns (radon_batch.c), with the bits of
 * one thread (at 512^2: FBP 2.4 -> 1.4 ms, slices 1.8 -> 0.9 ms on two).
 */
#ifndef SL_RADON_H
#define SL_RADON_H

#include <complex.h>

#include "status.h"
#include "base/tpool.h"

typedef enum radon_window {
    RADON_WIN_RAMLAK = 0,  /* plain ramp, cut at the window cut-off */
    RADON_WIN_SHEPP_LOGAN, /* ramp * sinc(f / 2fc) */
    RADON_WIN_COSINE,      /* ramp * cos(pi f / 2fc) */
    RADON_WIN_HANN         /* ramp * (1 + cos(pi f / fc)) / 2 */
} radon_window;

typedef enum radon_interp {
    RADON_INTERP_LINEAR = 0,
    RADON_INTERP_CUBIC      /* Keys, a = -0.5 */
} radon_interp;

typedef struct radon_opts {
    int nproj;              /* projection length (even); 0: even >= diagonal */
    int nfreq;              /* slice frequencies j < nfreq; 0: nproj/2 + 1 */
    double oversamp;        /* NUFFT grid oversampling sigma; 0: 2 at
                             * >= 60 angles, else the smallest grid
                             * >= 1.25 max(w, h) of the form 2^k, 3 2^k,
                             * 5 2^k */
    int kernel_bins;        /* Kaiser-Bessel width kw, 2..8; 0: 4 at sigma
                             * >= 1.9, else 6; few angles: 8 below sigma
                             * 1.6, else 6 */
    radon_window window;    /* FBP window (both FBP paths) */
    double window_cut_cyc_px; /* window and ramp cut-off fc; 0: 0.5 (Nyquist) */
    radon_interp bp_interp; /* radon_fbp interpolation */
    int bp_upsample;        /* radon_fbp: 1, 2 or 4x band-limited upsampling */
    int spatial;            /* 0: no spatial projector; radon_fbp makes
                             * its filter at its first call */
    int threads;            /* radon_project threads (1..16); 0: 1 */
    unsigned fftw_flags;    /* 0: FFTW_MEASURE */
    tpool *pool;            /* borrowed, may be NULL: radon_new's tables,
                             * radon_slices and radon_fbp_slices run on
                             * its threads, with the same bits as on one;
                             * the handle must not be used while the pool
                             * runs another job (tpool.h) */
} radon_opts;

/* Defaults: everything 0 except bp_interp = CUBIC, bp_upsample = 2,
 * spatial = 1, window = RAMLAK. */
void radon_opts_defaults(radon_opts *o);

typedef struct radon radon;

/* opts may be NULL (defaults).  Errors go to err (may be NULL). */
radon *radon_new(int w, int h, int nangles, const radon_opts *opts,
                 sl_err *err);
void radon_free(radon *r);
const char *radon_errmsg(const radon *r);

int radon_nangles(const radon *r);
int radon_nproj(const radon *r);
int radon_nfreq(const radon *r);
double radon_angle_rad(const radon *r, int k);

/* Spatial projections of img (w*h) into proj (nangles*nproj). */
int radon_project(radon *r, const float *img, float *proj);
/* Fourier-slice spectra of img into spec (nangles*nfreq). */
int radon_slices(radon *r, const float *img, float complex *spec);
/* The same with the caller's scratch: any number of threads may take
 * slices with one handle at once, each with its own radon_ws (tables and
 * FFTW plans are shared read-only; a radon_ws is ~(sigma N)^2 12 bytes).
 * Results are bit-identical to radon_slices. */
typedef struct radon_ws radon_ws;
radon_ws *radon_ws_new(const radon *r, sl_err *err);
void radon_ws_free(radon_ws *ws);
int radon_slices_ws(const radon *r, radon_ws *ws, const float *img, float complex *spec);
/* Spatial projections of img and their spectra (radon_project, then
 * radon_proj_to_spec) on the calling thread alone, with a radon_ws from
 * radon_ws_new_projector (NULL without the projector, spatial = 0):
 * threads project different frames with one handle at once.  The same
 * bits as the two calls. */
int radon_can_project(const radon *r);
radon_ws *radon_ws_new_projector(const radon *r, sl_err *err);
int radon_project_spec_ws(const radon *r, radon_ws *ws, const float *img,
                          float complex *spec);

/* 1-D transforms between projections and their spectra (per angle; phase
 * referred to s = 0).  spec_to_proj drops frequencies j >= nfreq. */
int radon_proj_to_spec(radon *r, const float *proj, float complex *spec);
int radon_spec_to_proj(radon *r, const float complex *spec, float *proj);

/* Inverses into img (w*h).  Pixels outside the disc of diameter nproj are
 * set to 0. */
int radon_fbp(radon *r, const float *proj, float *img);
int radon_fbp_slices(radon *r, const float complex *spec, float *img);
/* niter FISTA iterations starting from radon_fbp_slices; nonneg != 0 clips
 * negative pixels each iteration.  The step is 1/L with L the largest
 * eigenvalue of the normal operator, found once by power iteration on the
 * first call (that call costs about 20 extra iterations). */
int radon_invert_iter(radon *r, const float complex *spec, int niter,
                      int nonneg, float *img);

#endif
