/* detector.c - see detector.h for the model and its order of operations. */
#include "detector.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "io/cube.h"
#include "base/rng.h"

/* Random streams: frame k's noise is stream NOISE + k (a simulated cube
 * is reproducible from its SIMSEED only while this stays put); the defect
 * map has a stream far above any frame index. */
#define NOISE_STREAM 0x100000ULL
#define DEFECT_STREAM 0xDEFEC7000000ULL

struct detector {
    detector_opts o;
    int width, height;
    uint64_t seed;
    double full_scale_adu, hot_level_adu;
    int ndefects;       /* hot first, then dead */
    size_t defect[];    /* pixel indices y * width + x */
};

void detector_opts_defaults(detector_opts *o)
{
    memset(o, 0, sizeof *o);
    o->photons_per_frame = 1000;
    o->gain_e_per_adu = 1;
    o->saturation_adu = 65535;
    o->hot_level_adu = NAN;
}

static double full_scale(const detector_opts *o)
{
    double fs = o->saturation_adu;
    if (o->adc_bits > 0 && ldexp(1.0, o->adc_bits) - 1 < fs)
        fs = ldexp(1.0, o->adc_bits) - 1;
    return fs;
}

int detector_check(const detector_opts *o, int width, int height,
                   sl_err *err)
{
    if (!(o->photons_per_frame > 0 && isfinite(o->photons_per_frame)))
        return sl_seterr(err, SL_EINVAL, "detector: photons per frame %g "
                         "must be > 0 (noiseless frames are relative flux "
                         "and have no detector)", o->photons_per_frame);
    if (!(o->gain_e_per_adu > 0 && o->read_noise_e >= 0 &&
          o->saturation_adu > o->bias_adu))
        return sl_seterr(err, SL_EINVAL, "detector needs gain > 0, read noise "
                         ">= 0 and saturation above bias");
    if (o->adc_bits < 0 || o->adc_bits > DETECTOR_MAX_ADC_BITS)
        return sl_seterr(err, SL_EINVAL, "detector: ADC bits %d must lie in "
                         "[0, %d] (0 = no converter limit)", o->adc_bits,
                         DETECTOR_MAX_ADC_BITS);
    if (o->adc_bits > 0 && !(o->bias_adu < ldexp(1.0, o->adc_bits) - 1))
        return sl_seterr(err, SL_EINVAL, "detector: bias %g ADU is at or "
                         "above the %d-bit converter's full scale %g ADU",
                         o->bias_adu, o->adc_bits,
                         ldexp(1.0, o->adc_bits) - 1);
    double npix = (double)width * height;
    if (o->hot_pixels < 0 || o->dead_pixels < 0 ||
        (double)o->hot_pixels + o->dead_pixels > npix / 2)
        return sl_seterr(err, SL_EINVAL, "detector: %d hot and %d dead "
                         "pixels: each must be >= 0 and together at most "
                         "half of the %dx%d frame", o->hot_pixels,
                         o->dead_pixels, width, height);
    double fs = full_scale(o);
    if (!isnan(o->hot_level_adu) &&
        !(o->hot_level_adu >= 0 && o->hot_level_adu <= fs))
        return sl_seterr(err, SL_EINVAL, "detector: hot pixel level %g ADU "
                         "must lie in [0, %g] (the full scale)",
                         o->hot_level_adu, fs);
    return SL_OK;
}

/* Distinct uniform positions by rejection against a bit map: at most half
 * the frame is drawn (detector_check), so each draw needs < 2 tries on
 * average. */
static int draw_defects(detector *d, uint64_t seed, sl_err *err)
{
    size_t n = (size_t)d->width * d->height;
    unsigned char *taken = calloc(n / 8 + 1, 1);
    if (!taken)
        return sl_seterr(err, SL_ENOMEM, "detector: out of memory for the "
                         "defect map");
    rng r;
    rng_init(&r, seed, DEFECT_STREAM);
    for (int i = 0; i < d->ndefects; i++) {
        size_t p;
        do {
            p = (size_t)(rng_uniform(&r) * (double)n);
        } while (p >= n || (taken[p / 8] >> (p % 8) & 1));
        taken[p / 8] |= (unsigned char)(1u << (p % 8));
        d->defect[i] = p;
    }
    free(taken);
    return SL_OK;
}

int detector_new(detector **out, const detector_opts *o, int width,
                 int height, uint64_t seed, sl_err *err)
{
    *out = NULL;
    if (width < 1 || height < 1)
        return sl_seterr(err, SL_EINVAL, "detector: sensor %dx%d is empty",
                         width, height);
    int rc = detector_check(o, width, height, err);
    if (rc != SL_OK)
        return rc;
    int nd = o->hot_pixels + o->dead_pixels;
    detector *d = calloc(1, sizeof *d + (size_t)nd * sizeof(size_t));
    if (!d)
        return sl_seterr(err, SL_ENOMEM, "detector: out of memory");
    d->o = *o;
    d->width = width;
    d->height = height;
    d->seed = seed;
    d->ndefects = nd;
    d->full_scale_adu = full_scale(o);
    /* Codes are integers: a stuck level is one too. */
    d->hot_level_adu = isnan(o->hot_level_adu) ? d->full_scale_adu
                                               : nearbyint(o->hot_level_adu);
    if ((rc = draw_defects(d, seed, err)) != SL_OK) {
        free(d);
        return rc;
    }
    *out = d;
    return SL_OK;
}

void detector_free(detector *d)
{
    free(d);
}

void detector_read(const detector *d, int k, float *frame)
{
    const detector_opts *o = &d->o;
    rng r;
    rng_init(&r, d->seed, NOISE_STREAM + (uint64_t)k);
    size_t n = (size_t)d->width * d->height;
    for (size_t i = 0; i < n; i++) {
        double lam = frame[i] > 0 ? frame[i] * o->photons_per_frame : 0;
        double e = (double)rng_poisson(&r, lam);
        if (o->read_noise_e > 0)
            e += o->read_noise_e * rng_normal(&r);
        double adu = nearbyint(e / o->gain_e_per_adu + o->bias_adu);
        if (adu < 0)
            adu = 0;
        if (adu > d->full_scale_adu)
            adu = d->full_scale_adu;
        frame[i] = (float)adu;
    }
    for (int i = 0; i < d->ndefects; i++)
        frame[d->defect[i]] = i < o->hot_pixels ? (float)d->hot_level_adu
                                                : 0.0f;
}

double detector_full_scale_adu(const detector *d) { return d->full_scale_adu; }
double detector_hot_level_adu(const detector *d) { return d->hot_level_adu; }

int detector_defect(const detector *d, int i, int *x, int *y)
{
    if (i < 0 || i >= d->ndefects)
        return -1;
    *x = (int)(d->defect[i] % (size_t)d->width);
    *y = (int)(d->defect[i] / (size_t)d->width);
    return i < d->o.hot_pixels;
}

int detector_bitpix(const detector_opts *o)
{
    if (!(o->photons_per_frame > 0) || o->adc_bits <= 0 || o->adc_bits > 16)
        return -32;
    return o->adc_bits <= 8 ? 8 : CUBE_BITPIX_U16;
}
