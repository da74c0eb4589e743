/* skyfig.h - a sky image as a figure for people: the image enlarged, north
 * up and east left, with a title, a scale bar, an N/E compass and a colour
 * bar with values (cairo, written as RGB PNG).
 *
 * Zoomed (zoom, the default) to a box centred on the object, at the image
 * centre as the pipeline leaves it, that holds every pixel above the cut
 * with a quarter more room: the demo's 128 px TSM image is mostly empty
 * sky, its binary 12 px apart.  The figure says "central N x N of W x H
 * px" when it zooms; the whole image is shown when the box would be most
 * of it, and always with the "full" cut.
 *
 * Enlarged by an integer factor (the longer side at least min_display_px,
 * at most 64 x) with nearest neighbour: each image pixel is a square
 * block, so the sampling the reconstruction has is what is seen, no
 * interpolation invents smoothness, and the brightest block is the peak
 * pixel.  The PNG's image rows run from the highest y at the top; x runs
 * left to right, so -x (east) is left, as the position angle convention
 * (from +y north towards -x east) reads.
 *
 * Levels: display.h (cut, stretch) through colormap.h; non-finite pixels
 * are mid grey, a colour the map never uses.  The colour bar's values are
 * fractions of the peak when the peak is positive (a companion's level
 * reads as its flux ratio), else the image's own values.  The scale bar
 * is the longest 1, 2 or 5 x 10^n arcsec that fits in 30 % of the image's
 * width, rounded to whole screen pixels; without a plate scale it is in
 * image pixels and says that the scale is unknown.
 */
#ifndef SL_SKYFIG_H
#define SL_SKYFIG_H

#include "status.h"
#include "display.h"
#include "io/preview.h"
#include "pipeline/pipeline.h"

#define SKYFIG_TEXT_MAX 200

typedef struct skyfig_opts {
    char title[SKYFIG_TEXT_MAX];    /* e.g. "HD 123 - direct - 100 frames" */
    char subtitle[SKYFIG_TEXT_MAX]; /* a second line; "" for none */
    double plate_scale_arcsec;      /* arcsec per pixel; NAN or <= 0: unknown */
    preview_stretch stretch;        /* default asinh */
    display_cut cut;                /* default artifacts */
    int min_display_px;             /* default 512 */
    int zoom;                       /* 1 (default): crop to the object */
} skyfig_opts;

/* Where things are on the canvas (pixels, y down), for the tests and for
 * anyone marking the figure. */
typedef struct skyfig_layout {
    int width, height;              /* the PNG */
    int upscale;                    /* screen pixels per image pixel */
    int crop_x0, crop_y0, crop_w, crop_h; /* the image pixels shown */
    int img_x, img_y, img_w, img_h; /* where: image pixel (x, y) covers the
                                     * columns from img_x + (x - crop_x0) *
                                     * upscale and the rows from img_y +
                                     * (crop_y0 + crop_h - 1 - y) * upscale,
                                     * upscale of each */
    int bar_x, bar_y, bar_len_px, bar_thick_px; /* the scale bar's rectangle */
    double bar_value;               /* its length in arcsec (or image px) */
    int bar_in_arcsec;
    int compass_x, compass_y, compass_len; /* the arrows' common corner */
    int cbar_x, cbar_y, cbar_w, cbar_h;    /* the colour bar, highest at top */
} skyfig_layout;

/* Defaults: no title, scale unknown, asinh, artifacts cut, 512 px, zoom. */
void skyfig_opts_init(skyfig_opts *o);
/* Title and subtitle of a reconstruction: "NAME - METHOD - N frames" and
 * the binary's verdict when one was measured; the plate scale.  name
 * (e.g. OBJECT) may be NULL or "": the result's OBJECT, else "unnamed". */
void skyfig_opts_from_result(skyfig_opts *o, const pipeline_result *r,
                             const char *name);

/* The layout of img's figure (w x h; the zoom depends on the pixels).
 * SL_EINVAL for bad sizes, SL_EDATA when no pixel is finite. */
int skyfig_layout_of(const skyfig_opts *o, const float *img, int w, int h,
                     skyfig_layout *l, sl_err *err);
/* Draw img (w x h, pixel (x, y) at [y*w + x]) and write path.  SL_EINVAL,
 * SL_EDATA (no finite pixel), SL_ENOMEM, SL_EIO naming the path. */
int skyfig_write_png(const char *path, const float *img, int w, int h,
                     const skyfig_opts *o, sl_err *err);

#endif
