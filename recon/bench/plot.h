/* plot.h - a small greyscale raster canvas for charts: lines, markers and
 * 5x7 bitmap text, written as PNG through preview.h.
 *
 * Coordinates are pixels with the origin at the BOTTOM-left and +y up (the
 * image convention of seq.h; preview writes the highest y as the top row),
 * so chart code maps data to pixels without flipping.  Grey levels run from
 * 0 (black) to 1 (white); the canvas starts white.  plot_write_png stretches
 * linearly between the darkest and lightest pixel, so draw something black
 * (axes do) for the levels to come out as given.
 *
 * Text: upper-case letters, digits and " .,:;-+=()/_%<>*'" in a 5x7 font
 * (lower case is drawn as upper case; anything else as a blank), each cell
 * 6 x 8 pixels times `scale`.  Drawing clips at the canvas edge, so callers
 * need not check bounds.  Cost: O(pixels touched); one allocation in
 * plot_new.
 */
#ifndef SL_PLOT_H
#define SL_PLOT_H

#include "base/status.h"

typedef struct plot plot;

typedef enum plot_shape {
    PLOT_CIRCLE = 0,
    PLOT_SQUARE,
    PLOT_TRIANGLE,
    PLOT_DIAMOND,
    PLOT_CROSS,   /* x: never filled */
    PLOT_PLUS     /* +: never filled */
} plot_shape;

/* A white w x h canvas (16 <= w, h <= 8192); NULL with err set otherwise. */
plot *plot_new(int w, int h, sl_err *err);
void plot_free(plot *p);
int plot_width(const plot *p);
int plot_height(const plot *p);
/* Read-only pixels, w*h, pixel (x, y) at [y*w + x]. */
const float *plot_pixels(const plot *p);

void plot_pixel(plot *p, int x, int y, float grey);
/* A line of the given thickness (>= 1 px), end points included. */
void plot_line(plot *p, double x0, double y0, double x1, double y1,
               float grey, int thick);
/* A dashed line: on_px drawn, off_px skipped, along its length. */
void plot_dash(plot *p, double x0, double y0, double x1, double y1,
               float grey, int on_px, int off_px);
void plot_rect(plot *p, int x0, int y0, int x1, int y1, float grey);
/* A marker of half-size r px centred at (x, y). */
void plot_marker(plot *p, double x, double y, plot_shape shape, int filled,
                 int r, float grey);
/* Text with its bottom-left corner at (x, y); returns the width drawn. */
int plot_text(plot *p, int x, int y, const char *s, float grey, int scale);
/* The same rotated 90 degrees counter-clockwise (reads bottom to top);
 * (x, y) is the bottom-right corner of the first character. */
int plot_text_up(plot *p, int x, int y, const char *s, float grey,
                 int scale);
int plot_text_width(const char *s, int scale);
int plot_text_height(int scale);

/* Write the canvas as an 8-bit greyscale PNG (see the stretch above). */
int plot_write_png(const plot *p, const char *path, sl_err *err);

#endif
