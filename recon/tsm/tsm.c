/* tsm.c - tomographic speckle masking, see tsm.h.
 *
 * Costs measured on one core (200^2, nproj 200: J = 100, 2500 pairs per
 * angle, 100 frames, warm FFTW plans): TSM-180 Fourier ~140 ms CPU (2-D
 * FFTs 17 ms, slice taps 15 ms, bispectrum sums 34 ms, phases 42 ms of a
 * ~50 ms tsm_result); TSM-18 ~32 ms without reading and prep (FFTs 9 ms,
 * taps 8 ms, sums 4 ms, tsm_result 5 ms); see tsm.h for the cost model.
 * The spatial path adds ~3.5 ms per frame at 180 angles (radon_spatial.h;
 * on `threads` cores), plus ~30 ms in tsm_new for its noise transfer.
 * Memory at TSM-180: 7 MB of bispectrum sums, 5 MB of blocks (two of 8
 * frames and their slices), 1.6 MB of FFT scratch per thread, ~2 MB in the
 * radon handle.
 */
#include "tsm.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/finite.h"
#include "spectra/closure.h"
#include "base/rng.h"
#include "tsm_int.h"


void tsm_opts_defaults(tsm_opts *o) { memset(o, 0, sizeof *o); }

const char *tsm_errmsg(const tsm *t) { return t ? t->err.msg : ""; }
int tsm_nangles(const tsm *t) { return t->nang; }
int tsm_nproj(const tsm *t) { return t->ns; }
int tsm_nfreq(const tsm *t) { return t->nf; }
int tsm_npairs(const tsm *t) { return t->np; }
int tsm_nframes(const tsm *t) { return t->nframes; }
void tsm_arc(const tsm *t, double *arc_bins, double *extent_px)
{
    *arc_bins = t->arc, *extent_px = t->extent;
}

void tsm_free(tsm *t)
{
    if (!t)
        return;
    tsm_accum_free(t->acc);
    tsm_phase_free(t->ph); /* both hand their pages back on the pool */
    tpool_free(t->pool);
    radon_free(t->rad);
    void *m[] = {t->proj, t->ref, t->tgt, t->phase, t->psc, t->ospec, t->sref,
                 t->tr, t->pw};
    for (size_t i = 0; i < sizeof m / sizeof m[0]; i++)
        free(m[i]);
    free(t);
}

void tsm_reset(tsm *t)
{
    tsm_accum_reset(t->acc);
    t->nframes = 0;
    t->have_result = 0;
}

/* Add the buffered frames; the sums' pointers are fixed, this makes their
 * contents current. */
void tsm_sync_sums(tsm *t)
{
    const tsm_sums *s = tsm_accum_sums(t->acc);
    t->bre = s->bre, t->bim = s->bim, t->ps = s->ps, t->mre = s->mre, t->mim = s->mim;
}

/* The spatial projector's white-noise transfer T(a, u) = E|P(u)|^2 /
 * (w h sigma^2).  For white noise E p(s) p(s') depends on the rays' shared
 * pixels only, zero beyond |s - s'| = 2 px (a pixel feeds the rays within
 * sqrt 2 px of it), so T is exactly R(0) + 2 sum_{d=1,2} R(d) cos(2 pi u
 * d / ns) with R(d) = sum_s E p(s) p(s + d).  R is estimated from nt
 * projections of unit white noise (fixed seed: the same T every time),
 * nt = 8 (200 / side)^2 within [8, 64] for ~3 x 10^5 ray samples, and
 * averaged over the angles the pixel lattice maps onto each other
 * (theta, 180 - theta, 90 +- theta): the floor level then comes out within
 * ~1%.  Cost: nt spatial projections (~30 ms at 128^2 or 200^2, 180
 * angles). */
enum { NT_LAG = 2 };

static int noise_transfer(tsm *t, sl_err *err)
{
    size_t npix = (size_t)t->w * t->h;
    int ns = t->ns, nf = t->nf, K = t->nang, st = SL_OK, L1 = NT_LAG + 1;
    int nt = (int)ceil(8 * 200.0 * 200.0 / (double)npix);
    nt = nt < 8 ? 8 : nt > 64 ? 64 : nt;
    float *img = malloc(npix * sizeof *img);
    double *r = calloc((size_t)K * L1, sizeof *r);
    t->tr = malloc((size_t)K * nf * sizeof *t->tr);
    if (!img || !r || !t->tr) {
        st = sl_seterr(err, SL_ENOMEM, "tsm_new: out of memory");
        goto free_scratch;
    }
    rng g;
    rng_init(&g, 0x7534d, 0);
    for (int m = 0; m < nt; m++) {
        for (size_t i = 0; i < npix; i++)
            img[i] = (float)rng_normal(&g);
        if ((st = radon_project(t->rad, img, t->proj)) != SL_OK) {
            sl_seterr(err, st, "tsm_new: %s", radon_errmsg(t->rad));
            goto free_scratch;
        }
        for (int a = 0; a < K; a++) {
            const float *p = t->proj + (size_t)a * ns;
            for (int d = 0; d < L1; d++)
                for (int s = 0; s < ns; s++)
                    r[a * L1 + d] += (double)p[s] * p[(s + d) % ns];
        }
    }
    for (int a = 0; a < K; a++) {
        /* the orbit of theta_a under the lattice's reflections */
        int orb[4] = {a, (K - a) % K, -1, -1}, no = 2;
        if (K % 2 == 0)
            orb[2] = ((K / 2 - a) % K + K) % K, orb[3] = (K / 2 + a) % K, no = 4;
        for (int u = 0; u < nf; u++) {
            double v = 0;
            for (int k = 0; k < no; k++) {
                const double *ra = r + orb[k] * L1;
                v += ra[0];
                for (int d = 1; d < L1; d++)
                    v += 2 * ra[d] * cos(2 * M_PI * u * d / ns);
            }
            t->tr[(size_t)a * nf + u] = v / (no * nt * (double)npix);
        }
    }
free_scratch:
    free(img);
    free(r);
    return st;
}

/* Angles, projection length and cut-off bins J from o; SL_EINVAL (in
 * err) naming the parameters when they do not make a TSM. */
static int tsm_check(int w, int h, const tsm_opts *o, int *nang, int *ns,
                     int *J, sl_err *err)
{
    *nang = o->nangles ? o->nangles : 180;
    *ns = o->nproj ? o->nproj : (w > h ? w : h);
    *ns += *ns & 1;
    double cut = o->cutoff_cyc_px > 0 ? o->cutoff_cyc_px : 0.5;
    *J = (int)floor(cut * *ns + 1e-9);
    *J = *J > *ns / 2 ? *ns / 2 : *J;
    int batch = o->batch ? o->batch : 8;
    if (w < 8 || h < 8 || *nang < 1 || *J < 3 || o->r2_bins < 0 || batch < 1 ||
        batch > 1024 || o->threads < 0 || o->threads > 64 ||
        o->variant < TSM_FOURIER || o->variant > TSM_SPATIAL ||
        !(o->photons_per_frame >= 0) || !(o->read_noise_adu >= 0) ||
        o->bias < TSM_BIAS_AUTO || o->bias > TSM_BIAS_FLOOR ||
        (o->bias == TSM_BIAS_PHOTON && !(o->photons_per_frame > 0)))
        return sl_seterr(err, SL_EINVAL,
                         "tsm_new: bad parameters (%dx%d, %d angles, cut-off %d bins, "
                         "r2 %d, batch %d, %d threads, variant %d, bias %d with %g photons, "
                         "read noise %g)", w, h, *nang, *J, o->r2_bins, batch, o->threads,
                         (int)o->variant, (int)o->bias, o->photons_per_frame,
                         o->read_noise_adu);
    return SL_OK;
}

/* The projector, the phase solver, the thread team and the accumulator. */
static int tsm_parts(tsm *t, sl_err *err)
{
    const tsm_opts *o = &t->o;
    radon_opts ro;
    radon_opts_defaults(&ro);
    ro.nproj = t->ns;
    ro.nfreq = t->nf;
    ro.oversamp = o->oversamp;
    ro.kernel_bins = o->kernel_bins;
    ro.window = o->window;
    ro.window_cut_cyc_px = (double)(t->nf - 1) / t->ns;
    ro.spatial = o->variant == TSM_SPATIAL;
    ro.threads = o->threads > 0 ? o->threads : tpool_default_threads();
    ro.fftw_flags = o->fftw_flags;
    if (!(t->pool = tpool_new(o->threads, err)))
        return SL_ENOMEM;
    ro.pool = t->pool;   /* the result's slices and FBPs on every thread */
    if (!(t->rad = radon_new(t->w, t->h, t->nang, &ro, err)) ||
        !(t->ph = tsm_phase_new(t->nang, t->nf, o->r2_bins, err)))
        return SL_EINVAL;
    t->np = tsm_phase_npairs(t->ph);
    t->off = tsm_phase_rowoff(t->ph);
    t->len = tsm_phase_rowlen(t->ph);
    if (tsm_phase_set_pool(t->ph, t->pool) != SL_OK)
        return sl_seterr(err, SL_ENOMEM, "tsm_new: out of memory (phase scratch)");
    t->acc = tsm_accum_new(t->rad, t->w, t->h, t->nang,
                           t->nf, t->off, t->len, t->np, o->batch ? o->batch : 8, t->pool, err);
    return t->acc ? SL_OK : SL_ENOMEM;
}

/* The result's buffers, from one table (zeroed ones where a first use
 * reads them). */
static int tsm_buffers(tsm *t, sl_err *err)
{
    size_t nsp = (size_t)t->nang * t->nf;
    const struct { void **slot; size_t bytes; int zero; } bufs[] = {
        {(void **)&t->proj, (size_t)t->nang * t->ns * sizeof *t->proj, 0},
        {(void **)&t->ref, nsp * sizeof *t->ref, 0},
        {(void **)&t->tgt, nsp * sizeof *t->tgt, 0},
        {(void **)&t->phase, nsp * sizeof *t->phase, 1},
        {(void **)&t->psc, nsp * sizeof *t->psc, 0},
        {(void **)&t->ospec, nsp * sizeof *t->ospec, 1},
        {(void **)&t->sref, nsp * sizeof *t->sref, 1},
        {(void **)&t->pw, nsp * sizeof *t->pw, 0}};
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++)
        if (!(*bufs[i].slot = bufs[i].zero ? calloc(1, bufs[i].bytes) : malloc(bufs[i].bytes)))
            return sl_seterr(err, SL_ENOMEM, "tsm_new: out of memory (%zu bispectrum "
                             "elements)", (size_t)t->nang * t->np);
    return SL_OK;
}

tsm *tsm_new(int w, int h, const tsm_opts *opts, sl_err *err)
{
    tsm_opts o;
    if (opts)
        o = *opts;
    else
        tsm_opts_defaults(&o);
    int nang, ns, J;
    if (tsm_check(w, h, &o, &nang, &ns, &J, err) != SL_OK)
        return NULL;
    tsm *t = calloc(1, sizeof *t);
    if (!t) {
        sl_seterr(err, SL_ENOMEM, "tsm_new: out of memory");
        return NULL;
    }
    t->w = w, t->h = h, t->nang = nang, t->ns = ns, t->nf = J + 1;
    t->o = o;
    if (tsm_parts(t, err) != SL_OK)
        goto fail_free;
    tsm_sync_sums(t);
    if (tsm_buffers(t, err) != SL_OK)
        goto fail_free;
    if (o.variant == TSM_SPATIAL && o.bias != TSM_BIAS_NONE &&
        noise_transfer(t, err) != SL_OK)
        goto fail_free;
    tsm_reset(t);
    return t;
fail_free:
    tsm_free(t);
    return NULL;
}

int tsm_add(tsm *t, const float *frame)
{
    /* straight into the accumulator's block: sliced or projected there;
     * a bad frame's slot is not committed, the next frame overwrites it */
    size_t npix = (size_t)t->w * t->h, i;
    if ((i = finite_copy(tsm_accum_frame_slot(t->acc), frame, npix)) < npix)
        return sl_seterr(&t->err, SL_EDATA, "tsm_add: frame %d pixel (%zu, %zu) is not finite",
                         t->nframes, i % t->w, i / t->w);
    tsm_accum_commit_frame(t->acc);
    t->nframes++;
    t->have_result = 0;   /* the result no longer covers the frames */
    return SL_OK;
}

/* Mean frame sum, the photon gain g (0 unless photons are known and the
 * mode corrects) and the white-noise level L of the bias mode (tsm.h). */
void tsm_bias_terms(const tsm *t, double *sbar, double *g, double *level)
{
    double s = 0, n = t->nframes, ph = t->o.photons_per_frame;
    for (int a = 0; a < t->nang; a++)
        s += t->mre[(size_t)a * t->nf];
    *sbar = s / t->nang / n;
    tsm_bias mode = t->o.bias;
    if (mode == TSM_BIAS_AUTO)
        mode = ph > 0 ? TSM_BIAS_PHOTON : TSM_BIAS_FLOOR;
    *g = mode != TSM_BIAS_NONE && ph > 0 ? *sbar / ph : 0.0;
    *level = 0;
    if (mode == TSM_BIAS_PHOTON) {
        double rn = t->o.read_noise_adu;
        *level = *g * *sbar + (double)t->w * t->h * rn * rn;
    } else if (mode == TSM_BIAS_FLOOR) {
        /* sum |P|^2 / sum T over the outer shells: linear in the sums */
        int J = t->nf - 1, j0 = J - (J / 16 > 2 ? J / 16 : 2) + 1;
        double num = 0, den = 0;
        for (int a = 0; a < t->nang; a++)
            for (int j = j0; j <= J; j++) {
                size_t i = (size_t)a * t->nf + j;
                num += t->ps[i], den += t->tr ? t->tr[i] : 1.0;
            }
        *level = den > 0 ? num / n / den : 0.0;
    }
}

/* Mean power at i minus its non-photon white part (level - g <S>, e.g.
 * read noise): the |P|^2 of Wirnitzer's terms, which are photon bias only
 * (Gaussian noise adds nothing to the bispectrum). */
double tsm_photon_power(const tsm *t, size_t i, double sbar, double g, double lv)
{
    double white = lv - g * sbar;
    return t->ps[i] / t->nframes - (white > 0 ? white : 0) * (t->tr ? t->tr[i] : 1.0);
}

int tsm_noise_level(tsm *t, double *level)
{
    if (t->nframes == 0)
        return sl_seterr(&t->err, SL_EDATA, "tsm_noise_level: no frames");
    tsm_sync_sums(t);
    double sbar, g;
    tsm_bias_terms(t, &sbar, &g, level);
    return SL_OK;
}

int tsm_power(tsm *t, double *ps)
{
    if (t->nframes == 0)
        return sl_seterr(&t->err, SL_EDATA, "tsm_power: no frames");
    tsm_sync_sums(t);
    double sbar, g, lv;
    tsm_bias_terms(t, &sbar, &g, &lv);
    for (size_t i = 0; i < (size_t)t->nang * t->nf; i++)
        ps[i] = t->ps[i] / t->nframes - lv * (t->tr ? t->tr[i] : 1.0);
    return SL_OK;
}

int tsm_mean_projection(tsm *t, float *proj)
{
    if (t->nframes == 0)
        return sl_seterr(&t->err, SL_EDATA, "tsm_mean_projection: no frames");
    tsm_sync_sums(t);
    for (size_t i = 0; i < (size_t)t->nang * t->nf; i++)   /* sref: scratch */
        t->sref[i] = CMPLXF((float)(t->mre[i] / t->nframes), (float)(t->mim[i] / t->nframes));
    int st = radon_spec_to_proj(t->rad, t->sref, proj);
    return st ? sl_seterr(&t->err, st, "tsm_mean_projection: %s", radon_errmsg(t->rad)) : SL_OK;
}

/* Element q of angle k's row (pair u1, u2) of the mean bispectrum,
 * photon-bias-corrected when the gain g is known (Wirnitzer, 1-D). */
static void corrected_at(const tsm *t, int k, int u1, int u2, double sbar,
                         double g, double lv, double *re, double *im)
{
    double n = t->nframes;
    size_t q = (size_t)k * t->np + t->off[u1] + u2 - 1, i = (size_t)k * t->nf;
    *re = t->bre[q] / n + 2 * g * g * sbar;
    if (g > 0)
        *re -= g * (tsm_photon_power(t, i + u1, sbar, g, lv) + tsm_photon_power(t, i + u2, sbar, g, lv) +
                    tsm_photon_power(t, i + u1 + u2, sbar, g, lv));
    *im = t->bim[q] / n;
}

int tsm_bispectrum(tsm *t, int k, int u1, int u2, double *re, double *im)
{
    if (k < 0 || k >= t->nang || u1 < 1 || u1 >= t->nf - 1 || u2 < 1 ||
        u2 > t->len[u1])
        return sl_seterr(&t->err, SL_ERANGE, "tsm_bispectrum: (%d, %d, %d) not stored", k, u1, u2);
    if (t->nframes == 0)
        return sl_seterr(&t->err, SL_EDATA, "tsm_bispectrum: no frames");
    tsm_sync_sums(t);
    double sbar, g, lv;
    tsm_bias_terms(t, &sbar, &g, &lv);
    corrected_at(t, k, u1, u2, sbar, g, lv, re, im);
    return SL_OK;
}

int tsm_binary(tsm *t, int nstart, const binary_result *init, binary_result *out,
               closure_fit_info *info)
{
    if (!t || !init || !out)
        return sl_seterr(t ? &t->err : NULL, SL_EINVAL, "tsm_binary: NULL argument");
    if (t->nframes == 0)
        return sl_seterr(&t->err, SL_EDATA, "tsm_binary: no frames");
    size_t n = (size_t)t->nang * t->np;
    double *b = malloc(2 * n * sizeof *b);
    if (!b)
        return sl_seterr(&t->err, SL_ENOMEM, "tsm_binary: out of memory");
    tsm_sync_sums(t);
    double sbar, g, lv;
    tsm_bias_terms(t, &sbar, &g, &lv);
    for (int k = 0; k < t->nang; k++)
        for (int u1 = 1; u1 < t->nf; u1++)
            for (int u2 = 1; u2 <= t->len[u1]; u2++) {
                size_t q = (size_t)k * t->np + t->off[u1] + u2 - 1;
                corrected_at(t, k, u1, u2, sbar, g, lv, &b[q], &b[n + q]);
            }
    int rc = closure_fit_binary_1d(t->nang, t->nf, t->ns, t->off, t->len,
                                   t->np, b, b + n, 0, nstart, init, out, info, &t->err);
    free(b);
    return rc;
}

size_t tsm_partial(tsm *t, double *buf)
{
    size_t n = tsm_accum_pack(t->acc, buf);
    if (buf)
        buf[n] = t->nframes;
    return n + 1;
}

void tsm_partial_load(tsm *t, const double *buf)
{
    size_t n = tsm_accum_pack(t->acc, NULL);
    t->nframes = (int)buf[n];
    tsm_accum_unpack(t->acc, buf, t->nframes);
    tsm_sync_sums(t);
    t->have_result = 0;
}
