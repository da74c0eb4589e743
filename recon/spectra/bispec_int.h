/* bispec_int.h - the bispectrum handle's insides, shared by bispec.c
 * (planning and the accumulation hot loop) and bispec_result.c (phases
 * and the image).  Not a public header. */
#ifndef SL_BISPEC_INT_H
#define SL_BISPEC_INT_H

#include <complex.h>
#include <fftw3.h>

#include "base/slotpipe.h"
#include "base/tpool.h"
#include "bispec.h"

/* The kernel's vector: BISPEC_LANES frames of one leg (64 bytes, one
 * AVX-512 register, two AVX2 ones); a batch is kb / BISPEC_LANES of them. */
#define BISPEC_LANES 16
/* Frame slots (in, out: 12 w h bytes each), in two groups of
 * BISPEC_GROUP: one fills (bispec_add) while a job transforms the other
 * (slotpipe.h). */
#define BISPEC_SLOTS 8
#define BISPEC_GROUP (BISPEC_SLOTS / 2)
/* Targets are visited in tiles of BISPEC_TILE x BISPEC_TILE frequencies. */
#define BISPEC_TILE 8
/* and the u2 disk's rows in segments of BISPEC_SEG entries (bispec_kernel.c) */
#define BISPEC_SEG 16
/* The kernel's work units, claimed by whichever thread is free: a fixed
 * number, so their cut does not depend on the thread count.  The last
 * unit of a batch runs on one thread while the others wait, half a unit
 * on average: at 128 units that was ~2.7 ms a batch at 512^2 x 400 on
 * two threads (a unit ~5.5 ms of CPU), and would be ~6 % of the kernel
 * on 16; at 512 a quarter of that.  Units are cut at tile starts, so at
 * small sizes many are empty (a claim is one atomic add). */
#define BISPEC_KUNITS 512
typedef float vk __attribute__((vector_size(BISPEC_LANES * sizeof(float))));

struct bispec {
    int w, h, wc;
    bispec_opts o;
    int nf;                  /* F */
    int32_t *fp, *fq;        /* signed frequency of half-plane entry j */
    int32_t *ubase;          /* lut index of u_j */
    unsigned char *seed;
    int lw, lh, pm, qm;      /* lut geometry: (2pm+1) x (2qm+1) */
    int32_t *lut;
    size_t nd;
    int32_t *doff, *dleg;    /* the u2 disk, row by row (dq = -R2..R2) */
    int32_t *drow;           /* nrow + 1: first disk entry of each row */
    int32_t *dfirst;         /* nrow x (2 R2 + 2): a row's first entry
                              * with dp >= -R2, -R2 + 1, ..., R2 + 1 */
    int nrow;
    int64_t *tstart;
    uint16_t *tk;
    int32_t *order;          /* targets in the kernel's (tiled) order */
    int32_t *sorder;         /* frequencies in the spectra's memory order */
    unsigned char *tbeg;     /* per order[] position: a tile starts there */
    int64_t nt;
    int nthr;
    tpool *pool;             /* nthr threads: graph, kernel, phases */
    int32_t *kunit;          /* BISPEC_KUNITS + 1: the kernel's work units,
                              * ranges of order[] of about equal triple
                              * counts, cut at tile starts */
    double *accd, *acc2d;    /* 2 per triple; 1 per triple */
#define BISPEC_NMAP 4
    void *map[BISPEC_NMAP];  /* acc, acc2, fb and tk (bispec_alloc_big) */
    size_t maplen[BISPEC_NMAP]; /* their bytes */
    int nmap;
    float *accf, *acc2f;
    float *fb;               /* 2F legs x (kb re + kb im) */
    int kb;                  /* frames per batch (bispec_batch) */
    int simd;                /* BISPEC_SIMD_*, never AUTO */
    int nb;                  /* frames in the current batch */
    double kernel_s;         /* wall time in bispec_flush's triple loop */
    int n;                   /* frames added */
    double *psum, *xsum;     /* per frequency: sum |F|^2, sum X */
    double w2sum, w3sum;     /* sums over frames of sum w^2 I, sum w^3 I */
    double sw2[BISPEC_SLOTS], sw3[BISPEC_SLOTS]; /* the staged frames' */
    double rw2, rw3;         /* read noise per frame: rn^2 sum w^2, sum w^3 */
    double *w2ft;            /* per frequency: (rn^2 / g) conj FFT(w^2), or NULL */
    float *win, *in, *in2;   /* BISPEC_SLOTS frames, npad floats apart */
    fftwf_complex *out, *out2; /* their transforms, nhp apart */
    size_t npad, nhp;
    int nspread;             /* frames of the batch already in fb */
    slotpipe *pipe;          /* the slots' pipeline (bispec_kernel.c) */
    fftwf_plan plan, plan2;
    double *phi, *work;
    unsigned char *known;
    int phased;
    double misfit;         /* the recursion's (phasor_solve) */
    size_t refine_used;    /* bytes the last refinement took */
    fftw_complex *cin;       /* image: h*wc half spectrum */
    double *cout;            /* image: w*h */
    fftw_plan iplan;
    size_t mem;              /* bytes allocated (persistent) */
    sl_err err;
};

/* Index of frequency (p, q) in a w x h FFT array (negative p, q wrap). */
static inline size_t bispec_fidx(int p, int q, int w, int h)
{
    return (size_t)((q % h + h) % h) * w + (size_t)((p % w + w) % w);
}

/* Zeroed, 64-byte aligned, counted in b->mem (bispec.c). */
void *bispec_alloc(bispec *b, size_t bytes);
void *bispec_alloc_unzeroed(bispec *b, size_t bytes);
/* Zeroed on first touch, 2 MB aligned, huge pages asked for when huge;
 * its pages handed back by the pool's threads at bispec_free (bigmem.h).
 * At most BISPEC_NMAP such buffers. */
void *bispec_alloc_big(bispec *b, size_t bytes, int huge);

/* Frequencies, lut, disk, triples, target order and thread ranges
 * (bispec_graph.c).  SL_ENOMEM, or SL_EDATA with the message in err. */
int bispec_build_graph(bispec *b, sl_err *err);

/* Run the triple kernel over the batch of buffered frames
 * (bispec_kernel.c). */
void bispec_flush(bispec *b);
/* The slots' pipeline for b (its pool, nf set); NULL when out of memory
 * (bispec_kernel.c). */
slotpipe *bispec_pipe_new(bispec *b);

/* One target's run (bispec_lanes.c): triples t.. of target j while
 * t < tend and the disk entry is below kend, summed over the batch's nch
 * vectors of BISPEC_LANES frames into the accumulators; returns the first
 * triple not summed. */
typedef int64_t (*bispec_run_fn)(const bispec *b, int j, int64_t t, int64_t tend,
                                 int kend, int nch);
bispec_run_fn bispec_lanes_run(int simd, int acc_float, int snr);
int bispec_simd_best(void); /* BISPEC_SIMD_*, never AUTO */

#endif
