/* sim.h - the speckle-frame simulator: scene x turbulent pupil -> frames.
 *
 * Physics (per frame k):
 *   field  = pupil(x) * exp(i phi_k(x))        on an M x M pupil grid
 *   PSF_k  = |FFT(field)|^2 / sum               (any pupil: mask or full)
 *   frame  = PSF_k (*) object                   (FFT convolution)
 *   phi_k(x) = Phi(x - v t_k)                   (frozen flow, t_k = k dt)
 * Phi is a Kolmogorov / von Karman screen (screen.h) much larger than the
 * pupil.  Plate scale: the pupil grid pitch is dx = lambda / (M p), so an
 * FFT pixel is p radians.  When the requested plate scale p is coarser than
 * Nyquist for the pupil's outer extent E (p > lambda / 2E) the fringes of
 * the longest baselines alias: the simulator then computes at k = ceil(p /
 * p_nyq) times finer pixels and bins k x k (what a real detector does) and
 * reports the undersampling in sim_warning().  Default plate scale: Nyquist.
 * Frames are w x h; the grid is M = k max(w, h) and frames are cropped
 * (non-square pixels: M = max(k w, ceil(A k h) + 2)).
 *
 * Non-square pixels (pixel_aspect A = height / width): the plate scale is
 * the x pitch, rows are A times taller.  The fine grid stays square; an
 * output pixel sums k fine columns and A k fine rows, the two edge rows
 * weighted by the fraction inside, so flux is conserved.  For A < 1 the
 * grid is made at least 1/A times finer, so that no output row is thinner
 * than a fine row.
 *
 * Phase model: "screen" uses the screen at every pupil pixel; "piston"
 * (hole masks only) replaces it over each hole by its mean over that hole
 * (transmission-weighted): the classic NRM model with no phase variation
 * inside a hole.  Holes are labelled once, each pupil pixel by its nearest
 * hole centre (holes never overlap).
 *
 * Pointing: the scene is displaced by (offset_x_px, offset_y_px) output
 * pixels from the frame centre plus, per frame, a Gaussian tip-tilt jitter
 * of jitter_px rms per axis drawn from (seed, k).  Both are a phase ramp
 * on the object spectrum (sub-pixel exact, circular on the fine grid), so
 * they move the scene, not the PSF: sim_psf, sim_truth and sim_cophased
 * stay centred, as reconstructions put the object at the centre.
 *
 * Photometry: without photons (photons_per_frame = 0) frames are noiseless
 * and in relative flux (the scene's total flux is 1, so a frame sums to ~1).
 * With photons P, the detector (detector.h) turns the frame into integer
 * ADU: P expected photo-electrons, Poisson, read noise, gain, bias, the
 * clip to saturation and to an ADC's 2^bits - 1, hot and dead pixels.
 *
 * Every frame is a pure function of (options, scene, mask, seed, k): frame k
 * can be rendered in any order (the fake camera asks for frame ids).
 * Cost per frame: three M x M FFTs (one complex, a real pair) plus O(M^2).
 */
#ifndef SL_SIM_H
#define SL_SIM_H

#include <stdint.h>

#include "detector.h"
#include "mask.h"
#include "scene.h"
#include "status.h"

typedef struct sim sim;

typedef struct sim_opts {
    int width, height;          /* frame size, pixels */
    int nframes;                /* frames in the sequence */
    double wavelength_m;        /* 500e-9 (paper Table 1) */
    double plate_scale_arcsec;  /* arcsec per pixel; 0 = Nyquist for the pupil */
    double r0_m;                /* Fried parameter at wavelength_m; 0.2 */
    double L0_m;                /* outer scale; INFINITY = Kolmogorov */
    double wind_mps;            /* frozen-flow speed; 10 */
    double wind_dir_deg;        /* flow direction in the pupil plane, from +x
                                   towards +y; 0 */
    double frame_interval_s;    /* time between frames; 0.01 */
    double exposure_s;          /* recorded only (frames are instantaneous) */
    int turbulence;             /* 0: no screen (cophased frames) */
    uint64_t seed;
    double photons_per_frame;   /* 0 = noiseless relative flux */
    double read_noise_e;        /* Gaussian read noise, electrons rms */
    double gain_e_per_adu;      /* electrons per ADU */
    double bias_adu;
    double saturation_adu;      /* clip level */
    /* The rest of the detector (detector.h); need photons_per_frame > 0. */
    int adc_bits;               /* 0 = no converter limit */
    int hot_pixels, dead_pixels;
    double hot_level_adu;       /* NAN = full scale */
    /* Pointing, in output pixels: within half the frame; jitter rms within
     * a quarter of its smaller side. */
    double offset_x_px, offset_y_px;
    double jitter_px;           /* per-frame tip-tilt, rms per axis; 0 */
    double pixel_aspect;        /* pixel height / width, [0.5, 2]; 1 */
    int phase_model;            /* SIM_PHASE_SCREEN (default) or _PISTON */
    unsigned fftw_flags;        /* FFTW_MEASURE by default */
} sim_opts;

enum { SIM_PHASE_SCREEN = 0, SIM_PHASE_PISTON = 1 };

void sim_opts_defaults(sim_opts *o);

/* Plans everything: pupil, screen, object spectrum, FFTW plans and buffers.
 * The mask and scene are only read during sim_new. */
int sim_new(sim **out, const sim_opts *o, const mask *m, const scene *sc,
            sl_err *err);
void sim_free(sim *s);
const char *sim_errmsg(const sim *s);

/* Render frame k (0 <= k, any order) into w*h floats.  No allocation. */
int sim_frame(sim *s, int k, float *frame);
/* The true sky on the frame grid (scene_render), relative flux. */
int sim_truth(sim *s, float *img);
/* The same pupil with no turbulence: object (*) |FT(pupil)|^2, no noise. */
int sim_cophased(sim *s, float *img);
/* The noiseless, unbinned PSF of frame k (or cophased when k < 0), M x M,
 * unit sum, centred at pixel (M/2, M/2).  For tests and the fake camera. */
int sim_psf(sim *s, int k, float *psf);

/* Where frame k's scene centre sits relative to the frame centre, output
 * pixels: the offset plus frame k's jitter.  SL_EINVAL for k < 0. */
int sim_frame_offset_px(const sim *s, int k, double *dx_px, double *dy_px);

/* Effective parameters. */
double sim_plate_scale_arcsec(const sim *s);
double sim_nyquist_arcsec(const sim *s);   /* lambda / (2 E) */
int sim_oversample(const sim *s);          /* k (1 when Nyquist or finer) */
int sim_grid(const sim *s);                /* M */
double sim_pupil_pitch_m(const sim *s);    /* dx */
double sim_pupil_extent_m(const sim *s);   /* E */
/* Undersampling warning, or "" when the sampling is adequate. */
const char *sim_warning(const sim *s);
const sim_opts *sim_options(const sim *s);
/* The detector (defect positions, full scale); NULL for noiseless frames. */
const detector *sim_detector(const sim *s);
/* BITPIX that holds the frames exactly (detector_bitpix): 8, unsigned 16
 * (CUBE_BITPIX_U16) or -32. */
int sim_output_bitpix(const sim *s);

/* Phase screen over the pupil window for frame k: a win x win square
 * (win = sim_window_px) of the pupil grid, radians; the screen itself,
 * before the piston model averages it over holes.  Frozen flow means
 * frame k+1's window is frame k's shifted by v dt / dx pixels. */
int sim_window_px(const sim *s);
int sim_phase_window(sim *s, int k, float *phase);

#endif
