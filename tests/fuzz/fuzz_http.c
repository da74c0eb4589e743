/* fuzz_http.c - libFuzzer target: specklabd's web page server (daemon/web.h)
 * from raw bytes on a connection to the reply: libsoup's request parsing,
 * then web.c's connection handling, webroute.c's endpoints, webws.c's
 * event stream (an Upgrade input becomes a WebSocket whose frames are
 * the rest of the input), webstate.c's and webhist.c's JSON.
 *
 * The daemon around it: the real configuration (config.c: built-in
 * defaults, data in a scratch directory), a real catalogue there (the
 * history's queries run, on empty tables), the real view thread and frame
 * tap with one 48x40 frame taken and rendered in every stretch before the
 * first input (so image requests answer at once, never wait).  Stand-ins
 * for the runner (a run acquiring, both wheels known) and the worker.
 * No listener: each input's connection is one end of a socketpair handed
 * to web_accept, as the listener hands its own.
 *
 * The input is written, the client's side shut for writing, and the main
 * context run until the server has closed (or 3 s pass).  Contract checks
 * abort (a finding):
 *   - what comes back is empty or starts with "HTTP/1.", and a reply
 *     with a status has a valid one (100..599);
 *   - the server closes its end within 3 s of the client's shutdown
 *     (nothing hangs on a bad request);
 *   - afterwards no connection is left (web_nconnections 0: nothing
 *     leaks a connection);
 *   - no leak, no memory error (libFuzzer, ASan, UBSan).
 * SL_FUZZ_VERBOSE=1 prints each reply's first line.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <glib.h>
#include <gio/gio.h>
#include <poll.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#define FUZZ_NAME "fuzz_http"
#include "fuzz_util.h"

#include "config.h"
#include "web.h"
#include "webpng.h"
#include "webview.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define FRAME_W 48
#define FRAME_H 40
#define CLOSE_S 3.0

static struct {
    char root[96];
    config cfg;
    webtap *tap;
    web *w;
} FZ;

/* ---- stand-ins for the runner and the worker -------------------------------------- */

void runner_status_get(runner *r, runner_status *out)
{
    (void)r;
    memset(out, 0, sizeof *out);
    snprintf(out->current, sizeof out->current, "22222222-2222-4222-8222-222222222222");
    out->state = CATALOG_ACQUIRING;
    out->frames_acquired = 30;
    out->frames_requested = 100;
    out->frames_failed = 1;
    out->packets_missing = 7;
    out->queue = g_new0(char *, 1);
    out->stage_connected = out->stage_known = 1;
    for (int w = 0; w < STAGE_NWHEELS; w++) {
        out->wheels[w].wheel = w;
        out->wheels[w].slots = 6;
        out->wheels[w].position = w ? 1 : 3;
        out->wheels[w].homed = out->wheels[w].in_position = 1;
    }
    snprintf(out->camera_error, sizeof out->camera_error, "fuzz harness: no camera");
}

webtap *runner_tap(runner *r)
{
    (void)r;
    return FZ.tap;
}

void worker_status(worker *w, char current[CATALOG_UUID_LEN + 1], int *queued)
{
    (void)w;
    current[0] = '\0';
    *queued = 0;
}

/* ---- set-up ---------------------------------------------------------------------- */

static void fz_die(const char *what, const char *msg)
{
    fprintf(stderr, "%s: setup: %s: %s\n", FUZZ_NAME, what, msg);
    abort();
}

/* One frame through the tap, rendered in every stretch by the view. */
static void prime_view(void)
{
    float px[FRAME_W * FRAME_H];
    for (int i = 0; i < FRAME_W * FRAME_H; i++)
        px[i] = (float)(100 + (i * 7919) % 251);
    GMainContext *ctx = g_main_context_default();
    gint64 end = g_get_monotonic_time() + 10 * G_USEC_PER_SEC;
    for (;;) {
        /* an HTTP-less demand, as a request would make it */
        int ready = 1;
        webtap_want(FZ.tap);
        webtap_offer(FZ.tap, "22222222-2222-4222-8222-222222222222", px, FRAME_W, FRAME_H);
        for (int s = 0; s < WEB_NSTRETCH; s++) {
            GBytes *b = webview_frame_png(web_view(FZ.w), s, NULL);
            webview_demand(web_view(FZ.w), 10, s);
            ready &= b != NULL;
            if (b)
                g_bytes_unref(b);
        }
        GBytes *ps = webview_powspec_png(web_view(FZ.w), NULL, NULL);
        ready &= ps != NULL;
        if (ps)
            g_bytes_unref(ps);
        if (ready)
            return;
        if (g_get_monotonic_time() > end)
            fz_die("view", "no images within 10 s");
        g_main_context_iteration(ctx, FALSE);
        g_usleep(20000);
    }
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc, (void)argv;
    sl_err e = {0};
    const char *base = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : g_get_tmp_dir();
    snprintf(FZ.root, sizeof FZ.root, "%s/fuzz_http.XXXXXX", base);
    if (!mkdtemp(FZ.root))
        fz_die("mkdtemp", strerror(errno));
    char *data = g_build_filename(FZ.root, "var", NULL);
    if (config_load(&FZ.cfg, NULL, NULL, data, &e) != SL_OK)
        fz_die("config", e.msg);
    g_free(data);
    g_mkdir_with_parents(FZ.cfg.data_dir, 0750);
    FZ.cfg.web_max_connections = 8;
    g_main_context_acquire(g_main_context_default());
    FZ.tap = webtap_new();
    web_opts o = {&FZ.cfg, NULL, NULL, g_get_monotonic_time()};
    if (web_new(&FZ.w, &o, &e) != SL_OK)
        fz_die("web_new", e.msg);
    prime_view();
    return 0;
}

/* ---- one input -------------------------------------------------------------------- */

static void serve(int fd)
{
    GError *ge = NULL;
    GSocket *s = g_socket_new_from_fd(fd, &ge);
    if (!s)
        fz_die("g_socket_new_from_fd", ge->message);
    GSocketConnection *c = g_socket_connection_factory_create_connection(s);
    web_accept(FZ.w, G_IO_STREAM(c));
    g_object_unref(c);
    g_object_unref(s);
}

/* Write the input while the server runs, then shut the client's side. */
static void send_input(int cfd, const uint8_t *data, size_t size, GString *reply)
{
    size_t off = 0;
    gint64 end = g_get_monotonic_time() + CLOSE_S * G_USEC_PER_SEC;
    char buf[65536];
    while (off < size && g_get_monotonic_time() < end) {
        ssize_t n = send(cfd, data + off, size - off, MSG_NOSIGNAL | MSG_DONTWAIT);
        if (n > 0)
            off += (size_t)n;
        else if (n < 0 && errno != EAGAIN && errno != EINTR)
            break;   /* the server closed early: fine */
        ssize_t r = recv(cfd, buf, sizeof buf, MSG_DONTWAIT);
        if (r > 0)
            g_string_append_len(reply, buf, r);
        g_main_context_iteration(NULL, FALSE);
    }
    shutdown(cfd, SHUT_WR);
}

/* Run the server until it closes its end; 0 when it did in time. */
static int read_reply(int cfd, GString *reply)
{
    gint64 end = g_get_monotonic_time() + CLOSE_S * G_USEC_PER_SEC;
    char buf[65536];
    while (g_get_monotonic_time() < end) {
        ssize_t r = recv(cfd, buf, sizeof buf, MSG_DONTWAIT);
        if (r > 0) {
            if (reply->len < (1u << 24))
                g_string_append_len(reply, buf, r);
            continue;
        }
        if (r == 0 || (r < 0 && errno != EAGAIN && errno != EINTR))
            return 0;
        if (!g_main_context_iteration(NULL, FALSE))
            g_usleep(200);
    }
    return -1;
}

static void check_reply(const GString *reply)
{
    if (getenv("SL_FUZZ_VERBOSE"))
        fprintf(stderr, "%s: %zu bytes back: %.*s\n", FUZZ_NAME, reply->len,
                (int)strcspn(reply->str, "\r\n"), reply->str);
    if (reply->len == 0)
        return;
    require(reply->len >= 12 && !strncmp(reply->str, "HTTP/1.", 7), "reply",
            "the server sent something that is not an HTTP reply");
    int status = atoi(reply->str + 9);
    require(status >= 100 && status <= 599, "reply", "status outside 100..599");
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    int sv[2];
    if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0)
        fz_die("socketpair", strerror(errno));
    GString *reply = g_string_new(NULL);
    serve(sv[1]);
    send_input(sv[0], data, size, reply);
    require(read_reply(sv[0], reply) == 0, "close",
            "the server did not close within 3 s of the client's shutdown");
    close(sv[0]);
    check_reply(reply);
    g_string_free(reply, TRUE);
    gint64 end = g_get_monotonic_time() + CLOSE_S * G_USEC_PER_SEC;
    while (web_nconnections(FZ.w) > 0 && g_get_monotonic_time() < end)
        if (!g_main_context_iteration(NULL, FALSE))
            g_usleep(200);
    require(web_nconnections(FZ.w) == 0, "connections", "a connection outlived its input");
    return 0;
}
