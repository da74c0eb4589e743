/* closure.c - see closure.h. */
#include "closure_int.h"
#include "base/tpool.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NP 3          /* dx, dy, ln r */
#define MAX_STEPS 40
#define JK_STEPS 5    /* LM steps per jackknife refit (from the fit) */
#define MAX_DSTEP_PX 1.0 /* largest LM step of d */

/* cost()'s pass over the triples is cut into COST_CHUNKS fixed chunks,
 * summed on the pool's threads and added in chunk order: the same bits
 * on any number of threads. */
#define COST_CHUNKS 16
#define COST_SUMS (1 + NP + NP * NP)

/* The model at one frequency: arg V and its gradient in (dx, dy, ln r),
 * together so that a leg costs one cache line's half. */
typedef struct legm {
    double a, g[NP];
} legm;

typedef struct fitctx {
    const kept *t;
    long n;
    const double *k; /* 2 nf: each frequency's (kx, ky), radians per px */
    int nf;
    legm *mo;   /* nf: the model at each frequency */
    int skip;   /* jackknife group left out, -1 none */
    tpool *pool; /* NULL: this thread */
    int want_A;                          /* cost: also J^T W J, J^T W e */
    double part[COST_CHUNKS][COST_SUMS]; /* per chunk: f, b, A */
} fitctx;

/* arg V and its gradient at every frequency: one sincos and one atan2
 * each, so a step costs O(nf) here and O(n) in the triple loop. */
static void model(fitctx *c, const double th[NP])
{
    double r = exp(th[2]);
    for (int j = 0; j < c->nf; j++) {
        double kx = c->k[2 * j], ky = c->k[2 * j + 1];
        double ph = kx * th[0] + ky * th[1];
        double zr = r * cos(ph), zi = -r * sin(ph);
        double vr = 1.0 + zr, vi = zi, v2 = vr * vr + vi * vi;
        double qr = v2 > 0 ? (zr * vr + zi * vi) / v2 : 0;
        double qi = v2 > 0 ? (zi * vr - zr * vi) / v2 : 0;
        c->mo[j] = (legm){atan2(vi, vr), {-kx * qr, -ky * qr, qi}};
    }
}

/* The model of leg l: l >= nf is the conjugate frequency, whose phase
 * and gradient change sign (*s).  Selects, not branches: the legs'
 * halves come in no order a predictor could learn. */
static inline const legm *leg_model(const fitctx *c, int l, double *s)
{
    int mirror = l >= c->nf;
    *s = mirror ? -1.0 : 1.0;
    return &c->mo[mirror ? l - c->nf : l];
}

/* tpool job: chunk k's share of the cost, f then b then A's lower
 * triangle, into part[k].  Written out in scalars: with NP-loops over
 * arrays GCC kept J and A on the stack, at twice the time. */
static void cost_job(void *ctx, int tid, int nthr)
{
    fitctx *c = ctx;
    for (int k = tid; k < COST_CHUNKS; k += nthr) {
        double f = 0, b0 = 0, b1 = 0, b2 = 0;
        double a00 = 0, a10 = 0, a11 = 0, a20 = 0, a21 = 0, a22 = 0;
        for (long i = c->n * k / COST_CHUNKS; i < c->n * (k + 1) / COST_CHUNKS; i++) {
            const kept *t = &c->t[i];
            double wt = t->grp == c->skip ? 0.0 : t->wt, s1, s2;
            const legm *p1 = leg_model(c, t->l1, &s1), *p2 = leg_model(c, t->l2, &s2);
            const legm *p3 = &c->mo[t->j];
            double m = s1 * p1->a + s2 * p2->a - p3->a;
            /* |e| < 4 pi (four terms in [-pi, pi]): wrapped by the
             * nearest whole turn, rounded by truncation */
            double e = t->ph - m;
            e -= 2.0 * M_PI * (double)(int)(e * (0.5 / M_PI) + copysign(0.5, e));
            double we = wt * e;
            f += we * e;
            if (!c->want_A)
                continue;
            double j0 = s1 * p1->g[0] + s2 * p2->g[0] - p3->g[0];
            double j1 = s1 * p1->g[1] + s2 * p2->g[1] - p3->g[1];
            double j2 = s1 * p1->g[2] + s2 * p2->g[2] - p3->g[2];
            b0 += we * j0, b1 += we * j1, b2 += we * j2;
            double w0 = wt * j0, w1 = wt * j1, w2 = wt * j2;
            a00 += w0 * j0, a10 += w1 * j0, a11 += w1 * j1;
            a20 += w2 * j0, a21 += w2 * j1, a22 += w2 * j2;
        }
        double *o = c->part[k], *A = o + 1 + NP;
        o[0] = f, o[1] = b0, o[2] = b1, o[3] = b2;
        memset(A, 0, NP * NP * sizeof *A);
        A[0] = a00, A[3] = a10, A[4] = a11, A[6] = a20, A[7] = a21, A[8] = a22;
    }
}

/* Weighted cost at th; with A and b also J^T W J and J^T W e. */
static double cost(fitctx *c, const double th[NP], double *A, double *b)
{
    model(c, th);
    c->want_A = A != NULL;
    if (c->pool)
        tpool_run(c->pool, cost_job, c);
    else
        cost_job(c, 0, 1);
    double f = 0;
    if (A) {
        memset(A, 0, NP * NP * sizeof *A);
        memset(b, 0, NP * sizeof *b);
    }
    for (int k = 0; k < COST_CHUNKS; k++) {
        f += c->part[k][0];
        if (!A)
            continue;
        for (int p = 0; p < NP; p++) {
            b[p] += c->part[k][1 + p];
            for (int q = 0; q <= p; q++)
                A[p * NP + q] += c->part[k][1 + NP + p * NP + q];
        }
    }
    if (A)
        for (int p = 0; p < NP; p++)
            for (int q = p + 1; q < NP; q++)
                A[p * NP + q] = A[q * NP + p];
    return f;
}

/* Inverse of a symmetric 3 x 3 matrix by cofactors; 0 when singular. */
static int inv3(const double *m, double *o)
{
    o[0] = m[4] * m[8] - m[5] * m[7];
    o[1] = m[2] * m[7] - m[1] * m[8];
    o[2] = m[1] * m[5] - m[2] * m[4];
    o[3] = m[5] * m[6] - m[3] * m[8];
    o[4] = m[0] * m[8] - m[2] * m[6];
    o[5] = m[2] * m[3] - m[0] * m[5];
    o[6] = m[3] * m[7] - m[4] * m[6];
    o[7] = m[1] * m[6] - m[0] * m[7];
    o[8] = m[0] * m[4] - m[1] * m[3];
    double det = m[0] * o[0] + m[1] * o[3] + m[2] * o[6];
    if (!(fabs(det) > 0) || !isfinite(det))
        return 0;
    for (int k = 0; k < 9; k++)
        o[k] /= det;
    return 1;
}

/* Levenberg-Marquardt from th (updated); returns the final cost and
 * leaves J^T W J there in A. */
static double lm(fitctx *c, double th[NP], double *A, int max_steps,
                 int *steps)
{
    double b[NP], M[NP * NP], Mi[NP * NP], A2[NP * NP], b2[NP], lam = 1e-3;
    double f = cost(c, th, A, b);
    int it = 0;
    for (; it < max_steps && lam < 1e10; it++) {
        memcpy(M, A, sizeof M);
        for (int p = 0; p < NP; p++)
            M[p * NP + p] *= 1.0 + lam;
        if (!inv3(M, Mi)) {
            lam *= 10;
            continue;
        }
        double t2[NP];
        for (int p = 0; p < NP; p++) {
            double d = 0;
            for (int q = 0; q < NP; q++)
                d += Mi[p * NP + q] * b[q];
            t2[p] = th[p] + d;
        }
        /* A trust region of MAX_DSTEP_PX on d: the closure cost has a
         * local minimum about every pixel of d, and an unbounded step
         * from a poor start can leave the field (seen: 113 px away). */
        double dd = hypot(t2[0] - th[0], t2[1] - th[1]);
        if (dd > MAX_DSTEP_PX)
            for (int p = 0; p < NP; p++)
                t2[p] = th[p] + (t2[p] - th[p]) * MAX_DSTEP_PX / dd;
        /* r stays in (1e-4, 1e4): beyond that the fit has lost the pair. */
        t2[2] = fmin(fmax(t2[2], -9.2), 9.2);
        /* The trial pass also sums J^T W J: one pass per step, accepted
         * or not (most are), instead of a second pass on acceptance. */
        double f2 = cost(c, t2, A2, b2);
        if (f2 < f) {
            double rel = (f - f2) / (f > 0 ? f : 1);
            memcpy(th, t2, sizeof t2);
            memcpy(A, A2, sizeof A2);
            memcpy(b, b2, sizeof b2);
            f = f2;
            lam = fmax(lam / 3, 1e-9);
            if (rel < 1e-9)
                break;
        } else {
            lam *= 4;
        }
    }
    *steps = it;
    return f; /* A was computed at th: it changes only with an accepted step */
}

static void fill_result(const binary_result *init, const double th[NP],
                        const double C[NP * NP], double infl, int nfreq,
                        binary_result *out)
{
    double dx = th[0], dy = th[1], lr = th[2];
    if (lr > 0) { /* (d, r) ~ (-d, 1/r): state the fainter as companion */
        dx = -dx;
        dy = -dy;
        lr = -lr;
    }
    double s = hypot(dx, dy), r = exp(lr), s2 = s * s;
    *out = *init;
    out->dx_px = dx;
    out->dy_px = dy;
    out->x2_px = init->x1_px + dx;
    out->y2_px = init->y1_px + dy;
    out->sep_px = s;
    double pa = atan2(-dx, dy) * 180.0 / M_PI;
    out->pa_deg = pa < 0 ? pa + 360.0 : pa;
    out->flux_ratio = r;
    out->dm_mag = -2.5 * log10(r);
    /* Gradients of sep and PA (rad) in (dx, dy); the flip above changes
     * the signs of d and ln r together, which leaves these forms alone. */
    double gs[2] = {dx / s, dy / s}, gp[2] = {-dy / s2, dx / s2};
    double vs = 0, vp = 0;
    for (int p = 0; p < 2; p++)
        for (int q = 0; q < 2; q++) {
            vs += gs[p] * C[p * NP + q] * gs[q];
            vp += gp[p] * C[p * NP + q] * gp[q];
        }
    double vl = C[8];
    out->sep_err_px = sqrt(fmax(vs, 0));
    out->pa_err_deg = sqrt(fmax(vp, 0)) * 180.0 / M_PI;
    out->flux_ratio_err = r * sqrt(fmax(vl, 0));
    out->dm_err_mag = 2.5 / M_LN10 * sqrt(fmax(vl, 0));
    out->nfreq = nfreq;
    out->err_inflation = infl;
    out->fit_rms = NAN;
    out->d_from_peaks = 0;
    out->pa_ambiguous = 1.0 - r < 2.0 * out->flux_ratio_err || r > 1.0 - 1e-6;
}

static int refuse_equal(const binary_result *init, sl_err *err)
{
    return sl_seterr(err, SL_EDATA, "closure fit: an equal pair (dm %.2f +- "
                     "%.2f): closure phases cannot tell d from -d",
                     init->dm_mag, init->dm_err_mag);
}

static int is_equal_pair(const binary_result *init)
{
    return init->pa_ambiguous || !(init->flux_ratio > 0) || !(init->sep_px > 0);
}

/* The fit proper, on n kept triples over nf frequencies with k-vectors kv
 * (2 nf doubles, the model's a and gr scratch after them: 6 nf in all). */
/* Delete-a-group jackknife: refit without each sector of u_j's angle,
 * from the fit (a few LM steps each); its covariance into Cj. */
static void jackknife(fitctx *c, const double best[NP], double Cj[NP * NP])
{
    double jt[CLOSURE_JK][NP], jm[NP] = {0}, A[NP * NP];
    for (int k = 0; k < CLOSURE_JK; k++) {
        c->skip = k;
        memcpy(jt[k], best, NP * sizeof *best);
        int st;
        lm(c, jt[k], A, JK_STEPS, &st);
        for (int p = 0; p < NP; p++)
            jm[p] += jt[k][p] / CLOSURE_JK;
    }
    c->skip = -1;
    memset(Cj, 0, NP * NP * sizeof *Cj);
    for (int k = 0; k < CLOSURE_JK; k++)
        for (int p = 0; p < NP; p++)
            for (int q = 0; q < NP; q++)
                Cj[p * NP + q] += (CLOSURE_JK - 1.0) / CLOSURE_JK *
                                  (jt[k][p] - jm[p]) * (jt[k][q] - jm[q]);
}

/* The frequencies the kept triples use. */
static int count_used(const kept *t, long n, int nf, int *nused)
{
    unsigned char *used = calloc((size_t)nf, 1);
    if (!used)
        return SL_ENOMEM;
    for (long i = 0; i < n; i++)
        used[t[i].l1 % nf] = used[t[i].l2 % nf] = used[t[i].j] = 1;
    *nused = 0;
    for (int j = 0; j < nf; j++)
        *nused += used[j];
    free(used);
    return SL_OK;
}

static int fit_kept(const kept *t, long n, double *kv, int nf, double max_sep, tpool *pool,
                    const binary_result *init, binary_result *out,
                    closure_fit_info *info, sl_err *err)
{
    int nused = 0;
    if (count_used(t, n, nf, &nused) != SL_OK)
        return sl_seterr(err, SL_ENOMEM, "closure fit: out of memory");
    fitctx c = {t, n, kv, nf, (legm *)(kv + 2 * (size_t)nf), -1, pool, 0, {{0}}};
    double lr0 = log(fmin(fmax(init->flux_ratio, 1e-3), 0.9));
    double best[NP] = {init->dx_px, init->dy_px, lr0};
    double A[NP * NP], Abest[NP * NP] = {0}, fbest = INFINITY;
    int steps = 0;
    for (int sgn = 1; sgn >= -1; sgn -= 2) {
        double th[NP] = {sgn * init->dx_px, sgn * init->dy_px, lr0};
        int st;
        double f = lm(&c, th, A, MAX_STEPS, &st);
        if (f < fbest) {
            fbest = f;
            memcpy(best, th, sizeof th);
            memcpy(Abest, A, sizeof A);
            steps = st;
        }
    }
    double sep = hypot(best[0], best[1]);
    if (!(sep >= 0.5 && sep <= max_sep))
        return sl_seterr(err, SL_EDATA, "closure fit: no binary (separation "
                         "%.3g px, outside 0.5..%.0f px)", sep, max_sep);
    double wsum = 0;
    for (long i = 0; i < n; i++)
        wsum += t[i].wt;
    /* the same binary mirrored (-d): what the closure phases' sign says */
    double flip[NP] = {-best[0], -best[1], best[2]};
    double fflip = cost(&c, flip, NULL, NULL);
    /* and no companion at all (r -> 0: every model closure phase 0) */
    double none[NP] = {best[0], best[1], log(1e-12)};
    double fnone = cost(&c, none, NULL, NULL);
    double Ci[NP * NP], Cj[NP * NP];
    if (!inv3(Abest, Ci))
        return sl_seterr(err, SL_EDATA, "closure fit: singular normal "
                         "equations (%ld triples)", n);
    /* Residual variance per unit weight, and each frequency (not each
     * triple) counted as one measurement (closure.h, Limits). */
    double s2 = fbest / (double)(n > NP ? n - NP : 1);
    double infl = nused > 0 ? (double)n / nused : 1.0;
    for (int k = 0; k < NP * NP; k++)
        Ci[k] *= s2 * infl;
    jackknife(&c, best, Cj);
    /* The jackknife carries the atmosphere's correlations; the within-fit
     * part keeps the errors off zero when the sectors happen to agree. */
    for (int k = 0; k < NP * NP; k++)
        Ci[k] += Cj[k];
    fill_result(init, best, Ci, infl, nused, out);
    if (info)
        *info = (closure_fit_info){n, nused, sqrt(fbest / wsum), steps,
                                   (fflip - fbest) / (s2 * infl),
                                   (fnone - fbest) / (s2 * infl)};
    return SL_OK;
}

/* Start s within SAME_START_PX of a binary fitted from an earlier start,
 * or of its mirror (every fit tries d and -d): its fit would end in the
 * same minimum of the cost, whose minima lie about a pixel apart. */
#define SAME_START_PX 0.5
static int fitted_already(const binary_result *init, int s, const binary_result *fits,
                          const int *ok)
{
    for (int i = 0; i < s; i++) {
        double dx = init[s].dx_px, dy = init[s].dy_px, fx = fits[i].dx_px, fy = fits[i].dy_px;
        if (ok[i] && fmin(hypot(dx - fx, dy - fy), hypot(dx + fx, dy + fy)) < SAME_START_PX)
            return 1;
    }
    return 0;
}

/* The fit from each start that is not an equal pair nor at a binary
 * already fitted; the smaller weighted rms residual wins.  kv: 6 nf
 * doubles, the k-vectors first. */
static int fit_starts(const kept *t, long n, double *kv, int nf, double max_sep, tpool *pool,
                      int nstart, const binary_result *init, binary_result *out,
                      closure_fit_info *info, sl_err *err)
{
    int rc = SL_EDATA, found = 0, ok[CLOSURE_MAX_STARTS] = {0};
    binary_result fits[CLOSURE_MAX_STARTS];
    double best = INFINITY;
    for (int s = 0; s < nstart; s++) {
        binary_result r;
        closure_fit_info fi;
        if (is_equal_pair(&init[s])) {
            rc = refuse_equal(&init[s], err);
            continue;
        }
        if (fitted_already(init, s, fits, ok))
            continue;
        if ((rc = fit_kept(t, n, kv, nf, max_sep, pool, &init[s], &r, &fi, err)) != SL_OK)
            continue;
        fits[s] = r, ok[s] = 1;
        if (!found || fi.rms_rad < best) {
            best = fi.rms_rad, found = 1;
            *out = r;
            if (info)
                *info = fi;
        }
    }
    return found ? SL_OK : rc;
}

/* SL_OK when some of the nstart starts (1..CLOSURE_MAX_STARTS) is not an
 * equal pair, before the triples are chosen for nothing. */
static int check_starts(int nstart, const binary_result *init, sl_err *err)
{
    if (nstart < 1 || nstart > CLOSURE_MAX_STARTS)
        return sl_seterr(err, SL_EINVAL, "closure fit: %d starts (want 1 to %d)", nstart,
                         CLOSURE_MAX_STARTS);
    for (int s = 0; s < nstart; s++)
        if (!is_equal_pair(&init[s]))
            return SL_OK;
    return refuse_equal(&init[nstart - 1], err);
}

int closure_fit_binary(const phasor_graph *g, const int32_t *fp, const int32_t *fq, int w,
                       int h, double rel_min, int nstart, const binary_result *init,
                       binary_result *out, closure_fit_info *info, sl_err *err)
{
    if (!g || !fp || !fq || !init || !out || g->nfreq < 2 || w < 2 || h < 2)
        return sl_seterr(err, SL_EINVAL, "closure fit: bad argument");
    int nf = g->nfreq, rc = check_starts(nstart, init, err);
    if (rc != SL_OK)
        return rc;
    kept *t = NULL;
    long n = 0;
    double *k = malloc((size_t)nf * 6 * sizeof *k);
    if (!k)
        return sl_seterr(err, SL_ENOMEM, "closure fit: out of memory");
    if ((rc = closure_keep(g, fp, fq, rel_min, CLOSURE_MAX_TRIPLES, &t, &n, err)) != SL_OK)
        goto free_buffers;
    for (int j = 0; j < nf; j++) {
        k[2 * j] = 2.0 * M_PI * fp[j] / w;
        k[2 * j + 1] = 2.0 * M_PI * fq[j] / h;
    }
    rc = fit_starts(t, n, k, nf, 0.5 * (w < h ? w : h), g->pool, nstart, init, out, info, err);
free_buffers:
    free(t);
    free(k);
    return rc;
}

int closure_fit_binary_1d(int nang, int nf, int nproj, const int *off, const int *len, int np,
                          const double *bre, const double *bim, double rel_min, int nstart,
                          const binary_result *init, binary_result *out,
                          closure_fit_info *info, sl_err *err)
{
    if (nang < 1 || nf < 3 || nproj < 2 || !off || !len || np < 1 || !bre || !bim || !init ||
        !out)
        return sl_seterr(err, SL_EINVAL, "closure fit: bad argument");
    int nt = nang * nf, rc = check_starts(nstart, init, err);
    if (rc != SL_OK)
        return rc;
    kept *t = NULL;
    long n = 0;
    double *k = malloc((size_t)nt * 6 * sizeof *k);
    if (!k)
        return sl_seterr(err, SL_ENOMEM, "closure fit: out of memory");
    if ((rc = closure_keep_1d(nang, nf, off, len, np, bre, bim, rel_min, &t, &n, err)) != SL_OK)
        goto free_buffers;
    /* Fourier slice: frequency j of angle k is the 2-D rho_j n_k. */
    for (int a = 0; a < nang; a++) {
        double th = M_PI * a / nang;
        for (int j = 0; j < nf; j++) {
            double rho = 2.0 * M_PI * j / nproj;
            k[2 * (a * nf + j)] = rho * cos(th);
            k[2 * (a * nf + j) + 1] = rho * sin(th);
        }
    }
    rc = fit_starts(t, n, k, nt, 0.5 * nproj, NULL, nstart, init, out, info, err);
free_buffers:
    free(t);
    free(k);
    return rc;
}
