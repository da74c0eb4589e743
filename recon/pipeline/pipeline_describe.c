/* pipeline_describe.c - the reconstruction's header, written in one place
 * from the typed result (pipeline.h: pipeline_report, pipeline_binary).
 *
 * Every keyword is counted: a header that cannot hold one (the extras
 * list full, a string too long) is an error naming it, never a key
 * silently dropped.  Strings are cut to a FITS card's 68 characters. */
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "pipeline_int.h"

typedef struct keys {
    cube_meta *m;
    int rc;
    char first[CUBE_KEY_MAX];   /* the first keyword that did not fit */
} keys;

static void num(keys *k, const char *key, double v, const char *comment)
{
    int rc = cube_meta_set_num(k->m, key, v, comment);
    if (rc != SL_OK && k->rc == SL_OK) {
        k->rc = rc;
        snprintf(k->first, sizeof k->first, "%s", key);
    }
}

static void str(keys *k, const char *key, const char *v, const char *comment)
{
    char cut[CUBE_STR_MAX];
    snprintf(cut, sizeof cut, "%.68s", v);
    int rc = cube_meta_set_str(k->m, key, cut, comment);
    if (rc != SL_OK && k->rc == SL_OK) {
        k->rc = rc;
        snprintf(k->first, sizeof k->first, "%s", key);
    }
}

static const char *phsrc_names[] = {"none", "option", "SIMPHOT", "GAIN"};

const char *pipeline_photon_source_name(int s)
{
    return s >= 0 && s <= PIPE_PHOT_GAIN ? phsrc_names[s] : "unknown";
}

static const char *gain_names[] = {"none", "option", "header", "flux", "floor"};
static const char *stage_names[] = {"open", "plan", "read", "frame", "accum", "solve", "measure"};

const char *pipeline_stage_name(int s)
{
    return s >= 0 && s < PIPE_NSTAGES ? stage_names[s] : "unknown";
}

const char *pipeline_gain_source_name(int s)
{
    return s >= 0 && s <= PIPE_GAIN_FLOOR ? gain_names[s] : "unknown";
}

static void run_keys(keys *k, const pipeline_opts *o, const pipeline_result *r)
{
    const pipeline_report *p = &r->report;
    str(k, "RECMETH", pipeline_method_name(p->method), "reconstruction method");
    num(k, "RECNFRM", r->nframes, "frames reconstructed");
    num(k, "RECPHOT", p->photons, "photons/frame for bias, 0 = unknown");
    str(k, "RECPHSRC", pipeline_photon_source_name(p->photon_source),
        "RECPHOT from: option, SIMPHOT, or GAIN and the flux");
    if (p->photons > 0) {
        static const char *rdn_names[] = {"none", "header", "sky rms"};
        num(k, "RECRDN", p->read_noise_adu, "[adu] read noise for the photon bias");
        str(k, "RECRDSRC", rdn_names[p->read_noise_source % 3],
            "RECRDN from: SIMRDN/RDNOISE, or the sky's temporal rms");
    }
    if (p->gain_source != PIPE_GAIN_NONE) {
        num(k, "RECGAINE", p->gain_e_per_adu, "[e-/adu] detector gain");
        str(k, "RECGNSRC", pipeline_gain_source_name(p->gain_source),
            "RECGAINE from: option, header, flux/photons, PS floor");
    }
    str(k, "RECREF", o->ref_path ? o->ref_path : "none", "reference (point-source) sequence");
    if (p->scale != 1.0)
        num(k, "RECSCALE", p->scale, "frames x this (power of 2) for the float sums");
    num(k, "RECTIME", r->elapsed_s, "[s] reconstruction wall time");
    if (p->method == PIPE_DIRECT) {
        str(k, "RECWIN", p->window == POWSPEC_WIN_NONE ? "none" :
            p->window == POWSPEC_WIN_HANN ? "hann" : "tukey", "frame apodisation");
        num(k, "RECR2", p->r2_px, "[px] bispectrum |u2| radius");
        if (p->r2_bound_mb > 0)
            num(k, "RECR2MEM", p->r2_bound_mb, "[MB] RECR2 bounded by this bispectrum size");
        num(k, "RECRCUT", p->rcut_px, "[px] measured Fourier cut-off");
        num(k, "RECNTRI", (double)p->ntriples, "closure triangles stored");
        num(k, "RECMISF", p->misfit, "phase recursion's closure misfit");
        num(k, "RECSNRPS", p->support_snr, "power-spectrum SNR over the support");
        num(k, "RECFILL", p->stf_fill, "support's fill inside 0.8 of the cut-off");
        num(k, "RECSTF", p->stf_d_r0, "D/r0 of the model STF divided out, 0 = none");
        num(k, "RECGAIN", p->gain_adu / p->scale, "[adu/photon] photon-bias gain, 0 = floor");
        return;
    }
    num(k, "RECNANG", p->nangles, "TSM projection angles");
    num(k, "RECCUT", p->cutoff_cyc_px, "[cyc/px] TSM cut-off");
    num(k, "RECNPAIR", p->npairs, "1-D bispectrum pairs per angle");
    str(k, "RECTINV", p->inverse == TSM_INV_ITER ? "iterative" : "fbp",
        "TSM inverse: filtered back projection or iterative");
    str(k, "RECTPHAS", p->corrected_phases ? "corrected" : "raw",
        "TSM phases: raw or photon-bias-corrected bispectrum");
    num(k, "RECARC", p->arc_bins, "[bins] TSM bispectrum angular average");
    num(k, "RECTEXT", p->tsm_extent_px, "[px] TSM object diameter capping RECARC");
    str(k, "RECBIAS", p->bias_photon ? "photon" : "floor",
        "TSM white-noise bias: photon count or measured floor");
    num(k, "RECNOISE", p->noise_level, "TSM white-noise power subtracted");
}

static void prep_keys(keys *k, const pipeline_report *p)
{
    static const char *sky[] = {"none", "border median", "sky-mask mean", "none (dark given)"};
    static const char *sat[] = {"none", "type", "adc", "flat-top"};
    const pipeline_prep_report *c = &p->prep;
    if (c->on) {
        num(k, "PREPDARK", c->dark, "1 = dark/bias subtracted");
        num(k, "PREPFLAT", c->flat, "1 = flat-fielded");
        str(k, "PREPSKY", sky[c->sky], "sky estimate subtracted per frame");
        num(k, "PREPBORD", c->border_px, "[px] sky border band");
        num(k, "PREPSAT", c->saturation_adu / p->scale, "[adu] saturation, 0 = none");
        num(k, "PREPNBAD", c->nbad, "pixels in the bad-pixel map");
        str(k, "PREPWIN", "none", "apodisation window");
        num(k, "PREPCENT", c->recentred, "1 = frames recentred on the cloud");
    }
    const pipeline_detector_report *d = &p->detector;
    if (!d->learnt)
        return;
    num(k, "DETNFRM", d->nframes, "raw frames the detector was learnt from");
    num(k, "DETSTUCK", d->nstuck, "stuck pixels found (repaired)");
    num(k, "DETHOT", d->nhot, "hot pixels found (repaired)");
    num(k, "DETDEAD", d->ndead, "dead pixels found (repaired)");
    num(k, "DETSAT", d->sat_level_adu, "[adu] saturation level found, 0 = none");
    str(k, "DETSATSR", sat[d->sat_source], "saturation from: type, adc, flat-top");
    num(k, "DETQUANT", d->quantum_adu, "[adu] data step, 0 = real-valued");
    num(k, "DETSKY", d->sky_adu, "[adu] raw sky level");
    num(k, "DETSKYRM", d->sky_rms_adu, "[adu] sky temporal rms");
    num(k, "DETCX", d->cx_px, "[px] raw cloud centre x (0-based)");
    num(k, "DETCY", d->cy_px, "[px] raw cloud centre y (0-based)");
}

static void probe_keys(keys *k, const pipeline_probe_report *c)
{
    if (!c->probed)
        return;
    char buf[64];
    pipeline_skips_name(c->skips, buf, sizeof buf);
    str(k, "RECSKIPS", buf, "skips applied");
    num(k, "RECPRBN", c->probed, "frames the scene probe measured");
    num(k, "RECCROPX", c->crop_x0, "[px] crop origin x (0-based)");
    num(k, "RECCROPY", c->crop_y0, "[px] crop origin y (0-based)");
    num(k, "RECCROPW", c->crop_w, "[px] reconstructed crop width");
    num(k, "RECCROPH", c->crop_h, "[px] reconstructed crop height");
    num(k, "RECCLOUD", c->cloud_radius_px, "[px] speckle cloud radius at the crop's level");
    num(k, "RECCLEVL", c->cloud_level, "cloud edge, x long-exposure profile peak");
    num(k, "RECCFLUX", c->crop_flux_frac, "long-exposure flux inside the crop");
    if (c->spectrum) {
        num(k, "RECSUPP", c->support_cyc_px, "[cyc/px] measured Fourier support radius");
        num(k, "RECSFRAC", c->support_frac, "fraction of the crop's frequencies in the support");
        num(k, "RECEXTNT", c->extent_px, "[px] image diameter (autocorrelation)");
        num(k, "RECSNR", c->snr, "probe SNR: sqrt(support power / noise)");
    }
    num(k, "RECREJ", c->rejected[1] + c->rejected[2] + c->rejected[3] + c->rejected[4],
        "frames rejected (sum of RECREJ*)");
    num(k, "RECREJE", c->rejected[1], "rejected: empty");
    num(k, "RECREJS", c->rejected[2], "rejected: saturated");
    num(k, "RECREJF", c->rejected[3], "rejected: flux beyond median +- k MAD");
    num(k, "RECREJQ", c->rejected[4], "rejected: sharpness beyond median +- k MAD");
    num(k, "RECREJK", c->reject_mad, "rejection threshold k (MAD)");
    if (!c->chosen)
        return;
    num(k, "RECTGERR", c->target_error, "target error 1 - c of the model");
    num(k, "RECPRED", c->pred_error, "model's predicted 1 - c");
    num(k, "RECPCOST", c->pred_cost_s, "[s] model's predicted CPU time");
    str(k, "RECCHOSE", c->chosen_label, "configuration chosen");
}

static void closure_keys(keys *k, const pipeline_binary *r)
{
    if (!r->have_closure) {
        str(k, "CPSTAT", r->have_image || r->have_fringe ? "no closure fit"
            : "no start: no companion found", "closure-phase binary fit failed");
        return;
    }
    const binary_result *cp = &r->closure;
    str(k, "CPSTAT", "ok", "closure-phase binary fit (closure.h)");
    num(k, "CPSEP", cp->sep_px, "[px] binary separation, closure phases");
    num(k, "CPSEPE", cp->sep_err_px, "[px] its 1-sigma error");
    num(k, "CPPA", cp->pa_deg, "[deg] PA from +y (N) to -x (E)");
    num(k, "CPPAE", cp->pa_err_deg, "[deg] its 1-sigma error");
    num(k, "CPDM", cp->dm_mag, "[mag] magnitude difference");
    num(k, "CPDME", cp->dm_err_mag, "[mag] its 1-sigma error");
    num(k, "CPAMBIG", cp->pa_ambiguous, "1 = r within 2 sigma of 1");
    num(k, "CPNTRI", (double)r->closure_info.ntriples, "closure triangles fitted");
    num(k, "CPNFREQ", r->closure_info.nfreq, "distinct frequencies in them");
    num(k, "CPRMS", r->closure_info.rms_rad, "[rad] weighted rms closure residual");
    num(k, "CPSIGN", r->closure_info.sign_chi2, "chi2 by which -d fits worse");
    num(k, "CPDET", r->closure_info.detect_chi2, "chi2 by which no companion fits worse");
}

static void binary_keys(keys *k, const pipeline_binary *r)
{
    if (r->status == PIPE_BIN_NONE)
        return;
    str(k, "MEASSTAT", pipeline_binary_status_name(r->status),
        "binary: measured, ambiguous, unresolved, inconsistent");
    str(k, "MEASSRC", pipeline_binary_source_name(r->source), "binary from: closure, image, fringe");
    if (r->why[0])
        str(k, "MEASWHY", r->why, "why the binary is not plainly measured");
    if (r->source != PIPE_BIN_SRC_NONE) {
        num(k, "MEASSEP", r->sep_px, "[px] binary separation");
        num(k, "MEASSEPE", r->sep_err_px, "[px] its 1-sigma error");
        num(k, "MEASPA", r->pa_deg, "[deg] PA from +y (N) to -x (E)");
        num(k, "MEASPAE", r->pa_err_deg, "[deg] its 1-sigma error");
        num(k, "MEASDM", r->dm_mag, "[mag] magnitude difference");
        num(k, "MEASDME", r->dm_err_mag, "[mag] its 1-sigma error");
    }
    if (r->fringe_ran) {
        num(k, "FRSEP", r->fringe.sep_px, "[px] fringe fit separation");
        num(k, "FRPA", r->fringe.pa_deg, "[deg] fringe fit PA, or + 180");
        num(k, "FRDM", r->fringe.dm_mag, "[mag] fringe fit dm");
        num(k, "FRSIG", r->fringe.significance, "fringe fit significance");
        num(k, "FRCHI2", r->fringe.chi2_red, "fringe fit reduced chi2");
    }
    closure_keys(k, r);
}

/* ---- HISTORY: what made the image, as the caller asked for it ---- */

#define HIST_MAX_INPUTS 8   /* inputs named one by one; then a count */

static void hist(keys *k, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void hist(keys *k, const char *fmt, ...)
{
    char text[CUBE_HISTORY_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    if (cube_meta_add_history(k->m, "%s", text) != SL_OK && k->rc == SL_OK) {
        k->rc = SL_ERANGE;
        snprintf(k->first, sizeof k->first, "HISTORY");
    }
}

static const char *weight_name(int w)
{
    static const char *names[] = {"mod", "snr", "unit"};
    return w >= 0 && w <= 2 ? names[w] : "auto";
}

/* The options as `specklab recon` names them, requested values (auto's
 * choice and the defaults resolved are in the keywords). */
static void options_history(keys *k, const pipeline_opts *o)
{
    char skips[64] = "default", text[640];
    if (o->skips >= 0)
        pipeline_skips_name(o->skips, skips, sizeof skips);
    snprintf(text, sizeof text,
             "method=%s skips=%s target-error=%g projections=%d r2=%d window=%s "
             "tukey-alpha=%g prep=%d detect=%d learn-badpix=%d recentre=%d "
             "saturation-adu=%g photons=%g adu-per-photon=%g wiener=%g "
             "phase-weights=%s refine=%d tsm-inverse=%s tsm-phases=%s "
             "cutoff-cyc-px=%g binary=%d",
             pipeline_method_name(o->method), skips, o->target_error, o->nangles,
             o->r2_px, o->window == POWSPEC_WIN_NONE ? "none" :
             o->window == POWSPEC_WIN_HANN ? "hann" : "tukey", o->tukey_alpha,
             o->prep, o->detect, o->learn_badpix, o->recentre, o->saturation_adu,
             o->photons_per_frame, o->adu_per_photon, o->wiener,
             weight_name(o->phase_weight), o->refine_iters,
             o->tsm_inverse == TSM_INV_ITER ? "iter" : "fbp",
             o->tsm_corrected_phases ? "corrected" : "raw", o->cutoff_cyc_px,
             o->closure_binary);
    hist(k, "options: %s", text);
}

int pipeline_history(const char *const *paths, int npaths,
                     const pipeline_opts *asked, pipeline_result *r, sl_err *err)
{
    keys k = {&r->meta, SL_OK, ""};
    hist(&k, "reconstruction: %s from %d of %d frames",
         pipeline_method_name(r->report.method), r->nframes, r->report.nframes_in);
    for (int i = 0; i < npaths && i < HIST_MAX_INPUTS; i++)
        hist(&k, "input: %s", paths[i]);
    if (npaths > HIST_MAX_INPUTS)
        hist(&k, "input: and %d more, the last %s", npaths - HIST_MAX_INPUTS,
             paths[npaths - 1]);
    if (asked->ref_path)
        hist(&k, "reference: %s", asked->ref_path);
    if (asked->target_path)
        hist(&k, "target PSF: %s", asked->target_path);
    if (asked->badpix_path)
        hist(&k, "bad-pixel map: %s", asked->badpix_path);
    options_history(&k, asked);
    if (k.rc != SL_OK)
        return sl_seterr(err, k.rc, "the image header cannot hold its HISTORY (%zu "
                         "bytes of it the input's)", strlen(r->meta.history));
    return SL_OK;
}

int pipeline_describe(const pipeline_opts *o, const cube_meta *in,
                      pipeline_result *r, sl_err *err)
{
    keys k = {&r->meta, SL_OK, ""};
    r->meta = *in;
    /* Roughly the mean frame's flux (the input's unit) in total, but not
     * calibrated: apodisation, bias and sky subtraction change it. */
    snprintf(r->meta.bunit, sizeof r->meta.bunit, "relative flux");
    run_keys(&k, o, r);
    prep_keys(&k, &r->report);
    probe_keys(&k, &r->report.probe);
    binary_keys(&k, &r->binary);
    if (k.rc != SL_OK)
        return sl_seterr(err, k.rc, "the image header cannot hold %s (%d "
                         "keywords: the input's and ours)", k.first, r->meta.nextra);
    return SL_OK;
}
