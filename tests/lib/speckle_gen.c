/* speckle_gen.c - see speckle_gen.h. */
#include "speckle_gen.h"

void gen_init(gen *g, int n)
{
    size_t N = (size_t)n * n;
    g->n = n;
    g->a = fftw_alloc_complex(N);
    g->b = fftw_alloc_complex(N);
    g->fa = fftw_plan_dft_2d(n, n, g->a, g->a, FFTW_FORWARD, FFTW_ESTIMATE);
    g->ba = fftw_plan_dft_2d(n, n, g->a, g->a, FFTW_BACKWARD, FFTW_ESTIMATE);
    g->fb = fftw_plan_dft_2d(n, n, g->b, g->b, FFTW_FORWARD, FFTW_ESTIMATE);
}

void gen_done(gen *g)
{
    fftw_destroy_plan(g->fa);
    fftw_destroy_plan(g->ba);
    fftw_destroy_plan(g->fb);
    fftw_free(g->a);
    fftw_free(g->b);
}
