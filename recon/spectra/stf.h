/* stf.h - the speckle transfer function (STF) of a filled circular pupil
 * through Kolmogorov turbulence, modelled, for reconstructions that have
 * no reference star.
 *
 * Without a reference the mean power spectrum is |O|^2 STF.  Through a
 * non-redundant mask the STF is nearly flat over each baseline's patch, so
 * sqrt(power) is close to the object's modulus.  Through a filled pupil it
 * is not: a seeing bump at low frequencies, then Korff's 0.435 (r0/D)^2 T0
 * (T0 the diffraction OTF), where the image wants T0.  That caps c near
 * 0.89 on a 1.1 m pupil at D/r0 5.5 whatever the phases (c 0.995 with the
 * true modulus and the reconstructed phases).  Dividing the model STF out
 * and multiplying T0 in lifts it to 0.99, and c moves by less than 0.005
 * for D/r0 off by 30 % or the cut-off off by 10 %: the correction does
 * not need either exactly.
 *
 * The model: nreal realisations of a pupil dp px across (radial bin i of
 * the profiles is rho / rho_c = i / dp, rho_c the cut-off) through unit
 * Kolmogorov screens, drawn once and scaled by (D/r0)^(5/6) per
 * evaluation (common random numbers: the fit's cost is smooth in D/r0).
 * Each realisation's transfer function is aligned on its own
 * first-harmonic centroid, as powspec_aligned_power aligns the frames, so
 * the long exposure |<T>|^2 is the tilt-removed one on both sides and
 * large-scale tilt (outer scale, telescope shake, jitter) drops out.
 *
 * D/r0 is fitted to the data's spectral ratio eps = |<I>|^2 / <|I|^2>
 * (von der Luehe 1984), from which the object cancels.  Cost, on one
 * thread and on two: 13.5 and 7 ms per evaluation at 64 realisations of
 * 48 px, 83 and 51 ms for a fit at 32 of 32 px; drawing the screens
 * (serial: one random stream) 21 ms at 64 of 48 px.  The evaluation sums
 * the realisations in 8 fixed groups, so the bits do not depend on the
 * thread count.  Memory: the screens' pupil pixels (1.4 MB at 100
 * realisations of 48 px) and the groups' sums, 8 x 24 g^2 bytes (g the
 * transform's side, ~2 dp: 1.9 MB at 48 px).
 */
#ifndef SL_STF_H
#define SL_STF_H

#include <stdint.h>

#include "status.h"

typedef struct stf_model stf_model;

/* nreal >= 8 realisations of a pupil dp px across (16 <= dp <= 128),
 * evaluated on nthreads (1..64; more than 8 run as 8) threads of the
 * model's own pool, with the same bits on any count.  Not re-entrant:
 * one evaluation at a time per model. */
stf_model *stf_model_new(int dp, int nreal, int nthreads, uint64_t seed,
                         sl_err *err);
void stf_model_free(stf_model *m);
/* Bins of each radial profile: dp + 1, bin i at rho / rho_c = i / dp. */
int stf_model_nbins(const stf_model *m);

/* Radial profiles at D/r0 (> 0): stf normalised to 1 at 0, le the aligned
 * long exposure |<T>|^2 (finite-sample bias removed), t0 the diffraction
 * OTF.  Any may be NULL. */
int stf_model_eval(stf_model *m, double d_r0, double *stf, double *le,
                   double *t0);

/* D/r0 in [1, 40] minimising the squared difference of the model's
 * le / stf to eps (nbins values, NAN where not measured) over
 * 0 < rho / rho_c <= 0.5, where the ratio carries r0; rms (may be NULL)
 * gets the rms difference left, which says whether a filled pupil in
 * Kolmogorov turbulence describes the data at all.  SL_EDATA when fewer
 * than 4 bins there are measured. */
int stf_model_fit(stf_model *m, const double *eps, double *d_r0, double *rms);

/* FFT-order pixel (i, j) of a w x h plane in cycles per pixel, the
 * frequency every data-side pass below bins by |(x, y)|. */
static inline void stf_freq_cyc(int i, int j, int w, int h, double *x, double *y)
{
    *x = (double)(i <= w / 2 ? i : i - w) / w;
    *y = (double)(j <= h / 2 ? j : j - h) / h;
}

/* hypot(x, y) is within a few ulps of sqrt(x^2 + y^2): where x^2 + y^2
 * lies further than STF_MARGIN (relative) from a threshold's square, or
 * a bin position from a half-integer, the sum of squares decides as
 * hypot would, and hypot runs only near it (a hypot per pixel in these
 * passes was ~5 ms of one thread at 512^2; the answers are the same). */
#define STF_MARGIN 1e-9

/* The data side on w x h FFT-order planes: ps the bias-free mean power
 * spectrum, le the aligned long exposure's power (same units), rc_cyc the
 * cut-off in cycles per pixel (hypot(p / w, q / h)).  eps gets nbins
 * ratios of bin means (NAN for bins without pixels or power). */
void stf_spectral_ratio(const double *ps, const double *le, int w, int h,
                        double rc_cyc, int nbins, double *eps);

/* The corrected modulus sqrt(max(ps, 0) / STF) T0 on the w x h plane,
 * profiles interpolated linearly in rho / rho_c, 0 beyond the cut-off. */
void stf_modulus(const double *ps, int w, int h, double rc_cyc,
                 const double *stf, const double *t0, int nbins,
                 double *mod);

#endif
