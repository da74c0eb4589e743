/* nbr8.c - see nbr8.h. */
#include "nbr8.h"

#include <stddef.h>

/* Median of n <= 8 values (upper middle for even n), by insertion sort:
 * stats_median_inplace's histograms cost far more at this size. */
static float median_small(float *v, int n)
{
    for (int i = 1; i < n; i++) {
        float x = v[i];
        int j = i - 1;
        for (; j >= 0 && v[j] > x; j--)
            v[j + 1] = v[j];
        v[j + 1] = x;
    }
    return n ? v[n / 2] : 0.0f;
}

/* Median of the up-to-8 neighbours of pixel (x, y) into out. */
static void median8_slow(const float *a, int w, int h, int x, int y,
                         float *out)
{
    float v[8];
    int k = 0;
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
            int xx = x + dx, yy = y + dy;
            if ((dx || dy) && xx >= 0 && yy >= 0 && xx < w && yy < h)
                v[k++] = a[(size_t)yy * w + xx];
        }
    out[(size_t)y * w + x] = median_small(v, k);
}

/* minss/maxss: fminf/fmaxf are libm calls here (their NaN rules), and
 * the values are finite */
#define CSWAP(i, j) do { float lo_ = v[i] < v[j] ? v[i] : v[j]; \
                         v[j] = v[i] < v[j] ? v[j] : v[i]; v[i] = lo_; } while (0)

/* The 5th smallest of 8 (the upper median) by a 19-comparator sorting
 * network: branch-free, ~4x faster than insertion sort here. */
static float upper_median8(float v[8])
{
    CSWAP(0, 2); CSWAP(1, 3); CSWAP(4, 6); CSWAP(5, 7);
    CSWAP(0, 4); CSWAP(1, 5); CSWAP(2, 6); CSWAP(3, 7);
    CSWAP(0, 1); CSWAP(2, 3); CSWAP(4, 5); CSWAP(6, 7);
    CSWAP(2, 4); CSWAP(3, 5);
    CSWAP(1, 4); CSWAP(3, 6);
    CSWAP(1, 2); CSWAP(3, 4); CSWAP(5, 6);
    return v[4];
}

void nbr8_median(const float *a, int w, int h, int y0, int y1, float *out)
{
    for (int y = y0; y < y1; y++) {
        int inner = y > 0 && y + 1 < h;
        for (int x = 0; x < w; x++) {
            if (!inner || x == 0 || x + 1 == w) {
                median8_slow(a, w, h, x, y, out);
                continue;
            }
            const float *u = a + (size_t)(y - 1) * w + x, *m = u + w, *d = m + w;
            float v[8] = {u[-1], u[0], u[1], m[-1], m[1], d[-1], d[0], d[1]};
            out[(size_t)y * w + x] = upper_median8(v);
        }
    }
}

void nbr8_mean(const float *a, int w, int h, int y0, int y1, float *out)
{
    for (int y = y0; y < y1; y++)
        for (int x = 0; x < w; x++) {
            double s = 0;
            int k = 0;
            for (int dy = -1; dy <= 1; dy++) {
                int yy = y + dy;
                if (yy < 0 || yy >= h)
                    continue;
                for (int dx = -1; dx <= 1; dx++) {
                    int xx = x + dx;
                    if ((dx || dy) && xx >= 0 && xx < w)
                        s += a[(size_t)yy * w + xx], k++;
                }
            }
            out[(size_t)y * w + x] = (float)(s / k);
        }
}
