/* tsm_int.h - the TSM handle's insides, shared by tsm.c (planning,
 * accumulation, bias terms) and tsm_result.c (steps 3-6: phases, modulus,
 * registration, inversion).  Not a public header. */
#ifndef SL_TSM_INT_H
#define SL_TSM_INT_H

#include <complex.h>

#include "tsm.h"
#include "tsm_accum.h"

struct tsm {
    int w, h, nang, ns, nf, np, nframes;
    tsm_opts o;
    radon *rad;
    tsm_phase *ph;
    tpool *pool;              /* threads: accumulation, phases */
    tsm_accum *acc;           /* steps (1)-(2) */
    const int *off, *len;     /* pair rows, from ph */
    float *proj;              /* nang x ns: spatial projections, results */
    /* The sums, owned by acc (tsm_accum.h); current after tsm_sync_sums(). */
    const double *bre, *bim;  /* nang x np bispectrum sums */
    const double *ps;         /* nang x nf sum |P|^2 */
    const double *mre, *mim;  /* nang x nf sum P */
    double *ref;              /* nang x nf normalised reference power */
    double *tgt;              /* nang x nf normalised target power */
    double wiener;
    int has_ref, have_result;
    double *phase;            /* nang x nf */
    double *psc;              /* nang x nf bias-corrected mean power */
    float complex *ospec;     /* nang x nf recovered spectra */
    float complex *sref;      /* nang x nf alignment references */
    double *tr;               /* nang x nf noise transfer; NULL: 1 */
    double *pw;               /* nang x nf photon part of the mean power */
    double arc, extent;       /* step 3's arc and the diameter capping it */
    sl_err err;
};

/* Add the buffered frames to the sums (their pointers are fixed). */
void tsm_sync_sums(tsm *t);
/* Mean frame sum, the photon gain g (0 unless photons are known) and the
 * white-noise level subtracted from the power (tsm.c). */
void tsm_bias_terms(const tsm *t, double *sbar, double *g, double *level);
/* Mean power at element i minus its non-photon white part. */
double tsm_photon_power(const tsm *t, size_t i, double sbar, double g, double lv);

#endif
