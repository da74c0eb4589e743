/* phasor.c - see phasor.h.
 *
 * Phases are carried as unit phasors E = exp(i phi) for all 2*nfreq legs
 * (E[nfreq + j] = conj E[j]), so no angle is ever wrapped and a triple's
 * proposal is two complex products:  E(u_j) ~ E(l1) E(l2) conj(B_t)/|B_t|.
 * With PHASOR_WEIGHT_MOD the weight |B_t| cancels the normalisation and
 * the proposal is just E(l1) E(l2) conj(B_t).
 */
#include "phasor.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

size_t phasor_work_doubles(int nfreq) { return 6 * (size_t)(nfreq > 0 ? nfreq : 0); }

void phasor_triple(const phasor_graph *g, int j, int64_t t, int *l1, int *l2,
                   double *bre, double *bim, double *wt)
{
    int k = g->tk[t];
    int a = g->lut[g->ubase[j] - g->doff[k]], b = g->dleg[k];
    double inv = g->nframes > 0 ? 1.0 / g->nframes : 0.0;
    double re, im;
    if (g->accd) {
        re = g->accd[2 * t] * inv;
        im = g->accd[2 * t + 1] * inv;
    } else {
        re = g->accf[2 * t] * inv;
        im = g->accf[2 * t + 1] * inv;
    }
    double mre = re, mim = im; /* raw mean, for the variance */
    if (g->xsum) {
        /* X(-u) = conj X(u); the target enters conjugated. */
        int n = g->nfreq;
        int h1 = a % n, h2 = b % n;
        double x1r = g->xsum[2 * h1], x1i = g->xsum[2 * h1 + 1];
        double x2r = g->xsum[2 * h2], x2i = g->xsum[2 * h2 + 1];
        if (a >= n)
            x1i = -x1i;
        if (b >= n)
            x2i = -x2i;
        double x3r = g->xsum[2 * j], x3i = -g->xsum[2 * j + 1];
        re += g->bconst - g->xscale * (x1r + x2r + x3r);
        im -= g->xscale * (x1i + x2i + x3i);
    }
    double mod = sqrt(re * re + im * im); /* not hypot: 10x slower here */
    double w = mod;
    if (g->weight == PHASOR_WEIGHT_UNIT) {
        w = mod > 0 ? 1.0 : 0.0;
    } else if (g->weight == PHASOR_WEIGHT_SNR && g->nframes > 1 &&
               (g->acc2d || g->acc2f)) {
        double m2 = (g->acc2d ? g->acc2d[t] : g->acc2f[t]) * inv;
        double var = m2 - (mre * mre + mim * mim);
        double se = sqrt(fmax(var, 0.0) * inv);
        /* A triple with no scatter (noiseless data) gets the weight of
         * one with a standard error of 1e-6 of its modulus. */
        w = se > 1e-6 * mod ? mod / se : (mod > 0 ? 1e6 : 0.0);
    }
    *l1 = a;
    *l2 = b;
    *bre = re;
    *bim = im;
    *wt = w;
}

/* Proposal for E(u_j) from one triple: w * E1 E2 conj(B)/|B|. */
static void propose(const double *E, int l1, int l2, double bre, double bim,
                    double w, double *zr, double *zi)
{
    double mod = sqrt(bre * bre + bim * bim);
    if (!(w > 0) || !(mod > 0)) {
        *zr = *zi = 0;
        return;
    }
    double e1r = E[2 * l1], e1i = E[2 * l1 + 1];
    double e2r = E[2 * l2], e2i = E[2 * l2 + 1];
    double pr = e1r * e2r - e1i * e2i, pi = e1r * e2i + e1i * e2r;
    double s = w / mod;
    *zr = s * (pr * bre + pi * bim);
    *zi = s * (pi * bre - pr * bim);
}

static void set_phasor(double *E, int n, int j, double re, double im)
{
    E[2 * j] = re;
    E[2 * j + 1] = im;
    E[2 * (n + j)] = re;
    E[2 * (n + j) + 1] = -im;
}

/* Add a proposal for leg l (conjugated onto its half-plane frequency). */
static void add_leg(double *Z, int n, int l, double zr, double zi)
{
    if (l >= n) {
        l -= n;
        zi = -zi;
    }
    Z[2 * l] += zr;
    Z[2 * l + 1] += zi;
}

/* One strong triple of the refinement: target, legs, unit bispectrum
 * and weight. */
typedef struct strong {
    int32_t j, l1, l2;
    float br, bi, w;
} strong;

/* The strong triples: of each target's triples with known legs, those
 * of weight >= PHASOR_REFINE_REL x that target's largest, so every
 * frequency keeps its best constraints (a threshold on the global
 * largest weight kept only the few triples near the origin, where |B| is
 * larger by orders of magnitude).  Two passes over each target's
 * triples; NULL when out of memory. */
static strong *strong_triples(const phasor_graph *g, const unsigned char *known,
                              int64_t *n_out)
{
    int n = g->nfreq;
    int64_t cap = 0, ns = 0;
    strong *s = NULL;
    for (int j = 1; j < n; j++) {
        if (!known[j])
            continue;
        double wmax = 0;
        for (int pass = 0; pass < 2; pass++)
            for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++) {
                int l1, l2;
                double br, bi, w;
                phasor_triple(g, j, t, &l1, &l2, &br, &bi, &w);
                double mod = sqrt(br * br + bi * bi);
                if (!known[l1 % n] || !known[l2 % n] || !(w > 0) || !(mod > 0))
                    continue;
                if (pass == 0) {
                    wmax = fmax(wmax, w);
                    continue;
                }
                if (w < PHASOR_REFINE_REL * wmax)
                    continue;
                if (ns == cap) {
                    cap = cap ? 2 * cap : 65536;
                    strong *p = realloc(s, sizeof *p * (size_t)cap);
                    if (!p) {
                        free(s);
                        return NULL;
                    }
                    s = p;
                }
                s[ns++] = (strong){j, l1, l2, (float)(br / mod), (float)(bi / mod), (float)w};
            }
    }
    *n_out = ns;
    return s;
}

/* Weighted closure misfit sum w (1 - Re(E_j conj(E1 E2 conj b))). */
static double misfit(const strong *s, int64_t ns, const double *E)
{
    double c = 0;
    for (int64_t t = 0; t < ns; t++) {
        double pr, pi;
        propose(E, s[t].l1, s[t].l2, s[t].br, s[t].bi, s[t].w, &pr, &pi);
        c += s[t].w - (pr * E[2 * s[t].j] + pi * E[2 * s[t].j + 1]);
    }
    return c;
}

/* Least-squares refinement, Jacobi on phasors: from E(u_j) ~ E1 E2
 * conj(b) follow E1 ~ E(u_j) conj(E2) b and E2 ~ E(u_j) conj(E1) b
 * (b = B/|B|); each frequency takes the phasor of its proposals' sum.
 * Undamped it converged 2.5x faster than with the current phasor added
 * (c 0.954 after 20 passes against 0.932 on a piston-phase six-star);
 * the misfit is watched and a pass that raises it is undone, which ends
 * the refinement, as does one that lowers it by less than 1e-4.  Only
 * the strong triples (PHASOR_REFINE_REL) take part: at 0.01 about a
 * quarter of them, and with them the piston-phase six-star reaches c
 * 0.952 in 30 passes where 0.1 (6 %) left it at 0.850. */
static void refine(const phasor_graph *g, int iters, double *E, double *Z,
                   const unsigned char *known)
{
    int n = g->nfreq;
    int64_t ns = 0;
    phasor_graph gr = *g;
    gr.weight = g->refine_weight;
    strong *s = strong_triples(&gr, known, &ns);
    double *keep = malloc(sizeof *keep * 4 * (size_t)n);
    if (!s || !keep)
        goto free_all;
    double cost = misfit(s, ns, E);
    for (int it = 0; it < iters; it++) {
        memcpy(keep, E, sizeof *keep * 4 * (size_t)n);
        memset(Z, 0, sizeof *Z * 2 * (size_t)n);
        for (int64_t t = 0; t < ns; t++) {
            const strong *q = &s[t];
            double pr, pi, ur = q->w * q->br, ui = q->w * q->bi;
            double ejr = E[2 * q->j], eji = E[2 * q->j + 1];
            propose(E, q->l1, q->l2, q->br, q->bi, q->w, &pr, &pi);
            Z[2 * q->j] += pr;
            Z[2 * q->j + 1] += pi;
            for (int side = 0; side < 2; side++) {
                int lo = side ? q->l1 : q->l2, lt = side ? q->l2 : q->l1;
                double cr = E[2 * lo], ci = -E[2 * lo + 1];
                double xr = ejr * cr - eji * ci, xi = ejr * ci + eji * cr;
                add_leg(Z, n, lt, xr * ur - xi * ui, xr * ui + xi * ur);
            }
        }
        for (int j = 1; j < n; j++) {
            double m = hypot(Z[2 * j], Z[2 * j + 1]);
            if (known[j] && !g->seed[j] && m > 0)
                set_phasor(E, n, j, Z[2 * j] / m, Z[2 * j + 1] / m);
        }
        double c = misfit(s, ns, E);
        if (!(c < cost)) {
            memcpy(E, keep, sizeof *keep * 4 * (size_t)n);
            break;
        }
        int small = cost - c < 1e-3 * cost;
        cost = c;
        if (small)
            break;
    }
free_all:
    free(s);
    free(keep);
}

int phasor_solve(const phasor_graph *g, int iters, double *work, double *phi,
                 unsigned char *known, double *misfit_out)
{
    int n = g->nfreq;
    if (n <= 0 || !work || !phi || !known)
        return SL_EINVAL;
    double *E = work;            /* 4n: phasors of all legs */
    double *Z = work + 4 * (size_t)n; /* 2n: proposal sums */
    memset(known, 0, (size_t)n);
    for (int j = 0; j < n; j++)
        set_phasor(E, n, j, 1.0, 0.0);
    known[0] = 1;

    /* The recursion: legs always have lower rank than the target.  Its
     * misfit comes free, weighted by |B| whatever the recursion's weights
     * (so that one threshold serves them all): with zm the |B|-weighted
     * sum of the unit proposals, sum_t |B_t| (1 - cos(res_t)) = sum_t
     * |B_t| - Re(conj(E_j) zm). */
    double wsum = 0, miss = 0;
    for (int j = 1; j < n; j++) {
        if (g->seed[j]) {
            known[j] = 1;
            continue;
        }
        double zr = 0, zi = 0, mr = 0, mi = 0, ms = 0;
        for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++) {
            int l1, l2;
            double br, bi, w, pr, pi;
            phasor_triple(g, j, t, &l1, &l2, &br, &bi, &w);
            if (!known[l1 % n] || !known[l2 % n] || !(w > 0))
                continue;
            propose(E, l1, l2, br, bi, w, &pr, &pi);
            zr += pr;
            zi += pi;
            double mod = sqrt(br * br + bi * bi);
            mr += pr * mod / w, mi += pi * mod / w, ms += mod;
        }
        double m = hypot(zr, zi);
        if (m > 0) {
            set_phasor(E, n, j, zr / m, zi / m);
            known[j] = 1;
            wsum += ms;
            miss += ms - (mr * zr + mi * zi) / m;
        }
    }
    double misfit_rel = wsum > 0 ? miss / wsum : 0;
    if (misfit_out)
        *misfit_out = misfit_rel;
    if (iters < 0)
        iters = misfit_rel > PHASOR_AUTO_MISFIT ? PHASOR_AUTO_ITERS : 0;
    if (iters > 0)
        refine(g, iters, E, Z, known);
    for (int j = 0; j < n; j++)
        phi[j] = known[j] ? atan2(E[2 * j + 1], E[2 * j]) : 0.0;
    return SL_OK;
}

static size_t fidx(int p, int q, int w, int h)
{
    return (size_t)((q % h + h) % h) * w + (size_t)((p % w + w) % w);
}

void phasor_export(int nfreq, const int32_t *fp, const int32_t *fq,
                   const double *phi, const unsigned char *known, int w,
                   int h, double *phase, unsigned char *known_full)
{
    size_t npx = (size_t)w * h;
    if (phase)
        memset(phase, 0, npx * sizeof *phase);
    if (known_full)
        memset(known_full, 0, npx);
    for (int j = 0; j < nfreq; j++) {
        size_t a = fidx(fp[j], fq[j], w, h), m = fidx(-fp[j], -fq[j], w, h);
        if (phase) {
            phase[a] = phi[j];
            phase[m] = -phi[j];
        }
        if (known_full)
            known_full[a] = known_full[m] = known[j];
    }
}

void phasor_halfspec(int nfreq, const int32_t *fp, const int32_t *fq,
                     const double *phi, const unsigned char *known,
                     const double *mod, double taper_frac, int w, int h,
                     double *cin)
{
    int wc = w / 2 + 1;
    double rmax = 0;
    for (int j = 0; j < nfreq; j++)
        if (known[j])
            rmax = fmax(rmax, hypot(fp[j], fq[j]));
    double r0 = rmax * (1.0 - taper_frac), r1 = rmax + 1.0;
    memset(cin, 0, (size_t)h * wc * 2 * sizeof *cin);
    for (int j = 0; j < nfreq; j++) {
        if (!known[j])
            continue;
        int p = fp[j], q = fq[j];
        double r = hypot(p, q);
        double tap = r <= r0 ? 1.0
                             : 0.5 * (1.0 + cos(M_PI * (r - r0) / (r1 - r0)));
        double ph = phi[j] - 2.0 * M_PI * ((double)p * (w / 2) / w +
                                           (double)q * (h / 2) / h);
        double re = mod[j] * tap * cos(ph), im = mod[j] * tap * sin(ph);
        size_t k = (size_t)((q + h) % h) * wc + (size_t)p;
        cin[2 * k] = re;
        cin[2 * k + 1] = im;
        if (p == 0 && q > 0) { /* the p = 0 column holds both signs of q */
            k = (size_t)(h - q) * wc;
            cin[2 * k] = re;
            cin[2 * k + 1] = -im;
        }
    }
}
