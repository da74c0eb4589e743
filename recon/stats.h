/* stats.h - small robust statistics shared by the frame-cleaning and
 * seeing code. */
#ifndef SL_STATS_H
#define SL_STATS_H

#include <stddef.h>

/* Median of v[0..n) by quickselect: O(n) expected, reorders v.  For even
 * n the upper of the two middle values (a robust level, not an average).
 * 0 when n == 0. */
float stats_median_inplace(float *v, size_t n);

#endif
