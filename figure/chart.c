/* chart.c - log-log scatter charts; see chart.h. */
#include "chart.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "canvas.h"

#define PANEL_W 480
#define PANEL_H 360
#define COLS 3
#define BOX_L 78    /* left: tick labels and the y title */
#define BOX_R 18
#define BOX_B 56    /* bottom: tick labels and the x title */
#define BOX_T 34    /* top: the panel title */
#define LEGEND_CELL 300
#define LEGEND_ROW 24
#define LEGEND_PAD 16
#define MARKER_R 6
#define TEXT_PX 13.0
#define TITLE_PX 14.0
#define INK 0x000000
#define GRID 0xdddddd
#define FRONT_GREY 0x666666
#define PI 3.14159265358979323846

unsigned chart_colour(int i)
{
    /* Okabe & Ito: blue, vermillion, bluish green, reddish purple, orange,
     * sky blue, black, yellow (last: faint on white). */
    static const unsigned pal[CHART_NCOLOURS] = {0x0072b2, 0xd55e00, 0x009e73, 0xcc79a7,
                                                 0xe69f00, 0x56b4e9, 0x000000, 0xf0e442};
    return pal[((i % CHART_NCOLOURS) + CHART_NCOLOURS) % CHART_NCOLOURS];
}

static int drawable(const chart_point *p)
{
    return isfinite(p->x) && p->x > 0 && isfinite(p->y) && p->y > 0;
}

/* Whole decades [l0, l1] around the drawable values; 0 if none. */
static int decades(const chart_data *d, int use_x, double *l0, double *l1)
{
    double lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < d->npts; i++)
        if (drawable(&d->pts[i])) {
            double v = use_x ? d->pts[i].x : d->pts[i].y;
            lo = fmin(lo, v);
            hi = fmax(hi, v);
        }
    if (!isfinite(lo))
        return 0;
    *l1 = ceil(log10(hi) - 1e-9);
    *l0 = floor(log10(lo) + 1e-9);
    if (*l1 <= *l0)
        *l1 = *l0 + 1;
    if (*l1 - *l0 > CHART_MAX_DECADES)
        *l0 = *l1 - CHART_MAX_DECADES;
    return 1;
}

static int legend_cols(int width)
{
    int c = (width - 2 * LEGEND_PAD) / LEGEND_CELL;
    return c < 1 ? 1 : c;
}

int chart_layout_of(const chart_data *d, chart_layout *l, sl_err *err)
{
    if (!d || !l || d->npanels < 1 || d->npanels > CHART_MAX_PANELS || d->nseries < 1 ||
        d->nseries > CHART_MAX_SERIES || d->npts < 0 || (d->npts && !d->pts))
        return sl_seterr(err, SL_EINVAL, "chart: %d panels (1..%d), %d series (1..%d)",
                         d ? d->npanels : 0, CHART_MAX_PANELS, d ? d->nseries : 0,
                         CHART_MAX_SERIES);
    if (!decades(d, 1, &l->lx0, &l->lx1) || !decades(d, 0, &l->ly0, &l->ly1)) {
        l->lx0 = l->ly0 = -2; /* nothing to draw: empty axes */
        l->lx1 = l->ly1 = 0;
    }
    int ncols = d->npanels < COLS ? d->npanels : COLS, rows = (d->npanels + COLS - 1) / COLS;
    l->width = ncols * PANEL_W;
    int nleg = d->nseries + (d->front_name != NULL), lc = legend_cols(l->width);
    int leg_rows = (nleg + lc - 1) / lc;
    l->height = rows * PANEL_H + leg_rows * LEGEND_ROW + 2 * LEGEND_PAD;
    for (int k = 0; k < d->npanels; k++) {
        int px = (k % COLS) * PANEL_W, py = (k / COLS) * PANEL_H;
        l->box_x0[k] = px + BOX_L;
        l->box_x1[k] = px + PANEL_W - BOX_R;
        l->box_y0[k] = py + BOX_T;
        l->box_y1[k] = py + PANEL_H - BOX_B;
    }
    for (int i = 0; i < nleg; i++) {
        l->legend_x[i] = LEGEND_PAD + (i % lc) * LEGEND_CELL + MARKER_R + 4;
        l->legend_y[i] = rows * PANEL_H + LEGEND_PAD + (i / lc) * LEGEND_ROW + LEGEND_ROW / 2;
    }
    l->marker_r = MARKER_R;
    return SL_OK;
}

void chart_to_px(const chart_layout *l, int p, double x, double y, double *px, double *py)
{
    double tx = (log10(x) - l->lx0) / (l->lx1 - l->lx0);
    double ty = (log10(y) - l->ly0) / (l->ly1 - l->ly0);
    tx = tx < 0 ? 0 : tx > 1 ? 1 : tx;
    ty = ty < 0 ? 0 : ty > 1 ? 1 : ty;
    *px = l->box_x0[p] + tx * (l->box_x1[p] - l->box_x0[p]);
    *py = l->box_y1[p] - ty * (l->box_y1[p] - l->box_y0[p]);
}

static void decade_label(int k, char *buf, size_t n)
{
    if (k >= 0 && k <= 4)
        snprintf(buf, n, "%.0f", pow(10, k));
    else if (k < 0 && k >= -4)
        snprintf(buf, n, "%.*f", -k, pow(10, k));
    else
        snprintf(buf, n, "1e%d", k);
}

/* The path of a regular polygon of n corners, the first at angle a0. */
static void polygon(cairo_t *cr, double x, double y, double r, int n, double a0)
{
    for (int i = 0; i < n; i++) {
        double a = a0 + 2 * PI * i / n;
        if (i == 0)
            cairo_move_to(cr, x + r * cos(a), y + r * sin(a));
        else
            cairo_line_to(cr, x + r * cos(a), y + r * sin(a));
    }
    cairo_close_path(cr);
}

static void marker(canvas *c, double x, double y, const chart_series *s, double r)
{
    cairo_t *cr = canvas_cairo(c);
    int shape = ((s->shape % CHART_NSHAPES) + CHART_NSHAPES) % CHART_NSHAPES;
    switch (shape) {
    case CHART_SQUARE: cairo_rectangle(cr, x - r * 0.85, y - r * 0.85, 1.7 * r, 1.7 * r); break;
    case CHART_TRIANGLE: polygon(cr, x, y + r * 0.2, r * 1.2, 3, -PI / 2); break;
    case CHART_DIAMOND: polygon(cr, x, y, r * 1.2, 4, -PI / 2); break;
    case CHART_TRIANGLE_DOWN: polygon(cr, x, y - r * 0.2, r * 1.2, 3, PI / 2); break;
    case CHART_PENTAGON: polygon(cr, x, y, r * 1.1, 5, -PI / 2); break;
    default: cairo_new_sub_path(cr); cairo_arc(cr, x, y, r, 0, 2 * PI); break;
    }
    canvas_colour(c, s->filled ? chart_colour(s->colour) : 0xffffff);
    cairo_fill_preserve(cr);
    canvas_colour(c, chart_colour(s->colour));
    cairo_set_line_width(cr, 1.8);
    cairo_stroke(cr);
}

static void axes(canvas *c, const chart_layout *l, int p, const chart_data *d)
{
    cairo_t *cr = canvas_cairo(c);
    int x0 = l->box_x0[p], x1 = l->box_x1[p], y0 = l->box_y0[p], y1 = l->box_y1[p];
    char buf[32];
    cairo_set_line_width(cr, 1);
    for (int ax = 0; ax < 2; ax++) {
        double a = ax ? l->ly0 : l->lx0, b = ax ? l->ly1 : l->lx1;
        for (int k = (int)a; k <= (int)b; k++) {
            for (int m = 1; m <= 9; m++) {
                double v = m * pow(10, k), px, py;
                if (log10(v) > b + 1e-9 || (m > 1 && b - a > 4))
                    break;
                chart_to_px(l, p, ax ? pow(10, l->lx0) : v, ax ? v : pow(10, l->ly0), &px, &py);
                canvas_colour(c, m == 1 ? GRID : 0xf0f0f0);
                cairo_move_to(cr, ax ? x0 : floor(px) + 0.5, ax ? floor(py) + 0.5 : y0);
                cairo_line_to(cr, ax ? x1 : floor(px) + 0.5, ax ? floor(py) + 0.5 : y1);
                cairo_stroke(cr);
                if (m != 1)
                    continue;
                decade_label(k, buf, sizeof buf);
                canvas_colour(c, INK);
                if (ax)
                    canvas_text(c, x0 - 6, py + TEXT_PX * 0.35, buf, TEXT_PX, 0, CANVAS_RIGHT);
                else
                    canvas_text(c, px, y1 + TEXT_PX + 6, buf, TEXT_PX, 0, CANVAS_CENTRE);
            }
        }
    }
    canvas_colour(c, INK);
    cairo_rectangle(cr, x0 + 0.5, y0 + 0.5, x1 - x0, y1 - y0);
    cairo_stroke(cr);
    canvas_text(c, (x0 + x1) / 2.0, y1 + 2 * TEXT_PX + 16, d->x_title ? d->x_title : "",
                TEXT_PX, 0, CANVAS_CENTRE);
    canvas_text_up(c, (p % COLS) * PANEL_W + 16, (y0 + y1) / 2.0, d->y_title ? d->y_title : "",
                   TEXT_PX);
    canvas_text(c, x0, y0 - 10, d->panels[p] ? d->panels[p] : "", TITLE_PX, 1, CANVAS_LEFT);
}

static int by_x(const void *a, const void *b)
{
    const chart_point *p = *(const chart_point *const *)a, *q = *(const chart_point *const *)b;
    return (p->x > q->x) - (p->x < q->x);
}

/* Panel p's front points joined in order of x, dashed, under the markers. */
static int front(canvas *c, const chart_layout *l, const chart_data *d, int p)
{
    const chart_point **f = malloc(sizeof *f * (size_t)(d->npts > 0 ? d->npts : 1));
    if (!f)
        return SL_ENOMEM;
    int m = 0;
    for (int i = 0; i < d->npts; i++)
        if (d->pts[i].panel == p && d->pts[i].front && drawable(&d->pts[i]))
            f[m++] = &d->pts[i];
    qsort(f, (size_t)m, sizeof *f, by_x);
    cairo_t *cr = canvas_cairo(c);
    double dash[] = {6, 4}, px, py;
    for (int i = 0; i < m; i++) {
        chart_to_px(l, p, f[i]->x, f[i]->y, &px, &py);
        if (i == 0)
            cairo_move_to(cr, px, py);
        else
            cairo_line_to(cr, px, py);
    }
    canvas_colour(c, FRONT_GREY);
    cairo_set_line_width(cr, 1.5);
    cairo_set_dash(cr, dash, 2, 0);
    cairo_stroke(cr);
    cairo_set_dash(cr, NULL, 0, 0);
    free(f);
    return SL_OK;
}

static void legend(canvas *c, const chart_layout *l, const chart_data *d)
{
    cairo_t *cr = canvas_cairo(c);
    for (int i = 0; i < d->nseries; i++) {
        marker(c, l->legend_x[i], l->legend_y[i], &d->series[i], MARKER_R);
        canvas_colour(c, INK);
        canvas_text(c, l->legend_x[i] + MARKER_R + 8, l->legend_y[i] + TEXT_PX * 0.35,
                    d->series[i].name ? d->series[i].name : "", TEXT_PX, 0, CANVAS_LEFT);
    }
    if (!d->front_name)
        return;
    int i = d->nseries;
    double dash[] = {6, 4};
    canvas_colour(c, FRONT_GREY);
    cairo_set_line_width(cr, 1.5);
    cairo_set_dash(cr, dash, 2, 0);
    cairo_move_to(cr, l->legend_x[i] - MARKER_R - 4, l->legend_y[i] + 0.5);
    cairo_line_to(cr, l->legend_x[i] + MARKER_R + 4, l->legend_y[i] + 0.5);
    cairo_stroke(cr);
    cairo_set_dash(cr, NULL, 0, 0);
    canvas_colour(c, INK);
    canvas_text(c, l->legend_x[i] + MARKER_R + 8, l->legend_y[i] + TEXT_PX * 0.35,
                d->front_name, TEXT_PX, 0, CANVAS_LEFT);
}

static int draw(canvas *c, const chart_layout *l, const chart_data *d, sl_err *err)
{
    for (int p = 0; p < d->npanels; p++) {
        axes(c, l, p, d);
        if (front(c, l, d, p) != SL_OK)
            return sl_seterr(err, SL_ENOMEM, "chart: out of memory");
        for (int i = 0; i < d->npts; i++) {
            const chart_point *q = &d->pts[i];
            double px, py;
            if (q->panel != p || !drawable(q) || q->series < 0 || q->series >= d->nseries)
                continue;
            chart_to_px(l, p, q->x, q->y, &px, &py);
            marker(c, px, py, &d->series[q->series], MARKER_R);
        }
    }
    legend(c, l, d);
    return SL_OK;
}

int chart_write_png(const char *path, const chart_data *d, sl_err *err)
{
    chart_layout l;
    int rc = chart_layout_of(d, &l, err);
    if (rc != SL_OK)
        return rc;
    canvas *c = canvas_new(l.width, l.height, err);
    if (!c)
        return err ? err->code : SL_ENOMEM;
    rc = draw(c, &l, d, err);
    if (rc == SL_OK)
        rc = canvas_write_png(c, path, err);
    canvas_free(c);
    return rc;
}
