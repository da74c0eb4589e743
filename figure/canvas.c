/* canvas.c - the figures' cairo surface; see canvas.h. */
#include "canvas.h"

#include <fontconfig/fontconfig.h>
#include <stdint.h>
#include <stdlib.h>
#include <unistd.h>

#define CANVAS_MAX 16384
#define FONT "sans-serif"

struct canvas {
    cairo_surface_t *surface;
    cairo_t *cr;
};

static int cairo_fail(cairo_status_t st, sl_err *err, const char *what)
{
    return sl_seterr(err, st == CAIRO_STATUS_NO_MEMORY ? SL_ENOMEM : SL_EIO,
                     "%s: %s", what, cairo_status_to_string(st));
}

canvas *canvas_new(int w, int h, sl_err *err)
{
    if (w < 1 || h < 1 || w > CANVAS_MAX || h > CANVAS_MAX) {
        sl_seterr(err, SL_EINVAL, "canvas of %d x %d px: want 1..%d", w, h, CANVAS_MAX);
        return NULL;
    }
    canvas *c = calloc(1, sizeof *c);
    if (!c) {
        sl_seterr(err, SL_ENOMEM, "canvas: out of memory");
        return NULL;
    }
    c->surface = cairo_image_surface_create(CAIRO_FORMAT_RGB24, w, h);
    c->cr = cairo_create(c->surface);
    cairo_status_t st = cairo_status(c->cr);
    if (st != CAIRO_STATUS_SUCCESS) {
        cairo_fail(st, err, "canvas");
        canvas_free(c);
        return NULL;
    }
    cairo_set_source_rgb(c->cr, 1, 1, 1);
    cairo_paint(c->cr);
    cairo_select_font_face(c->cr, FONT, CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
    return c;
}

void canvas_free(canvas *c)
{
    if (!c)
        return;
    cairo_destroy(c->cr);
    cairo_surface_destroy(c->surface);
    free(c);
    /* cairo and fontconfig keep their fonts for the life of the process
     * unless told: leak checkers report them, and a daemon drawing one
     * figure per reconstruction needs nothing kept between figures.  The
     * next canvas loads them again: 8 ms measured, per figure. */
    cairo_debug_reset_static_data();
    FcFini();
}

cairo_t *canvas_cairo(canvas *c)
{
    return c->cr;
}

void canvas_colour(canvas *c, unsigned rgb)
{
    cairo_set_source_rgb(c->cr, ((rgb >> 16) & 255) / 255.0,
                         ((rgb >> 8) & 255) / 255.0, (rgb & 255) / 255.0);
}

static void font(canvas *c, double size_px, int bold)
{
    cairo_select_font_face(c->cr, FONT, CAIRO_FONT_SLANT_NORMAL,
                           bold ? CAIRO_FONT_WEIGHT_BOLD : CAIRO_FONT_WEIGHT_NORMAL);
    cairo_set_font_size(c->cr, size_px);
}

double canvas_text_width(canvas *c, const char *s, double size_px, int bold)
{
    cairo_text_extents_t ext;
    font(c, size_px, bold);
    cairo_text_extents(c->cr, s, &ext);
    return ext.x_advance;
}

void canvas_text(canvas *c, double x, double y, const char *s,
                 double size_px, int bold, canvas_align a)
{
    double wd = canvas_text_width(c, s, size_px, bold);
    cairo_move_to(c->cr, a == CANVAS_LEFT ? x : a == CANVAS_CENTRE ? x - wd / 2 : x - wd, y);
    cairo_show_text(c->cr, s);
}

void canvas_text_up(canvas *c, double x, double y, const char *s, double size_px)
{
    double wd = canvas_text_width(c, s, size_px, 0);
    cairo_save(c->cr);
    cairo_translate(c->cr, x, y);
    cairo_rotate(c->cr, -1.57079632679489662);
    cairo_move_to(c->cr, -wd / 2, size_px * 0.35); /* centre the x-height on (x, y) */
    cairo_show_text(c->cr, s);
    cairo_restore(c->cr);
}

int canvas_image(canvas *c, const unsigned char *rgb, int w, int h, int x,
                 int y, int scale, sl_err *err)
{
    cairo_surface_t *img = cairo_image_surface_create(CAIRO_FORMAT_RGB24, w, h);
    cairo_status_t st = cairo_surface_status(img);
    if (st != CAIRO_STATUS_SUCCESS) {
        cairo_surface_destroy(img);
        return cairo_fail(st, err, "figure image");
    }
    cairo_surface_flush(img);
    unsigned char *data = cairo_image_surface_get_data(img);
    int stride = cairo_image_surface_get_stride(img);
    for (int r = 0; r < h; r++) {
        uint32_t *row = (uint32_t *)(void *)(data + (size_t)r * (size_t)stride);
        const unsigned char *src = rgb + (size_t)r * (size_t)w * 3;
        for (int i = 0; i < w; i++)
            row[i] = (uint32_t)src[3 * i] << 16 | (uint32_t)src[3 * i + 1] << 8 | src[3 * i + 2];
    }
    cairo_surface_mark_dirty(img);
    cairo_save(c->cr);
    cairo_translate(c->cr, x, y);
    cairo_scale(c->cr, scale, scale);
    cairo_set_source_surface(c->cr, img, 0, 0);
    cairo_pattern_set_filter(cairo_get_source(c->cr), CAIRO_FILTER_NEAREST);
    cairo_rectangle(c->cr, 0, 0, w, h);
    cairo_fill(c->cr);
    cairo_restore(c->cr);
    cairo_surface_destroy(img);
    return SL_OK;
}

int canvas_write_png(canvas *c, const char *path, sl_err *err)
{
    cairo_surface_flush(c->surface);
    cairo_status_t st = cairo_status(c->cr);
    if (st == CAIRO_STATUS_SUCCESS)
        st = cairo_surface_write_to_png(c->surface, path);
    if (st == CAIRO_STATUS_SUCCESS)
        return SL_OK;
    unlink(path); /* never leave a half-written figure behind */
    return cairo_fail(st, err, path);
}
