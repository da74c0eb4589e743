/* slotpipe.h - frames staged in two groups of slots, made and taken in a
 * software pipeline on a tpool (powspec_frames.c, bispec_kernel.c).
 *
 * The caller copies a frame into slot slotpipe_slot(q), then calls
 * slotpipe_filled(q).  When its group is full a job starts on the pool's
 * workers: ops.make(ctx, slot) for each slot of that group (window,
 * transform), and ops.take(ctx, task, s0, n) for each of ntake tasks over
 * the group made by the job before (slots s0..s0+n-1, added to sums),
 * while the caller fills the other group.  The caller joins the job,
 * helping with what is left of it, when its group is full again or at
 * slotpipe_drain; after each job ops.done(ctx, s0, n) runs on the caller
 * for the group it took (n > 0).  Groups are taken in the order they were
 * filled, each after the job that took the one before has ended, so a
 * sum that takes its slots in order gets the frames in order: the bits of
 * one thread on any thread count.  make and take touch different groups,
 * so any thread runs any task.  The caller refills a group while the job
 * takes it: take and done must read only what make wrote (the spectra),
 * never the frames the caller copies in.
 *
 * Why: with one group, the caller copied each frame in (and waited for
 * the read-ahead) while the other threads sat idle until the group was
 * full: ~50 + ~60 ms of one core in the power-spectrum and bispectrum
 * passes of a 512^2 x 400 direct run on two threads.  The drain runs its
 * jobs on the workers too: run by the caller alone, a group took 4-5 ms
 * of one thread at every batch's end.
 *
 * With a pool of one thread the jobs run on the caller, when joined.
 * Slots 0..2 gsize - 1; the caller owns the memory they name.
 */
#ifndef SL_SLOTPIPE_H
#define SL_SLOTPIPE_H

#include "tpool.h"

typedef struct slotpipe_ops {
    void (*make)(void *ctx, int slot);
    void (*take)(void *ctx, int task, int s0, int n);
    void (*done)(void *ctx, int s0, int n);
} slotpipe_ops;

typedef struct slotpipe slotpipe;

/* gsize >= 1 slots a group, ntake >= 0 take tasks a job; the pool is
 * borrowed.  NULL when out of memory or given bad sizes. */
slotpipe *slotpipe_new(tpool *pool, int gsize, int ntake, const slotpipe_ops *ops,
                       void *ctx);
/* Joins a job in flight first (its done runs; frames still staged are
 * dropped: drain first to keep them); NULL: nothing. */
void slotpipe_free(slotpipe *q);
int slotpipe_slot(const slotpipe *q);
void slotpipe_filled(slotpipe *q);
/* Every frame filled made and taken (done called for each group). */
void slotpipe_drain(slotpipe *q);

#endif
