/* stats.h - small robust statistics and linear algebra shared by the
 * frame-cleaning, seeing and fitting code. */
#ifndef SL_STATS_H
#define SL_STATS_H

#include <stddef.h>

/* Median of v[0..n) by radix selection (stats.c): O(n); v is left as it
 * was (the name is historical: callers may still treat v as scratch).
 * For even n the upper of the two middle values (a robust level, not an
 * average); -0 sorts below +0.  0 when n == 0. */
float stats_median_inplace(float *v, size_t n);

/* Solve the n x n system A x = b (A row-major, n <= STATS_SOLVE_MAX) by
 * Gaussian elimination with partial pivoting; 0 when singular (a pivot
 * below 1e-14 of A's largest entry) or not finite, else 1. */
#define STATS_SOLVE_MAX 8
int stats_solve(int n, const double *A, const double *b, double *x);

#endif
