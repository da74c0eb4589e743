/* cmd_sim.c - `specklab sim`: simulate a speckle cube with known truth.
 *
 * Output: one FITS file.  The primary HDU is the frame cube (NAXIS1 = x,
 * NAXIS2 = y, NAXIS3 = frame), followed by two 2-D image extensions:
 * TRUTH (the sky on the frame grid, unit total flux) and COPHASED (the same
 * pupil without turbulence, unit total flux).  Frames are streamed to disk
 * one at a time, so memory does not grow with the frame count.  The cube's
 * BITPIX follows the detector (sim_output_bitpix): 8 or unsigned 16 for an
 * 8- or 16-bit converter, else float32.
 *
 * --blind writes the cube as a camera would: only DATE-OBS, EXPTIME,
 * INSTRUME, BUNIT and (when given) OBJECT, besides the standard header
 * (io/cube.h; no WCS: a camera does not know its plate scale), and a
 * HISTORY naming the sidecar; no extensions.  Everything the
 * simulator knows goes to a sidecar: its primary HDU is the truth (so a
 * reader opening it sees the keywords), then the TRUTH and COPHASED
 * extensions as in the normal output.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fftw3.h>

#include "cli.h"
#include "io/cube.h"
#include "sim/mask.h"
#include "outfile.h"
#include "progress.h"
#include "sim/scene.h"
#include "sim/sim.h"
#include "sim/sim_file.h"
#include "skyfig.h"

/* INSTRUME of a --blind cube: a camera, not the simulator. */
#define BLIND_INSTRUME "CMOS camera"

typedef struct sim_args {
    char *scene, *mask, *size, *out, *png, *object;
    char *offset_px, *phase_model, *truth_out;
    double sep_arcsec, pa_deg, dm, wavelength_nm, plate_scale, r0_m, L0_m;
    double wind_mps, wind_dir_deg, interval_ms, exposure_us;
    double photons, read_noise_e, gain, bias_adu, saturation_adu;
    double hot_level_adu, jitter_px, pixel_aspect, aperture_m, obstruction;
    gint64 seed;
    int frames, no_turbulence, json, quiet, overwrite;
    int adc_bits, hot_pixels, dead_pixels, blind;
    char *truth_path;   /* the sidecar's path when --blind (g_free) */
} sim_args;

static void defaults(sim_args *a)
{
    sim_opts o;
    sim_opts_defaults(&o);
    memset(a, 0, sizeof *a);
    a->sep_arcsec = 0.2;
    a->pa_deg = 30;
    a->dm = 1;
    a->wavelength_nm = o.wavelength_m * 1e9;
    a->r0_m = o.r0_m;
    a->L0_m = 0;
    a->wind_mps = o.wind_mps;
    a->interval_ms = o.frame_interval_s * 1e3;
    a->exposure_us = o.exposure_s * 1e6;
    a->gain = o.gain_e_per_adu;
    a->saturation_adu = o.saturation_adu;
    a->hot_level_adu = o.hot_level_adu;
    a->pixel_aspect = o.pixel_aspect;
    a->seed = 1;
    a->frames = o.nframes;
}

static int load_inputs(const sim_args *a, scene **sc, mask **m, sl_err *e)
{
    const char *sname = a->scene ? a->scene : "binary";
    int rc;
    if (!strcmp(sname, "point") || !strcmp(sname, "binary") ||
        !strcmp(sname, "six-star") || !strcmp(sname, "extended"))
        rc = scene_named(sc, sname, a->sep_arcsec, a->pa_deg, a->dm, e);
    else
        rc = scene_read(sc, sname, e);
    if (rc != SL_OK)
        return rc;
    const char *mname = a->mask ? a->mask : "nrm17";
    int telescope = a->aperture_m != 0 || a->obstruction != 0;
    if (telescope && strcmp(mname, "full") != 0)
        return sl_seterr(e, SL_EINVAL, "--aperture-m and --obstruction "
                         "describe a filled aperture: use them with --mask "
                         "full, not '%s'", mname);
    if (telescope) {
        /* the default diameter is the built-in "full" pupil's */
        *m = mask_new_full_obstructed(a->aperture_m != 0 ? a->aperture_m : 1.1,
                                      a->obstruction, e);
        return *m ? SL_OK : e->code;
    }
    if (!strcmp(mname, "nrm17") || !strcmp(mname, "full"))
        return mask_named(m, mname, e);
    return mask_read(m, mname, e);
}

/* The options this module adds beyond the paper's model.  all: write every
 * keyword (the --blind sidecar); otherwise only those of features in use,
 * so that default headers stay as they were. */
static void realism_meta(cube_meta *md, const sim *s, int all)
{
    const sim_opts *o = sim_options(s);
    if (all || o->adc_bits)
        cube_meta_set_num(md, "SIMADC", o->adc_bits, "ADC bits, 0 = no converter limit");
    if (all || o->hot_pixels)
        cube_meta_set_num(md, "SIMNHOT", o->hot_pixels, "hot pixels");
    if (o->hot_pixels && sim_detector(s))
        cube_meta_set_num(md, "SIMHOTL", detector_hot_level_adu(sim_detector(s)),
                          "[adu] hot pixel level");
    if (all || o->dead_pixels)
        cube_meta_set_num(md, "SIMNDEAD", o->dead_pixels, "dead pixels (0 adu)");
    if (all || o->offset_x_px != 0 || o->offset_y_px != 0) {
        cube_meta_set_num(md, "SIMOFFX", o->offset_x_px, "[px] scene offset from the centre, x");
        cube_meta_set_num(md, "SIMOFFY", o->offset_y_px, "[px] scene offset from the centre, y");
    }
    if (all || o->jitter_px > 0)
        cube_meta_set_num(md, "SIMJITT", o->jitter_px, "[px] tip-tilt jitter rms per axis");
    if (all || o->pixel_aspect != 1)
        cube_meta_set_num(md, "SIMASPCT", o->pixel_aspect, "pixel height / width");
    if (all || o->phase_model != SIM_PHASE_SCREEN)
        cube_meta_set_str(md, "SIMPHMOD", o->phase_model == SIM_PHASE_PISTON ?
                          "piston" : "screen", "phase model");
}

/* Record every simulation parameter in the header (our SIM* keywords). */
static void fill_meta(cube_meta *md, const sim_args *a, const sim *s,
                      const scene *sc, const mask *m, int all)
{
    const sim_opts *o = sim_options(s);
    cube_meta_init(md);
    snprintf(md->instrume, sizeof md->instrume, "specklab-sim");
    snprintf(md->object, sizeof md->object, "%s",
             a->object ? a->object : scene_name(sc));
    snprintf(md->bunit, sizeof md->bunit, "%s",
             o->photons_per_frame > 0 ? "adu" : "relative flux");
    md->exptime_s = o->exposure_s;
    md->plate_scale_arcsec = sim_plate_scale_arcsec(s);
    if (o->pixel_aspect != 1.0)
        md->pixel_aspect = o->pixel_aspect;
    md->wavelength_m = o->wavelength_m;
    cube_meta_add_history(md, "simulated by specklab sim: scene %s, mask %s, %d frames, "
                          "seed %lld; every parameter is in the SIM*, MASK* and BIN* "
                          "keywords", a->scene ? a->scene : "binary",
                          a->mask ? a->mask : "nrm17", o->nframes, (long long)o->seed);
    cube_meta_set_str(md, "SIMSCENE", scene_name(sc), "scene");
    cube_meta_set_str(md, "SIMMASK", a->mask ? a->mask : mask_name(m), "pupil mask");
    cube_meta_set_num(md, "MASKNH", mask_nholes(m), "mask holes (0 = filled)");
    cube_meta_set_num(md, "MASKEXT", mask_extent_m(m), "[m] pupil outer extent");
    if (mask_nholes(m) > 0) {
        cube_meta_set_num(md, "MASKHD", mask_hole_diameter_m(m), "[m] hole diameter");
        cube_meta_set_num(md, "MASKRED", (double)mask_redundancy(m),
                          "baseline pairs closer than a hole diameter");
    }
    if (mask_obstruction(m) > 0)
        cube_meta_set_num(md, "MASKOBS", mask_obstruction(m),
                          "central obstruction / aperture diameter");
    cube_meta_set_num(md, "NYQUIST", sim_nyquist_arcsec(s), "[arcsec/px] Nyquist for MASKEXT");
    cube_meta_set_num(md, "SIMOVS", sim_oversample(s), "computed at this x finer, binned");
    cube_meta_set_num(md, "SIMTURB", o->turbulence, "1 = turbulence on");
    cube_meta_set_num(md, "SIMR0", o->r0_m, "[m] Fried parameter at WAVELEN");
    cube_meta_set_num(md, "SIML0", isfinite(o->L0_m) ? o->L0_m : 0, "[m] outer scale, 0 = Kolmogorov");
    cube_meta_set_num(md, "SIMWIND", o->wind_mps, "[m/s] frozen-flow speed");
    cube_meta_set_num(md, "SIMWDIR", o->wind_dir_deg, "[deg] flow direction from +x to +y");
    cube_meta_set_num(md, "SIMDT", o->frame_interval_s, "[s] frame interval");
    cube_meta_set_num(md, "SIMSEED", (double)o->seed, "random seed");
    cube_meta_set_num(md, "SIMPHOT", o->photons_per_frame, "mean photons/frame, 0 = noiseless");
    if (o->photons_per_frame > 0) {
        cube_meta_set_num(md, "SIMRDN", o->read_noise_e, "[e-] read noise rms");
        cube_meta_set_num(md, "SIMGAIN", o->gain_e_per_adu, "[e-/adu] gain");
        cube_meta_set_num(md, "SIMBIAS", o->bias_adu, "[adu] bias");
        cube_meta_set_num(md, "SIMSAT", o->saturation_adu, "[adu] saturation");
    }
    if (!strcmp(scene_name(sc), "binary")) {
        cube_meta_set_num(md, "BINSEP", a->sep_arcsec, "[arcsec] binary separation");
        cube_meta_set_num(md, "BINSEPPX", a->sep_arcsec / sim_plate_scale_arcsec(s),
                          "[px] binary separation");
        cube_meta_set_num(md, "BINPA", a->pa_deg, "[deg] PA from +y (N) to -x (E)");
        cube_meta_set_num(md, "BINDM", a->dm, "[mag] companion magnitude difference");
    }
    realism_meta(md, s, all);
}

/* A --blind cube's header: what a camera writes, nothing it could not know. */
static void camera_meta(cube_meta *md, const sim_args *a, const sim *s)
{
    cube_meta_init(md);
    snprintf(md->instrume, sizeof md->instrume, "%s", BLIND_INSTRUME);
    if (a->object)
        snprintf(md->object, sizeof md->object, "%s", a->object);
    snprintf(md->bunit, sizeof md->bunit, "%s",
             sim_options(s)->photons_per_frame > 0 ? "adu" : "relative flux");
    md->exptime_s = sim_options(s)->exposure_s;
    cube_meta_add_history(md, "simulated camera frames (specklab sim --blind); the truth "
                          "and the parameters are in %s", a->truth_path);
}

/* Add the truth extensions (with_truth) and close. */
static int finish_file(sim *s, cube_writer *w, float *buf, sl_err *e)
{
    int rc = sim_file_add_truth(s, w, buf, e);
    if (rc == SL_OK && (rc = cube_writer_close(w)) != SL_OK)
        sl_seterr(e, rc, "%s", cube_writer_errmsg(w));
    return rc;
}

/* The frame cube; with_truth adds the extensions (not for --blind). */
static int write_cube(sim *s, const char *path, const cube_meta *md, float *buf,
                      int with_truth, progress *pg, sl_err *e)
{
    const sim_opts *o = sim_options(s);
    cube_writer *w = NULL;
    int rc = cube_writer_open(&w, path, o->width, o->height,
                              sim_output_bitpix(s), md, e);
    if (rc != SL_OK)
        return rc;
    for (int k = 0; k < o->nframes && rc == SL_OK; k++) {
        progress_update(pg, k, "frames");
        rc = sim_frame(s, k, buf);
        if (rc != SL_OK)
            sl_seterr(e, rc, "frame %d: %s", k, sim_errmsg(s));
        else if ((rc = cube_writer_append(w, buf)) != SL_OK)
            sl_seterr(e, rc, "%s", cube_writer_errmsg(w));
    }
    if (rc == SL_OK && with_truth)
        rc = finish_file(s, w, buf, e);
    else if (rc == SL_OK && (rc = cube_writer_close(w)) != SL_OK)
        sl_seterr(e, rc, "%s", cube_writer_errmsg(w));
    cube_writer_free(w);
    return rc;
}

static const char *const png_what[] = {"frame0", "truth", "cophased"};

/* Figures of frame 0 (the whole frame, minimum to maximum: speckles are
 * the subject), the truth and the cophased image (zoomed, cut above the
 * artifacts: the scene is the subject), to their temporaries. */
static int write_pngs(sim *s, outfile *png, const char *object, float *buf,
                      sl_err *e)
{
    const sim_opts *o = sim_options(s);
    static const char *title[] = {"frame 0", "truth", "cophased"};
    for (int i = 0; i < 3; i++) {
        int rc = i == 0 ? sim_frame(s, 0, buf) : i == 1 ? sim_truth(s, buf)
                                                         : sim_cophased(s, buf);
        skyfig_opts f;
        skyfig_opts_init(&f);
        snprintf(f.title, sizeof f.title, "%s \u00b7 simulated %s", object, title[i]);
        f.plate_scale_arcsec = sim_plate_scale_arcsec(s);
        f.stretch = i == 0 ? PREVIEW_SQRT : PREVIEW_ASINH;
        f.cut = i == 0 ? DISPLAY_CUT_FULL : DISPLAY_CUT_ARTIFACTS;
        if (rc == SL_OK)
            rc = skyfig_write_png(png[i].tmp, buf, o->width, o->height, &f, e);
        if (rc != SL_OK)
            return rc;
    }
    return SL_OK;
}

static void report(const sim_args *a, const sim *s, double elapsed_s)
{
    const sim_opts *o = sim_options(s);
    if (a->json) {
        JsonBuilder *b = json_builder_new();
        json_builder_begin_object(b);
        json_builder_set_member_name(b, "output");
        json_builder_add_string_value(b, a->out);
        json_builder_set_member_name(b, "frames");
        json_builder_add_int_value(b, o->nframes);
        json_builder_set_member_name(b, "width");
        json_builder_add_int_value(b, o->width);
        json_builder_set_member_name(b, "height");
        json_builder_add_int_value(b, o->height);
        json_builder_set_member_name(b, "plate_scale_arcsec");
        json_builder_add_double_value(b, sim_plate_scale_arcsec(s));
        json_builder_set_member_name(b, "nyquist_arcsec");
        json_builder_add_double_value(b, sim_nyquist_arcsec(s));
        json_builder_set_member_name(b, "oversample");
        json_builder_add_int_value(b, sim_oversample(s));
        json_builder_set_member_name(b, "warning");
        json_builder_add_string_value(b, sim_warning(s));
        if (a->truth_path) {
            json_builder_set_member_name(b, "truth_output");
            json_builder_add_string_value(b, a->truth_path);
        }
        json_builder_set_member_name(b, "elapsed_s");
        json_builder_add_double_value(b, elapsed_s);
        json_builder_set_member_name(b, "peak_rss_mb");
        json_builder_add_double_value(b, cli_peak_rss_mb());
        json_builder_end_object(b);
        cli_print_json(b);
        g_object_unref(b);
    } else if (!a->quiet) {
        printf("wrote %s: %d frames of %dx%d, %.4f arcsec/px (Nyquist %.4f), "
               "%.2f s\n", a->out, o->nframes, o->width, o->height,
               sim_plate_scale_arcsec(s), sim_nyquist_arcsec(s), elapsed_s);
        if (a->truth_path)
            printf("wrote %s: truth and simulation parameters\n", a->truth_path);
    }
}

/* "X,Y" into two finite numbers. */
static int parse_pair(const char *text, double *x, double *y)
{
    char *end;
    *x = strtod(text, &end);
    if (end == text || *end != ',')
        return 0;
    const char *p = end + 1;
    *y = strtod(p, &end);
    return end != p && *end == '\0' && isfinite(*x) && isfinite(*y);
}

/* The options beyond the paper's model into o; 0 with a message on stderr
 * when one does not parse. */
static int extra_opts(const sim_args *a, sim_opts *o)
{
    o->adc_bits = a->adc_bits;
    o->hot_pixels = a->hot_pixels;
    o->dead_pixels = a->dead_pixels;
    o->hot_level_adu = a->hot_level_adu;
    o->jitter_px = a->jitter_px;
    o->pixel_aspect = a->pixel_aspect;
    if (a->offset_px && !parse_pair(a->offset_px, &o->offset_x_px, &o->offset_y_px)) {
        fprintf(stderr, "specklab sim: --offset-px '%s': expected X,Y in pixels, "
                "e.g. 3.5,-2\n", a->offset_px);
        return 0;
    }
    if (!a->phase_model || !strcmp(a->phase_model, "screen"))
        o->phase_model = SIM_PHASE_SCREEN;
    else if (!strcmp(a->phase_model, "piston"))
        o->phase_model = SIM_PHASE_PISTON;
    else {
        fprintf(stderr, "specklab sim: --phase-model '%s': expected screen or "
                "piston\n", a->phase_model);
        return 0;
    }
    if (a->truth_out && !a->blind) {
        fprintf(stderr, "specklab sim: --truth-out needs --blind (without it the "
                "truth is in the cube's TRUTH and COPHASED extensions)\n");
        return 0;
    }
    return 1;
}

/* Every file sim writes (outfile.h): the cube, the --blind sidecar and
 * the three previews, checked against the scene and mask files it reads
 * before anything is simulated. */
typedef struct sim_outputs {
    outfile cube, truth, png[3];
} sim_outputs;

static void outputs_clear(sim_outputs *f)
{
    outfile_clear(&f->cube);
    outfile_clear(&f->truth);
    for (int i = 0; i < 3; i++)
        outfile_clear(&f->png[i]);
}

static int outputs_begin(sim_args *a, sim_outputs *f)
{
    memset(f, 0, sizeof *f);
    const char *in[] = {a->scene, a->mask};
    GError *gerr = NULL;
    int ok = outfile_begin(&f->cube, a->out, a->overwrite, in, 2, &gerr);
    if (ok && a->blind) {
        char *side = sim_file_sidecar_path(a->out);
        a->truth_path = g_strdup(a->truth_out ? a->truth_out : side);
        free(side);
        if (!strcmp(a->truth_path, a->out))
            g_set_error(&gerr, G_OPTION_ERROR, G_OPTION_ERROR_BAD_VALUE,
                        "--truth-out %s is the output cube itself", a->truth_path);
        ok = !gerr && outfile_begin(&f->truth, a->truth_path, a->overwrite, in, 2, &gerr);
    }
    for (int i = 0; ok && a->png && i < 3; i++) {
        char *path = g_strdup_printf("%s-%s.png", a->png, png_what[i]);
        ok = outfile_begin(&f->png[i], path, a->overwrite, in, 2, &gerr);
        g_free(path);
    }
    if (!ok) {
        fprintf(stderr, "specklab sim: %s\n", gerr->message);
        g_error_free(gerr);
        outputs_clear(f);
    }
    return ok;
}

/* Rename every file written into place. */
static int outputs_commit(const sim_args *a, sim_outputs *f, sl_err *e)
{
    GError *gerr = NULL;
    int ok = outfile_commit(&f->cube, &gerr) &&
             (!a->blind || outfile_commit(&f->truth, &gerr));
    for (int i = 0; ok && a->png && i < 3; i++)
        ok = outfile_commit(&f->png[i], &gerr);
    if (!ok) {
        sl_seterr(e, SL_EIO, "%s", gerr->message);
        g_error_free(gerr);
    }
    return ok;
}

/* The cube, the --blind sidecar, the previews. */
static int write_outputs(const sim_args *a, sim_outputs *f, sim *s,
                         const scene *sc, const mask *m, float *buf, sl_err *e)
{
    cube_meta md;
    progress *pg = progress_new(stderr, sim_options(s)->nframes);
    int rc;
    if (a->quiet || a->json) /* a bar only for a person watching */
        progress_free(pg), pg = NULL;
    if (!a->blind) {
        fill_meta(&md, a, s, sc, m, 0);
        rc = write_cube(s, f->cube.tmp, &md, buf, 1, pg, e);
    } else {
        camera_meta(&md, a, s);
        rc = write_cube(s, f->cube.tmp, &md, buf, 0, pg, e);
    }
    progress_finish(pg);
    progress_free(pg);
    if (rc != SL_OK)
        return 0;
    if (a->blind) {
        fill_meta(&md, a, s, sc, m, 1);
        /* the sidecar's own image is the truth */
        snprintf(md.bunit, sizeof md.bunit, "relative flux");
        if (sim_file_write_sidecar(s, f->truth.tmp, &md, buf, e) != SL_OK)
            return 0;
    }
    if (a->png && write_pngs(s, f->png, a->object ? a->object : scene_name(sc), buf,
                             e) != SL_OK)
        return 0;
    return outputs_commit(a, f, e);
}

static int run(sim_args *a)
{
    sl_err e = {0};
    scene *sc = NULL;
    mask *m = NULL;
    sim *s = NULL;
    float *buf = NULL;
    int status = 1;
    sim_opts o;
    sim_opts_defaults(&o);
    double t0 = cli_now_s();
    if (a->size) {
        GError *gerr = NULL;
        if (!cli_parse_size(a->size, &o.width, &o.height, &gerr)) {
            fprintf(stderr, "specklab sim: %s\n", gerr->message);
            g_error_free(gerr);
            return 2;
        }
    }
    o.nframes = a->frames;
    o.wavelength_m = a->wavelength_nm / 1e9;
    o.plate_scale_arcsec = a->plate_scale;
    o.r0_m = a->r0_m;
    o.L0_m = a->L0_m > 0 ? a->L0_m : INFINITY;
    o.wind_mps = a->wind_mps;
    o.wind_dir_deg = a->wind_dir_deg;
    o.frame_interval_s = a->interval_ms * 1e-3;
    o.exposure_s = a->exposure_us * 1e-6;
    o.turbulence = !a->no_turbulence;
    o.seed = (uint64_t)a->seed;
    o.photons_per_frame = a->photons;
    o.read_noise_e = a->read_noise_e;
    o.gain_e_per_adu = a->gain;
    o.bias_adu = a->bias_adu;
    o.saturation_adu = a->saturation_adu;
    if (!extra_opts(a, &o))
        return 2;
    sim_outputs f;
    if (!outputs_begin(a, &f))
        return 2;
    if (load_inputs(a, &sc, &m, &e) != SL_OK || sim_new(&s, &o, m, sc, &e) != SL_OK) {
        fprintf(stderr, "specklab sim: %s\n", e.msg);
        status = e.code == SL_EINVAL ? 2 : 1; /* options that cannot be */
        goto free_inputs;
    }
    if (sim_warning(s)[0])
        fprintf(stderr, "specklab sim: warning: %s\n", sim_warning(s));
    buf = malloc(sizeof(float) * o.width * o.height);
    if (!buf || !write_outputs(a, &f, s, sc, m, buf, &e)) {
        fprintf(stderr, "specklab sim: %s\n", buf ? e.msg : "out of memory");
        goto free_sim;
    }
    report(a, s, cli_now_s() - t0);
    status = 0;
free_sim:
    free(buf);
    sim_free(s);
free_inputs:
    mask_free(m);
    scene_free(sc);
    outputs_clear(&f);
    return status;
}

int cmd_sim(int argc, char **argv)
{
    sim_args a;
    defaults(&a);
    GOptionEntry entries[] = {
        {"scene", 0, 0, G_OPTION_ARG_STRING, &a.scene, "point|binary|six-star|extended|FILE (default binary)", "SCENE"},
        {"sep-arcsec", 0, 0, G_OPTION_ARG_DOUBLE, &a.sep_arcsec, "binary separation (default 0.2)", "ARCSEC"},
        {"pa-deg", 0, 0, G_OPTION_ARG_DOUBLE, &a.pa_deg, "binary position angle, from +y (N) towards -x (E) (default 30)", "DEG"},
        {"dm-mag", 0, 0, G_OPTION_ARG_DOUBLE, &a.dm, "binary magnitude difference (default 1)", "MAG"},
        {"frames", 'n', 0, G_OPTION_ARG_INT, &a.frames, "frames (default 100)", "N"},
        {"size", 0, 0, G_OPTION_ARG_STRING, &a.size, "frame size N or WxH (default 256)", "N"},
        {"seed", 0, 0, G_OPTION_ARG_INT64, &a.seed, "random seed (default 1)", "N"},
        {"photons", 0, 0, G_OPTION_ARG_DOUBLE, &a.photons, "mean photons per frame; 0 = noiseless (default 0)", "N"},
        {"mask", 0, 0, G_OPTION_ARG_STRING, &a.mask, "nrm17|full|FILE (default nrm17)", "MASK"},
        {"wavelength-nm", 0, 0, G_OPTION_ARG_DOUBLE, &a.wavelength_nm, "wavelength (default 500)", "NM"},
        {"plate-scale-arcsec", 0, 0, G_OPTION_ARG_DOUBLE, &a.plate_scale, "arcsec per pixel; 0 = Nyquist (default 0)", "ARCSEC"},
        {"r0-m", 0, 0, G_OPTION_ARG_DOUBLE, &a.r0_m, "Fried parameter at the wavelength (default 0.2)", "M"},
        {"L0-m", 0, 0, G_OPTION_ARG_DOUBLE, &a.L0_m, "outer scale; 0 = Kolmogorov (default 0)", "M"},
        {"wind-mps", 0, 0, G_OPTION_ARG_DOUBLE, &a.wind_mps, "wind speed (default 10)", "M/S"},
        {"wind-dir-deg", 0, 0, G_OPTION_ARG_DOUBLE, &a.wind_dir_deg, "wind direction from +x towards +y (default 0)", "DEG"},
        {"frame-interval-ms", 0, 0, G_OPTION_ARG_DOUBLE, &a.interval_ms, "time between frames (default 10)", "MS"},
        {"exposure-us", 0, 0, G_OPTION_ARG_DOUBLE, &a.exposure_us, "exposure recorded in EXPTIME (default 10000)", "US"},
        {"no-turbulence", 0, 0, G_OPTION_ARG_NONE, &a.no_turbulence, "cophased frames (no screen)", NULL},
        {"read-noise-e", 0, 0, G_OPTION_ARG_DOUBLE, &a.read_noise_e, "read noise, electrons rms (default 0)", "E"},
        {"gain-e-per-adu", 0, 0, G_OPTION_ARG_DOUBLE, &a.gain, "detector gain (default 1)", "E"},
        {"bias-adu", 0, 0, G_OPTION_ARG_DOUBLE, &a.bias_adu, "bias level (default 0)", "ADU"},
        {"saturation-adu", 0, 0, G_OPTION_ARG_DOUBLE, &a.saturation_adu, "clip level (default 65535)", "ADU"},
        {"adc-bits", 0, 0, G_OPTION_ARG_INT, &a.adc_bits, "ADC bits: codes clipped to 2^N-1; 1..8 write BITPIX 8, 9..16 unsigned 16 (default 0 = no converter, float32)", "N"},
        {"hot-pixels", 0, 0, G_OPTION_ARG_INT, &a.hot_pixels, "hot pixels, stuck at full scale, same positions every frame (default 0)", "N"},
        {"hot-level-adu", 0, 0, G_OPTION_ARG_DOUBLE, &a.hot_level_adu, "level of the hot pixels, e.g. a warm pixel (default full scale)", "ADU"},
        {"dead-pixels", 0, 0, G_OPTION_ARG_INT, &a.dead_pixels, "dead pixels, 0 ADU (default 0)", "N"},
        {"offset-px", 0, 0, G_OPTION_ARG_STRING, &a.offset_px, "scene displaced from the frame centre, sub-pixel (default 0,0)", "X,Y"},
        {"jitter-px", 0, 0, G_OPTION_ARG_DOUBLE, &a.jitter_px, "per-frame tip-tilt jitter, rms per axis (default 0)", "PX"},
        {"pixel-aspect", 0, 0, G_OPTION_ARG_DOUBLE, &a.pixel_aspect, "pixel height / width in [0.5, 2]; --plate-scale-arcsec is the x pitch (default 1)", "A"},
        {"phase-model", 0, 0, G_OPTION_ARG_STRING, &a.phase_model, "screen|piston: piston = each hole's mean phase, hole masks only (default screen)", "MODEL"},
        {"aperture-m", 0, 0, G_OPTION_ARG_DOUBLE, &a.aperture_m, "diameter of --mask full (default 1.1)", "M"},
        {"obstruction", 0, 0, G_OPTION_ARG_DOUBLE, &a.obstruction, "central obstruction of --mask full, fraction of the diameter (default 0)", "F"},
        {"blind", 0, 0, G_OPTION_ARG_NONE, &a.blind, "write the cube as a camera would (no SIM* keywords, no truth); truth to a sidecar", NULL},
        {"truth-out", 0, 0, G_OPTION_ARG_FILENAME, &a.truth_out, "the --blind sidecar (default OUTPUT-truth.fits)", "FILE"},
        {"object", 0, 0, G_OPTION_ARG_STRING, &a.object, "OBJECT keyword (default the scene name)", "NAME"},
        {"output", 'o', 0, G_OPTION_ARG_FILENAME, &a.out, "output FITS file (required)", "FILE"},
        {"png", 0, 0, G_OPTION_ARG_FILENAME, &a.png, "also write PREFIX-frame0/truth/cophased.png", "PREFIX"},
        {"overwrite", 0, 0, G_OPTION_ARG_NONE, &a.overwrite, "replace existing output files", NULL},
        {"json", 0, 0, G_OPTION_ARG_NONE, &a.json, "print a JSON summary", NULL},
        {"quiet", 'q', 0, G_OPTION_ARG_NONE, &a.quiet, "print nothing on success", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("- simulate a speckle cube");
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_set_description(ctx,
        "Defaults are the paper's Table 1: 100 frames, 500 nm, r0 = 0.2 m, wind 10 m/s,\n"
        "17-hole mask (10 cm holes, 1 m maximum baseline), sampled at Nyquist.\n"
        "Output: FITS cube (primary HDU) + TRUTH and COPHASED image extensions;\n"
        "with --blind, a camera-like cube and the truth in a sidecar file.");
    int status = 2;
    if (!cli_parse(ctx, &argc, &argv))
        goto free_ctx;
    if (argc > 1) {
        fprintf(stderr, "specklab sim: unexpected argument '%s'\n", argv[1]);
        goto free_ctx;
    }
    if (!a.out) {
        fprintf(stderr, "specklab sim: -o FILE is required\n");
        goto free_ctx;
    }
    status = run(&a);
free_ctx:
    g_option_context_free(ctx);
    g_free(a.scene); g_free(a.mask); g_free(a.size); g_free(a.out);
    g_free(a.png); g_free(a.object);
    g_free(a.offset_px); g_free(a.phase_model); g_free(a.truth_out);
    g_free(a.truth_path);
    return status;
}
