/* bispec_result.c - the direct bispectrum's results (bispec.h): a stored
 * triple, the phases by phasor recursion (phasor.h) over the accumulated
 * sums, and the image from those phases and a modulus. */
#include <math.h>

#include "bispec_int.h"
#include "closure.h"
#include "phasor.h"

static void graph_view(const bispec *b, phasor_graph *g)
{
    double gain = b->o.adu_per_photon, n = b->n;
    int ph = b->xsum && n > 0;
    *g = (phasor_graph){
        .nfreq = b->nf, .tstart = b->tstart, .tk = b->tk, .ubase = b->ubase,
        .doff = b->doff, .dleg = b->dleg, .lut = b->lut, .seed = b->seed,
        .accd = b->accd, .accf = b->accf, .acc2d = b->acc2d,
        .acc2f = b->acc2f, .nframes = n, .pool = b->pool, .weight = b->o.weight,
        .refine_weight = b->o.refine_weight,
        .refine_bytes = b->o.budget_bytes == 0 ? 0
                      : b->o.budget_bytes > b->mem + b->o.budget_bytes / 4
                            ? b->o.budget_bytes - b->mem : b->o.budget_bytes / 4,
        .xsum = ph ? b->xsum : NULL, .xscale = ph ? gain / n : 0,
        .bconst = ph ? 2.0 * gain * gain * b->w3sum / n + 3.0 * gain * b->rw3 : 0};
}

int bispec_triple(bispec *b, size_t t, int u1[2], int u2[2], double *bre,
                  double *bim, double *weight)
{
    if (!b || !u1 || !u2 || !bre || !bim || !weight || (int64_t)t >= b->nt)
        return sl_seterr(b ? &b->err : NULL, SL_EINVAL,
                         "bispec_triple: bad argument");
    bispec_flush(b);
    int lo = 0, hi = b->nf; /* largest j with tstart[j] <= t */
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (b->tstart[mid] <= (int64_t)t)
            lo = mid;
        else
            hi = mid;
    }
    phasor_graph g;
    graph_view(b, &g);
    int l1, l2;
    phasor_triple(&g, lo, (int64_t)t, &l1, &l2, bre, bim, weight);
    int nf = b->nf, s1 = l1 < nf ? 1 : -1, s2 = l2 < nf ? 1 : -1;
    u1[0] = s1 * b->fp[l1 % nf];
    u1[1] = s1 * b->fq[l1 % nf];
    u2[0] = s2 * b->fp[l2 % nf];
    u2[1] = s2 * b->fq[l2 % nf];
    return SL_OK;
}

double bispec_misfit(const bispec *b) { return b->phased ? b->misfit : NAN; }
size_t bispec_refine_bytes(const bispec *b) { return b && b->phased ? b->refine_used : 0; }

int bispec_phase(bispec *b, double *phase, unsigned char *known)
{
    if (!b)
        return SL_EINVAL;
    if (!b->n)
        return sl_seterr(&b->err, SL_EDATA, "bispec_phase: no frames");
    bispec_flush(b);
    if (!b->phased) {
        phasor_graph g;
        graph_view(b, &g);
        g.refine_used = &b->refine_used;
        int rc = phasor_solve(&g, b->o.refine_iters, b->work, b->phi,
                              b->known, &b->misfit);
        if (rc != SL_OK)
            return sl_seterr(&b->err, rc, "bispec_phase: solver failed");
        b->phased = 1;
    }
    phasor_export(b->nf, b->fp, b->fq, b->phi, b->known, b->w, b->h, phase,
                  known);
    return SL_OK;
}

int bispec_image(bispec *b, const double *modulus, float *img)
{
    if (!b || !img)
        return sl_seterr(b ? &b->err : NULL, SL_EINVAL,
                         "bispec_image: NULL argument");
    int rc = bispec_phase(b, NULL, NULL);
    if (rc != SL_OK)
        return rc;
    int w = b->w, h = b->h;
    double pbias = b->xsum ? b->o.adu_per_photon * b->w2sum / b->n + b->rw2 : 0.0;
    double *mod = b->work; /* free once the phases are solved */
    for (int j = 0; j < b->nf; j++)
        mod[j] = modulus ? modulus[bispec_fidx(b->fp[j], b->fq[j], w, h)]
                         : sqrt(fmax(b->psum[j] / b->n - pbias, 0.0));
    phasor_halfspec(b->pool, b->nf, b->fp, b->fq, b->phi, b->known, mod,
                    b->o.taper_frac, w, h, (double *)b->cin);
    fftw_execute(b->iplan);
    double sc = 1.0 / ((double)w * h);
    for (size_t i = 0; i < (size_t)w * h; i++)
        img[i] = (float)(b->cout[i] * sc);
    return SL_OK;
}

int bispec_binary(bispec *b, int nstart, const binary_result *init, binary_result *out,
                  closure_fit_info *info)
{
    if (!b || !init || !out)
        return sl_seterr(b ? &b->err : NULL, SL_EINVAL,
                         "bispec_binary: NULL argument");
    if (!b->n)
        return sl_seterr(&b->err, SL_EDATA, "bispec_binary: no frames");
    bispec_flush(b);
    phasor_graph g;
    graph_view(b, &g);
    return closure_fit_binary(&g, b->fp, b->fq, b->w, b->h, 0, nstart, init, out,
                              info, &b->err);
}
