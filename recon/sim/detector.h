/* detector.h - the simulator's camera: expected photons -> integer ADU.
 *
 * Input is a noiseless frame in relative flux (the scene's total flux is
 * 1); pixel i expects frame[i] * photons_per_frame photo-electrons.  Per
 * pixel, in this order:
 *   e    = Poisson(expected) + read_noise_e * N(0, 1)
 *   code = round(e / gain_e_per_adu + bias_adu), clipped to [0, full scale]
 * Full scale is saturation_adu, or 2^adc_bits - 1 when that is lower
 * (adc_bits = 0: no converter limit).  Then the defects: hot pixels are
 * stuck at hot_level_adu (NAN: full scale), dead pixels read 0.
 *
 * Defects sit at the same positions in every frame: they are drawn once
 * from the seed, distinct from each other, hot pixels first, so adding dead
 * pixels never moves a hot one.  The noise of frame k comes from its own
 * random stream (seed, k), and every pixel draws its noise even when a
 * defect overrides it: frame k is a pure function of (options, seed, k),
 * whatever the order frames are read in, and turning defects on changes
 * only the defective pixels.
 */
#ifndef SL_DETECTOR_H
#define SL_DETECTOR_H

#include <stdint.h>

#include "status.h"

/* Largest converter: float32 output holds every integer up to 2^24. */
#define DETECTOR_MAX_ADC_BITS 24

typedef struct detector_opts {
    double photons_per_frame; /* expected photo-electrons for unit flux; > 0 */
    double read_noise_e;      /* Gaussian, electrons rms */
    double gain_e_per_adu;
    double bias_adu;
    double saturation_adu;    /* clip level */
    int adc_bits;             /* 0 = no converter limit; 1..24 */
    int hot_pixels, dead_pixels;
    double hot_level_adu;     /* stuck level of hot pixels; NAN = full scale */
} detector_opts;

typedef struct detector detector;

/* 1000 photons, no read noise, gain 1, bias 0, saturation 65535, no ADC
 * limit, no defects. */
void detector_opts_defaults(detector_opts *o);
/* Validate o for a width x height sensor; SL_EINVAL naming the option. */
int detector_check(const detector_opts *o, int width, int height,
                   sl_err *err);
/* Check o and draw the defect positions from seed.  Cost: O(defects)
 * draws plus a width*height/8-byte scratch map. */
int detector_new(detector **out, const detector_opts *o, int width,
                 int height, uint64_t seed, sl_err *err);
void detector_free(detector *d);

/* Turn frame k's relative flux into ADU, in place (width*height floats).
 * No allocation. */
void detector_read(const detector *d, int k, float *frame);

/* Largest code: min(saturation, 2^adc_bits - 1). */
double detector_full_scale_adu(const detector *d);
/* Level of the hot pixels (full scale unless hot_level_adu was given). */
double detector_hot_level_adu(const detector *d);
/* Defect i (0 <= i < hot + dead): its pixel (x, y); returns 1 for hot, 0
 * for dead, -1 when i is out of range. */
int detector_defect(const detector *d, int i, int *x, int *y);

/* BITPIX for cube_writer_open that holds every code exactly: 8 for a 1..8
 * bit converter, CUBE_BITPIX_U16 for 9..16 bits, else -32 (float32). */
int detector_bitpix(const detector_opts *o);

#endif
