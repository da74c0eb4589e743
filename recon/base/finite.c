/* finite.c - see finite.h. */
#include "finite.h"

#include <math.h>

/* The first non-finite index of v[0..n), given that some value is. */
static size_t first_bad(const float *v, size_t n)
{
    size_t i = 0;
    while (i < n && isfinite(v[i]))
        i++;
    return i;
}

size_t finite_copy(float *restrict dst, const float *restrict src, size_t n)
{
    float z[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        for (int k = 0; k < 8; k++) {
            dst[i + k] = src[i + k];
            z[k] += src[i + k] * 0.0f;
        }
    for (; i < n; i++) {
        dst[i] = src[i];
        z[0] += src[i] * 0.0f;
    }
    float s = 0;
    for (int k = 0; k < 8; k++)
        s += z[k];
    return s == 0.0f ? n : first_bad(src, n);
}

size_t finite_scan(const float *v, size_t n)
{
    float z[8] = {0, 0, 0, 0, 0, 0, 0, 0};
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        for (int k = 0; k < 8; k++)
            z[k] += v[i + k] * 0.0f;
    for (; i < n; i++)
        z[0] += v[i] * 0.0f;
    float s = 0;
    for (int k = 0; k < 8; k++)
        s += z[k];
    return s == 0.0f ? n : first_bad(v, n);
}
