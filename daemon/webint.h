/* webint.h - what web.c (server, connections), webroute.c (the HTTP
 * endpoints), webws.c (the event stream) and webstate.c (the JSON)
 * share.  Not for other modules. */
#ifndef SL_DAEMON_WEBINT_H
#define SL_DAEMON_WEBINT_H

#include <libsoup/soup.h>

#include "catalog.h"
#include "web.h"
#include "webview.h"

#define WEB_REQUEST_S 10          /* a connection's request and reply, at most */
#define WEB_SILENT_S 60           /* socket inactivity that closes it */
#define WEB_WAIT_US 2000000       /* an image request waits for a first render */
#define WEB_WS_MAX_MSG 4096       /* incoming WebSocket message */
#define WEB_WS_BACKLOG (256 * 1024) /* unsent bytes that pause a WebSocket */
#define WEB_RATE_SAMPLES 32
#define WEB_HEAD_MAX 32768        /* request head, checked by webpeek.c */

/* A rate estimate's sample: frames acquired at a time. */
typedef struct web_sample {
    gint64 t_us;
    int n;
} web_sample;

struct web {
    const config *cfg;
    runner *run;
    worker *wk;
    gint64 started_us;
    webview *view;
    SoupServer *soup;
    GSocketService *svc;           /* NULL: no listener */
    char url[160];
    GHashTable *conns;             /* GIOStream* -> webconn* (weak refs) */
    GQueue waits;                  /* webwait*: image requests waiting */
    GPtrArray *ws;                 /* webws*: event streams */
    guint sweep_id;
    gint notify_queued;            /* atomic: a products idle is queued */
    guint notify_id;
    int stopped;
    /* webstate.c's caches (main thread) */
    catalog *cat;                  /* read-only use; NULL: no history */
    char *status_json;
    gint64 status_us;
    char *history_json;
    gint64 history_us;
    gint64 recon_id;               /* the last reconstruction's */
    char *recon_png;               /* its figure, checked under DATA_DIR/recon */
    GBytes *recon_bytes;
    char *recon_bytes_path;
    char run_uuid[CATALOG_UUID_LEN + 1];   /* the run the caches below are of */
    char *run_screen, *run_mask, *run_object;
    web_sample samples[WEB_RATE_SAMPLES];
    int nsamples;
};

/* webpeek.c: a new connection's request head checked before libsoup;
 * web_peek_done (web.c) gets the verdict: st 1 hands it on, else it is
 * answered (refused) or closed by the peek. */
typedef struct webpeek webpeek;
webpeek *web_peek_start(web *w, GIOStream *io, GSocket *s);
void web_peek_cancel(webpeek *p);
void web_peek_done(web *w, webpeek *p, GIOStream *io, int st);

/* webroute.c: the default handler, and the image requests that wait. */
void web_route(SoupServer *s, SoupServerMessage *msg, const char *path, GHashTable *query,
               gpointer user);
void web_waits_serve(web *w, int expire_all);
int web_host_ok(const web *w, SoupServerMessage *msg);

/* webws.c */
void web_ws_open(SoupServer *s, SoupServerMessage *msg, const char *path,
                 SoupWebsocketConnection *c, gpointer user);
void web_ws_close_all(web *w);
/* Mark a connection as upgraded (no request deadline) - web.c; remote:
 * soup_server_message_get_remote_address of its request. */
void web_conn_upgraded(web *w, GSocketAddress *remote);

/* webstate.c: JSON texts (owned by w, valid until the next call). */
const char *web_status_json(web *w);
const char *web_history_json(web *w);
/* The last reconstruction's figure (a reference), NULL when none. */
GBytes *web_recon_png(web *w);
void web_state_clear(web *w);

#endif
