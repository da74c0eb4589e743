/* runner.h - the run queue and the acquisition thread.
 *
 * Threading (the choice the issue leaves open): acquisition runs on ONE
 * long-lived thread, not as GLib sources, because the camera and stage
 * calls block (camera_pop waits for a frame, stage_wait polls for
 * seconds) and a blocking call on the main loop would freeze the socket.
 * The thread owns the camera, the stage handle and its own catalogue
 * handle; it talks to the main loop only through server_*_async (events,
 * replies to aborts) and to the worker through worker_submit.  Runs are
 * taken one at a time from a FIFO; runs handed to the worker do not hold
 * the queue, so reconstruction never delays the next acquisition.
 *
 * A run: queued -> moving (home unhomed wheels, move both wheels, wait
 * in position, settle) -> acquiring (configure the camera, stream good
 * frames into DATA/runs/<uuid>.fits.part, flushed at least every 100 ms
 * and before each progress event, so no frame a client was told about
 * can be lost) -> stored (FRAMES table, fsync, rename to .fits, fsync the
 * directory, SHA-256, catalogue) -> the worker.  Exits: failed (stage
 * fault or timeout before acquiring; camera lost, disk full, too many
 * damaged frames while acquiring) and aborted (request or daemon stop);
 * both keep every frame on disk as a valid .part cube, catalogued with
 * its checksum.  The seeing (r0 from image motion, recon/measure/seeing.h) of
 * each stored run is added to its screen's history.
 */
#ifndef SL_DAEMON_RUNNER_H
#define SL_DAEMON_RUNNER_H

#include "camera.h"
#include "config.h"
#include "proto.h"
#include "reserve.h"
#include "server.h"
#include "stage.h"
#include "webtap.h"
#include "worker.h"

typedef struct runner runner;

typedef struct runner_spec {
    char uuid[CATALOG_UUID_LEN + 1];
    int screen_slot, mask_slot;
    char screen[72], mask[72];
    int frames;
    double exposure_us;
    char object[72];
    char method[16];        /* reconstruction: "auto", ..., "none" */
    int projections;
    catalog_kind kind;      /* science, dark, flat or calibrator */
} runner_spec;

/* What status and devices report, from the thread's last contact. */
typedef struct runner_status {
    char current[CATALOG_UUID_LEN + 1];   /* "" when idle */
    catalog_state state;
    int frames_acquired, frames_requested;
    int frames_failed;                    /* damaged buffers this run */
    gint64 packets_missing;               /* this run, as of the last second */
    char **queue;                         /* NULL-terminated; g_strfreev */
    int camera_connected;
    camera_info camera;                   /* model/serial "" when never seen */
    char camera_error[256];
    int stage_connected, stage_known;
    stage_wheel_status wheels[STAGE_NWHEELS];
    char stage_error[256];
    unsigned stage_rejected;              /* replies the line damaged (rtu;
                                           * stage_rejected_replies) */
} runner_status;

enum { RUNNER_NOT_HERE = 0, RUNNER_DEQUEUED = 1, RUNNER_ABORTING = 2 };

/* Opens the thread's catalogue handle and starts the thread, which first
 * tries to open the camera (so `status` can name it; not fatal).  rs (may
 * be NULL) is the catalogue's reserve (reserve.h): held before each run,
 * released to record a run's end on a full disk. */
int runner_new(runner **out, const config *cfg, server *srv, worker *wk, reserve *rs,
               sl_err *err);
/* Queue a run already inserted as 'queued'.  *ahead: runs before it
 * (current included); behind: the uuid right before it ("" if none). */
void runner_enqueue(runner *r, const runner_spec *spec, int *ahead,
                    char behind[CATALOG_UUID_LEN + 1]);
/* RUNNER_DEQUEUED: it was queued and is removed (the caller marks it
 * aborted); RUNNER_ABORTING: it is the current run, the thread will stop
 * it and reply to req (copied) when it has; RUNNER_NOT_HERE otherwise. */
int runner_abort(runner *r, const char *uuid, const proto_req *req);
void runner_status_get(runner *r, runner_status *out);
/* The frame tap (webtap.h) the acquisition offers its good frames to:
 * the web view's.  Owned by the runner; valid until runner_free. */
webtap *runner_tap(runner *r);
/* Abort the current run ("daemon stopping"), mark queued runs aborted,
 * join the thread. */
void runner_stop(runner *r);
void runner_free(runner *r);

#endif
