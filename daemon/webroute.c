/* webroute.c - the web page's HTTP endpoints (see web.h): the page, the
 * JSON, the images, and the image requests that wait for a first render.
 */
#define _GNU_SOURCE
#include "webint.h"

#include <stdio.h>
#include <string.h>

#include "webpng.h"

/* glib-compile-resources (webpage.gresource.xml): the page, compiled in. */
GResource *web_res_get_resource(void);

#define PAGE_PATH "/org/specklab/web/webpage.html"
#define PAGE_CSP "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; " \
                 "img-src 'self'; connect-src 'self'; base-uri 'none'; form-action 'none'"

enum { IMG_FRAME, IMG_POWSPEC };

/* An image request waiting for the view's first render. */
typedef struct webwait {
    SoupServerMessage *msg;
    int kind, stretch;
    gint64 deadline;
} webwait;

static void reply_bytes(SoupServerMessage *msg, guint status, const char *type, GBytes *body)
{
    SoupMessageHeaders *h = soup_server_message_get_response_headers(msg);
    soup_server_message_set_status(msg, status, NULL);
    soup_message_headers_replace(h, "Cache-Control", "no-store");
    soup_message_headers_replace(h, "X-Content-Type-Options", "nosniff");
    soup_message_headers_set_content_type(h, type, NULL);
    if (body)
        soup_message_body_append_bytes(soup_server_message_get_response_body(msg), body);
}

static void reply_text(SoupServerMessage *msg, guint status, const char *type, const char *text)
{
    GBytes *b = g_bytes_new(text, strlen(text));
    reply_bytes(msg, status, type, b);
    g_bytes_unref(b);
}

static void page(web *w, SoupServerMessage *msg, GHashTable *query)
{
    (void)w, (void)query;
    GBytes *b = g_resource_lookup_data(web_res_get_resource(), PAGE_PATH, 0, NULL);
    if (!b) {
        reply_text(msg, 500, "text/plain", "the page is missing from this build\n");
        return;
    }
    reply_bytes(msg, 200, "text/html; charset=utf-8", b);
    soup_message_headers_replace(soup_server_message_get_response_headers(msg),
                                 "Content-Security-Policy", PAGE_CSP);
    g_bytes_unref(b);
}

static void status(web *w, SoupServerMessage *msg, GHashTable *query)
{
    (void)query;
    reply_text(msg, 200, "application/json", web_status_json(w));
}

static void history(web *w, SoupServerMessage *msg, GHashTable *query)
{
    (void)query;
    reply_text(msg, 200, "application/json", web_history_json(w));
}

static void recon(web *w, SoupServerMessage *msg, GHashTable *query)
{
    (void)query;
    GBytes *b = web_recon_png(w);
    if (!b) {
        reply_text(msg, 404, "text/plain", "no reconstruction yet\n");
        return;
    }
    reply_bytes(msg, 200, "image/png", b);
    g_bytes_unref(b);
}

/* The image if there is one now (1: replied); 0: none yet. */
static int try_image(web *w, SoupServerMessage *msg, int kind, int stretch)
{
    guint64 seq = 0;
    long n = 0;
    GBytes *b = kind == IMG_FRAME ? webview_frame_png(w->view, stretch, &seq)
                                  : webview_powspec_png(w->view, &seq, &n);
    if (!b)
        return 0;
    reply_bytes(msg, 200, "image/png", b);
    char num[32];
    SoupMessageHeaders *h = soup_server_message_get_response_headers(msg);
    snprintf(num, sizeof num, "%" G_GUINT64_FORMAT, seq);
    soup_message_headers_replace(h, "X-Frame-Seq", num);
    if (kind == IMG_POWSPEC) {
        snprintf(num, sizeof num, "%ld", n);
        soup_message_headers_replace(h, "X-Frames-Averaged", num);
    }
    g_bytes_unref(b);
    return 1;
}

/* No image yet: wait for the view (paused) unless nothing can come. */
static void image(web *w, SoupServerMessage *msg, GHashTable *query, int kind)
{
    const char *sname = query ? g_hash_table_lookup(query, "stretch") : NULL;
    int stretch = kind == IMG_FRAME ? web_stretch_parse(sname ? sname : "linear") : -1;
    if (kind == IMG_FRAME && stretch < 0) {
        reply_text(msg, 400, "text/plain", "stretch: expected linear, sqrt, log or asinh\n");
        return;
    }
    const char *hz = query ? g_hash_table_lookup(query, "hz") : NULL;
    webview_demand(w->view, hz ? g_ascii_strtod(hz, NULL) : 2, stretch);   /* clamped there */
    if (try_image(w, msg, kind, stretch))
        return;
    webview_info vi;
    runner_status rs;
    webview_info_get(w->view, &vi);
    runner_status_get(w->run, &rs);
    int coming = rs.current[0] != '\0' || vi.seq > 0 || webtap_seq(runner_tap(w->run)) > 0;
    g_strfreev(rs.queue);
    if (!coming || w->stopped) {
        reply_text(msg, 503, "text/plain", "no frame yet: start a run\n");
        soup_message_headers_replace(soup_server_message_get_response_headers(msg),
                                     "Retry-After", "2");
        return;
    }
    webwait *wt = g_new0(webwait, 1);
    wt->msg = g_object_ref(msg);
    wt->kind = kind, wt->stretch = stretch;
    wt->deadline = g_get_monotonic_time() + WEB_WAIT_US;
    soup_server_message_pause(msg);
    g_queue_push_tail(&w->waits, wt);
}

void web_waits_serve(web *w, int expire_all)
{
    gint64 now = g_get_monotonic_time();
    for (GList *l = w->waits.head, *next; l; l = next) {
        webwait *wt = l->data;
        next = l->next;
        int done = !expire_all && try_image(w, wt->msg, wt->kind, wt->stretch);
        if (!done && (expire_all || now >= wt->deadline)) {
            reply_text(wt->msg, 503, "text/plain", "no frame yet\n");
            done = 1;
        }
        if (done) {
            g_queue_delete_link(&w->waits, l);
            soup_server_message_unpause(wt->msg);
            g_object_unref(wt->msg);
            g_free(wt);
        }
    }
}

static void frame(web *w, SoupServerMessage *msg, GHashTable *query)
{
    image(w, msg, query, IMG_FRAME);
}

static void powspec(web *w, SoupServerMessage *msg, GHashTable *query)
{
    image(w, msg, query, IMG_POWSPEC);
}

typedef void (*route_fn)(web *w, SoupServerMessage *msg, GHashTable *query);

static const struct {
    const char *path;
    route_fn fn;
} routes[] = {
    {"/", page},
    {"/index.html", page},
    {"/api/status", status},
    {"/api/history", history},
    {"/api/frame.png", frame},
    {"/api/powspec.png", powspec},
    {"/api/recon.png", recon},
};

/* Served on loopback, the page answers only to a Host that is an IP
 * address or localhost: a name another site's DNS points at 127.0.0.1
 * (DNS rebinding) must not let that site's scripts read the bench. */
int web_host_ok(const web *w, SoupServerMessage *msg)
{
    const char *host = soup_message_headers_get_one(
        soup_server_message_get_request_headers(msg), "Host");
    if (!w->cfg->web_loopback || !host)
        return 1;   /* HTTP/1.0 without Host: no browser sends that */
    char name[300];
    const char *end = host[0] == '[' ? strchr(host, ']') : strrchr(host, ':');
    size_t n = host[0] == '[' ? (end ? (size_t)(end - host) + 1 : 0)
                              : end ? (size_t)(end - host) : strlen(host);
    if (n == 0 || n >= sizeof name)
        return 0;
    memcpy(name, host, n);
    name[n] = '\0';
    if (!g_ascii_strcasecmp(name, "localhost"))
        return 1;
    if (name[0] == '[') {
        name[n - 1] = '\0';
        return g_hostname_is_ip_address(name + 1) && strchr(name + 1, ':');
    }
    return g_hostname_is_ip_address(name);
}

void web_route(SoupServer *s, SoupServerMessage *msg, const char *path, GHashTable *query,
               gpointer user)
{
    web *w = user;
    (void)s;
    const char *method = soup_server_message_get_method(msg);
    if (w->stopped) {
        reply_text(msg, 503, "text/plain", "specklabd is stopping\n");
        return;
    }
    if (!web_host_ok(w, msg)) {
        reply_text(msg, 421, "text/plain", "this page answers to an IP address or localhost\n");
        soup_server_message_set_status(msg, 421, "Misdirected Request");
        return;
    }
    for (size_t i = 0; i < G_N_ELEMENTS(routes); i++)
        if (path && !strcmp(path, routes[i].path)) {
            if (method != SOUP_METHOD_GET && method != SOUP_METHOD_HEAD) {
                reply_text(msg, 405, "text/plain", "read-only: GET or HEAD\n");
                soup_message_headers_replace(soup_server_message_get_response_headers(msg),
                                             "Allow", "GET, HEAD");
                return;
            }
            routes[i].fn(w, msg, query);
            return;
        }
    reply_text(msg, 404, "text/plain", "not found\n");
}
