/* pipeline_stf.c - direct's modulus on a filled pupil without a reference:
 * the speckle transfer function modelled from the data's own spectral
 * ratio (spectra/stf.h) and divided out.
 *
 * Whether the pupil is filled is read from the data: the support must
 * cover the disc inside 0.8 of the cut-off, and the spectral ratio must
 * be one a filled pupil in Kolmogorov turbulence draws (the gates below).
 * Nothing is known of the telescope: the cut-off is the support's, D/r0
 * the spectral ratio's.  The correction is refused (and the plain modulus
 * kept) when the cut-off reaches past 0.5 cycles/px (coarser than
 * Nyquist: aliased power would be taken for signal), when the support is
 * under 8 px across, with fewer than 8 frames, or when the fit fails.
 * Cost, only on cubes that pass the fill gate: 0.12 s on one thread,
 * 0.08 s on two (0.03 s of it the models' screens, drawn serially), and
 * 4.7 MB on two threads; a refused fit skips the fine model's share.
 */
#include <math.h>
#include <stdlib.h>

#include "pipeline_int.h"
#include "spectra/stf.h"

/* Two gates, both measured on blind cubes.  The support's fill: filled
 * pupils 0.995-1.00 (obstructed 0.3 or not, D/r0 2.75-11, 40-100 frames,
 * 2e3 photons to noiseless); the 17-hole mask 0.30 at 10 e- read noise
 * but 0.92-0.95 at 1e5 photons or noiseless, where its patches cover the
 * disc.  So the fill alone does not tell, and the spectral ratio's fit
 * decides: rms left 0.011-0.028 on the filled pupils, 0.058-0.107 on the
 * mask, whose ratio stays at 1 over a hole's own patch and then drops in
 * one step, which no D/r0 of a filled pupil draws. */
#define FILL_MIN 0.9
#define RMS_MAX 0.045
#define RC_CYC_MAX 0.5
#define NREAL 64
#define FIT_DP 32
#define FIT_NREAL 32

/* The largest |(x, y)| of the support (stf.h: hypot only where the sum
 * of squares reaches the largest so far). */
static double cut_off_cyc(const unsigned char *support, int w, int h)
{
    double rc = 0, d2max = 0;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++)
            if (support[(size_t)j * w + i]) {
                double x, y;
                stf_freq_cyc(i, j, w, h, &x, &y);
                double d2 = x * x + y * y;
                if (d2 < d2max * (1 - STF_MARGIN))
                    continue;
                rc = fmax(rc, hypot(x, y));
                d2max = fmax(d2max, d2);
            }
    return rc;
}

/* The support's share of the frequencies within 0.8 rc_cyc. */
static double support_fill(const unsigned char *support, int w, int h,
                           double rc_cyc)
{
    long in = 0, all = 0;
    double c = 0.8 * rc_cyc, c2 = c * c;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            double x, y;
            stf_freq_cyc(i, j, w, h, &x, &y);
            double d2 = x * x + y * y;
            int inside = d2 < c2 * (1 - STF_MARGIN)   ? 1
                         : d2 > c2 * (1 + STF_MARGIN) ? 0
                                                      : hypot(x, y) <= c;
            if (inside) {
                all++;
                in += support[(size_t)j * w + i] != 0;
            }
        }
    return all ? (double)in / all : 0;
}

/* D/r0 fitted to the data's spectral ratio on a coarse pupil (its 23
 * evaluations cost 83 ms at 32 px on one thread, 51 on two); 0 when the
 * fit fails or its rms says a filled pupil in Kolmogorov turbulence does
 * not describe the data (an aperture mask's noiseless cube passes the
 * fill gate and ends here: the fine model is then never drawn). */
static int stf_fit(const pipe_stf_in *in, double rc, double *d_r0)
{
    stf_model *mf = stf_model_new(FIT_DP, FIT_NREAL, in->nthreads, 0x5f7, NULL);
    int nbf = stf_model_nbins(mf);
    double *eps = mf ? malloc((size_t)nbf * sizeof *eps) : NULL, rms = 0;
    int ok = eps != NULL;
    if (ok) {
        stf_spectral_ratio(in->ps, in->le, in->w, in->h, rc, nbf, eps);
        ok = stf_model_fit(mf, eps, d_r0, &rms) == SL_OK && rms < RMS_MAX;
    }
    free(eps);
    stf_model_free(mf);
    return ok;
}

int pipe_stf_modulus(const pipe_stf_in *in, double *mod, pipeline_report *rep)
{
    int w = in->w, h = in->h;
    rep->stf_d_r0 = 0;
    double rc = cut_off_cyc(in->support, w, h), d_r0 = 0;
    rep->stf_fill = rc > 0 ? support_fill(in->support, w, h, rc) : 0;
    int side = w < h ? w : h;
    if (rep->stf_fill < FILL_MIN || rc > RC_CYC_MAX || rc * side < 8 ||
        in->nframes < 8 || !stf_fit(in, rc, &d_r0))
        return 0;
    /* The profiles on a pupil as fine as the data's cut-off. */
    int dp = (int)lround(rc * side);
    dp = dp < FIT_DP ? FIT_DP : dp > 48 ? 48 : dp;
    stf_model *m = stf_model_new(dp, NREAL, in->nthreads, 0x5f8, NULL);
    int nb = stf_model_nbins(m);
    double *stf = m ? malloc((size_t)nb * sizeof *stf) : NULL;
    double *t0 = m ? malloc((size_t)nb * sizeof *t0) : NULL;
    int ok = stf && t0 && stf_model_eval(m, d_r0, stf, NULL, t0) == SL_OK;
    if (ok) {
        stf_modulus(in->ps, w, h, rc, stf, t0, nb, mod);
        rep->stf_d_r0 = d_r0;
    }
    stf_model_free(m);
    free(stf), free(t0);
    return ok;
}
