/* powspec.h - Labeyrie speckle interferometry: the mean power spectrum of
 * a frame stream, its photon bias, the object's Fourier modulus and the
 * measured Fourier support.
 *
 * Spectra are full w*h planes of doubles in FFT order (frequency (p, q)
 * at index (q mod h)*w + (p mod w), DC at 0, no fftshift), forward FFTW
 * sign exp(-2 pi i (p x/w + q y/h)).  "Normalised radius" rho of (p, q) is
 * hypot(p/(w/2), q/(h/2)): 1 is Nyquist along either axis, so the corners
 * rho > 1 lie beyond any pupil that is Nyquist-sampled (pupil diameter
 * D/lambda <= 1/(2 px)) and hold nothing but noise.  Sampling coarser than
 * Nyquist aliases speckle into the corners: the floor estimate is then
 * biased high, use photon bias instead.
 */
#ifndef SL_POWSPEC_H
#define SL_POWSPEC_H

#include <complex.h>

#include "status.h"

enum { POWSPEC_WIN_NONE = 0, POWSPEC_WIN_HANN = 1, POWSPEC_WIN_TUKEY = 2 };
enum {
    POWSPEC_BIAS_NONE = 0,
    /* Frames are photon counts times a gain: frame ADU = g * counts with
     * g = adu_per_photon.  Poisson noise adds to |FFT(w I)|^2 a flat
     * g * sum_x w(x)^2 I(x) per frame (= N photons when g = 1 and no
     * window); it is computed from each frame and subtracted, and so is
     * the read noise's flat rn^2 sum_x w(x)^2 (rn = read_noise_adu). */
    POWSPEC_BIAS_PHOTON = 1,
    /* Estimated: the mean of the mean power spectrum over rho > floor_rho
     * (white noise of any origin: photons, read noise), subtracted; only
     * beyond 1.2 floor_rho when that part is 10 % lower (speckle aliased
     * into the corners). */
    POWSPEC_BIAS_FLOOR = 2
};

typedef struct powspec_opts {
    int window;            /* POWSPEC_WIN_*; apodises each frame */
    double tukey_alpha;    /* tapered fraction for TUKEY (0 none, 1 Hann) */
    int bias;              /* POWSPEC_BIAS_* */
    double adu_per_photon; /* gain g for POWSPEC_BIAS_PHOTON (> 0) */
    double read_noise_adu; /* Gaussian read noise per pixel, ADU rms
                            * (POWSPEC_BIAS_PHOTON; >= 0, default 0) */
    double floor_rho;      /* floor region rho > floor_rho (default 1.0) */
    int measure;           /* 1: FFTW_MEASURE (default), 0: ESTIMATE */
    int aligned;           /* 1: also the aligned mean spectrum (default 0) */
    int nthreads;          /* threads for the frames' transforms (0, 1: the
                            * caller's alone, each frame summed as it
                            * comes); the sums are the same bits on any
                            * count (powspec_frames.c) */
} powspec_opts;

void powspec_opts_defaults(powspec_opts *o);

typedef struct powspec powspec;

/* Plans, accumulators and frame slots for w x h frames (the only
 * allocation).  Frames are summed as they come with one thread; with
 * more, up to POWSPEC_SLOTS are staged and transformed together, and
 * every result (and powspec_partial) sums the staged ones first. */
powspec *powspec_new(int w, int h, const powspec_opts *o, sl_err *err);
void powspec_free(powspec *p);
const char *powspec_errmsg(const powspec *p);

/* Accumulate one frame (w*h floats): |FFT(win * frame)|^2 in double, the
 * frame's flux, its photon bias and its FFT.  SL_EDATA on NaN/Inf. */
int powspec_add(powspec *p, const float *frame);
int powspec_nframes(const powspec *p);

/* Mean power spectrum minus the bias of the chosen mode (may be < 0 where
 * the signal is below the noise).  ps: w*h, FFT order. */
int powspec_result(powspec *p, double *ps);
/* The constant subtracted by powspec_result (0 for BIAS_NONE). */
double powspec_bias(powspec *p);
/* Mean of sum(frame) over the frames (no window). */
double powspec_mean_flux(powspec *p);
/* The detector's gain (ADU per photon) from the data alone, for frames
 * whose noise is photon noise plus white noise of white_adu rms per
 * pixel (read noise, sky, quantisation: the sky's temporal rms): the
 * measured floor (BIAS_FLOOR) is g sum(w^2 frame) + white^2 sum w^2, the
 * photon-transfer relation read in the Fourier domain.  SL_EDATA (and 0)
 * when the floor cannot say: another bias mode, speckle reaching the
 * floor's region (sampling coarser than Nyquist), no flux, or white
 * noise owning over 80 % of the floor. */
int powspec_floor_gain(powspec *p, double white_adu, double *adu_per_photon);
/* Mean of the frames' FFTs (windowed), w*h, FFT order. */
int powspec_mean_ft(powspec *p, double complex *ft);

/* With opts.aligned: |mean of the frames' spectra, each moved to its
 * first-harmonic centroid|^2, less its finite-sample bias (var / (n - 1):
 * the noise's share goes too), w*h, FFT order.  Over powspec_result's
 * spectrum plus its bias it is the tilt-removed spectral ratio (stf.h).
 * SL_EINVAL without opts.aligned or with fewer than 2 frames. */
int powspec_aligned_power(powspec *p, double *le);

/* The apodisation window (separable, periodic form: pixel x of n gets
 * 0.5 (1 - cos(2 pi x / n)) for Hann; Tukey is flat except for cosine
 * tapers over the alpha/2 fraction at each end; alpha 1 = Hann, 0 = none).
 * Shared with bispec so both see the same frames.  win: w*h. */
int powspec_window(int kind, double alpha, int w, int h, float *win);

/* Object Fourier modulus, w*h.  With a point-source reference power
 * spectrum (same window and bias handling): the speckle transfer function
 * T = ps_ref / ps_ref(0) is divided out with a Wiener-type floor,
 *   |O| = sqrt( max(ps_obj, 0) / (max(T, 0) + eps_rel) ),
 * so |O(0)| ~ the object's frame flux and eps_rel (relative to T's peak,
 * which is 1; 1e-3 is a sane start) caps the gain where T -> 0.  Without a
 * reference (ps_ref NULL): |O| = sqrt(max(ps_obj, 0)), the modulus ceiling
 * of the insights note (the speckle transfer function stays in it: c caps
 * near 0.95, a binary's flux ratio is biased high). */
int powspec_modulus(const double *ps_obj, const double *ps_ref, int w, int h,
                    double eps_rel, double *modulus);

/* Where the mean power spectrum is above the noise: mask[k] = 1 where
 * ps[k] > max(floor_mean + nsigma * floor_std, rel_min * ps[0]), with the
 * floor statistics over rho > floor_rho; or, when noise_sd > 0 (the
 * standard deviation of the white noise's mean power at one frequency:
 * its level / sqrt(frames), exponential statistics), where ps[k] >
 * max(nsigma * noise_sd, rel_min * ps[0]).  The floor region's spread
 * holds speckle too when the sampling is coarser than Nyquist: at 2x it
 * left direct 4199 triples and no binary, so callers that know the noise
 * level pass it.  Nyquist rows/columns are
 * excluded, DC is always in, pixels without a 4-neighbour in the mask
 * (isolated noise spikes) are dropped; the mask is point-symmetric because
 * ps is.  rcut_px (may be NULL) gets the largest hypot(p, q) in the mask.
 * Typical: nsigma 5, rel_min 1e-6, floor_rho 1. */
int powspec_support(const double *ps, int w, int h, double nsigma,
                    double rel_min, double floor_rho, double noise_sd,
                    unsigned char *mask, double *rcut_px);

/* The sums behind the result, as flat doubles (the frame count among
 * them), for a sequence split over processes: powspec_sums writes them to
 * buf (NULL: none) and returns how many; powspec_partial_load replaces this
 * handle's with buf's, e.g. the element-wise sum over every part. */
size_t powspec_partial(powspec *p, double *buf);
void powspec_partial_load(powspec *p, const double *buf);

#endif
