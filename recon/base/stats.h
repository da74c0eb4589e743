/* stats.h - small robust statistics and linear algebra shared by the
 * frame-cleaning, seeing and fitting code. */
#ifndef SL_STATS_H
#define SL_STATS_H

#include <stddef.h>

#include "tpool.h"

/* Median of v[0..n) by radix selection (stats.c): O(n); v is left as it
 * was (the name is historical: callers may still treat v as scratch).
 * For even n the upper of the two middle values (a robust level, not an
 * average); -0 sorts below +0.  0 when n == 0. */
float stats_median_inplace(float *v, size_t n);

/* The same median of the v[i] that are not NaN and whose key[i] <= below
 * (every one when key is NULL), without copying them: the same radix
 * passes, each a histogram per fixed band of indices made on the pool's
 * threads (NULL: the caller) and summed, so the value does not depend on
 * the thread count.  0 when none is selected; NaN when out of memory
 * (256 kB of histograms). */
float stats_median_where(tpool *pool, const float *v, const float *key, double below,
                         size_t n);

/* Solve the n x n system A x = b (A row-major, n <= STATS_SOLVE_MAX) by
 * Gaussian elimination with partial pivoting; 0 when singular (a pivot
 * below 1e-14 of A's largest entry) or not finite, else 1. */
#define STATS_SOLVE_MAX 8
int stats_solve(int n, const double *A, const double *b, double *x);

#endif
