/* cmd_devices.c - `specklab devices`: every camera and stage found, with
 * a diagnosis of what users trip over (USB link speed, permissions, usbfs
 * memory; a stage that does not answer or reports a fault). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"
#include "cli.h"
#include "stage.h"
#include "usb.h"

typedef struct devices_out {
    int json;
    JsonBuilder *b;
    int problems;     /* warnings and errors seen */
} devices_out;

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

static void show_stage(devices_out *d, const char *addr)
{
    stage_config cfg;
    stage_config_defaults(&cfg);
    char host[256];
    stage *s = NULL;
    stage_ident id;
    sl_err e = {0};
    const char *err = NULL;
    if (parse_stage(addr, &cfg, host, sizeof host) < 0)
        err = "bad address (expected HOST:PORT)";
    else if (stage_new(&s, &cfg, &e) != SL_OK)
        err = e.msg;
    else if (stage_info(s, &id) != SL_OK)
        err = stage_errmsg(s);
    if (d->json) {
        json_builder_set_member_name(d->b, "stage");
        json_builder_begin_object(d->b);
        cli_json_str(d->b, "address", addr);
        json_builder_set_member_name(d->b, "connected");
        json_builder_add_boolean_value(d->b, err == NULL);
        if (err)
            cli_json_str(d->b, "error", err);
    } else {
        printf("stage %s: %s\n", addr, err ? err : "connected");
    }
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
    int json = 0, no_stage = 0, status = 2;
    GOptionEntry entries[] = {
        {"stage", 0, 0, G_OPTION_ARG_STRING, &stage_addr, "stage to query (default 127.0.0.1:1502)", "HOST:PORT"},
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
        show_stage(&d, stage_addr ? stage_addr : "127.0.0.1:1502");
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
    g_free(backend);
    return status;
}
