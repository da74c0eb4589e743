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
