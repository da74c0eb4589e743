/* main.c - bin/specklab-fake-u3v: a USB3 Vision speckle camera in a
 * umockdev testbed.  Its registers and GenICam features are Aravis's
 * ArvFakeCamera behind the U3V bootstrap (u3v_regs.c), its USB side a
 * usbfs ioctl handler (u3v_usb.c), its frames recon's simulator through
 * the renderer the GigE fake camera uses (mocks/camsrc): frame (block)
 * id F, counted from 1, holds simulator frame F mod 65536
 * (mocks/camsrc/fakecam.h), with the screen/mask slots of --screen-slot
 * and --mask-slot (no stage polling: the beam is fixed).
 *
 * Programs see the camera when run under libumockdev-preload.so.0 with
 * UMOCKDEV_DIR set to the testbed: Aravis lists it as a U3V device and
 * opens it with ArvUvDevice; libusb's hot-plug sees it come and go.
 *
 * Readiness: prints "READY TESTBED_DIR DEVICE_NODE SERIAL" on stdout once
 * the device is in the testbed.  Commands on stdin, one per line, each
 * answered on stdout when done: "unplug" -> "UNPLUGGED", "plug" ->
 * "PLUGGED DEVICE_NODE" (a new address, as after a real re-plug).  EOF on
 * stdin, SIGTERM or SIGINT stop it (exit 0); the testbed is removed.
 */
#include <errno.h>
#include <glib-unix.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fakecam_app.h"
#include "u3v_regs.h"
#include "u3v_usb.h"

#define STREAM_MAX_UNITS 64   /* ~20 frames of leader+payload+trailer */
#define LEADER_SIZE 52
#define TRAILER_SIZE 32

typedef struct opts {
    char *serial, *size, *screen_r0, *mask_slots, *usbfs_mb;
    char *guid;   /* made from the serial */
    gint64 seed;
    int screen_slot, mask_slot, speed_mbit, node_mode, quiet;
} opts;

typedef struct app {
    opts o;
    ArvFakeCamera *fake;
    renderer *r;
    u3v_regs *regs;
    u3v_usb *usb;
    GThread *thread;
    int stop;
    guint64 sent, dropped;
    uint64_t block_id;      /* the last frame's, stream thread only; not reset
                             * by a re-plug, so ids stay unique in a test */
    fakecam_model m;
    GMainLoop *loop;
} app;

static void put16(uint8_t *p, uint32_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static void put32(uint8_t *p, uint32_t v) { put16(p, v); put16(p + 2, v >> 16); }
static void put64(uint8_t *p, uint64_t v) { put32(p, (uint32_t)v); put32(p + 4, (uint32_t)(v >> 32)); }

/* What one frame is: the features at the time it starts. */
typedef struct frame_desc {
    uint64_t id, ts_ns;
    guint32 w, h, x, y, format, exposure_us, gain;
    size_t payload;
} frame_desc;

static guint32 reg(ArvFakeCamera *fake, guint32 address)
{
    guint32 v = 0;
    arv_fake_camera_read_register(fake, address, &v);
    return v;
}

/* Power-up settings: acquisition stopped, ROI the whole --size sensor,
 * Mono16.  Also on every plug: a re-plugged camera has lost what its
 * host set (the host re-applies it). */
static void power_up(ArvFakeCamera *fake, const fakecam_model *m)
{
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_ACQUISITION, 0);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH, (guint32)m->sensor_w);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT, (guint32)m->sensor_h);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_X_OFFSET, 0);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_Y_OFFSET, 0);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, (guint32)m->sensor_w);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, (guint32)m->sensor_h);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT,
                                   ARV_PIXEL_FORMAT_MONO_16);
}

/* The U3V leader (image payload) and trailer of one frame. */
static void leader(uint8_t *b, const frame_desc *f)
{
    memset(b, 0, LEADER_SIZE);
    put32(b, 0x4C563355u);                 /* "U3VL" */
    put16(b + 6, LEADER_SIZE);
    put64(b + 8, f->id);
    put16(b + 18, 0x0001);                 /* payload type: image */
    put64(b + 20, f->ts_ns);
    put32(b + 28, f->format);
    put32(b + 32, f->w);
    put32(b + 36, f->h);
    put32(b + 40, f->x);
    put32(b + 44, f->y);
}

static void trailer(uint8_t *b, const frame_desc *f)
{
    memset(b, 0, TRAILER_SIZE);
    put32(b, 0x54563355u);                 /* "U3VT" */
    put16(b + 6, TRAILER_SIZE);
    put64(b + 8, f->id);
    put64(b + 20, f->payload);             /* valid payload size */
    put32(b + 28, f->h);
}

static int streaming(app *a)
{
    return u3v_usb_plugged(a->usb) && u3v_regs_stream_enabled(a->regs) &&
           arv_fake_camera_get_acquisition_status(a->fake);
}

/* One frame; U3V block ids are 64-bit and count from 1 per process (they
 * never wrap, unlike GigE Vision 1's 16-bit ids).  A frame that does not
 * fit the queue is dropped whole: the host sees an id gap, as with a
 * camera whose host stopped reading. */
static void send_frame(app *a, GByteArray *pixels)
{
    frame_desc f = {++a->block_id, (uint64_t)g_get_monotonic_time() * 1000u,
                    reg(a->fake, ARV_FAKE_CAMERA_REGISTER_WIDTH),
                    reg(a->fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT),
                    reg(a->fake, ARV_FAKE_CAMERA_REGISTER_X_OFFSET),
                    reg(a->fake, ARV_FAKE_CAMERA_REGISTER_Y_OFFSET),
                    reg(a->fake, ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT),
                    reg(a->fake, ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US),
                    reg(a->fake, ARV_FAKE_CAMERA_REGISTER_GAIN_RAW),
                    arv_fake_camera_get_payload(a->fake)};
    g_byte_array_set_size(pixels, (guint)f.payload);
    renderer_render(a->r, f.id, (int)f.w, (int)f.h, f.format, f.exposure_us, f.gain,
                    pixels->data, f.payload);
    if (u3v_usb_stream_queued(a->usb) + 3 > STREAM_MAX_UNITS) {
        a->dropped++;
        return;
    }
    uint8_t head[LEADER_SIZE], tail[TRAILER_SIZE];
    leader(head, &f);
    trailer(tail, &f);
    if (u3v_usb_stream_push(a->usb, head, sizeof head, STREAM_MAX_UNITS) == 0 &&
        u3v_usb_stream_push(a->usb, pixels->data, f.payload, STREAM_MAX_UNITS) == 0 &&
        u3v_usb_stream_push(a->usb, tail, sizeof tail, STREAM_MAX_UNITS) == 0)
        a->sent++;
}

static gpointer stream_main(gpointer data)
{
    app *a = data;
    GByteArray *pixels = g_byte_array_new();
    while (!g_atomic_int_get(&a->stop)) {
        if (!streaming(a)) {
            u3v_usb_stream_flush(a->usb);
            g_usleep(2000);   /* the device idles; the host's write wakes it within 2 ms */
            continue;
        }
        arv_fake_camera_wait_for_next_frame(a->fake);
        if (streaming(a))
            send_frame(a, pixels);
    }
    g_byte_array_unref(pixels);
    return NULL;
}

static void reply(const char *line)
{
    fputs(line, stdout);
    fputc('\n', stdout);
    fflush(stdout);
}

static gboolean on_stdin(GIOChannel *ch, GIOCondition cond, gpointer data)
{
    app *a = data;
    char *line = NULL;
    (void)cond;
    if (g_io_channel_read_line(ch, &line, NULL, NULL, NULL) != G_IO_STATUS_NORMAL) {
        g_main_loop_quit(a->loop);
        return G_SOURCE_REMOVE;
    }
    g_strstrip(line);
    sl_err e = {0};
    if (strcmp(line, "unplug") == 0) {
        u3v_usb_unplug(a->usb);
        reply("UNPLUGGED");
    } else if (strcmp(line, "plug") == 0) {
        if (!u3v_usb_plugged(a->usb)) {
            power_up(a->fake, &a->m);
            u3v_regs_reset(a->regs);
        }
        if (u3v_usb_plug(a->usb, &e) == SL_OK) {
            char out[128];
            snprintf(out, sizeof out, "PLUGGED %s", u3v_usb_node(a->usb));
            reply(out);
        } else {
            fprintf(stderr, "specklab-fake-u3v: %s\n", e.msg);
            reply("ERROR plug");
        }
    } else if (*line) {
        fprintf(stderr, "specklab-fake-u3v: unknown command '%s'\n", line);
        reply("ERROR unknown command");
    }
    g_free(line);
    return G_SOURCE_CONTINUE;
}

static gboolean on_signal(gpointer data)
{
    g_main_loop_quit(((app *)data)->loop);
    return G_SOURCE_CONTINUE;
}

/* The fake camera, powered up, its frames from the renderer. */
static ArvFakeCamera *make_camera(app *a, const fakecam_model *m)
{
    ArvFakeCamera *fake = arv_fake_camera_new(a->o.serial);
    power_up(fake, m);
    renderer_attach(a->r, fake);
    arv_fake_camera_set_fill_pattern(fake, renderer_fill, a->r);
    return fake;
}

static int start_device(app *a, sl_err *e)
{
    a->o.guid = g_strdup_printf("1AB2-0001-%s", a->o.serial);
    u3v_ident id = {2, 1, a->o.speed_mbit, 0x1ab2, 0x0001, "Specklab", "SpeckCam U3",
                    a->o.serial, a->o.guid, a->o.node_mode};
    int rc = u3v_regs_new(&a->regs, a->fake, id.vendor, id.model, a->o.serial, e);
    if (rc == SL_OK)
        rc = u3v_usb_new(&a->usb, a->regs, &id, e);
    if (rc == SL_OK && a->o.usbfs_mb)
        rc = u3v_usb_set_file(a->usb, "sys/module/usbcore/parameters/usbfs_memory_mb",
                              a->o.usbfs_mb, e);
    return rc;
}

/* The testbed's uevents are sent through libudev, which must see the
 * testbed's /sys: like umockdev-wrapper, run under the preload library
 * (re-executed once; a testbed made in a process without it cannot
 * announce plugs and unplugs). */
static void reexec_preloaded(char **argv)
{
    static const char lib[] = "libumockdev-preload.so.0";
    char line[1024], asan[1024] = "";
    int found = 0;
    FILE *maps = fopen("/proc/self/maps", "r");
    while (maps && fgets(line, sizeof line, maps)) {
        char *p = strchr(line, '/');
        found |= p && strstr(p, "/libumockdev-preload.so") != NULL;
        if (p && !asan[0] && strstr(p, "/libasan.so")) {   /* a sanitized build: first */
            p[strcspn(p, "\n")] = '\0';
            g_snprintf(asan, sizeof asan, "%s:", p);
        }
    }
    if (maps)
        fclose(maps);
    if (found || getenv("SPECKLAB_FAKE_U3V_REEXEC"))
        return;
    setenv("SPECKLAB_FAKE_U3V_REEXEC", "1", 1);
    const char *old = getenv("LD_PRELOAD");
    char *pre = g_strdup_printf("%s%s%s%s", asan, lib, old && *old ? ":" : "", old ? old : "");
    setenv("LD_PRELOAD", pre, 1);
    g_free(pre);
    execv("/proc/self/exe", argv);
    fprintf(stderr, "specklab-fake-u3v: cannot re-exec under %s: %s\n", lib, g_strerror(errno));
}

static int serve(app *a, const fakecam_model *m, mask **masks, int nmasks)
{
    sl_err e = {0};
    int status = 1;
    if (renderer_new(&a->r, m, masks, nmasks, &e) != SL_OK)
        goto report;
    a->m = *m;
    beam b = {1, 0, a->o.screen_slot, a->o.mask_slot};
    renderer_set_beam(a->r, &b);
    a->fake = make_camera(a, m);
    guint32 exposure_us = 0;
    arv_fake_camera_read_register(a->fake, ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US, &exposure_us);
    if (renderer_prepare(a->r, exposure_us, 0, &e) != SL_OK || start_device(a, &e) != SL_OK)
        goto free_device;
    a->thread = g_thread_new("u3v-stream", stream_main, a);
    a->loop = g_main_loop_new(NULL, FALSE);
    g_unix_signal_add(SIGTERM, on_signal, a);
    g_unix_signal_add(SIGINT, on_signal, a);
    GIOChannel *in = g_io_channel_unix_new(0);
    g_io_add_watch(in, G_IO_IN | G_IO_HUP | G_IO_ERR, on_stdin, a);
    char line[1024];
    snprintf(line, sizeof line, "READY %s %s %s", u3v_usb_root(a->usb), u3v_usb_node(a->usb),
             a->o.serial);
    reply(line);
    g_main_loop_run(a->loop);
    g_atomic_int_set(&a->stop, 1);
    g_thread_join(a->thread);
    g_io_channel_unref(in);
    g_main_loop_unref(a->loop);
    if (!a->o.quiet)
        fprintf(stderr, "specklab-fake-u3v: stopping: %llu frames sent, %llu dropped\n",
                (unsigned long long)a->sent, (unsigned long long)a->dropped);
    status = 0;
free_device:
    u3v_usb_free(a->usb);
    u3v_regs_free(a->regs);
    if (a->fake)
        g_object_unref(a->fake);
    renderer_free(a->r);
report:
    if (status)
        fprintf(stderr, "specklab-fake-u3v: %s\n", e.msg);
    return status;
}

int main(int argc, char **argv)
{
    reexec_preloaded(argv);
    app a = {0};
    opts *o = &a.o;
    o->seed = 1, o->screen_slot = 1, o->speed_mbit = 5000, o->node_mode = 0666;
    GOptionEntry entries[] = {
        {"serial", 0, 0, G_OPTION_ARG_STRING, &o->serial, "serial number (default SPECKU3V01)", "S"},
        {"size", 0, 0, G_OPTION_ARG_STRING, &o->size, "sensor size N or WxH (default 128x128)", "WxH"},
        {"seed", 0, 0, G_OPTION_ARG_INT64, &o->seed, "simulator seed (default 1)", "N"},
        {"screen-r0", 0, 0, G_OPTION_ARG_STRING, &o->screen_r0, "r0 [m] per screen slot, inf = open (default inf,0.25,0.15,0.10,0.07,0.05)", "LIST"},
        {"mask-slots", 0, 0, G_OPTION_ARG_STRING, &o->mask_slots, "pupil per mask slot: full, nrm17, closed or a mask file (default full,nrm17)", "LIST"},
        {"screen-slot", 0, 0, G_OPTION_ARG_INT, &o->screen_slot, "screen slot in the beam (default 1)", "N"},
        {"mask-slot", 0, 0, G_OPTION_ARG_INT, &o->mask_slot, "mask slot in the beam (default 0)", "N"},
        {"speed-mbit", 0, 0, G_OPTION_ARG_INT, &o->speed_mbit, "negotiated link speed in sysfs (default 5000; 480 = a USB 2 port)", "MBIT"},
        {"node-mode", 0, 0, G_OPTION_ARG_INT, &o->node_mode, "device node permissions, decimal (default 438 = 0666)", "MODE"},
        {"usbfs-memory-mb", 0, 0, G_OPTION_ARG_STRING, &o->usbfs_mb, "write this to the testbed's usbcore usbfs_memory_mb", "MB"},
        {"quiet", 'q', 0, G_OPTION_ARG_NONE, &o->quiet, "no summary on stderr", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("- fake USB3 Vision speckle camera (umockdev)");
    g_option_context_add_main_entries(ctx, entries, NULL);
    GError *ge = NULL;
    int status = 2, nmasks = 0;
    mask *masks[FAKECAM_MAX_SLOTS] = {0};
    fakecam_model m;
    sl_err e = {0};
    if (!g_option_context_parse(ctx, &argc, &argv, &ge)) {
        fprintf(stderr, "specklab-fake-u3v: %s (see --help)\n", ge->message);
        g_error_free(ge);
        goto free_opts;
    }
    o->serial = o->serial ? o->serial : g_strdup("SPECKU3V01");
    o->size = o->size ? o->size : g_strdup("128x128");
    o->screen_r0 = o->screen_r0 ? o->screen_r0 : g_strdup("inf,0.25,0.15,0.10,0.07,0.05");
    o->mask_slots = o->mask_slots ? o->mask_slots : g_strdup("full,nrm17");
    if (fakecam_model_from_args(o->size, o->screen_r0, o->mask_slots, &m, masks, &nmasks,
                                &e) != SL_OK) {
        fprintf(stderr, "specklab-fake-u3v: %s\n", e.msg);
        goto free_opts;
    }
    m.seed = (uint64_t)o->seed;
    status = serve(&a, &m, masks, nmasks);
free_opts:
    g_option_context_free(ctx);
    g_free(o->serial); g_free(o->size); g_free(o->screen_r0); g_free(o->mask_slots);
    g_free(o->usbfs_mb); g_free(o->guid);
    return status;
}
