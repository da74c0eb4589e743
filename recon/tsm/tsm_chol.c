/* tsm_chol.c - see tsm_chol.h.
 *
 * Row i holds L(i, 0..i) at i(i+1)/2: rows are contiguous, so the inner
 * loops are dot products of row prefixes, summed on 4 chains (3x faster
 * than one: the adds no longer wait on each other), four rows at a time
 * where four rows need the same prefix (below). */
#include "tsm_chol.h"

#include <math.h>
#include <string.h>

/* Row i of L. */
static inline double *row(double *L, int i) { return L + tsm_chol_packed(i); }

static inline double dot4(const double *restrict a, const double *restrict b, int n)
{
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    int k = 0;
    for (; k + 4 <= n; k += 4)
        s0 += a[k] * b[k], s1 += a[k + 1] * b[k + 1], s2 += a[k + 2] * b[k + 2],
        s3 += a[k + 3] * b[k + 3];
    for (; k < n; k++)
        s0 += a[k] * b[k];
    return (s0 + s1) + (s2 + s3);
}

/* dot4 for four rows at once, each summed exactly as dot4 sums it: lanes
 * 0-1 of row r's lo and hi vectors are dot4's chains s0-s1 and s2-s3 over
 * k < n4 (a multiple of 4: dot4's main loop); chains_close then adds
 * dot4's tail to s0 and joins the chains as it does.  16 chains run
 * instead of 4 and b's elements are loaded once for four rows: the same
 * bits, ~2x faster (the factor and the solves were ~40 % of a TSM solve,
 * bound by the chains' latency, not the arithmetic).  Two-double vectors:
 * SSE2 on every x86-64, plain pairs elsewhere. */
typedef double v2d __attribute__((vector_size(16)));

static inline v2d load2(const double *p)
{
    v2d v;
    memcpy(&v, p, sizeof v);
    return v;
}

static inline void chains4(const double *const a[4], const double *b, int n4, v2d lo[4],
                           v2d hi[4])
{
    for (int r = 0; r < 4; r++)
        lo[r] = hi[r] = (v2d){0, 0};
    for (int k = 0; k < n4; k += 4) {
        v2d b0 = load2(b + k), b1 = load2(b + k + 2);
        lo[0] += load2(a[0] + k) * b0, hi[0] += load2(a[0] + k + 2) * b1;
        lo[1] += load2(a[1] + k) * b0, hi[1] += load2(a[1] + k + 2) * b1;
        lo[2] += load2(a[2] + k) * b0, hi[2] += load2(a[2] + k + 2) * b1;
        lo[3] += load2(a[3] + k) * b0, hi[3] += load2(a[3] + k + 2) * b1;
    }
}

static inline double chains_close(v2d lo, v2d hi, const double *a, const double *b, int k0,
                                  int n)
{
    double s0 = lo[0];
    for (int k = k0; k < n; k++)
        s0 += a[k] * b[k];
    return (s0 + lo[1]) + (hi[0] + hi[1]);
}

/* Rows below j take column j four at a time. */
void tsm_chol_factor(double *L, int n)
{
    for (int j = 0; j < n; j++) {
        double *rj = row(L, j);
        double s = sqrt(fmax(rj[j] - dot4(rj, rj, j), 1e-300)), inv = 1 / s;
        rj[j] = s;
        int i = j + 1, n4 = j - j % 4;
        for (; i + 4 <= n; i += 4) {
            double *r4[4] = {row(L, i), row(L, i + 1), row(L, i + 2), row(L, i + 3)};
            v2d lo[4], hi[4];
            chains4((const double *const *)r4, rj, n4, lo, hi);
            for (int r = 0; r < 4; r++)
                r4[r][j] = (r4[r][j] - chains_close(lo[r], hi[r], r4[r], rj, n4, j)) * inv;
        }
        for (; i < n; i++) {
            double *ri = row(L, i);
            ri[j] = (ri[j] - dot4(ri, rj, j)) * inv;
        }
    }
}

/* L L^T x = b in place.  Forward: rows i..i+3 from i = 0 mod 4 share
 * dot4's main loop over k < i, each then adds its tail (k = i.., the b
 * just solved) to s0 as dot4 would.  Backward: b -= v row i, by pairs
 * (each element's one multiply and subtract, as before). */
void tsm_chol_solve(const double *L, int n, double *b)
{
    int i = 0;
    for (; i + 4 <= n; i += 4) {
        const double *r4[4] = {L + tsm_chol_packed(i), L + tsm_chol_packed(i + 1),
                               L + tsm_chol_packed(i + 2), L + tsm_chol_packed(i + 3)};
        v2d lo[4], hi[4];
        chains4(r4, b, i, lo, hi);
        for (int t = 0; t < 4; t++)
            b[i + t] = (b[i + t] - chains_close(lo[t], hi[t], r4[t], b, i, i + t)) /
                       r4[t][i + t];
    }
    for (; i < n; i++)
        b[i] = (b[i] - dot4(L + tsm_chol_packed(i), b, i)) / L[tsm_chol_packed(i) + i];
    for (i = n - 1; i >= 0; i--) {
        const double *ri = L + tsm_chol_packed(i);
        double v = b[i] / ri[i];
        v2d vv = {v, v};
        b[i] = v;
        int k = 0;
        for (; k + 2 <= i; k += 2) {
            v2d bk = load2(b + k) - load2(ri + k) * vv;
            memcpy(b + k, &bk, sizeof bk);
        }
        for (; k < i; k++)
            b[k] -= ri[k] * v;
    }
}
