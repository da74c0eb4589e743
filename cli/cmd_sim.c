/* cmd_sim.c - `specklab sim`: simulate a speckle cube with known truth.
 *
 * Output: one FITS file.  The primary HDU is the frame cube (NAXIS1 = x,
 * NAXIS2 = y, NAXIS3 = frame), followed by two 2-D image extensions:
 * TRUTH (the sky on the frame grid, unit total flux) and COPHASED (the same
 * pupil without turbulence, unit total flux).  Frames are streamed to disk
 * one at a time, so memory does not grow with the frame count.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fftw3.h>

#include "cli.h"
#include "cube.h"
#include "mask.h"
#include "preview.h"
#include "scene.h"
#include "sim.h"

typedef struct sim_args {
    char *scene, *mask, *size, *out, *png, *object;
    double sep_arcsec, pa_deg, dm, wavelength_nm, plate_scale, r0_m, L0_m;
    double wind_mps, wind_dir_deg, interval_ms, exposure_ms;
    double photons, read_noise_e, gain, bias_adu, saturation_adu;
    gint64 seed;
    int frames, no_turbulence, json, quiet;
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
    a->exposure_ms = o.exposure_s * 1e3;
    a->gain = o.gain_e_per_adu;
    a->saturation_adu = o.saturation_adu;
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
    if (!strcmp(mname, "nrm17") || !strcmp(mname, "full"))
        return mask_named(m, mname, e);
    return mask_read(m, mname, e);
}

/* Record every simulation parameter in the header (our SIM* keywords). */
static void fill_meta(cube_meta *md, const sim_args *a, const sim *s,
                      const scene *sc, const mask *m)
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
    md->wavelength_m = o->wavelength_m;
    cube_meta_set_str(md, "SIMSCENE", scene_name(sc), "scene");
    cube_meta_set_str(md, "SIMMASK", a->mask ? a->mask : mask_name(m), "pupil mask");
    cube_meta_set_num(md, "MASKNH", mask_nholes(m), "mask holes (0 = filled)");
    cube_meta_set_num(md, "MASKEXT", mask_extent_m(m), "[m] pupil outer extent");
    if (mask_nholes(m) > 0) {
        cube_meta_set_num(md, "MASKHD", mask_hole_diameter_m(m), "[m] hole diameter");
        cube_meta_set_num(md, "MASKRED", (double)mask_redundancy(m),
                          "baseline pairs closer than a hole diameter");
    }
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
}

static int write_cube(sim *s, const char *path, const cube_meta *md, float *buf,
                      sl_err *e)
{
    const sim_opts *o = sim_options(s);
    cube_writer *w = NULL;
    int rc = cube_writer_open(&w, path, o->width, o->height, -32, md, e);
    if (rc != SL_OK)
        return rc;
    for (int k = 0; k < o->nframes && rc == SL_OK; k++) {
        rc = sim_frame(s, k, buf);
        if (rc != SL_OK)
            sl_seterr(e, rc, "frame %d: %s", k, sim_errmsg(s));
        else if ((rc = cube_writer_append(w, buf)) != SL_OK)
            sl_seterr(e, rc, "%s", cube_writer_errmsg(w));
    }
    if (rc == SL_OK && (rc = sim_truth(s, buf)) == SL_OK)
        rc = cube_writer_add_image(w, "TRUTH", buf, o->width, o->height, NULL);
    if (rc == SL_OK && (rc = sim_cophased(s, buf)) == SL_OK)
        rc = cube_writer_add_image(w, "COPHASED", buf, o->width, o->height, NULL);
    if (rc == SL_OK && (rc = cube_writer_close(w)) != SL_OK)
        sl_seterr(e, rc, "%s", cube_writer_errmsg(w));
    else if (rc != SL_OK && e->msg[0] == 0)
        sl_seterr(e, rc, "%s", cube_writer_errmsg(w));
    cube_writer_free(w);
    return rc;
}

static int write_pngs(sim *s, const char *prefix, float *buf, sl_err *e)
{
    const sim_opts *o = sim_options(s);
    static const char *what[] = {"frame0", "truth", "cophased"};
    for (int i = 0; i < 3; i++) {
        int rc = i == 0 ? sim_frame(s, 0, buf) : i == 1 ? sim_truth(s, buf)
                                                         : sim_cophased(s, buf);
        char path[4096];
        snprintf(path, sizeof path, "%s-%s.png", prefix, what[i]);
        if (rc == SL_OK)
            rc = preview_write_png(path, buf, o->width, o->height,
                                   PREVIEW_SQRT, e);
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
    }
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
    o.exposure_s = a->exposure_ms * 1e-3;
    o.turbulence = !a->no_turbulence;
    o.seed = (uint64_t)a->seed;
    o.photons_per_frame = a->photons;
    o.read_noise_e = a->read_noise_e;
    o.gain_e_per_adu = a->gain;
    o.bias_adu = a->bias_adu;
    o.saturation_adu = a->saturation_adu;
    if (load_inputs(a, &sc, &m, &e) != SL_OK || sim_new(&s, &o, m, sc, &e) != SL_OK) {
        fprintf(stderr, "specklab sim: %s\n", e.msg);
        goto free_inputs;
    }
    if (sim_warning(s)[0])
        fprintf(stderr, "specklab sim: warning: %s\n", sim_warning(s));
    buf = malloc(sizeof(float) * o.width * o.height);
    cube_meta md;
    fill_meta(&md, a, s, sc, m);
    if (!buf || write_cube(s, a->out, &md, buf, &e) != SL_OK ||
        (a->png && write_pngs(s, a->png, buf, &e) != SL_OK)) {
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
        {"dm", 0, 0, G_OPTION_ARG_DOUBLE, &a.dm, "binary magnitude difference (default 1)", "MAG"},
        {"frames", 'n', 0, G_OPTION_ARG_INT, &a.frames, "frames (default 100)", "N"},
        {"size", 's', 0, G_OPTION_ARG_STRING, &a.size, "frame size N or WxH (default 256)", "N"},
        {"seed", 0, 0, G_OPTION_ARG_INT64, &a.seed, "random seed (default 1)", "N"},
        {"photons", 0, 0, G_OPTION_ARG_DOUBLE, &a.photons, "mean photons per frame; 0 = noiseless (default 0)", "N"},
        {"mask", 0, 0, G_OPTION_ARG_STRING, &a.mask, "nrm17|full|FILE (default nrm17)", "MASK"},
        {"wavelength-nm", 0, 0, G_OPTION_ARG_DOUBLE, &a.wavelength_nm, "wavelength (default 500)", "NM"},
        {"plate-scale", 0, 0, G_OPTION_ARG_DOUBLE, &a.plate_scale, "arcsec per pixel; 0 = Nyquist (default 0)", "ARCSEC"},
        {"r0-m", 0, 0, G_OPTION_ARG_DOUBLE, &a.r0_m, "Fried parameter at the wavelength (default 0.2)", "M"},
        {"L0-m", 0, 0, G_OPTION_ARG_DOUBLE, &a.L0_m, "outer scale; 0 = Kolmogorov (default 0)", "M"},
        {"wind-mps", 0, 0, G_OPTION_ARG_DOUBLE, &a.wind_mps, "wind speed (default 10)", "M/S"},
        {"wind-dir-deg", 0, 0, G_OPTION_ARG_DOUBLE, &a.wind_dir_deg, "wind direction from +x towards +y (default 0)", "DEG"},
        {"frame-interval-ms", 0, 0, G_OPTION_ARG_DOUBLE, &a.interval_ms, "time between frames (default 10)", "MS"},
        {"exposure-ms", 0, 0, G_OPTION_ARG_DOUBLE, &a.exposure_ms, "exposure recorded in EXPTIME (default 10)", "MS"},
        {"no-turbulence", 0, 0, G_OPTION_ARG_NONE, &a.no_turbulence, "cophased frames (no screen)", NULL},
        {"read-noise-e", 0, 0, G_OPTION_ARG_DOUBLE, &a.read_noise_e, "read noise, electrons rms (default 0)", "E"},
        {"gain", 0, 0, G_OPTION_ARG_DOUBLE, &a.gain, "electrons per ADU (default 1)", "E/ADU"},
        {"bias-adu", 0, 0, G_OPTION_ARG_DOUBLE, &a.bias_adu, "bias level (default 0)", "ADU"},
        {"saturation-adu", 0, 0, G_OPTION_ARG_DOUBLE, &a.saturation_adu, "clip level (default 65535)", "ADU"},
        {"object", 0, 0, G_OPTION_ARG_STRING, &a.object, "OBJECT keyword (default the scene name)", "NAME"},
        {"output", 'o', 0, G_OPTION_ARG_FILENAME, &a.out, "output FITS file (required)", "FILE"},
        {"png", 0, 0, G_OPTION_ARG_FILENAME, &a.png, "also write PREFIX-frame0/truth/cophased.png", "PREFIX"},
        {"json", 0, 0, G_OPTION_ARG_NONE, &a.json, "print a JSON summary", NULL},
        {"quiet", 'q', 0, G_OPTION_ARG_NONE, &a.quiet, "print nothing on success", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("- simulate a speckle cube");
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_set_description(ctx,
        "Defaults are the paper's Table 1: 100 frames, 500 nm, r0 = 0.2 m, wind 10 m/s,\n"
        "17-hole mask (10 cm holes, 1 m maximum baseline), sampled at Nyquist.\n"
        "Output: FITS cube (primary HDU) + TRUTH and COPHASED image extensions.");
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
    return status;
}
