/* webstate.c - the web page's JSON (see web.h for what each holds): the
 * status from the runner's, worker's and view's own, and the history (r0
 * per screen, the last reconstruction) from the catalogue through the
 * web's read-only handle.  Both are cached (status 50 ms, history 2 s),
 * so many viewers cost one build.  Main thread only.
 */
#define _GNU_SOURCE
#include "webint.h"

#include <stdio.h>
#include <json-glib/json-glib.h>
#include <math.h>
#include <string.h>

#include "proto.h"
#include "base/version.h"

#define STATUS_CACHE_US 50000
#define RATE_WINDOW_US 5000000
#define RATE_MIN_SPAN_US 500000

static char *take_json(JsonBuilder *b)
{
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    return proto_take_string(n);
}

/* ---- status -------------------------------------------------------------------- */

/* A new current run: its screen, mask and object from the catalogue. */
static void run_changed(web *w, const char *uuid)
{
    catalog_run r;
    snprintf(w->run_uuid, sizeof w->run_uuid, "%s", uuid);
    g_clear_pointer(&w->run_screen, g_free);
    g_clear_pointer(&w->run_mask, g_free);
    g_clear_pointer(&w->run_object, g_free);
    w->nsamples = 0;
    if (*uuid && w->cat && catalog_run_get(w->cat, uuid, &r) == SL_OK) {
        w->run_screen = g_strdup(r.screen_name);
        w->run_mask = g_strdup(r.mask_name);
        w->run_object = g_strdup(r.object);
        catalog_run_clear(&r);
    }
}

/* Frames per second over the last few seconds of samples; NaN until the
 * samples span RATE_MIN_SPAN_US. */
static double rate_hz(web *w, int acquired, gint64 now)
{
    web_sample *s = w->samples;
    if (w->nsamples == 0 || now - s[w->nsamples - 1].t_us >= 200000) {
        if (w->nsamples == WEB_RATE_SAMPLES)
            memmove(s, s + 1, (WEB_RATE_SAMPLES - 1) * sizeof *s), w->nsamples--;
        s[w->nsamples++] = (web_sample){now, acquired};
    }
    int i = 0;
    while (i < w->nsamples - 1 && now - s[i].t_us > RATE_WINDOW_US)
        i++;
    const web_sample *a = &s[i], *b = &s[w->nsamples - 1];
    if (b->t_us - a->t_us < RATE_MIN_SPAN_US)
        return NAN;
    return (b->n - a->n) / ((b->t_us - a->t_us) * 1e-6);
}

static void add_run(JsonBuilder *b, web *w, const runner_status *rs, gint64 now)
{
    json_builder_set_member_name(b, "run");
    if (!rs->current[0]) {
        if (w->run_uuid[0])
            run_changed(w, "");
        json_builder_add_null_value(b);
        return;
    }
    if (strcmp(w->run_uuid, rs->current))
        run_changed(w, rs->current);
    int acquiring = rs->state == CATALOG_ACQUIRING;
    double hz = acquiring ? rate_hz(w, rs->frames_acquired, now) : NAN;
    int left = rs->frames_requested - rs->frames_acquired;
    json_builder_begin_object(b);
    proto_add_str(b, "uuid", rs->current);
    proto_add_str(b, "state", catalog_state_name(rs->state));
    proto_add_str(b, "screen", w->run_screen);
    proto_add_str(b, "mask", w->run_mask);
    proto_add_str(b, "object", w->run_object);
    proto_add_int(b, "frames_requested", rs->frames_requested);
    proto_add_int(b, "frames_acquired", rs->frames_acquired);
    proto_add_int(b, "frames_failed", rs->frames_failed);
    proto_add_int(b, "packets_missing", rs->packets_missing);
    proto_add_dbl(b, "progress", rs->frames_requested > 0
                                     ? (double)rs->frames_acquired / rs->frames_requested : NAN);
    proto_add_dbl(b, "rate_hz", hz);
    proto_add_dbl(b, "eta_s", hz > 0 && left >= 0 ? left / hz : NAN);
    json_builder_end_object(b);
}

static void add_daemon(JsonBuilder *b, web *w, const runner_status *rs)
{
    json_builder_set_member_name(b, "daemon");
    json_builder_begin_object(b);
    proto_add_str(b, "version", SPECKLAB_VERSION);
    proto_add_dbl(b, "uptime_s", (g_get_monotonic_time() - w->started_us) * 1e-6);
    proto_add_str(b, "state", rs->current[0] || rs->queue[0] ? "running" : "idle");
    proto_add_time(b, "time", catalog_now_ms());
    json_builder_set_member_name(b, "queue");
    json_builder_begin_array(b);
    for (int i = 0; rs->queue[i]; i++)
        json_builder_add_string_value(b, rs->queue[i]);
    json_builder_end_array(b);
    json_builder_end_object(b);
}

static void add_camera(JsonBuilder *b, const config *cfg, const runner_status *rs)
{
    json_builder_set_member_name(b, "camera");
    json_builder_begin_object(b);
    proto_add_str(b, "address", cfg->camera_address);
    proto_add_bool(b, "connected", rs->camera_connected);
    proto_add_str(b, "vendor", rs->camera.vendor[0] ? rs->camera.vendor : NULL);
    proto_add_str(b, "model", rs->camera.model[0] ? rs->camera.model : NULL);
    proto_add_str(b, "serial", rs->camera.serial[0] ? rs->camera.serial : NULL);
    proto_add_str(b, "error", rs->camera_error[0] ? rs->camera_error : NULL);
    json_builder_end_object(b);
}

/* One wheel: where it is, what it holds, every slot it has. */
static void add_wheel(JsonBuilder *b, const config *cfg, const runner_status *rs, int wh)
{
    const stage_wheel_status *ws = &rs->wheels[wh];
    const config_slot *list = wh == 0 ? cfg->screens : cfg->masks;
    int n = wh == 0 ? cfg->nscreens : cfg->nmasks, known = rs->stage_known;
    const config_slot *at = !known || ws->position < 0 ? NULL
                            : wh == 0 ? config_screen_at(cfg, ws->position)
                                      : config_mask_at(cfg, ws->position);
    json_builder_begin_object(b);
    proto_add_str(b, "name", stage_wheel_name(wh));
    if (known && ws->position >= 0)
        proto_add_int(b, "position", ws->position);
    else
        proto_add_str(b, "position", NULL);
    proto_add_str(b, "holds", at ? at->name : NULL);
    proto_add_str(b, "status", !known ? NULL : ws->faulted ? "faulted" : ws->busy ? "moving"
                               : !ws->homed ? "not homed" : ws->in_position ? "in position"
                                                                           : "between slots");
    proto_add_str(b, "fault", known && ws->fault ? ws->fault_text : NULL);
    json_builder_set_member_name(b, "slots");
    json_builder_begin_array(b);
    for (int i = 0; i < n; i++) {
        json_builder_begin_object(b);
        proto_add_int(b, "slot", list[i].slot);
        proto_add_str(b, "name", list[i].name);
        json_builder_end_object(b);
    }
    json_builder_end_array(b);
    json_builder_end_object(b);
}

static void add_stage(JsonBuilder *b, const config *cfg, const runner_status *rs)
{
    json_builder_set_member_name(b, "stage");
    json_builder_begin_object(b);
    proto_add_bool(b, "connected", rs->stage_connected);
    proto_add_str(b, "error", rs->stage_error[0] ? rs->stage_error : NULL);
    json_builder_set_member_name(b, "wheels");
    json_builder_begin_array(b);
    for (int wh = 0; wh < STAGE_NWHEELS; wh++)
        add_wheel(b, cfg, rs, wh);
    json_builder_end_array(b);
    json_builder_end_object(b);
}

static void add_view(JsonBuilder *b, web *w)
{
    webview_info vi;
    webview_info_get(w->view, &vi);
    json_builder_set_member_name(b, "view");
    json_builder_begin_object(b);
    proto_add_int(b, "seq", (gint64)vi.seq);
    proto_add_str(b, "run", vi.seq ? vi.uuid : NULL);
    proto_add_int(b, "width", vi.w);
    proto_add_int(b, "height", vi.h);
    proto_add_dbl(b, "min", vi.min);
    proto_add_dbl(b, "max", vi.max);
    proto_add_dbl(b, "mean", vi.mean);
    proto_add_int(b, "powspec_frames", vi.ps_frames);
    proto_add_int(b, "frames_shown", (gint64)vi.taken);
    proto_add_int(b, "frames_skipped", (gint64)vi.skipped);
    proto_add_dbl(b, "rate_hz", vi.hz);
    proto_add_int(b, "viewers", w->ws->len);
    json_builder_end_object(b);
}

const char *web_status_json(web *w)
{
    gint64 now = g_get_monotonic_time();
    if (w->status_json && now - w->status_us < STATUS_CACHE_US)
        return w->status_json;
    runner_status rs;
    char cur[CATALOG_UUID_LEN + 1] = "";
    int queued = 0;
    runner_status_get(w->run, &rs);
    worker_status(w->wk, cur, &queued);
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    add_daemon(b, w, &rs);
    add_run(b, w, &rs, now);
    add_camera(b, w->cfg, &rs);
    add_stage(b, w->cfg, &rs);
    json_builder_set_member_name(b, "reconstruction");
    json_builder_begin_object(b);
    proto_add_str(b, "current", cur[0] ? cur : NULL);
    proto_add_int(b, "queued", queued);
    json_builder_end_object(b);
    add_view(b, w);
    json_builder_end_object(b);
    g_strfreev(rs.queue);
    g_free(w->status_json);
    w->status_json = take_json(b);
    w->status_us = now;
    return w->status_json;
}
