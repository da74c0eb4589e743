/* png_rgb.h - the figure tests read the PNGs back: 8-bit RGB through
 * libpng's simplified API, and small helpers on the pixels. */
#ifndef SL_PNG_RGB_H
#define SL_PNG_RGB_H

#include <png.h>
#include <stdlib.h>
#include <string.h>

typedef struct rgb_image {
    int w, h;
    unsigned char *px; /* w*h*3, rows top first */
} rgb_image;

/* 1 on success; free im->px after. */
int png_rgb_read(const char *path, rgb_image *im);

const unsigned char *png_rgb_at(const rgb_image *im, int x, int y);

/* Relative luminance (0..255) of the pixel, Rec. 709 weights on the
 * 8-bit values: enough to order the colour map's entries. */
double png_rgb_luma(const rgb_image *im, int x, int y);

int png_rgb_dark(const rgb_image *im, int x, int y);

int png_rgb_white(const rgb_image *im, int x, int y);

#endif
