/* tpool.h - a fixed team of threads that run one function together.
 *
 * tpool_run(p, fn, ctx) calls fn(ctx, tid, n) once on each of the n
 * threads (tid 0 is the caller, 1..n-1 are workers created at tpool_new)
 * and returns when every call has returned: a fork-join with no thread
 * creation per call (a wake-up costs ~10-50 us, the caller's share runs
 * meanwhile).  For bit-identical results with any n, give each output
 * element one owner whose order of operations does not depend on n: a
 * share fixed by (tid, n) (powspec_frames.c), or tasks claimed from a queue,
 * each computing its elements whole (tsm_accum.c).
 *
 * Not re-entrant: one job at a time per pool (tpool_run, or tpool_submit
 * then tpool_wait), from the thread that made it; fn must not start a job
 * on the same pool.  n = 1 creates no thread and runs fn(ctx, 0, 1)
 * inline.
 */
#ifndef SL_TPOOL_H
#define SL_TPOOL_H

#include "status.h"

typedef struct tpool tpool;
typedef void (*tpool_fn)(void *ctx, int tid, int nthreads);

/* Threads for nthreads = 0: the online CPUs, clamped to 1..4 (the work
 * per call is a few ms: more threads mostly wait). */
int tpool_default_threads(void);
/* nthreads >= 1 (0: tpool_default_threads()); SL_ENOMEM/SL_EINVAL via
 * err when a thread cannot be created. */
tpool *tpool_new(int nthreads, sl_err *err);
void tpool_free(tpool *p);
int tpool_size(const tpool *p);
void tpool_run(tpool *p, tpool_fn fn, void *ctx);
/* The same in two halves, so that the caller can do other work while the
 * workers run: tpool_submit starts fn on tid 1..n-1 and returns at once;
 * tpool_wait returns when they are done.  The caller runs tid 0's share
 * itself if the job has one (a job that claims tasks from a shared queue
 * can be joined late).  Every submit needs its wait before the next
 * submit or run.  With n = 1 both do nothing. */
void tpool_submit(tpool *p, tpool_fn fn, void *ctx);
void tpool_wait(tpool *p);

/* Inside a job, one step of waiting for work another thread of it is
 * doing: spin first, then give the core up (more threads than cores, or
 * a reader beside them, must not starve the one waited for).  *spins
 * starts at 0 for each wait. */
void tpool_pause(int *spins);

#endif
