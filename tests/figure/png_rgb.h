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
static inline int png_rgb_read(const char *path, rgb_image *im)
{
    png_image p;
    memset(&p, 0, sizeof p);
    p.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&p, path))
        return 0;
    p.format = PNG_FORMAT_RGB;
    im->px = malloc(PNG_IMAGE_SIZE(p));
    if (!im->px || !png_image_finish_read(&p, NULL, im->px, 0, NULL)) {
        png_image_free(&p);
        free(im->px);
        im->px = NULL;
        return 0;
    }
    im->w = (int)p.width;
    im->h = (int)p.height;
    return 1;
}

static inline const unsigned char *png_rgb_at(const rgb_image *im, int x, int y)
{
    static const unsigned char outside[3] = {255, 255, 255};
    if (x < 0 || y < 0 || x >= im->w || y >= im->h)
        return outside;
    return im->px + ((size_t)y * (size_t)im->w + (size_t)x) * 3;
}

/* Relative luminance (0..255) of the pixel, Rec. 709 weights on the
 * 8-bit values: enough to order the colour map's entries. */
static inline double png_rgb_luma(const rgb_image *im, int x, int y)
{
    const unsigned char *p = png_rgb_at(im, x, y);
    return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
}

static inline int png_rgb_dark(const rgb_image *im, int x, int y)
{
    const unsigned char *p = png_rgb_at(im, x, y);
    return p[0] < 80 && p[1] < 80 && p[2] < 80;
}

static inline int png_rgb_white(const rgb_image *im, int x, int y)
{
    const unsigned char *p = png_rgb_at(im, x, y);
    return p[0] > 245 && p[1] > 245 && p[2] > 245;
}

#endif
