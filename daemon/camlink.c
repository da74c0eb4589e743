/* camlink.c - the runner thread's hold on the camera (see camlink.h). */
#include "camlink.h"

#include <math.h>
#include <stdio.h>

#include "runner_int.h"

/* Keep trying to get the camera this long past its heartbeat timeout. */
#define OPEN_RETRY_EXTRA_US 5000000
#define RETRY_PAUSE_US 500000
/* Idle reopening: the first try this long after the loss, then doubling
 * (each try of an absent camera costs the thread ~2.5 s). */
#define REOPEN_FIRST_US 1000000
#define REOPEN_MAX_US 8000000

static void schedule_reopen(runner *r, gint64 wait_us)
{
    r->cam_retry_us = wait_us;
    r->cam_next_try_us = g_get_monotonic_time() + wait_us;
}

/* camera_open, and the fake backend's pixel source when configured
 * (loaded per handle: a reopened camera gets a fresh one). */
static int open_handle(runner *r, sl_err *e)
{
    const config *cfg = r->cfg;
    int rc = camera_open(&r->cam, cfg->camera_backend, cfg->camera_address, e);
    if (rc == SL_OK && cfg->camera_source &&
        (rc = camera_load_source(r->cam, cfg->camera_source, cfg->camera_source_args)) != SL_OK) {
        sl_seterr(e, rc, "%s", camera_errmsg(r->cam));
        camera_close(r->cam);
    }
    if (rc != SL_OK)
        r->cam = NULL;
    return rc;
}

/* Open (r->cam NULL) and read the identity; noted either way. */
static int open_camera(runner *r, sl_err *e)
{
    camera_info info;
    if (open_handle(r, e) == SL_OK &&
        camera_info_get(r->cam, &info) == SL_OK && camera_check(r->cam) == SL_OK) {
        runner_note_camera(r, 1, &info, NULL);
        r->cam_fresh = 1;
        g_message("camera %s: %s %s, serial %s", r->cfg->camera_address, info.vendor,
                  info.model, info.serial);
        return SL_OK;
    }
    if (r->cam)
        sl_seterr(e, SL_EIO, "%s", camera_errmsg(r->cam));
    runner_note_camera(r, 0, NULL, e->msg);
    camera_close(r->cam);
    r->cam = NULL;
    return SL_EIO;
}

void camlink_open(runner *r)
{
    sl_err e = {0};
    if (open_camera(r, &e) != SL_OK) {
        g_message("camera not available yet: %s", e.msg);
        schedule_reopen(r, REOPEN_FIRST_US);
    }
}

void camlink_idle(runner *r)
{
    sl_err e = {0};
    if (r->cam) {
        if (camera_check(r->cam) == SL_OK)
            return;
        snprintf(e.msg, sizeof e.msg, "%s (noticed while idle)", camera_errmsg(r->cam));
        g_message("%s; closing it and reopening when it answers", e.msg);
        runner_note_camera(r, 0, NULL, e.msg);
        camera_close(r->cam);
        r->cam = NULL;
        schedule_reopen(r, REOPEN_FIRST_US);
        return;
    }
    if (g_get_monotonic_time() < r->cam_next_try_us)
        return;
    if (open_camera(r, &e) != SL_OK)
        schedule_reopen(r, MIN(r->cam_retry_us * 2, REOPEN_MAX_US));
}

static int configure(camera *c, const config *cfg, const runner_spec *sp, camera_config *cf)
{
    int rc = camera_set_pixel_format(c, camera_pixfmt_parse(cfg->pixel_format));
    if (rc == SL_OK && cfg->roi[2] > 0)
        rc = camera_set_roi(c, cfg->roi[0], cfg->roi[1], cfg->roi[2], cfg->roi[3]);
    if (rc == SL_OK)
        rc = camera_set_exposure_us(c, sp->exposure_us);
    if (rc == SL_OK && isfinite(cfg->frame_rate_hz))
        rc = camera_set_frame_rate_hz(c, cfg->frame_rate_hz);
    if (rc == SL_OK)
        rc = camera_set_trigger(c, CAMERA_TRIGGER_FREE_RUN);
    if (rc == SL_OK)
        rc = camera_set_heartbeat_ms(c, cfg->heartbeat_timeout_ms);
    if (rc == SL_OK)
        rc = camera_config_get(c, cf);
    return rc;
}

/* One attempt: open if needed, make sure this host controls the camera,
 * configure, and prime a fresh handle with one start/stop (a camera whose
 * previous controller died mid-acquisition may still be "acquiring"
 * towards that controller's port: AcquisitionStop makes the real start
 * stream here; observed with Aravis's fake GigE camera). */
static int attempt(runner *r, const runner_spec *sp, camera_config *cf, camera_info *info,
                   sl_err *e)
{
    int fresh = !r->cam || r->cam_fresh;
    if (!r->cam && open_handle(r, e) != SL_OK)
        return SL_EIO;
    int rc = camera_probe(r->cam);
    if (rc == CAMERA_ELOST)
        g_message("camera: %s; opening it again", camera_errmsg(r->cam));
    else if (rc == SL_OK && configure(r->cam, r->cfg, sp, cf) == SL_OK &&
             camera_info_get(r->cam, info) == SL_OK &&
             (!fresh || (camera_start(r->cam, 2) == SL_OK && camera_stop(r->cam) == SL_OK)))
        return SL_OK;
    sl_seterr(e, SL_EIO, "%s", camera_errmsg(r->cam));
    camera_close(r->cam);
    r->cam = NULL;
    return SL_EIO;
}

int camlink_ready(runner *r, const runner_spec *sp, camera_config *cf, camera_info *info,
                  sl_err *e)
{
    gint64 end = g_get_monotonic_time() + r->cfg->heartbeat_timeout_ms * 1000LL +
                 OPEN_RETRY_EXTRA_US;
    for (int n = 0;; n++) {
        /* a handle that lost control is replaced at once, not after a pause */
        int stale = r->cam && !r->cam_fresh;
        if (n > 0)
            g_usleep(RETRY_PAUSE_US);
        int rc = attempt(r, sp, cf, info, e);
        if (rc != SL_OK && stale && !r->cam)
            rc = attempt(r, sp, cf, info, e);
        if (rc == SL_OK) {
            r->cam_fresh = 0;
            runner_note_camera(r, 1, info, NULL);
            return SL_OK;
        }
        runner_note_camera(r, 0, NULL, e->msg);
        if (g_get_monotonic_time() >= end || runner_aborting(r))
            return rc;
        g_message("camera: %s; retrying", e->msg);
    }
}
