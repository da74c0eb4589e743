/* web.h - specklabd's read-only web page of the bench (libsoup 3, on the
 * daemon's GLib main context).
 *
 * Endpoints (GET and HEAD; any other method 405, unknown paths 404):
 *   /                 the page: one self-contained HTML document (inline
 *                     CSS and JS, no external resource; webpage.html)
 *   /api/status       JSON: daemon, run (state, counters, rate, ETA),
 *                     camera, stage (both wheels, their slots and what
 *                     they hold), reconstruction queue, view
 *   /api/history      JSON: r0 per screen over the last 30 days, the last
 *                     reconstruction and its binary measure
 *   /api/frame.png    the latest frame, ?stretch=linear|sqrt|log|asinh
 *   /api/powspec.png  the running mean power spectrum, log scale
 *                     (both: ?hz=N, the rate the caller will poll at,
 *                     0.2..30, default 2: the view keeps them that fresh)
 *   /api/recon.png    the last reconstruction's figure
 *   /api/events       WebSocket: the status JSON pushed at ?hz=N (0.2..30,
 *                     default 2); a text message {"hz": N} changes it
 * The images are made on the view's thread (webview.h) from frames the
 * acquisition hands over without waiting (webtap.h); the JSON from the
 * runner's and worker's status and a read-only use of the catalogue
 * through a handle of the web's own (main thread).
 *
 * Served on loopback, a request whose Host is not an IP address or
 * localhost gets 421 (another site's name pointed at 127.0.0.1, DNS
 * rebinding, must not let its scripts read the bench), and a WebSocket
 * from a browser must come from the page's own Origin.
 *
 * Limits, so that a client cannot hurt the daemon: at most
 * cfg->web_max_connections connections (more get 503 and are closed); a
 * connection that has not completed its request within 10 s, or is silent
 * for 60 s, is closed (WebSockets are kept alive by pings); request
 * headers are capped by libsoup (100 KiB, then 400 and close); request
 * bodies are never kept (read and dropped); a WebSocket message over 4 KiB
 * closes it; a WebSocket whose client stops reading is not sent more
 * while 256 KiB wait in its socket.
 *
 * Threads: all of this runs on the thread of the main context; only the
 * view's thread computes, and it never touches a message.
 */
#ifndef SL_DAEMON_WEB_H
#define SL_DAEMON_WEB_H

#include <gio/gio.h>

#include "status.h"
#include "config.h"
#include "runner.h"
#include "webview.h"
#include "worker.h"

typedef struct web web;

typedef struct web_opts {
    const config *cfg;      /* web_host NULL: no listener (web_accept only) */
    runner *run;            /* status and the frame tap */
    worker *wk;
    gint64 started_us;      /* the daemon's start, g_get_monotonic_time */
} web_opts;

/* Listen on cfg->web_host:web_port (a non-loopback address is logged as a
 * warning), start the view's thread.  SL_EIO naming the address when it
 * cannot bind. */
int web_new(web **out, const web_opts *o, sl_err *err);
/* "http://HOST:PORT/" with the bound port; "" without a listener. */
const char *web_url(const web *w);
/* Serve a connection accepted elsewhere (the fuzz target's socketpair),
 * under the same limits. */
void web_accept(web *w, GIOStream *conn);
int web_nconnections(const web *w);
/* The view's thread (tests: to wait for its first images). */
webview *web_view(const web *w);
/* Stop listening, answer waiting requests, close every connection, stop
 * the view's thread.  Then run the main context dry before web_free. */
void web_stop(web *w);
void web_free(web *w);

#endif
