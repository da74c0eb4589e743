/* chart.h - log-log scatter charts in panels (the bench's run time
 * against error), drawn with cairo and written as RGB PNG.
 *
 * Each series has its own colour, marker shape and fill, so that every
 * configuration can be told apart: the caller gives a colour per family
 * (e.g. the method) and a shape per variant (e.g. 18 or 180 projections),
 * filled or hollow for a second choice (e.g. with a reference star).  The
 * colours are Okabe and Ito's palette, distinct also to colour-blind
 * readers; the shapes stay distinct in grey print.  A legend below the
 * panels has one entry per series (and one for the front lines when
 * front_name is set), in the order given.
 *
 * Both axes are log10 and shared by every panel so that panels compare at
 * a glance; they span whole decades around the drawn points, at most
 * CHART_MAX_DECADES (the lowest are dropped: points there sit on the
 * bottom edge).  Points with a non-positive or non-finite coordinate are
 * not drawn.  Each panel's front points are joined in order of x.
 */
#ifndef SL_CHART_H
#define SL_CHART_H

#include "status.h"

#define CHART_MAX_PANELS 12
#define CHART_MAX_SERIES 64
#define CHART_MAX_DECADES 6
#define CHART_NCOLOURS 8

typedef enum chart_shape {
    CHART_CIRCLE,
    CHART_SQUARE,
    CHART_TRIANGLE,
    CHART_DIAMOND,
    CHART_TRIANGLE_DOWN,
    CHART_PENTAGON,
    CHART_NSHAPES
} chart_shape;

typedef struct chart_series {
    const char *name;       /* legend text */
    int colour;             /* palette index, modulo CHART_NCOLOURS */
    int shape;              /* chart_shape, modulo CHART_NSHAPES */
    int filled;             /* 0: hollow (white inside) */
} chart_series;

typedef struct chart_point {
    double x, y;
    int series;             /* index into series */
    int panel;              /* index into panels */
    int front;              /* joined with its panel's other front points */
} chart_point;

typedef struct chart_data {
    const chart_point *pts;
    int npts;
    const chart_series *series;
    int nseries;            /* 1..CHART_MAX_SERIES */
    const char *const *panels; /* panel titles */
    int npanels;            /* 1..CHART_MAX_PANELS, 3 across */
    const char *x_title, *y_title;
    const char *front_name; /* legend text of the front lines; NULL: none */
} chart_data;

/* Where things are (pixels from the top-left, y down). */
typedef struct chart_layout {
    int width, height;
    int box_x0[CHART_MAX_PANELS], box_y0[CHART_MAX_PANELS]; /* plot boxes */
    int box_x1[CHART_MAX_PANELS], box_y1[CHART_MAX_PANELS];
    double lx0, lx1, ly0, ly1;  /* log10 ranges of the axes */
    int legend_x[CHART_MAX_SERIES + 1], legend_y[CHART_MAX_SERIES + 1];
                                /* legend marker centres; the front last */
    int marker_r;               /* marker half-size, px */
} chart_layout;

/* The palette's colour i (modulo CHART_NCOLOURS) as 0xRRGGBB. */
unsigned chart_colour(int i);
int chart_layout_of(const chart_data *d, chart_layout *l, sl_err *err);
/* Where (x, y) is drawn in panel p. */
void chart_to_px(const chart_layout *l, int p, double x, double y, double *px,
                 double *py);
/* SL_EINVAL (counts out of range), SL_ENOMEM, SL_EIO naming the path. */
int chart_write_png(const char *path, const chart_data *d, sl_err *err);

#endif
