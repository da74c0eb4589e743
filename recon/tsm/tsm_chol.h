/* tsm_chol.h - a dense Cholesky factor on a packed lower triangle, for
 * the phase solve of TSM (tsm_phase.c: H = sum w a a^T per angle).
 *
 * Row i of L holds L(i, 0..i) from tsm_chol_packed(i): rows are
 * contiguous.  tsm_chol_factor overwrites a symmetric positive
 * (semi)definite n x n matrix, given by its lower triangle, with its
 * factor (a pivot below 1e-300 is taken as 1e-300: the caller adds a
 * ridge); tsm_chol_solve solves L L^T x = b in place.  Cost: n^3/6 and
 * n^2 multiply-adds.  Every product and sum is fixed by n alone (sums on
 * four chains joined in one order), so the bits depend neither on the
 * CPU's vector width nor on threads.
 */
#ifndef SL_TSM_CHOL_H
#define SL_TSM_CHOL_H

#include <stddef.h>

static inline size_t tsm_chol_packed(int n) { return (size_t)n * (n + 1) / 2; }

void tsm_chol_factor(double *L, int n);
void tsm_chol_solve(const double *L, int n, double *b);

#endif
