/* runner.c - the run queue, the acquisition thread and the moving step;
 * see runner.h (acquire.c does the camera and the files). */
#define _GNU_SOURCE
#include "runner_int.h"

#include "camlink.h"
#include "runstate.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define SETTLE_SLICE_US 50000
/* While idle, the devices are checked this often.  A stage connection
 * open: one poll() on the socket, nothing sent; a stage restarted
 * meanwhile is then reported not connected by `status`, and the next run
 * starts on a new connection.  The camera: camlink_idle (camlink.h). */
#define IDLE_CHECK_US 1000000

/* ---- thread-side helpers ------------------------------------------------ */

int runner_stopping(void *runner_arg)
{
    runner *r = runner_arg;
    g_mutex_lock(&r->mu);
    int s = r->stopping;
    g_mutex_unlock(&r->mu);
    return s;
}

static void note_state(void *runner_arg, const char *uuid, catalog_state st)
{
    runner *r = runner_arg;
    g_mutex_lock(&r->mu);
    if (r->cur && !strcmp(r->cur->uuid, uuid)) {
        r->st.state = st;
        /* Ended: status says so before the event goes out (runstate_set
         * broadcasts after this), not once the thread has tidied up; a
         * client that read the end and asked for status at once saw the
         * run still current. */
        if (catalog_state_is_terminal(st))
            r->st.current[0] = '\0';
    }
    g_mutex_unlock(&r->mu);
}

void runner_set_state(runner *r, const char *uuid, catalog_state st, const char *reason)
{
    runstate_set(r->cat, &r->cl, r->srv, uuid, st, reason, note_state, r);
}

void runner_abort_reason(runner *r, char *buf, size_t n)
{
    g_mutex_lock(&r->mu);
    snprintf(buf, n, "%s", r->abort_reason);
    g_mutex_unlock(&r->mu);
}

int runner_aborting(runner *r)
{
    g_mutex_lock(&r->mu);
    int a = r->abort_current;
    g_mutex_unlock(&r->mu);
    return a;
}

void runner_note_camera(runner *r, int connected, const camera_info *info, const char *error)
{
    g_mutex_lock(&r->mu);
    r->st.camera_connected = connected;
    if (info)
        r->st.camera = *info;
    g_strlcpy(r->st.camera_error, error ? error : "", sizeof r->st.camera_error);
    g_mutex_unlock(&r->mu);
}

void runner_note_progress(runner *r, int acquired, int failed, int64_t missing)
{
    g_mutex_lock(&r->mu);
    r->st.frames_acquired = acquired;
    r->st.frames_failed = failed;
    if (missing >= 0)
        r->st.packets_missing = missing;
    g_mutex_unlock(&r->mu);
}

static void note_stage(runner *r, const char *error)
{
    stage_wheel_status ws[STAGE_NWHEELS];
    int ok = 1;
    for (int w = 0; w < STAGE_NWHEELS && ok; w++)
        ok = stage_status(r->stg, w, &ws[w]) == SL_OK;
    g_mutex_lock(&r->mu);
    r->st.stage_connected = stage_connected(r->stg);
    r->st.stage_rejected = stage_rejected_replies(r->stg);
    if (ok) {
        memcpy(r->st.wheels, ws, sizeof ws);
        r->st.stage_known = 1;
    }
    g_strlcpy(r->st.stage_error, error ? error : "", sizeof r->st.stage_error);
    g_mutex_unlock(&r->mu);
}

/* Idle: has the stage closed the connection (restarted, powered off)? */
static void check_stage(runner *r)
{
    g_mutex_lock(&r->mu);
    int was = r->st.stage_connected;   /* said once, not at every tick */
    if (r->stg)
        r->st.stage_rejected = stage_rejected_replies(r->stg);
    g_mutex_unlock(&r->mu);
    if (!was || !r->stg || stage_connected(r->stg))
        return;
    g_message("stage %s: connection closed by the stage", stage_label(r->stg));
    g_mutex_lock(&r->mu);
    r->st.stage_connected = 0;
    snprintf(r->st.stage_error, sizeof r->st.stage_error, "stage %s: connection closed by "
             "the stage", stage_label(r->stg));
    g_mutex_unlock(&r->mu);
}

/* ---- moving ------------------------------------------------------------- */

static int stage_ready(runner *r, sl_err *e)
{
    if (r->stg)
        return SL_OK;
    const config *c = r->cfg;
    stage_config sc;
    stage_config_defaults(&sc);
    sc.backend = c->stage_backend;
    sc.host = c->stage_host;
    sc.port = c->stage_port;
    sc.device = c->stage_device;
    sc.baud = c->stage_baud;
    sc.parity = c->stage_parity;
    sc.unit_id = c->stage_unit;
    sc.response_timeout_ms = c->response_timeout_ms;
    sc.call_timeout_ms = c->call_timeout_ms;
    sc.move_timeout_ms = c->move_timeout_ms;
    return stage_new(&r->stg, &sc, e);
}

/* Both wheels to the run's slots: home a wheel that is not homed, refuse
 * a faulted one (an operator must look at it: `specklab stage reset`),
 * start both moves, wait for both (bounded by move_timeout_ms), settle. */
static int move_wheels(runner *r, const runner_spec *sp, char *reason, size_t rlen)
{
    sl_err e = {0};
    stage_wheel_status ws;
    const int slot[STAGE_NWHEELS] = {sp->screen_slot, sp->mask_slot};
    int rc = stage_ready(r, &e), homing = 0;
    if (rc != SL_OK) {
        snprintf(reason, rlen, "stage: %s", e.msg);
        return rc;
    }
    for (int w = 0; w < STAGE_NWHEELS && rc == SL_OK; w++) {
        rc = stage_status(r->stg, w, &ws);
        if (rc == SL_OK && ws.faulted) {
            rc = SL_EDATA;
            snprintf(reason, rlen, "stage %s: %s wheel faulted (%s) before the move; reset "
                     "it", stage_label(r->stg), stage_wheel_name(w), ws.fault_text);
            note_stage(r, reason);
            return rc;
        }
        if (rc == SL_OK && !ws.homed) {
            g_message("stage: homing the %s wheel", stage_wheel_name(w));
            rc = stage_home(r->stg, w);
            homing = 1;
        }
    }
    if (rc == SL_OK && homing)
        rc = stage_wait(r->stg, STAGE_WHEEL_ALL, r->cfg->move_timeout_ms);
    for (int w = 0; w < STAGE_NWHEELS && rc == SL_OK; w++)
        rc = stage_move(r->stg, w, slot[w]);
    if (rc == SL_OK)
        rc = stage_wait(r->stg, STAGE_WHEEL_ALL, r->cfg->move_timeout_ms);
    if (rc != SL_OK) {
        snprintf(reason, rlen, "%s", stage_errmsg(r->stg));
        note_stage(r, reason);
        return rc;
    }
    note_stage(r, NULL);
    /* Let the bench settle (and the fake camera see the new beam: it polls
     * the stage every 50 ms), checking for an abort meanwhile. */
    for (gint64 t = 0; t < r->cfg->settle_ms * (gint64)1000 && !runner_aborting(r);
         t += SETTLE_SLICE_US)
        g_usleep(SETTLE_SLICE_US);
    return SL_OK;
}

/* The outer extent of the run's pupil: the seeing estimator's D. */
typedef struct pupil_find {
    const char *name;
    double extent_m;
} pupil_find;

static int pupil_match(const catalog_mask *m, void *user)
{
    pupil_find *f = user;
    if (strcmp(m->name, f->name) != 0)
        return 0;
    if (m->kind == CATALOG_MASK_FULL) {
        f->extent_m = m->diameter_m;
        return 0;
    }
    double far = 0;
    for (int i = 0; i < m->nholes; i++)
        for (int j = i + 1; j < m->nholes; j++)
            far = fmax(far, hypot(m->x_m[i] - m->x_m[j], m->y_m[i] - m->y_m[j]));
    f->extent_m = far + m->diameter_m;
    return 0;
}

static void do_run(runner *r, const runner_spec *sp)
{
    char reason[1024] = "";
    double r0_m;
    sl_err e = {0};
    g_message("run %s: screen %s (slot %d), mask %s (slot %d), %d frames", sp->uuid,
              sp->screen, sp->screen_slot, sp->mask, sp->mask_slot, sp->frames);
    /* A run that could not record its own end is not started. */
    if (reserve_hold(r->cl.rs, &e) != SL_OK) {
        snprintf(reason, sizeof reason, "%s; free space on that disk first", e.msg);
        runner_set_state(r, sp->uuid, CATALOG_FAILED, reason);
        return;
    }
    runner_set_state(r, sp->uuid, CATALOG_MOVING, NULL);
    if (move_wheels(r, sp, reason, sizeof reason) != SL_OK) {
        runner_set_state(r, sp->uuid, CATALOG_FAILED, reason);
        return;
    }
    if (runner_aborting(r)) {
        runner_abort_reason(r, reason, sizeof reason);
        runner_set_state(r, sp->uuid, CATALOG_ABORTED, reason);
        return;
    }
    pupil_find pf = {sp->mask, NAN};
    catalog_mask_list(r->cat, pupil_match, &pf);
    if (!(pf.extent_m > 0))
        pf.extent_m = 1.1;   /* the built-in pupils' extent */
    acq_end end;
    acq *a = acquire_open(r, sp, pf.extent_m, reason, sizeof reason, &end);
    if (a) {
        runner_set_state(r, sp->uuid, CATALOG_ACQUIRING, NULL);
        end = acquire_stream(a, reason, sizeof reason, &r0_m);
        acquire_free(a);
    }
    if (end != ACQ_COMPLETE) {
        runner_set_state(r, sp->uuid, end == ACQ_ABORTED ? CATALOG_ABORTED : CATALOG_FAILED,
                         reason);
        return;
    }
    runner_set_state(r, sp->uuid, CATALOG_STORED, NULL);
    if (isfinite(r0_m))
        g_message("run %s: r0 %.4f m (image motion)", sp->uuid, r0_m);
    worker_submit(r->wk, sp->uuid, sp->method, sp->projections, NULL, NULL);   /* defaults */
}

/* Answer the aborts that waited for the current run, with its end state. */
static void answer_aborts(runner *r, const char *uuid)
{
    catalog_run run;
    int have = catalog_run_get(r->cat, uuid, &run) == SL_OK;
    g_mutex_lock(&r->mu);
    for (guint i = 0; i < r->abort_reqs->len; i++) {
        proto_req *q = &g_array_index(r->abort_reqs, proto_req, i);
        char *line;
        if (have && run.state == CATALOG_ABORTED) {
            JsonBuilder *b = json_builder_new();
            json_builder_begin_object(b);
            proto_add_str(b, "run", uuid);
            proto_add_str(b, "state", "aborted");
            json_builder_end_object(b);
            JsonNode *n = json_builder_get_root(b);
            g_object_unref(b);
            line = proto_reply_ok(q, n);
        } else {
            line = proto_reply_error(q, "conflict", "run %s ended %s before the abort took "
                                     "effect", uuid,
                                     have ? catalog_state_name(run.state) : "?");
        }
        server_complete_async(r->srv, q->tok, line);
    }
    g_array_set_size(r->abort_reqs, 0);
    g_mutex_unlock(&r->mu);
    if (have)
        catalog_run_clear(&run);
}

/* A hot-plug event, between runs: a camera that left has its handle
 * closed (the next run opens afresh); one that arrived is opened. */
static void camera_event(runner *r, int ev)
{
    if (ev == RUNNER_CAM_ARRIVED) {
        camlink_open(r);
        return;
    }
    camera_close(r->cam);
    r->cam = NULL;
}

/* Wait for a run (NULL: stopping); hot-plug events are handled meanwhile,
 * and every idle tick checks the stage and the camera links.  Returns with
 * mu held: the run becomes current under the same lock that took it off
 * the queue (runner_abort finds it in one or the other). */
static runner_spec *next_run(runner *r)
{
    for (;;) {
        g_mutex_lock(&r->mu);
        while (!r->stopping && g_queue_is_empty(&r->queue) && !r->cam_event) {
            if (!g_cond_wait_until(&r->cv, &r->mu, g_get_monotonic_time() + IDLE_CHECK_US)) {
                g_mutex_unlock(&r->mu);
                check_stage(r);
                camlink_idle(r);
                g_mutex_lock(&r->mu);
            }
        }
        int ev = r->stopping ? RUNNER_CAM_NONE : r->cam_event;
        r->cam_event = RUNNER_CAM_NONE;
        g_mutex_unlock(&r->mu);
        if (!ev)
            break;
        camera_event(r, ev);
    }
    g_mutex_lock(&r->mu);
    return r->stopping ? NULL : g_queue_pop_head(&r->queue);
}

static gpointer thread_main(gpointer data)
{
    runner *r = data;
    camlink_open(r);   /* know the camera before the first run (status, devices) */
    for (;;) {
        runner_spec *sp = next_run(r);
        r->cur = sp;
        r->abort_current = 0;
        if (sp) {
            snprintf(r->st.current, sizeof r->st.current, "%s", sp->uuid);
            r->st.state = CATALOG_QUEUED;
            r->st.frames_acquired = r->st.frames_failed = 0;
            r->st.packets_missing = 0;
            r->st.frames_requested = sp->frames;
        }
        g_mutex_unlock(&r->mu);
        if (!sp)
            break;
        do_run(r, sp);
        answer_aborts(r, sp->uuid);
        g_mutex_lock(&r->mu);
        r->cur = NULL;
        r->st.current[0] = '\0';
        g_mutex_unlock(&r->mu);
        g_free(sp);
    }
    runner_spec *sp;
    while ((sp = g_queue_pop_head(&r->queue))) {
        runner_set_state(r, sp->uuid, CATALOG_ABORTED, "daemon stopping");
        g_free(sp);
    }
    return NULL;
}

/* The watch thread's callback: a USB3 Vision camera came or went.  The
 * configured camera is known by its serial once opened; before that, any
 * U3V camera arriving is worth an attempt to open. */
static void usb_event(int arrived, const usb_dev_info *dev, void *userdata)
{
    runner *r = userdata;
    char label[256];
    usb_dev_label(dev, label, sizeof label);
    g_mutex_lock(&r->mu);
    const camera_info *cam = &r->st.camera;
    int known = cam->serial[0] != '\0', ours = known && !strcmp(dev->serial, cam->serial);
    int act = 0;
    if (!arrived && ours && !strcmp(cam->protocol, "USB3Vision")) {
        snprintf(r->unplugged, sizeof r->unplugged, "USB camera %.200s unplugged", label);
        r->st.camera_connected = 0;
        g_strlcpy(r->st.camera_error, r->unplugged, sizeof r->st.camera_error);
        r->cam_event = RUNNER_CAM_LEFT;
        act = 1;
    } else if (arrived && (ours || !known) && !r->st.camera_connected) {
        r->unplugged[0] = '\0';
        r->cam_event = RUNNER_CAM_ARRIVED;
        act = 1;
    }
    g_cond_signal(&r->cv);
    g_mutex_unlock(&r->mu);
    if (act)
        g_message("%s %s", label, arrived ? "plugged in: opening the camera" : "unplugged");
}

int runner_camera_unplugged(runner *r, int probe, char *why, size_t n)
{
    char serial[CAMERA_STR_MAX] = "";
    g_mutex_lock(&r->mu);
    int gone = r->unplugged[0] != '\0';
    if (gone)
        g_strlcpy(why, r->unplugged, n);
    else if (!strcmp(r->st.camera.protocol, "USB3Vision"))
        g_strlcpy(serial, r->st.camera.serial, sizeof serial);
    g_mutex_unlock(&r->mu);
    /* Before the watch thread's event: is it still on the bus?  (A fresh
     * enumeration: only when control was lost, not on every timeout.) */
    if (!gone && probe && serial[0] && camwatch_present(serial) == 0) {
        snprintf(why, n, "USB camera (serial %s) is no longer on the bus", serial);
        gone = 1;
    }
    return gone;
}

/* ---- main-thread API ----------------------------------------------------- */

int runner_new(runner **out, const config *cfg, server *srv, worker *wk, reserve *rs,
               sl_err *err)
{
    runner *r = g_new0(runner, 1);
    catalog_opts co = {cfg->catalog_busy_timeout_ms};
    int rc = catalog_open_opts(&r->cat, cfg->catalog, &co, err);
    if (rc != SL_OK) {
        g_free(r);
        *out = NULL;
        return rc;
    }
    r->cfg = cfg;
    r->srv = srv;
    r->wk = wk;
    r->cl = (catlock_ctx){runner_stopping, r, rs};
    g_mutex_init(&r->mu);
    g_cond_init(&r->cv);
    g_queue_init(&r->queue);
    r->abort_reqs = g_array_new(FALSE, FALSE, sizeof(proto_req));
    r->tap = webtap_new();
    r->th = g_thread_new("acquire", thread_main, r);
    sl_err e = {0};
    if (camwatch_new(&r->cw, usb_event, r, &e) != SL_OK)
        g_message("no USB hot-plug: %s", e.msg);
    *out = r;
    return SL_OK;
}

void runner_enqueue(runner *r, const runner_spec *spec, int *ahead,
                    char behind[CATALOG_UUID_LEN + 1])
{
    runner_spec *sp = g_memdup2(spec, sizeof *spec);
    g_mutex_lock(&r->mu);
    runner_spec *last = g_queue_peek_tail(&r->queue);
    if (!last)
        last = r->cur;
    *ahead = (int)g_queue_get_length(&r->queue) + (r->cur != NULL);
    snprintf(behind, CATALOG_UUID_LEN + 1, "%s", last ? last->uuid : "");
    g_queue_push_tail(&r->queue, sp);
    g_cond_signal(&r->cv);
    g_mutex_unlock(&r->mu);
}

int runner_abort(runner *r, const char *uuid, const proto_req *req)
{
    int what = RUNNER_NOT_HERE;
    g_mutex_lock(&r->mu);
    if (r->cur && !strcmp(r->cur->uuid, uuid)) {
        r->abort_current = 1;
        snprintf(r->abort_reason, sizeof r->abort_reason, "aborted by request");
        g_array_append_val(r->abort_reqs, *req);
        what = RUNNER_ABORTING;
    }
    for (GList *l = r->queue.head; l && what == RUNNER_NOT_HERE; l = l->next)
        if (!strcmp(((runner_spec *)l->data)->uuid, uuid)) {
            g_free(l->data);
            g_queue_delete_link(&r->queue, l);
            what = RUNNER_DEQUEUED;
        }
    g_mutex_unlock(&r->mu);
    return what;
}

void runner_status_get(runner *r, runner_status *out)
{
    g_mutex_lock(&r->mu);
    *out = r->st;
    out->queue = g_new0(char *, g_queue_get_length(&r->queue) + 1);
    int i = 0;
    for (GList *l = r->queue.head; l; l = l->next)
        out->queue[i++] = g_strdup(((runner_spec *)l->data)->uuid);
    g_mutex_unlock(&r->mu);
}

webtap *runner_tap(runner *r)
{
    return r->tap;
}

void runner_stop(runner *r)
{
    if (!r || !r->th)
        return;
    camwatch_free(r->cw);   /* no event after this */
    r->cw = NULL;
    g_mutex_lock(&r->mu);
    r->stopping = 1;
    if (r->cur) {
        r->abort_current = 1;
        snprintf(r->abort_reason, sizeof r->abort_reason, "daemon stopping");
    }
    g_cond_signal(&r->cv);
    g_mutex_unlock(&r->mu);
    g_thread_join(r->th);
    r->th = NULL;
}

void runner_free(runner *r)
{
    if (!r)
        return;
    runner_stop(r);
    camera_close(r->cam);
    stage_free(r->stg);
    catalog_close(r->cat);
    g_queue_clear_full(&r->queue, g_free);
    g_array_free(r->abort_reqs, TRUE);
    webtap_free(r->tap);
    g_mutex_clear(&r->mu);
    g_cond_clear(&r->cv);
    g_free(r);
}
