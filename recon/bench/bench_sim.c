/* bench_sim.c - the benchmark's simulated data sets (bench.h): the
 * simulator's own code paths (sim.h, detector.h) into a cube as `specklab
 * sim` writes it, or as a camera would (blind) with the truth in a
 * sidecar; the gain a camera's operator would pick; the truth read back. */
#include "bench.h"
#include "sim/sim_file.h"

#include <fftw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "io/cube.h"
#include "sim/mask.h"
#include "sim/scene.h"
#include "sim/sim.h"

#define RAD_ARCSEC 206264.80624709636

void bench_sim_defaults(bench_sim *s)
{
    memset(s, 0, sizeof *s);
    s->scene = "binary";
    s->width = s->height = 128;
    s->nframes = 100;
    s->sep_lod = 6;
    s->pa_deg = 30;
    s->dm_mag = 1;
    s->seed = 1;
    s->r0_m = 0.2;
    s->wind_mps = 10;
    s->saturation_adu = 1e9;
}

/* INSTRUME of a blind cube: a camera, as `specklab sim --blind` says. */
#define BLIND_INSTRUME "CMOS camera"
/* Frames the gain pilot renders: enough speckle patterns that the
 * brightest is near the sequence's, few enough to cost a fraction of the
 * cube's own simulation (one more sim_new, 16 frames). */
#define PILOT_FRAMES 16

static const char *mask_label(const bench_sim *b)
{
    return b->mask ? b->mask : "nrm17";
}

/* The keywords of features beyond the paper's model: all of them for a
 * blind cube's sidecar, else only those in use (older headers unchanged). */
static void realism_header(const sim *s, int all, cube_meta *md)
{
    const sim_opts *o = sim_options(s);
    if (o->photons_per_frame > 0 && (all || o->read_noise_e > 0 || o->bias_adu != 0)) {
        cube_meta_set_num(md, "SIMRDN", o->read_noise_e, "[e-] read noise rms");
        cube_meta_set_num(md, "SIMBIAS", o->bias_adu, "[adu] bias");
    }
    if (all || o->adc_bits)
        cube_meta_set_num(md, "SIMADC", o->adc_bits, "ADC bits, 0 = no converter limit");
    if (all || o->hot_pixels)
        cube_meta_set_num(md, "SIMNHOT", o->hot_pixels, "hot pixels");
    if (all || o->dead_pixels)
        cube_meta_set_num(md, "SIMNDEAD", o->dead_pixels, "dead pixels (0 adu)");
    if (all || o->offset_x_px != 0 || o->offset_y_px != 0) {
        cube_meta_set_num(md, "SIMOFFX", o->offset_x_px, "[px] scene offset, x");
        cube_meta_set_num(md, "SIMOFFY", o->offset_y_px, "[px] scene offset, y");
    }
    if (all || o->jitter_px > 0)
        cube_meta_set_num(md, "SIMJITT", o->jitter_px, "[px] tip-tilt jitter rms per axis");
    if (all || o->phase_model != SIM_PHASE_SCREEN)
        cube_meta_set_str(md, "SIMPHMOD", o->phase_model == SIM_PHASE_PISTON ?
                          "piston" : "screen", "phase model");
}

/* The header `specklab sim` would write, for the keywords we read back. */
static void sim_header(const bench_sim *b, const sim *s, double lod_px,
                       double sep_arcsec, cube_meta *md)
{
    const sim_opts *o = sim_options(s);
    cube_meta_init(md);
    snprintf(md->instrume, sizeof md->instrume, "specklab-bench");
    snprintf(md->object, sizeof md->object, "%s", b->scene);
    snprintf(md->bunit, sizeof md->bunit, "%s",
             o->photons_per_frame > 0 ? "adu" : "relative flux");
    md->exptime_s = o->exposure_s;
    md->plate_scale_arcsec = sim_plate_scale_arcsec(s);
    md->wavelength_m = o->wavelength_m;
    cube_meta_set_str(md, "SIMSCENE", b->scene, "scene");
    cube_meta_set_str(md, "SIMMASK", mask_label(b), "pupil mask");
    cube_meta_set_num(md, "MASKEXT", sim_pupil_extent_m(s), "[m] pupil outer extent");
    if (b->obstruction > 0)
        cube_meta_set_num(md, "MASKOBS", b->obstruction, "central obstruction / diameter");
    cube_meta_set_num(md, "NYQUIST", sim_nyquist_arcsec(s), "[arcsec/px] Nyquist");
    cube_meta_set_num(md, "LODPX", lod_px, "[px] lambda/D, D = mask extent");
    cube_meta_set_num(md, "SIMR0", o->r0_m, "[m] Fried parameter");
    cube_meta_set_num(md, "SIMWIND", o->wind_mps, "[m/s] frozen-flow speed");
    cube_meta_set_num(md, "SIMDT", o->frame_interval_s, "[s] frame interval");
    cube_meta_set_num(md, "SIMSEED", (double)o->seed, "random seed");
    cube_meta_set_num(md, "SIMPHOT", o->photons_per_frame, "mean photons/frame, 0 = noiseless");
    if (o->photons_per_frame > 0) {
        cube_meta_set_num(md, "SIMGAIN", o->gain_e_per_adu, "[e-/adu] gain");
        cube_meta_set_num(md, "SIMSAT", o->saturation_adu, "[adu] saturation");
    }
    if (strcmp(b->scene, "binary") == 0) {
        cube_meta_set_num(md, "BINSEP", sep_arcsec, "[arcsec] binary separation");
        cube_meta_set_num(md, "BINSEPPX", sep_arcsec / sim_plate_scale_arcsec(s),
                          "[px] binary separation");
        cube_meta_set_num(md, "BINPA", b->pa_deg, "[deg] PA from +y (N) to -x (E)");
        cube_meta_set_num(md, "BINDM", b->dm_mag, "[mag] companion dm");
    }
    realism_header(s, b->blind, md);
    if (b->bad_frames > 0)
        cube_meta_set_num(md, "SIMBAD", b->bad_frames,
                          "frames emptied, and as many saturated");
}

/* An injected bad frame: empty (all zero) or saturated (x 20, clipped
 * at the frame's own peak). */
static void spoil(float *f, size_t n, int saturated)
{
    float mx = 0;
    for (size_t i = 0; i < n; i++)
        mx = f[i] > mx ? f[i] : mx;
    for (size_t i = 0; i < n; i++)
        f[i] = !saturated ? 0.0f : f[i] * 20 < mx ? f[i] * 20 : mx;
}

/* Frames into path, then (with_truth) TRUTH and COPHASED.  bad > 0:
 * frames 5, 15, 25, ... alternately emptied and saturated, bad of each. */
static int write_frames(sim *s, const char *path, const cube_meta *md,
                        int bad, int with_truth, float *buf, sl_err *err)
{
    const sim_opts *o = sim_options(s);
    cube_writer *w = NULL;
    int rc = cube_writer_open(&w, path, o->width, o->height,
                              sim_output_bitpix(s), md, err);
    if (rc != SL_OK)
        return rc;
    for (int k = 0; k < o->nframes && rc == SL_OK; k++) {
        if ((rc = sim_frame(s, k, buf)) != SL_OK)
            sl_seterr(err, rc, "frame %d: %s", k, sim_errmsg(s));
        else if (k % 10 == 5 && k / 10 < 2 * bad)
            spoil(buf, (size_t)o->width * o->height, (k / 10) % 2);
        if (rc == SL_OK && (rc = cube_writer_append(w, buf)) != SL_OK)
            sl_seterr(err, rc, "%s: frame %d: %s", path, k, cube_writer_errmsg(w));
    }
    if (rc == SL_OK && with_truth)
        rc = sim_file_add_truth(s, w, buf, err);
    if (rc == SL_OK && (rc = cube_writer_close(w)) != SL_OK)
        sl_seterr(err, rc, "%s", cube_writer_errmsg(w));
    cube_writer_free(w);
    return rc;
}

static void sim_options_of(const bench_sim *b, sim_opts *o)
{
    sim_opts_defaults(o);
    o->width = b->width;
    o->height = b->height;
    o->nframes = b->nframes;
    if (b->wavelength_m > 0)
        o->wavelength_m = b->wavelength_m;
    o->photons_per_frame = b->photons;
    o->seed = b->seed;
    o->plate_scale_arcsec = b->plate_scale_arcsec;
    o->r0_m = b->r0_m > 0 ? b->r0_m : 0.2;
    o->wind_mps = b->wind_mps;
    if (b->frame_interval_s > 0)
        o->frame_interval_s = b->frame_interval_s;
    if (b->exposure_s > 0)
        o->exposure_s = b->exposure_s;
    o->saturation_adu = b->saturation_adu > 0 ? b->saturation_adu : 1e9;
    o->read_noise_e = b->read_noise_e;
    if (b->gain_e_per_adu > 0)
        o->gain_e_per_adu = b->gain_e_per_adu;
    o->bias_adu = b->bias_adu;
    o->adc_bits = b->adc_bits;
    o->hot_pixels = b->hot_pixels;
    o->dead_pixels = b->dead_pixels;
    o->offset_x_px = b->offset_x_px;
    o->offset_y_px = b->offset_y_px;
    o->jitter_px = b->jitter_px;
    o->phase_model = b->phase_model;
    o->fftw_flags = FFTW_ESTIMATE;
}

static int load_mask(const bench_sim *b, mask **m, sl_err *err)
{
    if (!strcmp(mask_label(b), "full")) {
        *m = mask_new_full_obstructed(b->aperture_m > 0 ? b->aperture_m : 1.1,
                                      b->obstruction, err);
        return *m ? SL_OK : err ? err->code : SL_EINVAL;
    }
    if (b->aperture_m > 0 || b->obstruction > 0)
        return sl_seterr(err, SL_EINVAL, "bench_sim: aperture_m and "
                         "obstruction describe a filled aperture: use them "
                         "with mask \"full\", not \"%s\"", mask_label(b));
    return mask_named(m, mask_label(b), err);
}

/* The simulator for b; pilot: noiseless, no detector, at most
 * PILOT_FRAMES frames.  *lod_arcsec: lambda / mask extent; *sep_arcsec:
 * the binary's separation. */
static int make_sim(const bench_sim *b, int pilot, sim **out,
                    double *lod_arcsec, double *sep_arcsec, sl_err *err)
{
    mask *m = NULL;
    scene *sc = NULL;
    sim_opts o;
    sim_options_of(b, &o);
    if (pilot) {
        o.photons_per_frame = 0;
        o.adc_bits = o.hot_pixels = o.dead_pixels = 0;
        o.nframes = o.nframes < PILOT_FRAMES ? o.nframes : PILOT_FRAMES;
    }
    int rc = load_mask(b, &m, err);
    if (rc != SL_OK)
        return rc;
    *lod_arcsec = o.wavelength_m / mask_extent_m(m) * RAD_ARCSEC;
    if (!(o.plate_scale_arcsec > 0) && b->sampling_nyq > 0)
        o.plate_scale_arcsec = *lod_arcsec / 2 * b->sampling_nyq;
    else if (!(o.plate_scale_arcsec > 0) && b->oversample > 1)
        o.plate_scale_arcsec = *lod_arcsec / 2 / b->oversample; /* Nyquist / k */
    *sep_arcsec = b->sep_arcsec > 0 ? b->sep_arcsec : b->sep_lod * *lod_arcsec;
    rc = scene_named(&sc, b->scene, *sep_arcsec, b->pa_deg, b->dm_mag, err);
    if (rc == SL_OK)
        rc = sim_new(out, &o, m, sc, err);
    scene_free(sc);
    mask_free(m);
    return rc;
}

/* The camera's header: nothing a camera could not know. */
static void camera_header(const sim *s, cube_meta *md)
{
    cube_meta_init(md);
    snprintf(md->instrume, sizeof md->instrume, "%s", BLIND_INSTRUME);
    md->exptime_s = sim_options(s)->exposure_s;
}

int bench_sim_write(const bench_sim *b, const char *cube_path,
                    const char *psf_path, sl_err *err)
{
    sim *s = NULL;
    double lod_arcsec, sep_arcsec;
    int rc = make_sim(b, 0, &s, &lod_arcsec, &sep_arcsec, err);
    if (rc != SL_OK)
        return rc;
    const sim_opts *o = sim_options(s);
    float *buf = malloc(sizeof(float) * (size_t)o->width * (size_t)o->height);
    char *side = b->blind ? sim_file_sidecar_path(cube_path) : NULL;
    cube_meta *md = malloc(sizeof *md), *cam = malloc(sizeof *cam);
    if (!buf || !md || !cam || (b->blind && !side)) {
        rc = sl_seterr(err, SL_ENOMEM, "out of memory");
        goto free_all;
    }
    sim_header(b, s, lod_arcsec / sim_plate_scale_arcsec(s), sep_arcsec, md);
    if (b->blind) {
        camera_header(s, cam);
        if ((rc = write_frames(s, cube_path, cam, b->bad_frames, 0, buf,
                               err)) == SL_OK) {
            snprintf(md->bunit, sizeof md->bunit, "relative flux");
            rc = sim_file_write_sidecar(s, side, md, buf, err);
        }
    } else {
        rc = write_frames(s, cube_path, md, b->bad_frames, 1, buf, err);
    }
    if (rc == SL_OK && psf_path) {
        seq img = {o->width, o->height, 1, buf};
        rc = cube_write(psf_path, &img, md, err);
    }
free_all:
    free(buf);
    free(side);
    free(md);
    free(cam);
    sim_free(s);
    return rc;
}

int bench_sim_fit_gain(bench_sim *b, double fill, double *peak_adu,
                       sl_err *err)
{
    if (peak_adu)
        *peak_adu = NAN;
    if (!(b->photons > 0))
        return SL_OK;
    double full = b->saturation_adu > 0 ? b->saturation_adu : 1e9;
    if (b->adc_bits > 0 && b->adc_bits <= 24)
        full = fmin(full, ldexp(1, b->adc_bits) - 1);
    if (!(fill > 0 && fill <= 1))
        return sl_seterr(err, SL_EINVAL, "bench_sim_fit_gain: fill %g is "
                         "outside (0, 1]", fill);
    if (!(full > b->bias_adu))
        return sl_seterr(err, SL_EINVAL, "bench_sim_fit_gain: bias %g ADU "
                         "leaves no codes below full scale %g ADU",
                         b->bias_adu, full);
    sim *s = NULL;
    double lod, sep;
    int rc = make_sim(b, 1, &s, &lod, &sep, err);
    if (rc != SL_OK)
        return rc;
    const sim_opts *o = sim_options(s);
    size_t n = (size_t)o->width * (size_t)o->height;
    float *buf = malloc(sizeof(float) * n);
    double peak = 0;
    if (!buf)
        rc = sl_seterr(err, SL_ENOMEM, "out of memory");
    for (int k = 0; k < o->nframes && rc == SL_OK; k++) {
        if ((rc = sim_frame(s, k, buf)) != SL_OK)
            sl_seterr(err, rc, "gain pilot, frame %d: %s", k, sim_errmsg(s));
        for (size_t i = 0; i < n && rc == SL_OK; i++)
            peak = buf[i] > peak ? buf[i] : peak;
    }
    if (rc == SL_OK) {
        double g0 = b->gain_e_per_adu > 0 ? b->gain_e_per_adu : 1;
        double need = b->photons * peak / (fill * (full - b->bias_adu));
        b->gain_e_per_adu = need > g0 ? need : g0;
        if (peak_adu)
            *peak_adu = b->bias_adu + b->photons * peak / b->gain_e_per_adu;
    }
    free(buf);
    sim_free(s);
    return rc;
}

int bench_truth_read(bench_truth *t, const char *path, sl_err *err)
{
    memset(t, 0, sizeof *t);
    t->sep_px = t->pa_deg = t->dm_mag = NAN;
    seq *img = NULL;
    cube_reader *r = NULL;
    const char *paths[] = {path};
    int rc = cube_reader_open(&r, paths, 1, CUBE_ALLOW_NONFINITE, err);
    if (rc != SL_OK)
        return rc;
    const cube_meta *m = cube_reader_meta(r);
    const char *name = NULL;
    int simulated = cube_meta_get_str(m, "SIMSCENE", &name) == SL_OK;
    t->plate_scale_arcsec = m->plate_scale_arcsec;
    if (cube_meta_get_num(m, "NYQUIST", &t->nyquist_arcsec) != SL_OK)
        t->nyquist_arcsec = NAN;
    t->binary = cube_meta_get_num(m, "BINSEPPX", &t->sep_px) == SL_OK &&
                cube_meta_get_num(m, "BINPA", &t->pa_deg) == SL_OK &&
                cube_meta_get_num(m, "BINDM", &t->dm_mag) == SL_OK;
    cube_reader_free(r);
    if (!simulated) {
        char *side = sim_file_sidecar_path(path);
        rc = sl_seterr(err, SL_EFORMAT, "%s has no simulation keywords (a "
                       "blind cube?): its truth is in its sidecar %s", path,
                       side ? side : "");
        free(side);
        return rc;
    }
    if ((rc = cube_read_ext(&img, path, "COPHASED", err)) != SL_OK)
        return rc;
    t->width = img->width;
    t->height = img->height;
    t->cophased = img->data; /* take the pixels, free the shell */
    img->data = NULL;
    seq_free(img);
    return SL_OK;
}

int bench_truth_read_sidecar(bench_truth *t, const char *cube_path,
                             sl_err *err)
{
    char *side = sim_file_sidecar_path(cube_path);
    if (!side) {
        memset(t, 0, sizeof *t);
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    }
    int rc = bench_truth_read(t, side, err);
    free(side);
    return rc;
}

void bench_truth_clear(bench_truth *t)
{
    if (!t)
        return;
    free(t->cophased);
    t->cophased = NULL;
}

