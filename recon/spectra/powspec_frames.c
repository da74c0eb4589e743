/* powspec_frames.c - frames into a powspec (powspec.h): each frame is
 * copied into a slot; groups of slots are windowed and transformed, a
 * slot at a time, and added to the sums, a band of SUM_ROWS rows of the
 * half plane at a time, the slots in frame order, by the handle's
 * threads in a pipeline (slotpipe.h: the caller fills one group while a
 * job transforms the other and sums the group before); slots and bands
 * are claimed by whichever thread is free (fixed shares left one idle
 * whenever the read-ahead thread or the host slowed the other).  So
 * every sum takes the same operations in the same order as one frame at
 * a time on one thread: the same bits on any thread count.  The
 * transforms were the power spectrum pass's serial part (12 % of a
 * one-thread direct run at 512^2 x 400).
 */
#include "base/finite.h"
#include "powspec_int.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { SUM_ROWS = 8 };

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

/* slotpipe make: slot s windowed and transformed (new-array execute on
 * the plan's alignment), with its ramps. */
static void fft_slot(void *ctx, int s)
{
    powspec *p = ctx;
    window_slot(p, s);
    fftwf_execute_dft_r2c(p->plan, p->in + (size_t)s * p->npad, p->out + (size_t)s * p->nhp);
    if (p->aft)
        ramps(p, s);
}

/* Row j of the half plane: slots s0..s0+n-1, in order, added to |F|^2, F
 * and (opts.aligned) F moved by the slot's ramps; about 2 w flops a frame
 * for the alignment. */
static void sum_row(powspec *p, int s0, int n, int j)
{
    for (int s = s0; s < s0 + n; s++) {
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

/* Rows j0..j1-1 of the sums written (zeroed, as calloc left them)
 * before the first frames are added.  Why: calloc leaves big buffers to
 * the kernel, so a sum's first read mapped the shared zero page and its
 * first write then took a copy-on-write fault and flushed the mapping
 * from every CPU running the process, an interprocessor interrupt per
 * page (a trap to the host on this VM): ~6 ms of a 512^2 direct run's
 * CPU.  Written first, each page faults once. */
static void first_touch(powspec *p, int j0, int j1)
{
    size_t k0 = (size_t)j0 * p->wc, k1 = (size_t)j1 * p->wc;
    memset(p->ps + k0, 0, (k1 - k0) * sizeof *p->ps);
    memset(p->ft + k0, 0, (k1 - k0) * sizeof *p->ft);
    if (p->aft)
        memset(p->aft + k0, 0, (k1 - k0) * sizeof *p->aft);
}

/* slotpipe take: band t of SUM_ROWS rows, slots s0..s0+n-1 added. */
static void sum_band(void *ctx, int t, int s0, int n)
{
    powspec *p = ctx;
    int j0 = t * SUM_ROWS, j1 = j0 + SUM_ROWS < p->h ? j0 + SUM_ROWS : p->h;
    if (p->n == 0) /* nothing summed yet: see first_touch */
        first_touch(p, j0, j1);
    for (int j = j0; j < j1; j++)
        sum_row(p, s0, n, j);
}

/* slotpipe done: the summed slots' scalars, in frame order. */
static void sum_scalars(void *ctx, int s0, int n)
{
    powspec *p = ctx;
    for (int s = s0; s < s0 + n; s++) {
        p->flux += p->sflux[s];
        p->w2flux += p->sw2[s];
        p->pbias += p->o.adu_per_photon * p->sw2[s] + p->rbias;
        p->n++;
    }
}

slotpipe *powspec_pipe_new(powspec *p)
{
    static const slotpipe_ops ops = {fft_slot, sum_band, sum_scalars};
    return slotpipe_new(p->pool, p->ns, (p->h + SUM_ROWS - 1) / SUM_ROWS, &ops, p);
}

void powspec_flush(powspec *p) { slotpipe_drain(p->pipe); }

/* The frame into the next slot after one branch-free scan for NaN and
 * Inf; the window and the sums run with the transforms, on the threads
 * (they were 0.29 s of the caller's time in a 512^2 x 400 run). */
int powspec_add(powspec *p, const float *frame)
{
    if (!p || !frame)
        return sl_seterr(p ? &p->err : NULL, SL_EINVAL,
                         "powspec_add: NULL argument");
    size_t n = (size_t)p->w * p->h;
    size_t slot = (size_t)slotpipe_slot(p->pipe);
    size_t bad = finite_copy(p->in + slot * p->npad, frame, n);
    if (bad < n) /* the slot is not taken: the next frame overwrites it */
        return sl_seterr(&p->err, SL_EDATA, "powspec_add: frame %d pixel %zu is not finite",
                         p->nadded, bad);
    p->nadded++;
    slotpipe_filled(p->pipe);
    return SL_OK;
}
