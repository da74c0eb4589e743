/* canvas.h - the figure room's drawing surface: a white RGB cairo image,
 * text in a sans-serif face, written as an 8-bit RGB PNG.
 *
 * One canvas at a time in a process: canvas_free releases cairo's and
 * fontconfig's font caches (no cairo object may be alive then).
 *
 * Coordinates are cairo's: pixels from the top-left corner, y down; a
 * pixel's centre is at (x + 0.5, y + 0.5), so a 1 px line meant to cover
 * one pixel row sits on a half-integer.  Only figure/ sees this header
 * (it hands out the cairo context); skyfig.h and chart.h keep cairo out of
 * their callers.
 */
#ifndef SL_CANVAS_H
#define SL_CANVAS_H

#include <cairo.h>

#include "status.h"

typedef struct canvas canvas;

typedef enum canvas_align {
    CANVAS_LEFT,
    CANVAS_CENTRE,
    CANVAS_RIGHT
} canvas_align;

/* A white w x h canvas (1 <= w, h <= 16384); NULL with err set. */
canvas *canvas_new(int w, int h, sl_err *err);
void canvas_free(canvas *c);
cairo_t *canvas_cairo(canvas *c);

/* Source colour 0xRRGGBB for what is drawn next. */
void canvas_colour(canvas *c, unsigned rgb);
/* Text with its baseline at y, aligned at x; size_px is the em size. */
void canvas_text(canvas *c, double x, double y, const char *s,
                 double size_px, int bold, canvas_align a);
/* The same turned 90 degrees counter-clockwise (reads bottom to top),
 * centred on (x, y). */
void canvas_text_up(canvas *c, double x, double y, const char *s,
                    double size_px);
double canvas_text_width(canvas *c, const char *s, double size_px, int bold);
/* rgb (w x h, 3 bytes a pixel, rows top first) painted at (x, y), each
 * pixel a scale x scale block (nearest neighbour: nothing interpolated). */
int canvas_image(canvas *c, const unsigned char *rgb, int w, int h, int x,
                 int y, int scale, sl_err *err);

/* Write the canvas to path; a failed write leaves no file behind. */
int canvas_write_png(canvas *c, const char *path, sl_err *err);

#endif
