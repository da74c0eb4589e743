/* radon_spatial_int.h - the spatial Radon handle's insides, shared by
 * radon_spatial.c (tables, projector) and radon_backproject.c (the
 * filtered back projection).  Not a public header. */
#ifndef SL_RADON_SPATIAL_INT_H
#define SL_RADON_SPATIAL_INT_H

#include "radon_spatial.h"

#include <fftw3.h>
#include <stdint.h>

#if defined(__SSE2__) && defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>   /* SSE2 always; AVX2 in one function, if the CPU has it */
#define SP_SSE2 1
#else
#define SP_SSE2 0
#endif

enum { SP_MAX_THREADS = 16 };

typedef struct sp_line {
    int64_t x, y;             /* first point + 2 (border), 32.32 fixed */
    int32_t i0, n, o;         /* first inner index, points, outer index
                               * (indices offset by nd/2) */
} sp_line;

typedef struct sp_pass {
    int64_t ex, ey;           /* inner step e1, 32.32 fixed */
    int krow, kcol;           /* projections fed (-1: none) */
    int l0, l1;               /* its lines */
} sp_pass;

struct radon_spatial {
    int w, h, nang, ns;
    const double *cs, *sn;
    const int *xlo, *xhi;
    /* projector (NULL rp: not built) */
    int nd, npass, nline;     /* lattice indices -nd/2..nd/2 */
    int nthr, simd;           /* threads; 0 portable, 1 SSE2, 2 AVX2 */
    float *rp;                /* row pairs of the frame in a 2-pixel zero
                               * border, pw = w + 4 by h + 4 pixels:
                               * rp[2 (Y pw + X) + b] = pixel (X, Y + b) */
    sp_pass *pass;
    sp_line *line;
    float *cols;              /* nthr x (nd + 9): column sums of a pass,
                               * 8 floats of slack */
    int *bin;                 /* nd + 1: lattice index -> projection bin */
    /* FBP */
    radon_interp interp;
    int nl, up;               /* filter length 2 ns, upsampling */
    float *l_in, *u_out, *ramp;
    float *qall;              /* nang x (L + 8): filtered projections */
    float *l_spec, *u_spec;   /* interleaved complex */
    fftwf_plan l_r2c, u_c2r;
};

#endif
