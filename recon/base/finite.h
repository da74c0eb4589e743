/* finite.h - where a frame stops being finite.
 *
 * finite_scan(v, n): n when every value is finite, else the index of the
 * first NaN or Inf.  The common case, all finite, is one branch-free
 * pass (x * 0 is 0 unless x is NaN or Inf, summed on 8 lanes the
 * compiler vectorises: ~0.1 ns a value against ~1 for a test per value);
 * only a bad frame is scanned again for the index.
 *
 * finite_copy(dst, src, n): the same answer, with src copied into dst in
 * the same pass (a frame read once instead of twice: the copy into an
 * estimator's slot was most of what its caller did serially per frame).
 * dst holds the whole of src either way.
 */
#ifndef SL_FINITE_H
#define SL_FINITE_H

#include <stddef.h>

size_t finite_scan(const float *v, size_t n);
size_t finite_copy(float *restrict dst, const float *restrict src, size_t n);

#endif
