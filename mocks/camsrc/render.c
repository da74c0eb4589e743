/* render.c - the fake camera's fill-pattern callback: speckle frames from
 * recon's simulator for the configuration the stage has in the beam.
 *
 * Threads: Aravis calls renderer_fill from the fake camera's one thread,
 * which also answers GVCP, so a slow frame delays control replies; the
 * main thread only sets the beam (under lock) and, before streaming
 * starts, may call renderer_prepare.  Simulators are created and used
 * only under cache_lock, so the FFTW planner (not thread-safe) never runs
 * in two threads at once.
 *
 * Cache: one simulator per (screen slot, mask slot, exposure, gain),
 * made lazily (sim_new plans FFTs and makes a phase screen: ~10-50 ms for
 * 64..256 pixel sensors) and kept; FAKECAM_CACHE entries, least recently
 * used evicted.  Memory per entry is a few sensor-sized FFT buffers plus
 * the screen (<= 512^2 floats with FAKECAM_SIM_NFRAMES frames of travel).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fakecam_app.h"

#define FAKECAM_CACHE 4

typedef struct cache_entry {
    int used;
    int screen, mask;
    uint32_t exposure_us, gain;
    uint64_t last_use;
    sim *s;
} cache_entry;

struct renderer {
    fakecam_model m;
    mask *masks[FAKECAM_MAX_SLOTS];
    int nmasks;
    scene *sc;
    ArvFakeCamera *fake;
    GMutex beam_lock;
    beam beam;
    GMutex cache_lock;       /* cache, sensor, counters, planner */
    cache_entry cache[FAKECAM_CACHE];
    uint64_t clock;
    float *sensor;           /* sensor_w x sensor_h ADU */
    uint64_t rendered, dark;
    char last_error[SL_ERRMSG_MAX];
};

int renderer_new(renderer **out, const fakecam_model *m, mask **masks,
                 int nmasks, sl_err *err)
{
    *out = NULL;
    renderer *r = calloc(1, sizeof *r);
    int rc = SL_ENOMEM;
    if (!r)
        goto free_masks;
    r->m = *m;
    r->sensor = malloc(sizeof(float) * (size_t)m->sensor_w * (size_t)m->sensor_h);
    if (!r->sensor) {
        free(r);
        goto free_masks;
    }
    for (int i = 0; i < nmasks; i++)
        r->masks[i] = masks[i];
    r->nmasks = nmasks;
    g_mutex_init(&r->beam_lock);
    g_mutex_init(&r->cache_lock);
    if ((rc = fakecam_scene(m, &r->sc, err)) != SL_OK) {
        renderer_free(r);
        return rc;
    }
    *out = r;
    return SL_OK;
free_masks:
    for (int i = 0; i < nmasks; i++)
        mask_free(masks[i]);
    return sl_seterr(err, rc, "out of memory");
}

void renderer_free(renderer *r)
{
    if (!r)
        return;
    for (int i = 0; i < FAKECAM_CACHE; i++)
        sim_free(r->cache[i].s);
    for (int i = 0; i < r->nmasks; i++)
        mask_free(r->masks[i]);
    scene_free(r->sc);
    free(r->sensor);
    g_mutex_clear(&r->beam_lock);
    g_mutex_clear(&r->cache_lock);
    free(r);
}

void renderer_attach(renderer *r, ArvFakeCamera *fake)
{
    r->fake = fake;
}

guint32 renderer_init_camera(const renderer *r, ArvFakeCamera *fake)
{
    guint32 w = (guint32)r->m.sensor_w, h = (guint32)r->m.sensor_h, exposure_us = 0;
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_WIDTH, w);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_SENSOR_HEIGHT, h);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_WIDTH, w);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_HEIGHT, h);
    arv_fake_camera_write_register(fake, ARV_FAKE_CAMERA_REGISTER_PIXEL_FORMAT,
                                   ARV_PIXEL_FORMAT_MONO_16);
    arv_fake_camera_read_register(fake, ARV_FAKE_CAMERA_REGISTER_EXPOSURE_TIME_US, &exposure_us);
    return exposure_us;
}

void renderer_set_beam(renderer *r, const beam *b)
{
    g_mutex_lock(&r->beam_lock);
    r->beam = *b;
    g_mutex_unlock(&r->beam_lock);
}

static beam current_beam(renderer *r)
{
    g_mutex_lock(&r->beam_lock);
    beam b = r->beam;
    g_mutex_unlock(&r->beam_lock);
    return b;
}

/* The simulator for this configuration, made if needed.  Caller holds
 * cache_lock.  NULL (message in err) when it cannot be made. */
static sim *get_sim(renderer *r, const beam *b, uint32_t exposure_us, uint32_t gain,
                    sl_err *err)
{
    if (b->screen < 0 || b->screen >= r->m.n_screens || b->mask < 0 ||
        b->mask >= r->nmasks) {
        sl_seterr(err, SL_ERANGE, "slot screen %d / mask %d has no configuration "
                  "(%d screens, %d masks given)", b->screen, b->mask, r->m.n_screens,
                  r->nmasks);
        return NULL;
    }
    if (!r->masks[b->mask])
        return NULL;   /* a closed slot: dark, and no error */
    cache_entry *victim = &r->cache[0];
    for (int i = 0; i < FAKECAM_CACHE; i++) {
        cache_entry *e = &r->cache[i];
        if (e->used && e->screen == b->screen && e->mask == b->mask &&
            e->exposure_us == exposure_us && e->gain == gain) {
            e->last_use = ++r->clock;
            return e->s;
        }
        if (!e->used || (victim->used && e->last_use < victim->last_use))
            victim = e;
    }
    sim_opts o;
    fakecam_sim_opts(&r->m, b->screen, exposure_us, gain, &o);
    sim *s = NULL;
    if (sim_new(&s, &o, r->masks[b->mask], r->sc, err) != SL_OK)
        return NULL;
    sim_free(victim->s);
    *victim = (cache_entry){1, b->screen, b->mask, exposure_us, gain, ++r->clock, s};
    return s;
}

int renderer_prepare(renderer *r, uint32_t exposure_us, uint32_t gain, sl_err *err)
{
    beam b = current_beam(r);
    if (!b.known || b.moving)
        return SL_OK;
    g_mutex_lock(&r->cache_lock);
    sim *s = get_sim(r, &b, exposure_us, gain, err);
    g_mutex_unlock(&r->cache_lock);
    return s ? SL_OK : err->code;
}

static void render_dark(renderer *r)
{
    size_t n = (size_t)r->m.sensor_w * r->m.sensor_h;
    float v = (float)nearbyint(r->m.bias_adu);
    for (size_t i = 0; i < n; i++)
        r->sensor[i] = v;
    r->dark++;
}

static guint32 reg(renderer *r, guint32 address, guint32 fallback)
{
    guint32 v = fallback;
    if (r->fake && !arv_fake_camera_read_register(r->fake, address, &v))
        v = fallback;
    return v;
}

void renderer_fill(ArvBuffer *buffer, void *data, guint32 exposure_us,
                   guint32 gain, ArvPixelFormat pixel_format)
{
    renderer *r = data;
    if (!buffer || !r->fake)
        return;
    /* arv_buffer_get_data reports size 0 inside the callback: the payload
     * comes from the fake camera, which sized the buffer from it. */
    unsigned char *dst = (unsigned char *)arv_buffer_get_data(buffer, NULL);
    if (dst)
        renderer_render(r, arv_buffer_get_frame_id(buffer), arv_buffer_get_image_width(buffer),
                        arv_buffer_get_image_height(buffer), pixel_format, exposure_us, gain,
                        dst, arv_fake_camera_get_payload(r->fake));
}

void renderer_render(renderer *r, uint64_t frame_id, int w, int h, ArvPixelFormat pixel_format,
                     uint32_t exposure_us, uint32_t gain, unsigned char *dst, size_t payload)
{
    int bpp = pixel_format == ARV_PIXEL_FORMAT_MONO_8 ? 1
              : pixel_format == ARV_PIXEL_FORMAT_MONO_16 ? 2 : 0;
    if (w <= 0 || h <= 0)
        return;
    if (bpp == 0 || (size_t)w * h * bpp > payload) {
        memset(dst, 0, payload);   /* formats we do not render: black */
        return;
    }
    int x0 = (int)reg(r, ARV_FAKE_CAMERA_REGISTER_X_OFFSET, 0);
    int y0 = (int)reg(r, ARV_FAKE_CAMERA_REGISTER_Y_OFFSET, 0);
    int bx = (int)reg(r, ARV_FAKE_CAMERA_REGISTER_BINNING_HORIZONTAL, 1);
    int by = (int)reg(r, ARV_FAKE_CAMERA_REGISTER_BINNING_VERTICAL, 1);
    bx = bx < 1 ? 1 : bx;
    by = by < 1 ? 1 : by;
    beam b = current_beam(r);
    int k = fakecam_frame_index(frame_id);
    g_mutex_lock(&r->cache_lock);
    sl_err err = {0};
    sim *s = b.known && !b.moving ? get_sim(r, &b, exposure_us, gain, &err) : NULL;
    if (s && sim_frame(s, k, r->sensor) == SL_OK) {
        r->rendered++;
    } else {
        if (err.msg[0] && strcmp(err.msg, r->last_error) != 0) {
            fprintf(stderr, "specklab camera mock: dark frames: %s\n", err.msg);
            snprintf(r->last_error, sizeof r->last_error, "%s", err.msg);
        }
        render_dark(r);
    }
    fakecam_readout(r->sensor, r->m.sensor_w, r->m.sensor_h, x0, y0, w, h, bx, by,
                    bpp, dst);
    g_mutex_unlock(&r->cache_lock);
}

void renderer_counts(renderer *r, uint64_t *rendered, uint64_t *dark)
{
    g_mutex_lock(&r->cache_lock);
    *rendered = r->rendered;
    *dark = r->dark;
    g_mutex_unlock(&r->cache_lock);
}
