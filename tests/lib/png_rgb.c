/* png_rgb.c - see png_rgb.h. */
#include "png_rgb.h"

int png_rgb_read(const char *path, rgb_image *im)
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

const unsigned char *png_rgb_at(const rgb_image *im, int x, int y)
{
    static const unsigned char outside[3] = {255, 255, 255};
    if (x < 0 || y < 0 || x >= im->w || y >= im->h)
        return outside;
    return im->px + ((size_t)y * (size_t)im->w + (size_t)x) * 3;
}

double png_rgb_luma(const rgb_image *im, int x, int y)
{
    const unsigned char *p = png_rgb_at(im, x, y);
    return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
}

int png_rgb_dark(const rgb_image *im, int x, int y)
{
    const unsigned char *p = png_rgb_at(im, x, y);
    return p[0] < 80 && p[1] < 80 && p[2] < 80;
}

int png_rgb_white(const rgb_image *im, int x, int y)
{
    const unsigned char *p = png_rgb_at(im, x, y);
    return p[0] > 245 && p[1] > 245 && p[2] > 245;
}
