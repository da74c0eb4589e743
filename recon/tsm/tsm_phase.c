/* tsm_phase.c - the 1-D phases of TSM (see tsm.h): recovery from the
 * bispectrum, and step 5's alignment of every angle on the threads (the
 * shift of one angle, and the rounds against the reprojected image, are
 * in tsm_align.c).
 *
 * The problem.  Per angle the unknowns are phi(2..J); every stored pair
 * q = (u1, u2) gives a closure residual r = beta - phi(u1) - phi(u2) +
 * phi(u1 + u2), and we minimise f = sum_q w_q (1 - cos r_q).  In 1-D a
 * target u is reached by only ~u/2 pairs, and where the power spectrum
 * has a gap (an aperture mask's empty u-v annuli; a strong-seeing transfer
 * function fallen to ~1e-6 of its peak) almost no pair crosses it: the
 * elements with one leg on each side mostly have their small leg below
 * the gap and fix only phase *differences* beyond it.  The common offset
 * of the band beyond the gap rests on a few weak elements.  The recursion
 * sets it from the first elements it meets, and one-frequency-at-a-time
 * refinement (Gauss-Seidel, what this file did before) moves a whole band
 * only by tiny steps: measured on the bench binary (17-hole mask, D/r0 ~
 * 11, 128^2, 100 frames), c 0.68 after 4 sweeps, 0.74 after 400.  A band
 * rotated by a constant is a Hilbert-transform-like error: lobes 2-4 px
 * either side of each star, brighter than a dm = 1 companion.
 *
 * The solver.  f'' = cos r <= 1 along every r, so with the constant
 * H = sum w a a^T (a = dr/dphi, entries -1, -1, +1) the quadratic
 * f(phi) + g.d + d^T H d / 2 lies above f(phi + d): each step d = -H^-1 g
 * decreases f (majorise-minimise), and it moves every mode at once, bands
 * included.  H is factored once per angle (Cholesky); steps are
 * accelerated by Nesterov momentum, restarted whenever the momentum points
 * uphill (gradient test, O'Donoghue & Candes 2015), which halves the
 * steps needed.  Measured on that binary, noiseless, 24 seeds, without
 * the angular average of tsm_phase_inputs: binary found 18/24 -> 24/24,
 * mean c 0.756 -> 0.835 (the recursion alone: 0.80 with the average).  A
 * frequency no pair reaches keeps its recursion value (tiny ridge on H).
 *
 * Cost per angle: H from the pairs (~10 flops each), Cholesky (J-1)^3/6
 * multiply-adds, then per step one pass over the pairs (~25 flops each),
 * two triangular solves and J sin/cos: at J = 100, 180 angles, 10 steps
 * ~40 ms on one core.  Everything for one angle (pairs, factor) stays in
 * L2 while that angle is solved.  With a pool (tsm_phase_set_pool) the
 * threads claim angles as they free up, each with its own scratch
 * (phase_ws), for the inputs, the solve and the alignment alike.
 */
#include "tsm.h"
#include "tsm_chol.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "base/bigmem.h"
#include "base/tpool.h"

enum { PHASE_MAX_WS = 64 };

/* Scratch of one angle's inputs or solve: one per thread. */
typedef struct phase_ws {
    double *L;               /* n(n+1)/2: packed Cholesky factor */
    double *er, *ei;         /* nf: phasors of the evaluation point */
    double *x, *y, *g, *g0;  /* nf: iterate, extrapolated point, step,
                              * gradient */
    double *acc;             /* 2 np: one angle's averaged bispectrum */
    double *scr;             /* 2 nf: tsm_phase_align's */
} phase_ws;

struct tsm_phase {
    int nang, nf, np, n;     /* n = nf - 2 unknowns per angle */
    int *off, *len;          /* per u1 */
    int *pu1, *pu2;          /* per pair */
    float *ph, *wt;          /* caller's inputs */
    int *kq;                 /* np: angles averaged each side, per pair */
    int *qs, *nk;            /* pairs by kq descending; counts, scratch */
    tpool *pool;             /* NULL: one thread */
    int nws;
    phase_ws ws[PHASE_MAX_WS];
};

static void ws_free(phase_ws *w)
{
    free(w->L), free(w->er), free(w->ei), free(w->x), free(w->y), free(w->g);
    free(w->g0), free(w->acc), free(w->scr);
    memset(w, 0, sizeof *w);
}

static int ws_alloc(const tsm_phase *p, phase_ws *w);

/* The phasors' and weights' bytes (bigmem.h). */
static size_t ph_bytes(const tsm_phase *p) { return ((size_t)p->nang * p->np * 2 + 1) * sizeof(float); }
static size_t wt_bytes(const tsm_phase *p) { return ((size_t)p->nang * p->np + 1) * sizeof(float); }

/* tpool job: thread tid hands back its share of the phasors and weights
 * (23 + 12 MB at 512^2, 180 angles, unmapped by one thread alone at the
 * end of a run before). */
static void release_job(void *ctx, int tid, int nt)
{
    tsm_phase *p = ctx;
    bigmem_release_share(p->ph, ph_bytes(p), tid, nt);
    bigmem_release_share(p->wt, wt_bytes(p), tid, nt);
}

void tsm_phase_free(tsm_phase *p)
{
    if (!p)
        return;
    if (p->pool && tpool_size(p->pool) > 1)
        tpool_run(p->pool, release_job, p);
    free(p->off), free(p->len), free(p->pu1), free(p->pu2);
    bigmem_free(p->ph, ph_bytes(p));
    bigmem_free(p->wt, wt_bytes(p));
    free(p->kq);
    free(p->qs), free(p->nk);
    for (int i = 0; i < p->nws; i++)
        ws_free(&p->ws[i]);
    free(p);
}

int tsm_phase_npairs(const tsm_phase *p) { return p->np; }
const int *tsm_phase_rowoff(const tsm_phase *p) { return p->off; }
const int *tsm_phase_rowlen(const tsm_phase *p) { return p->len; }
float *tsm_phase_phasors(tsm_phase *p) { return p->ph; }
float *tsm_phase_weights(tsm_phase *p) { return p->wt; }

tsm_phase *tsm_phase_new(int nangles, int nfreq, int r2, sl_err *err)
{
    if (nangles < 1 || nfreq < 3 || r2 < 0) {
        sl_seterr(err, SL_EINVAL, "tsm_phase_new: %d angles, %d frequencies, r2 %d",
                  nangles, nfreq, r2);
        return NULL;
    }
    tsm_phase *p = calloc(1, sizeof *p);
    if (!p)
        goto fail_free;
    int J = nfreq - 1;
    p->nang = nangles, p->nf = nfreq, p->n = nfreq - 2;
    p->off = calloc(nfreq, sizeof *p->off);
    p->len = calloc(nfreq, sizeof *p->len);
    if (!p->off || !p->len)
        goto fail_free;
    for (int u1 = 1; u1 < J; u1++) {
        int n = u1 < J - u1 ? u1 : J - u1;
        if (r2 > 0 && n > r2)
            n = r2;
        p->off[u1] = p->np;
        p->len[u1] = n;
        p->np += n;
    }
    size_t np = (size_t)p->np, na = (size_t)nangles;
    p->pu1 = malloc((np + 1) * sizeof *p->pu1);
    p->pu2 = malloc((np + 1) * sizeof *p->pu2);
    p->ph = bigmem_alloc(ph_bytes(p), 0);
    p->wt = bigmem_alloc(wt_bytes(p), 0);
    p->nws = 1;
    p->kq = malloc((np + 1) * sizeof *p->kq);
    p->qs = malloc((np + 1) * sizeof *p->qs);
    p->nk = malloc(2 * (na / 8 + 2) * sizeof *p->nk);
    if (!p->pu1 || !p->pu2 || !p->ph || !p->wt || !p->kq || !p->qs || !p->nk ||
        ws_alloc(p, &p->ws[0]) != SL_OK)
        goto fail_free;
    for (int u1 = 1; u1 < J; u1++)
        for (int u2 = 1; u2 <= p->len[u1]; u2++) {
            int q = p->off[u1] + u2 - 1;
            p->pu1[q] = u1, p->pu2[q] = u2;
        }
    return p;
fail_free:
    sl_seterr(err, SL_ENOMEM, "tsm_phase_new: out of memory");
    tsm_phase_free(p);
    return NULL;
}

static int ws_alloc(const tsm_phase *p, phase_ws *w)
{
    size_t nf = (size_t)p->nf;
    w->L = malloc(tsm_chol_packed(p->n) * sizeof *w->L);
    w->er = malloc(nf * sizeof *w->er);
    w->ei = malloc(nf * sizeof *w->ei);
    w->x = malloc(nf * sizeof *w->x);
    w->y = malloc(nf * sizeof *w->y);
    w->g = malloc(nf * sizeof *w->g);
    w->g0 = malloc(nf * sizeof *w->g0);
    w->acc = malloc((2 * (size_t)p->np + 1) * sizeof *w->acc);
    w->scr = malloc(2 * nf * sizeof *w->scr);
    if (!w->L || !w->er || !w->ei || !w->x || !w->y || !w->g || !w->g0 || !w->acc || !w->scr) {
        ws_free(w);
        return SL_ENOMEM;
    }
    return SL_OK;
}

int tsm_phase_set_pool(tsm_phase *p, tpool *pool)
{
    int n = pool ? tpool_size(pool) : 1;
    if (n > PHASE_MAX_WS)
        return SL_EINVAL;
    for (; p->nws < n; p->nws++)
        if (ws_alloc(p, &p->ws[p->nws]) != SL_OK)
            return SL_ENOMEM;
    p->pool = pool;
    return SL_OK;
}

/* Run job(ctx, tid, n) on the pool, or inline. */
static void run(const tsm_phase *p, tpool_fn job, void *ctx)
{
    if (p->pool)
        tpool_run(p->pool, job, ctx);
    else
        job(ctx, 0, 1);
}

/* Angles are claimed ANG_CLAIM at a time by whichever thread is free:
 * each angle is computed whole by one thread from its own inputs (the
 * thread's workspace is scratch), so the bits do not depend on who takes
 * it.  Fixed halves left one thread idle whenever the shared host slowed
 * the other (one half took 2x the other's time in a 512^2 run). */
enum { ANG_CLAIM = 2 };

/* The next angles [*a0, *a1) for the caller; 0 when none is left. */
static int claim(atomic_int *next, int nang, int *a0, int *a1)
{
    *a0 = atomic_fetch_add(next, ANG_CLAIM);
    *a1 = *a0 + ANG_CLAIM < nang ? *a0 + ANG_CLAIM : nang;
    return *a0 < nang;
}

/* ---- inputs ------------------------------------------------------------ */

typedef struct inputs_job {
    tsm_phase *p;
    const double *bre, *bim, *pm, *pb;
    double n, g, sbar;
    tsm_weight weight;
    int kmax;
    const int *ge;
    atomic_int next;
} inputs_job;

static void inputs_angle(const inputs_job *j, phase_ws *ws, int a);

static void inputs_run(void *ctx, int tid, int n)
{
    inputs_job *j = ctx;
    (void)n;
    for (int a0, a1; claim(&j->next, j->p->nang, &a0, &a1);)
        for (int a = a0; a < a1; a++)
            inputs_angle(j, &j->p->ws[tid], a);
}

void tsm_phase_inputs(tsm_phase *p, const double *bre, const double *bim, double nframes,
                      const double *pm, const double *pb, double g, double sbar,
                      tsm_weight weight, double arc_bins)
{
    int na = p->nang, np = p->np, kmax = na / 8;
    double n = nframes;
    /* Angles each side within arc_bins at the pair's largest frequency u3:
     * neighbours are pi u3 / na bins apart there.  Pairs listed by k
     * descending (counting sort) so that angle offset m visits the prefix
     * of pairs with k >= |m|: sum_q (2k + 1) ~ 4.4 np at J = 100, 180
     * angles, arc 1.5, each pass over one angle's row (in cache). */
    int *ge = p->nk, *pos = p->nk + kmax + 2;
    memset(ge, 0, (kmax + 2) * sizeof *ge);
    for (int q = 0; q < np; q++) {
        double k = arc_bins > 0 ? floor(arc_bins * na / (M_PI * (p->pu1[q] + p->pu2[q]))) : 0;
        p->kq[q] = k < kmax ? (int)k : kmax;
        ge[p->kq[q]]++;
    }
    for (int k = kmax; k >= 0; k--) {   /* ge[k]: # pairs with kq >= k */
        pos[k] = ge[k + 1];
        ge[k] += ge[k + 1];
    }
    for (int q = 0; q < np; q++)
        p->qs[pos[p->kq[q]]++] = q;
    inputs_job j = {p, bre, bim, pm, pb, n, g, sbar, weight, kmax, ge, 0};
    run(p, inputs_run, &j);
}

/* Angle a's averaged bispectrum, phasors and weights (per pair: the
 * angles within its kq each side). */
static void inputs_angle(const inputs_job *j, phase_ws *ws, int a)
{
    const tsm_phase *p = j->p;
    int na = p->nang, nf = p->nf, np = p->np, kmax = j->kmax;
    const int *ge = j->ge;
    const double *bre = j->bre, *bim = j->bim, *pm = j->pm, *pb = j->pb;
    double n = j->n, g = j->g, sbar = j->sbar;
    tsm_weight weight = j->weight;
    double *acc = ws->acc;
    memset(acc, 0, 2 * (size_t)np * sizeof *acc);
    for (int m = -kmax; m <= kmax; m++) {
        /* theta + 180 deg is the same line reversed: B conjugated */
        int b = a + m, wrap = b < 0 || b >= na;
        b = b < 0 ? b + na : b >= na ? b - na : b;
        double sg = wrap ? -1.0 : 1.0;
        const double *br = bre + (size_t)b * np, *bi = bim + (size_t)b * np;
        const double *w = g > 0 ? pb + (size_t)b * nf : NULL;
        for (int i = 0; i < ge[m < 0 ? -m : m]; i++) {
            int q = p->qs[i], u1 = p->pu1[q], u2 = p->pu2[q];
            acc[2 * q] += br[q] / n;
            if (w)
                acc[2 * q] += 2 * g * g * sbar - g * (w[u1] + w[u2] + w[u1 + u2]);
            acc[2 * q + 1] += sg * bi[q] / n;
        }
    }
    const double *pa = pm + (size_t)a * nf;
    float *ph = p->ph + (size_t)a * np * 2, *wt = p->wt + (size_t)a * np;
    for (int q = 0; q < np; q++) {
        int u1 = p->pu1[q], u2 = p->pu2[q];
        double c = 1.0 / (2 * p->kq[q] + 1), xr = acc[2 * q] * c, xi = acc[2 * q + 1] * c;
        double m = sqrt(xr * xr + xi * xi), d = pa[u1] * pa[u2] * pa[u1 + u2];
        double w = 0;
        if (m > 0) {
            ph[2 * q] = (float)(xr / m), ph[2 * q + 1] = (float)(xi / m);
            switch (weight) {
            case TSM_WEIGHT_UNIT: w = 1; break;
            case TSM_WEIGHT_MODULUS: w = m; break;
            case TSM_WEIGHT_SNR2: w = d > 0 ? m * m / d : 0; break;
            default: w = d > 0 ? m / sqrt(d) : 0;
            }
        }
        wt[q] = (float)w;
    }
}

/* ---- one angle ---------------------------------------------------------- */

/* Recursion: phi(u) = arg sum over u1 + u2 = u of w E(u1) E(u2) conj(b),
 * u upwards from E(0), E(1) (set by the caller). */
static void recursion(const tsm_phase *p, phase_ws *ws, const float *ph, const float *wt)
{
    double *er = ws->er, *ei = ws->ei;
    for (int u = 2; u < p->nf; u++) {
        double sr = 0, si = 0;
        for (int u1 = (u + 1) / 2; u1 < u; u1++) {
            int u2 = u - u1;
            if (u2 > p->len[u1])
                continue;
            int q = p->off[u1] + u2 - 1;
            double w = wt[q], br = ph[2 * q], bi = ph[2 * q + 1];
            double tr = er[u1] * er[u2] - ei[u1] * ei[u2];
            double ti = er[u1] * ei[u2] + ei[u1] * er[u2];
            sr += w * (tr * br + ti * bi), si += w * (ti * br - tr * bi);
        }
        double m = sqrt(sr * sr + si * si);
        er[u] = m > 0 ? sr / m : 1.0, ei[u] = m > 0 ? si / m : 0.0;
    }
}

/* H = sum w a a^T over the unknowns u = 2..J (row u - 2), then factored. */
static void closure_factor(const tsm_phase *p, phase_ws *ws, const float *wt)
{
    int n = p->n;
    double *L = ws->L, tr = 0;
    memset(L, 0, tsm_chol_packed(n) * sizeof *L);
    for (int q = 0; q < p->np; q++) {
        double w = wt[q];
        if (!(w > 0))
            continue;
        int i1 = p->pu1[q] - 2, i2 = p->pu2[q] - 2, i3 = p->pu1[q] + p->pu2[q] - 2;
        /* a = -1, -1, +1 on u1, u2, u3 (i2 <= i1 < i3; phi(1) is fixed,
         * so i = -1 drops out; u1 = u2 puts 4w on the diagonal) */
        L[tsm_chol_packed(i3) + i3] += w;
        if (i1 >= 0)
            L[tsm_chol_packed(i1) + i1] += w, L[tsm_chol_packed(i3) + i1] -= w;
        if (i2 >= 0)
            L[tsm_chol_packed(i2) + i2] += w, L[tsm_chol_packed(i3) + i2] -= w,
            L[tsm_chol_packed(i1) + i2] += i1 == i2 ? 2 * w : w;
    }
    for (int i = 0; i < n; i++)
        tr += L[tsm_chol_packed(i) + i];
    /* a frequency no pair reaches has a zero row: the ridge keeps it put */
    for (int i = 0; i < n; i++)
        L[tsm_chol_packed(i) + i] += 1e-9 * tr / n + 1e-300;
    tsm_chol_factor(L, n);
}

/* Two pairs at once (u2, u2 + 1 < u1) of row u1, as the plain loop does
 * them one after the other: the same products, each g element's adds in
 * the same order (g1 takes lane 0 then lane 1).  A pair of zero weight
 * adds +0, which changes no element: g starts at +0 and a sum of +0 with
 * anything never gives -0. */
typedef double v2d __attribute__((vector_size(16)));
typedef long long v2i __attribute__((vector_size(16)));

static inline double gradient_pair2(const double *er, const double *ei, const float *ph,
                                    const float *wt, int u1, int u2, int q, double g1,
                                    double *g)
{
    double e1r = er[u1], e1i = ei[u1];
    v2d x2r, x2i, x3r, x3i, w = {wt[q], wt[q + 1]}, gv;
    memcpy(&x2r, er + u2, sizeof x2r), memcpy(&x2i, ei + u2, sizeof x2i);
    memcpy(&x3r, er + u1 + u2, sizeof x3r), memcpy(&x3i, ei + u1 + u2, sizeof x3i);
    v2d br = {ph[2 * q], ph[2 * q + 2]}, bi = {ph[2 * q + 1], ph[2 * q + 3]};
    v2d tr = e1r * x2r - e1i * x2i, ti = e1r * x2i + e1i * x2r;
    v2d cr = br * tr + bi * ti, ci = bi * tr - br * ti;
    v2d sv = w * (cr * x3i + ci * x3r);
    sv = (v2d)((v2i)sv & (v2i)(w > 0));
    g1 -= sv[0];
    g1 -= sv[1];
    memcpy(&gv, g + u2, sizeof gv), gv -= sv, memcpy(g + u2, &gv, sizeof gv);
    memcpy(&gv, g + u1 + u2, sizeof gv), gv += sv, memcpy(g + u1 + u2, &gv, sizeof gv);
    return g1;
}

/* Gradient of f at phases y into g (g[u] for u >= 2 meaningful). */
static void gradient(const tsm_phase *p, phase_ws *ws, const float *ph, const float *wt,
                     const double *y, double *g)
{
    int nf = p->nf;
    double *er = ws->er, *ei = ws->ei;
    for (int u = 2; u < nf; u++)
        er[u] = cos(y[u]), ei[u] = sin(y[u]);
    memset(g, 0, nf * sizeof *g);
    /* Row u1's pairs (q in order) with g[u1] held in a register: no other
     * pair of the row touches g[u1] (u2 < u1 but for u2 = u1, u3 > u1), so
     * these are the operations of one pass over q, in its order, without
     * a store-to-load chain through g[u1] from pair to pair (which had
     * made this loop half of a TSM solve); two pairs at a time while
     * both have u2 < u1. */
    for (int u1 = 1; u1 < nf - 1; u1++) {
        double e1r = er[u1], e1i = ei[u1], g1 = g[u1];
        int u2 = 1, q = p->off[u1], n = p->len[u1], n2 = n < u1 - 1 ? n : u1 - 1;
        for (; u2 + 1 <= n2; u2 += 2, q += 2)
            g1 = gradient_pair2(er, ei, ph, wt, u1, u2, q, g1, g);
        for (; u2 <= n; u2++, q++) {
            double w = wt[q];
            if (!(w > 0))
                continue;
            int u3 = u1 + u2;
            /* exp(i r) = b conj(E1 E2) E3; df/dr = w sin r */
            double tr = e1r * er[u2] - e1i * ei[u2], ti = e1r * ei[u2] + e1i * er[u2];
            double br = ph[2 * q], bi = ph[2 * q + 1];
            double cr = br * tr + bi * ti, ci = bi * tr - br * ti;
            double s = w * (cr * ei[u3] + ci * er[u3]);
            g1 -= s;
            if (u2 == u1)
                g1 -= s;
            else
                g[u2] -= s;
            g[u3] += s;
        }
        g[u1] = g1;
    }
}

static void solve_angle(const tsm_phase *p, phase_ws *ws, int a, int iters, double *phase)
{
    int nf = p->nf, n = p->n;
    const float *ph = p->ph + (size_t)a * p->np * 2, *wt = p->wt + (size_t)a * p->np;
    double *x = ws->x, *y = ws->y, *g = ws->g;
    ws->er[0] = 1, ws->ei[0] = 0, ws->er[1] = 1, ws->ei[1] = 0;
    recursion(p, ws, ph, wt);
    for (int u = 0; u < nf; u++)
        x[u] = y[u] = atan2(ws->ei[u], ws->er[u]);
    if (iters > 0)
        closure_factor(p, ws, wt);
    double t = 1;
    for (int it = 0; it < iters; it++) {
        gradient(p, ws, ph, wt, y, g);
        memcpy(ws->g0, g, nf * sizeof *g);
        tsm_chol_solve(ws->L, n, g + 2);
        /* x+ = y - d; momentum (t - 1)/t+ unless it points uphill, i.e.
         * grad f(y).(x+ - x) > 0 (O'Donoghue-Candes gradient restart) */
        double tn = 0.5 * (1 + sqrt(1 + 4 * t * t)), m = (t - 1) / tn, up = 0;
        for (int u = 2; u < nf; u++) {
            double xn = y[u] - g[u];
            up += ws->g0[u] * (xn - x[u]);
            y[u] = xn, g[u] = xn - x[u], x[u] = xn;   /* g: the step x+ - x */
        }
        if (up > 0)
            t = 1;
        else {
            for (int u = 2; u < nf; u++)
                y[u] += m * g[u];
            t = tn;
        }
    }
    for (int u = 0; u < nf; u++)
        phase[u] = remainder(x[u], 2 * M_PI);
}

/* ---- step 5's alignment of every angle (tsm_align.c: one angle) ------- */

typedef struct align_job {
    tsm_phase *p;
    float complex *spec;
    const float complex *ref;
    int ns;
    double range;
    float *dsum;
    atomic_int next;
} align_job;

static void align_run(void *ctx, int tid, int n)
{
    align_job *j = ctx;
    int nf = j->p->nf;
    (void)n;
    for (int a0, a1; claim(&j->next, j->p->nang, &a0, &a1);)
        for (int a = a0; a < a1; a++) {
            float complex *o = j->spec + (size_t)a * nf;
            double d = tsm_phase_align(o, j->ref + (size_t)a * nf, nf, j->ns, j->range,
                                       j->p->ws[tid].scr);
            tsm_phase_shift(o, nf, j->ns, d);
            if (j->dsum)
                j->dsum[a] += (float)d;
        }
}

void tsm_phase_align_all(tsm_phase *p, float complex *spec, const float complex *ref, int ns,
                         double range, float *dsum)
{
    align_job j = {p, spec, ref, ns, range, dsum, 0};
    run(p, align_run, &j);
}

typedef struct solve_job {
    tsm_phase *p;
    int iters;
    double *phase;
    atomic_int next;
} solve_job;

static void solve_run(void *ctx, int tid, int n)
{
    solve_job *j = ctx;
    (void)n;
    for (int a0, a1; claim(&j->next, j->p->nang, &a0, &a1);)
        for (int a = a0; a < a1; a++)
            solve_angle(j->p, &j->p->ws[tid], a, j->iters, j->phase + (size_t)a * j->p->nf);
}

int tsm_phase_solve(tsm_phase *p, int iters, double *phase)
{
    solve_job j = {p, iters, phase, 0};
    run(p, solve_run, &j);
    return SL_OK;
}
