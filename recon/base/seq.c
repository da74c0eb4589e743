/* seq.c - see seq.h. */
#include "seq.h"

#include <assert.h>
#include <stdint.h>
#include <stdlib.h>

seq *seq_new(int width, int height, int nframes)
{
    if (width <= 0 || height <= 0 || nframes <= 0)
        return NULL;
    size_t npix = (size_t)width * (size_t)height;
    if ((size_t)nframes > SIZE_MAX / sizeof(float) / npix)
        return NULL;
    seq *s = malloc(sizeof *s);
    if (!s)
        return NULL;
    s->data = calloc(npix * (size_t)nframes, sizeof(float));
    if (!s->data) {
        free(s);
        return NULL;
    }
    s->width = width;
    s->height = height;
    s->nframes = nframes;
    return s;
}

void seq_free(seq *s)
{
    if (!s)
        return;
    free(s->data);
    free(s);
}

size_t seq_frame_pixels(const seq *s)
{
    return (size_t)s->width * (size_t)s->height;
}

float *seq_frame(const seq *s, int k)
{
    assert(k >= 0 && k < s->nframes);
    return s->data + (size_t)k * seq_frame_pixels(s);
}
