/* stats.c - see stats.h.
 *
 * The median is a radix select on the floats' bit patterns, mapped so that
 * unsigned order is numeric order (negative: all bits flipped; positive:
 * the sign bit set): three read-only passes of 11, 11 and 10 bits, each a
 * histogram of the keys that share the prefix found so far, which then
 * fixes the next digit of the k-th key.  Few data-dependent branches, so
 * it costs ~3 n simple steps whatever the values: 22 us for the 9000
 * border pixels of a 200^2 frame, where a quickselect's partition
 * (mispredicting about once per element) took 54 us.
 */
#include "stats.h"

#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static uint32_t key_of(float f)
{
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return (u & 0x80000000u) ? ~u : u | 0x80000000u;
}

float stats_median_inplace(float *v, size_t n)
{
    if (n == 0)
        return 0;
    size_t k = n / 2;   /* the k-th smallest, 0-based */
    static const int shift[3] = {21, 10, 0};
    static const uint32_t digit[3] = {0x7ff, 0x7ff, 0x3ff};
    uint32_t prefix = 0, pmask = 0;
    for (int pass = 0; pass < 3; pass++) {
        size_t hist[2048];
        memset(hist, 0, sizeof hist);
        int s = shift[pass];
        uint32_t m = digit[pass];
        for (size_t i = 0; i < n; i++) {
            uint32_t key = key_of(v[i]);
            if ((key & pmask) == prefix)
                hist[(key >> s) & m]++;
        }
        uint32_t b = 0;
        while (k >= hist[b])
            k -= hist[b++];
        prefix |= b << s;
        pmask |= m << s;
    }
    /* the key is the k-th value's bits: map back */
    uint32_t u = (prefix & 0x80000000u) ? prefix & 0x7fffffffu : ~prefix;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

/* stats_median_where's passes: each band's histogram of the selected
 * keys that share the prefix, made whole by whichever thread claims it. */
enum { MW_BANDS = 16, MW_BINS = 2048 };
typedef struct mw_job {
    const float *v, *key;
    double below;
    size_t n;
    uint32_t prefix, pmask, digit;
    int shift;
    size_t (*hist)[MW_BINS]; /* MW_BANDS histograms */
    atomic_int next;
} mw_job;

static void mw_run(void *ctx, int tid, int nthr)
{
    mw_job *j = ctx;
    (void)tid, (void)nthr;
    for (int b; (b = atomic_fetch_add(&j->next, 1)) < MW_BANDS;) {
        size_t *h = j->hist[b], i1 = j->n * (b + 1) / MW_BANDS;
        memset(h, 0, MW_BINS * sizeof *h);
        for (size_t i = j->n * b / MW_BANDS; i < i1; i++) {
            uint32_t key = key_of(j->v[i]);
            int sel = !isnan(j->v[i]) && (!j->key || j->key[i] <= j->below);
            if (sel && (key & j->pmask) == j->prefix)
                h[(key >> j->shift) & j->digit]++;
        }
    }
}

float stats_median_where(tpool *pool, const float *v, const float *key, double below,
                         size_t n)
{
    static const int shift[3] = {21, 10, 0};
    static const uint32_t digit[3] = {0x7ff, 0x7ff, 0x3ff};
    mw_job j = {.v = v, .key = key, .below = below, .n = n};
    if (!(j.hist = malloc(sizeof *j.hist * MW_BANDS)))
        return NAN;
    size_t k = 0, hist[MW_BINS];
    for (int pass = 0; pass < 3; pass++) {
        j.shift = shift[pass], j.digit = digit[pass];
        atomic_init(&j.next, 0);
        if (pool && tpool_size(pool) > 1)
            tpool_run(pool, mw_run, &j);
        else
            mw_run(&j, 0, 1);
        size_t sel = 0;
        for (int b = 0; b < MW_BINS; b++) {
            hist[b] = 0;
            for (int i = 0; i < MW_BANDS; i++)
                hist[b] += j.hist[i][b];
            sel += hist[b];
        }
        if (pass == 0 && (k = sel / 2, sel == 0)) {
            free(j.hist);
            return 0;
        }
        uint32_t b = 0;
        while (k >= hist[b])
            k -= hist[b++];
        j.prefix |= b << j.shift;
        j.pmask |= j.digit << j.shift;
    }
    free(j.hist);
    uint32_t u = (j.prefix & 0x80000000u) ? j.prefix & 0x7fffffffu : ~j.prefix;
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

int stats_solve(int n, const double *A, const double *b, double *x)
{
    double M[STATS_SOLVE_MAX][STATS_SOLVE_MAX + 1];
    if (n < 1 || n > STATS_SOLVE_MAX)
        return 0;
    double scale = 0;
    for (int r = 0; r < n; r++) {
        for (int c = 0; c < n; c++) {
            M[r][c] = A[r * n + c];
            scale = fmax(scale, fabs(M[r][c]));
        }
        M[r][n] = b[r];
    }
    for (int k = 0; k < n; k++) {
        int piv = k;
        for (int r = k + 1; r < n; r++)
            if (fabs(M[r][k]) > fabs(M[piv][k]))
                piv = r;
        if (!(fabs(M[piv][k]) > 1e-14 * scale))
            return 0;
        if (piv != k)
            for (int c = k; c <= n; c++) {
                double t = M[k][c];
                M[k][c] = M[piv][c];
                M[piv][c] = t;
            }
        for (int r = k + 1; r < n; r++) {
            double m = M[r][k] / M[k][k];
            for (int c = k; c <= n; c++)
                M[r][c] -= m * M[k][c];
        }
    }
    for (int r = n - 1; r >= 0; r--) {
        double s = M[r][n];
        for (int c = r + 1; c < n; c++)
            s -= M[r][c] * x[c];
        x[r] = s / M[r][r];
        if (!isfinite(x[r]))
            return 0;
    }
    return 1;
}
