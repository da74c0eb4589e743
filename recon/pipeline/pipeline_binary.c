/* pipeline_binary.c - the binary measured on a reconstruction, and what
 * the data can support of it (pipeline.h, pipeline_binary).
 *
 * Three fits see the same data differently:
 *  - the image fit (binary.h) needs the companion resolved from the core;
 *  - the fringe fit (fringe.h) reads |d| and the flux ratio from the
 *    power spectrum alone, the PA only modulo 180 deg, and only through a
 *    filled pupil;
 *  - the closure fit (closure.h) reads d, its sign and r from the
 *    bispectrum's phases, but needs a start within a few pixels.
 * The closure fit starts from every other fit that found a companion and
 * keeps the start whose fit leaves the smaller residual.  The verdict:
 *  - measured: the closure fit (else the image fit) with its errors;
 *  - ambiguous: the sign of d is not supported (an equal pair, or the
 *    fits from d and -d end within chi^2 25 of each other): the PA is
 *    stated modulo 180 deg;
 *  - inconsistent: the fits disagree beyond max(3 sigma, 0.5 px / 5 deg);
 *  - unresolved: no fit found a companion above its noise, or the closure
 *    phases do not back the one found (DETECT_SIGMA, DETECT_CHI2).
 * A confident wrong binary is worse than none: nothing is called measured
 * unless the data back it.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "pipeline_int.h"

#define SIGN_CHI2_MIN 25.0
#define FRINGE_MAX_SEP_PX 16.0
/* A companion needs r above 5 of its (jackknife) sigmas and the closure
 * phases to fit 50 chi^2 better with it than without: a reconstructed
 * point source's residual closure phases (60 noiseless frames through the
 * mask) fit a dm 4.3-4.8 "companion" at 3.1-3.4 sigma, chi^2 44-108;
 * real companions from dm 1 to 2 at 1e4 photons or more sit at 20 sigma
 * and thousands. */
#define DETECT_SIGMA 5.0
#define DETECT_CHI2 50.0

static const char *status_names[] = {"none", "measured", "ambiguous",
                                     "unresolved", "inconsistent"};
static const char *source_names[] = {"none", "closure", "image", "fringe"};

const char *pipeline_binary_status_name(int s)
{
    return s >= 0 && s <= PIPE_BIN_INCONSISTENT ? status_names[s] : "unknown";
}

const char *pipeline_binary_source_name(int s)
{
    return s >= 0 && s <= PIPE_BIN_SRC_FRINGE ? source_names[s] : "unknown";
}

/* A start for the closure fit from the fringe fit's d and r. */
static binary_result fringe_start(const fringe_result *f)
{
    binary_result b;
    memset(&b, 0, sizeof b);
    b.dx_px = f->dx_px, b.dy_px = f->dy_px;
    b.sep_px = f->sep_px, b.pa_deg = f->pa_deg;
    b.flux_ratio = fmin(f->flux_ratio, 0.95);
    b.dm_mag = f->dm_mag;
    b.sep_err_px = f->sep_err_px, b.pa_err_deg = f->pa_err_deg;
    b.dm_err_mag = f->dm_err_mag;
    return b;
}

/* Angle between two PAs in degrees, modulo 360 or (mod180) 180. */
static double pa_diff(double a, double b, int mod180)
{
    double m = mod180 ? 180 : 360, d = fmod(fabs(a - b), m);
    return d > m / 2 ? m - d : d;
}

/* 1 when fit b disagrees with a (the measurement) beyond its errors. */
static int disagree(const pipeline_binary *a, double sep, double sep_e,
                    double pa, double pa_e, int mod180)
{
    double ds = fabs(sep - a->sep_px);
    double dp = pa_diff(pa, a->pa_deg, mod180);
    double es = sqrt(sep_e * sep_e + a->sep_err_px * a->sep_err_px);
    double ep = sqrt(pa_e * pa_e + a->pa_err_deg * a->pa_err_deg);
    return ds > fmax(3 * es, 0.5) || dp > fmax(3 * ep, 5);
}

static void set_meas(pipeline_binary *r, int source, const binary_result *b)
{
    r->source = source;
    r->sep_px = b->sep_px, r->sep_err_px = b->sep_err_px;
    r->pa_deg = b->pa_deg, r->pa_err_deg = b->pa_err_deg;
    r->dm_mag = b->dm_mag, r->dm_err_mag = b->dm_err_mag;
}

/* The closure fit from each start (closure.h: the triples chosen once,
 * the smaller weighted residual wins). */
static void closure_from_starts(const pipe_binary_in *in, pipeline_binary *r,
                                const char **why)
{
    binary_result starts[2], cp;
    closure_fit_info info;
    int ns = 0;
    if (r->have_image)
        starts[ns++] = r->image;
    if (r->have_fringe)
        starts[ns++] = fringe_start(&r->fringe);
    if (ns == 0)
        return;
    int rc = in->b ? bispec_binary(in->b, ns, starts, &cp, &info)
                   : tsm_binary(in->t, ns, starts, &cp, &info);
    if (rc != SL_OK) {
        *why = in->b ? bispec_errmsg(in->b) : tsm_errmsg(in->t);
        return;
    }
    r->closure = cp;
    r->closure_info = info;
    r->have_closure = 1;
}

static void verdict(pipeline_binary *r, const char *why)
{
    if (r->have_closure && r->closure.flux_ratio > DETECT_SIGMA * r->closure.flux_ratio_err &&
        r->closure_info.detect_chi2 > DETECT_CHI2) {
        set_meas(r, PIPE_BIN_SRC_CLOSURE, &r->closure);
        r->status = PIPE_BIN_MEASURED;
        if (r->closure.pa_ambiguous || r->closure_info.sign_chi2 < SIGN_CHI2_MIN) {
            r->status = PIPE_BIN_AMBIGUOUS;
            snprintf(r->why, sizeof r->why, "closure phases hardly tell d from "
                     "-d (chi2 %.1f): PA +- 180", r->closure_info.sign_chi2);
        }
    } else if (r->have_closure) {
        r->status = PIPE_BIN_UNRESOLVED;
        snprintf(r->why, sizeof r->why, "closure phases: companion r %.3f +- "
                 "%.3f, not significant", r->closure.flux_ratio,
                 r->closure.flux_ratio_err);
        return;
    } else if (r->have_image) {
        set_meas(r, PIPE_BIN_SRC_IMAGE, &r->image);
        r->status = r->image.pa_ambiguous ? PIPE_BIN_AMBIGUOUS : PIPE_BIN_MEASURED;
        snprintf(r->why, sizeof r->why, "%.95s", why);
    } else if (r->have_fringe) {
        r->source = PIPE_BIN_SRC_FRINGE;
        r->sep_px = r->fringe.sep_px, r->sep_err_px = r->fringe.sep_err_px;
        r->pa_deg = r->fringe.pa_deg, r->pa_err_deg = r->fringe.pa_err_deg;
        r->dm_mag = r->fringe.dm_mag, r->dm_err_mag = r->fringe.dm_err_mag;
        r->status = PIPE_BIN_AMBIGUOUS;
        snprintf(r->why, sizeof r->why, "power-spectrum fringes only: PA +- 180");
    } else {
        r->status = PIPE_BIN_UNRESOLVED;
        snprintf(r->why, sizeof r->why, "no companion above the noise");
        return;
    }
    /* every other fit that found a companion must agree, except an image
     * fit outvoted: when the closure phases and the power spectrum's
     * fringes (phases and moduli, independent) agree on a pair inside the
     * image's core, which the image fit cannot see, its companion
     * elsewhere is an artefact (a 1.8 px pair on a 30 px crop: 2.7 to
     * 12 px).  A pair the image resolves must agree with the image. */
    int mod = r->status == PIPE_BIN_AMBIGUOUS;
    int fringe_backs = r->source == PIPE_BIN_SRC_CLOSURE && r->have_fringe &&
                       r->sep_px <= r->image.core_radius_px + 1 &&
                       !disagree(r, r->fringe.sep_px, r->fringe.sep_err_px,
                                 r->fringe.pa_deg, r->fringe.pa_err_deg, 1);
    if (r->source != PIPE_BIN_SRC_IMAGE && r->have_image &&
        disagree(r, r->image.sep_px, r->image.sep_err_px, r->image.pa_deg,
                 r->image.pa_err_deg, mod || r->image.pa_ambiguous)) {
        if (fringe_backs) {
            if (!r->why[0])
                snprintf(r->why, sizeof r->why, "image fit %.2f px at %.1f deg "
                         "outvoted by the fringes", r->image.sep_px, r->image.pa_deg);
            return;
        }
        r->status = PIPE_BIN_INCONSISTENT;
        snprintf(r->why, sizeof r->why, "image fit %.2f px at %.1f deg",
                 r->image.sep_px, r->image.pa_deg);
    } else if (r->source != PIPE_BIN_SRC_FRINGE && r->have_fringe &&
               disagree(r, r->fringe.sep_px, r->fringe.sep_err_px,
                        r->fringe.pa_deg, r->fringe.pa_err_deg, 1)) {
        r->status = PIPE_BIN_INCONSISTENT;
        snprintf(r->why, sizeof r->why, "fringe fit %.2f px at %.1f deg (+-180)",
                 r->fringe.sep_px, r->fringe.pa_deg);
    }
}

void pipe_binary_measure(const pipe_binary_in *in, const float *img, int w,
                         int h, pipeline_binary *r)
{
    memset(r, 0, sizeof *r);
    sl_err e = {0};
    const char *why = "no companion in the image";
    r->have_image = binary_measure(img, w, h, &r->image, &e) == SL_OK;
    if (!r->have_image && e.msg[0])
        why = e.msg;
    int frc = SL_EDATA;
    /* The fringe fit is for pairs the image cannot resolve: a few
     * lambda/D, 16 px even at 2x Nyquist.  Its grid costs 8 max_sep^2
     * passes over the samples (2 s at 50 px on TSM's 180 angles). */
    double max_sep = fmin(0.25 * (w < h ? w : h), FRINGE_MAX_SEP_PX);
    if (in->ps2d)
        frc = fringe_fit_2d(in->ps2d, w, h, in->noise, in->nframes, in->rcut_px,
                            max_sep, &r->fringe, NULL);
    else if (in->ps_polar)
        frc = fringe_fit_polar(in->ps_polar, in->nang, in->nf, in->nproj,
                               in->noise, in->nframes, max_sep, &r->fringe, NULL);
    r->fringe_ran = frc == SL_OK;
    r->have_fringe = frc == SL_OK && r->fringe.detected;
    closure_from_starts(in, r, &why);
    verdict(r, why);
}
