/* runner_int.h - what runner.c (queue, thread, stage, states) and
 * acquire.c (camera, cube, files) share.  Not for other modules. */
#ifndef SL_DAEMON_RUNNER_INT_H
#define SL_DAEMON_RUNNER_INT_H

#include <glib.h>

#include "camwatch.h"
#include "catlock.h"
#include "runner.h"

struct runner {
    const config *cfg;
    server *srv;
    worker *wk;
    /* Thread-owned: only the acquisition thread touches these. */
    catalog *cat;
    catlock_ctx cl;            /* its catalogue writes: stop test, reserve */
    stage *stg;
    camera *cam;
    int cam_fresh;             /* opened but never streamed: prime it */
    gint64 cam_next_try_us;    /* idle, no camera: reopen from then (camlink.c) */
    gint64 cam_retry_us;       /* the wait before that try */
    GThread *th;
    /* Shared, under mu. */
    GMutex mu;
    GCond cv;
    GQueue queue;              /* runner_spec* */
    runner_spec *cur;          /* the run in hand, NULL when idle */
    int stopping;
    int abort_current;         /* set by abort / stop, read by the thread */
    char abort_reason[64];
    GArray *abort_reqs;        /* proto_req awaiting the current run's end */
    runner_status st;          /* queue field unused here */
    webtap *tap;               /* the web view's frames (never waits) */
    /* USB hot-plug (camwatch.h): the watch thread posts, the acquisition
     * thread acts (closes or reopens the camera when idle; a run in hand
     * fails at once with unplugged as its reason). */
    camwatch *cw;              /* NULL: no USB hot-plug here */
    int cam_event;             /* RUNNER_CAM_*, under mu */
    char unplugged[256];       /* why the camera is gone, "" when not, under mu */
};

enum { RUNNER_CAM_NONE = 0, RUNNER_CAM_LEFT, RUNNER_CAM_ARRIVED };

/* How an acquisition ended. */
typedef enum acq_end {
    ACQ_COMPLETE = 0,
    ACQ_ABORTED,
    ACQ_FAILED
} acq_end;

/* One run's acquisition (acquire.c), in two steps that return outcomes;
 * the runner makes the transitions (runstate.h): acquiring between them,
 * then stored, aborted or failed.
 * acquire_open: the camera ready and configured, the .part cube and its
 * frame log created and catalogued; NULL with *end (failed, or aborted
 * before the first frame) and the reason.
 * acquire_stream: the frames to the cube, the cube finished on disk, its
 * file and counts catalogued; the outcome, the reason, and *r0_m the
 * run's seeing (NaN when not measured).  acquire_free(NULL) is a no-op. */
typedef struct acq acq;
acq *acquire_open(runner *r, const runner_spec *sp, double pupil_m, char *reason,
                  size_t reason_len, acq_end *end);
acq_end acquire_stream(acq *a, char *reason, size_t reason_len, double *r0_m);
void acquire_free(acq *a);
/* The reason a run is being aborted (runner_abort's), into buf. */
void runner_abort_reason(runner *r, char *buf, size_t n);

/* Thread-side helpers from runner.c.  runner_set_state records the state
 * (waiting out another process's lock on the catalogue, catlock.h), then
 * tells subscribers; runner_stopping is catlock's stop test. */
int runner_stopping(void *runner_arg);
void runner_set_state(runner *r, const char *uuid, catalog_state st, const char *reason);
int runner_aborting(runner *r);
void runner_note_camera(runner *r, int connected, const camera_info *info, const char *error);
/* missing < 0: unchanged. */
void runner_note_progress(runner *r, int acquired, int failed, int64_t missing);
/* 1 (why filled) when the run's USB camera was unplugged: the watch
 * thread saw it leave, or (probe) it is a USB3 Vision camera no longer
 * enumerated.  Then control is not taken back: the run ends at once. */
int runner_camera_unplugged(runner *r, int probe, char *why, size_t n);

#endif
