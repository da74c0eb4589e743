/* skyfig.c - a sky image as a figure; see skyfig.h. */
#include "skyfig.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "canvas.h"
#include "colormap.h"

#define MARGIN 20
#define TITLE_PX 20.0
#define SUB_PX 14.0
#define LABEL_PX 13.0
#define IMG_TOP (MARGIN + 56)      /* below the title and subtitle */
#define CBAR_GAP 24
#define CBAR_W 20
#define TICK_PX 6
#define TICK_LABELS_W 58
#define CBAR_TITLE_W 30
#define BAND_H 88                  /* under the image: scale bar, compass */
#define BAR_THICK 6
#define COMPASS_LEN 48
#define MAX_UPSCALE 64
#define ZOOM_MIN_HALF 8            /* the zoom shows at least 17 x 17 px */
#define NAN_GREY 0x808080          /* not on the colour map */
#define INK 0x000000
#define FRAME_GREY 0x909090

void skyfig_opts_init(skyfig_opts *o)
{
    memset(o, 0, sizeof *o);
    o->plate_scale_arcsec = NAN;
    o->stretch = PREVIEW_ASINH;
    o->cut = DISPLAY_CUT_ARTIFACTS;
    o->min_display_px = 512;
    o->zoom = 1;
}

void skyfig_opts_from_result(skyfig_opts *o, const pipeline_result *r,
                             const char *name)
{
    const char *obj = name && name[0] ? name : r->meta.object[0] ? r->meta.object : "unnamed";
    snprintf(o->title, sizeof o->title, "%s \u00b7 %s \u00b7 %d frames", obj,
             pipeline_method_name(r->report.method), r->nframes);
    o->plate_scale_arcsec = r->plate_scale_arcsec;
    const pipeline_binary *b = &r->binary;
    o->subtitle[0] = '\0';
    if (b->status != PIPE_BIN_MEASURED && b->status != PIPE_BIN_AMBIGUOUS)
        return;
    double ps = r->plate_scale_arcsec;
    char sep[64];
    if (isfinite(ps) && ps > 0)
        snprintf(sep, sizeof sep, "%.3f\u2033 (%.2f px)", b->sep_px * ps, b->sep_px);
    else
        snprintf(sep, sizeof sep, "%.2f px", b->sep_px);
    snprintf(o->subtitle, sizeof o->subtitle,
             "binary %s: separation %s, PA %.1f\u00b0%s, \u0394m %.2f (%s)",
             pipeline_binary_status_name(b->status), sep, b->pa_deg,
             b->status == PIPE_BIN_AMBIGUOUS ? " or +180\u00b0" : "", b->dm_mag,
             pipeline_binary_source_name(b->source));
}

/* The longest 1, 2 or 5 x 10^n not above v (v > 0). */
static double nice_floor(double v)
{
    double p = pow(10.0, floor(log10(v)));
    return v >= 5 * p ? 5 * p : v >= 2 * p ? 2 * p : p;
}

static int scale_known(const skyfig_opts *o)
{
    return isfinite(o->plate_scale_arcsec) && o->plate_scale_arcsec > 0;
}

/* The zoom: a box centred on the object (the pipeline puts it at
 * (w/2, h/2)) holding every pixel above the cut with a quarter more room
 * and 4 px around; the whole image when that is most of it. */
static void crop(const float *img, int w, int h, const display *d, int zoom,
                 skyfig_layout *l)
{
    int cx = w / 2, cy = h / 2, r = 0;
    for (int y = 0; y < h && zoom; y++)
        for (int x = 0; x < w; x++) {
            float v = img[(size_t)y * (size_t)w + (size_t)x];
            int dist = abs(x - cx) > abs(y - cy) ? abs(x - cx) : abs(y - cy);
            if (isfinite(v) && v > d->lo && dist > r)
                r = dist;
        }
    int half = (int)ceil(1.25 * r) + 4;
    half = half < ZOOM_MIN_HALF ? ZOOM_MIN_HALF : half;
    l->crop_x0 = cx - half < 0 ? 0 : cx - half;
    l->crop_y0 = cy - half < 0 ? 0 : cy - half;
    l->crop_w = (cx + half >= w ? w - 1 : cx + half) - l->crop_x0 + 1;
    l->crop_h = (cy + half >= h ? h - 1 : cy + half) - l->crop_y0 + 1;
    if (!zoom || (5 * l->crop_w >= 4 * w && 5 * l->crop_h >= 4 * h)) {
        l->crop_x0 = l->crop_y0 = 0;
        l->crop_w = w;
        l->crop_h = h;
    }
}

/* The layout once the display is known. */
static void place(const skyfig_opts *o, const float *img, int w, int h,
                  const display *d, skyfig_layout *l)
{
    memset(l, 0, sizeof *l);
    crop(img, w, h, d, o->zoom, l);
    int longer = l->crop_w > l->crop_h ? l->crop_w : l->crop_h;
    int k = (o->min_display_px + longer - 1) / longer;
    l->upscale = k < 1 ? 1 : k > MAX_UPSCALE ? MAX_UPSCALE : k;
    l->img_x = MARGIN;
    l->img_y = IMG_TOP;
    l->img_w = l->crop_w * l->upscale;
    l->img_h = l->crop_h * l->upscale;
    l->cbar_x = l->img_x + l->img_w + CBAR_GAP;
    l->cbar_y = l->img_y;
    l->cbar_w = CBAR_W;
    l->cbar_h = l->img_h;
    l->width = l->cbar_x + CBAR_W + TICK_PX + TICK_LABELS_W + CBAR_TITLE_W + MARGIN;
    l->height = l->img_y + l->img_h + BAND_H + MARGIN;
    l->bar_in_arcsec = scale_known(o);
    double unit_px = (l->bar_in_arcsec ? 1.0 / o->plate_scale_arcsec : 1.0) * l->upscale;
    l->bar_value = nice_floor(0.3 * l->img_w / unit_px);
    l->bar_len_px = (int)lround(l->bar_value * unit_px);
    l->bar_thick_px = BAR_THICK;
    l->bar_x = l->img_x;
    l->bar_y = l->img_y + l->img_h + 26;
    l->compass_len = COMPASS_LEN;
    l->compass_x = l->img_x + l->img_w - 24;
    l->compass_y = l->img_y + l->img_h + BAND_H - 14;
}

/* Check the arguments, measure the display, lay out. */
static int plan(const skyfig_opts *o, const float *img, int w, int h, display *d,
                skyfig_layout *l, sl_err *err)
{
    if (!o || !img || !l || w < 1 || h < 1 || w > 8192 || h > 8192 || o->min_display_px < 1)
        return sl_seterr(err, SL_EINVAL, "skyfig: image of %d x %d px: want 1..8192", w, h);
    int rc = display_fit(d, img, w, h, o->cut, o->stretch, err);
    if (rc == SL_OK)
        place(o, img, w, h, d, l);
    return rc;
}

int skyfig_layout_of(const skyfig_opts *o, const float *img, int w, int h,
                     skyfig_layout *l, sl_err *err)
{
    display d;
    return plan(o, img, w, h, &d, l, err);
}

/* The shown pixels as RGB rows, highest y first (north up). */
static unsigned char *colour_pixels(const float *img, int w, const skyfig_layout *l,
                                    const display *d, const colormap *cm)
{
    int cw = l->crop_w, ch = l->crop_h;
    unsigned char *rgb = malloc((size_t)cw * (size_t)ch * 3);
    if (!rgb)
        return NULL;
    for (int j = 0; j < ch; j++)
        for (int i = 0; i < cw; i++) {
            unsigned char *p = rgb + ((size_t)(ch - 1 - j) * (size_t)cw + (size_t)i) * 3;
            size_t at = (size_t)(l->crop_y0 + j) * (size_t)w + (size_t)(l->crop_x0 + i);
            double lv = display_level(d, img[at]);
            if (isnan(lv)) {
                p[0] = p[1] = p[2] = (NAN_GREY >> 16) & 255;
                continue;
            }
            memcpy(p, colormap_rgb(cm, lv), 3);
        }
    return rgb;
}

/* 2 significant digits ("0.097", "1", "-0.12"); "0" near zero. */
static void tick_text(double v, char *buf, size_t n)
{
    snprintf(buf, n, "%.2g", fabs(v) < 5e-4 ? 0.0 : v);
}

static double round2(double v)
{
    if (fabs(v) < 5e-4)
        return 0.0;
    double p = pow(10.0, floor(log10(fabs(v))) - 1);
    return round(v / p) * p;
}

/* Ticks at the ends and at nice values near levels 1/4, 1/2, 3/4. */
static void cbar_ticks(canvas *c, const skyfig_layout *l, const display *d, double unit)
{
    cairo_t *cr = canvas_cairo(c);
    double last_y = -1e9;
    for (int k = 4; k >= 0; k--) {
        double v = display_value(d, k / 4.0) / unit;
        if (k > 0 && k < 4)
            v = round2(v);
        double lv = k == 0 || k == 4 ? k / 4.0 : display_level(d, v * unit);
        double y = l->cbar_y + (1.0 - lv) * (l->cbar_h - 1) + 0.5;
        if (!(lv >= 0 && lv <= 1) || fabs(y - last_y) < 16)
            continue;
        last_y = y;
        char buf[32];
        tick_text(v, buf, sizeof buf);
        canvas_colour(c, INK);
        cairo_set_line_width(cr, 1);
        cairo_move_to(cr, l->cbar_x + l->cbar_w, y);
        cairo_line_to(cr, l->cbar_x + l->cbar_w + TICK_PX, y);
        cairo_stroke(cr);
        canvas_text(c, l->cbar_x + l->cbar_w + TICK_PX + 3, y + LABEL_PX * 0.35, buf,
                    LABEL_PX, 0, CANVAS_LEFT);
    }
}

static int draw_cbar(canvas *c, const skyfig_layout *l, const display *d,
                     const colormap *cm, sl_err *err)
{
    unsigned char *rgb = malloc((size_t)l->cbar_w * (size_t)l->cbar_h * 3);
    if (!rgb)
        return sl_seterr(err, SL_ENOMEM, "skyfig: out of memory for the colour bar");
    for (int r = 0; r < l->cbar_h; r++) {
        const unsigned char *col = colormap_rgb(cm, 1.0 - (double)r / (l->cbar_h - 1));
        for (int i = 0; i < l->cbar_w; i++)
            memcpy(rgb + ((size_t)r * (size_t)l->cbar_w + (size_t)i) * 3, col, 3);
    }
    int rc = canvas_image(c, rgb, l->cbar_w, l->cbar_h, l->cbar_x, l->cbar_y, 1, err);
    free(rgb);
    if (rc != SL_OK)
        return rc;
    cairo_t *cr = canvas_cairo(c);
    canvas_colour(c, INK);
    cairo_set_line_width(cr, 1);
    cairo_rectangle(cr, l->cbar_x - 0.5, l->cbar_y - 0.5, l->cbar_w + 1, l->cbar_h + 1);
    cairo_stroke(cr);
    int rel = d->peak > 0;
    cbar_ticks(c, l, d, rel ? d->peak : 1.0);
    char title[96];
    snprintf(title, sizeof title, "%s, %s stretch", rel ? "flux / peak" : "value",
             d->stretch == PREVIEW_ASINH ? "asinh" : d->stretch == PREVIEW_SQRT ? "sqrt" : "linear");
    canvas_text_up(c, l->width - MARGIN - CBAR_TITLE_W / 2.0, l->cbar_y + l->cbar_h / 2.0,
                   title, LABEL_PX);
    return SL_OK;
}

static void draw_scale_bar(canvas *c, const skyfig_layout *l, int w, int h)
{
    cairo_t *cr = canvas_cairo(c);
    canvas_colour(c, INK);
    cairo_rectangle(cr, l->bar_x, l->bar_y, l->bar_len_px, l->bar_thick_px);
    cairo_fill(cr);
    char buf[64];
    if (l->bar_in_arcsec)
        snprintf(buf, sizeof buf, "%g\u2033", l->bar_value);
    else
        snprintf(buf, sizeof buf, "%g px (plate scale unknown)", l->bar_value);
    canvas_text(c, l->bar_x + (l->bar_len_px > 40 ? l->bar_len_px / 2.0 : 0),
                l->bar_y + l->bar_thick_px + 20, buf, SUB_PX, 0,
                l->bar_len_px > 40 ? CANVAS_CENTRE : CANVAS_LEFT);
    if (l->crop_w == w && l->crop_h == h)
        return;
    snprintf(buf, sizeof buf, "central %d \u00d7 %d of %d \u00d7 %d px", l->crop_w,
             l->crop_h, w, h);
    canvas_text(c, l->img_x + l->img_w * 0.55, l->bar_y + l->bar_thick_px + 20, buf,
                LABEL_PX, 0, CANVAS_CENTRE);
}

/* An arrow from (x0, y0) to (x1, y1) with a filled head. */
static void arrow(cairo_t *cr, double x0, double y0, double x1, double y1)
{
    double a = atan2(y1 - y0, x1 - x0), hl = 12, hw = 5;
    cairo_set_line_width(cr, 2);
    cairo_move_to(cr, x0, y0);
    cairo_line_to(cr, x1 - hl * 0.8 * cos(a), y1 - hl * 0.8 * sin(a));
    cairo_stroke(cr);
    cairo_move_to(cr, x1, y1);
    cairo_line_to(cr, x1 - hl * cos(a) - hw * sin(a), y1 - hl * sin(a) + hw * cos(a));
    cairo_line_to(cr, x1 - hl * cos(a) + hw * sin(a), y1 - hl * sin(a) - hw * cos(a));
    cairo_close_path(cr);
    cairo_fill(cr);
}

/* North up, east left: the image is never rotated, the compass says so. */
static void draw_compass(canvas *c, const skyfig_layout *l)
{
    cairo_t *cr = canvas_cairo(c);
    double x = l->compass_x + 0.5, y = l->compass_y + 0.5, n = l->compass_len;
    canvas_colour(c, INK);
    arrow(cr, x, y + 1, x, y - n);
    arrow(cr, x + 1, y, x - n, y);
    canvas_text(c, x, y - n - 5, "N", SUB_PX, 1, CANVAS_CENTRE);
    canvas_text(c, x - n - 5, y + SUB_PX * 0.35, "E", SUB_PX, 1, CANVAS_RIGHT);
}

/* Title and subtitle, shrunk to fit the width. */
static void draw_titles(canvas *c, const skyfig_opts *o, const skyfig_layout *l)
{
    const char *s[2] = {o->title, o->subtitle};
    const double size[2] = {TITLE_PX, SUB_PX}, base[2] = {MARGIN + 18, MARGIN + 42};
    double room = l->width - 2 * MARGIN;
    canvas_colour(c, INK);
    for (int i = 0; i < 2; i++) {
        if (!s[i][0])
            continue;
        double px = size[i], wd = canvas_text_width(c, s[i], px, i == 0);
        if (wd > room)
            px = fmax(8.0, px * room / wd);
        canvas_text(c, MARGIN, base[i], s[i], px, i == 0, CANVAS_LEFT);
    }
}

static int draw(canvas *c, const float *img, int w, int h, const skyfig_opts *o,
                const skyfig_layout *l, const display *d, sl_err *err)
{
    colormap cm;
    colormap_init(&cm);
    unsigned char *rgb = colour_pixels(img, w, l, d, &cm);
    if (!rgb)
        return sl_seterr(err, SL_ENOMEM, "skyfig: out of memory for %d x %d", w, h);
    int rc = canvas_image(c, rgb, l->crop_w, l->crop_h, l->img_x, l->img_y, l->upscale, err);
    free(rgb);
    if (rc != SL_OK)
        return rc;
    cairo_t *cr = canvas_cairo(c);
    canvas_colour(c, FRAME_GREY);
    cairo_set_line_width(cr, 1);
    cairo_rectangle(cr, l->img_x - 0.5, l->img_y - 0.5, l->img_w + 1, l->img_h + 1);
    cairo_stroke(cr);
    draw_titles(c, o, l);
    draw_scale_bar(c, l, w, h);
    draw_compass(c, l);
    return draw_cbar(c, l, d, &cm, err);
}

int skyfig_write_png(const char *path, const float *img, int w, int h,
                     const skyfig_opts *o, sl_err *err)
{
    skyfig_layout l;
    display d;
    if (!path)
        return sl_seterr(err, SL_EINVAL, "skyfig_write_png: no path");
    int rc = plan(o, img, w, h, &d, &l, err);
    if (rc != SL_OK)
        return rc;
    canvas *c = canvas_new(l.width, l.height, err);
    if (!c)
        return err ? err->code : SL_ENOMEM;
    rc = draw(c, img, w, h, o, &l, &d, err);
    if (rc == SL_OK)
        rc = canvas_write_png(c, path, err);
    canvas_free(c);
    return rc;
}
