/* finite.h - where a frame stops being finite.
 *
 * finite_scan(v, n): n when every value is finite, else the index of the
 * first NaN or Inf.  The common case, all finite, is one branch-free
 * pass (x * 0 is 0 unless x is NaN or Inf, summed on 8 lanes the
 * compiler vectorises: ~0.1 ns a value against ~1 for a test per value);
 * only a bad frame is scanned again for the index.
 */
#ifndef SL_FINITE_H
#define SL_FINITE_H

#include <stddef.h>

size_t finite_scan(const float *v, size_t n);

#endif
