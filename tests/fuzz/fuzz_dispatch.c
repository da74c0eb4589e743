/* fuzz_dispatch.c - libFuzzer target: the control socket, from bytes on
 * the wire to replies (daemon/server.c framing, daemon/dispatch.c and
 * query.c parsing, validation and commands, proto.c replies) against a
 * daemon with a real catalogue and no devices (fuzz_daemon_ctx.h).
 *
 * The input is what one client sends, any number of lines (a newline is
 * added when it does not end with one, so a corpus file may be a single
 * request).  It goes down a real connection; the client then shuts its
 * side and the main context runs until the server has answered and
 * closed.  The harness splits the input itself by PROTOCOL.md's framing
 * (LF ends a line, a trailing CR is dropped, blank lines are no request,
 * a line over 65536 bytes gets `too-large` and ends the conversation) and
 * parses each request with json-glib to know what the reply must be.
 * Contract checks abort (a finding):
 *   - every request gets exactly one reply, in order, and nothing else
 *     arrives but events after a `subscribe` reply; every line received
 *     is a JSON object;
 *   - the reply's id is the request's integer id, else null;
 *   - errors: a line that is not a JSON object is `bad-json`; a non-integer
 *     id, a non-string cmd, non-object args or an argument the command
 *     does not take is `bad-request` naming it; an unknown cmd is
 *     `unknown-command` listing every command; a well-formed request gets
 *     ok, `bad-request` naming one of its command's arguments, `not-found`
 *     or (abort-run, reconstruct) `conflict` - never `internal`;
 *   - results have their command's shape (status, devices with no device
 *     connected and the stage's error, runs within the limit and state
 *     filter, run matching the prefix, ...); only the queued and the
 *     current run can be aborted and only the stored one reconstructed;
 *   - nothing is created on disk: the scratch tree keeps its entries, and
 *     each run handed to the runner (a queued catalogued run, valid
 *     fields, free text without '/', '\', ".." or control characters) and
 *     each reconstruction handed to the worker maps to files directly in
 *     DATA/runs and DATA/recon;
 *   - only a successful start-run or abort-run changes the runs table
 *     (dispatch.h: a request that fails validation changes nothing);
 *   - no leak (libFuzzer's per-input leak check, on by default).
 * Cost: about 0.5 ms of CPU an input (socket round trip, catalogue
 * queries, ASan), 1-2 ms when a start-run or abort has to be undone;
 * 300-600 inputs/s on the shared 2-core machine.  SL_FUZZ_VERBOSE=1
 * prints what the server sent.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <json-glib/json-glib.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#define FUZZ_NAME "fuzz_dispatch"
#include "fuzz_util.h"
#include "fuzz_daemon_ctx.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* The commands and their arguments as daemon/PROTOCOL.md lists them
 * (with its extensions): the harness's own copy, so a dispatcher that
 * drifts from the protocol is a finding. */
static const struct proto_cmd {
    const char *name;
    const char *args[10];
} protocol[] = {
    {"status", {NULL}},
    {"devices", {NULL}},
    {"start-run", {"screen", "mask", "frames", "exposure_us", "object", "operator",
                   "reconstruct", "projections", "kind", NULL}},
    {"abort-run", {"run", NULL}},
    {"runs", {"state", "screen", "since", "limit", "kind", NULL}},
    {"run", {"run", NULL}},
    {"screens", {"since", NULL}},
    {"masks", {NULL}},
    {"reconstruct", {"run", "method", "projections", "options", "calibrator", NULL}},
    {"subscribe", {"run", NULL}},
};

/* What one request line says, as far as the reply depends on it. */
typedef struct req {
    int too_large;           /* the conversation's last: `too-large` */
    JsonNode *root;          /* NULL: not a JSON object -> bad-json */
    int has_id;
    gint64 id;
    const char *bad;         /* first violation's word, or NULL */
    const char *code;        /* ... and the code it must give */
    const struct proto_cmd *cmd;
    JsonObject *args;        /* NULL when absent */
} req;

static int is_int(JsonNode *n)
{
    return n && JSON_NODE_HOLDS_VALUE(n) && json_node_get_value_type(n) == G_TYPE_INT64;
}

static int is_str(JsonNode *n)
{
    return n && JSON_NODE_HOLDS_VALUE(n) && json_node_get_value_type(n) == G_TYPE_STRING;
}

static JsonNode *parse_object(const char *s, gssize len)
{
    JsonParser *p = json_parser_new_immutable();
    JsonNode *n = NULL;
    if (json_parser_load_from_data(p, s, len, NULL) && json_parser_get_root(p) &&
        JSON_NODE_HOLDS_OBJECT(json_parser_get_root(p)))
        n = json_node_copy(json_parser_get_root(p));
    g_object_unref(p);
    return n;
}

static int takes(const struct proto_cmd *c, const char *key)
{
    for (int i = 0; c->args[i]; i++)
        if (!strcmp(c->args[i], key))
            return 1;
    return 0;
}

static void model(req *r, const char *line, size_t len)
{
    if (!(r->root = parse_object(line, (gssize)len))) {
        r->bad = "request is not a JSON object", r->code = "bad-json";
        return;
    }
    JsonObject *o = json_node_get_object(r->root);
    JsonNode *id = json_object_get_member(o, "id"), *cmd = json_object_get_member(o, "cmd");
    JsonNode *args = json_object_get_member(o, "args");
    /* A number json-glib misreads (beyond gint64, or not JSON's) is
     * refused naming it; an id of that kind is not echoed. */
    proto_badnum bn;
    int nums_ok = proto_numbers_ok(line, len, &bn);
    if (is_int(id) && !bn.top_id) {
        r->has_id = 1;
        r->id = json_node_get_int(id);
    } else if (id && !JSON_NODE_HOLDS_NULL(id)) {
        r->bad = bn.top_id ? g_intern_string(bn.literal) : "id", r->code = "bad-request";
        return;
    }
    if (!nums_ok) {   /* interned: the req is copied, the literal must outlive it */
        r->bad = g_intern_string(bn.literal), r->code = "bad-request";
        return;
    }
    if (!is_str(cmd)) {
        r->bad = "cmd", r->code = "bad-request";
        return;
    }
    if (args && !JSON_NODE_HOLDS_NULL(args) && !JSON_NODE_HOLDS_OBJECT(args)) {
        r->bad = "args", r->code = "bad-request";
        return;
    }
    for (size_t i = 0; i < G_N_ELEMENTS(protocol); i++)
        if (!strcmp(protocol[i].name, json_node_get_string(cmd)))
            r->cmd = &protocol[i];
    if (!r->cmd) {
        r->bad = "unknown command", r->code = "unknown-command";
        return;
    }
    r->args = args && JSON_NODE_HOLDS_OBJECT(args) ? json_node_get_object(args) : NULL;
    GList *keys = r->args ? json_object_get_members(r->args) : NULL;
    for (GList *l = keys; l && !r->bad; l = l->next)
        if (!takes(r->cmd, l->data))
            r->bad = "takes no argument", r->code = "bad-request";
    g_list_free(keys);
}

/* PROTOCOL.md's framing, independently of server.c: the requests. */
static GArray *split(const char *in, size_t n)
{
    GArray *v = g_array_new(FALSE, TRUE, sizeof(req));
    for (size_t start = 0; start < n;) {
        const char *nl = memchr(in + start, '\n', n - start);
        size_t len = nl ? (size_t)(nl - (in + start)) : n - start;
        req r = {0};
        if (len > SERVER_MAX_LINE) {
            r.too_large = 1, r.code = "too-large";
            g_array_append_val(v, r);
            break;
        }
        if (!nl)
            break;   /* unterminated at EOF: not a request */
        const char *line = in + start;
        start += len + 1;
        if (len > 0 && line[len - 1] == '\r')
            len--;
        if (strspn(line, " \t") >= len)
            continue;
        model(&r, line, len);
        g_array_append_val(v, r);
    }
    return v;
}

/* ---- the conversation -------------------------------------------------------- */

/* Send everything, shut down, read until the server closes. */
static GString *converse(const char *in, size_t n)
{
    struct sockaddr_un a = {.sun_family = AF_UNIX};
    snprintf(a.sun_path, sizeof a.sun_path, "%s", FZ.cfg.socket);
    int fd = socket(AF_UNIX, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    require(fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) == 0, "connect",
            strerror(errno));
    GString *out = g_string_new(NULL);
    size_t sent = 0;
    int shut = 0;
    for (;;) {
        if (sent < n) {
            ssize_t k = send(fd, in + sent, n - sent, MSG_NOSIGNAL);
            if (k > 0)
                sent += (size_t)k;
            else if (k < 0 && errno != EAGAIN && errno != EINTR)
                sent = n;   /* the server stopped reading (too-large) */
        }
        if (sent == n && !shut) {
            shutdown(fd, SHUT_WR);
            shut = 1;
        }
        char buf[16384];
        ssize_t k = recv(fd, buf, sizeof buf, 0);
        if (k > 0) {
            g_string_append_len(out, buf, k);
            continue;
        }
        if (k == 0 || (errno != EAGAIN && errno != EINTR))
            break;
        /* Nothing to read and nothing dispatched: wait for the server (a
         * reply that never comes hangs here: libFuzzer's -timeout). */
        if (!g_main_context_iteration(NULL, FALSE))
            g_main_context_iteration(NULL, TRUE);
    }
    close(fd);
    return out;
}

/* ---- checks ------------------------------------------------------------------ */

static JsonObject *obj(JsonObject *o, const char *key)
{
    JsonNode *n = o ? json_object_get_member(o, key) : NULL;
    return n && JSON_NODE_HOLDS_OBJECT(n) ? json_node_get_object(n) : NULL;
}

static JsonArray *arr(JsonObject *o, const char *key)
{
    JsonNode *n = o ? json_object_get_member(o, key) : NULL;
    return n && JSON_NODE_HOLDS_ARRAY(n) ? json_node_get_array(n) : NULL;
}

static const char *str(JsonObject *o, const char *key)
{
    JsonNode *n = o ? json_object_get_member(o, key) : NULL;
    return is_str(n) ? json_node_get_string(n) : NULL;
}

static const char *arg_s(const req *r, const char *key)
{
    return str(r->args, key);
}

static int arg_i(const req *r, const char *key, gint64 def)
{
    JsonNode *n = r->args ? json_object_get_member(r->args, key) : NULL;
    return is_int(n) ? (int)json_node_get_int(n) : (int)def;
}

/* The error's message names what is wrong. */
static void check_error(const req *r, const char *code, const char *msg, const char *line)
{
    static const char *const codes[] = {"bad-json", "too-large", "bad-request",
                                        "unknown-command", "not-found", "conflict"};
    int known = 0;
    for (size_t i = 0; i < G_N_ELEMENTS(codes); i++)
        known |= !strcmp(codes[i], code);
    require(known, "error code (never internal, device or busy here)", line);
    require(msg[0] != '\0', "error message", line);
    if (r->code) {
        require(!strcmp(code, r->code), "error code of a malformed request", line);
        if (!strcmp(code, "unknown-command")) {
            for (size_t i = 0; i < G_N_ELEMENTS(protocol); i++)
                require(strstr(msg, protocol[i].name) != NULL,
                        "unknown-command lists every command", line);
        } else if (!r->too_large) {
            require(strstr(msg, r->bad) != NULL, "error names the bad part", line);
        }
        return;
    }
    const char *cmd = r->cmd->name;
    if (!strcmp(code, "bad-request")) {
        int named = 0;
        for (int i = 0; r->cmd->args[i]; i++)
            named |= strstr(msg, r->cmd->args[i]) != NULL;
        require(named, "bad-request names one of the command's arguments", line);
    } else if (!strcmp(code, "not-found")) {
        require(takes(r->cmd, "run") || takes(r->cmd, "screen"), "not-found from a lookup",
                line);
        require(strstr(msg, "run") || strstr(msg, "screen") || strstr(msg, "mask"),
                "not-found names what", line);
    } else {
        require(!strcmp(code, "conflict") &&
                    (!strcmp(cmd, "abort-run") || !strcmp(cmd, "reconstruct")),
                "conflict only from abort-run or reconstruct", line);
        require(strstr(msg, "run ") != NULL, "conflict names the run", line);
    }
}

static int uuid_ok(const char *u)
{
    return u && strlen(u) == CATALOG_UUID_LEN && g_uuid_string_is_valid(u) &&
           strspn(u, "0123456789abcdef-") == CATALOG_UUID_LEN;
}

/* Prefix p (any case) of uuid u. */
static int prefix_of(const char *p, const char *u)
{
    return p && u && strlen(p) <= strlen(u) && !g_ascii_strncasecmp(p, u, strlen(p));
}

static void check_ok(const req *r, JsonObject *res, const char *line, int *next_spec)
{
    const char *cmd = r->cmd->name;
    require(res != NULL, "ok reply has a result object", line);
    if (!strcmp(cmd, "status")) {
        require(!g_strcmp0(str(res, "version"), SPECKLABD_VERSION) &&
                    !g_strcmp0(str(res, "state"), "running") && arr(res, "queue") &&
                    !g_strcmp0(str(res, "data_dir"), FZ.cfg.data_dir),
                "status result", line);
    } else if (!strcmp(cmd, "devices")) {
        JsonObject *cam = obj(res, "camera"), *stg = obj(res, "stage");
        require(cam && stg && json_object_has_member(cam, "connected") &&
                    !json_object_get_boolean_member(cam, "connected") &&
                    json_object_has_member(stg, "connected") &&
                    !json_object_get_boolean_member(stg, "connected") && str(stg, "error") &&
                    arr(stg, "wheels"),
                "devices without devices: not connected, with the reason", line);
    } else if (!strcmp(cmd, "start-run")) {
        const char *run = str(res, "run");
        require(*next_spec < (int)FZ.enqueued->len &&
                    !strcmp(run ? run : "",
                            g_array_index(FZ.enqueued, runner_spec, *next_spec).uuid) &&
                    !g_strcmp0(str(res, "state"), "queued"),
                "start-run replies the run it queued", line);
        (*next_spec)++;
    } else if (!strcmp(cmd, "abort-run")) {
        const char *run = str(res, "run");
        require(!g_strcmp0(str(res, "state"), "aborted") &&
                    (!g_strcmp0(run, RUN_QUEUED) || !g_strcmp0(run, RUN_CURRENT)) &&
                    prefix_of(arg_s(r, "run"), run),
                "abort-run aborts the queued or the current run", line);
    } else if (!strcmp(cmd, "runs")) {
        JsonArray *v = arr(res, "runs");
        require(v && (int)json_array_get_length(v) <= arg_i(r, "limit", 50), "runs limit", line);
        for (guint i = 0; v && i < json_array_get_length(v); i++) {
            JsonObject *o = json_array_get_object_element(v, i);
            require(o && uuid_ok(str(o, "uuid")), "runs: run objects", line);
            require(!arg_s(r, "state") || !g_strcmp0(str(o, "state"), arg_s(r, "state")),
                    "runs: state filter", line);
        }
    } else if (!strcmp(cmd, "run")) {
        JsonObject *o = obj(res, "run");
        require(o && prefix_of(arg_s(r, "run"), str(o, "uuid")) &&
                    arr(res, "reconstructions"),
                "run: the run named", line);
    } else if (!strcmp(cmd, "screens") || !strcmp(cmd, "masks")) {
        require(arr(res, cmd) && (int)json_array_get_length(arr(res, cmd)) ==
                                     (!strcmp(cmd, "masks") ? FZ.cfg.nmasks : FZ.cfg.nscreens),
                "screens/masks: every configured one", line);
    } else if (!strcmp(cmd, "reconstruct")) {
        require(!g_strcmp0(str(res, "run"), RUN_STORED) &&
                    prefix_of(arg_s(r, "run"), RUN_STORED),
                "reconstruct only the run with a cube", line);
    } else {
        require(json_object_has_member(res, "subscribed"), "subscribe result", line);
    }
}

/* Free text, as PROTOCOL.md defines it. */
static int text_ok(const char *s)
{
    if (!s)
        return 1;
    if (strlen(s) > 68 || !g_utf8_validate(s, -1, NULL) || strstr(s, ".."))
        return 0;
    for (const unsigned char *p = (const unsigned char *)s; *p; p++)
        if (*p < 0x20 || *p == 0x7f || *p == '/' || *p == '\\')
            return 0;
    return 1;
}

/* path's directory, canonical, is dir. */
static void check_in(const char *dir, char *path, const char *what)
{
    char *canon = g_canonicalize_filename(path, NULL);
    char *parent = g_path_get_dirname(canon);
    require(!strcmp(parent, dir), what, path);
    g_free(parent);
    g_free(canon);
    g_free(path);
}

/* What the runner and the worker were handed stays inside DATA_DIR. */
static void check_handed_on(void)
{
    char *runs = g_build_filename(FZ.cfg.data_dir, "runs", NULL);
    char *recon = g_build_filename(FZ.cfg.data_dir, "recon", NULL);
    for (guint i = 0; i < FZ.enqueued->len; i++) {
        const runner_spec *sp = &g_array_index(FZ.enqueued, runner_spec, i);
        catalog_run r;
        require(uuid_ok(sp->uuid) && catalog_run_get(FZ.d.cat, sp->uuid, &r) == SL_OK,
                "queued run is catalogued", sp->uuid);
        int ok = r.state == CATALOG_QUEUED && text_ok(r.object) && text_ok(r.operator_name) &&
                 !strcmp(r.object ? r.object : "", sp->object);
        catalog_run_clear(&r);
        require(ok, "queued run: state and free text", sp->object);
        const config_slot *sc = config_screen_at(&FZ.cfg, sp->screen_slot);
        const config_slot *mk = config_mask_at(&FZ.cfg, sp->mask_slot);
        require(sc && mk && !strcmp(sc->name, sp->screen) && !strcmp(mk->name, sp->mask) &&
                    sp->frames >= 1 && sp->frames <= 100000 && sp->exposure_us >= 1 &&
                    sp->exposure_us <= 1e7 && sp->projections >= 0 &&
                    sp->projections <= 4096 && config_method_valid(sp->method),
                "runner_spec fields", sp->uuid);
        check_in(runs, g_strdup_printf("%s/%s.fits.part", runs, sp->uuid), "cube path");
    }
    for (guint i = 0; i < FZ.submitted->len; i++) {
        char **w = g_strsplit(g_ptr_array_index(FZ.submitted, i), " ", 2);
        require(w[0] && w[1] && !strcmp(w[0], RUN_STORED) && config_method_valid(w[1]) &&
                    strcmp(w[1], "none"),
                "worker job", g_ptr_array_index(FZ.submitted, i));
        check_in(recon, g_strdup_printf("%s/%s-%s.fits", recon, w[0], w[1]), "recon path");
        g_strfreev(w);
    }
    g_free(runs);
    g_free(recon);
}

/* Every line received, against the requests. */
static void check_replies(GArray *reqs, GString *out)
{
    require(out->len == 0 || out->str[out->len - 1] == '\n', "replies end with a newline",
            out->str);
    char **lines = g_strsplit(out->str, "\n", -1);
    guint next = 0;
    int subscribed = 0, next_spec = 0;
    char *sub_run = NULL;   /* subscribed to this run's events only */
    for (int i = 0; lines[i] && lines[i][0]; i++) {
        const char *line = lines[i];
        JsonNode *root = parse_object(line, -1);
        require(root != NULL, "every line is a JSON object", line);
        JsonObject *o = json_node_get_object(root);
        if (json_object_has_member(o, "event")) {
            require(subscribed && str(o, "event") && str(o, "run") &&
                        (!sub_run || !strcmp(sub_run, str(o, "run"))),
                    "events after subscribe, of the run subscribed to", line);
            json_node_unref(root);
            continue;
        }
        require(next < reqs->len, "no more replies than requests", line);
        const req *r = &g_array_index(reqs, req, next++);
        JsonNode *id = json_object_get_member(o, "id"), *ok = json_object_get_member(o, "ok");
        require(id && (r->has_id ? is_int(id) && json_node_get_int(id) == r->id
                                 : JSON_NODE_HOLDS_NULL(id)),
                "reply echoes the request's id", line);
        require(ok && JSON_NODE_HOLDS_VALUE(ok) &&
                    json_node_get_value_type(ok) == G_TYPE_BOOLEAN,
                "reply has ok", line);
        if (json_node_get_boolean(ok)) {
            require(!r->code, "malformed request answered ok", line);
            check_ok(r, obj(o, "result"), line, &next_spec);
            if (!strcmp(r->cmd->name, "subscribe")) {
                subscribed = 1;
                g_free(sub_run);
                sub_run = g_strdup(str(obj(o, "result"), "run"));
            }
        } else {
            JsonObject *e = obj(o, "error");
            require(e && str(e, "code") && str(e, "message"), "error object", line);
            check_error(r, str(e, "code"), str(e, "message"), line);
        }
        json_node_unref(root);
    }
    require(next == reqs->len, "one reply per request", out->str);
    g_free(sub_run);
    require(next_spec == (int)FZ.enqueued->len, "every queued run was replied", out->str);
    g_strfreev(lines);
}

/* ---- libFuzzer ------------------------------------------------------------------ */

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc, (void)argv;
    /* A GLib critical is API misuse: a finding, like a sanitizer report. */
    g_log_set_always_fatal(G_LOG_LEVEL_CRITICAL | G_LOG_LEVEL_WARNING);
    fz_setup();
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    GString *in = g_string_new_len((const char *)data, (gssize)size);
    if (size == 0 || data[size - 1] != '\n')
        g_string_append_c(in, '\n');
    GArray *reqs = split(in->str, in->len);
    char *before = fz_fingerprint();
    GString *out = converse(in->str, in->len);
    if (g_getenv("SL_FUZZ_VERBOSE"))   /* to read a conversation */
        fprintf(stderr, "%s", out->str);
    check_replies(reqs, out);
    check_handed_on();
    require(fz_tree_size() == FZ.ntree, "no file created", FZ.root);
    char *after = fz_fingerprint();
    require(FZ.dirty || !strcmp(before, after), "only start-run and abort-run change runs",
            after);
    g_free(before);
    g_free(after);
    for (guint i = 0; i < reqs->len; i++)
        if (g_array_index(reqs, req, i).root)
            json_node_unref(g_array_index(reqs, req, i).root);
    g_array_free(reqs, TRUE);
    g_string_free(out, TRUE);
    g_string_free(in, TRUE);
    g_array_set_size(FZ.enqueued, 0);
    g_ptr_array_set_size(FZ.submitted, 0);
    if (FZ.dirty)
        fz_restore();
    return 0;
}
