/* daemon_client.h - a test-side client of daemon/PROTOCOL.md (json-glib):
 * requests with ids, replies matched by id, events kept in a FIFO while
 * waiting, every read bounded by a deadline.  Included by daemon_fx.h.
 *
 * Nodes handed out are owned by the caller (json_node_unref).  Paths into
 * them are dotted member names with array indices: "result.runs.0.uuid".
 */
#ifndef SL_DAEMON_CLIENT_H
#define SL_DAEMON_CLIENT_H

typedef struct dc {
    int fd;
    GString *in;
    GQueue events;     /* JsonNode*: events not yet taken */
    GQueue replies;    /* JsonNode*: replies to other ids */
    gint64 next_id;
    int eof;
} dc;

/* 0, or -errno of connect(2). */
static inline int dc_connect(dc *c, const char *path)
{
    struct sockaddr_un a = {.sun_family = AF_UNIX};
    memset(c, 0, sizeof *c);
    c->fd = -1;
    if (strlen(path) >= sizeof a.sun_path)
        return -ENAMETOOLONG;
    c->fd = socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    memcpy(a.sun_path, path, strlen(path) + 1);
    if (c->fd < 0 || connect(c->fd, (struct sockaddr *)&a, sizeof a) != 0) {
        int e = errno;
        if (c->fd >= 0)
            close(c->fd);
        c->fd = -1;
        return -e;
    }
    c->in = g_string_new(NULL);
    g_queue_init(&c->events);
    g_queue_init(&c->replies);
    c->next_id = 1;
    return 0;
}

static inline void dc_close(dc *c)
{
    if (c->fd >= 0)
        close(c->fd);
    c->fd = -1;
    if (c->in)
        g_string_free(c->in, TRUE);
    c->in = NULL;
    g_queue_clear_full(&c->events, (GDestroyNotify)json_node_unref);
    g_queue_clear_full(&c->replies, (GDestroyNotify)json_node_unref);
}

static inline int dc_send_raw(dc *c, const char *data, size_t n)
{
    while (n > 0) {
        ssize_t w = send(c->fd, data, n, MSG_NOSIGNAL);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return -1;
        data += w;
        n -= (size_t)w;
    }
    return 0;
}

/* The next line as JSON (a non-JSON line comes back as a string node);
 * NULL on timeout or end of stream (c->eof). */
static inline JsonNode *dc_read(dc *c, double timeout_s)
{
    double end = fx_now() + timeout_s;
    for (;;) {
        char *nl = memchr(c->in->str, '\n', c->in->len);
        if (nl) {
            gsize len = (gsize)(nl - c->in->str);
            JsonParser *p = json_parser_new();
            JsonNode *n;
            if (json_parser_load_from_data(p, c->in->str, (gssize)len, NULL) &&
                json_parser_get_root(p))
                n = json_node_copy(json_parser_get_root(p));
            else
                n = json_node_init_string(json_node_alloc(), "(not JSON)");
            g_object_unref(p);
            g_string_erase(c->in, 0, (gssize)len + 1);
            return n;
        }
        double left = end - fx_now();
        if (c->eof || left <= 0)
            return NULL;
        struct pollfd pf = {c->fd, POLLIN, 0};
        if (poll(&pf, 1, (int)(left * 1000) + 1) <= 0)
            continue;
        char buf[65536];
        ssize_t r = recv(c->fd, buf, sizeof buf, 0);
        if (r <= 0)
            c->eof = 1;
        else
            g_string_append_len(c->in, buf, r);
    }
}

/* Send {"id", "cmd", "args": args_json (JSON text, NULL: none)}; the id. */
static inline gint64 dc_send(dc *c, const char *cmd, const char *args_json)
{
    JsonBuilder *b = json_builder_new();
    gint64 id = c->next_id++;
    json_builder_begin_object(b);
    json_builder_set_member_name(b, "id");
    json_builder_add_int_value(b, id);
    json_builder_set_member_name(b, "cmd");
    json_builder_add_string_value(b, cmd);
    if (args_json) {
        JsonNode *a = json_from_string(args_json, NULL);
        json_builder_set_member_name(b, "args");
        if (a)
            json_builder_add_value(b, a);
        else
            json_builder_add_null_value(b);
    }
    json_builder_end_object(b);
    JsonNode *n = json_builder_get_root(b);
    char *s = json_to_string(n, FALSE);
    char *line = g_strconcat(s, "\n", NULL);
    int rc = dc_send_raw(c, line, strlen(line));
    g_free(line);
    g_free(s);
    json_node_unref(n);
    g_object_unref(b);
    return rc == 0 ? id : -1;
}

static inline int is_event(JsonNode *n)
{
    return JSON_NODE_HOLDS_OBJECT(n) && json_object_has_member(json_node_get_object(n), "event");
}

static inline int reply_id_is(JsonNode *n, gint64 id)
{
    if (!JSON_NODE_HOLDS_OBJECT(n))
        return 0;
    JsonNode *i = json_object_get_member(json_node_get_object(n), "id");
    return i && JSON_NODE_HOLDS_VALUE(i) && json_node_get_value_type(i) == G_TYPE_INT64 &&
           json_node_get_int(i) == id;
}

/* The reply with this id (id < 0: the next reply of any id, e.g. a reply
 * with a null id); events meanwhile are queued. */
static inline JsonNode *dc_wait_reply(dc *c, gint64 id, double timeout_s)
{
    for (GList *l = c->replies.head; l; l = l->next)
        if (id < 0 || reply_id_is(l->data, id)) {
            JsonNode *n = l->data;
            g_queue_delete_link(&c->replies, l);
            return n;
        }
    double end = fx_now() + timeout_s;
    for (;;) {
        JsonNode *n = dc_read(c, end - fx_now());
        if (!n)
            return NULL;
        if (is_event(n))
            g_queue_push_tail(&c->events, n);
        else if (id < 0 || reply_id_is(n, id))
            return n;
        else
            g_queue_push_tail(&c->replies, n);
    }
}

static inline JsonNode *dc_call(dc *c, const char *cmd, const char *args_json, double timeout_s)
{
    gint64 id = dc_send(c, cmd, args_json);
    return id < 0 ? NULL : dc_wait_reply(c, id, timeout_s);
}

static inline JsonNode *dc_next_event(dc *c, double timeout_s)
{
    if (!g_queue_is_empty(&c->events))
        return g_queue_pop_head(&c->events);
    double end = fx_now() + timeout_s;
    for (;;) {
        JsonNode *n = dc_read(c, end - fx_now());
        if (!n || is_event(n))
            return n;
        g_queue_push_tail(&c->replies, n);
    }
}

/* ---- paths into nodes ------------------------------------------------------ */

static inline JsonNode *jget(JsonNode *n, const char *path)
{
    gchar **parts = g_strsplit(path, ".", -1);
    for (int i = 0; n && parts[i]; i++) {
        if (JSON_NODE_HOLDS_OBJECT(n)) {
            n = json_object_get_member(json_node_get_object(n), parts[i]);
        } else if (JSON_NODE_HOLDS_ARRAY(n)) {
            JsonArray *a = json_node_get_array(n);
            guint k = (guint)atoi(parts[i]);
            n = k < json_array_get_length(a) ? json_array_get_element(a, k) : NULL;
        } else {
            n = NULL;
        }
    }
    g_strfreev(parts);
    return n;
}

static inline const char *js(JsonNode *n, const char *path)
{
    JsonNode *m = n ? jget(n, path) : NULL;
    return m && JSON_NODE_HOLDS_VALUE(m) && json_node_get_value_type(m) == G_TYPE_STRING
               ? json_node_get_string(m)
               : NULL;
}

static inline gint64 ji(JsonNode *n, const char *path)
{
    JsonNode *m = n ? jget(n, path) : NULL;
    return m && JSON_NODE_HOLDS_VALUE(m) ? json_node_get_int(m) : G_MININT64;
}

static inline double jd(JsonNode *n, const char *path)
{
    JsonNode *m = n ? jget(n, path) : NULL;
    return m && JSON_NODE_HOLDS_VALUE(m) ? json_node_get_double(m) : NAN;
}

static inline int jok(JsonNode *n)
{
    JsonNode *m = n ? jget(n, "ok") : NULL;
    return m && JSON_NODE_HOLDS_VALUE(m) && json_node_get_boolean(m);
}

static inline int jnull(JsonNode *n, const char *path)
{
    JsonNode *m = n ? jget(n, path) : NULL;
    return m && JSON_NODE_HOLDS_NULL(m);
}

/* Short text of a node for messages (static buffer: one at a time). */
static inline const char *jtext(JsonNode *n)
{
    static char buf[600];
    char *s = n ? json_to_string(n, FALSE) : g_strdup("(nothing)");
    snprintf(buf, sizeof buf, "%.590s", s);
    g_free(s);
    return buf;
}

/* Events of run until a state event with a state in states (comma list);
 * that event is returned.  seen (may be NULL) collects every state of the
 * run in order, comma-separated; *last_progress the frames_acquired of
 * the last progress event (unchanged when none). */
static inline JsonNode *dc_wait_state(dc *c, const char *run, const char *states, double timeout_s,
                               GString *seen, gint64 *last_progress)
{
    double end = fx_now() + timeout_s;
    for (;;) {
        JsonNode *e = dc_next_event(c, end - fx_now());
        if (!e)
            return NULL;
        const char *kind = js(e, "event"), *r = js(e, "run");
        if (r && run && strcmp(r, run)) {
            json_node_unref(e);
            continue;
        }
        if (kind && !strcmp(kind, "progress") && last_progress)
            *last_progress = ji(e, "frames_acquired");
        if (kind && !strcmp(kind, "state")) {
            const char *s = js(e, "state");
            if (seen)
                g_string_append_printf(seen, "%s%s", seen->len ? "," : "", s);
            gchar **want = g_strsplit(states, ",", -1);
            int hit = 0;
            for (int i = 0; want[i]; i++)
                hit |= !strcmp(want[i], s);
            g_strfreev(want);
            if (hit)
                return e;
        }
        json_node_unref(e);
    }
}

/* Progress events of run until frames_acquired >= n: that count, or -1
 * when the run ended (a state event of a final state) or time ran out. */
static inline gint64 dc_wait_progress(dc *c, const char *run, gint64 n, double timeout_s)
{
    double end = fx_now() + timeout_s;
    for (;;) {
        JsonNode *e = dc_next_event(c, end - fx_now());
        if (!e)
            return -1;
        const char *kind = js(e, "event"), *r = js(e, "run"), *s = js(e, "state");
        gint64 got = -2;
        if (r && !strcmp(r, run) && kind && !strcmp(kind, "progress") &&
            ji(e, "frames_acquired") >= n)
            got = ji(e, "frames_acquired");
        else if (r && !strcmp(r, run) && s &&
                 (!strcmp(s, "failed") || !strcmp(s, "aborted") || !strcmp(s, "stored")))
            got = -1;
        json_node_unref(e);
        if (got != -2)
            return got;
    }
}

#endif
