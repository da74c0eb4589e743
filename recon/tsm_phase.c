/* tsm_phase.c - 1-D phase recovery from a bispectrum (see tsm.h).
 *
 * Why Gauss-Seidel sweeps after the recursion: in 1-D a target frequency u
 * is reached by only ~u/2 pairs (u1, u - u1), and the recursion uses only
 * those, so an error at a small u propagates up the chain.  Every
 * bispectrum element closes a triangle on three frequencies; a sweep
 * re-estimates phi(u) from all elements containing u (about 3x as many,
 * including those where u is the smaller frequency), which is a
 * block-coordinate descent of sum w |exp(i beta) - exp(i(phi1+phi2-phi3))|^2.
 * Cost per sweep: 3 complex multiply-adds per element per angle.
 */
#include "tsm.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { ROLE_SUM = 0, ROLE_U1 = 1, ROLE_U2 = 2, ROLE_DIAG = 3 };

struct tsm_phase {
    int nang, nf, np;
    int *off, *len;          /* per u1 */
    int *pu1, *pu2;          /* per pair */
    int *inc0;               /* nf + 1: incidence list start per u */
    int *incp;               /* pair of each incidence */
    unsigned char *incr;     /* role of u in that pair */
    float *ph, *wt;          /* caller's inputs */
    double *er, *ei;         /* current unit phasors, nang*nf */
};

void tsm_phase_free(tsm_phase *p)
{
    if (!p)
        return;
    free(p->off), free(p->len), free(p->pu1), free(p->pu2);
    free(p->inc0), free(p->incp), free(p->incr);
    free(p->ph), free(p->wt), free(p->er), free(p->ei);
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
    p->nang = nangles, p->nf = nfreq;
    p->off = calloc(nfreq, sizeof *p->off);
    p->len = calloc(nfreq, sizeof *p->len);
    p->inc0 = calloc(nfreq + 1, sizeof *p->inc0);
    if (!p->off || !p->len || !p->inc0)
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
    p->incp = malloc((3 * np + 1) * sizeof *p->incp);
    p->incr = malloc(3 * np + 1);
    p->ph = calloc(na * np * 2 + 1, sizeof *p->ph);
    p->wt = calloc(na * np + 1, sizeof *p->wt);
    p->er = malloc(na * nfreq * sizeof *p->er);
    p->ei = malloc(na * nfreq * sizeof *p->ei);
    if (!p->pu1 || !p->pu2 || !p->incp || !p->incr || !p->ph || !p->wt ||
        !p->er || !p->ei)
        goto fail_free;
    /* Incidence lists (CSR by frequency): count, prefix-sum, fill. */
    for (int u1 = 1; u1 < J; u1++)
        for (int u2 = 1; u2 <= p->len[u1]; u2++) {
            int q = p->off[u1] + u2 - 1;
            p->pu1[q] = u1, p->pu2[q] = u2;
            p->inc0[u1 + u2 + 1]++;
            p->inc0[u1 + 1]++;
            if (u2 != u1)
                p->inc0[u2 + 1]++;
        }
    for (int u = 0; u < nfreq; u++)
        p->inc0[u + 1] += p->inc0[u];
    int *fill = calloc(nfreq, sizeof *fill);
    if (!fill)
        goto fail_free;
    for (int q = 0; q < p->np; q++) {
        int u1 = p->pu1[q], u2 = p->pu2[q];
        int ids[3] = {u1 + u2, u1, u2};
        int roles[3] = {ROLE_SUM, u1 == u2 ? ROLE_DIAG : ROLE_U1, ROLE_U2};
        for (int k = 0; k < (u1 == u2 ? 2 : 3); k++) {
            int at = p->inc0[ids[k]] + fill[ids[k]]++;
            p->incp[at] = q;
            p->incr[at] = (unsigned char)roles[k];
        }
    }
    free(fill);
    return p;
fail_free:
    sl_seterr(err, SL_ENOMEM, "tsm_phase_new: out of memory");
    tsm_phase_free(p);
    return NULL;
}

/* The weighted phasor sum for phi(u) at angle a from its incidences; in
 * the recursion (all = 0) only the pairs summing to u. */
static void gather(const tsm_phase *p, int a, int u, int all, double *zr,
                   double *zi, double *wsum)
{
    const double *er = p->er + (size_t)a * p->nf, *ei = p->ei + (size_t)a * p->nf;
    const float *ph = p->ph + (size_t)a * p->np * 2, *wt = p->wt + (size_t)a * p->np;
    double sr = 0, si = 0, sw = 0;
    for (int e = p->inc0[u]; e < p->inc0[u + 1]; e++) {
        int role = p->incr[e];
        if (!all && role != ROLE_SUM)
            continue;
        int q = p->incp[e], u1 = p->pu1[q], u2 = p->pu2[q], u3 = u1 + u2;
        double w = wt[q];
        if (w <= 0)
            continue;
        double br = ph[2 * q], bi = ph[2 * q + 1], cr, ci, tr, ti;
        switch (role) {
        case ROLE_SUM:   /* E1 E2 conj(b) */
            tr = er[u1] * er[u2] - ei[u1] * ei[u2];
            ti = er[u1] * ei[u2] + ei[u1] * er[u2];
            cr = tr * br + ti * bi, ci = ti * br - tr * bi;
            break;
        case ROLE_U1:    /* b conj(E2) E3 */
        case ROLE_U2: {  /* b conj(E1) E3 */
            int o = role == ROLE_U1 ? u2 : u1;
            tr = br * er[o] + bi * ei[o], ti = bi * er[o] - br * ei[o];
            cr = tr * er[u3] - ti * ei[u3], ci = tr * ei[u3] + ti * er[u3];
            break;
        }
        default: {       /* u1 = u2 = u: exp(2i phi) = b E(2u); the root
                          * nearer the current phase */
            tr = br * er[u3] - bi * ei[u3], ti = br * ei[u3] + bi * er[u3];
            double m = sqrt(tr * tr + ti * ti);
            cr = sqrt(fmax(0.5 * (m + tr), 0)), ci = sqrt(fmax(0.5 * (m - tr), 0));
            ci = ti < 0 ? -ci : ci;
            if (m > 0) {
                cr /= sqrt(m), ci /= sqrt(m);
            }
            if (cr * er[u] + ci * ei[u] < 0)
                cr = -cr, ci = -ci;
            break;
        }
        }
        sr += w * cr, si += w * ci, sw += w;
    }
    *zr = sr, *zi = si, *wsum = sw;
}

static void set_unit(double *er, double *ei, double zr, double zi)
{
    double m = sqrt(zr * zr + zi * zi);
    if (m > 0)
        *er = zr / m, *ei = zi / m;
}

int tsm_phase_solve(tsm_phase *p, int sweeps, double angle_reg, double *phase)
{
    int nf = p->nf, na = p->nang;
    for (size_t i = 0; i < (size_t)na * nf; i++)
        p->er[i] = 1.0, p->ei[i] = 0.0;
    for (int a = 0; a < na; a++)
        for (int u = 2; u < nf; u++) {
            double zr, zi, sw;
            gather(p, a, u, 0, &zr, &zi, &sw);
            set_unit(p->er + (size_t)a * nf + u, p->ei + (size_t)a * nf + u, zr, zi);
        }
    for (int it = 0; it < sweeps; it++)
        for (int a = 0; a < na; a++)
            for (int u = 2; u < nf; u++) {
                double zr, zi, sw;
                gather(p, a, u, 1, &zr, &zi, &sw);
                if (sw > 0)
                    zr /= sw, zi /= sw;
                if (angle_reg > 0 && na > 1) {
                    /* Neighbours; across theta = 180 the line reverses. */
                    int am = a ? a - 1 : na - 1, ap = a + 1 < na ? a + 1 : 0;
                    double sm = a ? 1.0 : -1.0, sp = a + 1 < na ? 1.0 : -1.0;
                    zr += 0.5 * angle_reg * (p->er[(size_t)am * nf + u] + p->er[(size_t)ap * nf + u]);
                    zi += 0.5 * angle_reg * (sm * p->ei[(size_t)am * nf + u] +
                                             sp * p->ei[(size_t)ap * nf + u]);
                }
                set_unit(p->er + (size_t)a * nf + u, p->ei + (size_t)a * nf + u, zr, zi);
            }
    for (size_t i = 0; i < (size_t)na * nf; i++)
        phase[i] = atan2(p->ei[i], p->er[i]);
    return SL_OK;
}
