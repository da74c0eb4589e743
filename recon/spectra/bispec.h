/* bispec.h - direct (2-D) bispectrum speckle masking over a stored,
 * symmetry-reduced subset of (u1, u2), streamed one frame at a time.
 *
 * What is stored.  B(u1, u2) = I(u1) I(u2) conj I(u1 + u2) of a real image
 * depends only on the closure triangle {u1, u2, -(u1+u2)}: it is symmetric
 * under swapping u1, u2 and under any permutation of the three legs, and
 * B(-u1, -u2) = conj B(u1, u2) (12-fold).  Each triangle is stored once,
 * as target u = the longest leg (taken in the half plane H: p > 0, or
 * p = 0 and q >= 0), u2 = the shortest leg and u1 = u - u2, kept when
 *   |u2| <= R2,  u, u1, u2 all inside the support S, none of them DC,
 * with "longest/shortest" by the visiting rank (|u|, ties in a fixed
 * order).  This is the same information as the classic set "u1 anywhere
 * within the cut-off, |u2| <= R2", and it is exactly what the recursion
 * can use: both legs of every stored triple are visited before its target.
 * Triples whose legs cannot be reached from the seeds (an isolated patch
 * of S that no |u2| <= R2 step crosses to) are not stored either.
 * The support S: the caller's mask (e.g. powspec_support; a frequency is
 * in when it or its mirror is) cut to hypot(p, q) <= rcut_px, never the
 * Nyquist row/column, always DC.  Frequencies are integer FFT indices
 * (p, q), |p| < w/2, |q| < h/2, no wrap-around.
 *
 * Memory.  With T stored triples and F = |S n H| frequencies:
 *   bytes = T * (2 + A * (1 + s/2))
 *         + F * (95 + 16 kb + 16 * ph) + 8 + 8 * (2 R2 + 1)^2 + 4 * (2 R2 + 2)
 *         + 4 * (2 R2 + 1) * (2 R2 + 2)
 *         + 4 * (BISPEC_KUNITS + 1)    [= 2052: the kernel's work units]
 *         + 4 * (w + 2 R2 + 1) * (h + 2 R2 + 1)          [even w, h]
 *         + w*h * (8 + 4 * win + 32 * (1 + ph * win))
 *         + h * (w/2 + 1) * (16 + 64 * (1 + ph * win))
 * A = 16 (double accumulators) or 8 (acc_float), s = 1 for SNR weighting,
 * ph = 1 with photon-bias correction, win = 1 with a window, kb the
 * frames per batch (bispec_batch); the 8 frame slots round w*h up to
 * 16 floats and h (w/2 + 1) up to 8 complex values.  For a full
 * disk of radius r_c
 *   T ~ (pi^2/4) r_c^2 R2^2 - (pi/3) r_c R2^3 - 2 R2^4   (R2 <= r_c/2)
 * (half-plane targets, pi r_c^2/2, times the half disk of u2 with
 * |u - u2| < |u|, pi R2^2/2, less the lens and small-|u| corrections;
 * within ~1% of the lattice count).  A sparse (aperture-mask) support cuts
 * T by about the square of its filling factor.  bispec_memory_bytes()
 * reports the bytes actually allocated.  Cost at 200 x 200, R2 = 28, a
 * full disk r_c = 99 (F 15379, T 15.39 M; 182 MB with float accumulators
 * and 128-frame batches, 286 MB with double and 64): setup 0.24 s on one
 * thread, 0.11 on two; the triple kernel for 100 frames 0.39-0.48 s on
 * one, 0.20-0.26 on two (the 2-core VM, AVX-512, fastest of 4-6 runs;
 * its accumulators' first touch included).  A 17-hole mask's support (54 % of the plane) cuts T to
 * ~9.3 M, a 7-hole one to ~1.7 M.
 *
 * Streaming.  bispec_add copies the frame into one of BISPEC_SLOTS slots;
 * full slots are windowed and transformed on the handle's opts.nthreads
 * threads and their support values spread into a batch of kb frames
 * (bispec_batch: BISPEC_BATCH_MAX, halved while the batch buffer would
 * pass BISPEC_BATCH_BYTES or opts.batch_bytes).  The triple loop runs
 * once per batch, so each accumulator is read and written once per batch
 * rather than once per frame.  It visits the targets in small tiles and
 * the u2 disk in short segments, so the legs they share stay in L1, the
 * threads claiming work units of about equal triple counts; each triple
 * is summed by one thread, so the bits do not depend on the thread
 * count.  Results flush the partial
 * batch first.
 *
 * Phase recovery and image: see phasor.h and bispec_image.
 */
#ifndef SL_BISPEC_H
#define SL_BISPEC_H

#include <stddef.h>
#include <stdint.h>

#include "closure.h"
#include "phasor.h"
#include "powspec.h"
#include "status.h"

/* Frames per batch: 128, 64, 32 or 16, the largest whose batch buffer (2F
 * legs x 2 x batch floats) fits BISPEC_BATCH_BYTES (or opts.batch_bytes).
 * A batch is one pass of the kernel over every accumulator; with few
 * frames per batch the passes, not the products, cost (512^2: 16 frames,
 * 25 passes for 400 frames, and two threads gained 1.16x). */
#define BISPEC_BATCH_MAX 128
#define BISPEC_BATCH_BYTES (32u << 20)
#define BISPEC_R2_MAX 144 /* u2 offsets must fit a uint16 */

enum bispec_simd {
    BISPEC_SIMD_AUTO = 0,
    BISPEC_SIMD_PORTABLE, /* plain C with fmaf: any CPU, slow */
    BISPEC_SIMD_AVX2,     /* AVX2 and FMA */
    BISPEC_SIMD_AVX512    /* AVX-512F */
};

typedef struct bispec_opts {
    int r2_px;                    /* radius of the u2 disk (1..144) */
    double rcut_px;               /* cut-off on hypot(p, q); <= 0: none */
    const unsigned char *support; /* w*h mask, FFT order, or NULL; read
                                     by bispec_new only, not kept */
    int window;                   /* POWSPEC_WIN_* (same frames as powspec) */
    double tukey_alpha;
    /* > 0: frames are gain * photon counts (ADU per photon); subtract
     * Wirnitzer's bias from B and g * sum(w^2 I) from the power spectrum
     * (exact for any window: the w^2-weighted frame gets its own FFT). */
    double adu_per_photon;
    /* Gaussian read noise per pixel, ADU rms (with adu_per_photon > 0):
     * removed from the power spectrum (rn^2 sum w^2) and from the |F|^2
     * of Wirnitzer's terms (rn^2 sum w^3 in each X), being no photon
     * bias; it adds nothing to the mean bispectrum itself. */
    double read_noise_adu;
    int weight;                   /* PHASOR_WEIGHT_*; SNR stores sum |b|^2 */
    int refine_weight;            /* PHASOR_WEIGHT_* of the least-squares
                                   * refinement; SNR stores sum |b|^2 */
    int acc_float;                /* complex float accumulators (half memory) */
    size_t batch_bytes;           /* cap on the batch buffer, bytes (0:
                                   * BISPEC_BATCH_BYTES): more frames per
                                   * batch, fewer passes over the
                                   * accumulators (bispec_batch_frames) */
    int nthreads;                 /* threads for the triple loop, >= 1 */
    int measure;                  /* FFTW_MEASURE (1, default) or ESTIMATE */
    int simd;                     /* BISPEC_SIMD_*: the triple kernel's
                                   * instruction set; AUTO (0) the best the
                                   * CPU has.  Every one gives the same bits
                                   * (bispec_lanes.c); one the CPU lacks is
                                   * refused. */
    int refine_iters;             /* least-squares passes after recursion;
                                   * -1: as the recursion's misfit asks
                                   * (phasor_solve) */
    size_t budget_bytes;          /* the handle's memory budget (0: none):
                                   * the refinement's lists get what the
                                   * accumulators and tables leave of it,
                                   * at least a quarter */
    double taper_frac;            /* cosine roll-off over this outer fraction
                                     of the cut-off radius (0 = hard edge) */
} bispec_opts;

void bispec_opts_defaults(bispec_opts *o); /* R2 8, MOD weighting, 1 thread,
                                             no window/photons, taper 0.2 */

typedef struct bispec bispec;

/* Build the support, frequency order, triple tables, accumulators, FFT
 * plans and buffers: everything bispec_add and bispec_image use. */
bispec *bispec_new(int w, int h, const bispec_opts *o, sl_err *err);
void bispec_free(bispec *b);
const char *bispec_errmsg(const bispec *b);

/* Accumulate one frame (w*h floats).  SL_EDATA on NaN/Inf. */
int bispec_add(bispec *b, const float *frame);
int bispec_nframes(const bispec *b);

size_t bispec_ntriples(const bispec *b);
int bispec_nfreq(const bispec *b);       /* |S n H|, DC included */
size_t bispec_ndisk(const bispec *b);    /* stored u2 offsets (nd) */
size_t bispec_memory_bytes(const bispec *b);
int bispec_batch(const bispec *b);       /* frames per batch (16..128) */
/* The frames per batch bispec_new takes for nf = |S n H| frequencies and
 * a cap of batch_bytes (0: BISPEC_BATCH_BYTES): the largest of 128, 64,
 * 32 whose buffer, 16 nf kb bytes, fits; 16 at least. */
int bispec_batch_frames(int nf, size_t batch_bytes);
int bispec_simd(const bispec *b);        /* the kernel's BISPEC_SIMD_* */
const char *bispec_simd_name(int simd);  /* "avx512", ... */
int bispec_simd_has(int simd);           /* this CPU can run it (AUTO: 1) */
/* Wall seconds spent in the triple kernel so far (the batches flushed). */
double bispec_kernel_s(const bispec *b);

/* Triple t (0 <= t < ntriples): legs as signed frequencies (p, q), and
 * the photon-bias-corrected mean bispectrum and phase-recovery weight. */
int bispec_triple(bispec *b, size_t t, int u1[2], int u2[2], double *bre,
                  double *bim, double *weight);

/* The phase recursion's weighted closure misfit (phasor_solve), NAN
 * before the phases are recovered. */
double bispec_misfit(const bispec *b);
/* Bytes the last phase recovery's refinement took (its lists, planes and
 * scratch; 0: none ran). */
size_t bispec_refine_bytes(const bispec *b);
/* Recover the phases (recursion + opts.refine_iters LS passes; cached
 * until the next bispec_add).  phase (w*h, FFT order, radians, odd:
 * phi(-u) = -phi(u)) and known (w*h, 1 where recovered) may be NULL.
 * phi is 0 at DC and at (1,0), (0,1): the tilt-free convention, i.e. the
 * image is re-centred.  Outside S and where unreached: 0, known 0. */
int bispec_phase(bispec *b, double *phase, unsigned char *known);

/* Image = modulus x exp(i phase) x cosine taper at the cut-off, inverse
 * FFT, shifted so the object sits at (w/2, h/2), real part.  modulus:
 * w*h FFT order (powspec_modulus), or NULL for sqrt of this handle's own
 * photon-bias-corrected mean power spectrum (the modulus ceiling).
 * Unrecovered frequencies contribute nothing.  img: w*h floats. */
int bispec_image(bispec *b, const double *modulus, float *img);

/* A binary fitted to the stored triples' closure phases (closure.h),
 * from each of nstart starts init[] (binary_measure on this handle's
 * image, a fringe fit), the best kept.  info may be NULL.  SL_EDATA when
 * every start is an equal pair or fails, or too few strong triples. */
int bispec_binary(bispec *b, int nstart, const binary_result *init, binary_result *out,
                  closure_fit_info *info);

/* The accumulators as flat doubles (the frame count among them), for a
 * sequence split over processes (bispec_partial.c): bispec_sums adds the
 * buffered batch, writes them to buf (NULL: none) and returns how many;
 * bispec_partial_load replaces this handle's with buf's (e.g. the
 * element-wise sum over every part).  Same opts and support on every
 * part, so the layouts agree. */
size_t bispec_partial(bispec *b, double *buf);
void bispec_partial_load(bispec *b, const double *buf);

#endif
