/* binmeas.c - how the CLI reports a measured binary: the verdict of
 * pipeline.h's pipeline_binary (measured, ambiguous, unresolved,
 * inconsistent), from a reconstruction run here or read back from the
 * MEAS* and CP* keywords of an image that `recon --binary` wrote. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "binmeas.h"

static int status_of(const char *name)
{
    for (int s = PIPE_BIN_MEASURED; s <= PIPE_BIN_INCONSISTENT; s++)
        if (!strcmp(name, pipeline_binary_status_name(s)))
            return s;
    return PIPE_BIN_NONE;
}

static int source_of(const char *name)
{
    for (int s = PIPE_BIN_SRC_CLOSURE; s <= PIPE_BIN_SRC_FRINGE; s++)
        if (!strcmp(name, pipeline_binary_source_name(s)))
            return s;
    return PIPE_BIN_SRC_NONE;
}

void binmeas_from_header(const cube_meta *m, pipeline_binary *r)
{
    memset(r, 0, sizeof *r);
    const char *st, *src, *why;
    if (cube_meta_get_str(m, "MEASSTAT", &st) != SL_OK)
        return;
    r->status = status_of(st);
    if (cube_meta_get_str(m, "MEASSRC", &src) == SL_OK)
        r->source = source_of(src);
    if (cube_meta_get_str(m, "MEASWHY", &why) == SL_OK)
        snprintf(r->why, sizeof r->why, "%s", why);
    const struct { const char *key; double *v; } nums[] = {
        {"MEASSEP", &r->sep_px}, {"MEASSEPE", &r->sep_err_px},
        {"MEASPA", &r->pa_deg}, {"MEASPAE", &r->pa_err_deg},
        {"MEASDM", &r->dm_mag}, {"MEASDME", &r->dm_err_mag}};
    for (size_t i = 0; i < sizeof nums / sizeof nums[0]; i++)
        cube_meta_get_num(m, nums[i].key, nums[i].v);
    const char *cps;
    r->have_closure = cube_meta_get_str(m, "CPSTAT", &cps) == SL_OK && !strcmp(cps, "ok") &&
                      cube_meta_get_num(m, "CPSEP", &r->closure.sep_px) == SL_OK &&
                      cube_meta_get_num(m, "CPPA", &r->closure.pa_deg) == SL_OK &&
                      cube_meta_get_num(m, "CPDM", &r->closure.dm_mag) == SL_OK;
    cube_meta_get_num(m, "CPSEPE", &r->closure.sep_err_px);
    cube_meta_get_num(m, "CPPAE", &r->closure.pa_err_deg);
    cube_meta_get_num(m, "CPDME", &r->closure.dm_err_mag);
    double v = 0;
    if (cube_meta_get_num(m, "CPAMBIG", &v) == SL_OK)
        r->closure.pa_ambiguous = v != 0;
    if (cube_meta_get_num(m, "CPNTRI", &v) == SL_OK)
        r->closure_info.ntriples = (long)v;
}

static void fit_json(JsonBuilder *b, const char *name, const binary_result *f,
                     double ps)
{
    json_builder_set_member_name(b, name);
    json_builder_begin_object(b);
    cli_json_num(b, "sep_px", f->sep_px);
    cli_json_num(b, "sep_err_px", f->sep_err_px);
    cli_json_num(b, "pa_deg", f->pa_deg);
    cli_json_num(b, "pa_err_deg", f->pa_err_deg);
    cli_json_num(b, "dm_mag", f->dm_mag);
    cli_json_num(b, "dm_err_mag", f->dm_err_mag);
    cli_json_num(b, "sep_arcsec", f->sep_px * ps);
    json_builder_set_member_name(b, "pa_ambiguous");
    json_builder_add_boolean_value(b, f->pa_ambiguous != 0);
    json_builder_end_object(b);
}

void binmeas_json(JsonBuilder *b, const pipeline_binary *r, double ps)
{
    if (r->status == PIPE_BIN_NONE)
        return;
    json_builder_set_member_name(b, "binary");
    json_builder_begin_object(b);
    cli_json_str(b, "status", pipeline_binary_status_name(r->status));
    cli_json_str(b, "source", pipeline_binary_source_name(r->source));
    cli_json_str(b, "why", r->why);
    if (r->source != PIPE_BIN_SRC_NONE) {
        cli_json_num(b, "sep_px", r->sep_px);
        cli_json_num(b, "sep_err_px", r->sep_err_px);
        cli_json_num(b, "sep_arcsec", r->sep_px * ps);
        cli_json_num(b, "pa_deg", r->pa_deg);
        cli_json_num(b, "pa_err_deg", r->pa_err_deg);
        cli_json_num(b, "dm_mag", r->dm_mag);
        cli_json_num(b, "dm_err_mag", r->dm_err_mag);
        json_builder_set_member_name(b, "pa_modulo_180");
        json_builder_add_boolean_value(b, r->status == PIPE_BIN_AMBIGUOUS);
    }
    json_builder_end_object(b);
    if (r->have_closure)
        fit_json(b, "closure_phase", &r->closure, ps);
    if (r->have_fringe) {
        binary_result f = {0};
        f.sep_px = r->fringe.sep_px, f.sep_err_px = r->fringe.sep_err_px;
        f.pa_deg = r->fringe.pa_deg, f.pa_err_deg = r->fringe.pa_err_deg;
        f.dm_mag = r->fringe.dm_mag, f.dm_err_mag = r->fringe.dm_err_mag;
        f.pa_ambiguous = 1;
        fit_json(b, "fringe", &f, ps);
    }
}

void binmeas_print(const pipeline_binary *r, double ps)
{
    if (r->status == PIPE_BIN_NONE)
        return;
    printf("  binary: %s", pipeline_binary_status_name(r->status));
    if (r->source == PIPE_BIN_SRC_NONE) {
        printf(" (%s)\n", r->why);
        return;
    }
    static const char *from[] = {"", "closure phases", "the image", "the power spectrum's fringes"};
    printf(", from %s: sep %.3f +- %.3f px", from[r->source], r->sep_px, r->sep_err_px);
    if (isfinite(ps))
        printf(" (%.4f arcsec)", r->sep_px * ps);
    printf(", PA %.2f +- %.2f deg%s, dm %.3f +- %.3f mag\n", r->pa_deg, r->pa_err_deg,
           r->status == PIPE_BIN_AMBIGUOUS ? " (or +180)" : "", r->dm_mag, r->dm_err_mag);
    if (r->why[0])
        printf("          (%s)\n", r->why);
}
