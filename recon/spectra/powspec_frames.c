/* powspec_frames.c - frames into a powspec (powspec.h): each frame is
 * copied into a slot; when the slots are full (or a result is asked for)
 * the handle's threads window and transform them, a slot at a time, and
 * then add them to the sums, a band of SUM_ROWS rows of the half plane at
 * a time, adding the slots in frame order; slots and bands are claimed by
 * whichever thread is free (fixed shares left one idle whenever the
 * read-ahead thread or the host slowed the other).  So every sum takes the
 * same operations in the same order as one frame at a time on one thread:
 * the same bits on any thread count.  The transforms were the power
 * spectrum pass's serial part (12 % of a one-thread direct run at
 * 512^2 x 400).
 */
#include "base/finite.h"
#include "powspec_int.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

enum { SUM_ROWS = 8 };
typedef struct frames_job {
    powspec *p;
    atomic_int next;
} frames_job;

/* Slot s's alignment ramps: the frame's spectrum moved to its
 * first-harmonic centroid (the phase of F at (1, 0) and (0, 1) is the
 * circular centroid's) leaves per-frame tip-tilt out of the long
 * exposure. */
static void ramps(powspec *p, int s)
{
    const fftwf_complex *out = p->out + (size_t)s * p->nhp;
    double complex *ex = p->ex + (size_t)s * p->wc, *ey = p->ey + (size_t)s * p->h;
    double ax = cargf(out[1]), ay = cargf(out[p->wc]);
    for (int i = 0; i < p->wc; i++)
        ex[i] = cexp(-I * i * ax);
    for (int j = 0; j < p->h; j++)
        ey[j] = cexp(-I * (j <= p->h / 2 ? j : j - p->h) * ay);
}

/* Slot s's frame, as powspec_add copied it, windowed in place, with its
 * flux and sum of w^2 I: per pixel in order, as one thread would. */
static void window_slot(powspec *p, int s)
{
    size_t n = (size_t)p->w * p->h;
    float *in = p->in + (size_t)s * p->npad;
    double flux = 0, w2flux = 0;
    for (size_t i = 0; i < n; i++) {
        float v = in[i], wv = p->win ? p->win[i] : 1.0f;
        in[i] = wv * v;
        flux += v;
        w2flux += (double)wv * wv * v;
    }
    p->sflux[s] = flux;
    p->sw2[s] = w2flux;
}

/* tpool job: window and transform the slots claimed (new-array execute
 * on the plan's alignment) and make their ramps. */
static void fft_job(void *ctx, int tid, int n)
{
    frames_job *fj = ctx;
    powspec *p = fj->p;
    (void)tid, (void)n;
    for (int s; (s = atomic_fetch_add(&fj->next, 1)) < p->nstaged;) {
        window_slot(p, s);
        fftwf_execute_dft_r2c(p->plan, p->in + (size_t)s * p->npad,
                              p->out + (size_t)s * p->nhp);
        if (p->aft)
            ramps(p, s);
    }
}

/* Row j of the half plane: every staged slot, in order, added to |F|^2,
 * F and (opts.aligned) F moved by the slot's ramps; about 2 w flops a
 * frame for the alignment. */
static void sum_row(powspec *p, int j)
{
    for (int s = 0; s < p->nstaged; s++) {
        const fftwf_complex *out = p->out + (size_t)s * p->nhp;
        const double complex *ex = p->ex ? p->ex + (size_t)s * p->wc : NULL;
        const double complex *ey = p->ey ? p->ey + (size_t)s * p->h : NULL;
        for (int i = 0; i < p->wc; i++) {
            size_t k = (size_t)j * p->wc + i;
            double re = crealf(out[k]), im = cimagf(out[k]);
            p->ps[k] += re * re + im * im;
            p->ft[k] += re + I * im;
            if (p->aft)
                p->aft[k] += out[k] * ex[i] * ey[j];
        }
    }
}

/* tpool job: the bands of rows claimed, SUM_ROWS at a time. */
static void sum_job(void *ctx, int tid, int n)
{
    frames_job *fj = ctx;
    powspec *p = fj->p;
    (void)tid, (void)n;
    for (int j0; (j0 = atomic_fetch_add(&fj->next, SUM_ROWS)) < p->h;)
        for (int j = j0; j < j0 + SUM_ROWS && j < p->h; j++)
            sum_row(p, j);
}

void powspec_flush(powspec *p)
{
    if (!p->nstaged)
        return;
    frames_job ffts = {p, 0}, sums = {p, 0};
    tpool_run(p->pool, fft_job, &ffts);
    tpool_run(p->pool, sum_job, &sums);
    for (int s = 0; s < p->nstaged; s++) {
        p->flux += p->sflux[s];
        p->w2flux += p->sw2[s];
        p->pbias += p->o.adu_per_photon * p->sw2[s] + p->rbias;
        p->n++;
    }
    p->nstaged = 0;
}

/* The frame into the next slot after one branch-free scan for NaN and
 * Inf; the window and the sums run with the transforms, on the threads
 * (they were 0.29 s of the caller's time in a 512^2 x 400 run). */
int powspec_add(powspec *p, const float *frame)
{
    if (!p || !frame)
        return sl_seterr(p ? &p->err : NULL, SL_EINVAL,
                         "powspec_add: NULL argument");
    size_t n = (size_t)p->w * p->h;
    size_t bad = finite_copy(p->in + (size_t)p->nstaged * p->npad, frame, n);
    if (bad < n) /* the slot is not taken: the next frame overwrites it */
        return sl_seterr(&p->err, SL_EDATA, "powspec_add: frame %d pixel %zu is not finite",
                         p->n + p->nstaged, bad);
    if (++p->nstaged == p->ns)
        powspec_flush(p);
    return SL_OK;
}
