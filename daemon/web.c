/* web.c - the web page's server: listener, connections and their limits,
 * start and stop; see web.h.  The endpoints are in webroute.c, the event
 * stream in webws.c, the JSON in webstate.c.
 *
 * Connections are accepted here (a GSocketService), not by libsoup's own
 * listener, so that each is counted and bounded before libsoup sees it,
 * and so that the fuzz target's connection takes the very same path
 * (web_accept).  libsoup then serves one request per connection (it keeps
 * connections alive only for its own listeners), so a connection's life
 * is one request and its reply, bounded by WEB_REQUEST_S, unless it
 * becomes a WebSocket.
 */
#define _GNU_SOURCE
#include "webint.h"

#include <stdio.h>
#include <string.h>

#define SWEEP_MS 500

typedef struct webconn {
    GSocketAddress *local;
    GSocketAddress *remote;   /* the one given to libsoup: finds the connection again */
    webpeek *peek;            /* its head being checked (webpeek.c); NULL after */
    gint64 t0;           /* accepted */
    int upgraded;        /* a WebSocket now: no request deadline */
    int cut;             /* shut down by the deadline */
} webconn;

static void conn_free(gpointer p)
{
    webconn *c = p;
    g_clear_object(&c->local);
    g_clear_object(&c->remote);
    g_free(c);
}

static void conn_gone(gpointer user, GObject *gone)
{
    web *w = user;
    g_hash_table_remove(w->conns, gone);
}

static GSocket *conn_socket(GIOStream *io)
{
    return G_IS_SOCKET_CONNECTION(io) ? g_socket_connection_get_socket(G_SOCKET_CONNECTION(io))
                                      : NULL;
}

/* Too many connections: a short 503, then closed. */
static void refuse(GIOStream *io)
{
    static const char busy[] = "HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain\r\n"
                               "Content-Length: 35\r\nRetry-After: 1\r\nConnection: close\r\n"
                               "\r\ntoo many connections: retry later\r\n";
    GSocket *s = conn_socket(io);
    if (s) {
        g_socket_set_blocking(s, FALSE);
        g_socket_send(s, busy, sizeof busy - 1, NULL, NULL);
    }
    g_io_stream_close(io, NULL, NULL);
}

static void to_soup(web *w, webconn *c, GIOStream *io)
{
    GError *ge = NULL;
    if (!soup_server_accept_iostream(w->soup, io, c->local, c->remote, &ge)) {
        g_message("web: a connection not served: %s", ge ? ge->message : "?");
        g_clear_error(&ge);
        g_io_stream_close(io, NULL, NULL);
    }
}

void web_accept(web *w, GIOStream *io)
{
    if (w->stopped || (int)g_hash_table_size(w->conns) >= w->cfg->web_max_connections) {
        refuse(io);
        return;
    }
    GSocket *s = conn_socket(io);
    GSocketAddress *local = NULL, *remote = NULL;
    if (s && g_socket_get_family(s) != G_SOCKET_FAMILY_UNIX) {
        local = g_socket_get_local_address(s, NULL);
        remote = g_socket_get_remote_address(s, NULL);
    } else {   /* the fuzz target's socketpair: libsoup wants IP addresses */
        GInetAddress *lo = g_inet_address_new_loopback(G_SOCKET_FAMILY_IPV4);
        local = g_inet_socket_address_new(lo, 0);
        remote = g_inet_socket_address_new(lo, 0);
        g_object_unref(lo);
    }
    if (s)
        g_socket_set_timeout(s, WEB_SILENT_S);
    if (!local || !remote) {   /* the peer is gone already (reset) */
        g_io_stream_close(io, NULL, NULL);
    } else {
        webconn *c = g_new0(webconn, 1);
        c->t0 = g_get_monotonic_time();
        c->local = g_object_ref(local);
        c->remote = g_object_ref(remote);
        g_hash_table_insert(w->conns, io, c);
        g_object_weak_ref(G_OBJECT(io), conn_gone, w);
        if (s)
            c->peek = web_peek_start(w, io, s);
        else
            to_soup(w, c, io);
    }
    g_clear_object(&local);
    g_clear_object(&remote);
}

void web_peek_done(web *w, webpeek *p, GIOStream *io, int st)
{
    webconn *c = g_hash_table_lookup(w->conns, io);
    (void)p;
    if (c)
        c->peek = NULL;
    if (c && st == 1)
        to_soup(w, c, io);
}

void web_conn_upgraded(web *w, GSocketAddress *remote)
{
    GHashTableIter it;
    gpointer val;
    g_hash_table_iter_init(&it, w->conns);
    while (remote && g_hash_table_iter_next(&it, NULL, &val))
        if (((webconn *)val)->remote == remote)
            ((webconn *)val)->upgraded = 1;
}

int web_nconnections(const web *w)
{
    return (int)g_hash_table_size(w->conns);
}

webview *web_view(const web *w)
{
    return w->view;
}

static gboolean on_incoming(GSocketService *svc, GSocketConnection *conn, GObject *src,
                            gpointer user)
{
    (void)svc, (void)src;
    web_accept(user, G_IO_STREAM(conn));
    return TRUE;
}

/* Request deadlines, and image requests that waited long enough. */
static gboolean sweep(gpointer user)
{
    web *w = user;
    gint64 now = g_get_monotonic_time();
    GHashTableIter it;
    gpointer key, val;
    g_hash_table_iter_init(&it, w->conns);
    while (g_hash_table_iter_next(&it, &key, &val)) {
        webconn *c = val;
        GSocket *s = conn_socket(key);
        if (!c->upgraded && !c->cut && now - c->t0 > WEB_REQUEST_S * 1000000LL && s) {
            c->cut = 1;   /* libsoup sees the end of the stream and lets go */
            g_socket_shutdown(s, TRUE, TRUE, NULL);
        }
    }
    web_waits_serve(w, 0);
    return G_SOURCE_CONTINUE;
}

/* New images from the view's thread: answer the requests that waited. */
static gboolean products_idle(gpointer user)
{
    web *w = user;
    g_atomic_int_set(&w->notify_queued, 0);
    if (!w->stopped)
        web_waits_serve(w, 0);
    return G_SOURCE_REMOVE;
}

static void products_notify(void *user)
{
    web *w = user;
    if (g_atomic_int_compare_and_exchange(&w->notify_queued, 0, 1))
        g_idle_add(products_idle, w);
}

static void on_request_started(SoupServer *s, SoupServerMessage *msg, gpointer user)
{
    (void)s, (void)user;
    /* Bodies are never used: read and dropped, never kept in memory. */
    soup_message_body_set_accumulate(soup_server_message_get_request_body(msg), FALSE);
}

static int listen_on(web *w, sl_err *err)
{
    const config *cfg = w->cfg;
    GInetAddress *ia = g_inet_address_new_from_string(cfg->web_host);
    GSocketAddress *sa = ia ? g_inet_socket_address_new(ia, (guint16)cfg->web_port) : NULL;
    GSocketAddress *bound = NULL;
    GError *ge = NULL;
    w->svc = g_socket_service_new();
    int ok = sa && g_socket_listener_add_address(G_SOCKET_LISTENER(w->svc), sa,
                                                 G_SOCKET_TYPE_STREAM, G_SOCKET_PROTOCOL_TCP,
                                                 NULL, &bound, &ge);
    int rc = SL_OK;
    if (!ok) {
        rc = sl_seterr(err, SL_EIO, "web: cannot listen on %s:%d: %s", cfg->web_host,
                       cfg->web_port, ge ? ge->message : "not an address");
    } else {
        guint16 port = g_inet_socket_address_get_port(G_INET_SOCKET_ADDRESS(bound));
        int v6 = strchr(cfg->web_host, ':') != NULL;
        snprintf(w->url, sizeof w->url, "http://%s%s%s:%u/", v6 ? "[" : "", cfg->web_host,
                 v6 ? "]" : "", port);
        g_signal_connect(w->svc, "incoming", G_CALLBACK(on_incoming), w);
        if (!cfg->web_loopback)
            g_warning("web: the page is served on %s, a non-loopback address ([web] "
                      "allow_remote): anyone who reaches it sees the bench, without a password",
                      w->url);
    }
    g_clear_error(&ge);
    g_clear_object(&bound);
    g_clear_object(&sa);
    g_clear_object(&ia);
    return rc;
}

int web_new(web **out, const web_opts *o, sl_err *err)
{
    web *w = g_new0(web, 1);
    *out = NULL;
    w->cfg = o->cfg;
    w->run = o->run;
    w->wk = o->wk;
    w->started_us = o->started_us;
    w->conns = g_hash_table_new_full(NULL, NULL, NULL, conn_free);
    w->ws = g_ptr_array_new();
    g_queue_init(&w->waits);
    w->soup = soup_server_new("server-header", "specklabd", NULL);
    soup_server_add_handler(w->soup, NULL, web_route, w, NULL);
    soup_server_add_websocket_handler(w->soup, "/api/events", NULL, NULL, web_ws_open, w, NULL);
    g_signal_connect(w->soup, "request-started", G_CALLBACK(on_request_started), w);
    if (w->cfg->web_host && listen_on(w, err) != SL_OK) {
        web_free(w);
        return SL_EIO;
    }
    catalog_opts co = {w->cfg->catalog_busy_timeout_ms};
    sl_err ce = {0};
    if (catalog_open_opts(&w->cat, w->cfg->catalog, &co, &ce) != SL_OK) {
        g_warning("web: no r0 history or reconstructions on the page: %s", ce.msg);
        w->cat = NULL;
    }
    w->view = webview_new(runner_tap(w->run), products_notify, w);
    w->sweep_id = g_timeout_add(SWEEP_MS, sweep, w);
    *out = w;
    return SL_OK;
}

const char *web_url(const web *w)
{
    return w->url;
}

void web_stop(web *w)
{
    if (!w || w->stopped)
        return;
    w->stopped = 1;
    if (w->svc) {
        g_socket_service_stop(w->svc);
        g_socket_listener_close(G_SOCKET_LISTENER(w->svc));
    }
    web_waits_serve(w, 1);
    web_ws_close_all(w);
    GHashTableIter it;
    gpointer key, val;
    GPtrArray *peeks = g_ptr_array_new();
    g_hash_table_iter_init(&it, w->conns);
    while (g_hash_table_iter_next(&it, &key, &val)) {
        GSocket *s = conn_socket(key);
        if (((webconn *)val)->peek)
            g_ptr_array_add(peeks, ((webconn *)val)->peek), ((webconn *)val)->peek = NULL;
        else if (s)
            g_socket_shutdown(s, TRUE, TRUE, NULL);
    }
    for (guint i = 0; i < peeks->len; i++)   /* may drop connections from the table */
        web_peek_cancel(peeks->pdata[i]);
    g_ptr_array_free(peeks, TRUE);
    webview_free(w->view);   /* joins: no products notice after this */
    w->view = NULL;
    if (w->sweep_id)
        g_source_remove(w->sweep_id);
    w->sweep_id = 0;
}

void web_free(web *w)
{
    if (!w)
        return;
    web_stop(w);
    while (g_idle_remove_by_data(w))
        ;
    web_ws_close_all(w);
    if (w->soup) {
        soup_server_disconnect(w->soup);
        g_object_unref(w->soup);
    }
    GHashTableIter it;
    gpointer key;
    g_hash_table_iter_init(&it, w->conns);
    while (g_hash_table_iter_next(&it, &key, NULL))
        g_object_weak_unref(key, conn_gone, w);
    g_hash_table_destroy(w->conns);
    g_clear_object(&w->svc);
    g_ptr_array_free(w->ws, TRUE);
    web_state_clear(w);
    catalog_close(w->cat);
    g_free(w);
}
