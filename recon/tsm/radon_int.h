/* radon_int.h - the radon handle's insides, shared by radon.c (plans,
 * tables, 1-D transforms, the iterative inverse) and radon_slice.c (the
 * Fourier-slice forward transform and its gridding adjoint).  Not a
 * public header. */
#ifndef SL_RADON_INT_H
#define SL_RADON_INT_H

#include "radon.h"
#include "radon_spatial.h"
#include "base/tpool.h"
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A batch of 1-D FFTs in chunks of RADON_CHUNK transforms, so that any
 * thread can run any chunk (FFTW's new-array execute) and a single image
 * is transformed on every thread of the pool; one thread runs the chunks
 * in turn.  Chunk c starts in_step (out_step) floats after chunk 0: a
 * multiple of RADON_CHUNK elements, so every chunk has chunk 0's
 * alignment and the plans apply.  The bits of a transform do not depend
 * on which chunk or thread runs it. */
enum { RADON_CHUNK = 16, RADON_MAX_POOL = 64 };
typedef enum { RADON_R2C, RADON_C2C_FWD, RADON_C2C_INV, RADON_C2R } radon_kind;
typedef struct radon_batch {
    fftwf_plan full, tail;    /* RADON_CHUNK transforms; the last chunk's (NULL: full) */
    int shared;               /* the plans are another batch's (radon_batch_like) */
    radon_kind kind;
    int nchunk;               /* chunks of the batch's transforms */
    float *in, *out;          /* chunk 0's arrays, as planned */
    size_t in_step, out_step;
} radon_batch;

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
    /* forward, on a radon_ws: the row blocks a and b, the columns */
    radon_batch fr_a, fr_b, fc;
    /* inverse (gridding), on gspec and grid_out */
    radon_batch ic, ir_a, ir_b;
    /* the gridding by column chunk (RADON_CHUNK columns, as ic's): chunk
     * c's samples are gsamp[goff[c] .. goff[c + 1]), in sample order,
     * their frequencies gj */
    int *goff, *gsamp, *gj;
    tpool *pool;              /* radon_opts.pool, borrowed (NULL: none) */
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
    int np1;                  /* threads with 1-D scratch: 0 uses p_in, p_spec */
    float *p1_in[RADON_MAX_POOL], *p1_spec[RADON_MAX_POOL];
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

/* Plan b: count transforms of length n, element strides is and os,
 * transform distances idist and odist (in elements of the kind's input
 * and output type), on in and out; 0 when FFTW cannot.  Executing chunk
 * c on chunk 0's arrays shifted by the same offsets: radon_batch_run. */
int radon_batch_plan(radon_batch *b, radon_kind kind, int n, int count, float *in, int is,
                     int idist, float *out, int os, int odist, unsigned flags);
/* b as `like` on other arrays, sharing its plans when they apply (the
 * same transforms, and in and out of like's alignment for FFTW): 1, else
 * 0 and b untouched. */
int radon_batch_like(radon_batch *b, const radon_batch *like, float *in, float *out);
/* Chunk c of b on in and out, arrays laid out as the planned ones. */
void radon_batch_run(const radon_batch *b, int c, float *in, float *out);
void radon_batch_free(radon_batch *b);
/* Every plan of the handle, on the scratch pws and the handle's buffers;
 * 0 when FFTW cannot. */
int radon_plan_ffts(radon *r, radon_ws *pws, unsigned flags);
/* The gridding's sample lists per column chunk; SL_ENOMEM. */
int radon_grid_lists(radon *r);

/* The forward scratch's sizes, and zeroing its never-written parts. */
void radon_ws_clear(const radon *r, radon_ws *ws);
/* The sample tables, made in sample order, sorted by first tap column;
 * SL_ENOMEM. */
int radon_order_samples(radon *r);

#endif
