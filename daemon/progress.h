/* progress.h - a run's progress row in the catalogue, written by a
 * helper thread during acquisition (acquire.c).
 *
 * The catalogue's progress row during acquisition is written by a helper
 * thread with its own catalogue handle, never by the frame loop.  Why:
 * each write is a synchronous (fsynced) SQLite commit, and on a busy ext4
 * disk that fsync also flushes the cube's dirty pages: `make soak`
 * measured 100-300 ms, longer than the camera's buffer pool lasts (32
 * buffers = 160 ms at 200 Hz), and the frames that arrived meanwhile were
 * dropped (underruns, ~0.5 % of a 10000-frame run).  The loop posts its
 * latest counts (the latest wins); finish() joins the thread before it
 * writes the final counts, so no stale count can land after them.  The
 * row is advisory meanwhile (`run` shows it; a restart recounts the
 * .part), so a failed write is only logged.
 */
#ifndef SL_DAEMON_PROGRESS_H
#define SL_DAEMON_PROGRESS_H

#include <glib.h>
#include <stdint.h>

#include "catalog.h"

typedef struct progress_writer {
    const char *db_path, *uuid;
    int busy_timeout_ms;      /* the daemon's: a lock is logged, not waited out */
    GThread *th;              /* NULL: not running (write inline) */
    GMutex mu;                /* guards the fields below */
    GCond cv;
    int stored, failed, posted, stop;
    int64_t missing;
    int warned;               /* the helper thread's own */
} progress_writer;

/* The struct is embedded in the acquisition's state (no allocation on
 * the run's path); start it before use, stop it once. */
void progress_start(progress_writer *p, const char *db_path, int busy_timeout_ms,
                    const char *uuid);
/* Hand the counts over; without the thread, write them here (cat). */
void progress_post(progress_writer *p, catalog *cat, int stored, int failed, int64_t missing);
/* Stop and join (a write in progress completes first); idempotent. */
void progress_stop(progress_writer *p);

#endif
