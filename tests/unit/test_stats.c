/* test_stats.c - the selection median against sorting. */
#include <stdlib.h>

#include "base/rng.h"
#include "base/stats.h"
#include "tcheck.h"

static int cmpf(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

TEST(median_equals_sorted_middle)
{
    rng r;
    rng_init(&r, 3, 0);
    float v[257], w[257];
    for (int trial = 0; trial < 300; trial++) {
        size_t n = 1 + rng_u64(&r) % 257;
        int dup = trial % 3 == 0; /* many ties */
        for (size_t i = 0; i < n; i++)
            v[i] = w[i] = dup ? (float)(rng_u64(&r) % 4) : (float)rng_normal(&r);
        qsort(w, n, sizeof *w, cmpf);
        float m = stats_median_inplace(v, n);
        CHECK(m == w[n / 2], "n %zu: got %g, sorted middle %g", n, m, w[n / 2]);
        /* v keeps every value (seeing.c reuses it) */
        qsort(v, n, sizeof *v, cmpf);
        for (size_t i = 0; i < n; i++)
            CHECK(v[i] == w[i], "n %zu: element %zu lost (%g, want %g)", n, i, v[i], w[i]);
    }
    CHECK(stats_median_inplace(v, 0) == 0, "empty");
}

TC_MAIN(TC_CASE(median_equals_sorted_middle))
