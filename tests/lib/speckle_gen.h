/* speckle_gen.h - the FFT plumbing of the unit tests' synthetic speckle
 * frame generators (test_powspec.c, test_bispec.c): two n x n complex
 * buffers with their plans, and signed FFT frequencies.  Each test keeps
 * its own gen_frame, since they model different objects and noise. */
#ifndef SL_SPECKLE_GEN_H
#define SL_SPECKLE_GEN_H

#include <fftw3.h>

/* Signed frequency of FFT index i of n. */
static inline int sf(int i, int n) { return i <= (n - 1) / 2 ? i : i - n; }

typedef struct gen {
    int n;
    fftw_complex *a, *b;
    fftw_plan fa, ba, fb;
} gen;

void gen_init(gen *g, int n);

void gen_done(gen *g);

#endif
