/* test_tsm_chol.c - the packed Cholesky of TSM's phase solve
 * (recon/tsm/tsm_chol.c).
 *
 * factor_and_solve_are_exact: random symmetric positive definite
 * matrices of every size 1..41 (each remainder mod 4, so the four-row
 * paths and their tails all run): L L^T gives A back and A x gives b back
 * to ~1e-12.
 * same_bits_as_one_row_at_a_time: the factor and the solution are the
 * very bits of the plain algorithm (each row's dot product on dot4's four
 * chains, one row after another), which the module computes four rows at
 * once: the phases, and the images, do not change with how it is done.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "tcheck.h"
#include "tsm/tsm_chol.h"

#define NMAX 41

/* A = M M^T + n I from a random M: packed lower triangle. */
static void random_spd(rng *r, int n, double *A)
{
    double M[NMAX * NMAX];
    for (int i = 0; i < n * n; i++)
        M[i] = rng_uniform(r) - 0.5;
    for (int i = 0; i < n; i++)
        for (int j = 0; j <= i; j++) {
            double s = i == j ? n : 0;
            for (int k = 0; k < n; k++)
                s += M[i * n + k] * M[j * n + k];
            A[tsm_chol_packed(i) + j] = s;
        }
}

/* The plain algorithm the module's bits are defined by. */
static double dot4(const double *a, const double *b, int n)
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

static void plain_factor(double *L, int n)
{
    for (int j = 0; j < n; j++) {
        double *rj = L + tsm_chol_packed(j);
        double s = sqrt(fmax(rj[j] - dot4(rj, rj, j), 1e-300)), inv = 1 / s;
        rj[j] = s;
        for (int i = j + 1; i < n; i++) {
            double *ri = L + tsm_chol_packed(i);
            ri[j] = (ri[j] - dot4(ri, rj, j)) * inv;
        }
    }
}

static void plain_solve(const double *L, int n, double *b)
{
    for (int i = 0; i < n; i++)
        b[i] = (b[i] - dot4(L + tsm_chol_packed(i), b, i)) / L[tsm_chol_packed(i) + i];
    for (int i = n - 1; i >= 0; i--) {
        const double *ri = L + tsm_chol_packed(i);
        double v = b[i] / ri[i];
        b[i] = v;
        for (int k = 0; k < i; k++)
            b[k] -= ri[k] * v;
    }
}

static double entry(const double *A, int i, int j)
{
    return i >= j ? A[tsm_chol_packed(i) + j] : A[tsm_chol_packed(j) + i];
}

TEST(factor_and_solve_are_exact)
{
    static double A[NMAX * (NMAX + 1) / 2], L[NMAX * (NMAX + 1) / 2];
    double b[NMAX], x[NMAX], worst_f = 0, worst_s = 0;
    rng r;
    rng_init(&r, 11, 0);
    for (int n = 1; n <= NMAX; n++) {
        random_spd(&r, n, A);
        memcpy(L, A, tsm_chol_packed(n) * sizeof *L);
        tsm_chol_factor(L, n);
        for (int i = 0; i < n; i++)
            for (int j = 0; j <= i; j++) {
                double s = 0;
                for (int k = 0; k <= j; k++)
                    s += L[tsm_chol_packed(i) + k] * L[tsm_chol_packed(j) + k];
                worst_f = fmax(worst_f, fabs(s - entry(A, i, j)) / n);
            }
        for (int i = 0; i < n; i++)
            b[i] = x[i] = rng_uniform(&r) - 0.5;
        tsm_chol_solve(L, n, x);
        for (int i = 0; i < n; i++) {
            double s = 0;
            for (int j = 0; j < n; j++)
                s += entry(A, i, j) * x[j];
            worst_s = fmax(worst_s, fabs(s - b[i]));
        }
    }
    printf("    worst |L L^T - A| / n %.2g, worst |A x - b| %.2g\n", worst_f, worst_s);
    CHECK(worst_f < 1e-12 && worst_s < 1e-12, "factor %g, solve %g", worst_f, worst_s);
}

TEST(same_bits_as_one_row_at_a_time)
{
    static double A[NMAX * (NMAX + 1) / 2], L[NMAX * (NMAX + 1) / 2],
        P[NMAX * (NMAX + 1) / 2];
    double x[NMAX], y[NMAX];
    int bad_f = 0, bad_s = 0;
    rng r;
    rng_init(&r, 12, 0);
    for (int n = 1; n <= NMAX; n++) {
        random_spd(&r, n, A);
        size_t m = tsm_chol_packed(n);
        memcpy(L, A, m * sizeof *L);
        memcpy(P, A, m * sizeof *P);
        tsm_chol_factor(L, n);
        plain_factor(P, n);
        bad_f += memcmp(L, P, m * sizeof *L) != 0;
        for (int i = 0; i < n; i++)
            x[i] = y[i] = rng_uniform(&r) - 0.5;
        tsm_chol_solve(L, n, x);
        plain_solve(P, n, y);
        bad_s += memcmp(x, y, n * sizeof *x) != 0;
    }
    CHECK(bad_f == 0 && bad_s == 0, "sizes whose bits differ: %d factors, %d solutions of %d",
          bad_f, bad_s, NMAX);
}

TC_MAIN(TC_CASE(factor_and_solve_are_exact), TC_CASE(same_bits_as_one_row_at_a_time))
