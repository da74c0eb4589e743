/* bispec_kernel.c - bispec.h's accumulation: each frame's spectrum into
 * the batch buffer (bispec_add), and the triple kernel over a full batch
 * (bispec_flush) on opts.nthreads threads: the batch's transforms, the
 * spread of its spectra over the legs, and the triple kernel.
 *
 * The batch buffer holds, per leg, kb real parts then kb imaginary parts
 * (conjugates pre-made for the minus legs), so the kernel is branch-free
 * SIMD over the frames of a batch.
 */
#include <complex.h>
#include <fftw3.h>

#include "base/finite.h"
#include "bispec_int.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* The targets order[o0..o1) of one batch: a tile of up to 64
 * neighbouring targets at a time (8 x 8, row by row, bispec_graph.c),
 * and within it one segment of BISPEC_SEG entries of a u2 disk row at a
 * time for every target (each target's triples are sorted by disk entry,
 * so a segment is a run of them), each run summed by the handle's
 * bispec_lanes.c path.  Per triple: 2 bytes of index, two gathers from
 * small tables, the u1 and u2 leg blocks, one read-modify-write of the
 * accumulator, which streams through memory once per batch.  Why
 * segments: a segment's u2 legs (16, 14 kB at 100 frames) serve all the
 * tile's targets, and the u1 legs of one target (u - u2, 16 in a row)
 * are shifted by one for the next target in the row, so both stay in L1
 * (23 u1 legs per tile row, 20 kB); a whole u2 row (~57 legs each way,
 * 100 kB) does not fit L1, and legs loaded from L2 cost the kernel as
 * much as its arithmetic (docs/results.md).  Each triple is summed by one thread in a fixed order, so the
 * bits do not depend on the thread count or on this order.  Error: each
 * batch's float sum is within ~(log2 K + 4) 2^-24 of the sum of its
 * terms' magnitudes; the accumulators add batches in their own
 * precision. */
static void kernel(const bispec *b, int o0, int o1)
{
    int nch = (b->nb + BISPEC_LANES - 1) / BISPEC_LANES;
    bispec_run_fn run = bispec_lanes_run(b->simd, !b->accd, b->acc2d || b->acc2f);
    int64_t cur[BISPEC_TILE * BISPEC_TILE];
    for (int o = o0, e; o < o1; o = e) {
        for (e = o + 1; e < o1 && !b->tbeg[e]; e++)
            ;
        for (int i = o; i < e; i++)
            cur[i - o] = b->tstart[b->order[i]];
        for (int r = 0; r < b->nrow; r++)
            for (int ks = b->drow[r]; ks < b->drow[r + 1]; ks += BISPEC_SEG) {
                int kend = ks + BISPEC_SEG < b->drow[r + 1] ? ks + BISPEC_SEG : b->drow[r + 1];
                for (int i = o; i < e; i++) {
                    int j = b->order[i];
                    int64_t t = cur[i - o], tend = b->tstart[j + 1];
                    if (t < tend && b->tk[t] < kend)
                        cur[i - o] = run(b, j, t, tend, kend, nch);
                }
            }
    }
}

/* tpool job: sum the triples of the work units claimed (bispec_int.h:
 * a fixed cut, each unit summed whole by one thread).  Fixed halves left
 * one thread waiting whenever the read-ahead thread or the host slowed
 * the other. */
typedef struct kernel_job {
    const bispec *b;
    atomic_int next;
} kernel_job;

static void kjob(void *ctx, int tid, int n)
{
    kernel_job *j = ctx;
    (void)tid, (void)n;
    for (int u; (u = atomic_fetch_add(&j->next, 1)) < BISPEC_KUNITS;)
        kernel(j->b, j->b->kunit[u], j->b->kunit[u + 1]);
}

/* Slot k's frame, as bispec_add copied it, windowed in place (and w^2
 * times it into in2 for the photon terms), with its sums of w^2 I and
 * w^3 I: per pixel in order, as one thread would. */
static void window_slot(bispec *b, int k)
{
    size_t npx = (size_t)b->w * b->h;
    float *in = b->in + (size_t)k * b->npad;
    float *in2 = b->in2 ? b->in2 + (size_t)k * b->npad : NULL;
    double w2 = 0, w3 = 0;
    for (size_t i = 0; i < npx; i++) {
        float v = in[i], wv = b->win ? b->win[i] : 1.0f;
        in[i] = wv * v;
        if (in2)
            in2[i] = wv * wv * v;
        w2 += (double)wv * wv * v;
        w3 += (double)wv * wv * wv * v;
    }
    b->sw2[k] = w2;
    b->sw3[k] = w3;
}

/* The staged frames' transforms and spread run in a pipeline of two
 * groups of slots (slotpipe.h), claimed by whichever thread is free, a
 * slot or SPREAD_CLAIM frequencies at a time: each is computed whole by
 * one thread, so the bits do not depend on who runs it, and fixed shares
 * left a thread idle whenever the read-ahead thread (three threads on
 * two cores) or the host slowed the other.  A group is spread after the
 * groups before it, at lanes nspread.., so each frequency receives the
 * frames in order. */
enum { SPREAD_CLAIM = 256 };

/* slotpipe make: slot k windowed and transformed (fftwf_execute_dft_r2c
 * on the handle's plans: every slot has the planned arrays' alignment). */
static void fft_slot(void *ctx, int k)
{
    bispec *b = ctx;
    window_slot(b, k);
    fftwf_execute_dft_r2c(b->plan, b->in + (size_t)k * b->npad, b->out + (size_t)k * b->nhp);
    if (b->plan2)
        fftwf_execute_dft_r2c(b->plan2, b->in2 + (size_t)k * b->npad,
                              b->out2 + (size_t)k * b->nhp);
}

/* Frequency j of slots k0..k0+n-1 into its + and - legs' lanes
 * lane0.., and into its sums, in frame order. */
static void spread_freq(bispec *b, int j, int k0, int n, int lane0)
{
    size_t K = (size_t)b->kb, o = (size_t)((b->fq[j] + b->h) % b->h) * b->wc + b->fp[j];
    float *pj = b->fb + (size_t)j * 2 * K, *mj = pj + (size_t)b->nf * 2 * K;
    for (int i = 0; i < n; i++) {
        int s = lane0 + i;
        const fftwf_complex *f = b->out + (size_t)(k0 + i) * b->nhp;
        float re = crealf(f[o]), im = cimagf(f[o]);
        pj[s] = re;
        pj[K + s] = im;
        mj[s] = re;
        mj[K + s] = -im;
        double p2 = (double)re * re + (double)im * im;
        b->psum[j] += p2;
        if (!b->xsum)
            continue;
        /* X = F_w conj(F_{w^2}); without a window that is |F|^2. */
        if (b->out2) {
            const fftwf_complex *f2 = b->out2 + (size_t)(k0 + i) * b->nhp;
            double r2 = crealf(f2[o]), i2 = cimagf(f2[o]);
            b->xsum[2 * j] += re * r2 + im * i2;
            b->xsum[2 * j + 1] += im * r2 - re * i2;
            if (b->w2ft) { /* F (rn^2 / g) conj W2 */
                double wr = b->w2ft[2 * j], wi = b->w2ft[2 * j + 1];
                b->xsum[2 * j] += re * wr - im * wi;
                b->xsum[2 * j + 1] += re * wi + im * wr;
            }
        } else {
            b->xsum[2 * j] += p2;
        }
    }
}

/* slotpipe take: frequencies t SPREAD_CLAIM.. of slots k0..k0+n-1 into
 * lanes nspread.., taken in the spectra's memory order (sorder): in rank
 * order each frequency read the staged spectra at scattered places, a
 * cache miss per frame and frequency once they outgrow L2 (8 MB of
 * spectra at 512^2). */
static void spread_task(void *ctx, int t, int k0, int n)
{
    bispec *b = ctx;
    int i0 = t * SPREAD_CLAIM, i1 = i0 + SPREAD_CLAIM < b->nf ? i0 + SPREAD_CLAIM : b->nf;
    for (int i = i0; i < i1; i++)
        spread_freq(b, b->sorder[i], k0, n, b->nspread);
}

/* slotpipe done: the spread slots' window sums, in frame order. */
static void spread_done(void *ctx, int k0, int n)
{
    bispec *b = ctx;
    for (int k = k0; k < k0 + n; k++) {
        b->w2sum += b->sw2[k];
        b->w3sum += b->sw3[k];
    }
    b->nspread += n;
}

slotpipe *bispec_pipe_new(bispec *b)
{
    static const slotpipe_ops ops = {fft_slot, spread_task, spread_done};
    return slotpipe_new(b->pool, BISPEC_GROUP, (b->nf + SPREAD_CLAIM - 1) / SPREAD_CLAIM,
                        &ops, b);
}

/* Stage what is left, then run the kernel over the batch (the lanes of a
 * partial batch up to the next vector zeroed: they add nothing; vectors
 * beyond are skipped). */
void bispec_flush(bispec *b)
{
    if (!b->nb)
        return;
    slotpipe_drain(b->pipe);
    int used = (b->nb + BISPEC_LANES - 1) / BISPEC_LANES * BISPEC_LANES;
    if (b->nb < used)
        for (size_t l = 0; l < 2 * (size_t)b->nf; l++)
            for (int c = 0; c < 2; c++)
                memset(b->fb + (l * 2 + c) * b->kb + b->nb, 0,
                       (size_t)(used - b->nb) * sizeof(float));
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    kernel_job kj = {b, 0};
    tpool_run(b->pool, kjob, &kj);
    b->nb = b->nspread = 0;
    clock_gettime(CLOCK_MONOTONIC, &t1);
    b->kernel_s += (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
}

double bispec_kernel_s(const bispec *b) { return b ? b->kernel_s : 0; }

/* The frame into the next frame slot, after one branch-free scan for
 * NaN and Inf; the slots are windowed and transformed together on the
 * handle's threads when full (BISPEC_SLOTS of them: fewer than a batch,
 * to spare memory).  The window and its sums per pixel were this
 * caller's serial part: 0.38 s of a 512^2 x 400 run. */
int bispec_add(bispec *b, const float *frame)
{
    if (!b || !frame)
        return sl_seterr(b ? &b->err : NULL, SL_EINVAL,
                         "bispec_add: NULL argument");
    size_t npx = (size_t)b->w * b->h, k = (size_t)slotpipe_slot(b->pipe);
    size_t bad = finite_copy(b->in + k * b->npad, frame, npx);
    if (bad < npx) /* the slot is not taken: the next frame overwrites it */
        return sl_seterr(&b->err, SL_EDATA, "bispec_add: frame %d pixel %zu is not finite",
                         b->n, bad);
    b->n++;
    b->phased = 0;
    b->nb++;
    slotpipe_filled(b->pipe);
    if (b->nb == b->kb)
        bispec_flush(b);
    return SL_OK;
}
