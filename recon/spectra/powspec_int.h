/* powspec_int.h - the power-spectrum handle's insides, shared by
 * powspec.c (options, results) and powspec_frames.c (frames in: staging,
 * transforms on threads, sums).  Not a public header. */
#ifndef SL_POWSPEC_INT_H
#define SL_POWSPEC_INT_H

#include <complex.h>
#include <fftw3.h>

#include "base/slotpipe.h"
#include "base/tpool.h"
#include "powspec.h"

/* Frames staged per group before their transforms run together on the
 * handle's threads: its thread count within 4..POWSPEC_SLOTS (with one
 * thread: 1).  Two groups: one fills while the other's job runs
 * (powspec_frames.c).  Each slot costs 12 w h bytes (16 w h with
 * opts.aligned's ramps, which are small). */
#define POWSPEC_SLOTS 8

struct powspec {
    int w, h, wc;         /* wc = w/2 + 1 columns of the half plane */
    powspec_opts o;
    float *win;           /* w*h window or NULL */
    float *in;            /* 2 ns slots of npad floats: windowed frames */
    fftwf_complex *out;   /* 2 ns slots of nhp: their spectra */
    size_t npad, nhp;     /* slot strides, 64-byte multiples (the plan's
                             alignment holds in every slot) */
    int ns;               /* slots per group (slotpipe.h: 2 ns slots) */
    slotpipe *pipe;       /* the slots' pipeline (powspec_frames.c) */
    int nadded;           /* frames added: summed, in a job or staged */
    double *sflux, *sw2;  /* per slot: the frame's flux, sum w^2 frame */
    double complex *ex, *ey; /* per slot: wc and h alignment ramps */
    tpool *pool;          /* opts.nthreads */
    fftwf_plan plan;      /* slot 0's r2c */
    double *ps;           /* h*wc sum of |F|^2 */
    double complex *ft;   /* h*wc sum of F */
    double complex *aft;  /* h*wc sum of F aligned (opts.aligned) or NULL */
    double flux, pbias;   /* sums of frame flux and photon (+ read) bias */
    double w2flux;        /* sum of sum(w^2 frame): the photon noise's share */
    double w2;            /* sum w^2: white noise of variance s^2 adds s^2 w2 */
    double rbias;         /* read-noise bias per frame: rn^2 sum w^2 */
    int n;                /* frames summed */
    sl_err err;
};

/* Transform the staged frames and add them to the sums, in frame order
 * (powspec_frames.c); every reader of the sums calls it first. */
void powspec_flush(powspec *p);
/* The slots' pipeline for p (its pool, ns); NULL when out of memory. */
slotpipe *powspec_pipe_new(powspec *p);

#endif
