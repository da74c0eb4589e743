/* worker.h - reconstruction on its own thread, so acquisition of the next
 * run never waits for it.
 *
 * One long-lived thread takes jobs in order from a queue.  It has its own
 * catalogue handle (SQLite handles are per thread) and is the only thread
 * of the daemon that plans FFTs (FFTW's planner is not thread-safe; the
 * acquisition thread never plans).  A job reconstructs a catalogued run's
 * cube with pipeline_run, writes DATA/recon/<uuid>-<method>[-N].fits and
 * .png, measures the binary (metrics_binary), inserts a reconstruction
 * row and emits a `reconstruction` event.
 *   automatic  (a run the runner has just stored): the run goes stored ->
 *              reconstructing -> done; "none" goes stored -> done.  A
 *              failed reconstruction still ends the run 'done' (its frames
 *              are safe and catalogued), with exit_reason
 *              "reconstruction failed: ..." and no reconstruction row.
 *   on demand  (`reconstruct`): the run's state is left alone; the reply
 *              to the waiting request is sent from here when it is done.
 * worker_stop lets the current job finish; queued automatic jobs end
 * 'done' with "reconstruction not run: daemon stopping" and queued
 * requests get an error reply.
 */
#ifndef SL_DAEMON_WORKER_H
#define SL_DAEMON_WORKER_H

#include "config.h"
#include "proto.h"
#include "reserve.h"
#include "server.h"

typedef struct worker worker;

/* Opens the worker's catalogue handle (errors here, not in the thread)
 * and starts the thread.  cfg, srv and rs (the catalogue's reserve,
 * reserve.h; may be NULL) must outlive the worker. */
int worker_new(worker **out, const config *cfg, server *srv, reserve *rs, sl_err *err);
/* A job's choices beyond the method: NULL members are the defaults. */
typedef struct worker_extra {
    const char *options;      /* recon_opts.h's checked text */
    const char *calibrator;   /* calib.h's ref: a run, "none"; NULL nearest */
} worker_extra;

/* Queue a job (thread-safe).  req NULL: automatic. projections 0: the
 * configured default.  extra may be NULL.  Returns the number of jobs
 * ahead of it. */
int worker_submit(worker *w, const char *uuid, const char *method, int projections,
                  const worker_extra *extra, const proto_req *req);
/* The run being reconstructed (empty when idle) and the queue length. */
void worker_status(worker *w, char current[CATALOG_UUID_LEN + 1], int *queued);
/* Finish the current job, settle the queued ones, join the thread. */
void worker_stop(worker *w);
void worker_free(worker *w);

#endif
