/* camtruth_fx.h - what the camera mocks (bin/specklab-fake-camera and
 * bin/specklab-fake-u3v) render, re-rendered by a test: the geometry the
 * camera tests use and the simulator built from the same fakecam_model
 * (mocks/camsrc/fakecam.h), so each frame is compared bit for bit.
 */
#ifndef SL_TEST_CAMTRUTH_FX_H
#define SL_TEST_CAMTRUTH_FX_H

#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "../../mocks/camsrc/fakecam.h"
#include "camera.h"

#define SENSOR_W 80
#define SENSOR_H 72
#define ROI_X 8
#define ROI_Y 4
#define ROI_W 64
#define ROI_H 64
#define NPX ((size_t)ROI_W * ROI_H)

typedef struct truth {
    fakecam_model m;
    mask *msk;
    scene *sc;
    sim *s;
    float sensor[SENSOR_W * SENSOR_H];
    unsigned char packed[2 * NPX];
} truth;

/* What the camera mocks render with --size 80x72 --seed 11 at screen slot
 * `screen`, mask "full", with that ExposureTime and Gain. */
static int truth_new(truth *tr, int screen, uint32_t exposure_us, uint32_t gain_db, char *err,
                     size_t n)
{
    sl_err e = {0};
    memset(tr, 0, sizeof *tr);
    fakecam_model_defaults(&tr->m);
    tr->m.sensor_w = SENSOR_W;
    tr->m.sensor_h = SENSOR_H;
    tr->m.seed = 11;
    sim_opts o;
    fakecam_sim_opts(&tr->m, screen, exposure_us, gain_db, &o);
    if (fakecam_mask("full", &tr->msk, &e) != SL_OK || fakecam_scene(&tr->m, &tr->sc, &e) != SL_OK ||
        sim_new(&tr->s, &o, tr->msk, tr->sc, &e) != SL_OK) {
        snprintf(err, n, "%s", e.msg);
        return -1;
    }
    return 0;
}

static void truth_free(truth *tr)
{
    sim_free(tr->s);
    mask_free(tr->msk);
    scene_free(tr->sc);
}

/* Pixels of the ROI frame with this id that differ from the rendering. */
static long truth_diff(truth *tr, uint64_t frame_id, const uint16_t *pix)
{
    if (sim_frame(tr->s, fakecam_frame_index(frame_id), tr->sensor) != SL_OK)
        return -1;
    fakecam_readout(tr->sensor, SENSOR_W, SENSOR_H, ROI_X, ROI_Y, ROI_W, ROI_H, 1, 1, 2,
                    tr->packed);
    long bad = 0;
    for (size_t i = 0; i < NPX; i++)
        bad += pix[i] != (tr->packed[2 * i] | tr->packed[2 * i + 1] << 8);
    return bad;
}

/* Mono16, the ROI, fps, started with nbuf buffers; -1 with the message
 * in err. */
static inline int camtruth_configure(camera *c, double fps, int nbuf, char *err, size_t n)
{
    int rc;
    if ((rc = camera_set_pixel_format(c, CAMERA_PIX_MONO16)) == SL_OK &&
        (rc = camera_set_roi(c, ROI_X, ROI_Y, ROI_W, ROI_H)) == SL_OK &&
        (rc = camera_set_frame_rate_hz(c, fps)) == SL_OK)
        rc = camera_start(c, nbuf);
    if (rc != SL_OK)
        return snprintf(err, n, "%s", camera_errmsg(c)), -1;
    return 0;
}

/* Our driver on a camera mock: open target and configure it. */
static inline int camtruth_open(camera **c, const char *target, double fps, int nbuf, char *err,
                         size_t n)
{
    sl_err e = {0};
    int rc = camera_open(c, "aravis", target, &e);
    if (rc != SL_OK)
        return snprintf(err, n, "%s", e.msg), -1;
    return camtruth_configure(*c, fps, nbuf, err, n);
}

/* Pop into frame slot k of pix (NPX pixels a slot); the driver's code,
 * its message in err when not SL_OK. */
static int camtruth_pop(camera *c, uint16_t *pix, int timeout_ms, camera_frame *f, size_t k,
                        char *err, size_t n)
{
    *f = (camera_frame){.u16 = pix + NPX * k, .capacity_px = NPX};
    int rc = camera_pop(c, timeout_ms, f);
    if (rc != SL_OK)
        snprintf(err, n, "%s", camera_errmsg(c));
    return rc;
}

#endif
