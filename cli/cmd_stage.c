/* cmd_stage.c - `specklab stage home|move|status|stop|reset`: drive the
 * bench stage (phase-screen and mask wheels) through drivers/stage. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "stage.h"

typedef struct stage_opts {
    char *addr;    /* HOST[:PORT] or /dev/... (RTU) */
    char *wheel;   /* screen|mask|0|1|all */
    char *parity;  /* RTU: N|E|O */
    int unit, baud, timeout_ms, json, no_wait;
} stage_opts;

/* --stage: "/dev/..." is a serial line (RTU), anything else HOST[:PORT]. */
static int make_config(const stage_opts *o, stage_config *cfg, char *host,
                       size_t n)
{
    stage_config_defaults(cfg);
    cfg->unit_id = o->unit;
    if (o->timeout_ms > 0)
        cfg->move_timeout_ms = o->timeout_ms;
    const char *a = o->addr ? o->addr : "127.0.0.1:1502";
    if (a[0] == '/') {
        cfg->backend = "rtu";
        cfg->device = a;
        cfg->baud = o->baud;
        cfg->parity = o->parity ? o->parity[0] : 'E';
        return 0;
    }
    const char *colon = strrchr(a, ':');
    size_t hl = colon ? (size_t)(colon - a) : strlen(a);
    if (colon) {
        char *end = NULL;
        long p = strtol(colon + 1, &end, 10);
        if (end == colon + 1 || *end || p < 1 || p > 65535) {
            fprintf(stderr, "specklab stage: --stage '%s': bad port\n", a);
            return -1;
        }
        cfg->port = (int)p;
    }
    snprintf(host, n, "%.*s", (int)hl, a);
    if (!strcmp(host, "localhost"))
        snprintf(host, n, "127.0.0.1");
    cfg->host = host;
    return 0;
}

static const char *where(const stage_wheel_status *st, char *buf, size_t n)
{
    if (st->position >= 0)
        snprintf(buf, n, "slot %d", st->position);
    else
        snprintf(buf, n, "%s", st->homed ? "between slots" : "not homed");
    return buf;
}

static void print_text(const stage *s, const stage_ident *id,
                       const stage_wheel_status *st, int nst)
{
    char pos[32];
    printf("stage %s: specklab stage, register map version %u\n",
           stage_label(s), id->version);
    for (int i = 0; i < nst; i++) {
        const stage_wheel_status *w = &st[i];
        printf("  wheel %d (%s): %s, target %d%s%s%s", w->wheel,
               stage_wheel_name(w->wheel), where(w, pos, sizeof pos),
               w->target, w->busy ? ", busy" : "",
               w->in_position ? ", in position" : "",
               w->homed ? ", homed" : "");
        if (w->faulted || w->fault)
            printf(", FAULT %d (%s)", w->fault, w->fault_text);
        printf(" [slots 0..%d, %d ms/step]\n", w->slots - 1, w->move_ms);
    }
}

static void print_json(const stage *s, const char *action,
                       const stage_ident *id, const stage_wheel_status *st,
                       int nst)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    json_builder_set_member_name(b, "stage");
    json_builder_add_string_value(b, stage_label(s));
    json_builder_set_member_name(b, "action");
    json_builder_add_string_value(b, action);
    json_builder_set_member_name(b, "magic");
    json_builder_add_int_value(b, id->magic);
    json_builder_set_member_name(b, "version");
    json_builder_add_int_value(b, id->version);
    json_builder_set_member_name(b, "wheels");
    json_builder_begin_array(b);
    for (int i = 0; i < nst; i++) {
        const stage_wheel_status *w = &st[i];
        json_builder_begin_object(b);
        json_builder_set_member_name(b, "wheel");
        json_builder_add_int_value(b, w->wheel);
        json_builder_set_member_name(b, "name");
        json_builder_add_string_value(b, stage_wheel_name(w->wheel));
        json_builder_set_member_name(b, "slots");
        json_builder_add_int_value(b, w->slots);
        json_builder_set_member_name(b, "position");
        if (w->position >= 0)
            json_builder_add_int_value(b, w->position);
        else
            json_builder_add_null_value(b);
        json_builder_set_member_name(b, "target");
        json_builder_add_int_value(b, w->target);
        json_builder_set_member_name(b, "busy");
        json_builder_add_boolean_value(b, w->busy);
        json_builder_set_member_name(b, "in_position");
        json_builder_add_boolean_value(b, w->in_position);
        json_builder_set_member_name(b, "homed");
        json_builder_add_boolean_value(b, w->homed);
        json_builder_set_member_name(b, "fault");
        json_builder_add_int_value(b, w->fault);
        json_builder_set_member_name(b, "fault_text");
        json_builder_add_string_value(b, w->fault_text);
        json_builder_set_member_name(b, "move_ms");
        json_builder_add_int_value(b, w->move_ms);
        json_builder_end_object(b);
    }
    json_builder_end_array(b);
    json_builder_end_object(b);
    cli_print_json(b);
    g_object_unref(b);
}

/* Run the action; SL_OK or the driver's status (message in the handle). */
static int act(stage *s, const char *action, int wheel, int slot,
               const stage_opts *o)
{
    int rc;
    if (!strcmp(action, "home")) {
        rc = stage_home(s, wheel);
        if (rc == SL_OK && !o->no_wait)
            rc = stage_wait(s, wheel, o->timeout_ms);
    } else if (!strcmp(action, "move")) {
        rc = o->no_wait ? stage_move(s, wheel, slot)
                        : stage_move_wait(s, wheel, slot, o->timeout_ms);
    } else if (!strcmp(action, "stop")) {
        rc = stage_stop(s, wheel);
    } else if (!strcmp(action, "reset")) {
        rc = stage_reset(s, wheel);
    } else {
        rc = SL_OK; /* status: the report below is the whole job */
    }
    return rc;
}

/* Report the wheels the action touched (all for WHEEL_ALL). */
static int report(stage *s, const char *action, int wheel, int json)
{
    stage_ident id;
    stage_wheel_status st[STAGE_NWHEELS];
    int n = 0, rc = stage_info(s, &id);
    for (int i = 0; rc == SL_OK && i < STAGE_NWHEELS; i++)
        if (wheel == STAGE_WHEEL_ALL || wheel == i)
            rc = stage_status(s, i, &st[n++]);
    if (rc != SL_OK)
        return rc;
    if (json)
        print_json(s, action, &id, st, n);
    else
        print_text(s, &id, st, n);
    return SL_OK;
}

static int parse_action(int argc, char **argv, const stage_opts *o,
                        int *wheel, int *slot)
{
    static const char *const actions[] = {"home", "move", "status", "stop",
                                          "reset"};
    int known = 0;
    if (argc < 2) {
        fprintf(stderr, "specklab stage: expected home|move|status|stop|reset "
                "(try --help)\n");
        return -1;
    }
    for (size_t i = 0; i < sizeof actions / sizeof actions[0]; i++)
        known |= !strcmp(argv[1], actions[i]);
    int is_move = !strcmp(argv[1], "move");
    if (!known || argc != 2 + is_move) {
        fprintf(stderr, "specklab stage: expected 'home|status|stop|reset' or "
                "'move SLOT --wheel screen|mask' (try --help)\n");
        return -1;
    }
    *wheel = STAGE_WHEEL_ALL;
    if (o->wheel && stage_wheel_parse(o->wheel, wheel) != SL_OK) {
        fprintf(stderr, "specklab stage: --wheel '%s': expected screen, mask, "
                "0, 1 or all\n", o->wheel);
        return -1;
    }
    if (is_move) {
        char *end = NULL;
        long v = strtol(argv[2], &end, 10);
        if (end == argv[2] || *end || v < 0 || v > 65534 ||
            *wheel == STAGE_WHEEL_ALL) {
            fprintf(stderr, "specklab stage: move needs --wheel screen|mask and "
                    "a slot number (got '%s')\n", argv[2]);
            return -1;
        }
        *slot = (int)v;
    }
    return 0;
}

int cmd_stage(int argc, char **argv)
{
    stage_opts o = {NULL, NULL, NULL, 1, 19200, 0, 0, 0};
    stage_config cfg;
    stage *s = NULL;
    sl_err e = {0};
    char host[256];
    int status = 2, wheel = STAGE_WHEEL_ALL, slot = -1;
    GOptionEntry entries[] = {
        {"stage", 0, 0, G_OPTION_ARG_STRING, &o.addr, "HOST:PORT (Modbus TCP, default 127.0.0.1:1502) or /dev/... (RTU)", "ADDR"},
        {"unit", 0, 0, G_OPTION_ARG_INT, &o.unit, "Modbus unit id (default 1)", "N"},
        {"wheel", 0, 0, G_OPTION_ARG_STRING, &o.wheel, "screen|mask|0|1|all (default all; move needs one)", "W"},
        {"timeout-ms", 0, 0, G_OPTION_ARG_INT, &o.timeout_ms, "bound on waiting for in-position (default 10000)", "N"},
        {"no-wait", 0, 0, G_OPTION_ARG_NONE, &o.no_wait, "return once home/move is accepted", NULL},
        {"baud", 0, 0, G_OPTION_ARG_INT, &o.baud, "RTU baud rate (default 19200)", "N"},
        {"parity", 0, 0, G_OPTION_ARG_STRING, &o.parity, "RTU parity N|E|O (default E)", "P"},
        {"json", 0, 0, G_OPTION_ARG_NONE, &o.json, "print JSON", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("home|move SLOT|status|stop|reset");
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_set_description(ctx,
        "home: home the wheel(s) and wait until homed.\n"
        "move SLOT --wheel W: move one wheel to SLOT (0-based) and wait for in-position.\n"
        "status: identity and wheel registers.  stop: stop on the nearest slot.\n"
        "reset: clear a fault.  Each request waits at most 500 ms for its reply,\n"
        "each call at most 2 s; a lost link is reopened with backoff.");
    if (!cli_parse(ctx, &argc, &argv) ||
        parse_action(argc, argv, &o, &wheel, &slot) < 0 ||
        make_config(&o, &cfg, host, sizeof host) < 0)
        goto free_ctx;
    status = 1;
    if (stage_new(&s, &cfg, &e) != SL_OK) {
        fprintf(stderr, "specklab stage: %s\n", e.msg);
        goto free_ctx;
    }
    if (act(s, argv[1], wheel, slot, &o) != SL_OK ||
        report(s, argv[1], wheel, o.json) != SL_OK) {
        fprintf(stderr, "specklab stage: %s\n", stage_errmsg(s));
        goto free_stage;
    }
    status = 0;
free_stage:
    stage_free(s);
free_ctx:
    g_option_context_free(ctx);
    g_free(o.addr);
    g_free(o.wheel);
    g_free(o.parity);
    return status;
}
