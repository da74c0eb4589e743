/* stats.c - see stats.h. */
#include "stats.h"

float stats_median_inplace(float *v, size_t n)
{
    if (n == 0)
        return 0;
    size_t lo = 0, hi = n - 1, k = n / 2;
    while (lo < hi) { /* Hoare partition around the middle element */
        float pivot = v[lo + (hi - lo) / 2];
        size_t i = lo, j = hi;
        for (;;) {
            while (v[i] < pivot)
                i++;
            while (v[j] > pivot)
                j--;
            if (i >= j)
                break;
            float t = v[i];
            v[i] = v[j];
            v[j] = t;
            i++;
            j--;
        }
        /* now v[lo..j] <= pivot <= v[j+1..hi] */
        if (k <= j)
            hi = j;
        else
            lo = j + 1;
    }
    return v[k];
}
