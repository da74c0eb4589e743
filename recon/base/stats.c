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
#include <stdint.h>
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
