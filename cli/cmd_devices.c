/* cmd_devices.c - `specklab devices`: every camera and stage found, with
 * a diagnosis of what users trip over (USB link speed, permissions, usbfs
 * memory; a stage that does not answer or reports a fault; a serial
 * stage's port missing, not ours to open, or silent at its settings:
 * drivers/stage_probe.h). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "cli.h"
#include "stage.h"
#include "stage_probe.h"
#include "usb.h"

typedef struct devices_out {
    int json;
    JsonBuilder *b;
    int problems;     /* warnings and errors seen */
} devices_out;

/* A stage on a serial port (--stage /dev/...): its line settings. */
typedef struct serial_opts {
    int baud, unit;
    char *parity;
} serial_opts;

static void list_cameras(devices_out *d, const char *backend)
{
    camera_info *cams = NULL;
    int n = 0;
    sl_err e = {0};
    int rc = camera_list(backend, &cams, &n, &e);
    if (d->json) {
        json_builder_set_member_name(d->b, "cameras");
        json_builder_begin_array(d->b);
    } else {
        printf("cameras (%s):%s\n", backend, rc == SL_OK && n == 0 ? " none found" : "");
    }
    if (rc != SL_OK && !d->json)
        printf("  error: %s\n", e.msg);
    for (int i = 0; rc == SL_OK && i < n; i++) {
        const camera_info *c = &cams[i];
        if (d->json) {
            json_builder_begin_object(d->b);
            cli_json_str(d->b, "id", c->id);
            cli_json_str(d->b, "vendor", c->vendor);
            cli_json_str(d->b, "model", c->model);
            cli_json_str(d->b, "serial", c->serial);
            cli_json_str(d->b, "address", c->address);
            cli_json_str(d->b, "protocol", c->protocol);
            json_builder_end_object(d->b);
        } else {
            printf("  %s  %s %s, serial %s, %s at %s\n", c->id, c->vendor,
                   c->model, c->serial, c->protocol, c->address);
        }
    }
    if (d->json)
        json_builder_end_array(d->b);
    free(cams);
}

/* HOST[:PORT] (IPv4 or localhost) into cfg; host storage is the caller's. */
static int parse_stage(const char *addr, stage_config *cfg, char *host, size_t n)
{
    const char *colon = strrchr(addr, ':');
    size_t hl = colon ? (size_t)(colon - addr) : strlen(addr);
    if (hl == 0 || hl >= n)
        return -1;
    snprintf(host, n, "%.*s", (int)hl, addr);
    if (!strcmp(host, "localhost"))
        snprintf(host, n, "127.0.0.1");
    cfg->host = host;
    if (colon) {
        char *end;
        long p = strtol(colon + 1, &end, 10);
        if (*end || p <= 0 || p > 65535)
            return -1;
        cfg->port = (int)p;
    }
    return 0;
}

/* Why the serial stage cannot be used (stage_probe.h), as the stage's
 * error; its fix on the next line or in "fix".  err: the driver's words. */
static const char *diagnose_serial(devices_out *d, const stage_config *cfg,
                                   stage_probe_result *pr, const char *err)
{
    if (stage_probe_serial(cfg, 1, pr) != SL_OK || pr->verdict == STAGE_PROBE_OK)
        return err;
    if (d->json) {
        cli_json_str(d->b, "diagnosis", stage_probe_verdict_name(pr->verdict));
        cli_json_str(d->b, "fix", pr->fix);
    }
    return pr->what;
}

/* addr (a device path: Modbus RTU with so's settings) into cfg; NULL, or
 * what is wrong with addr. */
static const char *stage_cfg(const char *addr, const serial_opts *so, stage_config *cfg,
                             char *host, size_t n)
{
    stage_config_defaults(cfg);
    if (addr[0] != '/')
        return parse_stage(addr, cfg, host, n) < 0
                   ? "bad address (expected HOST:PORT or a serial device /dev/...)"
                   : NULL;
    cfg->backend = "rtu", cfg->device = addr;
    cfg->baud = so->baud > 0 ? so->baud : 19200;
    cfg->parity = so->parity ? g_ascii_toupper(so->parity[0]) : 'E';
    cfg->unit_id = so->unit > 0 ? so->unit : 1;
    return NULL;
}

static void show_stage(devices_out *d, const char *addr, const serial_opts *so)
{
    stage_config cfg;
    char host[256];
    stage *s = NULL;
    stage_ident id;
    stage_probe_result pr = {0};
    sl_err e = {0};
    const char *err = stage_cfg(addr, so, &cfg, host, sizeof host);
    if (!err && stage_new(&s, &cfg, &e) != SL_OK)
        err = e.msg;
    else if (!err && stage_info(s, &id) != SL_OK)
        err = stage_errmsg(s);
    if (d->json) {
        json_builder_set_member_name(d->b, "stage");
        json_builder_begin_object(d->b);
        cli_json_str(d->b, "address", addr);
        json_builder_set_member_name(d->b, "connected");
        json_builder_add_boolean_value(d->b, err == NULL);
    }
    if (err && s && !strcmp(cfg.backend, "rtu"))
        err = diagnose_serial(d, &cfg, &pr, err);
    if (d->json && err)
        cli_json_str(d->b, "error", err);
    else if (!d->json && err && g_str_has_prefix(err, "stage "))
        printf("%s\n", err);   /* the driver's words name the stage */
    else if (!d->json)
        printf("stage %s: %s\n", addr, err ? err : "connected");
    if (!d->json && pr.fix[0])
        printf("  fix: %s\n", pr.fix);
    if (err)
        d->problems++;
    if (!err && d->json) {
        json_builder_set_member_name(d->b, "wheels");
        json_builder_begin_array(d->b);
    }
    for (int w = 0; !err && w < (int)id.nwheels && w < STAGE_NWHEELS; w++) {
        stage_wheel_status st;
        if (stage_status(s, w, &st) != SL_OK)
            continue;
        d->problems += st.faulted;
        if (d->json) {
            json_builder_begin_object(d->b);
            cli_json_str(d->b, "name", stage_wheel_name(w));
            cli_json_int(d->b, "slots", st.slots);
            cli_json_int(d->b, "position", st.position);
            json_builder_set_member_name(d->b, "homed");
            json_builder_add_boolean_value(d->b, st.homed);
            cli_json_str(d->b, "fault", st.fault_text);
            json_builder_end_object(d->b);
        } else {
            printf("  %-6s wheel: %d slots, ", stage_wheel_name(w), st.slots);
            if (!st.homed)
                printf("not homed (run: specklab stage home)");
            else if (st.position < 0)
                printf("between slots");
            else
                printf("at slot %d", st.position);
            if (st.faulted)
                printf(", FAULT: %s (run: specklab stage reset)", st.fault_text);
            printf("\n");
        }
    }
    if (!err && d->json)
        json_builder_end_array(d->b);
    if (s && d->json)
        cli_json_int(d->b, "rejected_replies", stage_rejected_replies(s));
    else if (s && stage_rejected_replies(s) > 0)
        printf("  line: %u damaged replies rejected (CRC, cut short) and asked again\n",
               stage_rejected_replies(s));
    if (d->json)
        json_builder_end_object(d->b);
    stage_free(s);
}

static void usb_finding_cb(const usb_dev_info *dev, const usb_finding *f, void *ud)
{
    devices_out *d = ud;
    char label[256] = "system";
    if (dev)
        usb_dev_label(dev, label, sizeof label);
    if (f->level == USB_LEVEL_WARN || f->level == USB_LEVEL_ERROR)
        d->problems++;
    if (d->json) {
        json_builder_begin_object(d->b);
        cli_json_str(d->b, "device", label);
        cli_json_str(d->b, "level", usb_level_name(f->level));
        cli_json_str(d->b, "check", usb_check_name(f->check));
        cli_json_str(d->b, "text", f->text);
        cli_json_str(d->b, "fix", f->fix);
        json_builder_end_object(d->b);
    } else {
        printf("  [%s] %s: %s\n", usb_level_name(f->level), label, f->text);
        if (f->fix[0])
            printf("      fix: %s\n", f->fix);
    }
}

static void diagnose_usb(devices_out *d)
{
    usb *u = NULL;
    sl_err e = {0};
    if (d->json) {
        json_builder_set_member_name(d->b, "usb");
        json_builder_begin_array(d->b);
    } else {
        printf("usb:\n");
    }
    if (usb_new(&u, &e) != SL_OK) {
        if (!d->json)
            printf("  unavailable: %s\n", e.msg);
    } else {
        usb_diagnose(u, 0, usb_finding_cb, d);
    }
    if (d->json)
        json_builder_end_array(d->b);
    usb_free(u);
}

int cmd_devices(int argc, char **argv)
{
    char *stage_addr = NULL, *backend = NULL;
    serial_opts so = {0};
    int json = 0, no_stage = 0, status = 2;
    GOptionEntry entries[] = {
        {"stage", 0, 0, G_OPTION_ARG_STRING, &stage_addr, "stage to query (default 127.0.0.1:1502; /dev/...: Modbus RTU)", "HOST:PORT|DEVICE"},
        {"baud", 0, 0, G_OPTION_ARG_INT, &so.baud, "RTU baud rate (default 19200)", "N"},
        {"parity", 0, 0, G_OPTION_ARG_STRING, &so.parity, "RTU parity N|E|O (default E)", "P"},
        {"unit", 0, 0, G_OPTION_ARG_INT, &so.unit, "RTU unit id (default 1)", "N"},
        {"no-stage", 0, 0, G_OPTION_ARG_NONE, &no_stage, "do not query a stage", NULL},
        {"camera-backend", 0, 0, G_OPTION_ARG_STRING, &backend, "camera backend (default aravis)", "NAME"},
        {"json", 0, 0, G_OPTION_ARG_NONE, &json, "print one JSON object", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("- cameras and stages found, with diagnosis");
    g_option_context_add_main_entries(ctx, entries, NULL);
    if (!cli_parse(ctx, &argc, &argv))
        goto free_ctx;
    devices_out d = {.json = json};
    if (json) {
        d.b = json_builder_new();
        json_builder_begin_object(d.b);
    }
    list_cameras(&d, backend ? backend : "aravis");
    if (!no_stage)
        show_stage(&d, stage_addr ? stage_addr : "127.0.0.1:1502", &so);
    diagnose_usb(&d);
    if (json) {
        cli_json_int(d.b, "problems", d.problems);
        json_builder_end_object(d.b);
        cli_print_json(d.b);
        g_object_unref(d.b);
    } else {
        printf("%d problem%s found\n", d.problems, d.problems == 1 ? "" : "s");
    }
    status = 0;
free_ctx:
    g_option_context_free(ctx);
    g_free(stage_addr);
    g_free(so.parity);
    g_free(backend);
    return status;
}
