/* oifits.c - see oifits.h. */
#include "oifits.h"

#include <errno.h>
#include <fcntl.h>
#include <fitsio.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define REVN 2
#define NAME_COL 16           /* characters of TARGET, TEL_NAME, STA_NAME */

void oifits_data_init(oifits_data *d)
{
    memset(d, 0, sizeof *d);
    snprintf(d->frame, sizeof d->frame, "SKY");
}

static int finite_all(const double *v, int n)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(v[i]))
            return 0;
    return 1;
}

static int check_rows(const oifits_data *d, sl_err *err)
{
    for (int i = 0; i < d->nvis2; i++) {
        const oifits_vis2 *r = &d->vis2[i];
        double v[] = {r->u_m, r->v_m, r->vis2, r->vis2_err};
        if (r->sta[0] < 0 || r->sta[0] >= d->nsta || r->sta[1] < 0 || r->sta[1] >= d->nsta)
            return sl_seterr(err, SL_EINVAL, "OI_VIS2 row %d: station index out of "
                             "0..%d", i + 1, d->nsta - 1);
        if (!finite_all(v, 4))
            return sl_seterr(err, SL_EINVAL, "OI_VIS2 row %d: a value is not finite", i + 1);
    }
    for (int i = 0; i < d->nt3; i++) {
        const oifits_t3 *r = &d->t3[i];
        double v[] = {r->u1_m, r->v1_m, r->u2_m, r->v2_m, r->amp, r->amp_err,
                      r->phi_deg, r->phi_err_deg};
        for (int k = 0; k < 3; k++)
            if (r->sta[k] < 0 || r->sta[k] >= d->nsta)
                return sl_seterr(err, SL_EINVAL, "OI_T3 row %d: station index out "
                                 "of 0..%d", i + 1, d->nsta - 1);
        if (!finite_all(v, 8))
            return sl_seterr(err, SL_EINVAL, "OI_T3 row %d: a value is not finite", i + 1);
    }
    return SL_OK;
}

static int check_data(const oifits_data *d, sl_err *err)
{
    if (!d->date_obs[0])
        return sl_seterr(err, SL_EINVAL, "OIFITS: no DATE-OBS (OIFITS 2 requires it)");
    if (strcmp(d->frame, "SKY") && strcmp(d->frame, "GEOCENTRIC"))
        return sl_seterr(err, SL_EINVAL, "OIFITS: FRAME '%s' is neither SKY nor "
                         "GEOCENTRIC", d->frame);
    if (d->nsta < 1 || !d->sta)
        return sl_seterr(err, SL_EINVAL, "OIFITS: no stations for OI_ARRAY");
    if ((d->nvis2 > 0 && !d->vis2) || (d->nt3 > 0 && !d->t3) || d->nvis2 < 0 || d->nt3 < 0)
        return sl_seterr(err, SL_EINVAL, "OIFITS: rows missing");
    double v[] = {d->eff_wave_m, d->eff_band_m, d->mjd, d->int_time_s, d->ra_deg, d->dec_deg};
    if (!finite_all(v, 6) || !(d->eff_wave_m > 0))
        return sl_seterr(err, SL_EINVAL, "OIFITS: wavelength %g m, bandwidth %g m, MJD "
                         "%g, integration %g s, RA %g, DEC %g: each must be finite "
                         "(wavelength > 0)", v[0], v[1], v[2], v[3], v[4], v[5]);
    for (int i = 0; i < d->nsta; i++)
        if (!finite_all(d->sta[i].xyz_m, 3) || !isfinite(d->sta[i].diameter_m) ||
            !isfinite(d->sta[i].fov_arcsec))
            return sl_seterr(err, SL_EINVAL, "OI_ARRAY station %d: a value is not "
                             "finite", i + 1);
    return check_rows(d, err);
}

static const char *or_unknown(const char *s)
{
    return s[0] ? s : "UNKNOWN";
}

static void key_str(fitsfile *fp, const char *k, const char *v, const char *c, int *st)
{
    char buf[OIFITS_NAME_MAX];
    snprintf(buf, sizeof buf, "%s", v);
    fits_write_key_str(fp, k, buf, c, st);
}

/* HISTORY cards of at most HIST_CARD characters: one entry per line of
 * text, long lines wrapped at a blank (or cut where there is none). */
#define HIST_CARD 70
static void write_history(fitsfile *fp, const char *h, int *st)
{
    while (h && *h && !*st) {
        size_t n = strcspn(h, "\n"), k = n;
        if (k > HIST_CARD) {
            k = HIST_CARD;
            while (k > HIST_CARD / 2 && h[k] != ' ')
                k--;
            if (h[k] != ' ')
                k = HIST_CARD;
        }
        char line[HIST_CARD + 1];
        snprintf(line, sizeof line, "%.*s", (int)k, h);
        fits_write_history(fp, line, st);
        h += k;
        while (*h == ' ')
            h++;
        if (k == n && *h == '\n')
            h++;
    }
}

static void primary_header(fitsfile *fp, const oifits_data *d, int *st)
{
    fits_create_img(fp, BYTE_IMG, 0, NULL, st);
    key_str(fp, "CONTENT", "OIFITS2", "this file is an OIFITS 2 container", st);
    key_str(fp, "ORIGIN", or_unknown(d->origin), "who wrote the file", st);
    fits_write_date(fp, st);
    key_str(fp, "DATE-OBS", d->date_obs, "[UTC] start of the observation", st);
    key_str(fp, "TELESCOP", or_unknown(d->telescop), "telescope", st);
    key_str(fp, "INSTRUME", or_unknown(d->instrume), "instrument", st);
    key_str(fp, "OBSERVER", or_unknown(d->observer), "who acquired the data", st);
    key_str(fp, "INSMODE", or_unknown(d->insmode), "instrument mode", st);
    key_str(fp, "OBJECT", or_unknown(d->target), "target", st);
    if (d->obstech[0])
        key_str(fp, "OBSTECH", d->obstech, "observation technique", st);
    if (d->procsoft[0])
        key_str(fp, "PROCSOFT", d->procsoft, "software that made the data", st);
    write_history(fp, d->history, st);
    fits_write_chksum(fp, st);
}

/* The keywords every table starts with: OI_REVN, then ARRNAME and
 * INSNAME (and DATE-OBS) where the table refers to them. */
static void table_keys(fitsfile *fp, const oifits_data *d, int data_table, int *st)
{
    int revn = REVN;
    fits_write_key(fp, TINT, "OI_REVN", &revn, "revision of the table definition", st);
    if (data_table) {
        key_str(fp, "DATE-OBS", d->date_obs, "[UTC] start of the observation", st);
        key_str(fp, "ARRNAME", d->arrname, "array (OI_ARRAY)", st);
        key_str(fp, "INSNAME", d->insname, "instrument (OI_WAVELENGTH)", st);
    }
}

static void col_str(fitsfile *fp, int col, long row, const char *s, int *st)
{
    char buf[NAME_COL + 1];
    snprintf(buf, sizeof buf, "%.*s", NAME_COL, s);
    char *p = buf;
    fits_write_col_str(fp, col, row, 1, 1, &p, st);
}

static void write_target(fitsfile *fp, const oifits_data *d, int *st)
{
    char *tt[] = {"TARGET_ID", "TARGET", "RAEP0", "DECEP0", "EQUINOX", "RA_ERR",
                  "DEC_ERR", "SYSVEL", "VELTYP", "VELDEF", "PMRA", "PMDEC",
                  "PMRA_ERR", "PMDEC_ERR", "PARALLAX", "PARA_ERR", "SPECTYP"};
    char *tf[] = {"1I", "16A", "1D", "1D", "1E", "1D", "1D", "1D", "8A", "8A",
                  "1D", "1D", "1D", "1D", "1E", "1E", "16A"};
    char *tu[] = {"", "", "deg", "deg", "yr", "deg", "deg", "m/s", "", "",
                  "deg/yr", "deg/yr", "deg/yr", "deg/yr", "deg", "deg", ""};
    fits_create_tbl(fp, BINARY_TBL, 1, 17, tt, tf, tu, "OI_TARGET", st);
    table_keys(fp, d, 0, st);
    int id = 1;
    double num[] = {d->ra_deg, d->dec_deg, 2000.0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    int numcol[] = {3, 4, 5, 6, 7, 8, 11, 12, 13, 14, 15, 16};
    fits_write_col(fp, TINT, 1, 1, 1, 1, &id, st);
    col_str(fp, 2, 1, or_unknown(d->target), st);
    for (int k = 0; k < 12; k++)
        fits_write_col(fp, TDOUBLE, numcol[k], 1, 1, 1, &num[k], st);
    col_str(fp, 9, 1, "UNKNOWN", st);
    col_str(fp, 10, 1, "OPTICAL", st);
    col_str(fp, 17, 1, "UNKNOWN", st);
    fits_write_chksum(fp, st);
}

static void write_array(fitsfile *fp, const oifits_data *d, int *st)
{
    char *tt[] = {"TEL_NAME", "STA_NAME", "STA_INDEX", "DIAMETER", "STAXYZ", "FOV",
                  "FOVTYPE"};
    char *tf[] = {"16A", "16A", "1I", "1E", "3D", "1D", "6A"};
    char *tu[] = {"", "", "", "m", "m", "arcsec", ""};
    fits_create_tbl(fp, BINARY_TBL, d->nsta, 7, tt, tf, tu, "OI_ARRAY", st);
    table_keys(fp, d, 0, st);
    key_str(fp, "ARRNAME", d->arrname, "array name", st);
    key_str(fp, "FRAME", d->frame, "coordinate frame of STAXYZ", st);
    double zero = 0;
    const char *ax[] = {"ARRAYX", "ARRAYY", "ARRAYZ"};
    for (int k = 0; k < 3; k++) {
        fits_write_key(fp, TDOUBLE, ax[k], &zero, "array centre", st);
        fits_write_key_unit(fp, ax[k], "m", st);
    }
    for (long i = 0; i < d->nsta; i++) {
        const oifits_station *s = &d->sta[i];
        int idx = (int)i + 1;
        col_str(fp, 1, i + 1, s->tel_name, st);
        col_str(fp, 2, i + 1, s->sta_name, st);
        fits_write_col(fp, TINT, 3, i + 1, 1, 1, &idx, st);
        fits_write_col(fp, TDOUBLE, 4, i + 1, 1, 1, (void *)&s->diameter_m, st);
        fits_write_col(fp, TDOUBLE, 5, i + 1, 1, 3, (void *)s->xyz_m, st);
        fits_write_col(fp, TDOUBLE, 6, i + 1, 1, 1, (void *)&s->fov_arcsec, st);
        col_str(fp, 7, i + 1, "RADIUS", st);
    }
    fits_write_chksum(fp, st);
}

static void write_wavelength(fitsfile *fp, const oifits_data *d, int *st)
{
    char *tt[] = {"EFF_WAVE", "EFF_BAND"}, *tf[] = {"1E", "1E"}, *tu[] = {"m", "m"};
    fits_create_tbl(fp, BINARY_TBL, 1, 2, tt, tf, tu, "OI_WAVELENGTH", st);
    table_keys(fp, d, 0, st);
    key_str(fp, "INSNAME", d->insname, "instrument name", st);
    fits_write_col(fp, TDOUBLE, 1, 1, 1, 1, (void *)&d->eff_wave_m, st);
    fits_write_col(fp, TDOUBLE, 2, 1, 1, 1, (void *)&d->eff_band_m, st);
    fits_write_chksum(fp, st);
}

/* TARGET_ID, TIME, MJD, INT_TIME of row (columns 1..4) and FLAG (col). */
static void row_common(fitsfile *fp, const oifits_data *d, long row, int flag,
                       int flag_col, int *st)
{
    int id = 1;
    double zero = 0;
    char f = flag ? 1 : 0;
    fits_write_col(fp, TINT, 1, row, 1, 1, &id, st);
    fits_write_col(fp, TDOUBLE, 2, row, 1, 1, &zero, st);
    fits_write_col(fp, TDOUBLE, 3, row, 1, 1, (void *)&d->mjd, st);
    fits_write_col(fp, TDOUBLE, 4, row, 1, 1, (void *)&d->int_time_s, st);
    fits_write_col(fp, TLOGICAL, flag_col, row, 1, 1, &f, st);
}

static void write_vis2(fitsfile *fp, const oifits_data *d, int *st)
{
    char *tt[] = {"TARGET_ID", "TIME", "MJD", "INT_TIME", "VIS2DATA", "VIS2ERR",
                  "UCOORD", "VCOORD", "STA_INDEX", "FLAG"};
    char *tf[] = {"1I", "1D", "1D", "1D", "1D", "1D", "1D", "1D", "2I", "1L"};
    char *tu[] = {"", "s", "day", "s", "", "", "m", "m", "", ""};
    fits_create_tbl(fp, BINARY_TBL, d->nvis2, 10, tt, tf, tu, "OI_VIS2", st);
    table_keys(fp, d, 1, st);
    for (long i = 0; i < d->nvis2; i++) {
        const oifits_vis2 *r = &d->vis2[i];
        double v[] = {r->vis2, r->vis2_err, r->u_m, r->v_m};
        int sta[2] = {r->sta[0] + 1, r->sta[1] + 1};
        row_common(fp, d, i + 1, r->flag, 10, st);
        for (int k = 0; k < 4; k++)
            fits_write_col(fp, TDOUBLE, 5 + k, i + 1, 1, 1, &v[k], st);
        fits_write_col(fp, TINT, 9, i + 1, 1, 2, sta, st);
    }
    fits_write_chksum(fp, st);
}

static void write_t3(fitsfile *fp, const oifits_data *d, int *st)
{
    char *tt[] = {"TARGET_ID", "TIME", "MJD", "INT_TIME", "T3AMP", "T3AMPERR", "T3PHI",
                  "T3PHIERR", "U1COORD", "V1COORD", "U2COORD", "V2COORD", "STA_INDEX",
                  "FLAG"};
    char *tf[] = {"1I", "1D", "1D", "1D", "1D", "1D", "1D", "1D", "1D", "1D", "1D",
                  "1D", "3I", "1L"};
    char *tu[] = {"", "s", "day", "s", "", "", "deg", "deg", "m", "m", "m", "m", "", ""};
    fits_create_tbl(fp, BINARY_TBL, d->nt3, 14, tt, tf, tu, "OI_T3", st);
    table_keys(fp, d, 1, st);
    for (long i = 0; i < d->nt3; i++) {
        const oifits_t3 *r = &d->t3[i];
        double v[] = {r->amp, r->amp_err, r->phi_deg, r->phi_err_deg,
                      r->u1_m, r->v1_m, r->u2_m, r->v2_m};
        int sta[3] = {r->sta[0] + 1, r->sta[1] + 1, r->sta[2] + 1};
        row_common(fp, d, i + 1, r->flag, 14, st);
        for (int k = 0; k < 8; k++)
            fits_write_col(fp, TDOUBLE, 5 + k, i + 1, 1, 1, &v[k], st);
        fits_write_col(fp, TINT, 13, i + 1, 1, 3, sta, st);
    }
    fits_write_chksum(fp, st);
}

/* Every HDU into a new file tmp (which must not exist). */
static int write_file(const char *tmp, const oifits_data *d, sl_err *err)
{
    fitsfile *fp = NULL;
    int st = 0;
    if (fits_create_diskfile(&fp, tmp, &st) == 0) {
        primary_header(fp, d, &st);
        write_target(fp, d, &st);
        write_array(fp, d, &st);
        write_wavelength(fp, d, &st);
        write_vis2(fp, d, &st);
        write_t3(fp, d, &st);
    }
    int cst = 0;
    if (fp)
        fits_close_file(fp, &cst);
    if (st || cst) {
        char msg[FLEN_STATUS];
        fits_get_errstatus(st ? st : cst, msg);
        return sl_seterr(err, SL_EIO, "%s: %s", tmp, msg);
    }
    return SL_OK;
}

/* tmp's data to disk, then tmp becomes path: renamed over it
 * (overwrite), else linked (fails when path exists, atomically). */
static int commit(const char *tmp, const char *path, int overwrite, sl_err *err)
{
    int fd = open(tmp, O_RDONLY);
    if (fd < 0 || fsync(fd) != 0) {
        int e = errno;
        if (fd >= 0)
            close(fd);
        return sl_seterr(err, SL_EIO, "%s: %s", tmp, strerror(e));
    }
    close(fd);
    if (overwrite) {
        if (rename(tmp, path) != 0)
            return sl_seterr(err, SL_EIO, "%s: %s", path, strerror(errno));
        return SL_OK;
    }
    if (link(tmp, path) != 0) {
        int e = errno;
        if (e == EEXIST)
            return sl_seterr(err, SL_EIO, "%s exists (not overwritten)", path);
        /* no hard links on this file system: a check, then a rename */
        if (access(path, F_OK) == 0)
            return sl_seterr(err, SL_EIO, "%s exists (not overwritten)", path);
        if (rename(tmp, path) != 0)
            return sl_seterr(err, SL_EIO, "%s: %s", path, strerror(errno));
        return SL_OK;
    }
    unlink(tmp);
    return SL_OK;
}

int oifits_write(const char *path, const oifits_data *d, int overwrite,
                 sl_err *err)
{
    if (!path || !d)
        return sl_seterr(err, SL_EINVAL, "OIFITS: no path or data");
    int rc = check_data(d, err);
    if (rc != SL_OK)
        return rc;
    if (!overwrite && access(path, F_OK) == 0)
        return sl_seterr(err, SL_EIO, "%s exists (not overwritten)", path);
    /* the temporary beside path, so that the rename stays in one file
     * system: DIR/.NAME.XXXXXX */
    const char *slash = strrchr(path, '/');
    size_t dirlen = slash ? (size_t)(slash - path) + 1 : 0;
    size_t n = strlen(path) + 16;
    char *tmp = malloc(n);
    if (!tmp)
        return sl_seterr(err, SL_ENOMEM, "OIFITS: out of memory");
    snprintf(tmp, n, "%.*s.%s.XXXXXX", (int)dirlen, path, path + dirlen);
    int fd = mkstemp(tmp);
    if (fd < 0) {
        rc = sl_seterr(err, SL_EIO, "%s: cannot create a temporary beside it: %s",
                       path, strerror(errno));
        free(tmp);
        return rc;
    }
    close(fd);
    /* cfitsio creates files only where none is: the random name, made
     * unique a moment ago, is very unlikely to be taken again */
    unlink(tmp);
    rc = write_file(tmp, d, err);
    if (rc == SL_OK)
        rc = commit(tmp, path, overwrite, err);
    unlink(tmp);
    free(tmp);
    return rc;
}
