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

static inline void gen_init(gen *g, int n)
{
    size_t N = (size_t)n * n;
    g->n = n;
    g->a = fftw_alloc_complex(N);
    g->b = fftw_alloc_complex(N);
    g->fa = fftw_plan_dft_2d(n, n, g->a, g->a, FFTW_FORWARD, FFTW_ESTIMATE);
    g->ba = fftw_plan_dft_2d(n, n, g->a, g->a, FFTW_BACKWARD, FFTW_ESTIMATE);
    g->fb = fftw_plan_dft_2d(n, n, g->b, g->b, FFTW_FORWARD, FFTW_ESTIMATE);
}

static inline void gen_done(gen *g)
{
    fftw_destroy_plan(g->fa);
    fftw_destroy_plan(g->ba);
    fftw_destroy_plan(g->fb);
    fftw_free(g->a);
    fftw_free(g->b);
}

#endif
