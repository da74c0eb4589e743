/* pipeline_check.c - pipeline_opts_check and pipeline_check_data
 * (pipeline.h): the options that cannot make sense are refused with a
 * message naming the option and the value, never quietly changed.
 *
 * Why refuse rather than clamp: a clamped value reconstructs something
 * other than what was asked, and the header then records a choice the
 * user never made.  The limits are physical where they can be:
 *   - TSM projections: an object of diameter D px needs ~pi D / 2 angles
 *     (Crowther's criterion); beyond pi N for a frame of N px every angle
 *     repeats information while the memory grows with the count.  Fewer
 *     than 6 cannot sample a 2-D image at all.
 *   - the bispectrum radius |u2| is a spatial frequency: beyond half the
 *     frame it is past Nyquist.
 * The CLI calls pipeline_opts_check before reading anything (a usage
 * error); pipeline_run calls both, so the daemon gets the same answers. */
#include "pipeline.h"

#include <math.h>

#include "spectra/bispec.h"

#define MIN_ANGLES 6
#define MAX_THREADS 256
#define MAX_REFINE 10000

static int bad(sl_err *e, const char *fmt, double v, const char *why)
{
    return sl_seterr(e, SL_EINVAL, fmt, v, why);
}

/* The numbers that must be finite and at least 0 (photons may be < 0:
 * "not photon counts"). */
static int check_numbers(const pipeline_opts *o, sl_err *e)
{
    if (!isfinite(o->wiener) || o->wiener < 0)
        return bad(e, "wiener %g: %s", o->wiener,
                   "the reference regulariser is a positive number (0: default)");
    if (o->wiener > 0 && !o->ref_path)
        return bad(e, "wiener %g: %s", o->wiener,
                   "it regularises a reference; give the reference (--ref)");
    if (!isfinite(o->target_error) || o->target_error < 0 || o->target_error >= 1)
        return bad(e, "target error %g: %s", o->target_error, "1 - c lies in (0, 1)");
    if (!isfinite(o->photons_per_frame))
        return bad(e, "photons %g: %s", o->photons_per_frame, "not a number");
    if (!isfinite(o->adu_per_photon) || o->adu_per_photon < 0)
        return bad(e, "ADU per photon %g: %s", o->adu_per_photon,
                   "a gain is a positive number (0: from the header)");
    if (!isfinite(o->saturation_adu) || o->saturation_adu < 0)
        return bad(e, "saturation %g ADU: %s", o->saturation_adu,
                   "a level at least 0 (0: learnt from the data)");
    if (!isfinite(o->tukey_alpha) || o->tukey_alpha < 0 || o->tukey_alpha > 1)
        return bad(e, "Tukey alpha %g: %s", o->tukey_alpha, "a fraction in [0, 1]");
    if (!isfinite(o->cutoff_cyc_px) || o->cutoff_cyc_px < 0 || o->cutoff_cyc_px > 0.5)
        return bad(e, "cut-off %g cycles/px: %s", o->cutoff_cyc_px,
                   "beyond 0.5 is past Nyquist (0: Nyquist or measured)");
    return SL_OK;
}

int pipeline_opts_check(const pipeline_opts *o, sl_err *e)
{
    if (o->method < 0 || o->method > PIPE_AUTO)
        return sl_seterr(e, SL_EINVAL, "method %d: want direct, tsm, "
                         "tsm-fourier or auto", o->method);
    if (o->nangles != 0 && o->nangles < MIN_ANGLES)
        return sl_seterr(e, SL_EINVAL, "projections %d: fewer than %d cannot "
                         "sample a 2-D image (0: 180)", o->nangles, MIN_ANGLES);
    if (!(o->bispec_mem_mb >= 0))
        return sl_seterr(e, SL_EINVAL, "bispec memory %g MB: want a size in MB (0: %g)",
                         o->bispec_mem_mb, PIPE_BISPEC_MEM_MB);
    if (o->r2_px < 0 || o->r2_px > BISPEC_R2_MAX)
        return sl_seterr(e, SL_EINVAL, "r2 %d px: the bispectrum radius is "
                         "1..%d px (0: 0.14 x the frame)", o->r2_px, BISPEC_R2_MAX);
    if (o->nthreads < 0 || o->nthreads > MAX_THREADS)
        return sl_seterr(e, SL_EINVAL, "threads %d: want 1..%d (0: default)",
                         o->nthreads, MAX_THREADS);
    if (o->refine_iters < -1 || o->refine_iters > MAX_REFINE)
        return sl_seterr(e, SL_EINVAL, "refine %d: want -1 (automatic), 0 "
                         "(none) or up to %d passes", o->refine_iters, MAX_REFINE);
    const char *cal = o->dark_path ? "dark" : o->flat_path ? "flat"
                      : o->badpix_path ? "bad-pixel map" : NULL;
    if (cal && !o->prep)
        return sl_seterr(e, SL_EINVAL, "a %s is applied by the frame "
                         "cleaning, which is off (no-prep)", cal);
    if (o->flat_dark_path && !o->flat_path)
        return sl_seterr(e, SL_EINVAL, "the flat's dark %s: give the flat "
                         "(--flat) it belongs to", o->flat_dark_path);
    if (o->target_path && !o->ref_path)
        return sl_seterr(e, SL_EINVAL, "target PSF %s: it replaces a "
                         "reference's; give the reference (--ref)", o->target_path);
    return check_numbers(o, e);
}

int pipeline_check_data(const pipeline_opts *o, const char *what, int width,
                        int height, int nframes, sl_err *e)
{
    if (nframes < 2)
        return sl_seterr(e, SL_EDATA, "%s holds %d frame%s: speckle "
                         "reconstruction averages a sequence; give a cube "
                         "(NAXIS3 > 1) or several frames", what, nframes,
                         nframes == 1 ? "" : "s");
    int side = width < height ? width : height;
    int big = width > height ? width : height;
    if (o->r2_px > side / 2)
        return sl_seterr(e, SL_EINVAL, "r2 %d px: past Nyquist for the %dx%d "
                         "frames of %s (at most %d px)", o->r2_px, width,
                         height, what, side / 2);
    int max_angles = (int)ceil(M_PI * big);
    if (o->nangles > max_angles)
        return sl_seterr(e, SL_EINVAL, "projections %d: the %dx%d frames of "
                         "%s resolve at most pi x %d = %d angles", o->nangles,
                         width, height, what, big, max_angles);
    return SL_OK;
}
