/* cmd_mask.c - `specklab mask generate|show`: aperture masks. */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "outfile.h"
#include "sim/mask.h"

static int load(const char *name, mask **m, sl_err *e)
{
    if (!strcmp(name, "nrm17") || !strcmp(name, "full"))
        return mask_named(m, name, e);
    return mask_read(m, name, e);
}

static void show(const mask *m, int json)
{
    int n = mask_nholes(m);
    if (json) {
        JsonBuilder *b = json_builder_new();
        json_builder_begin_object(b);
        json_builder_set_member_name(b, "name");
        json_builder_add_string_value(b, mask_name(m));
        json_builder_set_member_name(b, "holes");
        json_builder_add_int_value(b, n);
        json_builder_set_member_name(b, "extent_m");
        json_builder_add_double_value(b, mask_extent_m(m));
        if (n > 0) {
            json_builder_set_member_name(b, "hole_diameter_m");
            json_builder_add_double_value(b, mask_hole_diameter_m(m));
            json_builder_set_member_name(b, "max_baseline_m");
            json_builder_add_double_value(b, mask_max_baseline_m(m));
            json_builder_set_member_name(b, "min_spacing_m");
            json_builder_add_double_value(b, mask_min_spacing_m(m));
            json_builder_set_member_name(b, "redundancy");
            json_builder_add_int_value(b, mask_redundancy(m));
            json_builder_set_member_name(b, "centres_m");
            json_builder_begin_array(b);
            for (int i = 0; i < n; i++) {
                double x, y;
                mask_hole(m, i, &x, &y);
                json_builder_begin_array(b);
                json_builder_add_double_value(b, x);
                json_builder_add_double_value(b, y);
                json_builder_end_array(b);
            }
            json_builder_end_array(b);
        }
        json_builder_end_object(b);
        cli_print_json(b);
        g_object_unref(b);
        return;
    }
    if (n == 0) {
        printf("%s: filled aperture, diameter %.3f m\n", mask_name(m),
               mask_diameter_m(m));
        return;
    }
    printf("%s: %d holes of %.3f m, baselines %.3f..%.3f m, extent %.3f m, "
           "redundancy %ld (baseline pairs closer than a hole diameter)\n",
           mask_name(m), n, mask_hole_diameter_m(m), mask_min_spacing_m(m),
           mask_max_baseline_m(m), mask_extent_m(m), mask_redundancy(m));
}

int cmd_mask(int argc, char **argv)
{
    mask_gen_opts g;
    mask_gen_defaults(&g);
    gint64 seed = (gint64)g.seed;
    char *out = NULL;
    int json = 0, overwrite = 0, status = 2;
    outfile of = {0};
    mask *m = NULL;
    sl_err e = {0};
    GOptionEntry entries[] = {
        {"holes", 0, 0, G_OPTION_ARG_INT, &g.nholes, "holes (default 17)", "N"},
        {"hole-diameter-m", 0, 0, G_OPTION_ARG_DOUBLE, &g.hole_diameter_m, "hole diameter (default 0.1)", "M"},
        {"max-baseline-m", 0, 0, G_OPTION_ARG_DOUBLE, &g.max_baseline_m, "longest baseline (default 1.0)", "M"},
        {"min-spacing-m", 0, 0, G_OPTION_ARG_DOUBLE, &g.min_spacing_m, "shortest baseline (default 0.2)", "M"},
        {"seed", 0, 0, G_OPTION_ARG_INT64, &seed, "search seed (default 17)", "N"},
        {"iterations", 0, 0, G_OPTION_ARG_INT, &g.iterations, "annealing moves per restart", "N"},
        {"output", 'o', 0, G_OPTION_ARG_FILENAME, &out, "write the mask file", "FILE"},
        {"overwrite", 0, 0, G_OPTION_ARG_NONE, &overwrite, "replace an existing mask file", NULL},
        {"json", 0, 0, G_OPTION_ARG_NONE, &json, "print JSON", NULL},
        {NULL, 0, 0, 0, NULL, NULL, NULL}};
    GOptionContext *ctx = g_option_context_new("generate | show NAME|FILE");
    g_option_context_add_main_entries(ctx, entries, NULL);
    g_option_context_set_description(ctx,
        "generate: search a least-redundant N-hole layout and report the redundancy reached.\n"
        "show: describe nrm17, full, or a mask file ('hole_diameter_m D' then 'x_m y_m' lines).");
    if (!cli_parse(ctx, &argc, &argv))
        goto free_ctx;
    GError *ge = NULL;
    const char *in[] = {argc == 3 ? argv[2] : NULL};
    if (out && !outfile_begin(&of, out, overwrite, in, 1, &ge)) {
        fprintf(stderr, "specklab mask: %s\n", ge->message);
        g_error_free(ge);
        goto free_ctx;
    }
    int rc;
    if (argc == 2 && !strcmp(argv[1], "generate")) {
        g.seed = (uint64_t)seed;
        rc = mask_generate(&m, &g, &e);
    } else if (argc == 3 && !strcmp(argv[1], "show")) {
        rc = load(argv[2], &m, &e);
    } else {
        fprintf(stderr, "specklab mask: expected 'generate' or 'show NAME|FILE'\n");
        goto free_ctx;
    }
    status = 1;
    if (rc != SL_OK) {
        fprintf(stderr, "specklab mask: %s\n", e.msg);
        goto free_ctx;
    }
    if (out && mask_write(m, of.tmp, &e) != SL_OK) {
        fprintf(stderr, "specklab mask: %s\n", e.msg);
        goto free_mask;
    }
    if (out && !outfile_commit(&of, &ge)) {
        fprintf(stderr, "specklab mask: %s\n", ge->message);
        g_error_free(ge);
        goto free_mask;
    }
    show(m, json);
    status = 0;
free_mask:
    mask_free(m);
free_ctx:
    outfile_clear(&of);
    g_option_context_free(ctx);
    g_free(out);
    return status;
}
