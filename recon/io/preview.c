/* preview.c - quick-look PNG; see preview.h. */
#include "preview.h"

#include <errno.h>
#include <math.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int preview_stretch_parse(const char *name, preview_stretch *out)
{
    static const char *const names[] = {"linear", "sqrt", "asinh"};
    for (int i = 0; name && i < 3; i++) {
        if (strcmp(name, names[i]) == 0) {
            *out = (preview_stretch)i;
            return SL_OK;
        }
    }
    return SL_EINVAL;
}

double preview_stretch_curve(preview_stretch stretch, double t)
{
    t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
    return stretch == PREVIEW_SQRT ? sqrt(t)
         : stretch == PREVIEW_ASINH ? asinh(10.0 * t) / asinh(10.0)
         : t; /* asinh softening = range / 10 */
}

/* Grey level of v for finite range [lo, lo + range]. */
static unsigned char grey(float v, double lo, double range,
                          preview_stretch stretch)
{
    if (!isfinite(v))
        return 0;
    if (!(range > 0.0))
        return 128; /* constant image: see preview.h */
    return (unsigned char)lround(255.0 * preview_stretch_curve(
                                     stretch, ((double)v - lo) / range));
}

/* 8-bit rows in PNG order: row r is image y = height - 1 - r (north up). */
static void render(const float *img, int w, int h, preview_stretch stretch,
                   unsigned char *pix)
{
    size_t n = (size_t)w * (size_t)h;
    double lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < n; i++) {
        if (isfinite(img[i])) {
            lo = img[i] < lo ? img[i] : lo;
            hi = img[i] > hi ? img[i] : hi;
        }
    }
    double range = hi > lo ? hi - lo : 0.0; /* 0 also when all non-finite */
    for (int y = 0; y < h; y++) {
        const float *src = img + (size_t)y * (size_t)w;
        unsigned char *dst = pix + (size_t)(h - 1 - y) * (size_t)w;
        for (int x = 0; x < w; x++)
            dst[x] = grey(src[x], lo, range, stretch);
    }
}

typedef struct png_ctx {
    const char *path;
    sl_err *err;
} png_ctx;

static void on_png_error(png_structp png, png_const_charp msg)
{
    png_ctx *c = png_get_error_ptr(png);
    sl_seterr(c->err, SL_EIO, "%s: PNG encoding failed: %s", c->path, msg);
    png_longjmp(png, 1);
}

static void on_png_warning(png_structp png, png_const_charp msg)
{
    (void)png; /* warnings (e.g. about chunks) do not affect the pixels */
    (void)msg;
}

/* libpng reports errors by longjmp; nothing that changes after setjmp is
 * read after it, so no local needs volatile. */
static int encode(FILE *fp, const unsigned char *pix, int w, int h,
                  png_ctx *ctx)
{
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, ctx,
                                              on_png_error, on_png_warning);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!info) {
        png_destroy_write_struct(&png, NULL);
        return sl_seterr(ctx->err, SL_ENOMEM, "%s: out of memory for PNG",
                         ctx->path);
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        return SL_EIO;
    }
    png_init_io(png, fp);
    png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 8,
                 PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int r = 0; r < h; r++)
        png_write_row(png, pix + (size_t)r * (size_t)w);
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    return SL_OK;
}

int preview_write_png(const char *path, const float *img, int width,
                      int height, preview_stretch stretch, sl_err *err)
{
    png_ctx ctx = {path, err};
    int rc = SL_OK;
    if (!path || !img || width < 1 || height < 1 || width > (1 << 20) ||
        height > (1 << 20) || (unsigned)stretch > PREVIEW_ASINH)
        return sl_seterr(err, SL_EINVAL, "preview_write_png(%s, %d x %d): "
                         "bad argument", path ? path : "NULL", width, height);
    unsigned char *pix = malloc((size_t)width * (size_t)height);
    if (!pix)
        return sl_seterr(err, SL_ENOMEM, "%s: out of memory for %d x %d",
                         path, width, height);
    render(img, width, height, stretch, pix);
    FILE *fp = fopen(path, "wb");
    if (!fp) {
        rc = sl_seterr(err, SL_EIO, "cannot create %s: %s", path,
                       strerror(errno));
        goto free_pix;
    }
    rc = encode(fp, pix, width, height, &ctx);
    if (fclose(fp) != 0 && rc == SL_OK)
        rc = sl_seterr(err, SL_EIO, "%s: write failed: %s", path,
                       strerror(errno));
    if (rc != SL_OK)
        unlink(path); /* never leave a half-written preview behind */
free_pix:
    free(pix);
    return rc;
}
