/* camera_aravis.c - the "aravis" camera backend, device half: GigE
 * Vision and USB3 Vision cameras through Aravis 0.8 (listing, opening,
 * identity, capabilities, settings, reconnect).  The acquisition half is
 * camera_aravis_stream.c.
 *
 * Control lost: ArvDevice emits "control-lost" from its heartbeat thread
 * when the camera stops answering; the handler only sets an atomic flag,
 * which pop and the setters test before touching the camera.
 *
 * Value checks against the capabilities, and re-applying settings after
 * a reconnect, are camera.c's: the setters here only talk to Aravis.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera_aravis.h"

/* Turn a GError into "camera ADDR: DOING: what it means (Aravis: msg)";
 * frees ge.  The code tells the caller what to do next. */
int arvcam_fail(sl_err *err, const arvcam *a, const char *doing, GError *ge)
{
    int code = SL_EIO;
    const char *hint = "error";
    if (ge && ge->domain == ARV_DEVICE_ERROR) {
        switch (ge->code) {
        case ARV_DEVICE_ERROR_NOT_FOUND:
            code = CAMERA_ENODEV;
            hint = "no reply (is it powered, and on this network at this address?)";
            break;
        case ARV_DEVICE_ERROR_TIMEOUT:
            code = CAMERA_ETIMEOUT;
            hint = "no reply in time";
            break;
        case ARV_DEVICE_ERROR_NOT_CONTROLLER:
            hint = "another application controls the camera";
            break;
        case ARV_DEVICE_ERROR_FEATURE_NOT_FOUND:
        case ARV_DEVICE_ERROR_WRONG_FEATURE:
            code = SL_ERANGE;
            hint = "the camera lacks this feature";
            break;
        case ARV_DEVICE_ERROR_NOT_CONNECTED:
        case ARV_DEVICE_ERROR_TRANSFER_ERROR:
            hint = "link error";
            break;
        case ARV_DEVICE_ERROR_GENICAM_NOT_FOUND:
            hint = "no GenICam description";
            break;
        default:
            break;
        }
    }
    sl_seterr(err, code, "camera %s: %s: %s (Aravis: %s)", a->target, doing, hint,
              ge ? ge->message : "unknown error");
    if (ge)
        g_error_free(ge);
    return code;
}

int arvcam_lost(sl_err *err, const arvcam *a)
{
    return sl_seterr(err, CAMERA_ELOST, "camera %s: camera control lost (no heartbeat "
                     "reply); camera_reconnect when it is back", a->target);
}

static void on_control_lost(ArvDevice *dev, gpointer data)
{
    (void)dev;
    g_atomic_int_set(&((arvcam *)data)->lost, 1);
}

static void copy_str(char *dst, size_t n, const char *src)
{
    snprintf(dst, n, "%s", src ? src : "");
}

/* ---- listing and opening ------------------------------------------------ */

static int arv_list(camera_info **out, int *n, sl_err *err)
{
    arv_update_device_list();
    unsigned count = arv_get_n_devices();
    if (count == 0)
        return SL_OK;
    camera_info *v = calloc(count, sizeof *v);
    if (!v)
        return sl_seterr(err, SL_ENOMEM, "camera list: out of memory");
    for (unsigned i = 0; i < count; i++) {
        const char *addr = arv_get_device_address(i);
        copy_str(v[i].id, sizeof v[i].id, arv_get_device_id(i));
        copy_str(v[i].vendor, sizeof v[i].vendor, arv_get_device_vendor(i));
        copy_str(v[i].model, sizeof v[i].model, arv_get_device_model(i));
        copy_str(v[i].serial, sizeof v[i].serial, arv_get_device_serial_nbr(i));
        copy_str(v[i].address, sizeof v[i].address,
                 addr ? addr : arv_get_device_physical_id(i));
        copy_str(v[i].protocol, sizeof v[i].protocol, arv_get_device_protocol(i));
    }
    *out = v;
    *n = (int)count;
    return SL_OK;
}

/* Drop stream and camera (statistics folded in); the state stays. */
static void teardown(arvcam *a)
{
    arvcam_drop_stream(a);
    if (a->cam) {
        if (a->lost_handler)
            g_signal_handler_disconnect(a->dev, a->lost_handler);
        a->lost_handler = 0;
        a->dev = NULL;
        g_clear_object(&a->cam);
    }
}

/* arv_camera_new takes an address straight to the device (GVCP unicast)
 * and anything else through discovery (id, physical id, vendor-serial). */
static int connect_camera(arvcam *a, sl_err *err)
{
    GError *ge = NULL;
    ArvCamera *cam = arv_camera_new(a->target, &ge);
    if (!cam)
        return arvcam_fail(err, a, "open", ge);
    a->cam = cam;
    a->dev = arv_camera_get_device(cam);
    g_atomic_int_set(&a->lost, 0);
    a->lost_handler = g_signal_connect(a->dev, "control-lost",
                                       G_CALLBACK(on_control_lost), a);
    int rc = arvcam_fake_attach(a, err);
    if (rc != SL_OK)
        teardown(a);
    return rc;
}

int arvcam_open_target(void **st, const char *target, int fake, sl_err *err)
{
    arvcam *a = g_new0(arvcam, 1);
    copy_str(a->target, sizeof a->target, target);
    a->fake = fake;
    int rc = connect_camera(a, err);
    if (rc != SL_OK) {
        g_free(a);
        return rc;
    }
    *st = a;
    return SL_OK;
}

static int arv_open(void **st, const char *target, sl_err *err)
{
    return arvcam_open_target(st, target, 0, err);
}

static void arv_close(void *st)
{
    arvcam *a = st;
    if (a->acquiring && a->cam && !g_atomic_int_get(&a->lost))
        arv_camera_stop_acquisition(a->cam, NULL);
    teardown(a);
    g_free(a);
}

static int arv_info(void *st, camera_info *out, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    memset(out, 0, sizeof *out);
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    copy_str(out->vendor, sizeof out->vendor, arv_camera_get_vendor_name(a->cam, &ge));
    if (!ge)
        copy_str(out->model, sizeof out->model, arv_camera_get_model_name(a->cam, &ge));
    if (!ge)
        copy_str(out->serial, sizeof out->serial,
                 arv_camera_get_device_serial_number(a->cam, &ge));
    if (!ge)
        copy_str(out->id, sizeof out->id, arv_camera_get_device_id(a->cam, &ge));
    if (ge)
        return arvcam_fail(err, a, "read identity", ge);
    copy_str(out->address, sizeof out->address, a->target);
    if (arv_camera_is_gv_device(a->cam)) {
        copy_str(out->protocol, sizeof out->protocol, "GigEVision");
        GSocketAddress *sa = arv_gv_device_get_device_address(ARV_GV_DEVICE(a->dev));
        if (G_IS_INET_SOCKET_ADDRESS(sa)) {
            char *s = g_inet_address_to_string(
                g_inet_socket_address_get_address(G_INET_SOCKET_ADDRESS(sa)));
            copy_str(out->address, sizeof out->address, s);
            g_free(s);
        }
    } else if (arv_camera_is_uv_device(a->cam)) {
        copy_str(out->protocol, sizeof out->protocol, "USB3Vision");
    } else if (ARV_IS_FAKE_DEVICE(a->dev)) {
        copy_str(out->protocol, sizeof out->protocol, "Fake");
    }
    return SL_OK;
}

/* ---- capabilities and settings ------------------------------------------ */

camera_pixfmt arvcam_pixfmt(ArvPixelFormat f)
{
    if (f == ARV_PIXEL_FORMAT_MONO_8) return CAMERA_PIX_MONO8;
    if (f == ARV_PIXEL_FORMAT_MONO_16) return CAMERA_PIX_MONO16;
    if (f == ARV_PIXEL_FORMAT_MONO_10) return CAMERA_PIX_MONO10;
    if (f == ARV_PIXEL_FORMAT_MONO_12) return CAMERA_PIX_MONO12;
    return CAMERA_PIX_UNKNOWN;
}

static int arv_caps(void *st, camera_caps *c, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    memset(c, 0, sizeof *c);
    c->gain_min_db = c->gain_max_db = NAN;
    c->frame_rate_min_hz = c->frame_rate_max_hz = NAN;
    c->binning_max = 1;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    arv_camera_get_sensor_size(a->cam, &c->sensor_width, &c->sensor_height, &ge);
    if (ge)
        return arvcam_fail(err, a, "read the sensor size", ge);
    guint n = 0;
    gint64 *fmts = arv_camera_dup_available_pixel_formats(a->cam, &n, &ge);
    if (ge)
        return arvcam_fail(err, a, "read the pixel formats", ge);
    for (guint i = 0; i < n; i++) {
        camera_pixfmt f = arvcam_pixfmt((ArvPixelFormat)fmts[i]);
        if (f != CAMERA_PIX_UNKNOWN)
            c->pixel_formats |= CAMERA_PIXF(f);
    }
    g_free(fmts);
    arv_camera_get_exposure_time_bounds(a->cam, &c->exposure_min_us, &c->exposure_max_us,
                                        &ge);
    if (ge)
        return arvcam_fail(err, a, "read the exposure range", ge);
    if (arv_camera_is_gain_available(a->cam, NULL)) {
        arv_camera_get_gain_bounds(a->cam, &c->gain_min_db, &c->gain_max_db, &ge);
        if (ge)
            return arvcam_fail(err, a, "read the gain range", ge);
    }
    if (arv_camera_is_frame_rate_available(a->cam, NULL)) {
        arv_camera_get_frame_rate_bounds(a->cam, &c->frame_rate_min_hz,
                                         &c->frame_rate_max_hz, &ge);
        if (ge)
            return arvcam_fail(err, a, "read the frame-rate range", ge);
    }
    if (arv_camera_is_binning_available(a->cam, NULL)) {
        gint lo = 1, hi = 1;
        arv_camera_get_x_binning_bounds(a->cam, &lo, &hi, NULL);
        c->binning_max = hi > 1 ? hi : 1;
    }
    c->software_trigger = arv_camera_is_software_trigger_supported(a->cam, NULL) ? 1 : 0;
    return SL_OK;
}

static int arv_get_config(void *st, camera_config *o, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    memset(o, 0, sizeof *o);
    o->bin_x = o->bin_y = 1;
    o->gain_db = o->frame_rate_hz = NAN;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    arv_camera_get_region(a->cam, &o->x, &o->y, &o->width, &o->height, &ge);
    if (!ge && arv_camera_is_binning_available(a->cam, NULL))
        arv_camera_get_binning(a->cam, &o->bin_x, &o->bin_y, &ge);
    if (!ge)
        o->pixel_format = arvcam_pixfmt(arv_camera_get_pixel_format(a->cam, &ge));
    if (!ge)
        o->exposure_us = arv_camera_get_exposure_time(a->cam, &ge);
    if (!ge && arv_camera_is_gain_available(a->cam, NULL))
        o->gain_db = arv_camera_get_gain(a->cam, &ge);
    if (ge)
        return arvcam_fail(err, a, "read the settings", ge);
    if (arv_camera_is_frame_rate_available(a->cam, NULL))
        o->frame_rate_hz = arv_camera_get_frame_rate(a->cam, NULL);
    if (a->trigger_set) {
        o->trigger = a->trigger;
    } else {
        const char *mode = arv_camera_get_string(a->cam, "TriggerMode", NULL);
        const char *src = arv_camera_get_string(a->cam, "TriggerSource", NULL);
        if (mode && strcmp(mode, "On") == 0)
            o->trigger = src && strcmp(src, "Software") == 0 ? CAMERA_TRIGGER_SOFTWARE
                                                             : CAMERA_TRIGGER_HARDWARE;
    }
    return SL_OK;
}

/* The setters are thin: camera.c has checked the value against
 * camera_caps and remembers it for reconnects. */
static int arv_set_roi(void *st, int x, int y, int w, int h, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    arv_camera_set_region(a->cam, x, y, w, h, &ge);
    if (ge)
        return arvcam_fail(err, a, "set the ROI", ge);
    /* Cameras round to their increments silently: say so. */
    int rx, ry, rw, rh;
    arv_camera_get_region(a->cam, &rx, &ry, &rw, &rh, &ge);
    if (ge)
        return arvcam_fail(err, a, "read back the ROI", ge);
    if (rx != x || ry != y || rw != w || rh != h)
        return sl_seterr(err, SL_ERANGE, "camera %s: ROI %d,%d,%dx%d became %d,%d,%dx%d "
                         "(width step %d, height step %d)", a->target, x, y, w, h, rx, ry,
                         rw, rh, arv_camera_get_width_increment(a->cam, NULL),
                         arv_camera_get_height_increment(a->cam, NULL));
    return SL_OK;
}

static int arv_set_binning(void *st, int bx, int by, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    if (!arv_camera_is_binning_available(a->cam, NULL))
        return bx == 1 && by == 1 ? SL_OK
                                  : sl_seterr(err, SL_ERANGE, "camera %s: the camera cannot "
                                              "bin", a->target);
    arv_camera_set_binning(a->cam, bx, by, &ge);
    return ge ? arvcam_fail(err, a, "set the binning", ge) : SL_OK;
}

static int arv_set_pixel_format(void *st, camera_pixfmt f, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    arv_camera_set_pixel_format(a->cam, f == CAMERA_PIX_MONO8 ? ARV_PIXEL_FORMAT_MONO_8
                                                               : ARV_PIXEL_FORMAT_MONO_16,
                                &ge);
    return ge ? arvcam_fail(err, a, "set the pixel format", ge) : SL_OK;
}

static int arv_set_exposure_us(void *st, double us, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    arv_camera_set_exposure_time(a->cam, us, &ge);
    return ge ? arvcam_fail(err, a, "set the exposure", ge) : SL_OK;
}

static int arv_set_gain_db(void *st, double db, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    arv_camera_set_gain(a->cam, db, &ge);
    return ge ? arvcam_fail(err, a, "set the gain", ge) : SL_OK;
}

static int arv_set_frame_rate_hz(void *st, double hz, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    arv_camera_set_frame_rate(a->cam, hz, &ge);
    return ge ? arvcam_fail(err, a, "set the frame rate", ge) : SL_OK;
}

static int arv_set_trigger(void *st, camera_trigger mode, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    if (mode == CAMERA_TRIGGER_FREE_RUN) {
        arv_camera_clear_triggers(a->cam, &ge);
    } else if (mode == CAMERA_TRIGGER_SOFTWARE) {
        arv_camera_set_trigger(a->cam, "Software", &ge);
    } else {
        guint n = 0;
        const char **src = arv_camera_dup_available_trigger_sources(a->cam, &n, &ge);
        const char *line = NULL;
        for (guint i = 0; !ge && i < n && !line; i++)
            if (strcmp(src[i], "Software") != 0)
                line = src[i];
        if (!ge && !line) {
            g_free(src);
            return sl_seterr(err, SL_ERANGE, "camera %s: no hardware trigger line",
                             a->target);
        }
        if (!ge)
            arv_camera_set_trigger(a->cam, line, &ge);
        g_free(src);
    }
    if (ge)
        return arvcam_fail(err, a, "set the trigger mode", ge);
    a->trigger = mode;
    a->trigger_set = 1;
    return SL_OK;
}

static int arv_trigger_software(void *st, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    arv_camera_software_trigger(a->cam, &ge);
    return ge ? arvcam_fail(err, a, "software trigger", ge) : SL_OK;
}

/* Re-open the same target; camera.c re-applies the settings and restarts
 * the stream.  Each attempt blocks for as long as Aravis takes to give up
 * on an absent camera (~2.5 s), so the call returns within timeout_ms
 * plus one attempt.  Between attempts: 100 ms doubling to 1 s. */
static int arv_reconnect(void *st, int timeout_ms, sl_err *err)
{
    arvcam *a = st;
    gint64 deadline = g_get_monotonic_time() + (gint64)timeout_ms * 1000;
    gint64 backoff_us = 100000;
    sl_err last = {0};
    teardown(a);
    a->resuming = a->acquiring;
    a->acquiring = 0;
    a->trigger_set = 0;
    for (int attempt = 1;; attempt++) {
        int rc = connect_camera(a, &last);
        if (rc == SL_OK)
            return SL_OK;
        gint64 left = deadline - g_get_monotonic_time();
        if (left <= 0)
            return sl_seterr(err, rc, "camera %s: not back after %d ms (%d attempts); last "
                             "error: %s", a->target, timeout_ms, attempt, last.msg);
        g_usleep((gulong)MIN(backoff_us, left));
        backoff_us = MIN(backoff_us * 2, 1000000);
    }
}

/* GigE Vision's bootstrap register Heartbeat Timeout [ms]: every GigE
 * Vision camera has it (GevHeartbeatTimeout in GenICam terms); USB3
 * Vision has no heartbeat. */
#define GV_HEARTBEAT_TIMEOUT_REG 0x0938

static int arv_set_heartbeat_ms(void *st, int ms, sl_err *err)
{
    arvcam *a = st;
    GError *ge = NULL;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    if (!arv_camera_is_gv_device(a->cam))
        return SL_OK;
    arv_device_write_register(a->dev, GV_HEARTBEAT_TIMEOUT_REG, (guint32)ms, &ge);
    return ge ? arvcam_fail(err, a, "set the heartbeat timeout", ge) : SL_OK;
}

/* A GigE Vision bootstrap register; *v = 0 and SL_OK on a USB3 Vision
 * camera, which has none of them. */
static int gv_read(arvcam *a, guint32 reg, guint32 *v, const char *doing, sl_err *err)
{
    GError *ge = NULL;
    *v = 0;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    if (!arv_camera_is_gv_device(a->cam))
        return SL_OK;
    arv_device_read_register(a->dev, reg, v, &ge);
    return ge ? arvcam_fail(err, a, doing, ge) : SL_OK;
}

static int arv_get_heartbeat_ms(void *st, int *ms, sl_err *err)
{
    guint32 v = 0;
    int rc = gv_read(st, GV_HEARTBEAT_TIMEOUT_REG, &v, "read the heartbeat timeout", err);
    *ms = (int)v;
    return rc;
}

/* GigE Vision's bootstrap register Control Channel Privilege: bit 1
 * control, bit 0 exclusive; a camera that restarted (or whose heartbeat
 * timeout ran out) reads 0.  The heartbeat thread reads the same. */
#define GV_CCP_REG 0x0A00
#define GV_CCP_HELD 0x3u

/* Aravis clears its controller flag when the heartbeat sees the control
 * go, and never sets it when the open could not take control (another
 * host holds it): either way streaming would be refused. */
static int arv_check(void *st, int probe, sl_err *err)
{
    arvcam *a = st;
    guint32 v = 0;
    int rc;
    if (g_atomic_int_get(&a->lost))
        return arvcam_lost(err, a);
    if (!arv_camera_is_gv_device(a->cam))
        return SL_OK;
    if (!arv_gv_device_is_controller(ARV_GV_DEVICE(a->dev)))
        return sl_seterr(err, CAMERA_ELOST, "camera %s: this host does not control the "
                         "camera (another application does, or it restarted)", a->target);
    if (!probe)
        return SL_OK;
    if ((rc = gv_read(a, GV_CCP_REG, &v, "read the control privilege", err)) != SL_OK)
        return rc;
    if (!(v & GV_CCP_HELD)) {
        g_atomic_int_set(&a->lost, 1);   /* as the heartbeat would, a period later */
        return sl_seterr(err, CAMERA_ELOST, "camera %s: the camera names no controller "
                         "(it restarted, or dropped this host)", a->target);
    }
    return SL_OK;
}

/* "aravis" and "fake" differ only in which devices they open. */
#define ARVCAM_SHARED_OPS                                                    \
    .close = arv_close, .info = arv_info, .caps = arv_caps,                  \
    .get_config = arv_get_config, .set_roi = arv_set_roi,                    \
    .set_binning = arv_set_binning, .set_pixel_format = arv_set_pixel_format, \
    .set_exposure_us = arv_set_exposure_us, .set_gain_db = arv_set_gain_db,  \
    .set_frame_rate_hz = arv_set_frame_rate_hz, .set_trigger = arv_set_trigger, \
    .trigger_software = arv_trigger_software, .start = arvcam_start,         \
    .pop = arvcam_pop, .stop = arvcam_stop, .stats = arvcam_stats,           \
    .reconnect = arv_reconnect, .set_heartbeat_ms = arv_set_heartbeat_ms,    \
    .get_heartbeat_ms = arv_get_heartbeat_ms, .check = arv_check

const camera_backend camera_backend_aravis = {
    .name = "aravis",
    .summary = "GigE Vision and USB3 Vision cameras (Aravis 0.8)",
    .list = arv_list,
    .open = arv_open,
    ARVCAM_SHARED_OPS,
};

const camera_backend camera_backend_fake = {
    .name = "fake",
    .summary = "Aravis's in-process fake camera (tests; no network)",
    .list = arvcam_fake_list,
    .open = arvcam_fake_open,
    .set_source = arvcam_set_source,
    ARVCAM_SHARED_OPS,
};
