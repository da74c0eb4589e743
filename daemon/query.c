/* query.c - the commands that only read: status, devices, runs, run,
 * screens, masks (see dispatch.h). */
#include "dispatch_int.h"

#include <gio/gio.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "stage_probe.h"

static JsonNode *builder_done(JsonBuilder *b)
{
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    return n;
}

static void add_camera(JsonBuilder *b, const config *cfg, const runner_status *rs)
{
    json_builder_set_member_name(b, "camera");
    json_builder_begin_object(b);
    proto_add_str(b, "backend", cfg->camera_backend);
    proto_add_str(b, "address", cfg->camera_address);
    proto_add_bool(b, "connected", rs->camera_connected);
    proto_add_str(b, "vendor", rs->camera.vendor[0] ? rs->camera.vendor : NULL);
    proto_add_str(b, "model", rs->camera.model[0] ? rs->camera.model : NULL);
    proto_add_str(b, "serial", rs->camera.serial[0] ? rs->camera.serial : NULL);
    proto_add_str(b, "error", rs->camera_error[0] ? rs->camera_error : NULL);
    json_builder_end_object(b);
}

static void stage_address(const config *cfg, char *buf, size_t n)
{
    if (!strcmp(cfg->stage_backend, "tcp"))
        snprintf(buf, n, "%s:%d", cfg->stage_host, cfg->stage_port);
    else
        snprintf(buf, n, "%s", cfg->stage_device);
}

static void add_wheels(JsonBuilder *b, const stage_wheel_status *ws, int known)
{
    json_builder_set_member_name(b, "wheels");
    json_builder_begin_array(b);
    for (int w = 0; known && w < STAGE_NWHEELS; w++) {
        const char *status = ws[w].faulted ? "faulted" : ws[w].busy ? "moving"
                             : !ws[w].homed ? "not homed" : ws[w].in_position ? "in position"
                                                                               : "between slots";
        json_builder_begin_object(b);
        proto_add_str(b, "name", stage_wheel_name(w));
        proto_add_int(b, "slots", ws[w].slots);
        if (ws[w].position >= 0)
            proto_add_int(b, "position", ws[w].position);
        else
            proto_add_str(b, "position", NULL);
        proto_add_str(b, "status", status);
        proto_add_str(b, "fault", ws[w].fault ? ws[w].fault_text : NULL);
        json_builder_end_object(b);
    }
    json_builder_end_array(b);
}

char *cmd_status(request *rq)
{
    daemon_ctx *d = rq->d;
    runner_status rs;
    char recon[CATALOG_UUID_LEN + 1], addr[160];
    int recon_queued = 0;
    runner_status_get(d->run, &rs);
    worker_status(d->wk, recon, &recon_queued);
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    proto_add_str(b, "version", SPECKLABD_VERSION);
    proto_add_dbl(b, "uptime_s", (g_get_monotonic_time() - d->started_us) * 1e-6);
    proto_add_str(b, "web", d->web_url[0] ? d->web_url : NULL);   /* null: no page */
    proto_add_str(b, "state", rs.current[0] || rs.queue[0] ? "running" : "idle");
    proto_add_str(b, "current_run", rs.current[0] ? rs.current : NULL);
    if (rs.current[0]) {
        proto_add_str(b, "current_state", catalog_state_name(rs.state));
        proto_add_int(b, "frames_acquired", rs.frames_acquired);
        proto_add_int(b, "frames_requested", rs.frames_requested);
    }
    json_builder_set_member_name(b, "queue");
    json_builder_begin_array(b);
    for (int i = 0; rs.queue[i]; i++)
        json_builder_add_string_value(b, rs.queue[i]);
    json_builder_end_array(b);
    proto_add_str(b, "reconstructing", recon[0] ? recon : NULL);
    proto_add_int(b, "reconstruct_queue", recon_queued);
    add_camera(b, d->cfg, &rs);
    json_builder_set_member_name(b, "stage");
    json_builder_begin_object(b);
    stage_address(d->cfg, addr, sizeof addr);
    proto_add_str(b, "address", addr);
    proto_add_bool(b, "connected", rs.stage_connected);
    proto_add_str(b, "error", rs.stage_error[0] ? rs.stage_error : NULL);
    proto_add_int(b, "rejected_replies", rs.stage_rejected + d->stage_rejected);
    json_builder_end_object(b);
    proto_add_str(b, "catalog", d->cfg->catalog);
    proto_add_str(b, "data_dir", d->cfg->data_dir);
    proto_add_int(b, "clients", server_nclients(d->srv));
    json_builder_end_object(b);
    g_strfreev(rs.queue);
    return reply_ok(rq, builder_done(b));
}

/* devices: the stage is read live on a short thread with a handle of its
 * own (a Modbus/TCP stage takes several clients; every call is bounded by
 * call_timeout_ms), so the main loop never waits on the network.  The
 * camera is reported from the runner's last contact: GigE Vision grants
 * control to one client, which is the runner. */
typedef struct devq {
    daemon_ctx *d;
    proto_req q;
    stage_wheel_status ws[STAGE_NWHEELS];
    int known, connected;
    unsigned rejected;
    char error[SL_ERRMSG_MAX];
    char fix[SL_ERRMSG_MAX];   /* a serial stage: what to do (stage_probe.h) */
} devq;

static void devices_thread(GTask *task, gpointer src, gpointer data, GCancellable *cancel)
{
    devq *v = data;
    const config *cfg = v->d->cfg;
    stage_config sc;
    stage *s = NULL;
    sl_err e = {0};
    (void)src, (void)cancel;
    stage_config_defaults(&sc);
    sc.backend = cfg->stage_backend;
    sc.host = cfg->stage_host;
    sc.port = cfg->stage_port;
    sc.device = cfg->stage_device;
    sc.baud = cfg->stage_baud;
    sc.parity = cfg->stage_parity;
    sc.unit_id = cfg->stage_unit;
    sc.response_timeout_ms = cfg->response_timeout_ms;
    sc.call_timeout_ms = cfg->call_timeout_ms;
    if (stage_new(&s, &sc, &e) != SL_OK) {
        snprintf(v->error, sizeof v->error, "%s", e.msg);
    } else {
        v->known = 1;
        for (int w = 0; w < STAGE_NWHEELS && v->known; w++)
            if (stage_status(s, w, &v->ws[w]) != SL_OK) {
                v->known = 0;
                snprintf(v->error, sizeof v->error, "%s", stage_errmsg(s));
            }
        v->connected = stage_connected(s);
        v->rejected = stage_rejected_replies(s);
        stage_free(s);
    }
    stage_probe_result pr;
    /* no scan of other settings here: a query is answered within seconds */
    if (!v->known && !strcmp(sc.backend, "rtu") && stage_probe_serial(&sc, 0, &pr) == SL_OK &&
        pr.verdict != STAGE_PROBE_OK && pr.verdict != STAGE_PROBE_ERROR) {
        snprintf(v->error, sizeof v->error, "%s", pr.what);
        snprintf(v->fix, sizeof v->fix, "%s", pr.fix);
    }
    g_task_return_boolean(task, TRUE);
}

static void devices_done(GObject *src, GAsyncResult *res, gpointer data)
{
    devq *v = data;
    daemon_ctx *d = v->d;
    runner_status rs;
    char addr[160];
    (void)src, (void)res;
    runner_status_get(d->run, &rs);
    d->stage_rejected += v->rejected;
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    add_camera(b, d->cfg, &rs);
    json_builder_set_member_name(b, "stage");
    json_builder_begin_object(b);
    stage_address(d->cfg, addr, sizeof addr);
    proto_add_str(b, "address", addr);
    proto_add_bool(b, "connected", v->known);
    proto_add_str(b, "error", v->error[0] ? v->error : NULL);
    proto_add_str(b, "fix", v->fix[0] ? v->fix : NULL);
    proto_add_int(b, "rejected_replies", rs.stage_rejected + d->stage_rejected);
    add_wheels(b, v->ws, v->known);
    json_builder_end_object(b);
    json_builder_end_object(b);
    g_strfreev(rs.queue);
    server_complete(d->srv, v->q.tok, proto_reply_ok(&v->q, builder_done(b)));
    d->pending_tasks--;
    g_free(v);
}

char *cmd_devices(request *rq)
{
    devq *v = g_new0(devq, 1);
    v->d = rq->d;
    v->q = rq->q;
    rq->d->pending_tasks++;
    GTask *t = g_task_new(NULL, NULL, devices_done, v);
    g_task_set_task_data(t, v, NULL);
    g_task_run_in_thread(t, devices_thread);
    g_object_unref(t);
    return NULL;
}

/* ---- runs, run -------------------------------------------------------------- */

typedef struct run_list {
    catalog *cat;
    JsonBuilder *b;
} run_list;

static int add_run(const catalog_run *r, void *user)
{
    run_list *l = user;
    json_builder_add_value(l->b, proto_run_node(l->cat, r));
    return 0;
}

char *cmd_runs(request *rq)
{
    daemon_ctx *d = rq->d;
    char *state = NULL, *screen = NULL, *kind = NULL, *reply = NULL;
    gint64 limit = 50;
    catalog_run_filter f = {0};
    if (arg_str(rq, "state", 0, 0, &state, &reply) ||
        arg_str(rq, "screen", 0, 1, &screen, &reply) || arg_since(rq, &f.since_ms, &reply) ||
        arg_int(rq, "limit", 0, 1, 10000, &limit, NULL, &reply) ||
        arg_str(rq, "kind", 0, 0, &kind, &reply))
        goto free_args;
    if (kind && catalog_kind_parse(kind, &f.kind) != SL_OK) {
        reply = reply_err(rq, "bad-request", "kind must be science, dark, flat or calibrator, "
                          "got '%.40s'", kind);
        goto free_args;
    }
    f.limit = (int)limit;
    if (state && (catalog_state_parse(state, &f.state) != SL_OK || f.state == CATALOG_STATE_ANY)) {
        reply = reply_err(rq, "bad-request", "state must be one of queued, moving, acquiring, "
                          "stored, reconstructing, done, failed, aborted, interrupted; got "
                          "'%.40s'", state);
        goto free_args;
    }
    if (screen) {
        const config_slot *sl = config_screen_find(d->cfg, screen);
        if (catalog_screen_find(d->cat, sl ? sl->name : screen, &f.screen_id) != SL_OK) {
            reply = reply_err(rq, "not-found", "%s", catalog_errmsg(d->cat));
            goto free_args;
        }
    }
    run_list l = {d->cat, json_builder_new()};
    json_builder_begin_object(l.b);
    json_builder_set_member_name(l.b, "runs");
    json_builder_begin_array(l.b);
    int rc = catalog_run_list(d->cat, &f, add_run, &l);
    json_builder_end_array(l.b);
    json_builder_end_object(l.b);
    JsonNode *n = builder_done(l.b);
    if (rc != SL_OK) {
        json_node_unref(n);
        reply = reply_err(rq, "internal", "%s", catalog_errmsg(d->cat));
    } else {
        reply = reply_ok(rq, n);
    }
free_args:
    g_free(state);
    g_free(screen);
    g_free(kind);
    return reply;
}

static int add_recon(const catalog_recon *r, void *user)
{
    json_builder_add_value(user, proto_recon_node(r));
    return 0;
}

char *cmd_run(request *rq)
{
    daemon_ctx *d = rq->d;
    char uuid[CATALOG_UUID_LEN + 1], *reply = NULL;
    catalog_run r;
    if (arg_run(rq, "run", 1, uuid, NULL, &reply) != SL_OK)
        return reply;
    if (catalog_run_get(d->cat, uuid, &r) != SL_OK)
        return reply_err(rq, "not-found", "%s", catalog_errmsg(d->cat));
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    json_builder_set_member_name(b, "run");
    json_builder_add_value(b, proto_run_node(d->cat, &r));
    json_builder_set_member_name(b, "reconstructions");
    json_builder_begin_array(b);
    int rc = catalog_recon_list(d->cat, uuid, add_recon, b);
    json_builder_end_array(b);
    json_builder_end_object(b);
    catalog_run_clear(&r);
    JsonNode *n = builder_done(b);
    if (rc != SL_OK) {
        json_node_unref(n);
        return reply_err(rq, "internal", "%s", catalog_errmsg(d->cat));
    }
    return reply_ok(rq, n);
}

/* ---- screens, masks --------------------------------------------------------- */

typedef struct screen_list {
    catalog *cat;
    JsonBuilder *b;
    int64_t since_ms;
    int rc;
} screen_list;

static int add_screen(const catalog_screen *s, void *user)
{
    screen_list *l = user;
    catalog_r0_stats st;
    JsonBuilder *b = l->b;
    if ((l->rc = catalog_screen_stats(l->cat, s->name, l->since_ms, 0, &st)) != SL_OK)
        return l->rc;
    json_builder_begin_object(b);
    proto_add_str(b, "name", s->name);
    if (s->slot >= 0)
        proto_add_int(b, "slot", s->slot);
    else
        proto_add_str(b, "slot", NULL);
    proto_add_str(b, "description", s->description);
    proto_add_dbl(b, "r0_m", s->last_r0_m);
    proto_add_time(b, "r0_measured", s->last_r0_ms);
    json_builder_set_member_name(b, "stats");
    json_builder_begin_object(b);
    proto_add_int(b, "n", st.n);
    proto_add_int(b, "nruns", st.nruns);
    proto_add_dbl(b, "mean_r0_m", st.r0_mean_m);
    proto_add_dbl(b, "median_r0_m", st.r0_median_m);
    proto_add_dbl(b, "min_r0_m", st.r0_min_m);
    proto_add_dbl(b, "max_r0_m", st.r0_max_m);
    proto_add_dbl(b, "std_r0_m", st.r0_std_m);
    proto_add_dbl(b, "mean_seeing_arcsec", st.seeing_mean_arcsec);
    proto_add_time(b, "first", st.first_ms);
    proto_add_time(b, "last", st.last_ms);
    json_builder_end_object(b);
    json_builder_end_object(b);
    return 0;
}

char *cmd_screens(request *rq)
{
    daemon_ctx *d = rq->d;
    char *reply = NULL;
    screen_list l = {d->cat, NULL, 0, SL_OK};
    if (arg_since(rq, &l.since_ms, &reply) != SL_OK)
        return reply;
    l.b = json_builder_new();
    json_builder_begin_object(l.b);
    json_builder_set_member_name(l.b, "screens");
    json_builder_begin_array(l.b);
    int rc = catalog_screen_list(d->cat, add_screen, &l);
    json_builder_end_array(l.b);
    json_builder_end_object(l.b);
    JsonNode *n = builder_done(l.b);
    if (rc != SL_OK) {
        json_node_unref(n);
        return reply_err(rq, "internal", "%s", catalog_errmsg(d->cat));
    }
    return reply_ok(rq, n);
}

static int add_mask(const catalog_mask *m, void *user)
{
    JsonBuilder *b = user;
    json_builder_begin_object(b);
    proto_add_str(b, "name", m->name);
    if (m->slot >= 0)
        proto_add_int(b, "slot", m->slot);
    else
        proto_add_str(b, "slot", NULL);
    proto_add_str(b, "kind", m->kind == CATALOG_MASK_FULL ? "full" : "holes");
    proto_add_dbl(b, "diameter_m", m->diameter_m);
    proto_add_int(b, "nholes", m->nholes);
    proto_add_str(b, "description", m->description);
    json_builder_end_object(b);
    return 0;
}

char *cmd_masks(request *rq)
{
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    json_builder_set_member_name(b, "masks");
    json_builder_begin_array(b);
    int rc = catalog_mask_list(rq->d->cat, add_mask, b);
    json_builder_end_array(b);
    json_builder_end_object(b);
    JsonNode *n = builder_done(b);
    if (rc != SL_OK) {
        json_node_unref(n);
        return reply_err(rq, "internal", "%s", catalog_errmsg(rq->d->cat));
    }
    return reply_ok(rq, n);
}
