/* closure.c - see closure.h. */
#include "closure.h"
#include "base/tpool.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NP 3          /* dx, dy, ln r */
#define MAX_STEPS 40
#define CLOSURE_JK 8  /* jackknife groups */
#define JK_STEPS 5    /* LM steps per jackknife refit (from the fit) */
#define MAX_DSTEP_PX 1.0 /* largest LM step of d */

typedef struct kept {
    int32_t l1, l2, j; /* legs (phasor.h) and target */
    float ph, wt;      /* arg B and |B| */
    int32_t grp;       /* jackknife group: the sector of u_j's angle */
} kept;

/* cost()'s pass over the triples is cut into COST_CHUNKS fixed chunks,
 * summed on the pool's threads and added in chunk order: the same bits
 * on any number of threads. */
#define COST_CHUNKS 16
#define COST_SUMS (1 + NP + NP * NP)

typedef struct fitctx {
    const kept *t;
    long n;
    const double *k; /* 2 nf: each frequency's (kx, ky), radians per px */
    int nf;
    double *a;  /* nf: arg V(u_j) */
    double *gr; /* NP nf: d arg V / d (dx, dy, ln r) */
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
        c->a[j] = atan2(vi, vr);
        double qr = v2 > 0 ? (zr * vr + zi * vi) / v2 : 0;
        double qi = v2 > 0 ? (zi * vr - zr * vi) / v2 : 0;
        c->gr[NP * j] = -kx * qr;
        c->gr[NP * j + 1] = -ky * qr;
        c->gr[NP * j + 2] = qi;
    }
}

/* The model phase of leg l (l >= nf: the conjugate frequency) and its
 * gradient added with sign s into *m and J. */
static inline void add_leg(const fitctx *c, int l, double s, double *m, double J[NP])
{
    if (l >= c->nf) {
        l -= c->nf;
        s = -s;
    }
    *m += s * c->a[l];
    for (int k = 0; k < NP; k++)
        J[k] += s * c->gr[NP * l + k];
}

/* tpool job: chunk k's share of the cost, f then b then A's lower
 * triangle, into part[k]. */
static void cost_job(void *ctx, int tid, int nthr)
{
    fitctx *c = ctx;
    for (int k = tid; k < COST_CHUNKS; k += nthr) {
        double *f = c->part[k], *b = f + 1, *A = b + NP;
        memset(f, 0, COST_SUMS * sizeof *f);
        for (long i = c->n * k / COST_CHUNKS; i < c->n * (k + 1) / COST_CHUNKS; i++) {
            const kept *t = &c->t[i];
            if (t->grp == c->skip)
                continue;
            double m = 0, J[NP] = {0};
            add_leg(c, t->l1, 1.0, &m, J);
            add_leg(c, t->l2, 1.0, &m, J);
            add_leg(c, t->j, -1.0, &m, J);
            /* |e| < 4 pi (four terms in [-pi, pi]): two folds wrap it, at
             * a tenth of remainder()'s cost */
            double e = t->ph - m;
            for (int w = 0; w < 2; w++)
                e = e > M_PI ? e - 2.0 * M_PI : e < -M_PI ? e + 2.0 * M_PI : e;
            *f += t->wt * e * e;
            if (!c->want_A)
                continue;
            for (int p = 0; p < NP; p++) {
                b[p] += t->wt * J[p] * e;
                for (int q = 0; q <= p; q++)
                    A[p * NP + q] += t->wt * J[p] * J[q];
            }
        }
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

/* Triple t of target j: its legs, mean bispectrum and |B|. */
static double triple_mod(const phasor_graph *g, int j, int64_t t, int *l1, int *l2, double *br,
                         double *bi)
{
    double wt;
    phasor_triple(g, j, t, l1, l2, br, bi, &wt);
    return sqrt(*br * *br + *bi * *bi);
}

/* Keep the triples with |B| >= thr: counts when out is NULL.  *mx (may
 * be NULL) gets the largest |B| seen. */
static long keep_triples(const phasor_graph *g, const int32_t *fp,
                         const int32_t *fq, double thr, kept *out, double *mx)
{
    long n = 0;
    for (int j = 1; j < g->nfreq; j++)
        for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++) {
            int l1, l2;
            double br, bi, m = triple_mod(g, j, t, &l1, &l2, &br, &bi);
            if (mx && m > *mx)
                *mx = m;
            if (!(m >= thr))
                continue;
            if (out) {
                /* half-plane angle in [0, pi) -> CLOSURE_JK sectors */
                double ang = atan2(fq[j], fp[j]);
                if (ang < 0)
                    ang += M_PI;
                int grp = (int)(ang / M_PI * CLOSURE_JK) % CLOSURE_JK;
                out[n] = (kept){l1, l2, j, (float)atan2(bi, br), (float)m, grp};
            }
            n++;
        }
    return n;
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
    fitctx c = {t, n, kv, nf, kv + 2 * (size_t)nf, kv + 3 * (size_t)nf, -1, pool, 0, {{0}}};
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

/* The threshold that keeps at most about cap of the triples at or above
 * thr, the strongest: a histogram of log(|B| / mx) in CAP_BINS bins
 * between thr and mx, cut where the running count would pass cap. */
#define CAP_BINS 1024
static double cap_threshold(const phasor_graph *g, double mx, double thr, long cap)
{
    long hist[CAP_BINS] = {0};
    double lo = log(thr / mx); /* < 0 */
    for (int j = 1; j < g->nfreq; j++)
        for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++) {
            int l1, l2;
            double br, bi, m = triple_mod(g, j, t, &l1, &l2, &br, &bi);
            if (!(m >= thr))
                continue;
            int b = (int)(log(m / mx) / lo * CAP_BINS);
            hist[b < 0 ? 0 : b >= CAP_BINS ? CAP_BINS - 1 : b]++;
        }
    long n = 0;
    for (int b = 0; b < CAP_BINS; b++) {
        if (n + hist[b] > cap)
            return mx * exp(lo * b / CAP_BINS);
        n += hist[b];
    }
    return thr;
}

int closure_fit_binary(const phasor_graph *g, const int32_t *fp,
                       const int32_t *fq, int w, int h, double rel_min,
                       const binary_result *init, binary_result *out,
                       closure_fit_info *info, sl_err *err)
{
    if (!g || !fp || !fq || !init || !out || g->nfreq < 2 || w < 2 || h < 2)
        return sl_seterr(err, SL_EINVAL, "closure fit: bad argument");
    if (is_equal_pair(init))
        return refuse_equal(init, err);
    int nf = g->nfreq, rc;
    double mx = 0;
    keep_triples(g, fp, fq, INFINITY, NULL, &mx);
    double thr = (rel_min > 0 ? rel_min : CLOSURE_REL_MIN) * mx;
    long n = keep_triples(g, fp, fq, thr, NULL, NULL);
    if (n > CLOSURE_MAX_TRIPLES) {
        thr = cap_threshold(g, mx, thr, CLOSURE_MAX_TRIPLES);
        n = keep_triples(g, fp, fq, thr, NULL, NULL);
    }
    if (n < 16)
        return sl_seterr(err, SL_EDATA, "closure fit: only %ld triples "
                         "above %.3g of the strongest", n, thr);
    kept *t = malloc((size_t)n * sizeof *t);
    double *k = malloc((size_t)nf * 6 * sizeof *k);
    if (!t || !k) {
        rc = sl_seterr(err, SL_ENOMEM, "closure fit: out of memory "
                       "(%ld triples)", n);
        goto free_buffers;
    }
    keep_triples(g, fp, fq, thr, t, NULL);
    for (int j = 0; j < nf; j++) {
        k[2 * j] = 2.0 * M_PI * fp[j] / w;
        k[2 * j + 1] = 2.0 * M_PI * fq[j] / h;
    }
    rc = fit_kept(t, n, k, nf, 0.5 * (w < h ? w : h), g->pool, init, out, info, err);
free_buffers:
    free(t);
    free(k);
    return rc;
}

/* TSM's pairs at or above thr (counts when out is NULL; *mx: the largest). */
static long keep_1d(int nang, int nf, const int *off, const int *len, int np,
                    const double *bre, const double *bim, double thr,
                    kept *out, double *mx)
{
    long n = 0;
    for (int k = 0; k < nang; k++)
        for (int u1 = 1; u1 < nf; u1++)
            for (int u2 = 1; u2 <= len[u1]; u2++) {
                size_t q = (size_t)k * np + off[u1] + u2 - 1;
                double m = sqrt(bre[q] * bre[q] + bim[q] * bim[q]);
                if (mx && m > *mx)
                    *mx = m;
                if (!(m >= thr))
                    continue;
                if (out) {
                    int b = k * nf;
                    out[n] = (kept){b + u1, b + u2, b + u1 + u2,
                                    (float)atan2(bim[q], bre[q]), (float)m,
                                    k * CLOSURE_JK / nang};
                }
                n++;
            }
    return n;
}

int closure_fit_binary_1d(int nang, int nf, int nproj, const int *off,
                          const int *len, int np, const double *bre,
                          const double *bim, double rel_min,
                          const binary_result *init, binary_result *out,
                          closure_fit_info *info, sl_err *err)
{
    if (nang < 1 || nf < 3 || nproj < 2 || !off || !len || np < 1 || !bre ||
        !bim || !init || !out)
        return sl_seterr(err, SL_EINVAL, "closure fit: bad argument");
    if (is_equal_pair(init))
        return refuse_equal(init, err);
    double mx = 0;
    keep_1d(nang, nf, off, len, np, bre, bim, INFINITY, NULL, &mx);
    double thr = (rel_min > 0 ? rel_min : CLOSURE_REL_MIN) * mx;
    long n = keep_1d(nang, nf, off, len, np, bre, bim, thr, NULL, NULL);
    if (n < 16)
        return sl_seterr(err, SL_EDATA, "closure fit: only %ld pairs above "
                         "%.3g of the strongest", n, thr);
    int nt = nang * nf, rc;
    kept *t = malloc((size_t)n * sizeof *t);
    double *k = malloc((size_t)nt * 6 * sizeof *k);
    if (!t || !k) {
        rc = sl_seterr(err, SL_ENOMEM, "closure fit: out of memory "
                       "(%ld pairs)", n);
        goto free_buffers;
    }
    keep_1d(nang, nf, off, len, np, bre, bim, thr, t, NULL);
    /* Fourier slice: frequency j of angle k is the 2-D rho_j n_k. */
    for (int a = 0; a < nang; a++) {
        double th = M_PI * a / nang;
        for (int j = 0; j < nf; j++) {
            double rho = 2.0 * M_PI * j / nproj;
            k[2 * (a * nf + j)] = rho * cos(th);
            k[2 * (a * nf + j) + 1] = rho * sin(th);
        }
    }
    rc = fit_kept(t, n, k, nt, 0.5 * nproj, NULL, init, out, info, err);
free_buffers:
    free(t);
    free(k);
    return rc;
}
