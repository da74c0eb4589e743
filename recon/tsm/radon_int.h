/* radon_int.h - the radon handle's insides, shared by radon.c (plans,
 * tables, 1-D transforms, the iterative inverse) and radon_slice.c (the
 * Fourier-slice forward transform and its gridding adjoint).  Not a
 * public header. */
#ifndef SL_RADON_INT_H
#define SL_RADON_INT_H

#include "radon.h"
#include "radon_spatial.h"
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct radon {
    int w, h, nang, ns, nf;
    radon_opts o;
    double *cs, *sn;          /* cos, sin per angle */
    int *xlo, *xhi;           /* per row: pixels inside the disc of nproj */
    sl_err err;
    /* Fourier slice */
    int ng, kw;
    float *deap_x, *deap_y;   /* 1/C per frame column, row */
    /* The frame fills only h of the ng grid rows, so the 2-D FFTs are done
     * by hand: 1-D row transforms on those rows only (two blocks: rows
     * y >= h/2 land at grid rows 0.., rows y < h/2 at ng - h/2..), and
     * column transforms over all nh = ng/2+1 columns.  Saves ~25%. */
    int spad, ld;             /* forward: spectrum padding, column stride */
    float *rowf;              /* forward: per frame row, deap_y (-1)^(y-h/2) */
    radon_ws *ws;             /* the handle's own forward scratch */
    float *grid_out;          /* h x ng */
    float *gspec;             /* ng x nh complex, interleaved (adjoint) */
    fftwf_plan rows_a, rows_b, cols_fwd;     /* forward, on a radon_ws */
    fftwf_plan cols_inv, irows_a, irows_b;   /* inverse (gridding) */
    /* The sample tables, in order of first tap column (radon_order_samples):
     * row i holds sample tord[i] (k*nf+j); sample s is row tpos[s]. */
    int *tx0, *ty0;           /* first tap */
    unsigned char *tconj;     /* sample taken at -k, conjugate it */
    float *twx, *twy;         /* kw weights */
    int *tord, *tpos;
    float *dens;              /* nf: gridding FBP weight, window included */
    /* 1-D */
    float *p_in;
    float *p_spec;
    fftwf_plan p_r2c, p_c2r;
    radon_spatial *sp;        /* projector and FBP (radon_spatial.c) */
    /* iterative */
    float *it_x, *it_z, *it_g;
    float complex *it_spec;
    double lip;               /* Lipschitz constant, 0 until measured */
};


/* Forward Fourier-slice scratch (see Forward layout above). */
struct radon_ws {
    float *grid;              /* h x ng: weighted frame rows, rest 0 */
    float *rows;              /* nh x ld complex: row spectra by column; the
                               * ky rows no frame row reaches stay 0 */
    float *spec;              /* (nh + 2 pad) x ld complex: padded, centred */
    /* or, from radon_ws_new_projector, the spatial path's: */
    float *sp_scratch;        /* the projector's row pairs and columns */
    float *proj;              /* nang x ns projections */
    float *p_in, *p_spec;     /* one projection and its spectrum */
};

/* i mod n in [0, n). */
static inline int radon_wrap(int i, int n) { i %= n; return i < 0 ? i + n : i; }

/* n bytes (at least 1), FFTW-aligned when fftw; *ok &= success. */
static inline void *radon_alloc(size_t n, int fftw, int *ok)
{
    void *p = fftw ? fftwf_malloc(n ? n : 1) : malloc(n ? n : 1);
    *ok &= p != NULL;
    return p;
}

/* The forward scratch's sizes, and zeroing its never-written parts. */
void radon_ws_clear(const radon *r, radon_ws *ws);
/* The sample tables, made in sample order, sorted by first tap column;
 * SL_ENOMEM. */
int radon_order_samples(radon *r);

#endif
