/* utcdate.h - FITS dates (DATE-OBS) as day counts and epochs.
 *
 * A FITS date is ISO-8601 in UTC: "YYYY-MM-DD" or "YYYY-MM-DDThh:mm:ss[.s...]"
 * (FITS 4.0 section 9.1.1).  Leap seconds and the UT1/TT offsets (about
 * a minute, 2e-6 year) are below what a speckle epoch needs and are not
 * modelled. */
#ifndef SL_UTCDATE_H
#define SL_UTCDATE_H

#include "status.h"

/* Modified Julian Date (days since 1858-11-17T00:00 UTC) of iso.
 * SL_EINVAL naming the text when it is not such a date, or a field is out
 * of range (month 13, 25 o'clock). */
int utcdate_mjd(const char *iso, double *mjd, sl_err *err);
/* Besselian epoch of an MJD: B = 1900.0 + (JD - 2415020.31352) /
 * 365.242198781 (Lieske 1979), the epochs double-star catalogues use. */
double utcdate_besselian_year(double mjd);

#endif
