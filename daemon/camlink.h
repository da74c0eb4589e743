/* camlink.h - the runner thread's hold on the camera: opened at start,
 * watched while idle, made ready (and taken again if needed) at a run's
 * start.  Only the acquisition thread calls these (it owns r->cam).
 *
 * Idle: every tick (runner.c's, 1 s) camlink_idle asks the handle whether
 * this host still controls the camera (camera_check: no traffic, the
 * GigE heartbeat does it).  A camera that went away (~5 s of silence) or
 * restarted (it names no controller) is reported not connected in
 * `status`, with the reason, and its handle closed; the camera is then
 * reopened while idle, 1 s after the loss and at doubling intervals up to
 * 8 s, so `status` shows it back.  An open of an absent GigE camera
 * blocks the thread ~2.5 s: a run queued meanwhile starts that much
 * later.
 *
 * Run start: camlink_ready asks the camera itself (camera_probe), since a
 * restart less than a heartbeat ago is not yet known; a handle that lost
 * control is replaced, within a bounded retry. */
#ifndef SL_DAEMON_CAMLINK_H
#define SL_DAEMON_CAMLINK_H

#include "camera.h"
#include "runner.h"

/* The first open, so `status` can name the camera before any run. */
void camlink_open(runner *r);
/* One idle tick: check the handle, or try to reopen when it is time. */
void camlink_idle(runner *r);
/* The camera open, in control and configured for sp: cf and info filled.
 * Tried for up to [camera] heartbeat_timeout_ms + 5 s (a controller that
 * died keeps the privilege until its heartbeat times out); SL_OK or the
 * last error in e.  Stops early on an abort. */
int camlink_ready(runner *r, const runner_spec *sp, camera_config *cf, camera_info *info,
                  sl_err *e);

#endif
