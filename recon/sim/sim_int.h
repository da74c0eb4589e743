/* sim_int.h - the simulator's state, shared by sim.c (planning: sampling,
 * pupil, screen, object, detector) and sim_frame.c (rendering frames).
 * Not a public header. */
#ifndef SL_SIM_INT_H
#define SL_SIM_INT_H

#include <complex.h>
#include <fftw3.h>

#include "screen.h"
#include "sim.h"

#define ARCSEC_PER_RAD (180.0 * 3600.0 / M_PI)

struct sim {
    sim_opts o;
    sl_err err;
    char warning[320];
    int M, k;            /* grid size, oversampling factor */
    int win, win0;       /* pupil window size and origin in the grid */
    double pscale;       /* arcsec per output pixel */
    double p_nyq;        /* Nyquist plate scale, arcsec */
    double dx, E;        /* pupil pitch and extent, m */
    double psf_scale;    /* 1 / sum |FFT(field)|^2 */
    float *pupil;        /* win x win transmission */
    float *phase;        /* win x win, radians */
    float *truth;        /* w x h, relative flux */
    fftwf_complex *fin, *fout;   /* M x M pupil field and its FFT */
    float *psf;                  /* M x M */
    fftwf_complex *otf, *obj;    /* M x (M/2+1) */
    float *img;                  /* M x M convolved image */
    fftwf_plan p_field, p_psf, p_img;
    screen *scr;
    double ky;           /* fine rows per output row: pixel_aspect * k */
    double oy;           /* fine-row edge where output row 0 starts (A != 1) */
    double *acc;         /* w: one output row being binned (A != 1) */
    fftwf_complex *rx, *ry;  /* shift ramps along u (M/2+1) and v (M) */
    int nholes;          /* piston model: holes, and per pixel of the */
    int *hole;           /* window its hole (-1 outside the pupil) */
    double *hsum;        /* 2 nholes: phase sums and weights */
    detector *det;       /* NULL for noiseless frames */
};

/* Piston model only: label the window's pupil pixels by hole (s->hole,
 * s->hsum); SL_EINVAL for a filled aperture.  Needs the pupil made. */
int sim_make_labels(sim *s, const mask *m);

#endif
