/* oifits.h - interferometric observables written as OIFITS version 2
 * (Duvert, Young & Hummel 2017, A&A 597, A8), the exchange format of
 * optical interferometry, with cfitsio.
 *
 * The file: a primary HDU without data whose header says what it holds
 * (CONTENT = 'OIFITS2', ORIGIN, DATE, DATE-OBS, TELESCOP, INSTRUME,
 * OBSERVER, INSMODE, OBJECT, and PROCSOFT, OBSTECH), then five binary
 * tables, each with OI_REVN = 2 and CHECKSUM/DATASUM:
 *   OI_TARGET      one target (TARGET_ID 1);
 *   OI_ARRAY       ARRNAME, FRAME, ARRAYX/Y/Z and one row per station
 *                  (TEL_NAME, STA_NAME, STA_INDEX from 1, DIAMETER [m],
 *                  STAXYZ [m], FOV [arcsec], FOVTYPE 'RADIUS');
 *   OI_WAVELENGTH  INSNAME and one channel (EFF_WAVE, EFF_BAND [m]);
 *   OI_VIS2        VIS2DATA, VIS2ERR, UCOORD, VCOORD [m], STA_INDEX pairs,
 *                  FLAG, TARGET_ID, TIME (0 [s]: deprecated), MJD [day],
 *                  INT_TIME [s]; DATE-OBS, ARRNAME, INSNAME;
 *   OI_T3          T3AMP, T3AMPERR, T3PHI, T3PHIERR [deg], U1COORD,
 *                  V1COORD, U2COORD, V2COORD [m], STA_INDEX triples, the
 *                  rest as OI_VIS2.
 * Coordinates are OIFITS's: U towards east, V towards north, the
 * visibility V(u) = sum I exp(-2 pi i u.alpha) with alpha (east, north),
 * T3 = V(u1) V(u2) V(-u1 - u2) for stations (A, B, C) with u1 = AB and
 * u2 = BC.  Strings longer than a column (16 characters for names) are cut.
 *
 * The write is atomic: the file is written under a temporary name in the
 * destination's directory, flushed to disk, then renamed over path
 * (overwrite) or linked to it (never replacing a file that exists,
 * however it got there).  A crash leaves no partial OIFITS at path. */
#ifndef SL_OIFITS_H
#define SL_OIFITS_H

#include "status.h"

#define OIFITS_NAME_MAX 69   /* one FITS string card: 68 characters + NUL */

typedef struct oifits_station {
    char tel_name[OIFITS_NAME_MAX], sta_name[OIFITS_NAME_MAX];
    double diameter_m;
    double xyz_m[3];          /* in the array's FRAME */
    double fov_arcsec;        /* radius */
} oifits_station;

typedef struct oifits_vis2 {
    int sta[2];               /* indices into the stations, from 0 */
    double u_m, v_m;
    double vis2, vis2_err;
    int flag;
} oifits_vis2;

typedef struct oifits_t3 {
    int sta[3];
    double u1_m, v1_m, u2_m, v2_m;
    double amp, amp_err, phi_deg, phi_err_deg;
    int flag;
} oifits_t3;

typedef struct oifits_data {
    /* primary header: "" is written as 'UNKNOWN' (OIFITS2 wants them) */
    char origin[OIFITS_NAME_MAX], telescop[OIFITS_NAME_MAX];
    char instrume[OIFITS_NAME_MAX], observer[OIFITS_NAME_MAX];
    char insmode[OIFITS_NAME_MAX], obstech[OIFITS_NAME_MAX];
    char procsoft[OIFITS_NAME_MAX];
    char date_obs[OIFITS_NAME_MAX];   /* ISO-8601 UTC, required */
    const char *history;      /* HISTORY lines, '\n'-separated, or NULL */
    /* OI_TARGET */
    char target[OIFITS_NAME_MAX];
    double ra_deg, dec_deg;   /* RAEP0, DECEP0 at EQUINOX 2000 */
    /* OI_ARRAY */
    char arrname[OIFITS_NAME_MAX], frame[OIFITS_NAME_MAX]; /* 'SKY' or
                                                            * 'GEOCENTRIC' */
    const oifits_station *sta;
    int nsta;
    /* OI_WAVELENGTH */
    char insname[OIFITS_NAME_MAX];
    double eff_wave_m, eff_band_m;
    /* every data row */
    double mjd, int_time_s;
    const oifits_vis2 *vis2;
    int nvis2;
    const oifits_t3 *t3;
    int nt3;
} oifits_data;

/* Everything empty or 0, FRAME 'SKY', no rows. */
void oifits_data_init(oifits_data *d);

/* Write d to path (see above).  SL_EINVAL for a station index out of
 * range, a non-finite number in a row, no DATE-OBS, FRAME not SKY or
 * GEOCENTRIC, fewer than one station; SL_EIO naming path when it exists
 * and overwrite is 0 ("exists"), or on any write error (cfitsio's message
 * or the system's).  The temporary is removed on failure. */
int oifits_write(const char *path, const oifits_data *d, int overwrite,
                 sl_err *err);

#endif
