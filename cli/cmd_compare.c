/* cmd_compare.c - `specklab compare` and `specklab binary`: compare two
 * images, measure a binary on an image or on a cube (direct, in memory). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "binmeas.h"
#include "cli.h"
#include "io/cube.h"
#include "measure/metrics.h"
#include "pipeline/pipeline.h"
#include "wds.h"

/* Read a 2-D image from the primary HDU, or from extension ext (a separate
 * option rather than FILE[EXT] syntax, so any path stays a path). */
static int read_image(const char *path, const char *ext, seq **out, sl_err *e)
{
    if (ext)
        return cube_read_ext(out, path, ext, e);
    const char *paths[] = {path};
    int rc = cube_read(out, NULL, paths, 1, 0, e);
    if (rc == SL_OK && (*out)->nframes != 1) {
        rc = sl_seterr(e, SL_EFORMAT, "%s has %d frames: expected a 2-D image "
                       "(reconstruct it first)", path, (*out)->nframes);
        seq_free(*out);
        *out = NULL;
    }
    return rc;
}

int cmd_compare(int argc, char **argv)
{
    char *ext_a = NULL, *ext_b = NULL;
    int json = 0, status = 2;
    seq *a = NULL, *b = NULL;
    GOptionEntry entries[] = {
        {"ext-a", 0, 0, G_OPTION_ARG_STRING, &ext_a, "read A from this image extension (e.g. COPHASED)", "EXT"},
        {"ext-b", 0, 0, G_OPTION_ARG_STRING, &ext_b, "read B from this image extension", "EXT"},
        {"json", 0, 0, G_OPTION_ARG_NONE, &json, "print JSON", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("A.fits B.fits - correlation coefficient c after sub-pixel registration");
    g_option_context_add_main_entries(ctx, entries, NULL);
    if (!cli_parse(ctx, &argc, &argv))
        goto free_ctx;
    if (argc != 3) {
        fprintf(stderr, "specklab compare: need two images A.fits B.fits\n");
        goto free_ctx;
    }
    status = 1;
    sl_err e = {0};
    if (read_image(argv[1], ext_a, &a, &e) != SL_OK || read_image(argv[2], ext_b, &b, &e) != SL_OK) {
        fprintf(stderr, "specklab compare: %s\n", e.msg);
        goto free_imgs;
    }
    if (a->width != b->width || a->height != b->height) {
        fprintf(stderr, "specklab compare: %s is %dx%d but %s is %dx%d\n", argv[1],
                a->width, a->height, argv[2], b->width, b->height);
        goto free_imgs;
    }
    double c = NAN, dx = 0, dy = 0;
    if (metrics_corr_registered(a->data, b->data, a->width, a->height, &c, &dx, &dy) != SL_OK) {
        fprintf(stderr, "specklab compare: registration failed\n");
        goto free_imgs;
    }
    if (json) {
        JsonBuilder *jb = json_builder_new();
        json_builder_begin_object(jb);
        cli_json_num(jb, "c", c);
        cli_json_num(jb, "c_unregistered", metrics_corr(a->data, b->data, a->width, a->height));
        cli_json_num(jb, "shift_x_px", dx);
        cli_json_num(jb, "shift_y_px", dy);
        json_builder_end_object(jb);
        cli_print_json(jb);
        g_object_unref(jb);
    } else {
        printf("c = %.4f (B shifted by %+.3f, %+.3f px onto A)\n", c, dx, dy);
    }
    status = 0;
free_imgs:
    seq_free(a);
    seq_free(b);
free_ctx:
    g_option_context_free(ctx);
    g_free(ext_a);
    g_free(ext_b);
    return status;
}

/* The image fit, and the verdict of the reconstruction's own fits when
 * there is one (v: status NONE when not). */
static void binary_report(const binary_result *b, const pipeline_binary *v,
                          double ps, int json)
{
    if (json) {
        JsonBuilder *jb = json_builder_new();
        json_builder_begin_object(jb);
        if (b) {
            cli_json_num(jb, "sep_px", b->sep_px);
            cli_json_num(jb, "sep_err_px", b->sep_err_px);
            cli_json_num(jb, "pa_deg", b->pa_deg);
            cli_json_num(jb, "pa_err_deg", b->pa_err_deg);
            cli_json_num(jb, "dm_mag", b->dm_mag);
            cli_json_num(jb, "dm_err_mag", b->dm_err_mag);
            cli_json_num(jb, "flux_ratio", b->flux_ratio);
            cli_json_num(jb, "err_inflation", b->err_inflation);
            cli_json_num(jb, "sep_arcsec", b->sep_px * ps);
            cli_json_num(jb, "sep_err_arcsec", b->sep_err_px * ps);
            json_builder_set_member_name(jb, "pa_ambiguous");
            json_builder_add_boolean_value(jb, b->pa_ambiguous);
        }
        binmeas_json(jb, v, ps);
        json_builder_end_object(jb);
        cli_print_json(jb);
        g_object_unref(jb);
        return;
    }
    if (b) {
        printf("image: sep %.3f +- %.3f px", b->sep_px, b->sep_err_px);
        if (isfinite(ps))
            printf(" (%.4f +- %.4f arcsec)", b->sep_px * ps, b->sep_err_px * ps);
        printf(", PA %.2f +- %.2f deg%s, dm %.3f +- %.3f mag\n", b->pa_deg,
               b->pa_err_deg, b->pa_ambiguous ? " (or +180: equal stars)" : "",
               b->dm_mag, b->dm_err_mag);
    } else {
        printf("image: no second component found\n");
    }
    binmeas_print(v, ps);
}

/* A cube: reconstruct it with direct (in memory, nothing written) and
 * measure the image and the bispectrum's closure phases. */
static int binary_of_cube(const char *path, int json)
{
    pipeline_opts o;
    pipeline_opts_defaults(&o);
    o.method = PIPE_DIRECT;
    o.closure_binary = 1;
    pipeline_result r;
    sl_err e = {0};
    const char *paths[] = {path};
    if (pipeline_run(paths, 1, &o, &r, &e) != SL_OK) {
        fprintf(stderr, "specklab binary: %s\n", e.msg);
        return 1;
    }
    const pipeline_binary *v = &r.binary;
    binary_report(v->have_image ? &v->image : NULL, v, r.plate_scale_arcsec, json);
    int status = v->status == PIPE_BIN_UNRESOLVED ? 1 : 0;
    if (status)
        fprintf(stderr, "specklab binary: no companion resolved in %s: %s\n",
                path, v->why);
    pipeline_result_clear(&r);
    return status;
}

int cmd_binary(int argc, char **argv)
{
    char *ext = NULL;
    int json = 0, status = 2, wds = 0;
    seq *img = NULL;
    cube_meta m;
    GOptionEntry entries[] = {
        {"ext", 0, 0, G_OPTION_ARG_STRING, &ext, "read the image from this extension", "EXT"},
        {"json", 0, 0, G_OPTION_ARG_NONE, &json, "print JSON", NULL},
        {"wds", 0, 0, G_OPTION_ARG_NONE, &wds, "print one WDS-style measure: Besselian epoch, theta, rho [arcsec], dm with errors (cli/wds.h)", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("IMAGE.fits|CUBE.fits - separation, position angle and dm of a binary");
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_set_description(ctx,
        "PA is measured from +y (north) towards -x (east), fainter relative to brighter.\n"
        "An image is fitted as it is (recon/measure/binary.h); one that `recon -m direct\n"
        "--binary` made also reports its closure-phase fit (recon/spectra/closure.h).  A cube\n"
        "(NAXIS3 > 1) is first reconstructed with direct, in memory, and gets both.");
    if (!cli_parse(ctx, &argc, &argv))
        goto free_ctx;
    if (argc != 2) {
        fprintf(stderr, "specklab binary: need one image or cube\n");
        goto free_ctx;
    }
    status = 1;
    if (wds) {
        status = wds_binary(argv[1], ext, json);
        goto free_ctx;
    }
    sl_err e = {0};
    const char *paths[] = {argv[1]};
    if (!ext) {
        cube_reader *cr = NULL;
        int nfr = cube_reader_open(&cr, paths, 1, 0, &e) == SL_OK ? cube_reader_nframes(cr) : 0;
        cube_reader_free(cr);
        if (nfr > 1) {
            status = binary_of_cube(argv[1], json);
            goto free_ctx;
        }
    }
    int rc = ext ? cube_read_ext(&img, argv[1], ext, &e) : cube_read(&img, &m, paths, 1, 0, &e);
    if (rc == SL_OK && ext) {
        cube_reader *r = NULL;
        cube_meta_init(&m);
        if (cube_reader_open(&r, paths, 1, 0, &e) == SL_OK)
            m = *cube_reader_meta(r);
        cube_reader_free(r);
    }
    if (rc != SL_OK || img->nframes != 1) {
        fprintf(stderr, "specklab binary: %s\n", rc != SL_OK ? e.msg : "expected a 2-D image");
        goto free_img;
    }
    binary_result b;
    pipeline_binary v; /* the reconstruction's own verdict, when recon --binary left one */
    binmeas_from_header(&m, &v);
    int found = metrics_binary(img->data, img->width, img->height, &b) == SL_OK;
    if (!found && v.status == PIPE_BIN_NONE) {
        fprintf(stderr, "specklab binary: no second component found in %s\n", argv[1]);
        goto free_img;
    }
    binary_report(found ? &b : NULL, &v, m.plate_scale_arcsec, json);
    status = v.status == PIPE_BIN_UNRESOLVED || (!found && v.source == PIPE_BIN_SRC_NONE);
free_img:
    seq_free(img);
free_ctx:
    g_option_context_free(ctx);
    g_free(ext);
    return status;
}
