/* fakesrc.c - the simulator as a camera_source (fakesrc.h): the renderer
 * of render.c on the fake camera of each (re)connect, and the fake
 * stage's beam polled by a thread of its own.
 *
 * Threads: attach runs in the thread driving the camera; the fill
 * callback in Aravis's stream thread; the poll thread only sets the beam
 * (renderer_set_beam locks).  release stops the poll thread first, and
 * runs after the camera (and its stream thread) is gone.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fakecam_app.h"
#include "fakesrc.h"

/* GigE Vision bootstrap "Serial Number" (16 bytes): the fake camera's
 * GenICam DeviceSerialNumber reads it, as bin/specklab-fake-camera's
 * --serial sets it. */
#define GVBS_SERIAL_OFFSET 0x00d8
#define GVBS_SERIAL_SIZE 16

typedef struct fakesrc {
    renderer *r;
    char serial[GVBS_SERIAL_SIZE];
    stage_poll *poll;
    int poll_ms;
    GThread *thread;
    GMutex lock;
    GCond cond;
    int stop;
    beam last;
} fakesrc;

typedef struct src_opts {
    char *size, *screen_r0, *mask_slots, *stage, *serial;
    double dm, sep_arcsec, pa_deg;
    gint64 seed;
    int screen_slot, mask_slot, stage_unit, stage_poll_ms;
} src_opts;

/* The fake camera of this connect: the model's sensor, the whole of it
 * as ROI in Mono16 (as bin/specklab-fake-camera starts), then the pixels.
 * The fill pattern is set last, once everything it reads is in place. */
static int src_attach(void *data, void *fake_camera, sl_err *err)
{
    fakesrc *s = data;
    ArvFakeCamera *fake = fake_camera;
    guint32 exposure_us = renderer_init_camera(s->r, fake);
    arv_fake_camera_write_memory(fake, GVBS_SERIAL_OFFSET, GVBS_SERIAL_SIZE, s->serial);
    renderer_attach(s->r, fake);
    int rc = renderer_prepare(s->r, exposure_us, 0, err);
    if (rc == SL_OK)
        arv_fake_camera_set_fill_pattern(fake, renderer_fill, s->r);
    return rc;
}

static gpointer poll_thread(gpointer data)
{
    fakesrc *s = data;
    g_mutex_lock(&s->lock);
    while (!s->stop) {
        gint64 until = g_get_monotonic_time() + (gint64)s->poll_ms * 1000;
        while (!s->stop && g_cond_wait_until(&s->cond, &s->lock, until))
            ;
        if (s->stop)
            break;
        g_mutex_unlock(&s->lock);
        beam b = s->last;
        sl_err e = {0};
        if (stage_poll_read(s->poll, &b, &e) == SL_OK && memcmp(&b, &s->last, sizeof b) != 0) {
            renderer_set_beam(s->r, &b);
            s->last = b;
        }
        g_mutex_lock(&s->lock);
    }
    g_mutex_unlock(&s->lock);
    return NULL;
}

static void src_release(void *data)
{
    fakesrc *s = data;
    if (!s)
        return;
    if (s->thread) {
        g_mutex_lock(&s->lock);
        s->stop = 1;
        g_cond_signal(&s->cond);
        g_mutex_unlock(&s->lock);
        g_thread_join(s->thread);
    }
    stage_poll_free(s->poll);
    renderer_free(s->r);
    g_mutex_clear(&s->lock);
    g_cond_clear(&s->cond);
    free(s);
}

static int parse_args(const char *args, src_opts *o, sl_err *err)
{
    GOptionEntry entries[] = {
        {"size", 0, 0, G_OPTION_ARG_STRING, &o->size, NULL, NULL},
        {"serial", 0, 0, G_OPTION_ARG_STRING, &o->serial, NULL, NULL},
        {"seed", 0, 0, G_OPTION_ARG_INT64, &o->seed, NULL, NULL},
        {"screen-r0", 0, 0, G_OPTION_ARG_STRING, &o->screen_r0, NULL, NULL},
        {"mask-slots", 0, 0, G_OPTION_ARG_STRING, &o->mask_slots, NULL, NULL},
        {"screen-slot", 0, 0, G_OPTION_ARG_INT, &o->screen_slot, NULL, NULL},
        {"mask-slot", 0, 0, G_OPTION_ARG_INT, &o->mask_slot, NULL, NULL},
        {"dm-mag", 0, 0, G_OPTION_ARG_DOUBLE, &o->dm, NULL, NULL},
        {"sep-arcsec", 0, 0, G_OPTION_ARG_DOUBLE, &o->sep_arcsec, NULL, NULL},
        {"pa-deg", 0, 0, G_OPTION_ARG_DOUBLE, &o->pa_deg, NULL, NULL},
        {"stage", 0, 0, G_OPTION_ARG_STRING, &o->stage, NULL, NULL},
        {"stage-unit", 0, 0, G_OPTION_ARG_INT, &o->stage_unit, NULL, NULL},
        {"stage-poll-ms", 0, 0, G_OPTION_ARG_INT, &o->stage_poll_ms, NULL, NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    char **argv = NULL, *line = g_strdup_printf("fake-source %s", args ? args : "");
    int argc = 0, rc = SL_OK;
    GError *ge = NULL;
    GOptionContext *ctx = g_option_context_new(NULL);
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_set_help_enabled(ctx, FALSE);
    /* parse_strv frees the arguments it takes out of argv. */
    if (!g_shell_parse_argv(line, &argc, &argv, &ge) ||
        !g_option_context_parse_strv(ctx, &argv, &ge)) {
        rc = sl_seterr(err, SL_EINVAL, "fake camera source '%s': %s", args, ge->message);
        g_error_free(ge);
    } else if ((argc = (int)g_strv_length(argv)) > 1) {
        rc = sl_seterr(err, SL_EINVAL, "fake camera source: unexpected argument '%s'", argv[1]);
    } else if (o->serial && strlen(o->serial) >= GVBS_SERIAL_SIZE) {
        rc = sl_seterr(err, SL_EINVAL, "fake camera source: --serial: at most %d characters",
                       GVBS_SERIAL_SIZE - 1);
    } else if (o->stage_poll_ms < 1) {
        rc = sl_seterr(err, SL_EINVAL, "fake camera source: --stage-poll-ms must be >= 1");
    }
    g_strfreev(argv);
    g_option_context_free(ctx);
    g_free(line);
    return rc;
}

/* The model (fake-camera's defaults) and, with --stage, the first
 * answer of the stage before the source is handed out. */
static int build(fakesrc *s, src_opts *o, sl_err *err)
{
    fakecam_model m;
    mask *masks[FAKECAM_MAX_SLOTS] = {0};
    int nmasks = 0;
    int rc = fakecam_model_from_args(o->size ? o->size : "128x128",
                                     o->screen_r0 ? o->screen_r0 : "inf,0.25,0.15,0.10,0.07,0.05",
                                     o->mask_slots ? o->mask_slots : "full,nrm17", &m, masks,
                                     &nmasks, err);
    if (rc != SL_OK)
        return rc;
    m.seed = (uint64_t)o->seed;
    m.dm = o->dm;
    m.sep_arcsec = o->sep_arcsec;
    m.pa_deg = o->pa_deg;
    if ((rc = renderer_new(&s->r, &m, masks, nmasks, err)) != SL_OK)
        return rc;
    if (!o->stage) {
        s->last = (beam){1, 0, o->screen_slot, o->mask_slot};
        renderer_set_beam(s->r, &s->last);
        return SL_OK;
    }
    if ((rc = stage_poll_new(&s->poll, o->stage, o->stage_unit, err)) != SL_OK)
        return rc;
    s->poll_ms = o->stage_poll_ms;
    sl_err first = {0};
    if (stage_poll_read(s->poll, &s->last, &first) == SL_OK)
        renderer_set_beam(s->r, &s->last);
    s->thread = g_thread_new("fake-source-stage", poll_thread, s);
    return SL_OK;
}

int fakesrc_new(camera_source *out, const char *args, sl_err *err)
{
    src_opts o = {.dm = 1, .sep_arcsec = 0.7, .pa_deg = 30, .seed = 1, .screen_slot = 1,
                  .stage_unit = 1, .stage_poll_ms = 50};
    memset(out, 0, sizeof *out);
    fakesrc *s = calloc(1, sizeof *s);
    if (!s)
        return sl_seterr(err, SL_ENOMEM, "fake camera source: out of memory");
    g_mutex_init(&s->lock);
    g_cond_init(&s->cond);
    int rc = parse_args(args, &o, err);
    if (rc == SL_OK)
        rc = build(s, &o, err);
    if (rc == SL_OK)
        snprintf(s->serial, sizeof s->serial, "%s", o.serial ? o.serial : "SPECKLE01");
    g_free(o.size), g_free(o.screen_r0), g_free(o.mask_slots), g_free(o.stage);
    g_free(o.serial);
    if (rc != SL_OK) {
        src_release(s);
        return rc;
    }
    *out = (camera_source){src_attach, src_release, s};
    return SL_OK;
}
