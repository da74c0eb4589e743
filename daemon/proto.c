/* proto.c - reply, event and object JSON; see proto.h. */
#include "proto.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

void proto_add_str(JsonBuilder *b, const char *key, const char *v)
{
    json_builder_set_member_name(b, key);
    if (v)
        json_builder_add_string_value(b, v);
    else
        json_builder_add_null_value(b);
}

void proto_add_int(JsonBuilder *b, const char *key, gint64 v)
{
    json_builder_set_member_name(b, key);
    json_builder_add_int_value(b, v);
}

void proto_add_dbl(JsonBuilder *b, const char *key, double v)
{
    json_builder_set_member_name(b, key);
    if (isfinite(v))
        json_builder_add_double_value(b, v);
    else
        json_builder_add_null_value(b);
}

void proto_add_bool(JsonBuilder *b, const char *key, int v)
{
    json_builder_set_member_name(b, key);
    json_builder_add_boolean_value(b, v != 0);
}

void proto_add_time(JsonBuilder *b, const char *key, int64_t t_ms)
{
    char buf[CATALOG_TIME_MAX];
    if (t_ms > 0)
        catalog_time_format(t_ms, buf);
    proto_add_str(b, key, t_ms > 0 ? buf : NULL);
}

char *proto_take_string(JsonNode *n)
{
    char *s = json_to_string(n, FALSE);
    json_node_unref(n);
    return s;
}

/* JSON's number: -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?; *is_int
 * when it has neither fraction nor exponent. */
static int json_number(const char *t, size_t n, int *is_int)
{
    size_t i = t[0] == '-';
    size_t d = i;
    while (i < n && g_ascii_isdigit(t[i]))
        i++;
    if (i == d || (t[d] == '0' && i - d > 1))
        return 0;
    *is_int = i == n;
    if (i < n && t[i] == '.') {
        size_t f = ++i;
        while (i < n && g_ascii_isdigit(t[i]))
            i++;
        if (i == f)
            return 0;
    }
    if (i < n && (t[i] == 'e' || t[i] == 'E')) {
        i += i + 1 < n && (t[i + 1] == '+' || t[i + 1] == '-') ? 2 : 1;
        size_t e = i;
        while (i < n && g_ascii_isdigit(t[i]))
            i++;
        if (i == e)
            return 0;
    }
    return i == n;
}

#define KEY_DEPTH 16   /* members deeper than this are not named */

/* One pass over the line.  json-glib has parsed it, so outside strings a
 * number is a run of [0-9A-Za-z+-.] starting with a digit, '-' or '.',
 * and a string right after '{' or ',' of an object is a member's name. */
int proto_numbers_ok(const char *text, size_t len, proto_badnum *bad)
{
    char keys[KEY_DEPTH][sizeof bad->key];
    int is_obj[KEY_DEPTH + 1] = {0}, depth = 0, want_key = 0;
    memset(bad, 0, sizeof *bad);
    for (size_t i = 0; i < len;) {
        char ch = text[i];
        if (ch == '"') {
            size_t start = ++i;
            while (i < len && text[i] != '"')
                i += text[i] == '\\' ? 2 : 1;
            if (want_key && depth <= KEY_DEPTH)
                snprintf(keys[depth - 1], sizeof keys[0], "%.*s", (int)(MIN(i, len) - start),
                         text + start);
            want_key = 0;
            i++;
        } else if (ch == '-' || ch == '.' || g_ascii_isdigit(ch)) {
            size_t start = i;
            int is_int = 0;
            while (i < len && (g_ascii_isalnum(text[i]) || (text[i] && strchr("+-.", text[i]))))
                i++;
            int ok = json_number(text + start, i - start, &is_int);
            char tok[64];
            snprintf(tok, sizeof tok, "%.*s", (int)MIN(i - start, sizeof tok - 1), text + start);
            if (ok && is_int && (i - start >= sizeof tok ||
                                 !g_ascii_string_to_signed(tok, 10, G_MININT64, G_MAXINT64,
                                                           NULL, NULL)))
                ok = 0;
            if (ok)
                continue;
            g_strlcpy(bad->literal, tok, sizeof bad->literal);
            bad->not_json = !json_number(text + start, i - start, &is_int);
            for (int d = MIN(depth, KEY_DEPTH); d >= 1 && !bad->key[0]; d--)
                if (is_obj[d])
                    snprintf(bad->key, sizeof bad->key, "%s", keys[d - 1]);
            bad->top_id = depth == 1 && !strcmp(bad->key, "id");
            return 0;
        } else {
            if (ch == '{' || ch == '[') {
                depth++;
                if (depth <= KEY_DEPTH)
                    is_obj[depth] = ch == '{', keys[depth - 1][0] = '\0';
            } else if (ch == '}' || ch == ']') {
                depth--;
            }
            if (ch && strchr("{}[]:,", ch))   /* whitespace, true/false/null: nothing */
                want_key = (ch == '{' || ch == ',') && depth >= 1 && depth <= KEY_DEPTH &&
                           is_obj[depth];
            i++;
        }
    }
    return 1;
}

JsonNode *proto_parse_object(const char *text)
{
    if (!text || !*text)
        return NULL;
    JsonParser *p = json_parser_new_immutable();
    JsonNode *n = NULL;
    if (json_parser_load_from_data(p, text, -1, NULL)) {
        JsonNode *root = json_parser_get_root(p);
        if (root && JSON_NODE_HOLDS_OBJECT(root))
            n = json_node_copy(root);
    }
    g_object_unref(p);
    return n;
}

static JsonBuilder *reply_start(const proto_req *q, int ok)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    json_builder_set_member_name(b, "id");
    if (q && q->has_id)
        json_builder_add_int_value(b, q->id);
    else
        json_builder_add_null_value(b);
    proto_add_bool(b, "ok", ok);
    return b;
}

static char *builder_take(JsonBuilder *b)
{
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    return proto_take_string(n);
}

char *proto_reply_ok(const proto_req *q, JsonNode *result)
{
    JsonBuilder *b = reply_start(q, 1);
    json_builder_set_member_name(b, "result");
    if (!result) {
        json_builder_begin_object(b);
        json_builder_end_object(b);
    } else {
        json_builder_add_value(b, result);   /* takes it */
    }
    json_builder_end_object(b);
    return builder_take(b);
}

char *proto_reply_error(const proto_req *q, const char *code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    char *msg = g_strdup_vprintf(fmt, ap);
    va_end(ap);
    /* Messages quote client input: keep the reply valid UTF-8. */
    char *clean = g_utf8_make_valid(msg, -1);
    JsonBuilder *b = reply_start(q, 0);
    json_builder_set_member_name(b, "error");
    json_builder_begin_object(b);
    proto_add_str(b, "code", code);
    proto_add_str(b, "message", clean);
    json_builder_end_object(b);
    json_builder_end_object(b);
    g_free(clean);
    g_free(msg);
    return builder_take(b);
}

static JsonBuilder *event_start(const char *event, const char *run)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    proto_add_str(b, "event", event);
    proto_add_str(b, "run", run);
    return b;
}

char *proto_event_state(const char *run, catalog_state st, const char *reason)
{
    JsonBuilder *b = event_start("state", run);
    proto_add_str(b, "state", catalog_state_name(st));
    proto_add_str(b, "reason", reason);
    json_builder_end_object(b);
    return builder_take(b);
}

char *proto_event_progress(const char *run, int acquired, int requested, int failed)
{
    JsonBuilder *b = event_start("progress", run);
    proto_add_int(b, "frames_acquired", acquired);
    proto_add_int(b, "frames_requested", requested);
    proto_add_int(b, "frames_failed", failed);
    json_builder_end_object(b);
    return builder_take(b);
}

char *proto_event_recon(const char *run, JsonNode *recon)
{
    JsonBuilder *b = event_start("reconstruction", run);
    json_builder_set_member_name(b, "reconstruction");
    json_builder_add_value(b, recon);
    json_builder_end_object(b);
    return builder_take(b);
}

/* The run's own r0: the newest measurement of its screen made from it. */
typedef struct r0_find {
    const char *uuid;
    double r0_m, seeing_arcsec, r0_err_m, wavelength_m;
} r0_find;

static int r0_match(const catalog_r0 *r, void *user)
{
    r0_find *f = user;
    if (r->run_uuid && !g_ascii_strcasecmp(r->run_uuid, f->uuid)) {
        f->r0_m = r->r0_m;
        f->seeing_arcsec = r->seeing_arcsec;
        f->r0_err_m = r->r0_err_m;
        f->wavelength_m = r->wavelength_m;
    }
    return 0;
}

static void add_json_text(JsonBuilder *b, const char *key, const char *text)
{
    JsonNode *n = proto_parse_object(text);
    json_builder_set_member_name(b, key);
    if (n)
        json_builder_add_value(b, n);
    else
        json_builder_add_null_value(b);
}

JsonNode *proto_run_node(catalog *c, const catalog_run *r)
{
    r0_find f = {r->uuid, NAN, NAN, NAN, NAN};
    if (r->screen_name)
        catalog_r0_list(c, r->screen_name, r->created_ms, r0_match, &f);
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    proto_add_str(b, "uuid", r->uuid);
    proto_add_str(b, "state", catalog_state_name(r->state));
    proto_add_str(b, "kind", catalog_kind_name(r->kind ? r->kind : CATALOG_SCIENCE));
    proto_add_str(b, "exit_reason", r->exit_reason);
    proto_add_time(b, "created", r->created_ms);
    proto_add_time(b, "started", r->started_ms);
    proto_add_time(b, "ended", r->ended_ms);
    proto_add_str(b, "operator", r->operator_name);
    proto_add_str(b, "object", r->object);
    proto_add_str(b, "screen", r->screen_name);
    proto_add_str(b, "mask", r->mask_name);
    proto_add_str(b, "camera_serial", r->camera_serial);
    add_json_text(b, "camera_settings", r->camera_settings_json);
    proto_add_int(b, "frames_requested", r->frames_requested);
    proto_add_int(b, "frames_acquired", r->frames_acquired);
    proto_add_int(b, "frames_failed", r->frames_failed);
    proto_add_int(b, "packets_missing", r->packets_missing);
    proto_add_str(b, "file", r->file_path);
    proto_add_str(b, "sha256", r->file_sha256);
    proto_add_dbl(b, "r0_m", f.r0_m);
    proto_add_dbl(b, "seeing_arcsec", f.seeing_arcsec);
    /* r0 holds at a wavelength (r0 ~ lambda^(6/5)): say which, with the
     * measurement's error */
    proto_add_dbl(b, "r0_err_m", f.r0_err_m);
    proto_add_dbl(b, "r0_wavelength_m", f.wavelength_m);
    json_builder_end_object(b);
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    return n;
}

JsonNode *proto_recon_node(const catalog_recon *r)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    proto_add_int(b, "id", r->id);
    proto_add_str(b, "method", r->method);
    add_json_text(b, "params", r->params_json);
    proto_add_time(b, "started", r->started_ms);
    proto_add_dbl(b, "elapsed_s", r->elapsed_s);
    proto_add_str(b, "fits", r->output_fits);
    proto_add_str(b, "png", r->output_png);
    proto_add_dbl(b, "sep_px", r->sep_px);
    proto_add_dbl(b, "sep_err_px", r->sep_err_px);
    proto_add_dbl(b, "pa_deg", r->pa_deg);
    proto_add_dbl(b, "pa_err_deg", r->pa_err_deg);
    proto_add_dbl(b, "dm_mag", r->dm_mag);
    proto_add_dbl(b, "dm_err_mag", r->dm_err_mag);
    proto_add_dbl(b, "sep_arcsec", r->sep_arcsec);
    proto_add_dbl(b, "c_cophased", r->c_cophased);
    add_json_text(b, "quality", r->quality_json);
    json_builder_end_object(b);
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    return n;
}
