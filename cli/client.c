/* client.c - see client.h.
 *
 * The socket is non-blocking and every wait is a poll() against an
 * absolute monotonic deadline, so no call can hang past its timeout however
 * the daemon trickles bytes.  Incoming bytes accumulate in one buffer that
 * is cut at '\n'; each line is parsed by json-glib and sorted into events
 * (FIFO) or replies (table by id) before the caller sees it, which is what
 * lets events interleave freely with replies.
 */
/* struct ucred (SO_PEERCRED) is a GNU extension of <sys/socket.h>. */
#define _GNU_SOURCE
#include "client.h"

#include <errno.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <time.h>
#include <unistd.h>

#define READ_CHUNK 65536
/* A request is a few hundred bytes: if the daemon does not take it within
 * this, it is not reading at all. */
#define WRITE_TIMEOUT_MS 10000
/* Retry period for a full listen backlog (EAGAIN from connect). */
#define BACKLOG_RETRY_MS 10

struct client {
    int fd;
    char *path;
    gint64 next_id;
    GByteArray *in;       /* received bytes not yet cut into lines */
    size_t scanned;       /* in->data[0..scanned) holds no '\n' */
    GQueue events;        /* JsonObject*, oldest first */
    GHashTable *replies;  /* gint64* id -> JsonObject* reply, not yet asked for */
    GHashTable *pending;  /* gint64* id -> char* cmd, sent and unanswered */
    sl_err err;
    char errcode[64];
};

static gint64 now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (gint64)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

static gint64 deadline_of(int timeout_ms)
{
    return timeout_ms < 0 ? -1 : now_ms() + timeout_ms;
}

/* ms left before deadline for poll(): -1 = forever, 0 = expired. */
static int left_ms(gint64 deadline)
{
    if (deadline < 0)
        return -1;
    gint64 d = deadline - now_ms();
    return d <= 0 ? 0 : d > G_MAXINT ? G_MAXINT : (int)d;
}

const char *client_socket_path(const char *path)
{
    if (path && *path)
        return path;
    const char *env = getenv("SPECKLAB_SOCKET");
    if (env && *env)
        return env;
    /* the system daemon (the unit's socket) when there is one, else a
     * daemon started from a source tree */
    return access(CLIENT_SYSTEM_SOCKET, F_OK) == 0 ? CLIENT_SYSTEM_SOCKET
                                                   : CLIENT_DEFAULT_SOCKET;
}

static int unreachable(sl_err *e, const char *path, int errnum)
{
    const char *hint = "";
    if (errnum == ENOENT || errnum == ECONNREFUSED)
        hint = " \xe2\x80\x94 start it with bin/specklabd";
    else if (errnum == EACCES || errnum == EPERM)
        hint = " \xe2\x80\x94 the socket admits the daemon's user and group "
               "only (is your user in that group?)";
    return sl_seterr(e, CLIENT_EUNREACHABLE, "cannot reach specklabd at %s: %s%s",
                     path, strerror(errnum), hint);
}

/* connect() on a non-blocking AF_UNIX socket: Linux answers at once, except
 * EAGAIN when the listen backlog is full (retried until the deadline) and,
 * on other systems, EINPROGRESS (waited for with poll). */
static int connect_within(int fd, const struct sockaddr_un *sa, const char *path,
                          int timeout_ms, sl_err *e)
{
    gint64 deadline = deadline_of(timeout_ms);
    for (;;) {
        if (connect(fd, (const struct sockaddr *)sa, sizeof *sa) == 0)
            return SL_OK;
        if (errno == EINTR)
            continue;
        if (errno == EAGAIN) {
            int left = left_ms(deadline);
            if (left == 0)
                break;
            poll(NULL, 0, left < 0 || left > BACKLOG_RETRY_MS ? BACKLOG_RETRY_MS : left);
            continue;
        }
        if (errno == EINPROGRESS) {
            struct pollfd p = {fd, POLLOUT, 0};
            int n;
            while ((n = poll(&p, 1, left_ms(deadline))) < 0 && errno == EINTR)
                ;
            if (n == 0)
                break;
            int soerr = 0;
            socklen_t sl = sizeof soerr;
            if (n < 0 || getsockopt(fd, SOL_SOCKET, SO_ERROR, &soerr, &sl) < 0)
                return unreachable(e, path, errno);
            if (soerr == 0)
                return SL_OK;
            return unreachable(e, path, soerr);
        }
        return unreachable(e, path, errno);
    }
    return sl_seterr(e, CLIENT_ETIMEOUT, "specklabd at %s accepted no connection "
                     "within %d ms (its backlog is full: is it stuck?)", path,
                     timeout_ms);
}

int client_connect(client **out, const char *path, int timeout_ms, sl_err *e)
{
    *out = NULL;
    struct sockaddr_un sa;
    memset(&sa, 0, sizeof sa);
    sa.sun_family = AF_UNIX;
    if (!path || !*path)
        return sl_seterr(e, SL_EINVAL, "no socket path given");
    if (strlen(path) >= sizeof sa.sun_path)
        return sl_seterr(e, SL_EINVAL, "socket path %s is %zu bytes: Unix "
                         "sockets allow at most %zu (use a shorter path)",
                         path, strlen(path), sizeof sa.sun_path - 1);
    memcpy(sa.sun_path, path, strlen(path) + 1);
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return sl_seterr(e, SL_EIO, "socket: %s", strerror(errno));
    int rc = connect_within(fd, &sa, path, timeout_ms, e);
    if (rc != SL_OK)
        goto close_fd;
    client *c = g_new0(client, 1);
    c->fd = fd;
    c->path = g_strdup(path);
    c->next_id = 1;
    c->in = g_byte_array_sized_new(READ_CHUNK);
    g_queue_init(&c->events);
    c->replies = g_hash_table_new_full(g_int64_hash, g_int64_equal, g_free,
                                       (GDestroyNotify)json_object_unref);
    c->pending = g_hash_table_new_full(g_int64_hash, g_int64_equal, g_free, g_free);
    *out = c;
    return SL_OK;
close_fd:
    close(fd);
    return rc;
}

void client_free(client *c)
{
    if (!c)
        return;
    close(c->fd);
    g_free(c->path);
    g_byte_array_unref(c->in);
    g_queue_clear_full(&c->events, (GDestroyNotify)json_object_unref);
    g_hash_table_destroy(c->replies);
    g_hash_table_destroy(c->pending);
    g_free(c);
}

const char *client_errmsg(const client *c)
{
    return c ? c->err.msg : "no client";
}

const char *client_errcode(const client *c)
{
    return c && c->err.code == CLIENT_EREMOTE && c->errcode[0] ? c->errcode : NULL;
}

const char *client_path(const client *c)
{
    return c ? c->path : NULL;
}

long client_peer_pid(const client *c)
{
    struct ucred cr;
    socklen_t len = sizeof cr;
    if (!c || getsockopt(c->fd, SOL_SOCKET, SO_PEERCRED, &cr, &len) < 0)
        return -1;
    return cr.pid > 0 ? (long)cr.pid : -1;
}

static gint64 *id_key(gint64 id);
static char *take_line(client *c, size_t *len);
static int parse_line(client *c, const char *line, size_t len, JsonObject **msg);
static int classify(JsonObject *msg, gint64 *id);
static int reply_result(client *c, gint64 id, JsonObject *reply, JsonObject **result);

/* The daemon closed the connection before it read the request: it says
 * why first (`busy`: every slot taken; `idle`: this connection sat idle),
 * in a line with a null id that stays readable after the close.  Report
 * that line rather than the broken pipe; keep anything else it sent. */
static int closed_by_daemon(client *c, const char *cmd, int errnum)
{
    guint8 buf[READ_CHUNK];
    ssize_t n;
    while ((n = recv(c->fd, buf, sizeof buf, MSG_DONTWAIT)) > 0 ||
           (n < 0 && errno == EINTR))
        if (n > 0)
            g_byte_array_append(c->in, buf, (guint)n);
    size_t len = 0;
    char *line;
    while ((line = take_line(c, &len))) {
        JsonObject *msg = NULL, *result = NULL;
        gint64 id = 0;
        int parsed = strspn(line, " \t\r") != len && parse_line(c, line, len, &msg) == SL_OK;
        g_free(line);
        if (!parsed)
            continue;
        switch (classify(msg, &id)) {
        case -1:
            g_queue_push_tail(&c->events, msg);
            break;
        case 0: {
            int rc = reply_result(c, 0, msg, &result);
            json_object_unref(msg);
            if (result)
                json_object_unref(result);
            if (rc == CLIENT_EREMOTE)
                return rc;
            break;
        }
        default:
            g_hash_table_replace(c->replies, id_key(id), msg);
        }
    }
    return sl_seterr(&c->err, SL_EIO, "sending '%s' to specklabd at %s: %s", cmd, c->path,
                     strerror(errnum));
}

static gint64 *id_key(gint64 id)
{
    gint64 *k = g_new(gint64, 1);
    *k = id;
    return k;
}

int client_send(client *c, const char *cmd, JsonObject *args, gint64 *id)
{
    sl_clearerr(&c->err);
    c->errcode[0] = '\0';
    gint64 my_id = c->next_id++;
    JsonObject *req = json_object_new();
    json_object_set_int_member(req, "id", my_id);
    json_object_set_string_member(req, "cmd", cmd);
    if (args)
        json_object_set_object_member(req, "args", json_object_ref(args));
    JsonNode *root = json_node_init_object(json_node_alloc(), req);
    JsonGenerator *g = json_generator_new();
    json_generator_set_root(g, root);
    gsize len = 0;
    gchar *text = json_generator_to_data(g, &len);
    g_object_unref(g);
    json_node_unref(root);
    json_object_unref(req);
    int rc = SL_OK;
    if (len > CLIENT_REQUEST_MAX) {
        rc = sl_seterr(&c->err, SL_EINVAL, "request '%s' is %zu bytes: the "
                       "daemon refuses lines over %d", cmd, (size_t)len,
                       CLIENT_REQUEST_MAX);
        goto free_text;
    }
    text[len] = '\n'; /* replaces the NUL: the buffer is len + 1 long */
    gint64 deadline = deadline_of(WRITE_TIMEOUT_MS);
    size_t off = 0;
    while (off < len + 1) {
        ssize_t n = send(c->fd, text + off, len + 1 - off, MSG_NOSIGNAL);
        if (n >= 0) {
            off += (size_t)n;
            continue;
        }
        if (errno == EINTR)
            continue;
        if (errno == EPIPE || errno == ECONNRESET) {
            rc = closed_by_daemon(c, cmd, errno);
            goto free_text;
        }
        if (errno != EAGAIN && errno != EWOULDBLOCK) {
            rc = sl_seterr(&c->err, SL_EIO, "sending '%s' to specklabd at %s: %s",
                           cmd, c->path, strerror(errno));
            goto free_text;
        }
        struct pollfd p = {c->fd, POLLOUT, 0};
        int pn = poll(&p, 1, left_ms(deadline));
        if (pn == 0) {
            rc = sl_seterr(&c->err, CLIENT_ETIMEOUT, "specklabd at %s took no "
                           "request for %d ms", c->path, WRITE_TIMEOUT_MS);
            goto free_text;
        }
    }
    g_hash_table_insert(c->pending, id_key(my_id), g_strdup(cmd));
    if (id)
        *id = my_id;
free_text:
    g_free(text);
    return rc;
}

/* Cut the next complete line out of c->in; NULL when there is none yet. */
static char *take_line(client *c, size_t *len)
{
    guint8 *nl = memchr(c->in->data + c->scanned, '\n', c->in->len - c->scanned);
    if (!nl) {
        c->scanned = c->in->len;
        return NULL;
    }
    *len = (size_t)(nl - c->in->data);
    char *line = g_strndup((const char *)c->in->data, *len);
    g_byte_array_remove_range(c->in, 0, (guint)(*len + 1));
    c->scanned = 0;
    return line;
}

static int parse_line(client *c, const char *line, size_t len, JsonObject **msg)
{
    JsonParser *p = json_parser_new();
    GError *ge = NULL;
    int rc = SL_OK;
    if (!json_parser_load_from_data(p, line, (gssize)len, &ge)) {
        rc = sl_seterr(&c->err, SL_EFORMAT, "specklabd sent a line that is "
                       "not JSON (%s): %.80s", ge->message, line);
        g_error_free(ge);
        goto free_parser;
    }
    JsonNode *root = json_parser_get_root(p);
    if (!root || !JSON_NODE_HOLDS_OBJECT(root)) {
        rc = sl_seterr(&c->err, SL_EFORMAT, "specklabd sent a line that is "
                       "not a JSON object: %.80s", line);
        goto free_parser;
    }
    *msg = json_object_ref(json_node_get_object(root));
free_parser:
    g_object_unref(p);
    return rc;
}

/* The next message from the daemon, waiting until deadline.  Blank lines
 * are skipped. */
static int read_message(client *c, gint64 deadline, JsonObject **msg)
{
    guint8 buf[READ_CHUNK];
    for (;;) {
        size_t len = 0;
        char *line = take_line(c, &len);
        if (line) {
            int rc = SL_OK;
            if (strspn(line, " \t\r") != len)
                rc = parse_line(c, line, len, msg);
            g_free(line);
            if (rc != SL_OK || *msg)
                return rc;
            continue;
        }
        if (c->in->len > CLIENT_LINE_MAX)
            return sl_seterr(&c->err, SL_EFORMAT, "specklabd sent a line longer "
                             "than %u bytes", CLIENT_LINE_MAX);
        struct pollfd p = {c->fd, POLLIN, 0};
        int pn = poll(&p, 1, left_ms(deadline));
        if (pn < 0 && errno == EINTR)
            continue;
        if (pn == 0)
            return CLIENT_ETIMEOUT; /* the caller words the message */
        ssize_t n = read(c->fd, buf, sizeof buf);
        if (n > 0) {
            g_byte_array_append(c->in, buf, (guint)n);
            continue;
        }
        if (n < 0 && (errno == EINTR || errno == EAGAIN || errno == EWOULDBLOCK))
            continue;
        return sl_seterr(&c->err, SL_EIO, "specklabd at %s closed the connection%s%s",
                         c->path, n < 0 ? ": " : "", n < 0 ? strerror(errno) : "");
    }
}

/* Reply id of msg: 1 with *id set; 0 for an id of null (the daemon could
 * not parse a request line: bad-json); -1 when msg is an event. */
static int classify(JsonObject *msg, gint64 *id)
{
    if (json_object_has_member(msg, "event"))
        return -1;
    JsonNode *n = json_object_get_member(msg, "id");
    if (n && JSON_NODE_HOLDS_VALUE(n) && json_node_get_value_type(n) == G_TYPE_INT64) {
        *id = json_node_get_int(n);
        return 1;
    }
    return 0;
}

/* o[k] when it is a string, else "" (a daemon bug must not crash us). */
static const char *str_member(JsonObject *o, const char *k)
{
    JsonNode *n = o ? json_object_get_member(o, k) : NULL;
    if (n && JSON_NODE_HOLDS_VALUE(n) && json_node_get_value_type(n) == G_TYPE_STRING)
        return json_node_get_string(n);
    return "";
}

static int reply_result(client *c, gint64 id, JsonObject *reply, JsonObject **result)
{
    char *cmd = g_strdup(g_hash_table_lookup(c->pending, &id));
    g_hash_table_remove(c->pending, &id);
    int rc = SL_OK;
    JsonNode *ok = json_object_get_member(reply, "ok");
    if (ok && JSON_NODE_HOLDS_VALUE(ok) && json_node_get_value_type(ok) == G_TYPE_BOOLEAN &&
        json_node_get_boolean(ok)) {
        JsonNode *r = json_object_get_member(reply, "result");
        *result = r && JSON_NODE_HOLDS_OBJECT(r) ? json_object_ref(json_node_get_object(r))
                                                  : json_object_new();
        goto free_cmd;
    }
    JsonNode *en = json_object_get_member(reply, "error");
    JsonObject *eo = en && JSON_NODE_HOLDS_OBJECT(en) ? json_node_get_object(en) : NULL;
    const char *code = str_member(eo, "code");
    const char *msg = str_member(eo, "message");
    snprintf(c->errcode, sizeof c->errcode, "%s", *code ? code : "unknown");
    if (*msg)
        rc = sl_seterr(&c->err, CLIENT_EREMOTE, "%s", msg);
    else
        rc = sl_seterr(&c->err, CLIENT_EREMOTE, "specklabd refused '%s' (%s) "
                       "without a message", cmd ? cmd : "?", c->errcode);
free_cmd:
    g_free(cmd);
    return rc;
}

int client_wait_reply(client *c, gint64 id, int timeout_ms, JsonObject **result)
{
    *result = NULL;
    sl_clearerr(&c->err);
    c->errcode[0] = '\0';
    gint64 deadline = deadline_of(timeout_ms);
    JsonObject *reply = NULL;
    gpointer key = NULL, val = NULL;
    if (g_hash_table_steal_extended(c->replies, &id, &key, &val)) {
        g_free(key);
        reply = val;
    }
    while (!reply) {
        JsonObject *msg = NULL;
        int rc = read_message(c, deadline, &msg);
        if (rc == CLIENT_ETIMEOUT) {
            const char *cmd = g_hash_table_lookup(c->pending, &id);
            return sl_seterr(&c->err, CLIENT_ETIMEOUT, "no reply to '%s' from "
                             "specklabd at %s within %.1f s", cmd ? cmd : "?",
                             c->path, timeout_ms / 1000.0);
        }
        if (rc != SL_OK)
            return rc;
        gint64 got = 0;
        switch (classify(msg, &got)) {
        case -1:
            g_queue_push_tail(&c->events, msg);
            break;
        case 0: /* id null: our line was unreadable, and we wait for one */
            reply = msg;
            break;
        default:
            if (got == id)
                reply = msg;
            else
                g_hash_table_replace(c->replies, id_key(got), msg);
        }
    }
    int rc = reply_result(c, id, reply, result);
    json_object_unref(reply);
    return rc;
}

int client_call(client *c, const char *cmd, JsonObject *args, int timeout_ms,
                JsonObject **result)
{
    gint64 id = 0;
    *result = NULL;
    int rc = client_send(c, cmd, args, &id);
    return rc != SL_OK ? rc : client_wait_reply(c, id, timeout_ms, result);
}

int client_next_event(client *c, int timeout_ms, JsonObject **event)
{
    *event = g_queue_pop_head(&c->events);
    if (*event)
        return SL_OK;
    sl_clearerr(&c->err);
    gint64 deadline = deadline_of(timeout_ms);
    for (;;) {
        JsonObject *msg = NULL;
        int rc = read_message(c, deadline, &msg);
        if (rc == CLIENT_ETIMEOUT)
            return SL_OK;
        if (rc != SL_OK)
            return rc;
        gint64 got = 0;
        int kind = classify(msg, &got);
        if (kind == -1) {
            *event = msg;
            return SL_OK;
        }
        if (kind == 1)
            g_hash_table_replace(c->replies, id_key(got), msg);
        else
            json_object_unref(msg); /* an unowned bad-json reply: nobody waits */
    }
}
