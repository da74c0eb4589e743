/* tsm_result.c - TSM steps 3-6 on the accumulated sums (tsm.h): the
 * phases (tsm_phase.c), the modulus with an optional reference, the
 * rebuilt projections and their registration across angles, and the
 * inverse Radon transform.  Cost at TSM-180, 200^2: ~50 ms, of which the
 * phases ~42 ms (tsm.c's header has the whole budget). */
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "tsm_int.h"

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int tsm_set_reference(tsm *t, const double *ps_ref, const double *ps_target,
                      double wiener)
{
    if (!ps_ref) {
        t->has_ref = 0;
        return SL_OK;
    }
    if (!(wiener >= 0))
        return sl_seterr(&t->err, SL_EINVAL, "tsm_set_reference: wiener %g", wiener);
    for (int pass = 0; pass < 2; pass++) {
        const double *src = pass ? ps_target : ps_ref;
        double *dst = pass ? t->tgt : t->ref;
        for (int a = 0; a < t->nang; a++) {
            const double *p = src ? src + (size_t)a * t->nf : NULL;
            if (p && !(p[0] > 0))
                return sl_seterr(&t->err, SL_EDATA, "tsm_set_reference: %s power at "
                                 "angle %d, u = 0 is %g", pass ? "target" : "reference",
                                 a, p[0]);
            for (int j = 0; j < t->nf; j++)
                dst[(size_t)a * t->nf + j] = p ? p[j] / p[0] : 1.0;
        }
    }
    /* The regulariser scales with the reference's own level: the median
     * of Rn^2 over u >= 1 (psc is free scratch until tsm_result). */
    size_t m = 0;
    for (int a = 0; a < t->nang; a++)
        for (int j = 1; j < t->nf; j++) {
            double r = t->ref[(size_t)a * t->nf + j];
            t->psc[m++] = r * r;
        }
    qsort(t->psc, m, sizeof *t->psc, cmp_double);
    t->wiener = wiener * t->psc[m / 2];
    t->has_ref = 1;
    return SL_OK;
}

/* Sum of the spectra of angle a's nbr neighbours each side; across
 * theta = 0/180 the line reverses, so the spectrum is conjugated. */
static void neighbour_sum(const tsm *t, int a, int nbr, float complex *out)
{
    int nf = t->nf, na = t->nang;
    for (int j = 0; j < nf; j++)
        out[j] = 0;
    for (int m = -nbr; m <= nbr; m++) {
        int b = a + m;
        if (m == 0)
            continue;
        int wrapped = b < 0 || b >= na;
        b = b < 0 ? b + na : b >= na ? b - na : b;
        const float complex *sp = t->ospec + (size_t)b * nf;
        for (int j = 0; j < nf; j++)
            out[j] += wrapped ? conjf(sp[j]) : sp[j];
    }
}

/* One job over the angles on t's pool: fn(t, a, arg) for every angle,
 * claimed 8 at a time.  Each angle writes only its own rows, so the bits
 * do not depend on the threads.  Why: the per-angle passes between the
 * phases and the inverse (the modulus with its cos and sin, the
 * neighbours' sums, the centring) were ~1-3 ms of one thread a run. */
typedef void (*angle_fn)(tsm *t, int a, void *arg);

typedef struct angle_job {
    tsm *t;
    angle_fn fn;
    void *arg;
    atomic_int next;
} angle_job;

static void angle_run(void *ctx, int tid, int n)
{
    angle_job *j = ctx;
    (void)tid, (void)n;
    for (int a0; (a0 = atomic_fetch_add(&j->next, 8)) < j->t->nang;)
        for (int a = a0; a < a0 + 8 && a < j->t->nang; a++)
            j->fn(j->t, a, j->arg);
}

static void each_angle(tsm *t, angle_fn fn, void *arg)
{
    angle_job j = {.t = t, .fn = fn, .arg = arg};
    atomic_init(&j.next, 0);
    tpool_run(t->pool, angle_run, &j);
}

/* What the modulus is divided by on the spatial path at frequency j of the
 * angle whose cos and sin are co, si (1 on the Fourier path).  The
 * bilinear rays sample the image's bilinear interpolant (transfer
 * sinc^2(u) sinc^2(v)) along a unit lattice, so a slice is damped by H =
 * sinc^2(rho cos) sinc^2(rho sin) (down to 0.41 at rho = 1/2) plus
 * aliases; the object's, a reference's and a target's power all carry it.
 * H is divided out up to j_K = nangles / pi, where neighbouring slices lie
 * within one bin of each other (arc pi j / nangles), and held at H(j_K)
 * beyond: there the FBP's angular undersampling streaks grow with the high
 * frequencies, and the damping acts as their window.  Measured, 200^2
 * bench six-star, 100 frames, seeds 1-3, c without / with a reference: 180
 * angles, damped 0.935 / 0.978, all divided 0.953 / 0.978, up to j_K 0.951
 * / 0.980; 90 angles 0.897 / 0.909, 0.870 / 0.853, 0.899 / 0.904; 18
 * angles 0.626 / 0.539, 0.531 / 0.461, 0.625 / 0.539. */
static double signal_transfer(const tsm *t, double co, double si, int j)
{
    if (t->o.variant != TSM_SPATIAL)
        return 1.0;
    double jk = t->nang / M_PI;
    double r = M_PI * (j < jk ? j : jk) / t->ns, x = r * co, y = r * si;
    double sx = fabs(x) > 1e-12 ? sin(x) / x : 1.0, sy = fabs(y) > 1e-12 ? sin(y) / y : 1.0;
    return sx * sx * sy * sy;
}

/* (3) The phases of every projection spectrum, from the raw bispectrum
 * unless asked: measured (64^2, binary and 6 stars, 300..10^4
 * photons/frame), the unbiased estimator's phases are much noisier where
 * the photon bias dominates (c 0.69 vs 0.88 at 300 photons, PA errors);
 * the bias, being real, only shrinks those elements' phases towards the
 * smooth continuation.  The arc: bench binary, 24 seeds each, binary
 * found / mean c, at D/r0 ~ 11 noiseless, 1e4 photons + read noise, and
 * D/r0 ~ 4 with that noise: off 24 / 0.835, 20 / 0.801, 24 / 0.895; 1 bin
 * 24 / 0.848, 23 / 0.843, 23 / 0.901; 1.5 bins 24 / 0.857, 24 / 0.862,
 * 23 / 0.901; 2 bins 24 / 0.868, 24 / 0.869, 22 / 0.899. */
static void result_phases(tsm *t, double sbar, double g, double lv)
{
    int nf = t->nf;
    double arc = t->o.arc_bins > 0 ? t->o.arc_bins : t->o.arc_bins < 0 ? 0.0 : 1.5;
    t->extent = 0;
    if (t->o.arc_bins == 0) {   /* capped by the diameter: tsm_extent.c */
        tsm_power(t, t->psc);
        t->extent = tsm_extent_px(t->psc, t->nang, nf, t->ns, 0.05, t->pool);
        t->extent = t->extent > 0 ? t->extent : 0;   /* NAN: no memory, no cap */
        arc = fmin(arc, tsm_arc_cap(t->extent, t->ns));
    }
    t->arc = arc;
    for (size_t i = 0; i < (size_t)t->nang * nf; i++) {   /* psc: scratch */
        t->psc[i] = t->ps[i] / t->nframes;
        t->pw[i] = tsm_photon_power(t, i, sbar, g, lv);
    }
    tsm_phase_inputs(t->ph, t->bre, t->bim, t->nframes, t->psc, t->pw,
                     t->o.bispec_bias_phase ? g : 0.0, sbar, t->o.weight, arc);
    int iters = t->o.refine_iters < 0 ? 0 : t->o.refine_iters ? t->o.refine_iters : 10;
    tsm_phase_solve(t->ph, iters, t->phase);
}

/* (4) the modulus (calibrated by the reference when there is one,
 * undamped, apodised) with the phases: angle a's projection spectrum. */
static void spectrum_angle(tsm *t, int a, void *arg)
{
    (void)arg;
    int nf = t->nf, J = nf - 1;
    const double *pc = t->psc + (size_t)a * nf, *rf = t->ref + (size_t)a * nf;
    const double *tg = t->tgt + (size_t)a * nf;
    double th = radon_angle_rad(t->rad, a), co = cos(th), si = sin(th);
    for (int j = 0; j < nf; j++) {
        double m2 = pc[j];
        if (t->has_ref && pc[0] > 0)
            m2 = pc[j] * rf[j] / (rf[j] * rf[j] + t->wiener) * fmax(tg[j], 0);
        double m = m2 > 0 ? sqrt(m2) / signal_transfer(t, co, si, j) : 0, x = (double)j / J;
        if (t->o.apod == TSM_APOD_HANN)
            m *= 0.5 * (1 + cos(M_PI * x));
        else if (t->o.apod == TSM_APOD_COSINE)
            m *= cos(M_PI_2 * x);
        double phi = t->phase[(size_t)a * nf + j];
        t->ospec[(size_t)a * nf + j] = CMPLXF((float)(m * cos(phi)), (float)(m * sin(phi)));
    }
}

/* Angle a shifted to its projection's centroid (of the part above
 * *(double *)cfrac of its peak). */
static void centre_angle(tsm *t, int a, void *cfrac)
{
    tsm_phase_shift(t->ospec + (size_t)a * t->nf, t->nf, t->ns,
                    tsm_phase_centroid(t->proj + (size_t)a * t->ns, t->ns, *(double *)cfrac));
}

/* Angle a's neighbours within *(int *)nbr each side, summed into sref. */
static void neighbours_angle(tsm *t, int a, void *nbr)
{
    neighbour_sum(t, a, *(int *)nbr, t->sref + (size_t)a * t->nf);
}

/* (5) centre each projection on its centroid: twice, the second pass
 * measures with the object already away from the wrap point.  Then align
 * each to the sum of its neighbours within align_deg (they see nearly the
 * same object): a per-angle shift measured on the whole profile rather
 * than on its bright part; then the reprojection rounds.  *moved: whether
 * the last two ran (the object may have moved as a whole). */
static int result_align(tsm *t, float *img, double cfrac, int *moved)
{
    int ns = t->ns, st;
    for (int pass = 0; pass < 2; pass++) {
        if ((st = radon_spec_to_proj(t->rad, t->ospec, t->proj)) != SL_OK)
            return st;
        each_angle(t, centre_angle, &cfrac);
    }
    double adeg = t->o.align_deg > 0 ? t->o.align_deg : t->o.align_deg < 0 ? 0.0 : 8.0;
    int nbr = (int)floor(adeg * t->nang / 180.0 + 1e-9);
    nbr = nbr > t->nang / 4 ? t->nang / 4 : nbr;
    for (int it = 0; nbr > 0 && it < 3; it++) {
        each_angle(t, neighbours_angle, &nbr);
        tsm_phase_align_all(t->ph, t->ospec, t->sref, ns, 3.0, NULL);
    }
    int riters = t->o.reproj_iters < 0 ? 0 : t->o.reproj_iters ? t->o.reproj_iters : 3;
    *moved = nbr > 0 || riters > 0;
    /* t->proj is free until the final projections: the rounds' shifts */
    if (riters > 0)
        return tsm_phase_reproj(t->ph, t->rad, t->ospec, (size_t)t->w * t->h, riters,
                                t->o.reproj_frac > 0 ? t->o.reproj_frac : 0.2, img,
                                t->sref, t->proj);
    return SL_OK;
}

/* Angle a's projection moved by the 2-D shift cxy[0..1] (its part along
 * the angle). */
static void shift_angle(tsm *t, int a, void *cxy)
{
    const double *c = cxy;
    double th = radon_angle_rad(t->rad, a);
    tsm_phase_shift(t->ospec + (size_t)a * t->nf, t->nf, t->ns, c[0] * cos(th) + c[1] * sin(th));
}

/* Put the object's centroid back at the centre with one 2-D shift, the
 * least-squares fit cx cos + cy sin of the per-angle centroids
 * (consistent across angles by construction). */
static int result_recentre(tsm *t, double cfrac)
{
    int ns = t->ns, st;
    if ((st = radon_spec_to_proj(t->rad, t->ospec, t->proj)) != SL_OK)
        return st;
    double sxx = 0, sxy = 0, syy = 0, bx = 0, by = 0;
    for (int a = 0; a < t->nang; a++) {
        double c = tsm_phase_centroid(t->proj + (size_t)a * ns, ns, cfrac);
        double th = radon_angle_rad(t->rad, a), co = cos(th), si = sin(th);
        sxx += co * co, sxy += co * si, syy += si * si, bx += c * co, by += c * si;
    }
    double det = sxx * syy - sxy * sxy;
    if (!(det > 1e-9 * (sxx + syy) * (sxx + syy)))
        return SL_OK;
    double cxy[2] = {(syy * bx - sxy * by) / det, (sxx * by - sxy * bx) / det};
    each_angle(t, shift_angle, cxy);
    return SL_OK;
}

/* (6) inversion */
static int result_invert(tsm *t, float *img)
{
    tsm_inverse inv = t->o.inverse;
    if (inv == TSM_INV_AUTO)
        inv = t->o.variant == TSM_FOURIER ? TSM_INV_FBP_GRID : TSM_INV_FBP_SPATIAL;
    switch (inv) {
    case TSM_INV_FBP_SPATIAL: return radon_fbp(t->rad, t->proj, img);
    case TSM_INV_ITER:
        return radon_invert_iter(t->rad, t->ospec, t->o.inv_iters ? t->o.inv_iters : 40, 1, img);
    default: return radon_fbp_slices(t->rad, t->ospec, img);
    }
}

int tsm_result(tsm *t, float *img)
{
    if (t->nframes == 0)
        return sl_seterr(&t->err, SL_EDATA, "tsm_result: no frames added");
    tsm_sync_sums(t);
    double sbar, g, lv;
    tsm_bias_terms(t, &sbar, &g, &lv);
    result_phases(t, sbar, g, lv);
    tsm_power(t, t->psc);
    each_angle(t, spectrum_angle, NULL);
    double cfrac = t->o.centroid_frac > 0 ? t->o.centroid_frac
                 : t->o.centroid_frac < 0 ? 0.0 : 0.05;
    int moved = 0, st;
    if ((st = result_align(t, img, cfrac, &moved)) != SL_OK ||
        (moved && (st = result_recentre(t, cfrac)) != SL_OK) ||
        (st = radon_spec_to_proj(t->rad, t->ospec, t->proj)) != SL_OK)
        goto fail_radon;
    t->have_result = 1;
    if ((st = result_invert(t, img)) != SL_OK)
        goto fail_radon;
    return SL_OK;
fail_radon:
    return sl_seterr(&t->err, st, "tsm_result: %s", radon_errmsg(t->rad));
}

int tsm_projections(tsm *t, float *proj)
{
    if (!t->have_result)
        return sl_seterr(&t->err, SL_EDATA, "tsm_projections: no result yet");
    memcpy(proj, t->proj, (size_t)t->nang * t->ns * sizeof *proj);
    return SL_OK;
}

int tsm_phases(tsm *t, double *phase)
{
    if (!t->have_result)
        return sl_seterr(&t->err, SL_EDATA, "tsm_phases: no result yet");
    memcpy(phase, t->phase, (size_t)t->nang * t->nf * sizeof *phase);
    return SL_OK;
}
