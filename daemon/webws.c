/* webws.c - the web page's event stream: the status JSON pushed over a
 * WebSocket at the rate each viewer chooses (see web.h).
 *
 * Each viewer has its own timer at its own rate, and asks the view
 * (webview.h) for images at that rate.  A viewer that stops reading is
 * not queued more: while WEB_WS_BACKLOG bytes wait unsent in its socket
 * (SIOCOUTQ), its updates are skipped, so libsoup's own queue stays
 * bounded and a stalled browser costs the daemon nothing.
 */
#define _GNU_SOURCE
#include "webint.h"

#include <stdio.h>
#include <json-glib/json-glib.h>
#include <linux/sockios.h>
#include <string.h>
#include <sys/ioctl.h>

#define DEFAULT_HZ 2.0

typedef struct webws {
    web *w;
    SoupWebsocketConnection *c;
    double hz;
    guint timer;
    guint64 sent, skipped;
} webws;

static double clamp_hz(double hz)
{
    return !(hz >= WEBVIEW_MIN_HZ) ? WEBVIEW_MIN_HZ : hz > WEBVIEW_MAX_HZ ? WEBVIEW_MAX_HZ : hz;
}

/* Bytes written but not yet taken by the peer; 0 when unknown. */
static int backlog(SoupWebsocketConnection *c)
{
    GIOStream *io = soup_websocket_connection_get_io_stream(c);
    int n = 0;
    if (G_IS_SOCKET_CONNECTION(io)) {
        GSocket *s = g_socket_connection_get_socket(G_SOCKET_CONNECTION(io));
        if (ioctl(g_socket_get_fd(s), SIOCOUTQ, &n) != 0)
            n = 0;
    }
    return n;
}

static void push(webws *v)
{
    if (soup_websocket_connection_get_state(v->c) != SOUP_WEBSOCKET_STATE_OPEN)
        return;
    if (backlog(v->c) > WEB_WS_BACKLOG) {
        v->skipped++;
        return;
    }
    webview_demand(v->w->view, v->hz, -1);
    soup_websocket_connection_send_text(v->c, web_status_json(v->w));
    v->sent++;
}

static gboolean on_tick(gpointer user)
{
    push(user);
    return G_SOURCE_CONTINUE;
}

static void schedule(webws *v)
{
    if (v->timer)
        g_source_remove(v->timer);
    v->timer = g_timeout_add((guint)(1000.0 / v->hz + 0.5), on_tick, v);
}

/* {"hz": N}: the viewer's rate.  Anything else is ignored. */
static void on_message(SoupWebsocketConnection *c, gint type, GBytes *msg, gpointer user)
{
    webws *v = user;
    gsize len = 0;
    const char *text = g_bytes_get_data(msg, &len);
    (void)c;
    if (type != SOUP_WEBSOCKET_DATA_TEXT || !text || len == 0)
        return;
    JsonParser *p = json_parser_new();
    if (json_parser_load_from_data(p, text, (gssize)len, NULL)) {
        JsonNode *root = json_parser_get_root(p);
        JsonObject *o = root && JSON_NODE_HOLDS_OBJECT(root) ? json_node_get_object(root) : NULL;
        JsonNode *hz = o ? json_object_get_member(o, "hz") : NULL;
        if (hz && JSON_NODE_HOLDS_VALUE(hz) &&
            (json_node_get_value_type(hz) == G_TYPE_DOUBLE ||
             json_node_get_value_type(hz) == G_TYPE_INT64)) {
            v->hz = clamp_hz(json_node_get_double(hz));
            schedule(v);
            push(v);
        }
    }
    g_object_unref(p);
}

static void forget(webws *v)
{
    if (v->timer)
        g_source_remove(v->timer);
    v->timer = 0;
    g_signal_handlers_disconnect_by_data(v->c, v);
    g_ptr_array_remove(v->w->ws, v);
    g_object_unref(v->c);
    g_free(v);
}

static void on_closed(SoupWebsocketConnection *c, gpointer user)
{
    (void)c;
    forget(user);
}

/* A browser's Origin must be this page's own (the Host it asked): another
 * site's script must not read the bench.  No Origin: not a browser. */
static int origin_ok(SoupServerMessage *msg)
{
    SoupMessageHeaders *h = soup_server_message_get_request_headers(msg);
    const char *origin = soup_message_headers_get_one(h, "Origin");
    const char *host = soup_message_headers_get_one(h, "Host");
    if (!origin)
        return 1;
    GUri *u = g_uri_parse(origin, G_URI_FLAGS_NONE, NULL);
    int ok = 0;
    if (u && host && g_uri_get_host(u) && !g_strcmp0(g_uri_get_scheme(u), "http")) {
        int port = g_uri_get_port(u);
        int v6 = strchr(g_uri_get_host(u), ':') != NULL;
        char *want = port > 0 ? g_strdup_printf("%s%s%s:%d", v6 ? "[" : "", g_uri_get_host(u),
                                                v6 ? "]" : "", port)
                              : g_strdup_printf("%s%s%s", v6 ? "[" : "", g_uri_get_host(u),
                                                v6 ? "]" : "");
        ok = !g_ascii_strcasecmp(want, host);
        g_free(want);
    }
    if (u)
        g_uri_unref(u);
    return ok;
}

void web_ws_open(SoupServer *s, SoupServerMessage *msg, const char *path,
                 SoupWebsocketConnection *c, gpointer user)
{
    web *w = user;
    (void)s;
    if (w->stopped || g_strcmp0(path, "/api/events") || !origin_ok(msg) ||
        !web_host_ok(w, msg)) {
        soup_websocket_connection_close(c, SOUP_WEBSOCKET_CLOSE_POLICY_VIOLATION,
                                        w->stopped ? "stopping" : "not this page's");
        return;
    }
    web_conn_upgraded(w, soup_server_message_get_remote_address(msg));
    webws *v = g_new0(webws, 1);
    v->w = w;
    v->c = g_object_ref(c);
    GUri *u = soup_server_message_get_uri(msg);
    GHashTable *q = u && g_uri_get_query(u) ? soup_form_decode(g_uri_get_query(u)) : NULL;
    const char *hz = q ? g_hash_table_lookup(q, "hz") : NULL;
    v->hz = clamp_hz(hz ? g_ascii_strtod(hz, NULL) : DEFAULT_HZ);
    if (q)
        g_hash_table_unref(q);
    soup_websocket_connection_set_max_incoming_payload_size(c, WEB_WS_MAX_MSG);
    soup_websocket_connection_set_keepalive_interval(c, WEB_SILENT_S / 3);
    g_signal_connect(c, "message", G_CALLBACK(on_message), v);
    g_signal_connect(c, "closed", G_CALLBACK(on_closed), v);
    g_ptr_array_add(w->ws, v);
    push(v);
    schedule(v);
}

void web_ws_close_all(web *w)
{
    while (w->ws->len > 0) {
        webws *v = g_ptr_array_index(w->ws, w->ws->len - 1);
        SoupWebsocketConnection *c = g_object_ref(v->c);
        forget(v);
        if (soup_websocket_connection_get_state(c) == SOUP_WEBSOCKET_STATE_OPEN)
            soup_websocket_connection_close(c, SOUP_WEBSOCKET_CLOSE_GOING_AWAY,
                                            "specklabd is stopping");
        g_object_unref(c);
    }
}
