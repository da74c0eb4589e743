/* cmd_recon.c - `specklab recon`: reconstruct a FITS sequence
 * (cmd_compare.c: compare two images, measure a binary). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "binmeas.h"
#include "cli.h"
#include "cmd_daemon.h"
#include "io/cube.h"
#include "measure/metrics.h"
#include "pipeline/pipeline.h"
#include "io/preview.h"
#include "outfile.h"
#include "progress.h"
#include "skyfig.h"
#include "tsm/tsm.h"
#include "wds.h"

typedef struct recon_args {
    char *method, *out, *png, *png_raw, *cut, *ref, *target, *window, *stretch, *skips, *tsm_phases, *tsm_inverse, *badpix, *phase_weights;
    char *dark, *flat, *flat_dark;
    int projections, r2, no_prep, no_detect, no_recentre, no_stf, learn_badpix, json, quiet, threads, refine, binary, overwrite;
    double photons, gain_adu_per_photon, saturation, wiener, target_error, bispec_mb;
} recon_args;

/* The scene probe's numbers and the choice (pipeline.h's report). */
static void probe_json(JsonBuilder *b, const pipeline_probe_report *p)
{
    if (!p->probed)
        return;
    char skips[64];
    pipeline_skips_name(p->skips, skips, sizeof skips);
    cli_json_str(b, "skips", skips);
    if (p->chosen)
        cli_json_str(b, "chosen", p->chosen_label);
    json_builder_set_member_name(b, "scene");
    json_builder_begin_object(b);
    cli_json_num(b, "probed_frames", p->probed);
    cli_json_num(b, "crop_x", p->crop_x0);
    cli_json_num(b, "crop_y", p->crop_y0);
    cli_json_num(b, "crop_width", p->crop_w);
    cli_json_num(b, "crop_height", p->crop_h);
    cli_json_num(b, "cloud_radius_px", p->cloud_radius_px);
    cli_json_num(b, "cloud_level", p->cloud_level);
    cli_json_num(b, "crop_flux_fraction", p->crop_flux_frac);
    if (p->spectrum) {
        cli_json_num(b, "support_cyc_px", p->support_cyc_px);
        cli_json_num(b, "support_fraction", p->support_frac);
        cli_json_num(b, "extent_px", p->extent_px);
        cli_json_num(b, "snr", p->snr);
    }
    cli_json_num(b, "rejected", p->rejected[1] + p->rejected[2] + p->rejected[3] + p->rejected[4]);
    cli_json_num(b, "rejected_empty", p->rejected[1]);
    cli_json_num(b, "rejected_saturated", p->rejected[2]);
    cli_json_num(b, "rejected_flux", p->rejected[3]);
    cli_json_num(b, "rejected_sharpness", p->rejected[4]);
    cli_json_num(b, "reject_mad", p->reject_mad);
    if (p->chosen) {
        cli_json_num(b, "target_error", p->target_error);
        cli_json_num(b, "predicted_error", p->pred_error);
        cli_json_num(b, "predicted_cpu_s", p->pred_cost_s);
    }
    json_builder_end_object(b);
}

/* The estimator's parameters (pipeline.h's report). */
static void parameters_json(JsonBuilder *b, const pipeline_opts *o,
                            const pipeline_report *p)
{
    json_builder_set_member_name(b, "parameters");
    json_builder_begin_object(b);
    if (p->method == PIPE_DIRECT) {
        cli_json_num(b, "R2", p->r2_px);
        cli_json_num(b, "R2MEM", p->r2_bound_mb);
        cli_json_num(b, "RCUT", p->rcut_px);
        cli_json_num(b, "NTRI", (double)p->ntriples);
        cli_json_num(b, "GAIN", p->gain_adu / p->scale);
        cli_json_num(b, "MISF", p->misfit);
        cli_json_num(b, "FILL", p->stf_fill);
        cli_json_num(b, "STF", p->stf_d_r0);
    } else {
        cli_json_num(b, "NANG", p->nangles);
        cli_json_num(b, "NPAIR", p->npairs);
        cli_json_num(b, "CUT", p->cutoff_cyc_px);
        cli_json_str(b, "TPHAS", p->corrected_phases ? "corrected" : "raw");
        cli_json_str(b, "TINV", p->inverse == TSM_INV_ITER ? "iterative" : "fbp");
    }
    cli_json_num(b, "PHOT", p->photons);
    cli_json_str(b, "PHSRC", pipeline_photon_source_name(p->photon_source));
    cli_json_num(b, "RDN", p->read_noise_adu);
    cli_json_str(b, "RDSRC", p->read_noise_source == PIPE_RDN_HEADER ? "header"
                             : p->read_noise_source == PIPE_RDN_SKY ? "sky rms" : "none");
    cli_json_num(b, "GAINE", p->gain_e_per_adu);
    cli_json_str(b, "GNSRC", pipeline_gain_source_name(p->gain_source));
    cli_json_str(b, "reference", o->ref_path ? o->ref_path : "none");
    json_builder_end_object(b);
}

static void recon_report(const recon_args *a, const pipeline_opts *o,
                         const pipeline_result *r, const char *input)
{
    if (a->json) {
        JsonBuilder *b = json_builder_new();
        json_builder_begin_object(b);
        cli_json_str(b, "input", input);
        cli_json_str(b, "output", a->out);
        cli_json_str(b, "method", pipeline_method_name(r->report.method));
        cli_json_str(b, "requested", pipeline_method_name(o->method));
        parameters_json(b, o, &r->report);
        probe_json(b, &r->report.probe);
        binmeas_json(b, &r->binary, r->plate_scale_arcsec);
        json_builder_set_member_name(b, "frames");
        json_builder_add_int_value(b, r->nframes);
        json_builder_set_member_name(b, "width");
        json_builder_add_int_value(b, r->width);
        json_builder_set_member_name(b, "height");
        json_builder_add_int_value(b, r->height);
        cli_json_num(b, "plate_scale_arcsec", r->plate_scale_arcsec);
        cli_json_num(b, "elapsed_s", r->elapsed_s);
        cli_json_num(b, "peak_rss_mb", cli_peak_rss_mb());
        json_builder_end_object(b);
        cli_print_json(b);
        g_object_unref(b);
    } else if (!a->quiet) {
        const pipeline_report *p = &r->report;
        printf("%s: %s of %d frames (%dx%d) -> %s in %.3f s, peak %.0f MB\n",
               input, pipeline_method_name(p->method), r->nframes, r->width,
               r->height, a->out, r->elapsed_s, cli_peak_rss_mb());
        if (p->photons > 0)
            printf("  photon bias: %.0f photons/frame (from %s)\n", p->photons,
                   p->photon_source == PIPE_PHOT_GAIN ? "GAIN and the mean flux"
                   : pipeline_photon_source_name(p->photon_source));
        const pipeline_probe_report *q = &p->probe;
        if (q->probed)
            printf("  skips: reconstructed on %dx%d, %d frame(s) rejected\n", q->crop_w,
                   q->crop_h, q->rejected[1] + q->rejected[2] + q->rejected[3] + q->rejected[4]);
        if (q->chosen)
            printf("  chosen: %s (predicted 1 - c %.3f%s)\n", q->chosen_label, q->pred_error,
                   q->pred_error > q->target_error
                       ? ", above the target: no configuration is expected to meet it" : "");
        binmeas_print(&r->binary, r->plate_scale_arcsec);
    }
}

/* One option through pipeline_opts_set (the daemon's words too); 1, or 0
 * after printing its error. */
static int set_opt(pipeline_opts *o, const char *name, const char *value)
{
    sl_err e = {0};
    if (!value || pipeline_opts_set(o, name, value, &e) == SL_OK)
        return 1;
    fprintf(stderr, "specklab recon: %s\n", e.msg);
    return 0;
}

/* The named choices of recon's options into o; 0 after a usage error. */
static int parse_choices(const recon_args *a, pipeline_opts *o)
{
    return set_opt(o, "method", a->method) && set_opt(o, "skips", a->skips) &&
           set_opt(o, "window", a->window) && set_opt(o, "tsm-phases", a->tsm_phases) &&
           set_opt(o, "tsm-inverse", a->tsm_inverse) &&
           set_opt(o, "phase-weights", a->phase_weights);
}

/* recon's options into o; 0 after a usage error (printed). */
static int opts_from_args(const recon_args *a, pipeline_opts *o)
{
    pipeline_opts_defaults(o);
    if (!parse_choices(a, o))
        return 0;
    o->target_error = a->target_error;
    o->nangles = a->projections;
    o->r2_px = a->r2;
    o->bispec_mem_mb = a->bispec_mb;
    o->prep = !a->no_prep;
    o->learn_badpix = a->learn_badpix;
    o->detect = !a->no_detect;
    o->recentre = !a->no_recentre;
    o->stf_model = !a->no_stf;
    o->badpix_path = a->badpix;
    o->dark_path = a->dark;
    o->flat_path = a->flat;
    o->flat_dark_path = a->flat_dark;
    o->saturation_adu = a->saturation;
    o->photons_per_frame = a->photons;
    o->adu_per_photon = a->gain_adu_per_photon;
    o->ref_path = a->ref;
    o->target_path = a->target;
    o->wiener = a->wiener;
    o->nthreads = a->threads;
    o->refine_iters = a->refine;
    o->closure_binary = a->binary;
    sl_err e = {0};
    if (pipeline_opts_check(o, &e) != SL_OK) {
        fprintf(stderr, "specklab recon: %s\n", e.msg);
        return 0;
    }
    return 1;
}

/* pipeline_opts.progress onto the bar (per mille of the frames fed). */
static void recon_progress(void *ctx, double done, double total, const char *what)
{
    progress_update(ctx, 1000 * done / total, what);
}

/* The image and the PNG may be written (outfile.h): neither is one of the
 * inputs, the reference, the target or a calibration file. */
static int outputs_begin(const recon_args *a, char **inputs, int ninputs,
                         outfile out[3])
{
    GPtrArray *in = g_ptr_array_new();
    for (int i = 0; i < ninputs; i++)
        g_ptr_array_add(in, inputs[i]);
    g_ptr_array_add(in, a->ref);
    g_ptr_array_add(in, a->target);
    g_ptr_array_add(in, a->badpix);
    g_ptr_array_add(in, a->dark);
    g_ptr_array_add(in, a->flat);
    g_ptr_array_add(in, a->flat_dark);
    GError *gerr = NULL;
    const char *const *v = (const char *const *)in->pdata;
    const char *path[3] = {a->out, a->png, a->png_raw};
    int ok = 1;
    for (int i = 0; ok && i < 3; i++)
        ok = !path[i] || outfile_begin(&out[i], path[i], a->overwrite, v, (int)in->len, &gerr);
    if (!ok) {
        fprintf(stderr, "specklab recon: %s\n", gerr->message);
        g_error_free(gerr);
        for (int i = 0; i < 3; i++)
            outfile_clear(&out[i]);
    }
    g_ptr_array_free(in, TRUE);
    return ok;
}

/* --stretch and --cut into the figure's options; 0 after a usage error. */
static int display_from_args(const recon_args *a, skyfig_opts *f)
{
    skyfig_opts_init(f);
    if (a->stretch && preview_stretch_parse(a->stretch, &f->stretch) != SL_OK) {
        fprintf(stderr, "specklab recon: unknown --stretch '%s' (linear, sqrt, asinh)\n", a->stretch);
        return 0;
    }
    if (a->cut && display_cut_parse(a->cut, &f->cut) != SL_OK) {
        fprintf(stderr, "specklab recon: unknown --cut '%s' (artifacts, full)\n", a->cut);
        return 0;
    }
    return 1;
}

/* The figure (--png) and the pixel-exact quick-look (--png-raw), to
 * their temporaries. */
static int write_pngs(const recon_args *a, const outfile out[3], skyfig_opts *f,
                      const pipeline_result *r, const char *input, sl_err *e)
{
    int rc = a->png_raw ? preview_write_png(out[2].tmp, r->image, r->width, r->height,
                                            f->stretch, e) : SL_OK;
    if (rc != SL_OK || !a->png)
        return rc;
    const char *base = strrchr(input, '/');
    skyfig_opts_from_result(f, r, r->meta.object[0] ? NULL : base ? base + 1 : input);
    return skyfig_write_png(out[1].tmp, r->image, r->width, r->height, f, e);
}

/* A rank other than 0 of a split run: its share of the sums, no output
 * (rank 0 recovers the phases and writes the image). */
static int recon_follow(const pipeline_opts *o, char **inputs, int ninputs)
{
    pipeline_result r;
    sl_err e = {0};
    int rc = pipeline_run((const char *const *)inputs, ninputs, o, &r, &e);
    if (rc == SL_EEND) /* its sums are in rank 0's: its part is done */
        return 0;
    if (rc != SL_OK) {
        fprintf(stderr, "specklab recon: rank %d: %s\n", o->share->rank, e.msg);
        return e.code == SL_EINVAL ? 2 : 1;
    }
    pipeline_result_clear(&r);
    return 0;
}

static int recon_run(recon_args *a, char **inputs, int ninputs,
                     const pipeline_share *share)
{
    pipeline_opts o;
    skyfig_opts fig;
    if (!opts_from_args(a, &o) || !display_from_args(a, &fig))
        return 2;
    if (share) {
        /* Plans by rule, not by timing: every rank transforms a frame
         * alike, so the image does not depend on which rank read it. */
        o.fftw_measure = 0;
        o.share = share;
        if (share->rank > 0)
            return recon_follow(&o, inputs, ninputs);
    }
    outfile out[3] = {{0}};
    if (!outputs_begin(a, inputs, ninputs, out))
        return 2;
    pipeline_result r;
    sl_err e = {0};
    int status = 1;
    progress *pg = progress_new(stderr, 1000);
    if (!a->quiet && !a->json) {
        o.progress = recon_progress;
        o.progress_ctx = pg;
    }
    int run = pipeline_run((const char *const *)inputs, ninputs, &o, &r, &e);
    progress_finish(pg);
    progress_free(pg);
    if (run != SL_OK) {
        fprintf(stderr, "specklab recon: %s\n", e.msg);
        status = e.code == SL_EINVAL ? 2 : 1;
        goto clear_outputs;
    }
    if (o.tsm_corrected_phases && r.report.method != PIPE_DIRECT && !r.report.corrected_phases)
        fprintf(stderr, "specklab recon: warning: --tsm-phases corrected needs photon "
                "statistics (header SIMPHOT or --photons); the phases are raw\n");
    seq img = {r.width, r.height, 1, r.image};
    GError *gerr = NULL;
    if (cube_write(out[0].tmp, &img, &r.meta, &e) != SL_OK ||
        write_pngs(a, out, &fig, &r, inputs[0], &e) != SL_OK) {
        fprintf(stderr, "specklab recon: %s\n", e.msg);
    } else if (!outfile_commit(&out[0], &gerr) || (a->png && !outfile_commit(&out[1], &gerr)) ||
               (a->png_raw && !outfile_commit(&out[2], &gerr))) {
        fprintf(stderr, "specklab recon: %s\n", gerr->message);
        g_error_free(gerr);
    } else {
        recon_report(a, &o, &r, inputs[0]);
        status = 0;
    }
    pipeline_result_clear(&r);
clear_outputs:
    for (int i = 0; i < 3; i++)
        outfile_clear(&out[i]);
    return status;
}

int cmd_recon(int argc, char **argv)
{
    return cmd_recon_shared(argc, argv, NULL);
}

int cmd_recon_shared(int argc, char **argv, const pipeline_share *share)
{
    /* `specklab recon RUN-ID`: a catalogued run, reconstructed by the
     * daemon and stored as a new reconstruction row. */
    for (int i = 1; i < argc && !share; i++)
        if (argv[i][0] != '-' && (i == 1 || argv[i - 1][0] != '-' ||
                                  strchr(argv[i - 1], '=')))
            if (cmd_recon_is_run_id(argv[i]))
                return cmd_recon_run(argc, argv);
    recon_args a = {0};
    a.refine = -1;
    GOptionEntry entries[] = {
        {"method", 'm', 0, G_OPTION_ARG_STRING, &a.method, "direct|tsm|tsm-fourier|auto (default auto: chosen from the data)", "M"},
        {"target-error", 0, 0, G_OPTION_ARG_DOUBLE, &a.target_error, "auto: the 1 - c wanted (default 0.1)", "E"},
        {"skips", 0, 0, G_OPTION_ARG_STRING, &a.skips, "reject,crop,support,angles|all|none (default: all for auto, none otherwise)", "LIST"},
        {"projections", 'p', 0, G_OPTION_ARG_INT, &a.projections, "TSM projection angles (default 180)", "N"},
        {"r2-px", 0, 0, G_OPTION_ARG_INT, &a.r2, "direct: |u2| radius in pixels (default 0.14 x frame size, bounded by --bispec-memory-mb)", "PX"},
        {"bispec-memory-mb", 0, 0, G_OPTION_ARG_DOUBLE, &a.bispec_mb, "direct: the default R2 shrinks so that the bispectrum fits this (default 448)", "MB"},
        {"ref", 0, 0, G_OPTION_ARG_FILENAME, &a.ref, "point-source reference sequence (transfer-function calibration)", "FITS"},
        {"target", 0, 0, G_OPTION_ARG_FILENAME, &a.target, "with --ref: PSF wanted in the result (e.g. cophased)", "FITS"},
        {"wiener", 0, 0, G_OPTION_ARG_DOUBLE, &a.wiener, "reference regulariser (default 1e-3 direct, 0.05 TSM)", "X"},
        {"photons", 0, 0, G_OPTION_ARG_DOUBLE, &a.photons, "mean photons per frame (default: header SIMPHOT; <0: not photon data)", "N"},
        {"adu-per-photon", 0, 0, G_OPTION_ARG_DOUBLE, &a.gain_adu_per_photon, "detector gain in ADU per photon (default: header)", "G"},
        {"tsm-inverse", 0, 0, G_OPTION_ARG_STRING, &a.tsm_inverse, "TSM step 6: filtered back projection, or the iterative non-negative inverse (few angles; default fbp)", "fbp|iter"},
        {"tsm-phases", 0, 0, G_OPTION_ARG_STRING, &a.tsm_phases, "TSM phases from the raw or the photon-bias-corrected bispectrum (raw; corrected: better dm from ~1e4 photons/frame)", "raw|corrected"},
        {"window", 0, 0, G_OPTION_ARG_STRING, &a.window, "direct: frame apodisation none|hann|tukey (default tukey)", "W"},
        {"saturation-adu", 0, 0, G_OPTION_ARG_DOUBLE, &a.saturation, "repair raw pixels at or above this", "ADU"},
        {"no-prep", 0, 0, G_OPTION_ARG_NONE, &a.no_prep, "do not clean frames (sky, NaN, saturation)", NULL},
        {"learn-badpix", 0, 0, G_OPTION_ARG_NONE, &a.learn_badpix, "learn the detector from every frame, not the first 32", NULL},
        {"dark", 0, 0, G_OPTION_ARG_FILENAME, &a.dark, "dark or bias: a FITS image, or a cube of them (averaged), in the frames' ADU; subtracted (then no sky is subtracted)", "FITS"},
        {"flat", 0, 0, G_OPTION_ARG_FILENAME, &a.flat, "flat field: an image or a cube (averaged), dark-subtracted unless --flat-dark; divided after normalising to mean 1", "FITS"},
        {"flat-dark", 0, 0, G_OPTION_ARG_FILENAME, &a.flat_dark, "the flat's own dark (an image or a cube), subtracted from the flat first", "FITS"},
        {"badpix", 0, 0, G_OPTION_ARG_FILENAME, &a.badpix, "bad-pixel map: a FITS image of the frame size, nonzero = bad", "FITS"},
        {"no-detect", 0, 0, G_OPTION_ARG_NONE, &a.no_detect, "do not learn the detector from the raw frames (bad pixels, saturation, sky region, recentring)", NULL},
        {"no-recentre", 0, 0, G_OPTION_ARG_NONE, &a.no_recentre, "do not recentre frames on the speckle cloud", NULL},
        {"no-stf", 0, 0, G_OPTION_ARG_NONE, &a.no_stf, "direct on a filled pupil without --ref: keep sqrt(power) as the modulus (no model speckle transfer function)", NULL},
        {"threads", 0, 0, G_OPTION_ARG_INT, &a.threads, "threads (direct: default 2; tsm: online CPUs, at most 4)", "N"},
        {"phase-weights", 0, 0, G_OPTION_ARG_STRING, &a.phase_weights, "direct: weights of the phase recursion mod|snr|unit (default: automatic)", "W"},
        {"refine", 0, 0, G_OPTION_ARG_INT, &a.refine, "direct: least-squares phase passes (default -1: up to 40 when the phase recursion's closure misfit says it went astray; 0: none)", "N"},
        {"binary", 0, 0, G_OPTION_ARG_NONE, &a.binary, "also measure a binary (closure phases, image, power-spectrum fringes) and say whether the data support it: measured, ambiguous, unresolved or inconsistent (header MEAS*, CP*, FR*)", NULL},
        {"output", 'o', 0, G_OPTION_ARG_FILENAME, &a.out, "output FITS image (required)", "FILE"},
        {"png", 0, 0, G_OPTION_ARG_FILENAME, &a.png, "also write a figure: the image enlarged, north up, with title, scale bar, compass and colour bar", "FILE"},
        {"stretch", 0, 0, G_OPTION_ARG_STRING, &a.stretch, "PNG stretch linear|sqrt|asinh (default asinh)", "S"},
        {"cut", 0, 0, G_OPTION_ARG_STRING, &a.cut, "figure's low cut: artifacts (above 9 in 10 of the image's local maxima; default) or full (minimum to maximum)", "C"},
        {"png-raw", 0, 0, G_OPTION_ARG_FILENAME, &a.png_raw, "also write a plain grey PNG, one pixel per image pixel (minimum to maximum, --stretch)", "FILE"},
        {"overwrite", 0, 0, G_OPTION_ARG_NONE, &a.overwrite, "replace existing output files (never an input)", NULL},
        {"json", 0, 0, G_OPTION_ARG_NONE, &a.json, "print one JSON object", NULL},
        {"quiet", 'q', 0, G_OPTION_ARG_NONE, &a.quiet, "print nothing on success", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("CUBE.fits|FRAME.fits...|'GLOB' - reconstruct a speckle sequence");
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_set_description(ctx,
        "Input: a FITS cube (NAXIS3 = frames), or 2-D frames read as one sequence.\n"
        "Output: a 2-D float32 image, frame-sized, object centred; the plate scale\n"
        "is carried over from the input header (PLTSCALE).\n"
        "\n"
        "--method auto probes the first 32 frames (speckle cloud, Fourier support,\n"
        "the image's extent, frame quality, SNR) and runs the cheapest configuration\n"
        "a model calibrated on `specklab bench` expects to reach --target-error\n"
        "(1 - c against a perfect, cophased image; recon/pipeline/autoconf.c).  Skips, also\n"
        "for the fixed methods with --skips: reject empty, saturated and outlier\n"
        "frames; reconstruct on a crop holding the speckle cloud; cut TSM at the\n"
        "measured Fourier support; take TSM's projections from the measured extent.\n"
        "What was measured and chosen goes into the header (RECSKIPS, RECCROP*,\n"
        "RECREJ*, RECSUPP, RECEXTNT, RECSNR, RECCHOSE, RECPRED) and into --json.");
    int status = 2;
    if (!cli_parse(ctx, &argc, &argv))
        goto free_ctx;
    if (argc < 2 || !a.out) {
        fprintf(stderr, "specklab recon: need an input sequence and -o FILE (try --help)\n");
        goto free_ctx;
    }
    status = recon_run(&a, argv + 1, argc - 1, share);
free_ctx:
    g_option_context_free(ctx);
    g_free(a.method); g_free(a.out); g_free(a.png); g_free(a.ref);
    g_free(a.target); g_free(a.window); g_free(a.tsm_phases); g_free(a.tsm_inverse); g_free(a.stretch); g_free(a.cut); g_free(a.png_raw); g_free(a.skips); g_free(a.badpix); g_free(a.phase_weights);
    g_free(a.dark); g_free(a.flat); g_free(a.flat_dark);
    return status;
}
