/* plot.c - see plot.h. */
#include "plot.h"

#include <ctype.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "io/preview.h"

struct plot {
    int w, h;
    float *pix;
};

/* 5x7 glyphs: row 0 is the TOP row, bit 4 the leftmost column. */
typedef struct glyph {
    char c;
    uint8_t rows[7];
} glyph;

static const glyph font[] = {
    {'0', {0x0e, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0e}}, {'1', {0x04, 0x0c, 0x04, 0x04, 0x04, 0x04, 0x0e}},
    {'2', {0x0e, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1f}}, {'3', {0x1f, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0e}},
    {'4', {0x02, 0x06, 0x0a, 0x12, 0x1f, 0x02, 0x02}}, {'5', {0x1f, 0x10, 0x1e, 0x01, 0x01, 0x11, 0x0e}},
    {'6', {0x06, 0x08, 0x10, 0x1e, 0x11, 0x11, 0x0e}}, {'7', {0x1f, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
    {'8', {0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e}}, {'9', {0x0e, 0x11, 0x11, 0x0f, 0x01, 0x02, 0x0c}},
    {'A', {0x0e, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11}}, {'B', {0x1e, 0x11, 0x11, 0x1e, 0x11, 0x11, 0x1e}},
    {'C', {0x0e, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0e}}, {'D', {0x1c, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1c}},
    {'E', {0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x1f}}, {'F', {0x1f, 0x10, 0x10, 0x1e, 0x10, 0x10, 0x10}},
    {'G', {0x0e, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0f}}, {'H', {0x11, 0x11, 0x11, 0x1f, 0x11, 0x11, 0x11}},
    {'I', {0x0e, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0e}}, {'J', {0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0c}},
    {'K', {0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11}}, {'L', {0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1f}},
    {'M', {0x11, 0x1b, 0x15, 0x15, 0x11, 0x11, 0x11}}, {'N', {0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11}},
    {'O', {0x0e, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e}}, {'P', {0x1e, 0x11, 0x11, 0x1e, 0x10, 0x10, 0x10}},
    {'Q', {0x0e, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0d}}, {'R', {0x1e, 0x11, 0x11, 0x1e, 0x14, 0x12, 0x11}},
    {'S', {0x0f, 0x10, 0x10, 0x0e, 0x01, 0x01, 0x1e}}, {'T', {0x1f, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04}},
    {'U', {0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0e}}, {'V', {0x11, 0x11, 0x11, 0x11, 0x11, 0x0a, 0x04}},
    {'W', {0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0a}}, {'X', {0x11, 0x11, 0x0a, 0x04, 0x0a, 0x11, 0x11}},
    {'Y', {0x11, 0x11, 0x0a, 0x04, 0x04, 0x04, 0x04}}, {'Z', {0x1f, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1f}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0c, 0x0c}}, {',', {0x00, 0x00, 0x00, 0x00, 0x0c, 0x04, 0x08}},
    {':', {0x00, 0x0c, 0x0c, 0x00, 0x0c, 0x0c, 0x00}}, {';', {0x00, 0x0c, 0x0c, 0x00, 0x0c, 0x04, 0x08}},
    {'-', {0x00, 0x00, 0x00, 0x1f, 0x00, 0x00, 0x00}}, {'+', {0x00, 0x04, 0x04, 0x1f, 0x04, 0x04, 0x00}},
    {'=', {0x00, 0x00, 0x1f, 0x00, 0x1f, 0x00, 0x00}}, {'(', {0x02, 0x04, 0x08, 0x08, 0x08, 0x04, 0x02}},
    {')', {0x08, 0x04, 0x02, 0x02, 0x02, 0x04, 0x08}}, {'/', {0x01, 0x02, 0x02, 0x04, 0x08, 0x08, 0x10}},
    {'_', {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1f}}, {'%', {0x18, 0x19, 0x02, 0x04, 0x08, 0x13, 0x03}},
    {'<', {0x02, 0x04, 0x08, 0x10, 0x08, 0x04, 0x02}}, {'>', {0x08, 0x04, 0x02, 0x01, 0x02, 0x04, 0x08}},
    {'*', {0x00, 0x04, 0x15, 0x0e, 0x15, 0x04, 0x00}}, {'\'', {0x04, 0x04, 0x08, 0x00, 0x00, 0x00, 0x00}},
};

static const uint8_t *glyph_rows(char c)
{
    c = (char)toupper((unsigned char)c);
    for (size_t i = 0; i < sizeof font / sizeof font[0]; i++)
        if (font[i].c == c)
            return font[i].rows;
    return NULL; /* drawn as a blank */
}

plot *plot_new(int w, int h, sl_err *err)
{
    if (w < 16 || h < 16 || w > 8192 || h > 8192) {
        sl_seterr(err, SL_EINVAL, "plot size %dx%d outside 16..8192", w, h);
        return NULL;
    }
    plot *p = malloc(sizeof *p);
    float *pix = malloc(sizeof(float) * (size_t)w * (size_t)h);
    if (!p || !pix) {
        free(p);
        free(pix);
        sl_seterr(err, SL_ENOMEM, "out of memory for a %dx%d plot", w, h);
        return NULL;
    }
    p->w = w;
    p->h = h;
    p->pix = pix;
    for (size_t i = 0; i < (size_t)w * (size_t)h; i++)
        pix[i] = 1.0f;
    return p;
}

void plot_free(plot *p)
{
    if (!p)
        return;
    free(p->pix);
    free(p);
}

int plot_width(const plot *p) { return p->w; }
int plot_height(const plot *p) { return p->h; }
const float *plot_pixels(const plot *p) { return p->pix; }

void plot_pixel(plot *p, int x, int y, float grey)
{
    if (x >= 0 && y >= 0 && x < p->w && y < p->h)
        p->pix[(size_t)y * (size_t)p->w + (size_t)x] = grey;
}

/* A square brush of side thick centred on (x, y). */
static void brush(plot *p, int x, int y, float grey, int thick)
{
    int lo = -(thick - 1) / 2, hi = thick / 2;
    for (int dy = lo; dy <= hi; dy++)
        for (int dx = lo; dx <= hi; dx++)
            plot_pixel(p, x + dx, y + dy, grey);
}

/* Clip the segment to the canvas grown by a margin (Liang-Barsky), so a
 * point far off the chart costs nothing; 0 when nothing is left. */
static int clip_segment(const plot *p, double *x0, double *y0, double *x1,
                        double *y1, double margin)
{
    double t0 = 0, t1 = 1, dx = *x1 - *x0, dy = *y1 - *y0;
    double q[4] = {*x0 + margin, p->w - 1 + margin - *x0, *y0 + margin,
                   p->h - 1 + margin - *y0};
    double d[4] = {-dx, dx, -dy, dy};
    for (int i = 0; i < 4; i++) {
        if (d[i] == 0) {
            if (q[i] < 0)
                return 0;
            continue;
        }
        double r = q[i] / d[i];
        if (d[i] < 0)
            t0 = r > t0 ? r : t0;
        else
            t1 = r < t1 ? r : t1;
    }
    if (t0 > t1)
        return 0;
    *x1 = *x0 + t1 * dx;
    *y1 = *y0 + t1 * dy;
    *x0 += t0 * dx;
    *y0 += t0 * dy;
    return 1;
}

/* Walk the clipped line in unit steps along its longer axis (DDA); on/off
 * > 0 dashes it (the dash phase restarts at the clipped start). */
static void walk(plot *p, double x0, double y0, double x1, double y1,
                 float grey, int thick, int on, int off)
{
    if (!isfinite(x0) || !isfinite(y0) || !isfinite(x1) || !isfinite(y1) ||
        !clip_segment(p, &x0, &y0, &x1, &y1, thick))
        return;
    double dx = x1 - x0, dy = y1 - y0;
    int n = (int)ceil(fmax(fabs(dx), fabs(dy)));
    for (int i = 0; i <= n; i++) {
        if (on > 0 && i % (on + off) >= on)
            continue;
        double t = n > 0 ? (double)i / n : 0.0;
        brush(p, (int)lround(x0 + t * dx), (int)lround(y0 + t * dy), grey,
              thick);
    }
}

void plot_line(plot *p, double x0, double y0, double x1, double y1,
               float grey, int thick)
{
    walk(p, x0, y0, x1, y1, grey, thick < 1 ? 1 : thick, 0, 0);
}

void plot_dash(plot *p, double x0, double y0, double x1, double y1,
               float grey, int on_px, int off_px)
{
    walk(p, x0, y0, x1, y1, grey, 1, on_px < 1 ? 1 : on_px,
         off_px < 0 ? 0 : off_px);
}

void plot_rect(plot *p, int x0, int y0, int x1, int y1, float grey)
{
    plot_line(p, x0, y0, x1, y0, grey, 1);
    plot_line(p, x1, y0, x1, y1, grey, 1);
    plot_line(p, x1, y1, x0, y1, grey, 1);
    plot_line(p, x0, y1, x0, y0, grey, 1);
}

/* Inside test of a filled shape at offset (dx, dy) from the centre. */
static int inside(plot_shape s, int dx, int dy, int r)
{
    switch (s) {
    case PLOT_CIRCLE: return dx * dx + dy * dy <= r * r + r / 2;
    case PLOT_SQUARE: return abs(dx) <= r && abs(dy) <= r;
    case PLOT_DIAMOND: return abs(dx) + abs(dy) <= r;
    case PLOT_TRIANGLE: /* apex up, base at -r */
        return dy >= -r && dy <= r && 2 * abs(dx) <= r - dy;
    default: return 0;
    }
}

void plot_marker(plot *p, double x, double y, plot_shape shape, int filled,
                 int r, float grey)
{
    if (!isfinite(x) || !isfinite(y))
        return;
    int cx = (int)lround(x), cy = (int)lround(y);
    r = r < 1 ? 1 : r;
    if (shape == PLOT_CROSS || shape == PLOT_PLUS) {
        for (int i = -r; i <= r; i++) {
            if (shape == PLOT_CROSS) {
                brush(p, cx + i, cy + i, grey, 2);
                brush(p, cx + i, cy - i, grey, 2);
            } else {
                brush(p, cx + i, cy, grey, 2);
                brush(p, cx, cy + i, grey, 2);
            }
        }
        return;
    }
    /* Outline = inside but with a 4-neighbour outside (two pixels thick
     * so hollow markers stay visible on a busy chart). */
    for (int dy = -r - 1; dy <= r + 1; dy++)
        for (int dx = -r - 1; dx <= r + 1; dx++) {
            if (!inside(shape, dx, dy, r))
                continue;
            int edge = 0;
            for (int k = 1; k <= 2 && !edge; k++)
                edge = !inside(shape, dx + k, dy, r) ||
                       !inside(shape, dx - k, dy, r) ||
                       !inside(shape, dx, dy + k, r) ||
                       !inside(shape, dx, dy - k, r);
            if (filled || edge)
                plot_pixel(p, cx + dx, cy + dy, grey);
        }
}

int plot_text_width(const char *s, int scale)
{
    return (int)strlen(s) * 6 * (scale < 1 ? 1 : scale);
}

int plot_text_height(int scale) { return 8 * (scale < 1 ? 1 : scale); }

/* Shared by both directions: glyph pixel (gx, gy) (gy up from the cell's
 * bottom) of character i lands at (x + u, y + v) after the map. */
static int text(plot *p, int x, int y, const char *s, float grey, int scale,
                int up)
{
    scale = scale < 1 ? 1 : scale;
    int i = 0;
    for (; s[i]; i++) {
        const uint8_t *rows = glyph_rows(s[i]);
        if (!rows)
            continue;
        for (int row = 0; row < 7; row++)
            for (int col = 0; col < 5; col++) {
                if (!(rows[row] >> (4 - col) & 1))
                    continue;
                int gx = (i * 6 + col) * scale, gy = (7 - row) * scale;
                for (int a = 0; a < scale; a++)
                    for (int b = 0; b < scale; b++) {
                        if (up)
                            plot_pixel(p, x - gy - b, y + gx + a, grey);
                        else
                            plot_pixel(p, x + gx + a, y + gy + b, grey);
                    }
            }
    }
    return i * 6 * scale;
}

int plot_text(plot *p, int x, int y, const char *s, float grey, int scale)
{
    return text(p, x, y, s, grey, scale, 0);
}

int plot_text_up(plot *p, int x, int y, const char *s, float grey, int scale)
{
    return text(p, x, y, s, grey, scale, 1);
}

int plot_write_png(const plot *p, const char *path, sl_err *err)
{
    return preview_write_png(path, p->pix, p->w, p->h, PREVIEW_LINEAR, err);
}
