/* pipeline.c - see pipeline.h. */
#include "pipeline.h"

#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "spectra/bispec.h"
#include "spectra/powspec.h"
#include "prep.h"
#include "pipeline_int.h"
#include "tsm/tsm.h"

void pipeline_result_clear(pipeline_result *r)
{
    if (!r)
        return;
    free(r->image);
    r->image = NULL;
}

static double now_s(void) { return stream_now_s(); }

static int ps_add(void *h, const float *f) { return powspec_add(h, f); }
static int bs_add(void *h, const float *f) { return bispec_add(h, f); }
static int tsm_add_fn(void *h, const float *f) { return tsm_add(h, f); }

/* The power spectrum of a whole sequence (pass 1 of direct, and the
 * reference).  When the gain is unknown but photons are, g comes from the
 * mean flux of this very pass. */
typedef struct seq_ps {
    double *ps;       /* w*h: the bias-free mean power spectrum */
    double *le;       /* w*h or NULL: powspec_aligned_power */
    double g, bias;   /* gain used (or found), white-noise level */
    double g_floor;   /* blind: the gain the floor implies (0: it cannot say) */
    int nframes;
} seq_ps;

/* Direct's threads, the power spectrum's, the bispectrum's and the STF
 * model's: 0 means 2. */
static int direct_threads(const pipeline_opts *o)
{
    return o->nthreads > 0 ? o->nthreads : 2;
}

static int sequence_powspec(stream *s, const pipeline_opts *o, double g,
                            double photons, seq_ps *out, sl_err *err)
{
    powspec_opts po;
    powspec_opts_defaults(&po);
    po.aligned = out->le != NULL;
    po.window = o->window;
    po.tukey_alpha = o->tukey_alpha;
    po.measure = o->fftw_measure;
    po.nthreads = direct_threads(o);
    po.bias = g > 0 ? POWSPEC_BIAS_PHOTON : POWSPEC_BIAS_FLOOR;
    po.adu_per_photon = g;
    if (g > 0)
        po.read_noise_adu = stream_read_noise_adu(s, photons);
    stream_prefetch(s); /* the first frames read while the plans are made */
    powspec *p = powspec_new(s->w, s->h, &po, err);
    if (!p)
        return err ? err->code : SL_ENOMEM;
    int rc = stream_feed(s, ps_add, p, "power spectrum", err);
    if (rc == SL_OK)
        rc = stream_share_powspec(s, p, err);
    if (rc == SL_OK && !(g > 0) && photons > 0) {
        /* Gain from the data, for the bispectrum's Wirnitzer terms; in
         * this pass the floor estimate stands for the photon bias. */
        g = powspec_mean_flux(p) / photons;
    }
    out->g_floor = 0;
    if (rc == SL_OK && !(g > 0) && !(photons > 0) && s->det_learnt)
        powspec_floor_gain(p, s->det.sky_rms, &out->g_floor);
    if (rc == SL_OK && (rc = powspec_result(p, out->ps)) != SL_OK)
        sl_seterr(err, rc, "%s", powspec_errmsg(p));
    if (rc == SL_OK && out->le && powspec_aligned_power(p, out->le) != SL_OK)
        out->le = NULL; /* one frame: no long exposure to compare */
    out->g = g;
    out->bias = powspec_bias(p);
    out->nframes = powspec_nframes(p);
    powspec_free(p);
    return rc;
}

/* |FFT(target PSF)| normalised to 1 at DC, w*h FFT order. */
static int target_mtf(const char *path, int w, int h, double *mtf,
                      sl_err *err)
{
    seq *t = NULL;
    const char *paths[] = {path};
    int rc = cube_read(&t, NULL, paths, 1, 0, err);
    if (rc != SL_OK)
        return rc;
    if (t->width != w || t->height != h || t->nframes != 1) {
        rc = sl_seterr(err, SL_EFORMAT, "target PSF %s is %dx%d x %d frames; "
                       "want one image of the frames' %dx%d", path, t->width,
                       t->height, t->nframes, w, h);
        seq_free(t);
        return rc;
    }
    fftw_complex *in = fftw_alloc_complex((size_t)w * h);
    fftw_plan p = fftw_plan_dft_2d(h, w, in, in, FFTW_FORWARD, FFTW_ESTIMATE);
    for (size_t i = 0; i < (size_t)w * h; i++)
        in[i] = t->data[i];
    fftw_execute(p);
    double dc = cabs(in[0]);
    for (size_t i = 0; i < (size_t)w * h; i++)
        mtf[i] = dc > 0 ? cabs(in[i]) / dc : 0;
    fftw_destroy_plan(p);
    fftw_free(in);
    seq_free(t);
    return SL_OK;
}

/* sqrt(mean power over the support, DC out / white-noise power per
 * frequency), as the probe measures it; 1e6 without noise. */
static double support_snr(const double *ps, const unsigned char *support,
                          size_t n, double noise)
{
    double sum = 0;
    size_t k = 0;
    for (size_t i = 1; i < n; i++)
        if (support[i])
            sum += ps[i], k++;
    if (!(noise > 1e-12 * ps[0]) || !k)
        return 1e6;
    return sqrt(fmax(sum / k, 0) / noise);
}

/* The bispectrum's options for s: R2, support, window, photon bias,
 * threads and the phase solver's weights and refinement. */
static void direct_opts(const stream *s, const pipeline_opts *o, double g,
                        double photons, double snr, unsigned char *support,
                        bispec_opts *bo)
{
    bispec_opts_defaults(bo);
    if (o->r2_px > 0)   /* checked against the frame; the default: direct_bispec */
        bo->r2_px = o->r2_px;
    bo->support = support;
    bo->window = o->window;
    bo->tukey_alpha = o->tukey_alpha;
    bo->adu_per_photon = g;
    bo->read_noise_adu = g > 0 ? stream_read_noise_adu(s, photons) : 0;
    bo->nthreads = direct_threads(o);
    bo->measure = o->fftw_measure;
    /* Float accumulators: half the memory, and the fresh pages the
     * kernel must zero at first touch (12 % of a 200^2 x 100 run's CPU
     * on this VM), for one more rounding per batch of 128 frames: nb
     * 2^-24 of sum |B_f| over nb batches, under the float batch sums'
     * own ~11 2^-24 until ~1400 frames and 3e-5 at 64 000 (test_bispec_kernel
     * float_sums_within_bound), far below any phase noise of that many
     * frames. */
    bo->acc_float = 1;
    /* Noisy data (the power in the support within 30^2 of the white
     * noise's: 1000 photons give ~2) get the least-squares refinement with
     * SNR weights, |B| over its standard error across the frames (50 %
     * more accumulator memory): six-star at 1000 photons c 0.793 -> 0.886,
     * a binary unchanged.  Clean data refine only when the recursion's
     * misfit asks (phasor.h). */
    int noisy = snr < 30;
    bo->refine_iters = o->refine_iters >= 0 ? o->refine_iters : noisy ? PHASOR_AUTO_ITERS : -1;
    bo->weight = o->phase_weight >= 0 ? o->phase_weight : PHASOR_WEIGHT_MOD;
    bo->refine_weight = o->phase_weight >= 0 ? o->phase_weight
                                             : noisy ? PHASOR_WEIGHT_SNR : PHASOR_WEIGHT_MOD;
}

/* The modulus divided by the reference's transfer function (and times the
 * target's), into mod; ps_ref: n doubles of scratch. */
static int reference_modulus(stream *s, stream *ref, const pipeline_opts *o,
                             const double *ps, double *ps_ref, double *mod,
                             sl_err *err)
{
    double gr = 0, pr = 0;
    int src, rc;
    seq_ps sp = {.ps = ps_ref};
    if ((rc = stream_photon_stats(ref, o, &pr, &gr, &src, err)) != SL_OK ||
        (rc = sequence_powspec(ref, o, gr, pr, &sp, err)) != SL_OK)
        return rc;
    powspec_modulus(ps, ps_ref, s->w, s->h, o->wiener > 0 ? o->wiener : 1e-3, mod);
    if (!o->target_path)
        return SL_OK;
    if ((rc = target_mtf(o->target_path, s->w, s->h, ps_ref, err)) != SL_OK)
        return rc;
    for (size_t i = 0, n = (size_t)s->w * s->h; i < n; i++)
        mod[i] *= ps_ref[i];
    return SL_OK;
}

/* Direct's first pass: the power spectrum (and, for the filled-pupil
 * model, the aligned long exposure), its support and cut-off. */
static int direct_powspec(stream *s, const pipeline_opts *o, double photons,
                          seq_ps *sp, unsigned char *support, double *rcut,
                          sl_err *err)
{
    int rc = sequence_powspec(s, o, sp->g, photons, sp, err);
    if (rc != SL_OK)
        return rc;
    /* Support at 3 sigma, not 5: the threshold acts on the object's power,
     * so at low photon counts it keeps a binary's fringe maxima and drops
     * its minima, which exaggerates the fringe contrast: the true spectrum
     * cut to the 5-sigma support gives a dm error of -0.5, the whole one
     * the metric's own -0.13.  Bench binary 128^2, 6 lambda/D, dm 1, 1000
     * photons, seeds 1-4: dm error -0.46 -> -0.34, c 0.900 -> 0.921;
     * six-star at 1000 photons c 0.74 -> 0.85; noiseless unchanged (the
     * 1e-6 floor decides there). */
    powspec_support(sp->ps, s->w, s->h, 3, 1e-6, 1.0, sp->bias / sqrt(sp->nframes),
                    support, rcut);
    return SL_OK;
}

/* The modulus bispec_image uses: NULL (its own sqrt(power)), the
 * reference's, or the filled-pupil model's. */
static int direct_modulus(stream *s, stream *ref, const pipeline_opts *o,
                          const seq_ps *sp, const unsigned char *support,
                          double **mod, pipeline_report *rep, sl_err *err)
{
    size_t n = (size_t)s->w * s->h;
    if (!ref && !sp->le)
        return SL_OK;
    double *m = malloc(n * sizeof *m), *ps_ref = ref ? malloc(n * sizeof *ps_ref) : NULL;
    int rc = SL_OK;
    if (!m || (ref && !ps_ref))
        rc = sl_seterr(err, SL_ENOMEM, "out of memory");
    else if (ref)
        rc = reference_modulus(s, ref, o, sp->ps, ps_ref, m, err);
    else {
        pipe_stf_in si = {.ps = sp->ps, .le = sp->le, .support = support,
                          .w = s->w, .h = s->h, .nframes = sp->nframes,
                          .nthreads = direct_threads(o)};
        if (!pipe_stf_modulus(&si, m, rep))
            free(m), m = NULL;
    }
    free(ps_ref);
    if (rc != SL_OK)
        free(m), m = NULL;
    *mod = m;
    return rc;
}

/* The bispectrum handle with bo's options; the default R2 is bounded by
 * the memory (pipeline_r2.c): modelled first, then checked against the
 * handle built and made again smaller when the model was short. */
static bispec *direct_bispec(const stream *s, const pipeline_opts *o,
                             const unsigned char *support, double rcut, bispec_opts *bo,
                             pipeline_report *rep, sl_err *err)
{
    double budget = o->bispec_mem_mb > 0 ? o->bispec_mem_mb : PIPE_BISPEC_MEM_MB;
    int bounded = 0;
    int snr_acc = bo->weight == PHASOR_WEIGHT_SNR || bo->refine_weight == PHASOR_WEIGHT_SNR;
    /* A quarter of the budget for the batch of frames' spectra: a big
     * frame's many frequencies would otherwise get 16-frame batches, and
     * the kernel's passes over the accumulators, one per batch, cost
     * more than its products (512^2 x 400: 25 passes). */
    bo->batch_bytes = (size_t)(budget * 1048576.0 / 4);
    bo->budget_bytes = (size_t)(budget * 1048576.0);   /* the refinement's too */
    if (o->r2_px <= 0)
        bo->r2_px = pipe_direct_r2(s->w, s->h, support, rcut, snr_acc, budget,
                                   bo->batch_bytes, &bounded);
    for (;;) {
        bispec *b = bispec_new(s->w, s->h, bo, err);
        if (!b)
            return NULL;
        int r2 = o->r2_px > 0 ? bo->r2_px
                              : pipe_direct_r2_shrink(bo->r2_px, bispec_memory_bytes(b), budget);
        if (r2 == bo->r2_px) {
            rep->r2_bound_mb = bounded ? budget : 0;
            return b;
        }
        bispec_free(b);
        bo->r2_px = r2, bounded = 1;
    }
}

static int run_direct(stream *s, stream *ref, const pipeline_opts *o,
                      double photons, double g, float *img, pipeline_report *rep,
                      pipeline_binary *bin, sl_err *err)
{
    size_t n = (size_t)s->w * s->h;
    int want_le = !ref && o->stf_model;
    seq_ps sp = {.ps = malloc(n * sizeof *sp.ps),
                 .le = want_le ? malloc(n * sizeof *sp.le) : NULL, .g = g};
    double *mod = NULL, *le = sp.le;
    unsigned char *support = malloc(n);
    bispec *b = NULL;
    int rc = SL_ENOMEM;
    if (!sp.ps || !support || (want_le && !sp.le)) {
        sl_seterr(err, rc, "out of memory");
        goto free_all;
    }
    double rcut = 0;
    if ((rc = direct_powspec(s, o, photons, &sp, support, &rcut, err)) != SL_OK)
        goto free_all;
    g = sp.g;
    if (g > 0 && rep->gain_source == PIPE_GAIN_NONE)
        rep->gain_e_per_adu = s->scale / g, rep->gain_source = PIPE_GAIN_FLUX;
    else if (sp.g_floor > 0)
        rep->gain_e_per_adu = s->scale / sp.g_floor, rep->gain_source = PIPE_GAIN_FLOOR;
    double snr = support_snr(sp.ps, support, n, sp.bias);
    bispec_opts bo;
    double t_plan = now_s();
    direct_opts(s, o, g, photons, snr, support, &bo);
    if (!(b = direct_bispec(s, o, support, rcut, &bo, rep, err))) {
        rc = err ? err->code : SL_ENOMEM;
        goto free_all;
    }
    rep->stage_s[PIPE_STAGE_PLAN] = now_s() - t_plan;
    s->ahead_want = bispec_batch(b); /* its add returns once a batch */
    rc = stream_feed(s, bs_add, b, "bispectrum", err);
    s->ahead_want = 0;
    if (rc != SL_OK ||
        (rc = stream_share_bispec(s, b, err)) != SL_OK)
        goto free_all;
    double t_solve = now_s(), k_fed = bispec_kernel_s(b);
    if ((rc = direct_modulus(s, ref, o, &sp, support, &mod, rep, err)) != SL_OK)
        goto free_all;
    if ((rc = bispec_image(b, mod, img)) != SL_OK) {
        sl_seterr(err, rc, "%s", bispec_errmsg(b));
        goto free_all;
    }
    double t_meas = now_s();
    if (o->closure_binary) {
        pipe_binary_in bi = {.b = b, .ps2d = sp.ps, .rcut_px = rcut, .noise = sp.bias,
                             .nframes = bispec_nframes(b)};
        pipe_binary_measure(&bi, img, s->w, s->h, bin);
    }
    /* the last, partial batch is flushed by bispec_image: accumulation */
    rep->stage_s[PIPE_STAGE_ACCUM] = bispec_kernel_s(b);
    rep->stage_s[PIPE_STAGE_SOLVE] = t_meas - t_solve - (bispec_kernel_s(b) - k_fed);
    rep->stage_s[PIPE_STAGE_MEASURE] = now_s() - t_meas;
    s->frame_s -= k_fed;   /* FRAME: the feed less its triple kernel */
    rep->window = o->window;
    rep->r2_px = bo.r2_px;
    rep->rcut_px = rcut;
    rep->ntriples = (long)bispec_ntriples(b);
    rep->misfit = bispec_misfit(b);
    rep->support_snr = snr;
    rep->gain_adu = g;
free_all:
    bispec_free(b);
    free(sp.ps);
    free(le);
    free(mod);
    free(support);
    return rc;
}

static int tsm_sequence(stream *s, const tsm_opts *to, tsm **out, sl_err *err)
{
    stream_prefetch(s); /* the first frames read while the plans are made */
    tsm *t = tsm_new(s->w, s->h, to, err);
    if (!t)
        return err ? err->code : SL_ENOMEM;
    int rc = stream_feed(s, tsm_add_fn, t, "projections", err);
    if (rc == SL_OK)
        rc = stream_share_tsm(s, t, err);
    if (rc != SL_OK) {
        tsm_free(t);
        return rc;
    }
    *out = t;
    return SL_OK;
}

/* TSM power of a single image (the target PSF) through the same geometry. */
static int tsm_target_power(const char *path, const tsm_opts *to, int w,
                            int h, double *ps, sl_err *err)
{
    seq *img = NULL;
    const char *paths[] = {path};
    int rc = cube_read(&img, NULL, paths, 1, 0, err);
    if (rc != SL_OK)
        return rc;
    tsm_opts o1 = *to;
    o1.photons_per_frame = 0;
    tsm *t = NULL;
    if (img->width != w || img->height != h || img->nframes != 1)
        rc = sl_seterr(err, SL_EFORMAT, "target PSF %s is %dx%d x %d frames; "
                       "want one image of the frames' %dx%d", path, img->width,
                       img->height, img->nframes, w, h);
    else if (!(t = tsm_new(w, h, &o1, err)))
        rc = err ? err->code : SL_ENOMEM;
    else if ((rc = tsm_add(t, img->data)) == SL_OK)
        rc = tsm_power(t, ps);
    tsm_free(t);
    seq_free(img);
    return rc;
}

/* The binary measured on TSM's result: its polar power spectra carry the
 * fringes (pipeline_binary.c). */
static int tsm_measure_binary(tsm *t, const float *img, int w, int h,
                              pipeline_binary *bin, sl_err *err)
{
    size_t np = (size_t)tsm_nangles(t) * tsm_nfreq(t);
    double *ps = malloc(np * sizeof *ps), level = 0;
    if (!ps)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    int rc = tsm_power(t, ps);
    tsm_noise_level(t, &level);
    pipe_binary_in bi = {.t = t, .ps_polar = rc == SL_OK ? ps : NULL,
                         .nang = tsm_nangles(t), .nf = tsm_nfreq(t),
                         .nproj = tsm_nproj(t), .noise = level,
                         .nframes = tsm_nframes(t)};
    pipe_binary_measure(&bi, img, w, h, bin);
    free(ps);
    return SL_OK;
}

static int run_tsm(stream *s, stream *ref, const pipeline_opts *o,
                   double photons, float *img, pipeline_report *rep,
                   pipeline_binary *bin, sl_err *err)
{
    tsm_opts to;
    tsm_opts_defaults(&to);
    to.nangles = o->nangles > 0 ? o->nangles : 180;
    to.variant = o->method == PIPE_TSM ? TSM_SPATIAL : TSM_FOURIER;
    to.cutoff_cyc_px = o->cutoff_cyc_px;
    to.inverse = (tsm_inverse)o->tsm_inverse;
    /* Corrected phases need the photon statistics (the gain of Wirnitzer's
     * terms); without them the phases stay raw, with their own weights,
     * and RECTPHAS says so. */
    int corrected = o->tsm_corrected_phases && photons > 0;
    if (corrected) {
        to.bispec_bias_phase = 1;
        to.weight = TSM_WEIGHT_SNR2;
    }
    to.photons_per_frame = photons;
    to.fftw_flags = o->fftw_measure ? FFTW_MEASURE : FFTW_ESTIMATE;
    to.threads = o->nthreads;   /* 0: online CPUs, at most 4 */
    /* Bias (tsm.h): photons known -> photon bias plus the read noise the
     * simulator records (SIMRDN e-, SIMGAIN e-/adu); unknown (real camera
     * data) -> the floor TSM measures beyond the pupil cut-off. */
    to.read_noise_adu = stream_read_noise_adu(s, photons);
    tsm *t = NULL, *tr = NULL;
    double *ps_ref = NULL, *ps_tgt = NULL;
    double t_plan = now_s(), fed0 = s->read_s + s->frame_s;
    int rc = tsm_sequence(s, &to, &t, err);
    rep->stage_s[PIPE_STAGE_PLAN] = now_s() - t_plan - (s->read_s + s->frame_s - fed0);
    if (rc != SL_OK)
        return rc;
    if (ref) {
        tsm_opts ro = to;
        double gr;   /* TSM takes its gain from the photon count */
        int src;
        if ((rc = stream_photon_stats(ref, o, &ro.photons_per_frame, &gr, &src, err)) != SL_OK)
            goto free_all;
        ro.read_noise_adu = stream_read_noise_adu(ref, ro.photons_per_frame);
        /* the target is a model PSF: noiseless, no bias to remove */
        tsm_opts tt = to;
        tt.bias = TSM_BIAS_NONE;
        size_t np = (size_t)tsm_nangles(t) * tsm_nfreq(t);
        ps_ref = malloc(np * sizeof *ps_ref);
        ps_tgt = o->target_path ? malloc(np * sizeof *ps_tgt) : NULL;
        if (!ps_ref || (o->target_path && !ps_tgt))
            rc = sl_seterr(err, SL_ENOMEM, "out of memory");
        else if ((rc = tsm_sequence(ref, &ro, &tr, err)) == SL_OK &&
                 (rc = tsm_power(tr, ps_ref)) == SL_OK && o->target_path)
            rc = tsm_target_power(o->target_path, &tt, s->w, s->h, ps_tgt, err);
        if (rc == SL_OK)
            rc = tsm_set_reference(t, ps_ref, ps_tgt, o->wiener > 0 ? o->wiener : 0.05);
        if (rc != SL_OK)
            goto free_all;
    }
    double t_solve = now_s();
    if ((rc = tsm_result(t, img)) != SL_OK) {
        sl_seterr(err, rc, "%s", tsm_errmsg(t));
        goto free_all;
    }
    double t_meas = now_s();
    if (o->closure_binary && (rc = tsm_measure_binary(t, img, s->w, s->h, bin, err)) != SL_OK)
        goto free_all;
    rep->stage_s[PIPE_STAGE_SOLVE] = t_meas - t_solve;
    rep->stage_s[PIPE_STAGE_MEASURE] = now_s() - t_meas;
    rep->nangles = tsm_nangles(t);
    rep->cutoff_cyc_px = (double)(tsm_nfreq(t) - 1) / tsm_nproj(t);
    rep->npairs = tsm_npairs(t);
    rep->inverse = to.inverse;
    rep->corrected_phases = corrected;
    tsm_arc(t, &rep->arc_bins, &rep->tsm_extent_px);
    rep->bias_photon = photons > 0;
    tsm_noise_level(t, &rep->noise_level);
free_all:
    tsm_free(t);
    tsm_free(tr);
    free(ps_ref);
    free(ps_tgt);
    return rc;
}

/* The point-source reference, checked against the object's frames s;
 * closed again on failure. */
static int open_reference(const pipeline_opts *o, stream *s, stream *ref,
                          sl_err *err)
{
    const char *rp[] = {o->ref_path};
    pipeline_opts ro = *o;
    ro.progress = NULL; /* one bar: the object's frames */
    int rc = stream_open(ref, rp, 1, &ro, err);
    if (rc != SL_OK)
        return rc;
    if (ref->w != s->w || ref->h != s->h)
        rc = sl_seterr(err, SL_EFORMAT, "reference %s is %dx%d, frames are %dx%d",
                       o->ref_path, ref->w, ref->h, s->w, s->h);
    else
        rc = pipeline_check_data(o, o->ref_path, ref->w, ref->h, ref->n, err);
    if (rc != SL_OK)
        stream_close(ref);
    return rc;
}

int pipeline_run(const char *const *paths, int npaths,
                 const pipeline_opts *o, pipeline_result *out, sl_err *err)
{
    double t0 = now_s();
    memset(out, 0, sizeof *out);
    stream s, ref;
    stream *refp = NULL;
    int rc = pipeline_opts_check(o, err);
    if (rc != SL_OK || (rc = stream_open(&s, paths, npaths, o, err)) != SL_OK)
        return rc;
    if ((rc = pipeline_check_data(o, paths[0], s.w, s.h, s.n, err)) != SL_OK)
        goto close_s;
    if (o->ref_path && (rc = open_reference(o, &s, &ref, err)) != SL_OK)
        goto close_s;
    refp = o->ref_path ? &ref : NULL;
    double photons, g;
    int phsrc;
    if ((rc = stream_photon_stats(&s, o, &photons, &g, &phsrc, err)) != SL_OK)
        goto close_ref;
    /* eo: what runs (auto's choice applied); ch: what autoconf chose */
    pipeline_opts eo = *o;
    autoconf_choice ch;
    memset(&ch, 0, sizeof ch);
    int skips = skip_effective(o);
    if ((skips || o->method == PIPE_AUTO) &&
        (rc = skip_apply(&s, refp != NULL, o, skips, &eo, &ch, &photons, err)) != SL_OK)
        goto close_ref;
    out->image = malloc(sizeof(float) * s.w * s.h);
    if (!out->image) {
        rc = sl_seterr(err, SL_ENOMEM, "out of memory");
        goto close_ref;
    }
    /* direct: the power spectrum, then the bispectrum; TSM: one pass */
    stream_expect_passes(&s, eo.method == PIPE_DIRECT ? 2 : 1);
    pipeline_report *rep = &out->report;
    rep->method = eo.method;
    rep->nframes_in = s.n;
    rep->photons = photons;
    rep->photon_source = phsrc;
    rep->read_noise_adu = stream_read_noise(&s, photons, &rep->read_noise_source) / s.scale;
    if (g > 0) {
        rep->gain_e_per_adu = s.scale / g;
        rep->gain_source = o->adu_per_photon > 0 ? PIPE_GAIN_OPTION : PIPE_GAIN_HEADER;
    }
    rep->scale = s.scale;
    rep->stage_s[PIPE_STAGE_OPEN] = now_s() - t0 - (s.read_s + s.frame_s);
    rc = eo.method == PIPE_DIRECT
             ? run_direct(&s, refp, &eo, photons, g, out->image, rep, &out->binary, err)
             : run_tsm(&s, refp, &eo, photons, out->image, rep, &out->binary, err);
    if (rc == SL_OK && s.scale != 1.0)
        for (size_t i = 0, n = (size_t)s.w * s.h; i < n; i++)
            out->image[i] = (float)(out->image[i] / s.scale);
    if (rc == SL_OK && s.pb)
        rc = skip_place(&s, &out->image, err);
    if (rc != SL_OK) {
        pipeline_result_clear(out);
        goto close_ref;
    }
    out->nframes = s.n;
    stream_report(&s, rep);
    if (s.pb) {
        skip_report(&s, o, skips, &ch, &rep->probe);
        out->nframes = skip_nkept(&s);
        s.w = s.fw, s.h = s.fh;
    }
    out->width = s.w;
    out->height = s.h;
    out->plate_scale_arcsec = cube_reader_meta(s.rd)->plate_scale_arcsec;
    out->elapsed_s = now_s() - t0;
    if ((rc = pipeline_describe(&eo, cube_reader_meta(s.rd), out, err)) != SL_OK ||
        (rc = pipeline_history(paths, npaths, o, out, err)) != SL_OK)
        pipeline_result_clear(out);
close_ref:
    if (refp)
        stream_close(refp);
close_s:
    stream_close(&s);
    return rc;
}
