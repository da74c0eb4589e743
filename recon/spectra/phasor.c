/* phasor.c - see phasor.h.
 *
 * Phases are carried as unit phasors E = exp(i phi) for all 2*nfreq legs
 * (E[nfreq + j] = conj E[j]), so no angle is ever wrapped and a triple's
 * proposal is two complex products:  E(u_j) ~ E(l1) E(l2) conj(B_t)/|B_t|.
 * With PHASOR_WEIGHT_MOD the weight |B_t| cancels the normalisation and
 * the proposal is just E(l1) E(l2) conj(B_t).
 */
#include "phasor_int.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

size_t phasor_work_doubles(int nfreq) { return 6 * (size_t)(nfreq > 0 ? nfreq : 0); }

void phasor_triple(const phasor_graph *g, int j, int64_t t, int *l1, int *l2,
                   double *bre, double *bim, double *wt)
{
    phasor_triple_mod(g, j, t, l1, l2, bre, bim, wt);
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
        phasor_set(E, n, j, 1.0, 0.0);
    known[0] = 1;

    /* The recursion: legs always have lower rank than the target.  Its
     * misfit comes free, weighted by |B| whatever the recursion's weights
     * (so that one threshold serves them all): with zm the |B|-weighted
     * sum of the unit proposals, sum_t |B_t| (1 - cos(res_t)) = sum_t
     * |B_t| - Re(conj(E_j) zm). */
    double misfit_rel = 0;
    int rc = phasor_recur(g, E, known, &misfit_rel);
    if (rc != SL_OK)
        return rc;
    if (misfit_out)
        *misfit_out = misfit_rel;
    if (iters < 0)
        iters = misfit_rel > PHASOR_AUTO_MISFIT ? PHASOR_AUTO_ITERS : 0;
    if (iters > 0)
        phasor_refine(g, iters, E, Z, known);
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
    if (!phase && !known_full)
        return; /* bispec_phase's solve-only call */
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

/* phasor_halfspec's frequencies in fixed chunks, claimed by any thread;
 * each writes only its own frequencies' cells. */
enum { HALF_CHUNK = 2048 };
typedef struct half_job {
    const int32_t *fp, *fq;
    const double *phi, *mod;
    const unsigned char *known;
    int nfreq, w, h;
    double r0, r1, r0sq; /* r0sq: below it hypot(p, q) <= r0 surely */
    double *cin;
    atomic_int next;
} half_job;

static void half_run(void *ctx, int tid, int nthr)
{
    half_job *J = ctx;
    int w = J->w, h = J->h, wc = w / 2 + 1;
    (void)tid, (void)nthr;
    for (int j0; (j0 = atomic_fetch_add(&J->next, HALF_CHUNK)) < J->nfreq;)
        for (int j = j0; j < J->nfreq && j < j0 + HALF_CHUNK; j++) {
            if (!J->known[j])
                continue;
            int p = J->fp[j], q = J->fq[j];
            double tap = 1.0;
            if ((double)p * p + (double)q * q >= J->r0sq) {
                double r = hypot(p, q);
                tap = r <= J->r0 ? 1.0 : 0.5 * (1.0 + cos(M_PI * (r - J->r0) / (J->r1 - J->r0)));
            }
            double ph = J->phi[j] - 2.0 * M_PI * ((double)p * (w / 2) / w +
                                                  (double)q * (h / 2) / h);
            double re = J->mod[j] * tap * cos(ph), im = J->mod[j] * tap * sin(ph);
            size_t k = (size_t)((q + h) % h) * wc + (size_t)p;
            J->cin[2 * k] = re;
            J->cin[2 * k + 1] = im;
            if (p == 0 && q > 0) { /* the p = 0 column holds both signs of q */
                k = (size_t)(h - q) * wc;
                J->cin[2 * k] = re;
                J->cin[2 * k + 1] = -im;
            }
        }
}

void phasor_halfspec(tpool *pool, int nfreq, const int32_t *fp, const int32_t *fq,
                     const double *phi, const unsigned char *known,
                     const double *mod, double taper_frac, int w, int h,
                     double *cin)
{
    int wc = w / 2 + 1;
    double rmax = 0;
    long r2max = -1; /* hypot only where |u|^2 reaches the largest so far */
    for (int j = 0; j < nfreq; j++)
        if (known[j]) {
            long r2 = (long)fp[j] * fp[j] + (long)fq[j] * fq[j];
            if (r2 >= r2max) {
                double r = hypot(fp[j], fq[j]);
                rmax = r2 > r2max || r > rmax ? r : rmax;
                r2max = r2;
            }
        }
    half_job J = {.fp = fp, .fq = fq, .phi = phi, .mod = mod, .known = known,
                  .nfreq = nfreq, .w = w, .h = h, .cin = cin,
                  .r0 = rmax * (1.0 - taper_frac), .r1 = rmax + 1.0};
    J.r0sq = J.r0 * J.r0 * (1 - 1e-9);
    atomic_init(&J.next, 0);
    memset(cin, 0, (size_t)h * wc * 2 * sizeof *cin);
    tpool_run_or_inline(pool, half_run, &J);
}
