/* server.c - Unix socket, per-client buffers and ordered replies; see
 * server.h.
 *
 * Per client: an input GString (never more than SERVER_MAX_LINE + one read
 * chunk), an output GString with a write offset, and a FIFO of reply
 * slots.  A slot is filled by server_complete; filled slots at the head of
 * the FIFO move to the output buffer, so replies keep request order while
 * a slow request is pending.  The main loop watches POLLIN while the
 * client may send and POLLOUT only while output is waiting, so an idle
 * daemon does not spin.  An idle client (see server.h) has one timeout
 * source, armed only while it is idle; activity only moves a timestamp,
 * and the timer, when it fires early, re-arms itself for the rest.
 */
#define _GNU_SOURCE
#include "server.h"

#include <errno.h>
#include <fcntl.h>
#include <glib-unix.h>
#include <json-glib/json-glib.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#define READ_CHUNK 16384
#define MAX_PENDING 64      /* unanswered requests before reading pauses */

typedef struct slot {
    guint64 seq;
    char *line;        /* NULL while pending */
    int subscribe;     /* activate the subscription when written */
    char *sub_run;
} slot;

typedef struct client {
    server *srv;
    guint64 id;
    int fd;
    guint in_watch, out_watch;
    GString *in, *out;
    gsize out_off;
    GQueue slots;
    guint64 next_seq;
    int subscribed;
    char *sub_run;     /* NULL: every run */
    int reading;       /* 0 after EOF or an oversized line */
    gint64 active_us;  /* its last request or reply (monotonic) */
    guint idle_timer;  /* armed while idle */
} client;

struct server {
    char *path;
    int listen_fd;
    guint listen_watch;
    int max_clients;
    int idle_ms;
    guint64 next_id;
    GHashTable *clients;   /* id -> client* */
    server_request_fn fn;
    void *user;
    GMainContext *ctx;
};

static void client_close(server *s, client *c);
static int client_pump(server *s, client *c);

/* {"id": null, "ok": false, "error": {"code": code, "message": msg}} */
static char *error_line(const char *code, const char *msg)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    json_builder_set_member_name(b, "id");
    json_builder_add_null_value(b);
    json_builder_set_member_name(b, "ok");
    json_builder_add_boolean_value(b, FALSE);
    json_builder_set_member_name(b, "error");
    json_builder_begin_object(b);
    json_builder_set_member_name(b, "code");
    json_builder_add_string_value(b, code);
    json_builder_set_member_name(b, "message");
    json_builder_add_string_value(b, msg);
    json_builder_end_object(b);
    json_builder_end_object(b);
    JsonNode *n = json_builder_get_root(b);
    char *line = json_to_string(n, FALSE);
    json_node_unref(n);
    g_object_unref(b);
    return line;
}

static void slot_free(gpointer p)
{
    slot *sl = p;
    g_free(sl->line);
    g_free(sl->sub_run);
    g_free(sl);
}

static void append_line(client *c, const char *line)
{
    g_string_append(c->out, line);
    g_string_append_c(c->out, '\n');
}

static gboolean on_client_io(gint fd, GIOCondition cond, gpointer data);
static gboolean on_idle(gpointer data);

/* Nothing in hand: not subscribed, no request pending, nothing to send,
 * still reading. */
static int is_idle(const client *c)
{
    return c->reading && !c->subscribed && c->slots.length == 0 &&
           c->out->len == c->out_off;
}

/* Best effort, never blocking: an idle client's buffers are empty, and a
 * socket takes one short line. */
static void last_words(int fd, const char *code, const char *msg)
{
    char *line = error_line(code, msg);
    if (send(fd, line, strlen(line), MSG_NOSIGNAL | MSG_DONTWAIT) > 0)
        send(fd, "\n", 1, MSG_NOSIGNAL | MSG_DONTWAIT);
    g_free(line);
}

static void arm_idle(client *c)
{
    gint64 left_ms = (c->active_us - g_get_monotonic_time()) / 1000 + c->srv->idle_ms;
    c->idle_timer = g_timeout_add((guint)CLAMP(left_ms, 1, G_MAXINT), on_idle, c);
}

static gboolean on_idle(gpointer data)
{
    client *c = data;
    server *s = c->srv;
    c->idle_timer = 0;
    double idle_s = (g_get_monotonic_time() - c->active_us) * 1e-6;
    if (idle_s * 1000 < s->idle_ms) {   /* active since it was armed */
        arm_idle(c);
        return G_SOURCE_REMOVE;
    }
    char msg[128];
    snprintf(msg, sizeof msg, "no request for %.1f s (client_idle_timeout_ms = %d): "
             "connection closed", idle_s, s->idle_ms);
    g_message("client %" G_GUINT64_FORMAT ": %s", c->id, msg);
    last_words(c->fd, "idle", msg);
    client_close(s, c);
    return G_SOURCE_REMOVE;
}

static void update_watches(client *c)
{
    int want_out = c->out->len > c->out_off;
    /* Back-pressure: a client that pipelines faster than it reads its
     * replies, or than they are answered, is not read until they drain. */
    int want_in = c->reading && c->out->len - c->out_off < READ_CHUNK * 4 &&
                  g_queue_get_length(&c->slots) < MAX_PENDING;
    if (want_in && !c->in_watch)
        c->in_watch = g_unix_fd_add(c->fd, G_IO_IN | G_IO_HUP | G_IO_ERR, on_client_io,
                                    c);
    else if (!want_in && c->in_watch)
        g_source_remove(c->in_watch), c->in_watch = 0;
    if (want_out && !c->out_watch)
        c->out_watch = g_unix_fd_add(c->fd, G_IO_OUT | G_IO_ERR, on_client_io,
                                     c);
    else if (!want_out && c->out_watch)
        g_source_remove(c->out_watch), c->out_watch = 0;
    int idle = is_idle(c);
    if (idle && !c->idle_timer)
        arm_idle(c);
    else if (!idle && c->idle_timer)
        g_source_remove(c->idle_timer), c->idle_timer = 0;
}

/* Move filled head slots to the output, write what the socket takes, and
 * close a client that has nothing more to say or hear. */
static int client_pump(server *s, client *c)
{
    slot *sl;
    while ((sl = g_queue_peek_head(&c->slots)) && sl->line) {
        g_queue_pop_head(&c->slots);
        c->active_us = g_get_monotonic_time();   /* idle counts from its last reply */
        append_line(c, sl->line);
        if (sl->subscribe) {
            c->subscribed = 1;
            g_free(c->sub_run);
            c->sub_run = g_strdup(sl->sub_run);
        }
        slot_free(sl);
    }
    while (c->out->len > c->out_off) {
        ssize_t n = send(c->fd, c->out->str + c->out_off, c->out->len - c->out_off,
                         MSG_NOSIGNAL | MSG_DONTWAIT);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
            break;
        if (n <= 0) {   /* EPIPE, ECONNRESET: the client is gone */
            client_close(s, c);
            return -1;
        }
        c->out_off += (gsize)n;
    }
    if (c->out_off == c->out->len) {
        g_string_truncate(c->out, 0);
        c->out_off = 0;
    } else if (c->out_off > (1u << 20)) {
        g_string_erase(c->out, 0, (gssize)c->out_off);
        c->out_off = 0;
    }
    if (c->out->len - c->out_off > SERVER_MAX_OUTPUT) {
        g_message("client %" G_GUINT64_FORMAT ": %zu bytes unread, disconnecting", c->id,
                  c->out->len - c->out_off);
        client_close(s, c);
        return -1;
    }
    if (!c->reading && g_queue_is_empty(&c->slots) && c->out->len == c->out_off) {
        client_close(s, c);
        return -1;
    }
    update_watches(c);
    return 0;
}

/* Hand every complete line to the handler; an over-long line (complete
 * or not) ends the conversation with `too-large`.  Returns -1 when the
 * handler closed the client. */
static int handle_lines(server *s, client *c)
{
    guint64 id = c->id;
    gsize start = 0;
    for (;;) {
        char *line = c->in->str + start;
        char *nl = memchr(line, '\n', c->in->len - start);
        gsize len = nl ? (gsize)(nl - line) : c->in->len - start;
        if (len > SERVER_MAX_LINE) {
            char msg[128];
            slot *sl = g_new0(slot, 1);
            snprintf(msg, sizeof msg, "request line longer than %d bytes; closing the "
                     "connection", SERVER_MAX_LINE);
            sl->seq = c->next_seq++;
            sl->line = error_line("too-large", msg);
            g_queue_push_tail(&c->slots, sl);
            c->reading = 0;
            start = c->in->len;
            break;
        }
        if (!nl)
            break;
        *nl = '\0';
        start += len + 1;
        if (len > 0 && line[len - 1] == '\r')
            line[--len] = '\0';
        if (strspn(line, " \t") == len)
            continue;   /* blank: not a request */
        slot *sl = g_new0(slot, 1);
        sl->seq = c->next_seq++;
        g_queue_push_tail(&c->slots, sl);
        c->active_us = g_get_monotonic_time();
        server_token tok = {id, sl->seq};
        s->fn(s, tok, line, len, s->user);
        if (!g_hash_table_lookup(s->clients, &id))
            return -1;
    }
    g_string_erase(c->in, 0, (gssize)start);
    return 0;
}

static gboolean on_client_io(gint fd, GIOCondition cond, gpointer data)
{
    client *c = data;
    server *s = c->srv;
    (void)fd;
    if ((cond & (G_IO_IN | G_IO_HUP | G_IO_ERR)) && c->reading) {
        char buf[READ_CHUNK];
        ssize_t n = recv(c->fd, buf, sizeof buf, MSG_DONTWAIT);
        if (n > 0) {
            g_string_append_len(c->in, buf, n);
            if (handle_lines(s, c) != 0)
                return G_SOURCE_REMOVE;
        } else if (n == 0 || (errno != EAGAIN && errno != EINTR && errno != EWOULDBLOCK)) {
            c->reading = 0;   /* EOF: answer what was asked, then close */
            g_string_truncate(c->in, 0);
        }
    } else if (cond & G_IO_ERR) {
        client_close(s, c);
        return G_SOURCE_REMOVE;
    }
    /* client_pump may remove this very source (update_watches): GLib
     * allows that, and the return value is then ignored. */
    client_pump(s, c);
    return G_SOURCE_CONTINUE;
}

static void client_close(server *s, client *c)
{
    if (c->in_watch)
        g_source_remove(c->in_watch);
    if (c->out_watch)
        g_source_remove(c->out_watch);
    if (c->idle_timer)
        g_source_remove(c->idle_timer);
    close(c->fd);
    g_string_free(c->in, TRUE);
    g_string_free(c->out, TRUE);
    g_queue_clear_full(&c->slots, slot_free);
    g_free(c->sub_run);
    g_hash_table_remove(s->clients, &c->id);   /* frees c */
}

/* Every slot taken: the client idle longest makes room (it is told why),
 * so idle connections cannot lock the others out.  0 when none is idle. */
static int evict_idlest(server *s)
{
    client *victim = NULL;
    GHashTableIter it;
    gpointer k, v;
    g_hash_table_iter_init(&it, s->clients);
    while (g_hash_table_iter_next(&it, &k, &v)) {
        client *c = v;
        if (is_idle(c) && (!victim || c->active_us < victim->active_us))
            victim = c;
    }
    if (!victim)
        return 0;
    char msg[128];
    snprintf(msg, sizeof msg, "idle for %.1f s: connection closed to let another client in "
             "(max_clients = %d)", (g_get_monotonic_time() - victim->active_us) * 1e-6,
             s->max_clients);
    g_message("client %" G_GUINT64_FORMAT ": %s", victim->id, msg);
    last_words(victim->fd, "idle", msg);
    client_close(s, victim);
    return 1;
}

static gboolean on_accept(gint fd, GIOCondition cond, gpointer data)
{
    server *s = data;
    (void)cond;
    int cfd = accept4(fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (cfd < 0) {
        if (errno != EAGAIN && errno != EINTR && errno != ECONNABORTED)
            g_warning("accept on %s: %s", s->path, g_strerror(errno));
        return G_SOURCE_CONTINUE;
    }
    if ((int)g_hash_table_size(s->clients) >= s->max_clients && !evict_idlest(s)) {
        char msg[96];
        snprintf(msg, sizeof msg, "too many clients (max_clients = %d); try later",
                 s->max_clients);
        /* A fresh socket's buffer takes one short line without blocking;
         * it stays readable after the close, also when the client has
         * already written its request. */
        last_words(cfd, "busy", msg);
        close(cfd);
        return G_SOURCE_CONTINUE;
    }
    client *c = g_new0(client, 1);
    c->srv = s;
    c->id = ++s->next_id;
    c->fd = cfd;
    c->in = g_string_sized_new(1024);
    c->out = g_string_sized_new(1024);
    c->reading = 1;
    c->active_us = g_get_monotonic_time();
    g_queue_init(&c->slots);
    g_hash_table_insert(s->clients, &c->id, c);
    update_watches(c);
    return G_SOURCE_CONTINUE;
}

/* Refuse a path where a daemon is listening or something else lives;
 * unlink a stale socket. */
static int clear_path(const char *path, sl_err *err)
{
    struct stat st;
    if (lstat(path, &st) != 0)
        return errno == ENOENT ? SL_OK
                               : sl_seterr(err, SL_EIO, "socket %s: %s", path,
                                           g_strerror(errno));
    if (!S_ISSOCK(st.st_mode))
        return sl_seterr(err, SL_EINVAL, "socket %s: exists and is not a socket", path);
    struct sockaddr_un a = {.sun_family = AF_UNIX};
    snprintf(a.sun_path, sizeof a.sun_path, "%s", path);
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    int live = fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) == 0;
    if (fd >= 0)
        close(fd);
    if (live)
        return sl_seterr(err, SL_EIO, "socket %s: another daemon is serving it", path);
    if (unlink(path) != 0)
        return sl_seterr(err, SL_EIO, "socket %s: cannot remove the stale socket: %s", path,
                         g_strerror(errno));
    return SL_OK;
}

static int listen_on(server *s, sl_err *err)
{
    struct sockaddr_un a = {.sun_family = AF_UNIX};
    if (strlen(s->path) >= sizeof a.sun_path)
        return sl_seterr(err, SL_EINVAL, "socket %s: path longer than %zu bytes", s->path,
                         sizeof a.sun_path - 1);
    int rc = clear_path(s->path, err);
    if (rc != SL_OK)
        return rc;
    memcpy(a.sun_path, s->path, strlen(s->path) + 1);
    s->listen_fd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (s->listen_fd < 0)
        return sl_seterr(err, SL_EIO, "socket: %s", g_strerror(errno));
    mode_t old = umask(0117);   /* the inode is born 0660, never wider */
    int b = bind(s->listen_fd, (struct sockaddr *)&a, sizeof a);
    int e = errno;
    umask(old);
    if (b != 0)
        return sl_seterr(err, SL_EIO, "socket %s: bind: %s", s->path, g_strerror(e));
    if (chmod(s->path, 0660) != 0 || chown(s->path, geteuid(), getegid()) != 0 ||
        listen(s->listen_fd, 32) != 0) {
        e = errno;
        unlink(s->path);
        return sl_seterr(err, SL_EIO, "socket %s: %s", s->path, g_strerror(e));
    }
    s->listen_watch = g_unix_fd_add(s->listen_fd, G_IO_IN, on_accept, s);
    return SL_OK;
}

static void client_free_value(gpointer p)
{
    g_free(p);
}

int server_new(server **out, const char *path, int max_clients, int idle_ms,
               server_request_fn fn, void *user, sl_err *err)
{
    server *s = g_new0(server, 1);
    s->path = g_strdup(path);
    s->listen_fd = -1;
    s->max_clients = max_clients > 0 ? max_clients : 64;
    s->idle_ms = idle_ms > 0 ? idle_ms : 30000;
    s->fn = fn;
    s->user = user;
    s->ctx = g_main_context_ref_thread_default();
    s->clients = g_hash_table_new_full(g_int64_hash, g_int64_equal, NULL, client_free_value);
    int rc = listen_on(s, err);
    if (rc != SL_OK) {
        if (s->listen_fd >= 0)
            close(s->listen_fd);
        s->listen_fd = -1;
        server_free(s);
        *out = NULL;
        return rc;
    }
    *out = s;
    return SL_OK;
}

void server_stop_listening(server *s)
{
    if (!s || s->listen_fd < 0)
        return;
    g_source_remove(s->listen_watch);
    close(s->listen_fd);
    s->listen_fd = -1;
    unlink(s->path);
}

void server_free(server *s)
{
    if (!s)
        return;
    server_stop_listening(s);
    GList *all = g_hash_table_get_values(s->clients);
    for (GList *l = all; l; l = l->next) {
        client *c = l->data;
        /* Last words that fit the socket buffer; never block here. */
        client_pump(s, c);
    }
    g_list_free(all);
    all = g_hash_table_get_values(s->clients);
    for (GList *l = all; l; l = l->next)
        client_close(s, l->data);
    g_list_free(all);
    g_hash_table_destroy(s->clients);
    g_main_context_unref(s->ctx);
    g_free(s->path);
    g_free(s);
}

const char *server_path(const server *s)
{
    return s->path;
}

int server_nclients(const server *s)
{
    return (int)g_hash_table_size(s->clients);
}

static void complete(server *s, server_token tok, char *line, int subscribe, const char *run)
{
    client *c = g_hash_table_lookup(s->clients, &tok.client);
    slot *sl = NULL;
    for (GList *l = c ? c->slots.head : NULL; l; l = l->next)
        if (((slot *)l->data)->seq == tok.slot)
            sl = l->data;
    if (!sl || sl->line) {   /* the client left (or a double completion) */
        g_free(line);
        return;
    }
    sl->line = line;
    sl->subscribe = subscribe;
    sl->sub_run = g_strdup(run);
    /* Inside the request handler the pump runs after it returns; here it
     * may run at once (the slot is at the head only when it is next). */
    if (g_queue_peek_head(&c->slots) == sl)
        client_pump(s, c);
}

void server_complete(server *s, server_token tok, char *line)
{
    complete(s, tok, line, 0, NULL);
}

void server_complete_subscribe(server *s, server_token tok, char *line, const char *run)
{
    complete(s, tok, line, 1, run);
}

typedef struct async_msg {
    server *s;
    server_token tok;
    char *line;
    char *run;
    int event;
} async_msg;

static gboolean deliver(gpointer p)
{
    async_msg *m = p;
    if (m->event)
        server_event(m->s, m->run, m->line);
    else
        server_complete(m->s, m->tok, m->line), m->line = NULL;
    return G_SOURCE_REMOVE;
}

static void async_free(gpointer p)
{
    async_msg *m = p;
    g_free(m->line);
    g_free(m->run);
    g_free(m);
}

void server_complete_async(server *s, server_token tok, char *line)
{
    async_msg *m = g_new0(async_msg, 1);
    m->s = s, m->tok = tok, m->line = line;
    g_main_context_invoke_full(s->ctx, G_PRIORITY_DEFAULT, deliver, m, async_free);
}

void server_event(server *s, const char *run, const char *line)
{
    GList *all = g_hash_table_get_values(s->clients);
    for (GList *l = all; l; l = l->next) {
        client *c = l->data;
        if (!c->subscribed || (c->sub_run && (!run || strcmp(c->sub_run, run))))
            continue;
        append_line(c, line);
        client_pump(s, c);   /* may close a client that stopped reading */
    }
    g_list_free(all);
}

void server_event_async(server *s, const char *run, char *line)
{
    async_msg *m = g_new0(async_msg, 1);
    m->s = s, m->line = line, m->run = g_strdup(run), m->event = 1;
    g_main_context_invoke_full(s->ctx, G_PRIORITY_DEFAULT, deliver, m, async_free);
}
