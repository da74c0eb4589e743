/* pipeline_optset.c - the reconstruction's options: their defaults, and
 * pipeline_opts_set, one option by the CLI's name and its value as text.  The CLI parses its own command line
 * through it and specklabd the options a client sends for a catalogued
 * run, so both accept the same names and values and refuse the same
 * nonsense with the same words.  The option's range is pipeline_check.c's
 * business (pipeline_opts_check), not this file's: here only the syntax.
 */
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline.h"
#include "spectra/powspec.h"
#include "tsm/tsm.h"

enum kind { K_INT, K_DOUBLE, K_FLAG, K_NOFLAG, K_CHOICE, K_METHOD, K_SKIPS };

typedef struct choice {
    const char *name;
    int value;
} choice;

static const choice windows[] = {{"none", POWSPEC_WIN_NONE}, {"hann", POWSPEC_WIN_HANN},
                                 {"tukey", POWSPEC_WIN_TUKEY}, {NULL, 0}};
static const choice phases[] = {{"raw", 0}, {"corrected", 1}, {NULL, 0}};
static const choice inverses[] = {{"fbp", TSM_INV_AUTO}, {"iter", TSM_INV_ITER}, {NULL, 0}};
static const choice weights[] = {{"mod", 0}, {"snr", 1}, {"unit", 2}, {NULL, 0}};

typedef struct optdef {
    const char *name;
    enum kind kind;
    size_t off;              /* of the int or double in pipeline_opts */
    const choice *choices;   /* K_CHOICE */
} optdef;

#define F(field) offsetof(pipeline_opts, field)
static const optdef defs[] = {
    {"method", K_METHOD, F(method), NULL},
    {"skips", K_SKIPS, F(skips), NULL},
    {"target-error", K_DOUBLE, F(target_error), NULL},
    {"projections", K_INT, F(nangles), NULL},
    {"r2-px", K_INT, F(r2_px), NULL},
    {"bispec-memory-mb", K_DOUBLE, F(bispec_mem_mb), NULL},
    {"wiener", K_DOUBLE, F(wiener), NULL},
    {"photons", K_DOUBLE, F(photons_per_frame), NULL},
    {"adu-per-photon", K_DOUBLE, F(adu_per_photon), NULL},
    {"tsm-inverse", K_CHOICE, F(tsm_inverse), inverses},
    {"tsm-phases", K_CHOICE, F(tsm_corrected_phases), phases},
    {"window", K_CHOICE, F(window), windows},
    {"saturation-adu", K_DOUBLE, F(saturation_adu), NULL},
    {"no-prep", K_NOFLAG, F(prep), NULL},
    {"learn-badpix", K_FLAG, F(learn_badpix), NULL},
    {"no-detect", K_NOFLAG, F(detect), NULL},
    {"no-recentre", K_NOFLAG, F(recentre), NULL},
    {"no-stf", K_NOFLAG, F(stf_model), NULL},
    {"threads", K_INT, F(nthreads), NULL},
    {"phase-weights", K_CHOICE, F(phase_weight), weights},
    {"refine", K_INT, F(refine_iters), NULL},
    {"binary", K_FLAG, F(closure_binary), NULL},
};
#undef F

void pipeline_opts_defaults(pipeline_opts *o)
{
    memset(o, 0, sizeof *o);
    /* auto: the method, crop and angles chosen from the data (probe.h,
     * autoconf.h); the one default the CLI and specklabd share */
    o->method = PIPE_AUTO;
    o->window = POWSPEC_WIN_TUKEY;
    o->tukey_alpha = 0.25;
    o->prep = 1;
    o->detect = 1;
    o->recentre = 1;
    o->stf_model = 1;
    o->fftw_measure = 1;
    o->skips = -1;
    o->refine_iters = -1;
    o->phase_weight = -1;
}

const char *pipeline_opts_name(int i, int *is_flag)
{
    if (i < 0 || i >= (int)(sizeof defs / sizeof defs[0]))
        return NULL;
    if (is_flag)
        *is_flag = defs[i].kind == K_FLAG || defs[i].kind == K_NOFLAG;
    return defs[i].name;
}

static int set_choice(const optdef *d, const choice *c, const char *value, int *out,
                      sl_err *err)
{
    char names[96] = "";
    for (int i = 0; c[i].name; i++) {
        if (!strcmp(value, c[i].name)) {
            *out = c[i].value;
            return SL_OK;
        }
        size_t n = strlen(names);
        snprintf(names + n, sizeof names - n, "%s%s", i ? ", " : "", c[i].name);
    }
    return sl_seterr(err, SL_EINVAL, "unknown --%s '%s' (%s)", d->name, value, names);
}

/* A flag's value: "" or "true" sets it, "false" leaves the default. */
static int set_flag(const optdef *d, const char *value, int on, int *out, sl_err *err)
{
    if (!strcmp(value, "false"))
        return SL_OK;
    if (*value && strcmp(value, "true"))
        return sl_seterr(err, SL_EINVAL, "--%s takes no value (or true/false), got '%s'",
                         d->name, value);
    *out = on;
    return SL_OK;
}

static int set_number(const optdef *d, const char *value, void *field, sl_err *err)
{
    char *end = NULL;
    errno = 0;
    if (d->kind == K_INT) {
        long v = strtol(value, &end, 10);
        if (end == value || *end || errno || v < -2147483647L || v > 2147483647L)
            return sl_seterr(err, SL_EINVAL, "--%s '%s': not an integer", d->name, value);
        *(int *)field = (int)v;
    } else {
        double v = strtod(value, &end);
        if (end == value || *end || !isfinite(v))
            return sl_seterr(err, SL_EINVAL, "--%s '%s': not a finite number", d->name,
                             value);
        *(double *)field = v;
    }
    return SL_OK;
}

int pipeline_opts_set(pipeline_opts *o, const char *name, const char *value, sl_err *err)
{
    const optdef *d = NULL;
    for (size_t i = 0; !d && name && i < sizeof defs / sizeof defs[0]; i++)
        if (!strcmp(defs[i].name, name))
            d = &defs[i];
    if (!d)
        return sl_seterr(err, SL_EINVAL, "unknown option --%s", name ? name : "(null)");
    if (!value)
        value = "";
    void *field = (char *)o + d->off;
    switch (d->kind) {
    case K_METHOD:
        if (pipeline_method_parse(value, field) != SL_OK)
            return sl_seterr(err, SL_EINVAL, "unknown --method '%s' (direct, tsm, "
                             "tsm-fourier, auto)", value);
        return SL_OK;
    case K_SKIPS: {
        int skips;   /* a refusal changes nothing */
        if (pipeline_skips_parse(value, &skips) != SL_OK)
            return sl_seterr(err, SL_EINVAL, "--skips '%s': a list of reject, crop, "
                             "support, angles, or all, none", value);
        *(int *)field = skips;
        return SL_OK;
    }
    case K_CHOICE:
        return set_choice(d, d->choices, value, field, err);
    case K_FLAG:
    case K_NOFLAG:
        return set_flag(d, value, d->kind == K_FLAG, field, err);
    default:
        return set_number(d, value, field, err);
    }
}
