/* finite.c - see finite.h. */
#include "finite.h"

#include <math.h>

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
    if (s == 0.0f)
        return n;
    for (i = 0; i < n && isfinite(v[i]); i++)
        ;
    return i;
}
