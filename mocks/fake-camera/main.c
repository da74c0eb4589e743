/* main.c - bin/specklab-fake-camera: a GigE Vision speckle camera on an
 * interface of this host, built on Aravis's ArvGvFakeCamera (which speaks
 * GVCP on UDP port 3956 and streams GVSP), rendering frames with recon's
 * simulator (fakecam.h says exactly what each frame holds).
 *
 * Beam configuration: with --stage HOST:PORT the camera polls the fake
 * stage every --stage-poll-ms and renders the screen/mask slots it has in
 * the beam; while a wheel moves (or is unhomed, faulted, or the stage has
 * not answered yet) the beam is blocked and frames are dark (every pixel
 * = bias, no noise).  If the stage stops answering, the last answer
 * stands.  Without --stage the configuration is fixed by --screen-slot and
 * --mask-slot.
 *
 * Camera features: ExposureTime scales the photons (--photons-per-ms x
 * ms), Gain (raw, dB) divides the electrons per ADU, Width/Height/OffsetX/
 * OffsetY/Binning crop and bin the --size sensor, PixelFormat Mono16 or
 * Mono8 (others: black frames); --lost-ratio is Aravis's own
 * "gvsp-lost-ratio" (each GVSP packet dropped with that probability,
 * never resent).
 *
 * Readiness: once GVCP is listening and the first configuration's
 * simulator exists, it prints "READY ADDRESS SERIAL" on stdout and, with
 * --ready-fd FD, writes the same line to FD and closes it.  SIGTERM and
 * SIGINT stop it cleanly (exit 0).  SIGUSR1 drops the controlling host
 * (the control channel privilege goes to 0, streaming stops), as a camera
 * does whose heartbeat timeout ran out while its host was busy: the host
 * sees "control lost" at its next heartbeat and may take control again.
 */
#include <glib-unix.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "fakecam_app.h"

typedef struct opts {
    char *iface, *serial, *size, *screen_r0, *mask_slots, *stage;
    double sep_arcsec, pa_deg, dm, ratio, plate_scale, wavelength_nm;
    double wind_mps, wind_dir_deg, interval_ms;
    double photons_per_ms, read_noise_e, gain_e_per_adu, bias_adu, lost_ratio;
    gint64 seed;
    int screen_slot, mask_slot, stage_unit, stage_poll_ms, ready_fd, quiet;
} opts;

typedef struct app {
    opts o;
    ArvFakeCamera *fake;   /* while serving */
    renderer *r;
    stage_poll *stage;
    beam last;
    char last_err[SL_ERRMSG_MAX];
    GMainLoop *loop;
} app;

static void say(const app *a, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void say(const app *a, const char *fmt, ...)
{
    if (a->o.quiet)
        return;
    va_list ap;
    va_start(ap, fmt);
    fputs("specklab-fake-camera: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

/* SIGUSR1: the controller's heartbeat "ran out". */
static gboolean on_drop_control(gpointer data)
{
    app *a = data;
    say(a, "dropping the controlling host (SIGUSR1)");
    arv_fake_camera_set_control_channel_privilege(a->fake, 0);
    return G_SOURCE_CONTINUE;
}

/* The rest of the model, after fakecam_model_from_args. */
static int build_model(const opts *o, fakecam_model *m, sl_err *e)
{
    m->wavelength_m = o->wavelength_nm * 1e-9;
    m->plate_scale_arcsec = o->plate_scale > 0 ? o->plate_scale
                            : fakecam_default_plate_scale() * o->wavelength_nm / 633.0;
    m->sep_arcsec = o->sep_arcsec;
    m->pa_deg = o->pa_deg;
    m->dm = o->ratio > 0 ? -2.5 * log10(o->ratio) : o->dm;
    m->wind_mps = o->wind_mps;
    m->wind_dir_deg = o->wind_dir_deg;
    m->frame_interval_s = o->interval_ms * 1e-3;
    m->photons_per_ms = o->photons_per_ms;
    m->read_noise_e = o->read_noise_e;
    m->gain_e_per_adu = o->gain_e_per_adu;
    m->bias_adu = o->bias_adu;
    m->seed = (uint64_t)o->seed;
    if (o->ratio > 1)
        return sl_seterr(e, SL_EINVAL, "--ratio %g: the companion is the fainter (<= 1)",
                         o->ratio);
    if (!(o->photons_per_ms > 0))
        return sl_seterr(e, SL_EINVAL, "--photons-per-ms must be > 0");
    if (!(o->lost_ratio >= 0 && o->lost_ratio <= 1))
        return sl_seterr(e, SL_EINVAL, "--lost-ratio %g: expected 0..1", o->lost_ratio);
    return SL_OK;
}

static void describe(app *a, const beam *b)
{
    if (!b->known)
        say(a, "beam: stage not read yet (dark frames)");
    else if (b->moving)
        say(a, "beam: blocked (a wheel is moving, unhomed or faulted): dark frames");
    else
        say(a, "beam: screen slot %d, mask slot %d", b->screen, b->mask);
}

static gboolean poll_stage(gpointer data)
{
    app *a = data;
    beam b = a->last;
    sl_err e = {0};
    if (stage_poll_read(a->stage, &b, &e) != SL_OK) {
        if (strcmp(e.msg, a->last_err) != 0)
            say(a, "%s (keeping the last configuration)", e.msg);
        snprintf(a->last_err, sizeof a->last_err, "%s", e.msg);
        return G_SOURCE_CONTINUE;
    }
    a->last_err[0] = 0;
    if (memcmp(&b, &a->last, sizeof b) != 0) {
        renderer_set_beam(a->r, &b);
        describe(a, &b);
        a->last = b;
    }
    return G_SOURCE_CONTINUE;
}

static gboolean on_signal(gpointer data)
{
    g_main_loop_quit(((app *)data)->loop);
    return G_SOURCE_CONTINUE;
}

static void announce(const app *a)
{
    char line[512];
    snprintf(line, sizeof line, "READY %s %s\n", a->o.iface, a->o.serial);
    fputs(line, stdout);
    fflush(stdout);
    if (a->o.ready_fd >= 0) {
        size_t n = strlen(line);
        if (write(a->o.ready_fd, line, n) != (ssize_t)n)
            fprintf(stderr, "specklab-fake-camera: cannot write to --ready-fd %d\n",
                    a->o.ready_fd);
        close(a->o.ready_fd);
    }
}

static int serve(app *a, const fakecam_model *m, mask **masks, int nmasks)
{
    sl_err e = {0};
    int status = 1;
    if (renderer_new(&a->r, m, masks, nmasks, &e) != SL_OK) {
        fprintf(stderr, "specklab-fake-camera: %s\n", e.msg);
        return 1;
    }
    if (a->o.stage) {
        if (stage_poll_new(&a->stage, a->o.stage, a->o.stage_unit, &e) != SL_OK) {
            fprintf(stderr, "specklab-fake-camera: %s\n", e.msg);
            goto free_renderer;
        }
        poll_stage(a);          /* first answer (bounded) before READY */
        if (!a->last.known)
            describe(a, &a->last);
    } else {
        a->last = (beam){1, 0, a->o.screen_slot, a->o.mask_slot};
        renderer_set_beam(a->r, &a->last);
        describe(a, &a->last);
    }
    ArvGvFakeCamera *gv = arv_gv_fake_camera_new_full(a->o.iface, a->o.serial, NULL);
    if (!gv || !arv_gv_fake_camera_is_running(gv)) {
        fprintf(stderr, "specklab-fake-camera: cannot serve on %s (is UDP port 3956 in "
                "use by another camera in this network namespace?)\n", a->o.iface);
        goto free_gv;
    }
    ArvFakeCamera *fake = arv_gv_fake_camera_get_fake_camera(gv);
    /* The sensor is --size; the ROI starts as the whole sensor. */
    guint32 exposure_us = renderer_init_camera(a->r, fake);
    g_object_set(gv, "gvsp-lost-ratio", a->o.lost_ratio, NULL);
    renderer_attach(a->r, fake);
    arv_fake_camera_set_fill_pattern(fake, renderer_fill, a->r);
    if (renderer_prepare(a->r, exposure_us, 0, &e) != SL_OK) {
        fprintf(stderr, "specklab-fake-camera: %s\n", e.msg);
        goto free_gv;
    }
    a->loop = g_main_loop_new(NULL, FALSE);
    g_unix_signal_add(SIGTERM, on_signal, a);
    g_unix_signal_add(SIGINT, on_signal, a);
    a->fake = fake;
    g_unix_signal_add(SIGUSR1, on_drop_control, a);
    if (a->stage)
        g_timeout_add((guint)a->o.stage_poll_ms, poll_stage, a);
    announce(a);
    g_main_loop_run(a->loop);
    uint64_t rendered = 0, dark = 0;
    renderer_counts(a->r, &rendered, &dark);
    say(a, "stopping: %llu frames rendered, %llu dark", (unsigned long long)rendered,
        (unsigned long long)dark);
    g_main_loop_unref(a->loop);
    status = 0;
free_gv:
    if (gv)
        g_object_unref(gv);   /* joins the camera thread: no callback after */
    stage_poll_free(a->stage);
free_renderer:
    renderer_free(a->r);
    return status;
}

/* String defaults after parsing: GOption replaces a string without
 * freeing what was there. */
static void string_defaults(opts *o)
{
    o->iface = o->iface ? o->iface : g_strdup("127.0.0.1");
    o->serial = o->serial ? o->serial : g_strdup("SPECKLE01");
    o->size = o->size ? o->size : g_strdup("128x128");
    o->screen_r0 = o->screen_r0 ? o->screen_r0 : g_strdup("inf,0.25,0.15,0.10,0.07,0.05");
    o->mask_slots = o->mask_slots ? o->mask_slots : g_strdup("full,nrm17");
}

int main(int argc, char **argv)
{
    app a = {0};
    opts *o = &a.o;
    o->sep_arcsec = 0.7, o->pa_deg = 30, o->dm = 1, o->wavelength_nm = 633;
    o->wind_mps = 10, o->interval_ms = 10;
    o->photons_per_ms = 1000, o->read_noise_e = 2, o->gain_e_per_adu = 1, o->bias_adu = 100;
    o->seed = 1, o->screen_slot = 1, o->stage_unit = 1, o->stage_poll_ms = 50;
    o->ready_fd = -1;
    GOptionEntry entries[] = {
        {"interface", 'i', 0, G_OPTION_ARG_STRING, &o->iface, "address or interface to serve on (default 127.0.0.1)", "ADDR"},
        {"serial", 0, 0, G_OPTION_ARG_STRING, &o->serial, "serial number (default SPECKLE01)", "S"},
        {"size", 0, 0, G_OPTION_ARG_STRING, &o->size, "sensor size N or WxH (default 128x128)", "WxH"},
        {"seed", 0, 0, G_OPTION_ARG_INT64, &o->seed, "simulator seed (default 1)", "N"},
        {"sep-arcsec", 0, 0, G_OPTION_ARG_DOUBLE, &o->sep_arcsec, "binary separation (default 0.7, ~6 lambda/D)", "ARCSEC"},
        {"pa-deg", 0, 0, G_OPTION_ARG_DOUBLE, &o->pa_deg, "position angle, +y towards -x (default 30)", "DEG"},
        {"dm-mag", 0, 0, G_OPTION_ARG_DOUBLE, &o->dm, "companion magnitude difference (default 1)", "MAG"},
        {"ratio", 0, 0, G_OPTION_ARG_DOUBLE, &o->ratio, "companion flux ratio <= 1 (overrides --dm-mag)", "R"},
        {"wavelength-nm", 0, 0, G_OPTION_ARG_DOUBLE, &o->wavelength_nm, "laser wavelength (default 633)", "NM"},
        {"plate-scale-arcsec", 0, 0, G_OPTION_ARG_DOUBLE, &o->plate_scale, "arcsec per pixel; 0 = Nyquist for 1.1 m (default)", "ARCSEC"},
        {"screen-r0", 0, 0, G_OPTION_ARG_STRING, &o->screen_r0, "r0 [m] per screen slot, inf = open (default inf,0.25,0.15,0.10,0.07,0.05)", "LIST"},
        {"mask-slots", 0, 0, G_OPTION_ARG_STRING, &o->mask_slots, "pupil per mask slot: full, nrm17, closed (no light: bias frames) or a mask file (default full,nrm17)", "LIST"},
        {"screen-slot", 0, 0, G_OPTION_ARG_INT, &o->screen_slot, "screen slot without --stage (default 1)", "N"},
        {"mask-slot", 0, 0, G_OPTION_ARG_INT, &o->mask_slot, "mask slot without --stage (default 0)", "N"},
        {"stage", 0, 0, G_OPTION_ARG_STRING, &o->stage, "poll the stage at HOST:PORT (Modbus/TCP) for the slots", "HOST:PORT"},
        {"stage-unit", 0, 0, G_OPTION_ARG_INT, &o->stage_unit, "stage Modbus unit id (default 1)", "ID"},
        {"stage-poll-ms", 0, 0, G_OPTION_ARG_INT, &o->stage_poll_ms, "stage poll period (default 50)", "MS"},
        {"wind-mps", 0, 0, G_OPTION_ARG_DOUBLE, &o->wind_mps, "frozen-flow speed (default 10)", "M/S"},
        {"wind-dir-deg", 0, 0, G_OPTION_ARG_DOUBLE, &o->wind_dir_deg, "flow direction (default 0)", "DEG"},
        {"frame-interval-ms", 0, 0, G_OPTION_ARG_DOUBLE, &o->interval_ms, "simulated time per frame id (default 10)", "MS"},
        {"photons-per-ms", 0, 0, G_OPTION_ARG_DOUBLE, &o->photons_per_ms, "photons per frame per ms of ExposureTime (default 1000)", "N"},
        {"read-noise-e", 0, 0, G_OPTION_ARG_DOUBLE, &o->read_noise_e, "read noise, electrons rms (default 2)", "E"},
        {"gain-e-per-adu", 0, 0, G_OPTION_ARG_DOUBLE, &o->gain_e_per_adu, "electrons per ADU at Gain 0 (default 1)", "E"},
        {"bias-adu", 0, 0, G_OPTION_ARG_DOUBLE, &o->bias_adu, "bias level (default 100)", "ADU"},
        {"lost-ratio", 0, 0, G_OPTION_ARG_DOUBLE, &o->lost_ratio, "fraction of GVSP packets dropped (default 0)", "R"},
        {"ready-fd", 0, 0, G_OPTION_ARG_INT, &o->ready_fd, "write the READY line to this fd too", "FD"},
        {"quiet", 'q', 0, G_OPTION_ARG_NONE, &o->quiet, "no progress messages on stderr", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("- fake GigE Vision speckle camera");
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_set_description(ctx,
        "Frames: the binary laser star through the phase screen and mask in the beam\n"
        "(recon's simulator; mocks/camsrc/fakecam.h defines each frame exactly:\n"
        "frame id F renders simulator frame F mod 65536).  Serves GVCP on UDP 3956:\n"
        "one camera per network namespace.  Prints 'READY ADDRESS SERIAL' when serving.");
    GError *ge = NULL;
    int status = 2, nmasks = 0;
    mask *masks[FAKECAM_MAX_SLOTS] = {0};
    fakecam_model m;
    sl_err e = {0};
    if (!g_option_context_parse(ctx, &argc, &argv, &ge)) {
        fprintf(stderr, "specklab-fake-camera: %s (see --help)\n", ge->message);
        g_error_free(ge);
        goto free_opts;
    }
    if (argc > 1) {
        fprintf(stderr, "specklab-fake-camera: unexpected argument '%s'\n", argv[1]);
        goto free_opts;
    }
    string_defaults(o);
    if (fakecam_model_from_args(o->size, o->screen_r0, o->mask_slots, &m, masks, &nmasks,
                                &e) != SL_OK ||
        build_model(o, &m, &e) != SL_OK) {
        fprintf(stderr, "specklab-fake-camera: %s\n", e.msg);
        for (int i = 0; i < nmasks; i++)
            mask_free(masks[i]);
        goto free_opts;
    }
    status = serve(&a, &m, masks, nmasks);
free_opts:
    g_option_context_free(ctx);
    g_free(o->iface); g_free(o->serial); g_free(o->size); g_free(o->screen_r0);
    g_free(o->mask_slots); g_free(o->stage);
    return status;
}
