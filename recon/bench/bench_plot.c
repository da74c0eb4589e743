/* bench_plot.c - bench_plot_png: the run-time / error chart (bench.h).
 *
 * Layout: panels of PANEL_W x PANEL_H pixels, up to COLS across, then a
 * legend in as many columns of LEGEND_CELL pixels as fit.
 * Inside a panel the plot box leaves room for tick labels and axis titles.
 * Both axes are log10 and shared by every panel so panels compare at a
 * glance; they span whole decades around the drawn points, at most
 * MAX_DECADES (the lowest decades are dropped, points there sit on the
 * bottom edge).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"

#define PANEL_W 480
#define PANEL_H 360
#define COLS 3
#define MAX_PANELS 12
#define MAX_DECADES 6
#define BOX_L 104  /* left margin: 6-character tick labels + y title */
#define BOX_R 16
#define BOX_B 56   /* bottom: tick labels + x title */
#define BOX_T 34   /* top: panel title */
#define LEGEND_ROW 28
#define MARKER_R 6
#define LEGEND_CELL 264 /* px per legend entry */
#define TEXT 2     /* text scale: 12 x 16 px cells */

typedef struct axes {
    int x0, y0, x1, y1;   /* plot box in canvas pixels */
    double lx0, lx1;      /* log10 range of x */
    double ly0, ly1;
} axes;

static double map(double v, double l0, double l1, int p0, int p1)
{
    double t = (log10(v) - l0) / (l1 - l0);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return p0 + t * (p1 - p0);
}

static void decade_label(int k, char *buf, size_t n)
{
    if (k >= 0 && k <= 4)
        snprintf(buf, n, "%.0f", pow(10, k));
    else if (k < 0 && k >= -4)
        snprintf(buf, n, "%.*f", -k, pow(10, k));
    else
        snprintf(buf, n, "1E%d", k);
}

/* Decade range [l0, l1] around the positive finite values; 0 if none. */
static int decades(const bench_point *p, int n, int use_x, double *l0,
                   double *l1)
{
    double lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i < n; i++) {
        double v = use_x ? p[i].time_s : p[i].err;
        if (isfinite(v) && v > 0) {
            lo = fmin(lo, v);
            hi = fmax(hi, v);
        }
    }
    if (!isfinite(lo))
        return 0;
    *l1 = ceil(log10(hi) - 1e-9);
    *l0 = floor(log10(lo) + 1e-9);
    if (*l1 <= *l0)
        *l1 = *l0 + 1;
    if (*l1 - *l0 > MAX_DECADES)
        *l0 = *l1 - MAX_DECADES;
    return 1;
}

static void draw_axes(plot *pl, const axes *a, int panel_x, const char *title)
{
    char buf[32];
    int th = plot_text_height(TEXT);
    for (int k = (int)a->lx0; k <= (int)a->lx1; k++) {
        double x = map(pow(10, k), a->lx0, a->lx1, a->x0, a->x1);
        if (k > a->lx0 && k < a->lx1)
            plot_dash(pl, x, a->y0, x, a->y1, 0.8f, 3, 4);
        plot_line(pl, x, a->y0, x, a->y0 + 8, 0, 1);
        decade_label(k, buf, sizeof buf);
        plot_text(pl, (int)x - plot_text_width(buf, TEXT) / 2,
                  a->y0 - th - 6, buf, 0, TEXT);
        for (int m = 2; m <= 9 && k < a->lx1 && a->lx1 - a->lx0 <= 4; m++) {
            double xm = map(m * pow(10, k), a->lx0, a->lx1, a->x0, a->x1);
            plot_line(pl, xm, a->y0, xm, a->y0 + 4, 0, 1);
        }
    }
    for (int k = (int)a->ly0; k <= (int)a->ly1; k++) {
        double y = map(pow(10, k), a->ly0, a->ly1, a->y0, a->y1);
        if (k > a->ly0 && k < a->ly1)
            plot_dash(pl, a->x0, y, a->x1, y, 0.8f, 3, 4);
        plot_line(pl, a->x0, y, a->x0 + 8, y, 0, 1);
        decade_label(k, buf, sizeof buf);
        plot_text(pl, a->x0 - 6 - plot_text_width(buf, TEXT),
                  (int)y - th / 2, buf, 0, TEXT);
        for (int m = 2; m <= 9 && k < a->ly1 && a->ly1 - a->ly0 <= 4; m++) {
            double ym = map(m * pow(10, k), a->ly0, a->ly1, a->y0, a->y1);
            plot_line(pl, a->x0, ym, a->x0 + 4, ym, 0, 1);
        }
    }
    plot_rect(pl, a->x0, a->y0, a->x1, a->y1, 0);
    const char *xt = "RUN TIME (S)";
    plot_text(pl, (a->x0 + a->x1 - plot_text_width(xt, TEXT)) / 2,
              a->y0 - 2 * th - 14, xt, 0, TEXT);
    const char *yt = "ERROR 1 - C";
    plot_text_up(pl, panel_x + 20,
                 (a->y0 + a->y1 - plot_text_width(yt, TEXT)) / 2, yt, 0, TEXT);
    plot_text(pl, a->x0, a->y1 + 8, title, 0, TEXT);
}

static int by_time(const void *a, const void *b)
{
    const bench_point *p = *(const bench_point *const *)a;
    const bench_point *q = *(const bench_point *const *)b;
    return (p->time_s > q->time_s) - (p->time_s < q->time_s);
}

static int drawable(const bench_point *p)
{
    return isfinite(p->time_s) && p->time_s > 0 && isfinite(p->err) &&
           p->err > 0;
}

/* The front of one panel as a connected line, in order of time. */
static int draw_front(plot *pl, const axes *a, const bench_point *p, int n,
                      int panel)
{
    const bench_point **f = malloc(sizeof *f * (size_t)(n > 0 ? n : 1));
    if (!f)
        return SL_ENOMEM;
    int m = 0;
    for (int i = 0; i < n; i++)
        if (p[i].panel == panel && p[i].front && drawable(&p[i]))
            f[m++] = &p[i];
    qsort(f, (size_t)m, sizeof *f, by_time);
    for (int i = 1; i < m; i++)
        plot_line(pl, map(f[i - 1]->time_s, a->lx0, a->lx1, a->x0, a->x1),
                  map(f[i - 1]->err, a->ly0, a->ly1, a->y0, a->y1),
                  map(f[i]->time_s, a->lx0, a->lx1, a->x0, a->x1),
                  map(f[i]->err, a->ly0, a->ly1, a->y0, a->y1), 0, 2);
    free(f);
    return SL_OK;
}

static int legend_cols(int width)
{
    int c = (width - 20) / LEGEND_CELL;
    return c < 1 ? 1 : c;
}

static void draw_legend(plot *pl, const bench_series *s, int ns, int y_top)
{
    int cols = legend_cols(plot_width(pl)), th = plot_text_height(TEXT);
    for (int i = 0; i <= ns; i++) {
        int x = 20 + (i % cols) * LEGEND_CELL;
        int y = y_top - LEGEND_ROW * (i / cols + 1) + 6;
        if (i < ns) {
            plot_marker(pl, x + 10, y + th / 2, s[i].shape, s[i].filled,
                        MARKER_R, s[i].grey);
            plot_text(pl, x + 26, y, s[i].name, 0, TEXT);
        } else {
            plot_line(pl, x, y + th / 2, x + 20, y + th / 2, 0, 2);
            plot_text(pl, x + 26, y, "PARETO FRONT", 0, TEXT);
        }
    }
}

int bench_plot_png(const char *path, const bench_point *pts, int n,
                   const bench_series *series, int nseries,
                   const char *const *panels, int npanels, sl_err *err)
{
    if (npanels < 1 || npanels > MAX_PANELS || nseries < 1 || n < 0)
        return sl_seterr(err, SL_EINVAL, "bench_plot_png: %d panels (1..%d), "
                         "%d series", npanels, MAX_PANELS, nseries);
    axes a = {0};
    if (!decades(pts, n, 1, &a.lx0, &a.lx1) ||
        !decades(pts, n, 0, &a.ly0, &a.ly1)) {
        a.lx0 = a.ly0 = -2; /* nothing to draw: empty axes */
        a.lx1 = a.ly1 = 0;
    }
    int rows = (npanels + COLS - 1) / COLS;
    int W = (npanels < COLS ? npanels : COLS) * PANEL_W;
    int lc = legend_cols(W);
    int legend_h = LEGEND_ROW * ((nseries + 1 + lc - 1) / lc) + 12;
    int H = rows * PANEL_H + legend_h;
    plot *pl = plot_new(W, H, err);
    if (!pl)
        return err ? err->code : SL_ENOMEM;
    int rc = SL_OK;
    for (int k = 0; k < npanels && rc == SL_OK; k++) {
        int px = (k % COLS) * PANEL_W;
        int py = H - (k / COLS + 1) * PANEL_H; /* rows from the top */
        a.x0 = px + BOX_L;
        a.x1 = px + PANEL_W - BOX_R;
        a.y0 = py + BOX_B;
        a.y1 = py + PANEL_H - BOX_T;
        draw_axes(pl, &a, px, panels[k]);
        if ((rc = draw_front(pl, &a, pts, n, k)) != SL_OK)
            sl_seterr(err, rc, "out of memory");
        for (int i = 0; i < n; i++) {
            const bench_point *p = &pts[i];
            if (p->panel != k || !drawable(p) || p->series < 0 ||
                p->series >= nseries)
                continue;
            const bench_series *s = &series[p->series];
            plot_marker(pl, map(p->time_s, a.lx0, a.lx1, a.x0, a.x1),
                        map(p->err, a.ly0, a.ly1, a.y0, a.y1), s->shape,
                        s->filled, MARKER_R, s->grey);
        }
    }
    if (rc == SL_OK) {
        draw_legend(pl, series, nseries, legend_h);
        rc = plot_write_png(pl, path, err);
    }
    plot_free(pl);
    return rc;
}
