/* camera.c - the backend-independent half of the camera interface:
 * backend lookup, argument and range checks, remembered settings, frame
 * counting and names.
 *
 * Frame accounting lives here, not in the backends, so that "every buffer
 * returned is counted exactly once, completed or failed" holds for any
 * backend: camera_pop is the only place a buffer reaches the caller.
 * Settings are checked against camera_caps (one capability read per
 * setter: a few control round trips) and remembered, so that a reconnect
 * re-applies them whatever the backend.
 */
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera.h"

/* Settings made through the interface, for camera_reconnect. */
typedef struct want {
    int roi, bin, fmt, exp, gain, fps, trig, beat;  /* which are set */
    int beat_ms;
    int x, y, w, h, bx, by;
    camera_pixfmt pixfmt;
    double exp_us, gain_db, fps_hz;
    camera_trigger trigger;
} want;

struct camera {
    const camera_backend *be;
    void *st;              /* backend state */
    sl_err err;
    int started, nbuffers;
    want w;
    char target[CAMERA_STR_MAX];
    camera_stats counted;  /* completed, failed, by_status, timeouts,
                              reconnects: this file's counters */
    camera_source src;     /* a simulated sensor's pixels (fake backend) */
    void *src_lib;         /* dlopen handle of src's library, or NULL */
};

static const camera_backend *const backends[] = {&camera_backend_aravis,
                                                 &camera_backend_fake, NULL};

const camera_backend *const *camera_backends(void)
{
    return backends;
}

const camera_backend *camera_backend_find(const char *name)
{
    if (!name || !name[0])
        return backends[0];
    for (int i = 0; backends[i]; i++)
        if (strcmp(backends[i]->name, name) == 0)
            return backends[i];
    return NULL;
}

static int unknown_backend(sl_err *err, const char *name)
{
    return sl_seterr(err, SL_EINVAL, "unknown camera backend '%s' (known: aravis, fake)",
                     name);
}

int camera_list(const char *backend, camera_info **out, int *n, sl_err *err)
{
    const camera_backend *be = camera_backend_find(backend);
    if (!out || !n)
        return sl_seterr(err, SL_EINVAL, "camera_list: NULL output");
    *out = NULL;
    *n = 0;
    if (!be)
        return unknown_backend(err, backend);
    return be->list(out, n, err);
}

int camera_open(camera **out, const char *backend, const char *id_or_address,
                sl_err *err)
{
    const camera_backend *be = camera_backend_find(backend);
    if (!out)
        return sl_seterr(err, SL_EINVAL, "camera_open: NULL output");
    *out = NULL;
    if (!be)
        return unknown_backend(err, backend);
    if (!id_or_address || !id_or_address[0])
        return sl_seterr(err, SL_EINVAL, "camera: no id or address given");
    if (strlen(id_or_address) >= CAMERA_STR_MAX)
        return sl_seterr(err, SL_EINVAL, "camera: id or address longer than %d characters",
                         CAMERA_STR_MAX - 1);
    camera *c = calloc(1, sizeof *c);
    if (!c)
        return sl_seterr(err, SL_ENOMEM, "camera %s: out of memory", id_or_address);
    c->be = be;
    snprintf(c->target, sizeof c->target, "%s", id_or_address);
    int rc = be->open(&c->st, id_or_address, err);
    if (rc != SL_OK) {
        free(c);
        return rc;
    }
    *out = c;
    return SL_OK;
}

void camera_close(camera *c)
{
    if (!c)
        return;
    if (c->started)
        c->be->stop(c->st, &c->err);
    /* The device (and its stream thread, which calls the source) goes
     * first; then the source and its library. */
    c->be->close(c->st);
    if (c->src.release)
        c->src.release(c->src.data);
    if (c->src_lib)
        dlclose(c->src_lib);
    free(c);
}

int camera_set_source(camera *c, const camera_source *src)
{
    if (!src || !src->attach)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: a source needs attach", c->target);
    if (!c->be->set_source)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: the %s backend has no simulated "
                         "sensor to feed", c->target, c->be->name);
    int rc = c->be->set_source(c->st, src, &c->err);
    if (rc != SL_OK)
        return rc;
    if (c->src.release)
        c->src.release(c->src.data);
    c->src = *src;
    return SL_OK;
}

int camera_load_source(camera *c, const char *path, const char *args)
{
    if (!path || !path[0])
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: no source library given", c->target);
    if (!c->be->set_source)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: the %s backend has no simulated "
                         "sensor to feed", c->target, c->be->name);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib)
        return sl_seterr(&c->err, SL_EIO, "camera %s: source %s: %s", c->target, path,
                         dlerror());
    /* POSIX's way from a data pointer to a function pointer. */
    camera_source_entry entry;
    *(void **)&entry = dlsym(lib, CAMERA_SOURCE_ENTRY);
    if (!entry) {
        dlclose(lib);
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: %s exports no %s", c->target, path,
                         CAMERA_SOURCE_ENTRY);
    }
    camera_source src = {0};
    int rc = entry(args ? args : "", &src, &c->err);
    if (rc == SL_OK && (rc = camera_set_source(c, &src)) != SL_OK && src.release)
        src.release(src.data);
    if (rc != SL_OK) {
        dlclose(lib);
        return rc;
    }
    /* The previous library's source was released by camera_set_source. */
    if (c->src_lib)
        dlclose(c->src_lib);
    c->src_lib = lib;
    return SL_OK;
}

const char *camera_errmsg(const camera *c)
{
    return c ? c->err.msg : "camera: NULL handle";
}

const char *camera_target(const camera *c)
{
    return c ? c->target : "";
}

int camera_info_get(camera *c, camera_info *out)
{
    if (!out)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: NULL output", c->target);
    return c->be->info(c->st, out, &c->err);
}

int camera_caps_get(camera *c, camera_caps *out)
{
    if (!out)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: NULL output", c->target);
    return c->be->caps(c->st, out, &c->err);
}

int camera_config_get(camera *c, camera_config *out)
{
    if (!out)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: NULL output", c->target);
    return c->be->get_config(c->st, out, &c->err);
}

/* Geometry and format decide the buffer size: the pool is allocated at
 * start, so they may not change under a running stream. */
static int refuse_started(camera *c, const char *what)
{
    return sl_seterr(&c->err, SL_EINVAL, "camera %s: cannot change %s while acquiring "
                     "(camera_stop first)", c->target, what);
}

static int get_caps(camera *c, camera_caps *cp)
{
    return c->be->caps(c->st, cp, &c->err);
}

static int check_range(camera *c, const char *what, double v, double lo, double hi,
                       const char *unit)
{
    if (isnan(lo))
        return sl_seterr(&c->err, SL_ERANGE, "camera %s: the camera has no settable %s",
                         c->target, what);
    if (v < lo || v > hi)
        return sl_seterr(&c->err, SL_ERANGE, "camera %s: %s %g %s outside the camera's "
                         "range %g..%g %s", c->target, what, v, unit, lo, hi, unit);
    return SL_OK;
}

int camera_set_roi(camera *c, int x, int y, int width, int height)
{
    camera_caps cp;
    int rc;
    if (c->started)
        return refuse_started(c, "the ROI");
    if (x < 0 || y < 0 || width <= 0 || height <= 0)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: bad ROI %d,%d,%dx%d (need x, y >= 0 "
                         "and a positive size)", c->target, x, y, width, height);
    if ((rc = get_caps(c, &cp)) != SL_OK)
        return rc;
    if (x + width > cp.sensor_width || y + height > cp.sensor_height)
        return sl_seterr(&c->err, SL_ERANGE, "camera %s: ROI %d,%d,%dx%d exceeds the %dx%d "
                         "sensor", c->target, x, y, width, height, cp.sensor_width,
                         cp.sensor_height);
    if ((rc = c->be->set_roi(c->st, x, y, width, height, &c->err)) == SL_OK)
        c->w.roi = 1, c->w.x = x, c->w.y = y, c->w.w = width, c->w.h = height;
    return rc;
}

int camera_set_binning(camera *c, int bin_x, int bin_y)
{
    camera_caps cp;
    int rc;
    if (c->started)
        return refuse_started(c, "binning");
    if (bin_x < 1 || bin_y < 1)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: bad binning %dx%d", c->target,
                         bin_x, bin_y);
    if ((rc = get_caps(c, &cp)) != SL_OK)
        return rc;
    if (bin_x > cp.binning_max || bin_y > cp.binning_max)
        return sl_seterr(&c->err, SL_ERANGE, "camera %s: binning %dx%d beyond the camera's "
                         "%d", c->target, bin_x, bin_y, cp.binning_max);
    if ((rc = c->be->set_binning(c->st, bin_x, bin_y, &c->err)) == SL_OK)
        c->w.bin = 1, c->w.bx = bin_x, c->w.by = bin_y;
    return rc;
}

int camera_set_pixel_format(camera *c, camera_pixfmt f)
{
    camera_caps cp;
    int rc;
    if (c->started)
        return refuse_started(c, "the pixel format");
    if (f != CAMERA_PIX_MONO8 && f != CAMERA_PIX_MONO16)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: pixel format must be Mono8 or "
                         "Mono16", c->target);
    if ((rc = get_caps(c, &cp)) != SL_OK)
        return rc;
    if (!(cp.pixel_formats & CAMERA_PIXF(f)))
        return sl_seterr(&c->err, SL_ERANGE, "camera %s: pixel format %s not offered by the "
                         "camera", c->target, camera_pixfmt_name(f));
    if ((rc = c->be->set_pixel_format(c->st, f, &c->err)) == SL_OK)
        c->w.fmt = 1, c->w.pixfmt = f;
    return rc;
}

int camera_set_exposure_us(camera *c, double exposure_us)
{
    camera_caps cp;
    int rc;
    if (!(exposure_us > 0))
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: exposure must be > 0 us",
                         c->target);
    if ((rc = get_caps(c, &cp)) == SL_OK &&
        (rc = check_range(c, "exposure", exposure_us, cp.exposure_min_us, cp.exposure_max_us,
                          "us")) == SL_OK &&
        (rc = c->be->set_exposure_us(c->st, exposure_us, &c->err)) == SL_OK)
        c->w.exp = 1, c->w.exp_us = exposure_us;
    return rc;
}

int camera_set_gain_db(camera *c, double gain_db)
{
    camera_caps cp;
    int rc;
    if (isnan(gain_db))
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: gain is NaN", c->target);
    if ((rc = get_caps(c, &cp)) == SL_OK &&
        (rc = check_range(c, "gain", gain_db, cp.gain_min_db, cp.gain_max_db, "dB")) == SL_OK &&
        (rc = c->be->set_gain_db(c->st, gain_db, &c->err)) == SL_OK)
        c->w.gain = 1, c->w.gain_db = gain_db;
    return rc;
}

int camera_set_frame_rate_hz(camera *c, double frame_rate_hz)
{
    camera_caps cp;
    int rc;
    if (!(frame_rate_hz > 0))
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: frame rate must be > 0 Hz",
                         c->target);
    if ((rc = get_caps(c, &cp)) == SL_OK &&
        (rc = check_range(c, "frame rate", frame_rate_hz, cp.frame_rate_min_hz,
                          cp.frame_rate_max_hz, "Hz")) == SL_OK &&
        (rc = c->be->set_frame_rate_hz(c->st, frame_rate_hz, &c->err)) == SL_OK)
        c->w.fps = 1, c->w.fps_hz = frame_rate_hz;
    return rc;
}

int camera_set_trigger(camera *c, camera_trigger mode)
{
    int rc;
    if (mode != CAMERA_TRIGGER_FREE_RUN && mode != CAMERA_TRIGGER_SOFTWARE &&
        mode != CAMERA_TRIGGER_HARDWARE)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: unknown trigger mode %d",
                         c->target, (int)mode);
    if ((rc = c->be->set_trigger(c->st, mode, &c->err)) == SL_OK)
        c->w.trig = 1, c->w.trigger = mode;
    return rc;
}

int camera_trigger_software(camera *c)
{
    return c->be->trigger_software(c->st, &c->err);
}

int camera_start(camera *c, int nbuffers)
{
    if (c->started)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: already acquiring", c->target);
    if (nbuffers == 0)
        nbuffers = 16;
    if (nbuffers < 2 || nbuffers > 1024)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: %d buffers (need 2..1024)",
                         c->target, nbuffers);
    int rc = c->be->start(c->st, nbuffers, &c->err);
    if (rc == SL_OK)
        c->started = 1, c->nbuffers = nbuffers;
    return rc;
}

int camera_pop(camera *c, int timeout_ms, camera_frame *out)
{
    if (!out || (!out->u16 == !out->f32))
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: camera_pop needs exactly one of "
                         "u16 / f32", c->target);
    if (!c->started)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: not acquiring (camera_start "
                         "first)", c->target);
    if (timeout_ms < 0)
        timeout_ms = 0;
    int rc = c->be->pop(c->st, timeout_ms, out, &c->err);
    if (rc == CAMERA_ETIMEOUT)
        c->counted.timeouts++;
    if (rc != SL_OK && rc != SL_ERANGE)
        return rc;
    /* SL_ERANGE: a good frame that did not fit the caller's buffer; the
     * backend has set SIZE_MISMATCH, so it counts as failed below. */
    camera_frame_status s = out->status;
    if ((unsigned)s >= CAMERA_FRAME_NSTATUS)
        s = out->status = CAMERA_FRAME_UNKNOWN;
    c->counted.by_status[s]++;
    if (s == CAMERA_FRAME_SUCCESS)
        c->counted.completed++;
    else
        c->counted.failed++;
    return rc;
}

int camera_stop(camera *c)
{
    if (!c->started)
        return SL_OK;
    c->started = 0;
    return c->be->stop(c->st, &c->err);
}

int camera_is_started(const camera *c)
{
    return c->started;
}

void camera_stats_get(const camera *c, camera_stats *out)
{
    *out = c->counted;
    camera_stats t = {0};
    c->be->stats(c->st, &t);
    out->missing_packets = t.missing_packets;
    out->resent_packets = t.resent_packets;
    out->underruns = t.underruns;
    out->id_gaps = t.id_gaps;
}

/* Settings in the order cameras accept them: format and binning change
 * the ROI limits, the ROI changes the frame-rate limit. */
static int reapply(camera *c)
{
    want w = c->w;
    int rc = SL_OK;
    if (rc == SL_OK && w.fmt)
        rc = camera_set_pixel_format(c, w.pixfmt);
    if (rc == SL_OK && w.bin)
        rc = camera_set_binning(c, w.bx, w.by);
    if (rc == SL_OK && w.roi)
        rc = camera_set_roi(c, w.x, w.y, w.w, w.h);
    if (rc == SL_OK && w.exp)
        rc = camera_set_exposure_us(c, w.exp_us);
    if (rc == SL_OK && w.gain)
        rc = camera_set_gain_db(c, w.gain_db);
    if (rc == SL_OK && w.fps)
        rc = camera_set_frame_rate_hz(c, w.fps_hz);
    if (rc == SL_OK && w.trig)
        rc = camera_set_trigger(c, w.trigger);
    if (rc == SL_OK && w.beat)
        rc = camera_set_heartbeat_ms(c, w.beat_ms);
    return rc;
}

int camera_set_heartbeat_ms(camera *c, int ms)
{
    if (ms < 100 || ms > 600000)
        return sl_seterr(&c->err, SL_ERANGE, "camera %s: heartbeat timeout %d ms outside "
                         "100..600000", c->target, ms);
    int rc = c->be->set_heartbeat_ms(c->st, ms, &c->err);
    if (rc == SL_OK)
        c->w.beat = 1, c->w.beat_ms = ms;
    return rc;
}

int camera_heartbeat_ms(camera *c, int *ms)
{
    if (!ms)
        return sl_seterr(&c->err, SL_EINVAL, "camera %s: NULL output", c->target);
    return c->be->get_heartbeat_ms(c->st, ms, &c->err);
}

int camera_check(camera *c)
{
    return c->be->check(c->st, 0, &c->err);
}

int camera_probe(camera *c)
{
    return c->be->check(c->st, 1, &c->err);
}

int camera_reconnect(camera *c, int timeout_ms)
{
    int was_started = c->started;
    if (timeout_ms < 0)
        timeout_ms = 0;
    c->started = 0;   /* the backend drops the stream with the old device */
    int rc = c->be->reconnect(c->st, timeout_ms, &c->err);
    if (rc == SL_OK)
        rc = reapply(c);
    if (rc == SL_OK && was_started)
        rc = camera_start(c, c->nbuffers);
    if (rc == SL_OK)
        c->counted.reconnects++;
    return rc;
}

const char *camera_pixfmt_name(camera_pixfmt f)
{
    switch (f) {
    case CAMERA_PIX_MONO8: return "Mono8";
    case CAMERA_PIX_MONO16: return "Mono16";
    case CAMERA_PIX_MONO10: return "Mono10";
    case CAMERA_PIX_MONO12: return "Mono12";
    default: return "unknown";
    }
}

camera_pixfmt camera_pixfmt_parse(const char *name)
{
    static const camera_pixfmt all[] = {CAMERA_PIX_MONO8, CAMERA_PIX_MONO16,
                                        CAMERA_PIX_MONO10, CAMERA_PIX_MONO12};
    for (size_t i = 0; name && i < sizeof all / sizeof all[0]; i++)
        if (strcmp(name, camera_pixfmt_name(all[i])) == 0)
            return all[i];
    return CAMERA_PIX_UNKNOWN;
}

int camera_pixfmt_bytes(camera_pixfmt f)
{
    switch (f) {
    case CAMERA_PIX_MONO8: return 1;
    case CAMERA_PIX_MONO16:
    case CAMERA_PIX_MONO10:
    case CAMERA_PIX_MONO12: return 2;
    default: return 0;
    }
}

const char *camera_frame_status_name(camera_frame_status s)
{
    static const char *const names[CAMERA_FRAME_NSTATUS] = {
        "SUCCESS", "MISSING_PACKETS", "TIMEOUT", "SIZE_MISMATCH", "ABORTED",
        "WRONG_PACKET_ID", "CLEARED", "FILLING", "FORMAT", "UNKNOWN"};
    return (unsigned)s < CAMERA_FRAME_NSTATUS ? names[s] : "UNKNOWN";
}

const char *camera_trigger_name(camera_trigger t)
{
    switch (t) {
    case CAMERA_TRIGGER_FREE_RUN: return "free-run";
    case CAMERA_TRIGGER_SOFTWARE: return "software";
    case CAMERA_TRIGGER_HARDWARE: return "hardware";
    default: return "unknown";
    }
}
