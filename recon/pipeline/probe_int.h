/* probe_int.h - the probe's handle, shared by probe.c (frames, quality,
 * cloud, crop) and probe_spectrum.c (the crop's power spectrum).  Not a
 * public header. */
#ifndef SL_PROBE_INT_H
#define SL_PROBE_INT_H

#include "probe.h"

struct probe {
    int w, h, ntotal, want, n;
    probe_opts o;
    float *frames;            /* want x w x h cleaned frames */
    double *flux, *sharp, *plateau; /* per probed frame, on the crop */
    int *nsat;                /* per probed frame: prep's saturated count */
    double *le;               /* w x h long exposure, after probe_finish */
    signed char *verdict;     /* ntotal: -1 not judged yet */
    int counts[PROBE_NVERDICT];
    int finished;
    probe_scene sc;
    sl_err err;
};

/* Copy the crop of frame f (row pitch w) out. */
void probe_crop_copy(const probe_scene *sc, int w, const float *f, float *out);
/* The crop's mean power spectrum: support, noise, SNR, profile, extent
 * (probe_spectrum.c). */
int probe_measure_spectrum(probe *p);

#endif
