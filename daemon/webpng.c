/* webpng.c - stretches, display ranges and in-memory PNGs; see webpng.h. */
#include "webpng.h"

#include <math.h>
#include <png.h>
#include <setjmp.h>
#include <stdlib.h>
#include <string.h>

static const char *const names[WEB_NSTRETCH] = {"linear", "sqrt", "log", "asinh"};

int web_stretch_parse(const char *name)
{
    for (int i = 0; name && i < WEB_NSTRETCH; i++)
        if (!strcmp(name, names[i]))
            return i;
    return -1;
}

const char *web_stretch_name(int s)
{
    return s >= 0 && s < WEB_NSTRETCH ? names[s] : "?";
}

static double curve(int s, double t)
{
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    switch (s) {
    case WEB_STRETCH_SQRT: return sqrt(t);
    case WEB_STRETCH_LOG: return log10(1 + 1000 * t) / log10(1001.0);
    case WEB_STRETCH_ASINH: return asinh(10 * t) / asinh(10.0);
    default: return t;
    }
}

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

int webpng_range(const float *img, size_t n, double lo_pct, double *lo, double *hi,
                 double *mean, double *min)
{
    size_t step = n > 65536 ? n / 65536 : 1, ns = 0, nf = 0;
    float *s = g_new(float, n / step + 1);
    double sum = 0, mx = -INFINITY, mn = INFINITY;
    for (size_t i = 0; i < n; i++) {
        float v = img[i];
        if (!isfinite(v))
            continue;
        sum += v, nf++;
        mx = v > mx ? v : mx;
        mn = v < mn ? v : mn;
        if (i % step == 0)
            s[ns++] = v;
    }
    if (nf == 0 || ns == 0) {
        g_free(s);
        *lo = *hi = *mean = *min = NAN;
        return 0;
    }
    qsort(s, ns, sizeof *s, cmp_float);
    size_t k = (size_t)(lo_pct / 100.0 * (double)(ns - 1) + 0.5);
    *lo = s[k < ns ? k : ns - 1];
    *hi = mx;
    *mean = sum / (double)nf;
    *min = mn;
    g_free(s);
    return 1;
}

static void write_cb(png_structp png, png_bytep data, png_size_t len)
{
    g_byte_array_append(png_get_io_ptr(png), data, (guint)len);
}

static void flush_cb(png_structp png)
{
    (void)png;
}

/* One grey row of image row y. */
static void gray_row(const float *row, int w, int stretch, double lo, double hi,
                     unsigned char *out)
{
    double span = hi - lo;
    for (int x = 0; x < w; x++) {
        double v = row[x];
        if (!isfinite(v))
            out[x] = 0;
        else if (!(span > 0))
            out[x] = 128;
        else
            out[x] = (unsigned char)lrint(255 * curve(stretch, (v - lo) / span));
    }
}

GBytes *webpng_gray(const float *img, int w, int h, int stretch, double lo, double hi)
{
    if (w < 1 || h < 1)
        return NULL;
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    GByteArray *buf = g_byte_array_sized_new((guint)((size_t)w * h / 2 + 1024));
    unsigned char *row = g_new(unsigned char, (size_t)w);
    volatile int ok = 0;
    if (info && !setjmp(png_jmpbuf(png))) {
        png_set_write_fn(png, buf, write_cb, flush_cb);
        png_set_compression_level(png, 1);   /* speed: the view renders live */
        png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 8, PNG_COLOR_TYPE_GRAY,
                     PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
        png_write_info(png, info);
        for (int y = h - 1; y >= 0; y--) {   /* north up */
            gray_row(img + (size_t)y * w, w, stretch, lo, hi, row);
            png_write_row(png, row);
        }
        png_write_end(png, info);
        ok = 1;
    }
    png_destroy_write_struct(png ? &png : NULL, info ? &info : NULL);
    g_free(row);
    if (!ok) {
        g_byte_array_free(buf, TRUE);
        return NULL;
    }
    return g_byte_array_free_to_bytes(buf);
}
