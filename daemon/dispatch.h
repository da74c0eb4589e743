/* dispatch.h - control-socket requests to handlers (daemon/PROTOCOL.md).
 *
 * Every line is parsed with json-glib; a line that is not a JSON object is
 * `bad-json`, a missing or ill-typed argument (or one the command does
 * not take) `bad-request` naming it, an unknown command
 * `unknown-command` listing the known ones.  A request that fails
 * validation changes nothing.  Requests never carry paths: runs are named
 * by uuid (or a unique prefix of at least 4 hex digits), screens and
 * masks by configured name or slot, and every file the daemon touches is
 * DATA_DIR/runs/<uuid>.fits[.part] or DATA_DIR/recon/<uuid>-<method>*.
 * Free text (object, operator) is limited to 68 bytes without control
 * characters, '/', '\' or "..", so no later use can turn it into a path.
 *
 * Most commands answer at once from the main thread's catalogue handle.
 * Three answer later without blocking other clients: `reconstruct` (from
 * the worker when done), `abort-run` of the current run (from the runner
 * once stopped) and `devices` (a short thread reads the stage).
 */
#ifndef SL_DAEMON_DISPATCH_H
#define SL_DAEMON_DISPATCH_H

#include <glib.h>

#include "catalog.h"
#include "config.h"
#include "runner.h"
#include "server.h"
#include "worker.h"
#include "base/version.h"

/* status's "version": the one the programs print (recon/base/version.h) */
#define SPECKLABD_VERSION SPECKLAB_VERSION

typedef struct daemon_ctx {
    const config *cfg;
    catalog *cat;        /* the main thread's handle */
    server *srv;
    runner *run;
    worker *wk;
    gint64 started_us;   /* g_get_monotonic_time at start */
    int pending_tasks;   /* `devices` queries in flight */
    unsigned stage_rejected; /* damaged replies the `devices` queries' stage
                              * handles rejected (the runner counts its own) */
    char web_url[128];   /* the live page's address (a copy: the page
                          * stops before the socket); "": no page */
} daemon_ctx;

/* server_request_fn; user is the daemon_ctx. */
void dispatch_request(server *s, server_token tok, const char *line, size_t len, void *user);

#endif
