/* test_stats.c - the selection median against sorting. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "base/finite.h"
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

/* stats_median_where: the sorted middle of the selected, non-NaN values
 * (key <= below, or all), on pools of 1-3 threads and without one, for
 * sizes below, at and above the 16 bands (some bands empty), with ties,
 * negative zeros and NaNs; 0 when nothing is selected. */
TEST(median_where_equals_sorted_middle_of_the_selection)
{
    rng r;
    rng_init(&r, 5, 0);
    tpool *pools[4] = {NULL, tpool_new(1, NULL), tpool_new(2, NULL), tpool_new(3, NULL)};
    size_t nmax = 5000;
    float *v = malloc(nmax * sizeof *v), *key = malloc(nmax * sizeof *key);
    float *w = malloc(nmax * sizeof *w);
    for (int trial = 0; trial < 200 && v && key && w; trial++) {
        size_t n = trial < 20 ? (size_t)trial : 1 + rng_u64(&r) % nmax, k = 0;
        double below = trial % 4 == 3 ? INFINITY : rng_normal(&r);
        for (size_t i = 0; i < n; i++) {
            uint64_t u = rng_u64(&r);
            v[i] = trial % 3 == 0 ? (float)(u % 4) - 2.0f : (float)rng_normal(&r);
            v[i] = u % 97 == 0 ? NAN : u % 89 == 0 ? -0.0f : v[i];
            key[i] = (float)rng_normal(&r);
            if (!isnan(v[i]) && key[i] <= below)
                w[k++] = v[i];
        }
        qsort(w, k, sizeof *w, cmpf);
        for (int p = 0; p < 4; p++) {
            float m = stats_median_where(pools[p], v, key, below, n);
            int same = k ? memcmp(&m, &w[k / 2], sizeof m) == 0 || m == w[k / 2] : m == 0;
            CHECK(same, "n %zu, %zu selected, pool %d: got %g, sorted middle %g", n, k, p, m,
                  k ? w[k / 2] : 0.0);
        }
    }
    for (int p = 0; p < 4; p++)
        tpool_free(pools[p]);
    free(v), free(key), free(w);
}

/* finite_scan: n when all finite; else the first NaN or Inf, wherever it
 * lies against the 8-lane blocks (first, inside, last block, the tail),
 * and huge finite values are finite. */
TEST(finite_scan_finds_the_first_bad_value)
{
    enum { N = 37 };
    float v[N];
    for (int i = 0; i < N; i++)
        v[i] = i % 2 ? 3.4e38f : -1.0f * i;
    CHECK(finite_scan(v, N) == N, "all finite read as %zu", finite_scan(v, N));
    CHECK(finite_scan(v, 0) == 0, "empty");
    static const int at[] = {0, 5, 8, 31, 32, 36};
    for (int k = 0; k < 6; k++) {
        float bad[2] = {NAN, INFINITY};
        for (int b = 0; b < 2; b++) {
            float w[N];
            memcpy(w, v, sizeof w);
            w[at[k]] = b ? -bad[b] : bad[b];
            if (at[k] + 3 < N)
                w[at[k] + 3] = NAN; /* a later one does not matter */
            size_t got = finite_scan(w, N);
            CHECK(got == (size_t)at[k], "%s at %d read as %zu", b ? "-Inf" : "NaN", at[k], got);
            float c[N];
            got = finite_copy(c, w, N);
            CHECK(got == (size_t)at[k], "copy: %s at %d read as %zu", b ? "-Inf" : "NaN",
                  at[k], got);
            CHECK(!memcmp(c, w, sizeof c), "copy: %s at %d: not the whole frame",
                  b ? "-Inf" : "NaN", at[k]);
        }
    }
    float c[N];
    CHECK(finite_copy(c, v, N) == N && !memcmp(c, v, sizeof c), "copy of a finite frame");
    CHECK(finite_copy(c, v, 0) == 0, "empty copy");
}

TC_MAIN(TC_CASE(median_equals_sorted_middle),
        TC_CASE(median_where_equals_sorted_middle_of_the_selection),
        TC_CASE(finite_scan_finds_the_first_bad_value))
