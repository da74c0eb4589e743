/* cmd_daemon.c - helpers shared by the daemon subcommands (cmd_daemon.h),
 * `specklab daemon status` and `specklab masks list`. */
#include "cmd_daemon.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "progress.h"

void dcmd_opts_add(dcmd_opts *o, GOptionContext *ctx)
{
    GOptionEntry e[3] = {
        {"socket", 0, 0, G_OPTION_ARG_FILENAME, &o->socket,
         "specklabd control socket (default $SPECKLAB_SOCKET, else " CLIENT_SYSTEM_SOCKET " when it exists, else " CLIENT_DEFAULT_SOCKET ")", "PATH"},
        {"json", 0, 0, G_OPTION_ARG_NONE, &o->json, "print JSON on one line", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    memcpy(o->entries, e, sizeof e);
    g_option_context_add_main_entries(ctx, o->entries, NULL);
}

void dcmd_opts_clear(dcmd_opts *o)
{
    g_free(o->socket);
    o->socket = NULL;
}

client *dcmd_connect(const dcmd_opts *o, const char *prog)
{
    client *c = NULL;
    sl_err e = {0};
    if (client_connect(&c, client_socket_path(o->socket), DCMD_CONNECT_MS, &e) != SL_OK) {
        fprintf(stderr, "%s: %s\n", prog, e.msg);
        return NULL;
    }
    return c;
}

int dcmd_call(client *c, const char *prog, const char *cmd, JsonObject *args,
              int timeout_ms, JsonObject **result)
{
    if (client_call(c, cmd, args, timeout_ms, result) == SL_OK)
        return 0;
    fprintf(stderr, "%s: %s\n", prog, client_errmsg(c));
    return 1;
}

void dcmd_print_node(JsonNode *n)
{
    JsonGenerator *g = json_generator_new();
    json_generator_set_root(g, n);
    gchar *text = json_generator_to_data(g, NULL);
    printf("%s\n", text);
    g_free(text);
    g_object_unref(g);
}

void dcmd_print_object(JsonObject *o)
{
    JsonNode *n = json_node_init_object(json_node_alloc(), o);
    dcmd_print_node(n);
    json_node_unref(n);
}

static JsonNode *member(JsonObject *o, const char *k)
{
    return o && k ? json_object_get_member(o, k) : NULL;
}

const char *dcmd_str(JsonObject *o, const char *k)
{
    JsonNode *n = member(o, k);
    if (n && JSON_NODE_HOLDS_VALUE(n) && json_node_get_value_type(n) == G_TYPE_STRING)
        return json_node_get_string(n);
    return NULL;
}

double dcmd_num(JsonObject *o, const char *k)
{
    JsonNode *n = member(o, k);
    if (!n || !JSON_NODE_HOLDS_VALUE(n))
        return NAN;
    GType t = json_node_get_value_type(n);
    if (t == G_TYPE_DOUBLE)
        return json_node_get_double(n);
    if (t == G_TYPE_INT64)
        return (double)json_node_get_int(n);
    return NAN;
}

gint64 dcmd_int(JsonObject *o, const char *k, gint64 def)
{
    double v = dcmd_num(o, k);
    return isfinite(v) ? (gint64)llround(v) : def;
}

JsonObject *dcmd_obj(JsonObject *o, const char *k)
{
    JsonNode *n = member(o, k);
    return n && JSON_NODE_HOLDS_OBJECT(n) ? json_node_get_object(n) : NULL;
}

JsonArray *dcmd_arr(JsonObject *o, const char *k)
{
    JsonNode *n = member(o, k);
    return n && JSON_NODE_HOLDS_ARRAY(n) ? json_node_get_array(n) : NULL;
}

void dcmd_set_name_or_slot(JsonObject *o, const char *k, const char *v)
{
    size_t n = strlen(v);
    if (n > 0 && n < 10 && strspn(v, "0123456789") == n)
        json_object_set_int_member(o, k, atoi(v));
    else
        json_object_set_string_member(o, k, v);
}

const char *dcmd_fmt(char *buf, size_t n, const char *fmt, double v)
{
    if (isfinite(v))
        snprintf(buf, n, fmt, v);
    else
        snprintf(buf, n, "-");
    return buf;
}

double dcmd_iso_s(const char *iso)
{
    if (!iso)
        return NAN;
    GTimeZone *utc = g_time_zone_new_utc();
    GDateTime *dt = g_date_time_new_from_iso8601(iso, utc);
    g_time_zone_unref(utc);
    if (!dt)
        return NAN;
    double s = (double)g_date_time_to_unix(dt) + g_date_time_get_microsecond(dt) * 1e-6;
    g_date_time_unref(dt);
    return s;
}

char *dcmd_since_iso(const char *text, GError **error)
{
    GDateTime *dt = NULL;
    size_t n = strlen(text);
    size_t digits = strspn(text, "0123456789");
    if (n >= 2 && digits == n - 1 && strchr("smhdw", text[n - 1])) {
        /* relative: "30d" = the last 30 days */
        static const double unit_s[] = {1, 60, 3600, 86400, 604800};
        double s = atof(text) * unit_s[strchr("smhdw", text[n - 1]) - "smhdw"];
        GDateTime *now = g_date_time_new_now_utc();
        dt = g_date_time_add_seconds(now, -s);
        g_date_time_unref(now);
    } else if (n > 0 && digits == n) {
        dt = g_date_time_new_from_unix_utc(g_ascii_strtoll(text, NULL, 10));
    } else if (n == 10 && text[4] == '-' && text[7] == '-') {
        dt = g_date_time_new_utc(atoi(text), atoi(text + 5), atoi(text + 8), 0, 0, 0);
    } else {
        GTimeZone *utc = g_time_zone_new_utc();
        dt = g_date_time_new_from_iso8601(text, utc);
        g_time_zone_unref(utc);
    }
    if (!dt) {
        g_set_error(error, G_OPTION_ERROR, G_OPTION_ERROR_BAD_VALUE,
                    "--since '%s': expected a date (2024-05-01), an ISO-8601 "
                    "time, unix seconds or an age (30d, 12h, 90m, 2w)", text);
        return NULL;
    }
    GDateTime *u = g_date_time_to_utc(dt);
    char *s = g_date_time_format(u, "%Y-%m-%dT%H:%M:%SZ");
    g_date_time_unref(u);
    g_date_time_unref(dt);
    return s;
}

int cmd_recon_is_run_id(const char *arg)
{
    size_t n = arg ? strlen(arg) : 0;
    if (n < 4 || n > 36 || g_file_test(arg, G_FILE_TEST_EXISTS))
        return 0;
    int hex = 0;
    for (size_t i = 0; i < n; i++) {
        if (isxdigit((unsigned char)arg[i]))
            hex++;
        else if (arg[i] != '-')
            return 0;
    }
    return hex >= 4;
}

/* ---- specklab daemon status ---- */

static const char *yesno(JsonObject *o, const char *k)
{
    JsonNode *n = o ? json_object_get_member(o, k) : NULL;
    if (n && JSON_NODE_HOLDS_VALUE(n) && json_node_get_value_type(n) == G_TYPE_BOOLEAN)
        return json_node_get_boolean(n) ? "connected" : "NOT CONNECTED";
    return "?";
}

static const char *or_dash(const char *s)
{
    return s && *s ? s : "-";
}

static void print_status(const char *path, JsonObject *st, JsonObject *dev)
{
    char up[32];
    JsonArray *q = dcmd_arr(st, "queue");
    printf("specklabd %s at %s: %s, up %s\n", or_dash(dcmd_str(st, "version")), path,
           or_dash(dcmd_str(st, "state")),
           progress_fmt_time(up, sizeof up, dcmd_num(st, "uptime_s")));
    printf("  current run: %s, queued: %u\n", or_dash(dcmd_str(st, "current_run")),
           q ? json_array_get_length(q) : 0);
    printf("  catalogue:   %s\n  data:        %s\n", or_dash(dcmd_str(st, "catalog")),
           or_dash(dcmd_str(st, "data_dir")));
    if (dcmd_str(st, "web"))
        printf("  live page:   %s\n", dcmd_str(st, "web"));
    if (!dev)
        return;
    JsonObject *cam = dcmd_obj(dev, "camera"), *stg = dcmd_obj(dev, "stage");
    const char *model = dcmd_str(cam, "model"), *serial = dcmd_str(cam, "serial");
    printf("  camera:      %s %s%s%s%s%s%s (%s)\n", or_dash(dcmd_str(cam, "backend")),
           or_dash(dcmd_str(cam, "address")), model || serial ? "," : "",
           model ? " " : "", model ? model : "", serial ? " " : "", serial ? serial : "",
           yesno(cam, "connected"));
    if (dcmd_str(cam, "error"))
        printf("    error: %s\n", dcmd_str(cam, "error"));
    printf("  stage:       %s (%s)\n", or_dash(dcmd_str(stg, "address")),
           yesno(stg, "connected"));
    if (dcmd_str(stg, "error"))
        printf("    error: %s\n", dcmd_str(stg, "error"));
    if (dcmd_str(stg, "fix"))
        printf("    fix: %s\n", dcmd_str(stg, "fix"));
    if (dcmd_int(stg, "rejected_replies", 0) > 0)
        printf("    line: %lld damaged replies rejected (CRC, cut short) and asked again\n",
               (long long)dcmd_int(stg, "rejected_replies", 0));
    JsonArray *wheels = dcmd_arr(stg, "wheels");
    for (guint i = 0; wheels && i < json_array_get_length(wheels); i++) {
        JsonObject *w = json_array_get_object_element(wheels, i);
        gint64 pos = dcmd_int(w, "position", -1);
        char p[32];
        snprintf(p, sizeof p, pos >= 0 ? "slot %lld" : "no slot", (long long)pos);
        printf("    wheel %-7s %s of %lld, %s%s%s\n", or_dash(dcmd_str(w, "name")), p,
               (long long)dcmd_int(w, "slots", 0), or_dash(dcmd_str(w, "status")),
               dcmd_str(w, "fault") ? ", fault: " : "",
               dcmd_str(w, "fault") ? dcmd_str(w, "fault") : "");
    }
}

int cmd_daemon(int argc, char **argv)
{
    dcmd_opts o = {0};
    GOptionContext *ctx = g_option_context_new("status - the daemon's state and devices");
    dcmd_opts_add(&o, ctx);
    int status = 2;
    client *c = NULL;
    JsonObject *st = NULL, *dev = NULL;
    if (!cli_parse(ctx, &argc, &argv))
        goto free_ctx;
    if (argc != 2 || strcmp(argv[1], "status") != 0) {
        fprintf(stderr, "specklab daemon: usage: specklab daemon status [--json] [--socket PATH]\n");
        goto free_ctx;
    }
    status = 1;
    if (!(c = dcmd_connect(&o, "specklab daemon")))
        goto free_ctx;
    if (dcmd_call(c, "specklab daemon", "status", NULL, DCMD_QUERY_MS, &st))
        goto free_client;
    /* The daemon answers status while a device hangs; a devices failure is
     * reported but the daemon is up, which is what this command checks. */
    if (client_call(c, "devices", NULL, DCMD_QUERY_MS, &dev) != SL_OK)
        fprintf(stderr, "specklab daemon: devices: %s\n", client_errmsg(c));
    if (o.json) {
        JsonObject *all = json_object_new();
        json_object_set_object_member(all, "status", json_object_ref(st));
        if (dev)
            json_object_set_object_member(all, "devices", json_object_ref(dev));
        else
            json_object_set_null_member(all, "devices");
        dcmd_print_object(all);
        json_object_unref(all);
    } else {
        print_status(client_path(c), st, dev);
    }
    status = 0;
    if (st)
        json_object_unref(st);
    if (dev)
        json_object_unref(dev);
free_client:
    client_free(c);
free_ctx:
    g_option_context_free(ctx);
    dcmd_opts_clear(&o);
    return status;
}

/* ---- specklab masks list ---- */

int cmd_masks(int argc, char **argv)
{
    dcmd_opts o = {0};
    GOptionContext *ctx = g_option_context_new("list - the masks the daemon knows");
    dcmd_opts_add(&o, ctx);
    int status = 2;
    client *c = NULL;
    JsonObject *res = NULL;
    if (!cli_parse(ctx, &argc, &argv))
        goto free_ctx;
    if (argc > 2 || (argc == 2 && strcmp(argv[1], "list") != 0)) {
        fprintf(stderr, "specklab masks: usage: specklab masks list [--json]\n");
        goto free_ctx;
    }
    status = 1;
    if (!(c = dcmd_connect(&o, "specklab masks")) ||
        dcmd_call(c, "specklab masks", "masks", NULL, DCMD_QUERY_MS, &res))
        goto free_client;
    if (o.json) {
        dcmd_print_object(res);
    } else {
        JsonArray *a = dcmd_arr(res, "masks");
        printf("%-12s %4s  %-10s %12s %6s\n", "MASK", "SLOT", "KIND", "DIAMETER(m)", "HOLES");
        for (guint i = 0; a && i < json_array_get_length(a); i++) {
            JsonObject *m = json_array_get_object_element(a, i);
            char d[32], h[32];
            printf("%-12s %4lld  %-10s %12s %6s\n", or_dash(dcmd_str(m, "name")),
                   (long long)dcmd_int(m, "slot", -1), or_dash(dcmd_str(m, "kind")),
                   dcmd_fmt(d, sizeof d, "%.3f", dcmd_num(m, "diameter_m")),
                   dcmd_fmt(h, sizeof h, "%.0f", dcmd_num(m, "nholes")));
        }
    }
    status = 0;
    json_object_unref(res);
free_client:
    client_free(c);
free_ctx:
    g_option_context_free(ctx);
    dcmd_opts_clear(&o);
    return status;
}
