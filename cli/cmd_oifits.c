/* cmd_oifits.c - `specklab oifits CUBE -o OUT.oifits`: an aperture-mask
 * cube's squared visibilities and closure phases as OIFITS 2
 * (recon/pipeline/oiexport.h: what goes where; recon/spectra/maskobs.h:
 * how they are measured; recon/io/oifits.h: the file).
 *
 * Defaults come from the cube's header: the mask from SIMMASK (the
 * simulator's: nrm17 or a mask file) or MASK (specklabd's wheel slot,
 * when it names a built-in mask or a readable file), the wavelength from
 * WAVELEN, the plate scale from PLTSCALE, the date from DATE-OBS, the
 * target from OBJECT.  What is missing is named with the option that
 * gives it.  The output is never the input and an existing output is
 * kept unless --overwrite (io/oifits.h writes a temporary and renames).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "io/cube.h"
#include "pipeline/oiexport.h"
#include "sim/mask.h"

typedef struct oifits_args {
    char *out, *mask, *target, *date_obs;
    double wavelength_nm, plate_scale_arcsec, bandwidth_nm;
    int overwrite, json, quiet;
} oifits_args;

/* The mask: --mask, else the header's SIMMASK or MASK.  *name gets what
 * ARRNAME will say (g_free). */
static int load_mask(const oifits_args *a, const cube_meta *m, mask **out,
                     char **name, sl_err *e)
{
    const char *want = a->mask, *key = "--mask";
    if (!want && cube_meta_get_str(m, "SIMMASK", &want) == SL_OK)
        key = "SIMMASK";
    else if (!want && cube_meta_get_str(m, "MASK", &want) == SL_OK)
        key = "MASK";
    if (!want)
        return sl_seterr(e, SL_EINVAL, "no mask: give --mask (nrm17 or a mask file); "
                         "the header has neither SIMMASK nor MASK");
    int rc = !strcmp(want, "nrm17") || !strcmp(want, "full") ? mask_named(out, want, e)
                                                             : mask_read(out, want, e);
    if (rc != SL_OK)
        return sl_seterr(e, rc, "mask '%s' (%s): %s", want, key, e->msg);
    if (mask_nholes(*out) < 3) {
        mask_free(*out);
        *out = NULL;
        return sl_seterr(e, SL_EINVAL, "mask '%s' (%s) is a filled aperture: OIFITS "
                         "export needs an aperture mask of holes (--mask)", want, key);
    }
    *name = g_path_get_basename(want);
    return SL_OK;
}

/* The output must not be an input, and must not exist without
 * --overwrite; 0 with the reason printed. */
static int output_ok(const oifits_args *a, char **inputs, int ninputs)
{
    struct stat so, si;
    if (stat(a->out, &so) != 0)
        return 1;
    for (int i = 0; i < ninputs; i++)
        if (stat(inputs[i], &si) == 0 && si.st_dev == so.st_dev && si.st_ino == so.st_ino) {
            fprintf(stderr, "specklab oifits: %s is the input: choose another output\n",
                    a->out);
            return 0;
        }
    if (!a->overwrite) {
        fprintf(stderr, "specklab oifits: %s exists: give --overwrite to replace it\n",
                a->out);
        return 0;
    }
    return 1;
}

static double median(double *v, int n)
{
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && v[j - 1] > v[j]; j--) {
            double t = v[j];
            v[j] = v[j - 1];
            v[j - 1] = t;
        }
    return n ? (n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2])) : NAN;
}

static void report(const oifits_args *a, const oiexport_result *r)
{
    const maskobs_result *b = &r->obs;
    double rms = 0, *err = malloc(sizeof(double) * (b->nt3 ? b->nt3 : 1));
    for (int i = 0; i < b->nt3; i++) {
        rms += b->t3[i].phi_deg * b->t3[i].phi_deg / b->nt3;
        if (err)
            err[i] = b->t3[i].phi_err_deg;
    }
    double med = err ? median(err, b->nt3) : NAN;
    free(err);
    if (a->json) {
        JsonBuilder *jb = json_builder_new();
        json_builder_begin_object(jb);
        cli_json_str(jb, "output", a->out);
        cli_json_int(jb, "frames", b->nframes);
        cli_json_int(jb, "vis2", b->nvis2);
        cli_json_int(jb, "t3", b->nt3);
        cli_json_int(jb, "vis2_not_measured", b->nvis2_lost);
        cli_json_int(jb, "t3_not_measured", b->nt3_lost);
        cli_json_num(jb, "wavelength_m", r->wavelength_m);
        cli_json_num(jb, "plate_scale_arcsec", r->plate_scale_arcsec);
        cli_json_num(jb, "t3phi_rms_deg", sqrt(rms));
        cli_json_num(jb, "t3phierr_median_deg", med);
        cli_json_num(jb, "photons_per_frame", r->photons.photons);
        json_builder_end_object(jb);
        cli_print_json(jb);
        g_object_unref(jb);
    } else if (!a->quiet) {
        printf("%s: %d V2 and %d closure phases from %d frames (mask %s: %d baselines "
               "and %d triangles redundant, not measured); closure phases rms %.2f deg, "
               "median error %.2f deg\n", a->out, b->nvis2, b->nt3, b->nframes,
               r->oi.arrname, b->nvis2_lost, b->nt3_lost, sqrt(rms), med);
    }
}

/* What the header lacks and no option gives, with the options that
 * would: SL_EINVAL naming them all, else SL_OK. */
static int check_header(const oifits_args *a, const cube_meta *m, const char *path,
                        sl_err *e)
{
    char miss[256] = "", opts[256] = "";
    struct { int lacking; const char *what, *opt; } need[] = {
        {!(a->wavelength_nm > 0) && !(m->wavelength_m > 0), "wavelength (WAVELEN)",
         "--wavelength-nm"},
        {!(a->plate_scale_arcsec > 0) && !(m->plate_scale_arcsec > 0),
         "plate scale (PLTSCALE)", "--plate-scale-arcsec"},
        {!a->date_obs && !m->date_obs[0], "date (DATE-OBS)", "--date-obs"}};
    for (size_t i = 0; i < sizeof need / sizeof need[0]; i++)
        if (need[i].lacking) {
            size_t nm = strlen(miss), no = strlen(opts);
            snprintf(miss + nm, sizeof miss - nm, "%s%s", nm ? ", " : "", need[i].what);
            snprintf(opts + no, sizeof opts - no, "%s%s", no ? ", " : "", need[i].opt);
        }
    if (!miss[0])
        return SL_OK;
    return sl_seterr(e, SL_EINVAL, "%s has no %s: give %s", path, miss, opts);
}

/* The header, the mask and the options into the export's options. */
static int prepare(const oifits_args *a, char **inputs, int ninputs, mask **m,
                   char **mname, oiexport_opts *o, sl_err *e)
{
    cube_reader *cr = NULL;
    int rc = cube_reader_open(&cr, (const char *const *)inputs, ninputs,
                              CUBE_ALLOW_NONFINITE, e);
    if (rc == SL_OK)
        rc = load_mask(a, cube_reader_meta(cr), m, mname, e);
    if (rc == SL_OK)
        rc = check_header(a, cube_reader_meta(cr), inputs[0], e);
    cube_reader_free(cr);
    if (rc != SL_OK)
        return rc;
    oiexport_opts_defaults(o);
    if (a->wavelength_nm > 0)
        o->wavelength_m = a->wavelength_nm * 1e-9;
    if (a->plate_scale_arcsec > 0)
        o->plate_scale_arcsec = a->plate_scale_arcsec;
    o->bandwidth_m = a->bandwidth_nm > 0 ? a->bandwidth_nm * 1e-9 : 0;
    o->target = a->target;
    o->date_obs = a->date_obs;
    return SL_OK;
}

static int run(const oifits_args *a, char **inputs, int ninputs)
{
    mask *m = NULL;
    char *mname = NULL;
    oiexport_opts o;
    sl_err e = {0};
    if (prepare(a, inputs, ninputs, &m, &mname, &o, &e) != SL_OK) {
        fprintf(stderr, "specklab oifits: %s\n", e.msg);
        mask_free(m);
        g_free(mname);
        return 1;
    }
    int n = mask_nholes(m), status = 1;
    double *x = malloc(sizeof(double) * n), *y = malloc(sizeof(double) * n);
    for (int i = 0; x && y && i < n; i++)
        mask_hole(m, i, &x[i], &y[i]);
    oiexport_mask om = {x, y, n, mask_hole_diameter_m(m), mname};
    oiexport_result r;
    if (!x || !y) {
        fprintf(stderr, "specklab oifits: out of memory\n");
    } else if (oiexport_run((const char *const *)inputs, ninputs, &om, &o, &r, &e) != SL_OK) {
        fprintf(stderr, "specklab oifits: %s\n", e.msg);
    } else {
        if (oifits_write(a->out, &r.oi, a->overwrite, &e) != SL_OK)
            fprintf(stderr, "specklab oifits: %s\n", e.msg);
        else
            report(a, &r), status = 0;
        oiexport_result_clear(&r);
    }
    free(x);
    free(y);
    g_free(mname);
    mask_free(m);
    return status;
}

int cmd_oifits(int argc, char **argv)
{
    oifits_args a = {0};
    int status = 2;
    GOptionEntry entries[] = {
        {"output", 'o', 0, G_OPTION_ARG_FILENAME, &a.out, "the OIFITS file to write (required)", "FILE"},
        {"mask", 0, 0, G_OPTION_ARG_STRING, &a.mask, "nrm17|FILE (default the header's SIMMASK or MASK)", "MASK"},
        {"wavelength-nm", 0, 0, G_OPTION_ARG_DOUBLE, &a.wavelength_nm, "wavelength (default the header's WAVELEN)", "NM"},
        {"plate-scale-arcsec", 0, 0, G_OPTION_ARG_DOUBLE, &a.plate_scale_arcsec, "arcsec per pixel (default the header's PLTSCALE)", "S"},
        {"bandwidth-nm", 0, 0, G_OPTION_ARG_DOUBLE, &a.bandwidth_nm, "EFF_BAND (default 0: unknown or monochromatic)", "NM"},
        {"target", 0, 0, G_OPTION_ARG_STRING, &a.target, "target name (default the header's OBJECT)", "NAME"},
        {"date-obs", 0, 0, G_OPTION_ARG_STRING, &a.date_obs, "start of the observation, ISO-8601 UTC (default the header's DATE-OBS)", "DATE"},
        {"overwrite", 0, 0, G_OPTION_ARG_NONE, &a.overwrite, "replace an existing output", NULL},
        {"json", 0, 0, G_OPTION_ARG_NONE, &a.json, "print one JSON object", NULL},
        {"quiet", 'q', 0, G_OPTION_ARG_NONE, &a.quiet, "print nothing on success", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("CUBE.fits... - an aperture-mask cube's V2 and closure phases as OIFITS 2");
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_set_description(ctx,
        "Frames are cleaned as `specklab recon` cleans them.  Each baseline is sampled at one\n"
        "FFT pixel of its splodge, clean of the others; redundant baselines (no clean pixel)\n"
        "and the triangles using them are not written.  UCOORD is east, VCOORD north.\n"
        "VIS2DATA and T3AMP are raw (divided by the mask's own transfer only).");
    if (!cli_parse(ctx, &argc, &argv))
        goto free_ctx;
    if (argc < 2 || !a.out) {
        fprintf(stderr, "specklab oifits: need a cube and -o OUT.oifits\n");
        goto free_ctx;
    }
    status = output_ok(&a, argv + 1, argc - 1) ? run(&a, argv + 1, argc - 1) : 1;
free_ctx:
    g_option_context_free(ctx);
    g_free(a.out);
    g_free(a.mask);
    g_free(a.target);
    g_free(a.date_obs);
    return status;
}
