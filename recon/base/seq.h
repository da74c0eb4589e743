/* seq.h - a frame sequence: float32, width x height x nframes.
 *
 * Layout (the one axis convention of specklab): pixel (x, y) of frame k is
 * data[((size_t)k * height + y) * width + x].  x is the FITS NAXIS1 axis
 * (fastest), y is NAXIS2, k is NAXIS3.  On the sky +y is north and -x is
 * east (east left), so position angles are measured from +y towards -x.
 * The image centre, where reconstructions put the object, is pixel
 * (width/2, height/2), 0-based (the FFT origin after fftshift).
 */
#ifndef SL_SEQ_H
#define SL_SEQ_H

#include <stddef.h>

typedef struct seq {
    int width;     /* pixels along x (NAXIS1) */
    int height;    /* pixels along y (NAXIS2) */
    int nframes;   /* frames (NAXIS3) */
    float *data;   /* width*height*nframes floats, owned */
} seq;

/* Allocate a zeroed sequence; NULL on bad sizes or out of memory. */
seq *seq_new(int width, int height, int nframes);
void seq_free(seq *s);
/* Pointer to frame k (no bounds check beyond an assert). */
float *seq_frame(const seq *s, int k);
size_t seq_frame_pixels(const seq *s);

#endif
