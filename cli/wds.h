/* wds.h - a binary's measure as one line in the style of the Washington
 * Double Star catalogue's measures (and the Fourth Interferometric
 * Catalog): `specklab binary --wds`.
 *
 * The line, whitespace-separated:
 *   EPOCH THETA eTHETA RHO eRHO DM eDM FLAG METHOD NOTE...
 *   2026.9048  30.05 0.51  0.1979 0.0022  0.96 0.03  -  speckle/closure  100 frames, 500 nm
 * EPOCH: the Besselian epoch of DATE-OBS (utcdate.h), 4 decimals, or
 *        'nodate' when the header has no DATE-OBS (the NOTE says so);
 * THETA: position angle [deg], from north through east, 0..360;
 * RHO:   separation [arcsec] (pixels x PLTSCALE);
 * DM:    magnitude difference; each followed by its 1-sigma error;
 * FLAG:  '-', or 'Q' when the quadrant is unknown: the PA is THETA or
 *        THETA + 180 (an equal pair, or fringes only);
 * METHOD: 'speckle/' and the fit the verdict took (closure, image,
 *        fringe: recon/pipeline/pipeline.h).
 * When the verdict is unresolved or inconsistent no numbers are given:
 *   2026.9048  unresolved  speckle  no companion above the noise
 * so a catalogue never receives a confident wrong measure. */
#ifndef SL_WDS_H
#define SL_WDS_H

#include <stddef.h>

#include "io/cube.h"
#include "pipeline/pipeline.h"

typedef struct wds_measure {
    int has_date;
    double epoch;                 /* Besselian */
    int status, source;           /* enum pipeline_binary_status, _source */
    double theta_deg, theta_err_deg, rho_arcsec, rho_err_arcsec;
    double dm_mag, dm_err_mag;
    char note[160];
} wds_measure;

/* The measure of verdict v (pixels) with plate scale ps [arcsec/px] and
 * the header's DATE-OBS; note: frames (when > 0) and wavelength, and v's
 * why.
 * SL_EINVAL naming PLTSCALE when ps is not finite and > 0 (rho needs
 * it), or naming DATE-OBS when it is there but not a date. */
int wds_measure_from(const pipeline_binary *v, double ps, const cube_meta *m,
                     int nframes, wds_measure *out, sl_err *err);
/* The line (no newline) into buf of n bytes. */
void wds_format(const wds_measure *w, char *buf, size_t n);

/* `specklab binary --wds PATH`: a cube reconstructed in memory (direct,
 * closure phases) or an image (its recon --binary verdict, else the
 * image fit); prints the line (or JSON).  Exit status: 0, or 1 when
 * unresolved or on an error (printed). */
int wds_binary(const char *path, const char *ext, int json);

#endif
