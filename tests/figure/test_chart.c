/* test_chart.c - the bench chart read back: a legend entry per series,
 * every series' marker different from every other's (colour, shape or
 * fill), points drawn where the log axes put them, the front line. */
#include <math.h>
#include <unistd.h>

#include "chart.h"
#include "png_rgb.h"
#include "tcheck.h"

/* The bench's kind of sweep: three methods, 18 and 180 projections (and
 * direct's R2), with and without a reference. */
static const chart_series series[] = {
    {"direct R2=18", 0, 0, 0},       {"direct R2=18 +ref", 0, 0, 1},
    {"tsm 18", 1, 0, 0},             {"tsm 180", 1, 1, 0},
    {"tsm 180 +ref", 1, 1, 1},       {"tsm-fourier 18", 2, 0, 0},
    {"tsm-fourier 180", 2, 1, 0},    {"direct R2=28", 0, 1, 0}};
#define NS ((int)(sizeof series / sizeof series[0]))

static int close_to(const unsigned char *p, unsigned rgb, int tol)
{
    return abs(p[0] - (int)(rgb >> 16 & 255)) <= tol && abs(p[1] - (int)(rgb >> 8 & 255)) <= tol &&
           abs(p[2] - (int)(rgb & 255)) <= tol;
}

/* Series i's point in panel p: spread over two decades in time and error. */
static chart_point point(int i, int p)
{
    return (chart_point){0.05 * pow(1.8, i), 0.02 * pow(1.6, NS - i) * (1 + p), i, p, i % 3 == 0};
}

static int write_chart(const char *path, chart_layout *l, chart_point *pts, sl_err *e)
{
    static const char *const panels[] = {"binary 6/1 128x128", "six-star 128x128"};
    for (int p = 0; p < 2; p++)
        for (int i = 0; i < NS; i++)
            pts[p * NS + i] = point(i, p);
    chart_data d = {pts, 2 * NS, series, NS, panels, 2, "run time (s)", "error 1 - c",
                    "Pareto front"};
    return chart_write_png(path, &d, e) == SL_OK && chart_layout_of(&d, l, e) == SL_OK;
}

/* The marker of legend entry i as a (2r+5)^2 mask: 0 white, 1 its colour,
 * 2 anything else (text, outline blending). */
static void legend_mask(const rgb_image *im, const chart_layout *l, int i, unsigned char *m)
{
    int r = l->marker_r + 2, n = 0;
    for (int dy = -r; dy <= r; dy++)
        for (int dx = -r; dx <= r; dx++) {
            const unsigned char *p = png_rgb_at(im, l->legend_x[i] + dx, l->legend_y[i] + dy);
            m[n++] = png_rgb_white(im, l->legend_x[i] + dx, l->legend_y[i] + dy) ? 0
                   : close_to(p, chart_colour(series[i].colour), 40) ? 1 : 2;
        }
}

TEST(every_series_has_its_own_legend_marker)
{
    char path[128];
    snprintf(path, sizeof path, "/tmp/test_chart_%ld.png", (long)getpid());
    chart_layout l;
    chart_point pts[2 * NS];
    sl_err e = {0};
    rgb_image im = {0};
    int ok = write_chart(path, &l, pts, &e) && png_rgb_read(path, &im);
    unlink(path);
    CHECK(ok, "%s", e.msg);
    enum { SIDE = 2 * (6 + 2) + 1 };
    static unsigned char mask[NS][SIDE * SIDE];
    int bad_colour = -1, text_missing = -1, same_a = -1, same_b = -1;
    for (int i = 0; i < NS; i++) {
        legend_mask(&im, &l, i, mask[i]);
        int coloured = 0, ink = 0;
        for (int k = 0; k < SIDE * SIDE; k++)
            coloured += mask[i][k] == 1;
        for (int y = l.legend_y[i] - 8; y <= l.legend_y[i] + 6; y++)
            for (int x = l.legend_x[i] + l.marker_r + 8; x < l.legend_x[i] + 120; x++)
                ink += png_rgb_dark(&im, x, y);
        if (coloured < 10 && bad_colour < 0)
            bad_colour = i;
        if (ink < 20 && text_missing < 0)
            text_missing = i;
    }
    /* pairs: differ in colour (the palette's), or in 12+ mask pixels */
    for (int a = 0; a < NS && same_a < 0; a++)
        for (int b = a + 1; b < NS && same_a < 0; b++) {
            int diff = 0;
            for (int k = 0; k < SIDE * SIDE; k++)
                diff += (mask[a][k] != 0) != (mask[b][k] != 0) ||
                        (mask[a][k] == 1) != (mask[b][k] == 1);
            if (chart_colour(series[a].colour) == chart_colour(series[b].colour) && diff < 12)
                same_a = a, same_b = b;
        }
    int hollow_white = png_rgb_white(&im, l.legend_x[0], l.legend_y[0]);
    int filled_colour = close_to(png_rgb_at(&im, l.legend_x[1], l.legend_y[1]),
                                 chart_colour(series[1].colour), 10);
    free(im.px);
    CHECK(im.w == l.width && im.h == l.height, "PNG %d x %d, layout %d x %d", im.w, im.h,
          l.width, l.height);
    CHECK(bad_colour < 0, "legend marker of '%s' lacks its colour", series[bad_colour].name);
    CHECK(text_missing < 0, "no legend text for '%s'", series[text_missing].name);
    CHECK(same_a < 0, "'%s' and '%s' look the same", series[same_a].name, series[same_b].name);
    CHECK(hollow_white && filled_colour, "hollow centre white %d, filled centre coloured %d",
          hollow_white, filled_colour);
}

TEST(points_sit_where_the_log_axes_put_them)
{
    char path[128];
    snprintf(path, sizeof path, "/tmp/test_chart_pts_%ld.png", (long)getpid());
    chart_layout l;
    chart_point pts[2 * NS];
    sl_err e = {0};
    rgb_image im = {0};
    int ok = write_chart(path, &l, pts, &e) && png_rgb_read(path, &im);
    unlink(path);
    CHECK(ok, "%s", e.msg);
    int missing = -1;
    for (int k = 0; k < 2 * NS && missing < 0; k++) {
        double px, py;
        chart_to_px(&l, pts[k].panel, pts[k].x, pts[k].y, &px, &py);
        int hit = 0;
        const chart_series *s = &series[pts[k].series];
        for (int dy = -l.marker_r; dy <= l.marker_r; dy++)
            for (int dx = -l.marker_r; dx <= l.marker_r; dx++)
                hit += close_to(png_rgb_at(&im, (int)px + dx, (int)py + dy), chart_colour(s->colour), 30);
        if (hit < 6)
            missing = k;
    }
    /* decades: 0.05 .. 0.05 x 1.8^7 = 3.1 s -> 0.01 .. 10 */
    int axes_ok = l.lx0 == -2 && l.lx1 == 1;
    double ax, ay, bx, by;
    chart_to_px(&l, 0, 1.0, 1.0, &ax, &ay);
    chart_to_px(&l, 0, 10.0, 0.1, &bx, &by);
    free(im.px);
    CHECK(missing < 0, "point %d (%s at %g, %g) not drawn", missing,
          missing >= 0 ? series[pts[missing].series].name : "", missing >= 0 ? pts[missing].x : 0,
          missing >= 0 ? pts[missing].y : 0);
    CHECK(axes_ok && bx > ax && by > ay, "x decades %g..%g; 10 s right of 1 s, 0.1 below 1",
          l.lx0, l.lx1);
}

TEST(bad_counts_are_refused)
{
    chart_data d = {NULL, 0, series, 0, NULL, 1, NULL, NULL, NULL};
    sl_err e = {0};
    CHECK(chart_write_png("/tmp/never.png", &d, &e) == SL_EINVAL && strstr(e.msg, "series"),
          "no series: %s", e.msg);
}

TC_MAIN(TC_CASE(every_series_has_its_own_legend_marker),
        TC_CASE(points_sit_where_the_log_axes_put_them),
        TC_CASE(bad_counts_are_refused))
