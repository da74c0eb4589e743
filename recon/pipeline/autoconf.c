/* autoconf.c - see autoconf.h.
 *
 * THE MODEL.  For a candidate configuration (method, crop level, TSM
 * projections N, TSM inverse, TSM cut-off) on a probed scene it predicts
 * the error 1 - c against the cophased image and the CPU time; the choice
 * is the cheapest candidate whose predicted error is <= the target.
 *
 * Error = floor + angular term + crop term.
 *  - floor, what a method reaches with every angle (phase recovery and
 *    the sqrt(<|I|^2>) modulus ceiling): linear in F, the fraction of the
 *    probe's power spectrum (DC excluded) above 0.04 cycles/px - fine
 *    structure, which the modulus ceiling and the phase errors hurt; a
 *    smooth object has F ~ 0 and every method reaches 1 - c ~ 0.005:
 *        tsm-fourier, FBP    0.035 + 0.171 F
 *        tsm-fourier, ITER   0.030 + 0.181 F
 *        tsm (spatial)       as FBP + 0.01 (bilinear rays)
 *        direct              0.020 + 0.084 F + 0.5 / SNR^2
 *    The intercepts are the least-squares ones plus the largest residual
 *    (below), so that the prediction errs high.  The direct method's SNR
 *    term: at 1000 photons/frame (SNR 2.1) its support shrinks to the
 *    splodges above the noise and 1 - c rises from 0.05 to 0.14-0.16,
 *    while TSM's does not (0.08).
 *  - angular term, TSM only: the power beyond the frequency f_N at which N
 *    projections still sample the spectrum of an image of diameter D
 *    (the arc between slices, pi f / N, must stay below 1 / D), i.e.
 *        P_out(f_N) = (pcum(f_c) - pcum(f_N)) / pcum(f_c),  f_N = N / (pi D')
 *    with f_c the cut-off and pcum the probe's cumulative power profile:
 *        FBP   1.20 P_out, D' = 0.40 x crop side: filtered back projection
 *              with few angles streaks over the whole crop, and the TSM
 *              image (with its seeing pedestal) fills the crop;
 *        ITER  0.55 P_out, D' = 0.34 (D + 0.25 x crop side), D the
 *              measured extent (the autocorrelation's): the non-negative
 *              iterative inverse confines the streaks near the object.
 *    (alpha and D' fitted with under-prediction weighted 25x (FBP) and
 *    9x (ITER): the choice must meet the target, so the model should err
 *    high.)
 *  - crop term: the tight crop (probe level 1) costs TSM +0.03 (the
 *    binary's floor rises by 0.016 and its angular term by up to 0.03
 *    more; point and six-star lose nothing) and direct +0.003.
 * Calibration (bench, 200^2, 100 frames, 17-hole mask, Nyquist unless
 * noted; loose crop side 90-96; 1 - c measured, FBP / ITER floor at
 * N >= 96, direct):
 *        scene              F      D    SNR    FBP     ITER    direct
 *        binary 6/1       0.441  37.1  1315   0.109   0.105   0.052
 *        six-star         0.247  41.9  1624   0.078   0.073   0.041
 *        point            0.522  31.1  1200   0.090   0.091   0.051
 *        extended         0.001  42.4   1e6   0.006   0.004   0.003
 *        binary, 1000 ph  0.454  38.3   2.1   0.083   0.078   0.143
 *        binary, 2x oversampled 0.458 70.3 1e6 0.101 0.111   0.051
 *    angular terms (1 - c minus the floor) of the binary on the loose
 *    crop, FBP at N = 8, 16, 32, 64: 0.45, 0.32, 0.18, 0.02 (model 0.53,
 *    0.44, 0.23, 0.00), on the whole 200^2 frame at 16, 32, 64, 96: 0.49,
 *    0.36, 0.20, 0.11 (model 0.53, 0.46, 0.28, 0.10); ITER on the crop at
 *    8, 12, 16, 24: 0.19, 0.13, 0.09, 0.02 (model 0.21, 0.17, 0.13, 0.05),
 *    on the frame at 16, 24, 32, 48: 0.14, 0.07, 0.05, 0.00 (model 0.18,
 *    0.12, 0.06, 0.00).  Over 144 points per inverse (6 scenes x 2 crops
 *    x N = 8..180, 4 scenes on the whole frame) the rms residual is 0.064
 *    (FBP, mostly over-predicted; 10 points under by more than 0.03) and
 *    0.020 (ITER; 4 points).
 *
 * Cost, CPU seconds on the bench machine (2 cores, shared), F frames of
 * w x h, crop C x C, kappa = cut-off / Nyquist:
 *        all        9e-9 F w h + 0.005  (read, clean, probe)
 *        TSM-F      + F C^2 (6.6e-9 + 3.9e-10 N kappa^2)   [+ ITER:
 *                     4.5e-8 N C^2 + 0.002]
 *        TSM        + F C^2 (6.6e-9 + 5e-9 N) + 7.5e-6 C^2 (noise transfer)
 *        direct     + F (1.5e-8 C^2 + 1.2e-11 C^4 (s / 0.658)^2)
 *    with s the support fraction (closure triangles ~ support^2 R2^2,
 *    R2 = 0.14 C).  Measured at C = 64, 90, 108, 200 and N = 12, 48, 180
 *    (binary): TSM-F FBP 0.045, 0.055, 0.072 s at C = 64 and 0.084,
 *    0.152, 0.319 s at C = 200; direct 0.059 s at C = 64, 0.12 s at 90,
 *    2.25 s at 200.  The spatial TSM is never chosen by auto: it is
 *    slower than tsm-fourier and no more accurate.
 */
#include "autoconf.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "pipeline.h"
#include "tsm/tsm.h"

static const int angle_grid[] = {8, 12, 16, 24, 32, 48, 64, 96, 128, 180};

static int crop_side(const probe_scene *sc, int level)
{
    int s = sc->crop_side[level];
    if (!s)
        return sc->width > sc->height ? sc->width : sc->height;
    return s;
}

double autoconf_cutoff(const probe_scene *sc)
{
    double f = sc->support_cyc_px;
    if (!(f > 0) || f >= 0.45)
        return 0;
    /* The cut-off sits beyond the support by 8% + 4 bins of the shortest
     * projection, so that TSM's floor shells (the outer J/16) hold noise
     * only; measured on a 2x oversampled binary (support 0.248): cut-off
     * 0.29, the same image (1 - c 0.1019 both), CPU 0.30 -> 0.18 s. */
    int ns = crop_side(sc, 0);
    ns += ns & 1;
    double cut = (ceil(1.08 * f * ns) + 4) / ns;
    return cut >= 0.45 ? 0 : cut;
}

/* Cumulative power below f cycles/px, interpolated in the profile. */
static double pcum_at(const probe_scene *sc, double f)
{
    if (f >= 0.5)
        return sc->pcum[PROBE_NBIN - 1];
    double x = f / 0.5 * PROBE_NBIN - 1;
    if (x < 0)
        return 0;
    int i = (int)x;
    double fr = x - i;
    return sc->pcum[i] * (1 - fr) + sc->pcum[i + 1 < PROBE_NBIN ? i + 1 : i] * fr;
}

/* Fraction of the power (up to the cut-off) above f_N. */
static double p_out(const probe_scene *sc, double f_n, double f_c)
{
    double top = pcum_at(sc, f_c);
    if (!(top > 0) || f_n >= f_c)
        return 0;
    return fmax(0, (top - pcum_at(sc, f_n)) / top);
}

static double fine_fraction(const probe_scene *sc)
{
    double top = pcum_at(sc, 0.5);
    return top > 0 ? 1 - pcum_at(sc, 0.04) / top : 0;
}

static double predict(const probe_scene *sc, int method, int level, int nangles,
                      int inverse, double cutoff)
{
    double F = fine_fraction(sc);
    if (method == PIPE_DIRECT) {
        double snr = sc->snr > 0 ? sc->snr : 1e6;
        return 0.020 + 0.084 * F + 0.5 / (snr * snr) + (level ? 0.003 : 0);
    }
    double fc = cutoff > 0 ? cutoff : 0.5, e;
    if (inverse == TSM_INV_ITER) {
        double d = 0.34 * ((sc->extent_px > 1 ? sc->extent_px : 1) +
                           0.25 * crop_side(sc, level));
        e = 0.030 + 0.181 * F + 0.55 * p_out(sc, nangles / (M_PI * d), fc);
    } else {
        double d = 0.40 * crop_side(sc, level);
        e = 0.035 + 0.171 * F + 1.20 * p_out(sc, nangles / (M_PI * d), fc);
    }
    return e + (method == PIPE_TSM ? 0.01 : 0) + (level ? 0.03 : 0);
}

static double cost(const probe_scene *sc, int nframes, int method, int level,
                   int nangles, int inverse, double cutoff)
{
    double C = crop_side(sc, level), C2 = C * C;
    double t = 9e-9 * sc->nframes * (double)sc->width * sc->height + 0.005;
    double kap = cutoff > 0 ? cutoff / 0.5 : 1;
    if (method == PIPE_DIRECT) {
        double s = sc->support_frac / 0.658;
        return t + nframes * (1.5e-8 * C2 + 1.2e-11 * C2 * C2 * s * s);
    }
    if (method == PIPE_TSM)
        return t + nframes * C2 * (6.6e-9 + 5e-9 * nangles) + 7.5e-6 * C2;
    t += nframes * C2 * (6.6e-9 + 3.9e-10 * nangles * kap * kap);
    if (inverse == TSM_INV_ITER)
        t += 4.5e-8 * nangles * C2 + 0.002;
    return t;
}

double autoconf_error(const probe_scene *sc, int nframes, int method,
                      int nangles, double cutoff_cyc_px)
{
    (void)nframes;
    return predict(sc, method, sc->crop_level, nangles, TSM_INV_AUTO, cutoff_cyc_px);
}

double autoconf_cost(const probe_scene *sc, int nframes, int method,
                     int nangles, double cutoff_cyc_px)
{
    return cost(sc, nframes, method, sc->crop_level, nangles, TSM_INV_AUTO,
                cutoff_cyc_px);
}

/* Keep the better of *best and a candidate: meeting the target first,
 * then cheaper; when neither meets it, the smaller error. */
static void consider(autoconf_choice *best, const autoconf_choice *c)
{
    int better = !best->chosen ||
                 (c->meets && !best->meets) ||
                 (c->meets && best->meets && c->pred_cost < best->pred_cost) ||
                 (!c->meets && !best->meets && c->pred_error < best->pred_error);
    if (better)
        *best = *c;
}

void autoconf_choose(const probe_scene *sc, int nframes, int method,
                     int angles, int nangles_fixed, int support, int crop,
                     double target, autoconf_choice *best)
{
    memset(best, 0, sizeof *best);
    if (!(target > 0))
        target = 0.1;
    int methods[2], nm = 0;
    /* Outside the calibrated domain, the safe choice: a support reaching
     * past Nyquist means aliased fringes (sampling coarser than Nyquist),
     * where TSM's angular model does not hold (2x: tsm-fourier 48
     * promised 0.084 and reached 0.17; direct 0.09). */
    if (method == PIPE_AUTO && sc->support_cyc_px >= 0.5)
        method = PIPE_DIRECT;
    if (method == PIPE_AUTO) {
        methods[nm++] = PIPE_DIRECT;
        methods[nm++] = PIPE_TSM_FOURIER;
    } else {
        methods[nm++] = method;
    }
    double cut = support ? autoconf_cutoff(sc) : 0;
    int fixed_n = nangles_fixed > 0 ? nangles_fixed : 180;
    /* Only the loose crop: the tight one cuts into the speckle cloud (its
     * edge is 3 % of the profile's peak), and on a piston-phase six-star
     * it cost direct c 0.956 -> 0.941 where the model promised 0.955. */
    for (int m = 0; m < nm; m++)
        for (int l = 0; l < 1; l++) {
            int level = crop ? l : sc->crop_level;
            int is_tsm = methods[m] != PIPE_DIRECT;
            int na = is_tsm && angles ? (int)(sizeof angle_grid / sizeof angle_grid[0]) : 1;
            int ni = is_tsm && angles && methods[m] == PIPE_TSM_FOURIER ? 2 : 1;
            for (int a = 0; a < na; a++)
                for (int i = 0; i < ni; i++) {
                    autoconf_choice c;
                    memset(&c, 0, sizeof c);
                    c.chosen = 1;
                    c.method = methods[m];
                    c.crop_level = level;
                    c.nangles = is_tsm ? (angles ? angle_grid[a] : fixed_n) : 0;
                    c.inverse = i ? TSM_INV_ITER : TSM_INV_AUTO;
                    c.cutoff_cyc_px = is_tsm ? cut : 0;
                    c.pred_error = predict(sc, c.method, level, c.nangles,
                                           c.inverse, c.cutoff_cyc_px);
                    c.pred_cost = cost(sc, nframes, c.method, level, c.nangles,
                                       c.inverse, c.cutoff_cyc_px);
                    c.meets = c.pred_error <= target;
                    consider(best, &c);
                }
        }
}

void autoconf_label(const autoconf_choice *c, char *buf, int n)
{
    if (c->method == PIPE_DIRECT)
        snprintf(buf, (size_t)n, "direct, crop level %d", c->crop_level);
    else
        snprintf(buf, (size_t)n, "%s %d %s, cut %.3g, crop level %d",
                 pipeline_method_name(c->method), c->nangles,
                 c->inverse == TSM_INV_ITER ? "iter" : "fbp",
                 c->cutoff_cyc_px > 0 ? c->cutoff_cyc_px : 0.5, c->crop_level);
}
