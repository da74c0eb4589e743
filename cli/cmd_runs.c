/* cmd_runs.c - `specklab runs list|show` and `specklab screens list|show`:
 * catalogue queries answered by specklabd. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "cmd_daemon.h"

static const char *or_dash(const char *s)
{
    return s && *s ? s : "-";
}

/* "2024-05-01T12:34:56Z" -> "2024-05-01 12:34:56" (UTC, as stored). */
static const char *short_time(char *buf, size_t n, const char *iso)
{
    if (!iso) {
        snprintf(buf, n, "-");
        return buf;
    }
    snprintf(buf, n, "%.19s", iso);
    char *t = strchr(buf, 'T');
    if (t)
        *t = ' ';
    return buf;
}

/* "2024-05-01T12:34:56Z" -> "12:34:56"; "-" when absent. */
static const char *time_of_day(char *buf, size_t n, const char *iso)
{
    const char *t = iso ? strchr(iso, 'T') : NULL;
    snprintf(buf, n, "%.8s", t ? t + 1 : "-");
    return buf;
}

static void print_run_row(JsonObject *r)
{
    char fr[48], r0[32], ct[32];
    snprintf(fr, sizeof fr, "%lld/%lld", (long long)dcmd_int(r, "frames_acquired", 0),
             (long long)dcmd_int(r, "frames_requested", 0));
    printf("%-8.8s  %-14s %-10s %-10s %-8s %9s %7s  %-19s  %s\n", or_dash(dcmd_str(r, "uuid")),
           or_dash(dcmd_str(r, "state")), or_dash(dcmd_str(r, "kind")),
           or_dash(dcmd_str(r, "screen")),
           or_dash(dcmd_str(r, "mask")), fr,
           dcmd_fmt(r0, sizeof r0, "%.3f", dcmd_num(r, "r0_m")),
           short_time(ct, sizeof ct, dcmd_str(r, "created")),
           dcmd_str(r, "exit_reason") ? dcmd_str(r, "exit_reason") : "");
}

static void print_run_header(void)
{
    printf("%-8s  %-14s %-10s %-10s %-8s %9s %7s  %-19s  %s\n", "RUN", "STATE", "KIND",
           "SCREEN", "MASK", "FRAMES", "R0(m)", "CREATED (UTC)", "REASON");
}

static void print_recon_rows(JsonArray *recs)
{
    if (!recs || json_array_get_length(recs) == 0) {
        printf("reconstructions: none\n");
        return;
    }
    printf("reconstructions:\n  %-4s %-12s %9s %9s %8s %8s %8s %7s %8s  %s\n", "ID",
           "METHOD", "SEP(\")", "SEP(px)", "PA(deg)", "dm(mag)", "CP(deg)", "TIME(s)",
           "STARTED", "OUTPUT");
    for (guint i = 0; i < json_array_get_length(recs); i++) {
        JsonObject *x = json_array_get_object_element(recs, i);
        char a[32], b[32], p[32], d[32], c[32], t[32], st[32];
        printf("  %-4lld %-12s %9s %9s %8s %8s %8s %7s %8.8s  %s\n",
               (long long)dcmd_int(x, "id", -1), or_dash(dcmd_str(x, "method")),
               dcmd_fmt(a, sizeof a, "%.4f", dcmd_num(x, "sep_arcsec")),
               dcmd_fmt(b, sizeof b, "%.3f", dcmd_num(x, "sep_px")),
               dcmd_fmt(p, sizeof p, "%.2f", dcmd_num(x, "pa_deg")),
               dcmd_fmt(d, sizeof d, "%.3f", dcmd_num(x, "dm_mag")),
               dcmd_fmt(c, sizeof c, "%.2f", dcmd_num(dcmd_obj(x, "quality"), "closure_rms_deg")),
               dcmd_fmt(t, sizeof t, "%.2f", dcmd_num(x, "elapsed_s")),
               time_of_day(st, sizeof st, dcmd_str(x, "started")),
               or_dash(dcmd_str(x, "png") ? dcmd_str(x, "png") : dcmd_str(x, "fits")));
        /* what ran: method parameters, skips, TSM phases (the worker's) */
        JsonObject *params = dcmd_obj(x, "params");
        if (params) {
            JsonNode *n = json_node_new(JSON_NODE_OBJECT);
            json_node_set_object(n, params);
            gchar *txt = json_to_string(n, FALSE);
            printf("       params %s\n", txt);
            g_free(txt);
            json_node_free(n);
        }
    }
}

/* Every member of a run object, one per line, in the protocol's order. */
static void print_run_detail(JsonObject *r)
{
    static const char *keys[] = {"uuid", "state", "kind", "exit_reason", "created", "started",
                                 "ended", "operator", "object", "screen", "mask",
                                 "camera_serial", "frames_requested", "frames_acquired",
                                 "frames_failed", "packets_missing", "file", "sha256",
                                 "r0_m", "seeing_arcsec"};
    for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++) {
        JsonNode *n = json_object_get_member(r, keys[i]);
        char v[64];
        const char *text = "-";
        if (n && JSON_NODE_HOLDS_VALUE(n)) {
            GType t = json_node_get_value_type(n);
            if (t == G_TYPE_STRING)
                text = json_node_get_string(n);
            else if (t == G_TYPE_INT64)
                snprintf(v, sizeof v, "%lld", (long long)json_node_get_int(n)), text = v;
            else if (t == G_TYPE_DOUBLE)
                snprintf(v, sizeof v, "%.4g", json_node_get_double(n)), text = v;
        }
        printf("%-17s %s\n", keys[i], text);
    }
    JsonObject *cs = dcmd_obj(r, "camera_settings");
    if (cs) {
        JsonNode *n = json_node_init_object(json_node_alloc(), cs);
        gchar *s = json_to_string(n, FALSE);
        printf("%-17s %s\n", "camera_settings", s);
        g_free(s);
        json_node_unref(n);
    }
}

/* The filters of `runs list` into args; 0 after a usage error. */
static int list_args(JsonObject *args, const char *state, const char *screen,
                     const char *kind, const char *since, int limit)
{
    if (state)
        json_object_set_string_member(args, "state", state);
    if (kind)
        json_object_set_string_member(args, "kind", kind);
    if (screen)
        json_object_set_string_member(args, "screen", screen);
    if (limit < 0 || limit > 100000) {
        fprintf(stderr, "specklab runs: --limit %d: expected 1..100000\n", limit);
        return 0;
    }
    if (limit > 0)
        json_object_set_int_member(args, "limit", limit);
    if (since) {
        GError *ge = NULL;
        char *iso = dcmd_since_iso(since, &ge);
        if (!iso) {
            fprintf(stderr, "specklab runs: %s\n", ge->message);
            g_error_free(ge);
            return 0;
        }
        json_object_set_string_member(args, "since", iso);
        g_free(iso);
    }
    return 1;
}

int cmd_runs(int argc, char **argv)
{
    dcmd_opts o = {0};
    char *state = NULL, *screen = NULL, *since = NULL, *kind = NULL;
    int limit = 0;
    GOptionEntry entries[] = {
        {"state", 0, 0, G_OPTION_ARG_STRING, &state, "list: only runs in this state (done, failed...)", "S"},
        {"screen", 0, 0, G_OPTION_ARG_STRING, &screen, "list: only runs through this screen", "NAME"},
        {"kind", 0, 0, G_OPTION_ARG_STRING, &kind, "list: only runs of this kind (science, dark, flat, calibrator)", "KIND"},
        {"since", 0, 0, G_OPTION_ARG_STRING, &since, "list: created since DATE, ISO time, unix s or age (30d)", "DATE"},
        {"limit", 0, 0, G_OPTION_ARG_INT, &limit, "list: at most N runs, newest first (default 50)", "N"},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("list|show [RUN-ID] - catalogued runs");
    g_option_context_add_main_entries(ctx, entries, NULL);
    dcmd_opts_add(&o, ctx);
    g_option_context_set_description(ctx, "RUN-ID: a uuid or a unique prefix of one (as listed).");
    int status = 2;
    client *c = NULL;
    JsonObject *args = json_object_new(), *res = NULL;
    if (!cli_parse(ctx, &argc, &argv))
        goto free_args;
    const char *sub = argc >= 2 ? argv[1] : "list";
    int show = !strcmp(sub, "show");
    if ((show && argc != 3) || (!show && (strcmp(sub, "list") || argc > 2))) {
        fprintf(stderr, "specklab runs: usage: specklab runs list [--state S] [--screen NAME] "
                        "[--kind KIND] [--since DATE] [--limit N] | specklab runs show RUN-ID\n");
        goto free_args;
    }
    if (show)
        json_object_set_string_member(args, "run", argv[2]);
    else if (!list_args(args, state, screen, kind, since, limit))
        goto free_args;
    status = 1;
    if (!(c = dcmd_connect(&o, "specklab runs")) ||
        dcmd_call(c, "specklab runs", show ? "run" : "runs", args, DCMD_QUERY_MS, &res))
        goto free_client;
    if (o.json) {
        dcmd_print_object(res);
    } else if (show) {
        JsonObject *r = dcmd_obj(res, "run");
        if (r)
            print_run_detail(r);
        print_recon_rows(dcmd_arr(res, "reconstructions"));
    } else {
        JsonArray *a = dcmd_arr(res, "runs");
        print_run_header();
        for (guint i = 0; a && i < json_array_get_length(a); i++)
            print_run_row(json_array_get_object_element(a, i));
        if (!a || json_array_get_length(a) == 0)
            printf("(no runs)\n");
    }
    status = 0;
    json_object_unref(res);
free_client:
    client_free(c);
free_args:
    json_object_unref(args);
    g_option_context_free(ctx);
    dcmd_opts_clear(&o);
    g_free(state); g_free(screen); g_free(since); g_free(kind);
    return status;
}

/* ---- specklab screens list|show ---- */

static void print_screen_row(JsonObject *s)
{
    JsonObject *st = dcmd_obj(s, "stats");
    char l[32], mean[32], med[32], mn[32], mx[32], sd[32];
    printf("%-12s %4lld %9s %5lld %8s %8s %8s %8s %8s  %s\n", or_dash(dcmd_str(s, "name")),
           (long long)dcmd_int(s, "slot", -1),
           dcmd_fmt(l, sizeof l, "%.4f", dcmd_num(s, "r0_m")),
           (long long)dcmd_int(st, "n", 0),
           dcmd_fmt(mean, sizeof mean, "%.4f", dcmd_num(st, "mean_r0_m")),
           dcmd_fmt(med, sizeof med, "%.4f", dcmd_num(st, "median_r0_m")),
           dcmd_fmt(mn, sizeof mn, "%.4f", dcmd_num(st, "min_r0_m")),
           dcmd_fmt(mx, sizeof mx, "%.4f", dcmd_num(st, "max_r0_m")),
           dcmd_fmt(sd, sizeof sd, "%.4f", dcmd_num(st, "std_r0_m")),
           dcmd_str(s, "description") ? dcmd_str(s, "description") : "");
}

static void print_screen_header(void)
{
    printf("%-12s %4s %9s %5s %8s %8s %8s %8s %8s  %s\n", "SCREEN", "SLOT", "R0 LAST",
           "N", "MEAN", "MEDIAN", "MIN", "MAX", "STD", "DESCRIPTION");
}

/* The screen called name, or in slot name when name is a number. */
static JsonObject *find_screen(JsonArray *a, const char *name)
{
    for (guint i = 0; a && i < json_array_get_length(a); i++) {
        JsonObject *s = json_array_get_object_element(a, i);
        const char *n = dcmd_str(s, "name");
        if (n && !strcmp(n, name))
            return s;
    }
    size_t len = strlen(name);
    if (len == 0 || strspn(name, "0123456789") != len)
        return NULL;
    for (guint i = 0; a && i < json_array_get_length(a); i++) {
        JsonObject *s = json_array_get_object_element(a, i);
        if (dcmd_int(s, "slot", -1) == g_ascii_strtoll(name, NULL, 10))
            return s;
    }
    return NULL;
}

/* screens show: the screen, its statistics and its r0 history (the
 * screen's runs, newest first). */
static int screens_show(client *c, const dcmd_opts *o, JsonObject *res,
                        const char *name, const char *since_iso, int limit)
{
    JsonObject *s = find_screen(dcmd_arr(res, "screens"), name);
    if (!s) {
        fprintf(stderr, "specklab screens: no screen '%s' (specklab screens list)\n", name);
        return 1;
    }
    JsonObject *args = json_object_new(), *runs = NULL;
    json_object_set_string_member(args, "screen", or_dash(dcmd_str(s, "name")));
    json_object_set_int_member(args, "limit", limit > 0 ? limit : 20);
    if (since_iso)
        json_object_set_string_member(args, "since", since_iso);
    int status = dcmd_call(c, "specklab screens", "runs", args, DCMD_QUERY_MS, &runs);
    json_object_unref(args);
    if (status)
        return status;
    JsonArray *ra = dcmd_arr(runs, "runs");
    if (o->json) {
        JsonObject *all = json_object_new();
        json_object_set_object_member(all, "screen", json_object_ref(s));
        json_object_set_array_member(all, "runs", ra ? json_array_ref(ra) : json_array_new());
        dcmd_print_object(all);
        json_object_unref(all);
    } else {
        print_screen_header();
        print_screen_row(s);
        printf("\nr0 history (newest first):\n");
        print_run_header();
        for (guint i = 0; ra && i < json_array_get_length(ra); i++)
            print_run_row(json_array_get_object_element(ra, i));
        if (!ra || json_array_get_length(ra) == 0)
            printf("(no runs)\n");
    }
    json_object_unref(runs);
    return 0;
}

int cmd_screens(int argc, char **argv)
{
    dcmd_opts o = {0};
    char *since = NULL, *iso = NULL;
    int limit = 0;
    GOptionEntry entries[] = {
        {"since", 0, 0, G_OPTION_ARG_STRING, &since, "statistics over runs since DATE, ISO time, unix s or age (30d)", "DATE"},
        {"limit", 0, 0, G_OPTION_ARG_INT, &limit, "show: at most N runs of history (default 20)", "N"},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("list|show [NAME] - phase screens and their measured r0");
    g_option_context_add_main_entries(ctx, entries, NULL);
    dcmd_opts_add(&o, ctx);
    int status = 2;
    client *c = NULL;
    JsonObject *args = json_object_new(), *res = NULL;
    if (!cli_parse(ctx, &argc, &argv))
        goto free_args;
    const char *sub = argc >= 2 ? argv[1] : "list";
    int show = !strcmp(sub, "show");
    if ((show && argc != 3) || (!show && (strcmp(sub, "list") || argc > 2))) {
        fprintf(stderr, "specklab screens: usage: specklab screens list [--since DATE] | "
                        "specklab screens show NAME|SLOT\n");
        goto free_args;
    }
    if (since) {
        GError *ge = NULL;
        if (!(iso = dcmd_since_iso(since, &ge))) {
            fprintf(stderr, "specklab screens: %s\n", ge->message);
            g_error_free(ge);
            goto free_args;
        }
        json_object_set_string_member(args, "since", iso);
    }
    status = 1;
    if (!(c = dcmd_connect(&o, "specklab screens")) ||
        dcmd_call(c, "specklab screens", "screens", args, DCMD_QUERY_MS, &res))
        goto free_client;
    if (show) {
        status = screens_show(c, &o, res, argv[2], iso, limit);
    } else if (o.json) {
        dcmd_print_object(res);
        status = 0;
    } else {
        JsonArray *a = dcmd_arr(res, "screens");
        print_screen_header();
        for (guint i = 0; a && i < json_array_get_length(a); i++)
            print_screen_row(json_array_get_object_element(a, i));
        status = 0;
    }
    json_object_unref(res);
free_client:
    client_free(c);
free_args:
    json_object_unref(args);
    g_option_context_free(ctx);
    dcmd_opts_clear(&o);
    g_free(since); g_free(iso);
    return status;
}
