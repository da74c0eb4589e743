/* tsm_accum.h - the sums of TSM steps (1)-(2) (tsm.h), over a stream of
 * frames: per angle, in double, the power sum |P(u)|^2, the spectrum sum
 * P(u) and the 1-D bispectrum sum P(u1) P(u2) conj(P(u1 + u2)) over the
 * pairs of tsm_phase (rows off[u1], len[u1]).
 *
 * Frames are buffered in blocks of `batch`.  Two blocks alternate: when
 * one is full it goes to the pool's workers and the caller returns to
 * fill the other (reading and cleaning the next frames meanwhile); before
 * the next block goes out, the caller joins the work left on the job in
 * flight.  The jobs are a pipeline: job p makes block p's spectra and
 * adds block p - 1's, tasks that any thread may claim in any order:
 *   (1) spectra, one frame each, with the thread's own radon_ws: Fourier
 *       slices (radon_slices_ws), or the spatial projector's projections
 *       and their 1-D transforms (radon_project_spec_ws: per frame on one
 *       thread rather than each frame's rays over all of them, whose
 *       serial parts, the 1-D FFTs and a thread start, were ~10 % of the
 *       spatial variant's frames on two threads);
 *   (2) additions, a few angles each, adding the previous block's spectra
 *       to those angles in frame order, 4 frames per pass so that one
 *       angle's bispectrum (np x 16 bytes) is read and written once per
 *       4 frames.
 * Every sum is added to by one task at a time, in frame order, and jobs
 * go one after the other: the sums are bit-identical for any number of
 * threads and any interleaving (tests/stress/test_stress_edge.c).
 * Memory: 2 batch (w h 4 + K nf 8) bytes of blocks, K (np + 3 nf) 8 bytes
 * of sums, one radon_ws per thread; none of it grows with the number of
 * frames.
 *
 * Cost per frame, K angles, J = nf - 1, np ~ J^2/4 pairs, grid g
 * (radon.h): (1) one g x g real 2-D FFT, ~2.5 g^2 log2 g flops (0.09 ms
 * at g = 256, 0.17 ms at 400), plus K nf kw^2 complex taps; (2) K (np 14
 * + nf 6) flops in double (200^2, 180 angles: 450 000 pairs, 0.32 ms on
 * one core with AVX2, 0.48 without).  Both divide among the threads.
 */
#ifndef SL_TSM_ACCUM_H
#define SL_TSM_ACCUM_H

#include <complex.h>
#include <stddef.h>

#include "radon.h"
#include "status.h"
#include "base/tpool.h"

typedef struct tsm_accum tsm_accum;

/* The sums, nang x np (bispectrum) and nang x nf (the others). */
typedef struct tsm_sums {
    const double *bre, *bim;
    const double *ps;
    const double *mre, *mim;
} tsm_sums;

/* rad: the frames' spectra, by its spatial projector when it has one
 * (radon_project_spec_ws), else by Fourier slices (radon_slices_ws);
 * off/len/np: the pair rows (tsm_phase), kept by reference; pool: the
 * threads (kept by reference, may be NULL = 1). */
tsm_accum *tsm_accum_new(const radon *rad, int w, int h, int nang, int nf,
                         const int *off, const int *len, int np, int batch,
                         tpool *pool, sl_err *err);
void tsm_accum_free(tsm_accum *a);
void tsm_accum_reset(tsm_accum *a);
int tsm_accum_nframes(const tsm_accum *a);

/* The next slot of the filling block for one frame (w*h): fill it, then
 * commit it (or not: an uncommitted slot is reused).  A full block is
 * sent to the pool's threads and the call returns at once; the caller
 * fills the other block meanwhile. */
float *tsm_accum_frame_slot(tsm_accum *a);
void tsm_accum_commit_frame(tsm_accum *a);
/* Add whatever is buffered, then the sums (valid until the next add). */
const tsm_sums *tsm_accum_sums(tsm_accum *a);

/* The sums as flat doubles (bre, bim, ps, mre, mim), for a sequence
 * split over processes: pack adds what is buffered, writes them to buf
 * (NULL: none) and returns how many; unpack replaces them with buf's and
 * the frame count with nframes. */
size_t tsm_accum_pack(tsm_accum *a, double *buf);
void tsm_accum_unpack(tsm_accum *a, const double *buf, int nframes);

#endif
