/* fakecam.h - what the fake speckle camera renders, as a pure function.
 *
 * This header is the contract between bin/specklab-fake-camera and the
 * tests that check its pixels: both build the simulator from the same
 * fakecam_model through these functions, so a test re-renders exactly the
 * frame the camera sent (bit for bit) without sharing any other code.
 *
 * Frame content.  For a beam configuration (screen slot s, mask slot m),
 * the camera's ExposureTime e_us and raw Gain g (dB), frame id F is
 *     k      = fakecam_frame_index(F) = F mod 65536
 *     sensor = sim_frame(sim(model, s, m, e_us, g), k)     (sensor-sized)
 *     pixels = fakecam_readout(sensor, ROI, binning, format)
 * where sim(...) is sim_new(fakecam_sim_opts(...), mask m, fakecam_scene).
 * GigE Vision 1 block ids run 1..65535 (0 is skipped on wrap), so k runs
 * 1..65535 and the sequence of frames repeats every 65535 frames.  The
 * simulator is deterministic given (options, seed, k) and the FFTW plans
 * are made with FFTW_ESTIMATE (FFTW_MEASURE picks plans by timing, which
 * can change the last bits between processes).
 *
 * Physics and photometry (see sim.h): the scene is a binary of two point
 * sources at 633 nm; screen slot s has Fried parameter r0_m[s] (INFINITY:
 * an open slot, no turbulence) and its own phase screen (seed + 7919 s),
 * the same glass whatever the mask; frozen flow moves it wind_mps *
 * frame_interval_s per frame id.  Photons per frame = photons_per_ms *
 * exposure in ms; Poisson and Gaussian read noise; ADU = e- / gain with
 * gain = gain_e_per_adu * 10^(-g/20) (more camera gain, fewer e- per
 * ADU); plus bias, clipped to 65535 before readout.
 *
 * Readout: output pixel (x, y) is the sum of the bin_x x bin_y sensor
 * pixels from (x0 + x bin_x, y0 + y bin_y) (sensor pixels outside the
 * sensor count 0), clipped to 255 (Mono8) or 65535 (Mono16, written
 * little-endian).  x0, y0 are OffsetX/OffsetY in sensor pixels.
 */
#ifndef SL_FAKECAM_H
#define SL_FAKECAM_H

#include <fftw3.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "sim/mask.h"
#include "sim/scene.h"
#include "sim/sim.h"

#define FAKECAM_MAX_SLOTS 16
#define FAKECAM_ARCSEC_PER_RAD (180.0 * 3600.0 / 3.14159265358979323846)
/* Screen size: sim_new sizes its phase screen for nframes of travel; 64
 * keeps that small (a 512^2 screen at most, ~20 ms to make) and frames
 * beyond it still work (the screen's periodic part wraps seamlessly). */
#define FAKECAM_SIM_NFRAMES 64

typedef struct fakecam_model {
    int sensor_w, sensor_h;       /* sensor pixels */
    double wavelength_m;          /* 633 nm, the laser */
    double plate_scale_arcsec;    /* arcsec per sensor pixel */
    double sep_arcsec, pa_deg, dm; /* the binary */
    double wind_mps, wind_dir_deg;
    double frame_interval_s;      /* simulated time per frame id */
    double photons_per_ms;        /* photons per frame per ms of exposure */
    double read_noise_e, gain_e_per_adu, bias_adu;
    uint64_t seed;
    int n_screens;
    double r0_m[FAKECAM_MAX_SLOTS]; /* per screen slot; INFINITY = open */
} fakecam_model;

/* Nyquist for the 1.1 m outer extent of the built-in pupils at 633 nm:
 * 633e-9 / 2.2 rad = 0.0593 arcsec per pixel. */
static inline double fakecam_default_plate_scale(void)
{
    return 633e-9 / (2 * 1.1) * FAKECAM_ARCSEC_PER_RAD;
}

/* The defaults of bin/specklab-fake-camera's flags. */
static inline void fakecam_model_defaults(fakecam_model *m)
{
    static const double r0[] = {INFINITY, 0.25, 0.15, 0.10, 0.07, 0.05};
    memset(m, 0, sizeof *m);
    m->sensor_w = m->sensor_h = 128;
    m->wavelength_m = 633e-9;
    m->plate_scale_arcsec = fakecam_default_plate_scale();
    m->sep_arcsec = 0.7;   /* ~6 lambda/D for D = 1.1 m: 12 pixels */
    m->pa_deg = 30;
    m->dm = 1;
    m->wind_mps = 10;
    m->wind_dir_deg = 0;
    m->frame_interval_s = 0.01;
    m->photons_per_ms = 1000;
    m->read_noise_e = 2;
    m->gain_e_per_adu = 1;
    m->bias_adu = 100;
    m->seed = 1;
    m->n_screens = (int)(sizeof r0 / sizeof r0[0]);
    for (int i = 0; i < m->n_screens; i++)
        m->r0_m[i] = r0[i];
}

static inline int fakecam_frame_index(uint64_t frame_id)
{
    return (int)(frame_id & 0xFFFFu);
}

/* Simulator options for screen slot s (0 <= s < n_screens). */
static inline void fakecam_sim_opts(const fakecam_model *m, int s,
                                    uint32_t exposure_us, uint32_t gain_db,
                                    sim_opts *o)
{
    sim_opts_defaults(o);
    o->width = m->sensor_w;
    o->height = m->sensor_h;
    o->nframes = FAKECAM_SIM_NFRAMES;
    o->wavelength_m = m->wavelength_m;
    o->plate_scale_arcsec = m->plate_scale_arcsec;
    o->turbulence = isfinite(m->r0_m[s]) ? 1 : 0;
    o->r0_m = o->turbulence ? m->r0_m[s] : 0.2;
    o->L0_m = INFINITY;
    o->wind_mps = m->wind_mps;
    o->wind_dir_deg = m->wind_dir_deg;
    o->frame_interval_s = m->frame_interval_s;
    o->exposure_s = exposure_us * 1e-6;
    o->seed = m->seed + 7919u * (uint64_t)s;
    o->photons_per_frame = m->photons_per_ms * (exposure_us / 1000.0);
    o->read_noise_e = m->read_noise_e;
    o->gain_e_per_adu = m->gain_e_per_adu * pow(10.0, -(double)gain_db / 20.0);
    o->bias_adu = m->bias_adu;
    o->saturation_adu = 65535;
    o->fftw_flags = FFTW_ESTIMATE;
}

static inline int fakecam_scene(const fakecam_model *m, scene **out, sl_err *err)
{
    return scene_binary(out, m->sep_arcsec, m->pa_deg, m->dm, err);
}

/* A mask slot entry: a built-in name ("full", "nrm17") or a mask file. */
/* "closed": a blank slot, *out NULL: no light reaches the sensor (the
 * bench's darks); the frames are the bias (render.c). */
static inline int fakecam_mask(const char *name, mask **out, sl_err *err)
{
    if (strcmp(name, "closed") == 0) {
        *out = NULL;
        return SL_OK;
    }
    if (strcmp(name, "full") == 0 || strcmp(name, "nrm17") == 0)
        return mask_named(out, name, err);
    return mask_read(out, name, err);
}

/* Crop, bin, clip and pack: bytes_pp 1 (Mono8) or 2 (Mono16, LE). */
static inline void fakecam_readout(const float *sensor, int sw, int sh,
                                   int x0, int y0, int w, int h, int bx, int by,
                                   int bytes_pp, unsigned char *dst)
{
    double top = bytes_pp == 1 ? 255 : 65535;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double sum = 0;
            for (int j = 0; j < by; j++) {
                int sy = y0 + y * by + j;
                for (int i = 0; i < bx && sy < sh; i++) {
                    int sx = x0 + x * bx + i;
                    if (sx < sw)
                        sum += sensor[(size_t)sy * sw + sx];
                }
            }
            unsigned v = (unsigned)(sum > top ? top : sum < 0 ? 0 : sum);
            size_t o = (size_t)y * w + x;
            if (bytes_pp == 1) {
                dst[o] = (unsigned char)v;
            } else {
                dst[2 * o] = (unsigned char)(v & 0xFF);
                dst[2 * o + 1] = (unsigned char)(v >> 8);
            }
        }
}

#endif
