/* dispatch.c - request parsing, argument checks and the commands that act
 * (start-run, abort-run, reconstruct, subscribe); see dispatch.h.  The
 * read-only commands are in query.c. */
#include "dispatch_int.h"
#include "recon_opts.h"
#include "runstate.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#define TEXT_MAX 68   /* one FITS card value */

/* ---- replies and arguments ------------------------------------------------ */

char *reply_ok(request *rq, JsonNode *result)
{
    return proto_reply_ok(&rq->q, result);
}

char *reply_err(request *rq, const char *code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    char *msg = g_strdup_vprintf(fmt, ap);
    va_end(ap);
    char *line = proto_reply_error(&rq->q, code, "%s", msg);
    g_free(msg);
    return line;
}

static int is_int(JsonNode *n)
{
    return JSON_NODE_HOLDS_VALUE(n) && json_node_get_value_type(n) == G_TYPE_INT64;
}

static int is_num(JsonNode *n)
{
    return JSON_NODE_HOLDS_VALUE(n) && (json_node_get_value_type(n) == G_TYPE_INT64 ||
                                        json_node_get_value_type(n) == G_TYPE_DOUBLE);
}

static int is_str(JsonNode *n)
{
    return JSON_NODE_HOLDS_VALUE(n) && json_node_get_value_type(n) == G_TYPE_STRING;
}

/* The member, or NULL when absent or null. */
static JsonNode *member(request *rq, const char *key)
{
    JsonNode *n = json_object_get_member(rq->args, key);
    return n && !JSON_NODE_HOLDS_NULL(n) ? n : NULL;
}

static int missing(request *rq, const char *key, char **reply)
{
    *reply = reply_err(rq, "bad-request", "%s: missing argument '%s'", rq->cmd, key);
    return SL_EINVAL;
}

int arg_int(request *rq, const char *key, int required, gint64 lo, gint64 hi, gint64 *out,
            int *present, char **reply)
{
    JsonNode *n = member(rq, key);
    if (present)
        *present = n != NULL;
    if (!n)
        return required ? missing(rq, key, reply) : SL_OK;
    if (!is_int(n) || json_node_get_int(n) < lo || json_node_get_int(n) > hi) {
        char *txt = json_to_string(n, FALSE);
        *reply = reply_err(rq, "bad-request", "%s must be an integer %" G_GINT64_FORMAT "..%"
                           G_GINT64_FORMAT ", got %.80s", key, lo, hi, txt);
        g_free(txt);
        return SL_EINVAL;
    }
    *out = json_node_get_int(n);
    return SL_OK;
}

int arg_num(request *rq, const char *key, int required, double lo, double hi, double *out,
            int *present, char **reply)
{
    JsonNode *n = member(rq, key);
    if (present)
        *present = n != NULL;
    if (!n)
        return required ? missing(rq, key, reply) : SL_OK;
    double v = is_num(n) ? json_node_get_double(n) : NAN;
    if (!(v >= lo && v <= hi)) {
        char *txt = json_to_string(n, FALSE);
        *reply = reply_err(rq, "bad-request", "%s must be a number %g..%g, got %.80s", key, lo,
                           hi, txt);
        g_free(txt);
        return SL_EINVAL;
    }
    *out = v;
    return SL_OK;
}

int arg_str(request *rq, const char *key, int required, int allow_int, char **out,
            char **reply)
{
    JsonNode *n = member(rq, key);
    *out = NULL;
    if (!n)
        return required ? missing(rq, key, reply) : SL_OK;
    if (allow_int && is_int(n)) {
        *out = g_strdup_printf("%" G_GINT64_FORMAT, json_node_get_int(n));
        return SL_OK;
    }
    if (!is_str(n)) {
        *reply = reply_err(rq, "bad-request", "%s must be a string%s", key,
                           allow_int ? " or an integer" : "");
        return SL_EINVAL;
    }
    *out = g_strdup(json_node_get_string(n));
    return SL_OK;
}

/* Free text that may end up in a FITS card or a file name downstream. */
static int text_ok(const char *s)
{
    size_t n = strlen(s);
    if (n > TEXT_MAX || !g_utf8_validate(s, -1, NULL) || strstr(s, ".."))
        return 0;
    for (const unsigned char *p = (const unsigned char *)s; *p; p++)
        if (*p < 0x20 || *p == 0x7f || *p == '/' || *p == '\\')
            return 0;
    return 1;
}

int arg_run(request *rq, const char *key, int required, char uuid[CATALOG_UUID_LEN + 1],
            int *present, char **reply)
{
    char *s = NULL;
    int rc = arg_str(rq, key, required, 0, &s, reply);
    if (present)
        *present = s != NULL;
    if (rc != SL_OK || !s)
        return rc;
    size_t n = strlen(s);
    if (n < 4 || n > CATALOG_UUID_LEN || strspn(s, "0123456789abcdefABCDEF-") != n) {
        *reply = reply_err(rq, "bad-request", "%s must be a run uuid or a prefix of at least "
                           "4 hex digits, got '%.40s'", key, s);
        rc = SL_EINVAL;
    } else if (catalog_run_resolve(rq->d->cat, s, uuid) != SL_OK) {
        *reply = reply_err(rq, "not-found", "%s", catalog_errmsg(rq->d->cat));
        rc = SL_EINVAL;
    }
    g_free(s);
    return rc;
}

int arg_since(request *rq, int64_t *since_ms, char **reply)
{
    JsonNode *n = member(rq, "since");
    sl_err e = {0};
    *since_ms = 0;
    if (!n)
        return SL_OK;
    /* An integer goes through the text parser too, for its range check
     * (seconds * 1000 overflowed int64 for |s| > 9.2e15: found by review
     * while writing the fuzz target, kept in its corpus). */
    char secs[32];
    if (is_int(n))
        snprintf(secs, sizeof secs, "%" G_GINT64_FORMAT, json_node_get_int(n));
    const char *text = is_int(n) ? secs : is_str(n) ? json_node_get_string(n) : NULL;
    if (text && catalog_time_parse(text, since_ms, &e) == SL_OK)
        return SL_OK;
    *reply = reply_err(rq, "bad-request", "since must be ISO-8601, a date or unix seconds%s%s",
                       e.msg[0] ? ": " : "", e.msg);
    return SL_EINVAL;
}

/* ---- start-run ------------------------------------------------------------ */

static char *slot_names(const config_slot *v, int n)
{
    GString *s = g_string_new(NULL);
    for (int i = 0; i < n; i++)
        g_string_append_printf(s, "%s%s (%d)", i ? ", " : "", v[i].name, v[i].slot);
    return g_string_free(s, FALSE);
}

static char *settings_json(const config *cfg, double exposure_us)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    proto_add_dbl(b, "exposure_us", exposure_us);
    proto_add_str(b, "pixel_format", cfg->pixel_format);
    proto_add_dbl(b, "frame_rate_hz", cfg->frame_rate_hz);
    if (cfg->roi[2] > 0) {
        json_builder_set_member_name(b, "roi");
        json_builder_begin_array(b);
        for (int i = 0; i < 4; i++)
            json_builder_add_int_value(b, cfg->roi[i]);
        json_builder_end_array(b);
    }
    proto_add_str(b, "camera", cfg->camera_address);
    json_builder_end_object(b);
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    return proto_take_string(n);
}

/* start-run's arguments, read and checked (start_read). */
typedef struct start_args {
    char *screen, *mask, *object, *oper, *method, *kind;
    gint64 frames, proj;
    double exposure_us;
    catalog_kind k;
    const config_slot *sc, *mk;
} start_args;

static void start_args_clear(start_args *a)
{
    g_free(a->screen), g_free(a->mask), g_free(a->object), g_free(a->oper);
    g_free(a->method), g_free(a->kind);
}

/* NULL, or the error reply. */
static char *start_read(request *rq, start_args *a)
{
    const config *cfg = rq->d->cfg;
    char *reply = NULL;
    a->exposure_us = cfg->exposure_us;
    if (arg_str(rq, "screen", 1, 1, &a->screen, &reply) ||
        arg_str(rq, "mask", 1, 1, &a->mask, &reply) ||
        arg_int(rq, "frames", 1, 1, 100000, &a->frames, NULL, &reply) ||
        arg_num(rq, "exposure_us", 0, 1, 1e7, &a->exposure_us, NULL, &reply) ||
        arg_str(rq, "object", 0, 0, &a->object, &reply) ||
        arg_str(rq, "operator", 0, 0, &a->oper, &reply) ||
        arg_str(rq, "reconstruct", 0, 0, &a->method, &reply) ||
        arg_int(rq, "projections", 0, 1, 4096, &a->proj, NULL, &reply) ||
        arg_str(rq, "kind", 0, 0, &a->kind, &reply))
        return reply;
    if ((a->object && !text_ok(a->object)) || (a->oper && !text_ok(a->oper)))
        return reply_err(rq, "bad-request", "%s must be at most %d bytes of UTF-8 without "
                         "control characters, '/', '\\' or '..'",
                         a->object && !text_ok(a->object) ? "object" : "operator", TEXT_MAX);
    if (a->method && !config_method_valid(a->method))
        return reply_err(rq, "bad-request", "reconstruct must be auto, direct, tsm, tsm-fourier "
                         "or none, got '%.40s'", a->method);
    a->k = CATALOG_SCIENCE;
    if (a->kind && catalog_kind_parse(a->kind, &a->k) != SL_OK)
        return reply_err(rq, "bad-request", "kind must be science, dark, flat or calibrator, "
                         "got '%.40s'", a->kind);
    /* a dark or a flat is calibration, never an image of anything */
    int calib = a->k == CATALOG_DARK || a->k == CATALOG_FLAT;
    if (calib && a->method && strcmp(a->method, "none"))
        return reply_err(rq, "bad-request", "a %s run is not reconstructed: reconstruct "
                         "'%.40s' with kind %s", a->kind, a->method, a->kind);
    if (!(a->sc = config_screen_find(cfg, a->screen)) || !(a->mk = config_mask_find(cfg, a->mask))) {
        int bad_screen = !a->sc;
        char *names = bad_screen ? slot_names(cfg->screens, cfg->nscreens)
                                 : slot_names(cfg->masks, cfg->nmasks);
        reply = reply_err(rq, "not-found", "no %s '%.64s' on the wheel; configured: %s",
                          bad_screen ? "screen" : "mask", bad_screen ? a->screen : a->mask,
                          names);
        g_free(names);
    }
    return reply;
}

static JsonNode *queued_node(const char *uuid, int ahead, const char *behind)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    proto_add_str(b, "run", uuid);
    proto_add_str(b, "state", "queued");
    proto_add_int(b, "queue_position", ahead);
    proto_add_str(b, "queued_behind", behind[0] ? behind : NULL);
    json_builder_end_object(b);
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    return n;
}

static char *cmd_start_run(request *rq)
{
    daemon_ctx *d = rq->d;
    const config *cfg = d->cfg;
    start_args a = {0};
    char *reply = NULL, *settings = NULL;
    int64_t screen_id = 0, mask_id = 0;
    if ((reply = start_read(rq, &a)))
        goto free_args;
    if (catalog_screen_find(d->cat, a.sc->name, &screen_id) != SL_OK ||
        catalog_mask_find(d->cat, a.mk->name, &mask_id) != SL_OK) {
        reply = reply_err(rq, "internal", "%s", catalog_errmsg(d->cat));
        goto free_args;
    }
    runner_status rs;
    runner_status_get(d->run, &rs);
    g_strfreev(rs.queue);
    settings = settings_json(cfg, a.exposure_us);
    catalog_run_spec spec = {
        .operator_name = a.oper, .object = a.object, .screen_id = screen_id,
        .mask_id = mask_id, .camera_serial = rs.camera.serial[0] ? rs.camera.serial : NULL,
        .camera_settings_json = settings, .frames_requested = (int)a.frames, .kind = a.k};
    runner_spec sp = {0};
    if (catalog_run_insert(d->cat, &spec, sp.uuid) != SL_OK) {
        reply = reply_err(rq, "internal", "%s", catalog_errmsg(d->cat));
        goto free_args;
    }
    sp.screen_slot = a.sc->slot, sp.mask_slot = a.mk->slot;
    snprintf(sp.screen, sizeof sp.screen, "%s", a.sc->name);
    snprintf(sp.mask, sizeof sp.mask, "%s", a.mk->name);
    snprintf(sp.object, sizeof sp.object, "%s", a.object ? a.object : "");
    int calib = a.k == CATALOG_DARK || a.k == CATALOG_FLAT;
    snprintf(sp.method, sizeof sp.method, "%s",
             calib ? "none" : a.method ? a.method : cfg->reconstruct);
    sp.frames = (int)a.frames;
    sp.exposure_us = a.exposure_us;
    sp.projections = (int)a.proj;
    sp.kind = a.k;
    int ahead = 0;
    char behind[CATALOG_UUID_LEN + 1];
    char *ev = proto_event_state(sp.uuid, CATALOG_QUEUED, NULL);
    server_event(d->srv, sp.uuid, ev);
    g_free(ev);
    runner_enqueue(d->run, &sp, &ahead, behind);
    reply = reply_ok(rq, queued_node(sp.uuid, ahead, behind));
free_args:
    start_args_clear(&a);
    g_free(settings);
    return reply;
}

/* ---- abort-run, reconstruct, subscribe ------------------------------------ */

static JsonNode *run_state_node(const char *uuid, const char *state)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    proto_add_str(b, "run", uuid);
    proto_add_str(b, "state", state);
    json_builder_end_object(b);
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    return n;
}

static char *cmd_abort_run(request *rq)
{
    char uuid[CATALOG_UUID_LEN + 1], *reply = NULL;
    catalog_run r;
    if (arg_run(rq, "run", 1, uuid, NULL, &reply) != SL_OK)
        return reply;
    if (catalog_run_get(rq->d->cat, uuid, &r) != SL_OK)
        return reply_err(rq, "not-found", "%s", catalog_errmsg(rq->d->cat));
    catalog_state st = r.state;
    catalog_run_clear(&r);
    if (catalog_state_is_terminal(st))
        return reply_err(rq, "conflict", "run %s is already %s", uuid, catalog_state_name(st));
    if (st == CATALOG_STORED || st == CATALOG_RECONSTRUCTING)
        return reply_err(rq, "conflict", "run %s has finished acquiring (%s): its frames are "
                         "stored; a reconstruction cannot be aborted", uuid,
                         catalog_state_name(st));
    switch (runner_abort(rq->d->run, uuid, &rq->q)) {
    case RUNNER_ABORTING:
        return NULL;   /* the runner replies once the run has stopped */
    case RUNNER_DEQUEUED:   /* one attempt: the main loop does not wait on a lock */
        if (runstate_set(rq->d->cat, NULL, rq->d->srv, uuid, CATALOG_ABORTED,
                         "aborted by request", NULL, NULL) != SL_OK)
            return reply_err(rq, "internal", "%s", catalog_errmsg(rq->d->cat));
        return reply_ok(rq, run_state_node(uuid, "aborted"));
    default:
        return reply_err(rq, "conflict", "run %s is %s but not in this daemon's queue", uuid,
                         catalog_state_name(st));
    }
}

static char *cmd_reconstruct(request *rq)
{
    daemon_ctx *d = rq->d;
    char uuid[CATALOG_UUID_LEN + 1], *reply = NULL, *method = NULL, *why = NULL;
    char opts[RECON_OPTS_MAX], opt_method[16] = "", *calibrator = NULL;
    gint64 proj = 0;
    int opt_proj = -1;
    catalog_run r;
    /* Syntax first, then lookups: a bad argument is reported as such even
     * when the run does not exist. */
    if (arg_str(rq, "method", 0, 0, &method, &reply) ||
        arg_int(rq, "projections", 0, 1, 4096, &proj, NULL, &reply) ||
        arg_str(rq, "calibrator", 0, 0, &calibrator, &reply))
        goto free_method;
    if ((why = recon_opts_read(rq->args, opts, opt_method, &opt_proj))) {
        reply = reply_err(rq, "bad-request", "%s", why);   /* recon's own words */
        g_free(why);
        goto free_method;
    }
    if (opt_method[0])
        g_free(method), method = g_strdup(opt_method);
    if (opt_proj >= 0)
        proj = opt_proj;
    if (!method)
        method = g_strdup(strcmp(d->cfg->reconstruct, "none") ? d->cfg->reconstruct : "auto");
    pipeline_opts po;
    sl_err e = {0};
    pipeline_opts_defaults(&po);
    if (pipeline_opts_set(&po, "method", method, &e) != SL_OK) {
        reply = reply_err(rq, "bad-request", "%s", e.msg);   /* recon's words */
        goto free_method;
    }
    if (arg_run(rq, "run", 1, uuid, NULL, &reply))
        goto free_method;
    if (catalog_run_get(d->cat, uuid, &r) != SL_OK) {
        reply = reply_err(rq, "not-found", "%s", catalog_errmsg(d->cat));
        goto free_method;
    }
    if (r.state == CATALOG_QUEUED || r.state == CATALOG_MOVING || r.state == CATALOG_ACQUIRING)
        reply = reply_err(rq, "conflict", "run %s is %s: its cube is not complete yet", uuid,
                          catalog_state_name(r.state));
    else if (r.kind == CATALOG_DARK || r.kind == CATALOG_FLAT)
        reply = reply_err(rq, "bad-request", "run %s is a %s: calibration, not an image to "
                          "reconstruct", uuid, catalog_kind_name(r.kind));
    else if (!r.file_path || !g_file_test(r.file_path, G_FILE_TEST_IS_REGULAR))
        reply = reply_err(rq, "not-found", "run %s has no cube on disk%s%s", uuid,
                          r.file_path ? ": " : "", r.file_path ? r.file_path : "");
    else
        worker_submit(d->wk, uuid, method, (int)proj, &(worker_extra){opts, calibrator},
                      &rq->q);   /* replies when done; the worker checks the calibrator */
    catalog_run_clear(&r);
free_method:
    g_free(method);
    g_free(calibrator);
    return reply;
}

static char *cmd_subscribe(request *rq)
{
    char uuid[CATALOG_UUID_LEN + 1], *reply = NULL;
    int present = 0;
    if (arg_run(rq, "run", 0, uuid, &present, &reply) != SL_OK)
        return reply;
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    proto_add_bool(b, "subscribed", 1);
    proto_add_str(b, "run", present ? uuid : NULL);
    json_builder_end_object(b);
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    server_complete_subscribe(rq->d->srv, rq->q.tok, reply_ok(rq, n), present ? uuid : NULL);
    return NULL;
}

/* ---- the table ------------------------------------------------------------ */

typedef struct command {
    const char *name;
    handler_fn fn;
    const char *args[10];
} command;

static const command commands[] = {
    {"status", cmd_status, {NULL}},
    {"devices", cmd_devices, {NULL}},
    {"start-run", cmd_start_run, {"screen", "mask", "frames", "exposure_us", "object",
                                  "operator", "reconstruct", "projections", "kind", NULL}},
    {"abort-run", cmd_abort_run, {"run", NULL}},
    {"runs", cmd_runs, {"state", "screen", "since", "limit", "kind", NULL}},
    {"run", cmd_run, {"run", NULL}},
    {"screens", cmd_screens, {"since", NULL}},
    {"masks", cmd_masks, {NULL}},
    {"reconstruct", cmd_reconstruct, {"run", "method", "projections", "options", "calibrator",
                                      NULL}},
    {"subscribe", cmd_subscribe, {"run", NULL}},
};

static char *check_args(request *rq, const command *c)
{
    GList *keys = json_object_get_members(rq->args);
    char *reply = NULL;
    for (GList *l = keys; l && !reply; l = l->next) {
        int ok = 0;
        for (int i = 0; c->args[i]; i++)
            ok |= !strcmp(c->args[i], l->data);
        if (!ok) {
            GString *s = g_string_new(NULL);
            for (int i = 0; c->args[i]; i++)
                g_string_append_printf(s, "%s%s", i ? ", " : "", c->args[i]);
            reply = reply_err(rq, "bad-request", "%s takes no argument '%.40s' (%s%s)", c->name,
                              (const char *)l->data, s->len ? "it takes " : "it takes none",
                              s->str);
            g_string_free(s, TRUE);
        }
    }
    g_list_free(keys);
    return reply;
}

void dispatch_request(server *s, server_token tok, const char *line, size_t len, void *user)
{
    request rq = {.d = user, .q = {.tok = tok}};
    JsonParser *p = json_parser_new_immutable();
    GError *ge = NULL;
    char *reply = NULL;
    JsonObject *empty = json_object_new();
    if (!json_parser_load_from_data(p, line, (gssize)len, &ge) || !json_parser_get_root(p) ||
        !JSON_NODE_HOLDS_OBJECT(json_parser_get_root(p))) {
        reply = reply_err(&rq, "bad-json", "request is not a JSON object%s%s",
                          ge ? ": " : "", ge ? ge->message : "");
        goto send;
    }
    JsonObject *o = json_node_get_object(json_parser_get_root(p));
    JsonNode *id = json_object_get_member(o, "id");
    proto_badnum bn;
    int nums_ok = proto_numbers_ok(line, len, &bn);
    if (id && is_int(id) && !bn.top_id) {
        rq.q.id = json_node_get_int(id);
        rq.q.has_id = 1;
    } else if (id && !JSON_NODE_HOLDS_NULL(id)) {
        reply = reply_err(&rq, "bad-request", "id must be a JSON integer from -2^63 to "
                          "2^63-1%s%s", bn.top_id ? ", got " : "", bn.top_id ? bn.literal : "");
        goto send;
    }
    /* json-glib would have read it as another number: refused, never
     * guessed. */
    if (!nums_ok) {
        reply = reply_err(&rq, "bad-request", "%s%s%s is %s", bn.key, bn.key[0] ? ": " : "",
                          bn.literal, bn.not_json ? "not a JSON number"
                                                  : "an integer outside -2^63..2^63-1");
        goto send;
    }
    JsonNode *cmd = json_object_get_member(o, "cmd");
    JsonNode *args = json_object_get_member(o, "args");
    if (!cmd || !is_str(cmd)) {
        reply = reply_err(&rq, "bad-request", "cmd must be a string");
        goto send;
    }
    if (args && !JSON_NODE_HOLDS_OBJECT(args) && !JSON_NODE_HOLDS_NULL(args)) {
        reply = reply_err(&rq, "bad-request", "args must be an object");
        goto send;
    }
    rq.cmd = json_node_get_string(cmd);
    rq.args = args && JSON_NODE_HOLDS_OBJECT(args) ? json_node_get_object(args) : empty;
    const command *c = NULL;
    for (size_t i = 0; i < G_N_ELEMENTS(commands) && !c; i++)
        if (!strcmp(commands[i].name, rq.cmd))
            c = &commands[i];
    if (!c) {
        GString *names = g_string_new(NULL);
        for (size_t i = 0; i < G_N_ELEMENTS(commands); i++)
            g_string_append_printf(names, "%s%s", i ? ", " : "", commands[i].name);
        reply = reply_err(&rq, "unknown-command", "unknown command '%.40s'; known: %s", rq.cmd,
                          names->str);
        g_string_free(names, TRUE);
        goto send;
    }
    if (!(reply = check_args(&rq, c)))
        reply = c->fn(&rq);
send:
    if (reply)
        server_complete(s, tok, reply);
    if (ge)
        g_error_free(ge);
    json_object_unref(empty);
    g_object_unref(p);
}
