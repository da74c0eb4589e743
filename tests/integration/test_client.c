/* test_client.c - cli/client.c against a stub server that speaks
 * daemon/PROTOCOL.md on a Unix socket in a temporary directory.
 *
 * The stub is a thread of this process: it accepts one connection, reads
 * request lines and answers according to the request's cmd:
 *   echo     {"ok": true, "result": {"cmd", "id", "args"}}
 *   split    the echo reply written one byte per send()
 *   batch    two events, the echo reply and a third event in ONE send()
 *   big      a 300 kB string in the result (several reads of the client)
 *   fail     {"ok": false, "error": {"code": "not-found", "message": ...}}
 *   silent   no reply at all
 *   close    closes the connection
 *   garbage  a line that is not JSON
 * so each test drives the stub with its requests alone.  A second stub
 * (serve_busy) plays a daemon with every slot taken: it sends the `busy`
 * line and closes before reading anything.
 */
#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "client.h"
#include "tcheck.h"

#define BIG_LEN 300000

typedef struct stub {
    char dir[32], path[64];
    int lfd;
    pthread_t th;
    int nreq;        /* requests seen (read after join) */
    int max_line;    /* longest request line seen */
} stub;

static void send_all(int fd, const char *s, size_t n)
{
    while (n > 0) {
        ssize_t w = send(fd, s, n, MSG_NOSIGNAL);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return;
        s += w;
        n -= (size_t)w;
    }
}

static char *to_line(JsonObject *o)
{
    JsonNode *n = json_node_init_object(json_node_alloc(), o);
    char *s = json_to_string(n, FALSE);
    json_node_unref(n);
    char *line = g_strconcat(s, "\n", NULL);
    g_free(s);
    return line;
}

static char *echo_reply(gint64 id, const char *cmd, JsonObject *req, int big)
{
    JsonObject *r = json_object_new(), *res = json_object_new();
    json_object_set_int_member(r, "id", id);
    json_object_set_boolean_member(r, "ok", TRUE);
    json_object_set_string_member(res, "cmd", cmd);
    json_object_set_int_member(res, "id", id);
    JsonNode *a = json_object_get_member(req, "args");
    if (a)
        json_object_set_member(res, "args", json_node_copy(a));
    if (big) {
        char *s = g_malloc(BIG_LEN + 1);
        memset(s, 'x', BIG_LEN);
        s[BIG_LEN] = '\0';
        json_object_set_string_member(res, "blob", s);
        g_free(s);
    }
    json_object_set_object_member(r, "result", res);
    char *line = to_line(r);
    json_object_unref(r);
    return line;
}

static char *event_line(const char *run, int k)
{
    JsonObject *e = json_object_new();
    json_object_set_string_member(e, "event", "progress");
    json_object_set_string_member(e, "run", run);
    json_object_set_int_member(e, "frames_acquired", k);
    json_object_set_int_member(e, "frames_requested", 3);
    char *line = to_line(e);
    json_object_unref(e);
    return line;
}

/* Answer one request; 0 to stop serving. */
static int answer(stub *s, int fd, const char *line)
{
    JsonParser *p = json_parser_new();
    int go = 1;
    if (!json_parser_load_from_data(p, line, -1, NULL)) {
        static const char bad[] = "{\"id\":null,\"ok\":false,\"error\":"
                                  "{\"code\":\"bad-json\",\"message\":\"not JSON\"}}\n";
        send_all(fd, bad, sizeof bad - 1);
        goto free_parser;
    }
    JsonObject *req = json_node_get_object(json_parser_get_root(p));
    gint64 id = json_object_get_int_member(req, "id");
    const char *cmd = json_object_get_string_member(req, "cmd");
    s->nreq++;
    if (!strcmp(cmd, "echo") || !strcmp(cmd, "big")) {
        char *r = echo_reply(id, cmd, req, !strcmp(cmd, "big"));
        send_all(fd, r, strlen(r));
        g_free(r);
    } else if (!strcmp(cmd, "split")) {
        char *r = echo_reply(id, cmd, req, 0);
        for (size_t i = 0; r[i]; i++)
            send_all(fd, r + i, 1);
        g_free(r);
    } else if (!strcmp(cmd, "batch")) {
        char *e1 = event_line("r1", 1), *e2 = event_line("r1", 2), *e3 = event_line("r1", 3);
        char *r = echo_reply(id, cmd, req, 0);
        char *all = g_strconcat(e1, e2, r, e3, NULL);
        send_all(fd, all, strlen(all));
        g_free(e1); g_free(e2); g_free(e3); g_free(r); g_free(all);
    } else if (!strcmp(cmd, "fail")) {
        char *r = g_strdup_printf("{\"id\":%lld,\"ok\":false,\"error\":{\"code\":\"not-found\","
                                  "\"message\":\"no run abc123\"}}\n", (long long)id);
        send_all(fd, r, strlen(r));
        g_free(r);
    } else if (!strcmp(cmd, "garbage")) {
        send_all(fd, "this is not json\n", 17);
    } else if (!strcmp(cmd, "close")) {
        go = 0;
    } /* silent: nothing */
free_parser:
    g_object_unref(p);
    return go;
}

static void *serve(void *arg)
{
    stub *s = arg;
    int fd = accept(s->lfd, NULL, NULL);
    if (fd < 0)
        return NULL;
    GString *buf = g_string_new("");
    char chunk[4096];
    for (;;) {
        char *nl = memchr(buf->str, '\n', buf->len);
        if (nl) {
            size_t len = (size_t)(nl - buf->str);
            char *line = g_strndup(buf->str, len);
            if ((int)len > s->max_line)
                s->max_line = (int)len;
            g_string_erase(buf, 0, (gssize)len + 1);
            int go = answer(s, fd, line);
            g_free(line);
            if (!go)
                break;
            continue;
        }
        ssize_t n = read(fd, chunk, sizeof chunk);
        if (n <= 0)
            break;
        g_string_append_len(buf, chunk, n);
    }
    g_string_free(buf, TRUE);
    close(fd);
    return NULL;
}

/* A daemon at max_clients: the busy line, then the close, request unread. */
static void *serve_busy(void *arg)
{
    stub *s = arg;
    static const char busy[] = "{\"id\":null,\"ok\":false,\"error\":{\"code\":\"busy\","
                               "\"message\":\"too many clients (max_clients = 64); try "
                               "later\"}}\n";
    int fd = accept(s->lfd, NULL, NULL);
    if (fd >= 0) {
        send_all(fd, busy, sizeof busy - 1);
        close(fd);
    }
    return NULL;
}

static int stub_start_with(stub *s, void *(*fn)(void *))
{
    memset(s, 0, sizeof *s);
    snprintf(s->dir, sizeof s->dir, "/tmp/test_client.XXXXXX");
    if (!mkdtemp(s->dir))
        return -1;
    snprintf(s->path, sizeof s->path, "%.40s/d.sock", s->dir);
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", s->path);
    s->lfd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (s->lfd < 0 || bind(s->lfd, (struct sockaddr *)&sa, sizeof sa) < 0 ||
        listen(s->lfd, 4) < 0)
        return -1;
    return pthread_create(&s->th, NULL, fn, s) == 0 ? 0 : -1;
}

static int stub_start(stub *s)
{
    return stub_start_with(s, serve);
}

/* The client must be freed first: the stub serves until EOF. */
static void stub_stop(stub *s)
{
    pthread_join(s->th, NULL);
    close(s->lfd);
    unlink(s->path);
    rmdir(s->dir);
}

static client *connect_stub(stub *s)
{
    client *c = NULL;
    sl_err e = {0};
    if (stub_start(s) != 0 || client_connect(&c, s->path, 2000, &e) != SL_OK)
        return NULL;
    return c;
}

TEST(echo_matches_id_and_args)
{
    stub s;
    client *c = connect_stub(&s);
    CHECK(c, "connect to the stub at %s", s.path);
    JsonObject *args = json_object_new(), *res = NULL;
    json_object_set_string_member(args, "screen", "s\"1\n\\");  /* escapes survive */
    json_object_set_int_member(args, "frames", 100);
    int rc = client_call(c, "echo", args, 5000, &res);
    json_object_unref(args);
    int ok = rc == SL_OK && res && !strcmp(json_object_get_string_member(res, "cmd"), "echo");
    JsonObject *a = ok ? json_object_get_object_member(res, "args") : NULL;
    int same = a && !strcmp(json_object_get_string_member(a, "screen"), "s\"1\n\\") &&
               json_object_get_int_member(a, "frames") == 100;
    char msg[256];
    snprintf(msg, sizeof msg, "%s", client_errmsg(c));
    if (res)
        json_object_unref(res);
    client_free(c);
    stub_stop(&s);
    CHECK(ok, "rc %d: %s", rc, msg);
    CHECK(same, "the stub saw other args than were sent");
    CHECK(s.nreq == 1, "stub saw %d requests", s.nreq);
}

TEST(pipelined_replies_matched_by_id)
{
    stub s;
    client *c = connect_stub(&s);
    CHECK(c, "connect");
    gint64 id[3];
    int rc = SL_OK;
    for (int i = 0; i < 3 && rc == SL_OK; i++)
        rc = client_send(c, i == 1 ? "split" : "echo", NULL, &id[i]);
    /* ask out of order: 3rd, 1st, 2nd; each must get its own reply */
    int order[3] = {2, 0, 1}, good = rc == SL_OK;
    for (int k = 0; k < 3 && good; k++) {
        JsonObject *res = NULL;
        int i = order[k];
        good = client_wait_reply(c, id[i], 5000, &res) == SL_OK &&
               json_object_get_int_member(res, "id") == id[i] &&
               !strcmp(json_object_get_string_member(res, "cmd"), i == 1 ? "split" : "echo");
        if (res)
            json_object_unref(res);
    }
    int distinct = id[0] != id[1] && id[1] != id[2] && id[0] != id[2];
    client_free(c);
    stub_stop(&s);
    CHECK(distinct, "ids %lld %lld %lld", (long long)id[0], (long long)id[1], (long long)id[2]);
    CHECK(good, "a reply was not matched to its request");
}

TEST(events_interleaved_with_replies_are_kept_in_order)
{
    stub s;
    client *c = connect_stub(&s);
    CHECK(c, "connect");
    JsonObject *res = NULL, *ev = NULL;
    int rc = client_call(c, "batch", NULL, 5000, &res);
    int got_reply = rc == SL_OK && !strcmp(json_object_get_string_member(res, "cmd"), "batch");
    if (res)
        json_object_unref(res);
    /* a later call must not eat the third event either */
    rc = client_call(c, "echo", NULL, 5000, &res);
    if (res)
        json_object_unref(res);
    int seq_ok = rc == SL_OK;
    for (int k = 1; k <= 3 && seq_ok; k++) {
        seq_ok = client_next_event(c, 5000, &ev) == SL_OK && ev &&
                 !strcmp(json_object_get_string_member(ev, "event"), "progress") &&
                 json_object_get_int_member(ev, "frames_acquired") == k;
        if (ev)
            json_object_unref(ev);
        ev = NULL;
    }
    int quiet = client_next_event(c, 50, &ev) == SL_OK && ev == NULL;
    client_free(c);
    stub_stop(&s);
    CHECK(got_reply, "the reply was not found between the events");
    CHECK(seq_ok, "events lost or reordered");
    CHECK(quiet, "an event appeared from nowhere");
}

TEST(large_reply_spanning_many_reads)
{
    stub s;
    client *c = connect_stub(&s);
    CHECK(c, "connect");
    JsonObject *res = NULL;
    int rc = client_call(c, "big", NULL, 5000, &res);
    size_t len = rc == SL_OK ? strlen(json_object_get_string_member(res, "blob")) : 0;
    if (res)
        json_object_unref(res);
    client_free(c);
    stub_stop(&s);
    CHECK(len == BIG_LEN, "blob of %zu bytes, expected %d", len, BIG_LEN);
}

TEST(error_reply_carries_code_and_message)
{
    stub s;
    client *c = connect_stub(&s);
    CHECK(c, "connect");
    JsonObject *res = NULL;
    int rc = client_call(c, "fail", NULL, 5000, &res);
    char msg[256], code[64];
    snprintf(msg, sizeof msg, "%s", client_errmsg(c));
    snprintf(code, sizeof code, "%s", client_errcode(c) ? client_errcode(c) : "(null)");
    /* the connection stays usable after an error reply */
    JsonObject *res2 = NULL;
    int rc2 = client_call(c, "echo", NULL, 5000, &res2);
    int cleared = client_errcode(c) == NULL;
    if (res2)
        json_object_unref(res2);
    client_free(c);
    stub_stop(&s);
    CHECK(rc == CLIENT_EREMOTE && res == NULL, "rc %d", rc);
    CHECK(!strcmp(msg, "no run abc123"), "message '%s'", msg);
    CHECK(!strcmp(code, "not-found"), "code '%s'", code);
    CHECK(rc2 == SL_OK && cleared, "next call rc %d", rc2);
}

TEST(no_reply_times_out)
{
    stub s;
    client *c = connect_stub(&s);
    CHECK(c, "connect");
    JsonObject *res = NULL;
    int rc = client_call(c, "silent", NULL, 200, &res);
    int named = strstr(client_errmsg(c), "'silent'") != NULL;
    client_free(c);
    stub_stop(&s);
    CHECK(rc == CLIENT_ETIMEOUT, "rc %d", rc);
    CHECK(named, "timeout message does not name the request");
}

TEST(closed_connection_and_garbage_are_errors)
{
    stub s;
    client *c = connect_stub(&s);
    CHECK(c, "connect");
    JsonObject *res = NULL;
    int rc_g = client_call(c, "garbage", NULL, 5000, &res);
    int rc_c = client_call(c, "close", NULL, 5000, &res);
    JsonObject *ev = NULL;
    int rc_e = client_next_event(c, 1000, &ev);
    client_free(c);
    stub_stop(&s);
    CHECK(rc_g == SL_EFORMAT, "garbage line: rc %d", rc_g);
    CHECK(rc_c == SL_EIO, "closed connection: rc %d", rc_c);
    CHECK(rc_e == SL_EIO && ev == NULL, "event after close: rc %d", rc_e);
}

/* The daemon refused the connection and closed it before the request was
 * sent (the stub's thread has ended: joined before the call): the send
 * meets a broken pipe, and the client reports the daemon's busy line. */
TEST(refused_before_the_request_is_sent)
{
    stub s;
    client *c = NULL;
    sl_err e = {0};
    CHECK(stub_start_with(&s, serve_busy) == 0, "stub");
    int rc_conn = client_connect(&c, s.path, 2000, &e);
    pthread_join(s.th, NULL);
    JsonObject *res = NULL;
    int rc = rc_conn == SL_OK ? client_call(c, "status", NULL, 5000, &res) : rc_conn;
    char msg[SL_ERRMSG_MAX], code[32];
    snprintf(msg, sizeof msg, "%s", c ? client_errmsg(c) : e.msg);
    snprintf(code, sizeof code, "%s", c && client_errcode(c) ? client_errcode(c) : "");
    client_free(c);
    close(s.lfd);
    unlink(s.path);
    rmdir(s.dir);
    CHECK(rc == CLIENT_EREMOTE && !strcmp(code, "busy") && strstr(msg, "too many clients"),
          "rc %d, code '%s': %s", rc, code, msg);
}

TEST(oversized_request_refused_locally)
{
    stub s;
    client *c = connect_stub(&s);
    CHECK(c, "connect");
    JsonObject *args = json_object_new(), *res = NULL;
    char *big = g_malloc(CLIENT_REQUEST_MAX + 1);
    memset(big, 'a', CLIENT_REQUEST_MAX);
    big[CLIENT_REQUEST_MAX] = '\0';
    json_object_set_string_member(args, "object", big);
    g_free(big);
    int rc = client_call(c, "echo", args, 5000, &res);
    json_object_unref(args);
    JsonObject *res2 = NULL;
    int rc2 = client_call(c, "echo", NULL, 5000, &res2); /* still in sync */
    if (res2)
        json_object_unref(res2);
    client_free(c);
    stub_stop(&s);
    CHECK(rc == SL_EINVAL, "rc %d", rc);
    CHECK(rc2 == SL_OK && s.nreq == 1 && s.max_line < 1000,
          "rc2 %d, stub saw %d requests, longest %d bytes", rc2, s.nreq, s.max_line);
}

TEST(daemon_not_running)
{
    char dir[] = "/tmp/test_client.XXXXXX";
    CHECK(mkdtemp(dir), "mkdtemp");
    char path[64];
    snprintf(path, sizeof path, "%.40s/specklabd.sock", dir);
    client *c = NULL;
    sl_err e = {0};
    int rc = client_connect(&c, path, 1000, &e);
    int says = strstr(e.msg, path) && strstr(e.msg, "No such file or directory") &&
               strstr(e.msg, "start it with bin/specklabd");
    /* a socket file nobody listens on any more: refused, same advice */
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%s", path);
    int fd = socket(AF_UNIX, SOCK_STREAM, 0);
    int bound = fd >= 0 && bind(fd, (struct sockaddr *)&sa, sizeof sa) == 0;
    if (fd >= 0)
        close(fd);
    sl_err e2 = {0};
    int rc2 = bound ? client_connect(&c, path, 1000, &e2) : 0;
    unlink(path);
    rmdir(dir);
    CHECK(rc == CLIENT_EUNREACHABLE && c == NULL, "rc %d", rc);
    CHECK(says, "message: %s", e.msg);
    CHECK(bound, "could not make a dead socket");
    CHECK(rc2 == CLIENT_EUNREACHABLE && strstr(e2.msg, "refused"), "rc %d: %s", rc2, e2.msg);
}

TEST(socket_path_default_and_env)
{
    unsetenv("SPECKLAB_SOCKET");
    int def = !strcmp(client_socket_path(NULL), "./var/specklabd.sock") &&
              !strcmp(client_socket_path(""), "./var/specklabd.sock");
    setenv("SPECKLAB_SOCKET", "/run/x.sock", 1);
    int env = !strcmp(client_socket_path(NULL), "/run/x.sock") &&
              !strcmp(client_socket_path("/a.sock"), "/a.sock");
    unsetenv("SPECKLAB_SOCKET");
    char longp[200];
    memset(longp, 'p', sizeof longp - 1);
    longp[sizeof longp - 1] = '\0';
    client *c = NULL;
    sl_err e = {0};
    int rc = client_connect(&c, longp, 100, &e);
    CHECK(def, "default path");
    CHECK(env, "$SPECKLAB_SOCKET / explicit path precedence");
    CHECK(rc == SL_EINVAL && strstr(e.msg, "at most"), "long path: rc %d %s", rc, e.msg);
}

TC_MAIN(TC_CASE(echo_matches_id_and_args), TC_CASE(pipelined_replies_matched_by_id),
        TC_CASE(events_interleaved_with_replies_are_kept_in_order),
        TC_CASE(large_reply_spanning_many_reads), TC_CASE(error_reply_carries_code_and_message),
        TC_CASE(no_reply_times_out), TC_CASE(closed_connection_and_garbage_are_errors),
        TC_CASE(refused_before_the_request_is_sent),
        TC_CASE(oversized_request_refused_locally), TC_CASE(daemon_not_running),
        TC_CASE(socket_path_default_and_env))
