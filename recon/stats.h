/* stats.h - small robust statistics shared by the frame-cleaning and
 * seeing code. */
#ifndef SL_STATS_H
#define SL_STATS_H

#include <stddef.h>

/* Median of v[0..n) by radix selection (stats.c): O(n); v is left as it
 * was (the name is historical: callers may still treat v as scratch).
 * For even n the upper of the two middle values (a robust level, not an
 * average); -0 sorts below +0.  0 when n == 0. */
float stats_median_inplace(float *v, size_t n);

#endif
