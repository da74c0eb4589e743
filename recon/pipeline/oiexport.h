/* oiexport.h - an aperture-mask cube on disk to OIFITS: its frames
 * cleaned as pipeline_run cleans them (framefeed.h), the mask's squared
 * visibilities and closure phases measured on them (spectra/maskobs.h),
 * and the tables io/oifits.h writes, filled in one place.
 *
 * What goes where.
 *   OI_ARRAY   one station per hole, TEL_NAME = STA_NAME = 'H<n>' (n from
 *              1 in the mask's order), DIAMETER the hole's, FRAME 'SKY'
 *              and STAXYZ = (east, north, 0) = (-x_m, y_m, 0): the mask's
 *              +x lands on the image's +x, which is west (maskobs.h);
 *              FOV 1.22 lambda / d (a hole's Airy radius);
 *   OI_WAVELENGTH  the wavelength, EFF_BAND the bandwidth (0: unknown or
 *              monochromatic, as the simulator's frames are);
 *   OI_VIS2, OI_T3  every measured baseline and triangle; redundant ones
 *              (no clean pixel, maskobs.h) are not written, and HISTORY
 *              says how many; MJD = DATE-OBS + INT_TIME / 2, INT_TIME =
 *              frames used x EXPTIME (0 without EXPTIME);
 *   OI_TARGET  the target, RAEP0/DECEP0 from RA/DEC keywords, else 0 (and
 *              HISTORY says the position is unknown);
 *   primary    ORIGIN 'specklab', INSTRUME the cube's, INSMODE 'NRM
 *              <mask>', OBSTECH, PROCSOFT, TELESCOP and OBSERVER when the
 *              cube has them, and HISTORY: the input, the frames, the
 *              cleaning, the photon bias, what was not measured, the
 *              error factors, and that V2 is raw (uncalibrated).
 * V2 and T3 are raw: divided by the mask's own transfer only, so
 * turbulence, the pixels and the optics still lower them until a
 * calibrator's are divided out; closure phases need no calibration. */
#ifndef SL_OIEXPORT_H
#define SL_OIEXPORT_H

#include "io/oifits.h"
#include "spectra/maskobs.h"
#include "framefeed.h"
#include "pipeline.h"

typedef struct oiexport_mask {
    const double *x_m, *y_m;  /* hole centres (sim/mask.h's frame) */
    int nholes;
    double hole_diameter_m;
    const char *name;         /* ARRNAME: "nrm17", a file's name */
} oiexport_mask;

typedef struct oiexport_opts {
    pipeline_opts clean;      /* the cleaning (framefeed.h) */
    double wavelength_m;      /* NAN: WAVELEN from the header */
    double plate_scale_arcsec;/* NAN: PLTSCALE from the header */
    double bandwidth_m;       /* EFF_BAND; 0 unknown */
    const char *target;       /* NULL: OBJECT, else 'UNKNOWN' */
    const char *date_obs;     /* NULL: DATE-OBS from the header */
    int block_frames;         /* maskobs_opts.block_frames; 0 default */
} oiexport_opts;

void oiexport_opts_defaults(oiexport_opts *o);

typedef struct oiexport_result {
    maskobs_result obs;       /* what was measured */
    framefeed_photons photons;
    double wavelength_m, plate_scale_arcsec;
    oifits_data oi;           /* the file, pointing into this result */
    oifits_station *sta;
    oifits_vis2 *vis2;
    oifits_t3 *t3;
    char history[2048];
} oiexport_result;

/* Measure paths[0..npaths) through mask into out (free with
 * oiexport_result_clear).  Errors name what is missing: the wavelength
 * (WAVELEN), the plate scale (PLTSCALE), the date (DATE-OBS); or the
 * file and frame that failed. */
int oiexport_run(const char *const *paths, int npaths,
                 const oiexport_mask *mask, const oiexport_opts *o,
                 oiexport_result *out, sl_err *err);
void oiexport_result_clear(oiexport_result *r);

#endif
