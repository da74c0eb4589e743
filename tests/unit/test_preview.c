/* test_preview.c - quick-look PNGs read back with libpng: size, black =
 * min, white = max, north up, monotonic stretches. */
#include "io/preview.h"
#include "tcheck.h"

#include <png.h>
#include <stdlib.h>
#include <unistd.h>

/* Read path as 8-bit grey; NULL on failure. */
static unsigned char *read_png(const char *path, int *w, int *h)
{
    png_image im;
    memset(&im, 0, sizeof im);
    im.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&im, path))
        return NULL;
    im.format = PNG_FORMAT_GRAY;
    unsigned char *buf = malloc(PNG_IMAGE_SIZE(im));
    if (!buf || !png_image_finish_read(&im, NULL, buf, 0, NULL)) {
        png_image_free(&im);
        free(buf);
        return NULL;
    }
    *w = (int)im.width;
    *h = (int)im.height;
    return buf;
}

static const char *tmp_png(char *buf, size_t n, const char *tag)
{
    snprintf(buf, n, "/tmp/test_preview_%ld_%s.png", (long)getpid(), tag);
    return buf;
}

/* Write img with stretch and read it back as png[h][w] (PNG row order). */
static unsigned char *round_trip(const float *img, int w, int h,
                                 preview_stretch s, int *rc)
{
    char path[128];
    int pw = 0, ph = 0;
    sl_err e = {0};
    tmp_png(path, sizeof path, "rt");
    *rc = preview_write_png(path, img, w, h, s, &e);
    unsigned char *png = *rc == SL_OK ? read_png(path, &pw, &ph) : NULL;
    unlink(path);
    if (png && (pw != w || ph != h)) {
        free(png);
        png = NULL;
    }
    return png;
}

TEST(parse_names)
{
    preview_stretch s = PREVIEW_LINEAR;
    CHECK(preview_stretch_parse("sqrt", &s) == SL_OK && s == PREVIEW_SQRT,
          "sqrt");
    CHECK(preview_stretch_parse("asinh", &s) == SL_OK && s == PREVIEW_ASINH,
          "asinh");
    CHECK(preview_stretch_parse("linear", &s) == SL_OK && s == PREVIEW_LINEAR,
          "linear");
    CHECK(preview_stretch_parse("log", &s) == SL_EINVAL, "log");
    CHECK(preview_stretch_parse(NULL, &s) == SL_EINVAL, "NULL");
}

/* 9 x 6 ramp v = x + 9 y - 20 (min at (0,0), max at (8,5)) with a NaN. */
static void ramp(float *img)
{
    for (int i = 0; i < 54; i++)
        img[i] = (float)i - 20.0f;
    img[9 * 2 + 3] = NAN;
}

TEST(extremes_orientation_and_nan)
{
    float img[54];
    ramp(img);
    for (int s = PREVIEW_LINEAR; s <= PREVIEW_ASINH; s++) {
        int rc;
        unsigned char *png = round_trip(img, 9, 6, (preview_stretch)s, &rc);
        CHECK(png, "stretch %d: write %d or read back failed", s, rc);
        /* image (x, y) is PNG row 5 - y */
        int lo = png[5 * 9 + 0], hi = png[0 * 9 + 8], nan = png[3 * 9 + 3];
        int top_left = png[0];
        free(png);
        CHECK(lo == 0 && hi == 255, "stretch %d: min %d max %d", s, lo, hi);
        CHECK(nan == 0, "stretch %d: NaN drawn %d", s, nan);
        CHECK(top_left > 128, "stretch %d: high y not on top (%d)", s,
              top_left);
    }
}

TEST(stretches_are_monotonic_and_ordered)
{
    float img[54];
    unsigned char *png[3];
    int rc = SL_OK;
    for (int i = 0; i < 54; i++)
        img[i] = (float)(i * i) * 0.01f; /* increasing with y*9 + x */
    for (int s = 0; s < 3; s++)
        png[s] = round_trip(img, 9, 6, (preview_stretch)s, &rc);
    int ok = png[0] && png[1] && png[2], mono = 1, order = 1, lin = 1;
    for (int i = 1; ok && i < 54; i++) {
        int y = i / 9, x = i % 9, py = (i - 1) / 9, px = (i - 1) % 9;
        for (int s = 0; s < 3; s++)
            mono &= png[s][(5 - y) * 9 + x] >= png[s][(5 - py) * 9 + px];
    }
    for (int i = 0; ok && i < 54; i++) {
        int r = (5 - i / 9) * 9 + i % 9;
        double frac = ((double)img[i] - img[0]) /
                      ((double)img[53] - img[0]);
        lin &= png[0][r] == (int)lround(255.0 * frac);
        /* sqrt(t) >= t and asinh(10t)/asinh(10) >= t on [0, 1] */
        order &= png[1][r] >= png[0][r] && png[2][r] >= png[0][r];
    }
    for (int s = 0; s < 3; s++)
        free(png[s]);
    CHECK(ok, "write/read failed: %d", rc);
    CHECK(mono, "a stretch is not monotonic");
    CHECK(lin, "linear grey != round(255 t)");
    CHECK(order, "sqrt/asinh darker than linear somewhere");
}

TEST(constant_and_empty_images)
{
    float flat[12], nan[12];
    int rc, grey_ok = 1, black_ok = 1;
    for (int i = 0; i < 12; i++) {
        flat[i] = 42.0f;
        nan[i] = NAN;
    }
    unsigned char *a = round_trip(flat, 4, 3, PREVIEW_ASINH, &rc);
    unsigned char *b = round_trip(nan, 4, 3, PREVIEW_LINEAR, &rc);
    for (int i = 0; a && b && i < 12; i++) {
        grey_ok &= a[i] == 128;
        black_ok &= b[i] == 0;
    }
    int both = a && b;
    free(a);
    free(b);
    CHECK(both, "write/read failed");
    CHECK(grey_ok && black_ok, "constant -> 128, all-NaN -> 0");
}

TEST(unwritable_path)
{
    float img[4] = {0, 1, 2, 3};
    sl_err e = {0};
    const char *path = "/nonexistent-dir-specklab/p.png";
    int rc = preview_write_png(path, img, 2, 2, PREVIEW_LINEAR, &e);
    CHECK(rc == SL_EIO && strstr(e.msg, path), "%d %s", rc, e.msg);
    rc = preview_write_png("/tmp/x.png", img, 0, 2, PREVIEW_LINEAR, &e);
    CHECK(rc == SL_EINVAL, "zero width: %d", rc);
}

TC_MAIN(TC_CASE(parse_names), TC_CASE(extremes_orientation_and_nan),
        TC_CASE(stretches_are_monotonic_and_ordered),
        TC_CASE(constant_and_empty_images), TC_CASE(unwritable_path))
