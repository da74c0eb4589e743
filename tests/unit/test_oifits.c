/* test_oifits.c - OIFITS 2 files as written (oifits.h), read back with
 * cfitsio: the primary header, the five tables with their revision,
 * keywords, column units and values, the checksums; an existing file is
 * not replaced without overwrite, nothing is left behind when a write is
 * refused; and MJD / Besselian epochs of FITS dates (utcdate.h). */
#include <fitsio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>
#include <dirent.h>

#include "base/utcdate.h"
#include "io/oifits.h"
#include "tcheck.h"

typedef struct fx {
    char dir[64], path[128];
    oifits_station sta[3];
    oifits_vis2 v2[3];
    oifits_t3 t3[1];
    oifits_data d;
} fx;

static int fx_start(fx *f)
{
    snprintf(f->dir, sizeof f->dir, "/tmp/sl_oifits_XXXXXX");
    if (!mkdtemp(f->dir))
        return -1;
    snprintf(f->path, sizeof f->path, "%s/a.oifits", f->dir);
    oifits_data *d = &f->d;
    oifits_data_init(d);
    snprintf(d->origin, sizeof d->origin, "specklab");
    snprintf(d->instrume, sizeof d->instrume, "specklab-sim");
    snprintf(d->insmode, sizeof d->insmode, "NRM nrm17");
    snprintf(d->date_obs, sizeof d->date_obs, "2026-03-01T02:03:04.5");
    snprintf(d->target, sizeof d->target, "a target name longer than sixteen");
    snprintf(d->arrname, sizeof d->arrname, "nrm17");
    snprintf(d->insname, sizeof d->insname, "specklab-nrm17");
    d->history = "line one\nline two is long enough that one card of seventy characters "
                 "cannot hold it, so it is wrapped at a blank";
    for (int i = 0; i < 3; i++) {
        f->sta[i] = (oifits_station){"", "", 0.1, {-0.1 * i, 0.2 * i, 0}, 1.26};
        snprintf(f->sta[i].tel_name, sizeof f->sta[i].tel_name, "H%d", i + 1);
        snprintf(f->sta[i].sta_name, sizeof f->sta[i].sta_name, "H%d", i + 1);
    }
    int pairs[3][2] = {{0, 1}, {1, 2}, {0, 2}};
    for (int i = 0; i < 3; i++)
        f->v2[i] = (oifits_vis2){{pairs[i][0], pairs[i][1]}, 0.1 * (i + 1), -0.2 * (i + 1),
                                 0.5 + 0.1 * i, 0.01, 0};
    f->t3[0] = (oifits_t3){{0, 1, 2}, 0.1, -0.2, 0.1, -0.2, 0.9, 0.05, -12.5, 1.5, 0};
    d->sta = f->sta, d->nsta = 3;
    d->vis2 = f->v2, d->nvis2 = 3;
    d->t3 = f->t3, d->nt3 = 1;
    d->eff_wave_m = 500e-9, d->eff_band_m = 0;
    d->mjd = 61100.5, d->int_time_s = 1.0;
    return 0;
}

static void fx_stop(fx *f)
{
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", f->dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", f->dir);
}

static int nfiles(const char *dir)
{
    DIR *d = opendir(dir);
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        n += strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
    if (d)
        closedir(d);
    return n;
}

/* The unit of the column named col in the current HDU, "" when none. */
static void col_unit(fitsfile *fp, const char *col, char *unit, int *st)
{
    int c = 0;
    char key[16];
    fits_get_colnum(fp, CASEINSEN, (char *)col, &c, st);
    snprintf(key, sizeof key, "TUNIT%d", c);
    unit[0] = 0;
    int s2 = 0;
    fits_read_key_str(fp, key, unit, NULL, &s2);
}

TEST(tables_read_back)
{
    fx f;
    CHECK(fx_start(&f) == 0, "temporary directory");
    sl_err e = {0};
    int rc = oifits_write(f.path, &f.d, 0, &e);
    fitsfile *fp = NULL;
    int st = 0, nhdu = 0, revn = 0;
    char s[FLEN_VALUE] = "", u[FLEN_VALUE], frame[FLEN_VALUE] = "", tgt[FLEN_VALUE] = "";
    int ok_units = 1, ok_revn = 1, hdutype, dataok = 0, hsum = 0;
    double v2 = 0, t3phi = 0, t3u = 0;
    int sta3[3] = {0};
    static const char *ext[] = {"OI_TARGET", "OI_ARRAY", "OI_WAVELENGTH", "OI_VIS2", "OI_T3"};
    int nhist = 0, nkeys = 0;
    char card[FLEN_CARD], last[FLEN_CARD] = "";
    if (rc == SL_OK && fits_open_diskfile(&fp, f.path, READONLY, &st) == 0) {
        fits_get_hdrspace(fp, &nkeys, NULL, &st);
        for (int k = 1; k <= nkeys && !st; k++)
            if (fits_read_record(fp, k, card, &st) == 0 && !strncmp(card, "HISTORY ", 8))
                nhist++, snprintf(last, sizeof last, "%s", card + 8);
        fits_get_num_hdus(fp, &nhdu, &st);
        fits_read_key_str(fp, "CONTENT", s, NULL, &st);
        fits_verify_chksum(fp, &dataok, &hsum, &st);
        for (int k = 0; k < 5 && !st; k++) {
            fits_movnam_hdu(fp, BINARY_TBL, (char *)ext[k], 0, &st);
            fits_read_key(fp, TINT, "OI_REVN", &revn, NULL, &st);
            ok_revn &= revn == 2;
        }
        fits_movnam_hdu(fp, BINARY_TBL, "OI_ARRAY", 0, &st);
        fits_read_key_str(fp, "FRAME", frame, NULL, &st);
        fits_movnam_hdu(fp, BINARY_TBL, "OI_TARGET", 0, &st);
        char *tp = tgt;
        fits_read_col_str(fp, 2, 1, 1, 1, "", &tp, NULL, &st);
        fits_movnam_hdu(fp, BINARY_TBL, "OI_VIS2", 0, &st);
        col_unit(fp, "UCOORD", u, &st);
        ok_units &= !strcmp(u, "m");
        fits_read_col(fp, TDOUBLE, 5, 2, 1, 1, NULL, &v2, NULL, &st);
        fits_movnam_hdu(fp, BINARY_TBL, "OI_T3", 0, &st);
        col_unit(fp, "T3PHI", u, &st);
        ok_units &= !strcmp(u, "deg");
        col_unit(fp, "T3PHIERR", u, &st);
        ok_units &= !strcmp(u, "deg");
        col_unit(fp, "U2COORD", u, &st);
        ok_units &= !strcmp(u, "m");
        fits_read_col(fp, TDOUBLE, 7, 1, 1, 1, NULL, &t3phi, NULL, &st);
        fits_read_col(fp, TDOUBLE, 11, 1, 1, 1, NULL, &t3u, NULL, &st);
        fits_read_col(fp, TINT, 13, 1, 1, 3, NULL, sta3, NULL, &st);
        fits_verify_chksum(fp, &dataok, &hsum, &st);
        fits_get_hdu_type(fp, &hdutype, &st);
        fits_close_file(fp, &st);
    }
    int left = nfiles(f.dir);
    if (getenv("SL_KEEP_OIFITS")) /* for fitsverify by hand */
        rename(f.path, getenv("SL_KEEP_OIFITS"));
    fx_stop(&f);
    CHECK(rc == SL_OK, "%s", e.msg);
    CHECK(st == 0, "cfitsio status %d reading it back", st);
    CHECK(nhdu == 6 && !strcmp(s, "OIFITS2"), "%d HDUs, CONTENT '%s'", nhdu, s);
    CHECK(nhist == 3 && !strncmp(last, "hold it, so it is wrapped at a blank", 36),
          "%d HISTORY cards, the last '%s'", nhist, last);
    CHECK(ok_revn && !strcmp(frame, "SKY"), "OI_REVN 2 in every table; FRAME '%s'", frame);
    CHECK(!strcmp(tgt, "a target name lo"), "TARGET cut to 16: '%s'", tgt);
    CHECK(ok_units, "column units");
    CHECK(dataok == 1 && hsum == 1, "OI_T3 checksums %d %d", dataok, hsum);
    CHECK(v2 == 0.6 && t3phi == -12.5 && t3u == 0.1, "values %g %g %g", v2, t3phi, t3u);
    CHECK(sta3[0] == 1 && sta3[1] == 2 && sta3[2] == 3, "STA_INDEX from 1: %d %d %d",
          sta3[0], sta3[1], sta3[2]);
    CHECK(left == 1, "%d files in the directory (a temporary left?)", left);
}

TEST(no_overwrite_without_asking)
{
    fx f;
    CHECK(fx_start(&f) == 0, "temporary directory");
    sl_err e = {0};
    FILE *o = fopen(f.path, "w");
    if (o) {
        fputs("precious", o);
        fclose(o);
    }
    int rc1 = oifits_write(f.path, &f.d, 0, &e);
    char e1[SL_ERRMSG_MAX];
    snprintf(e1, sizeof e1, "%s", e.msg);
    struct stat sb1 = {0}, sb2 = {0};
    stat(f.path, &sb1);
    int rc2 = oifits_write(f.path, &f.d, 1, &e);
    stat(f.path, &sb2);
    f.d.vis2 = NULL;
    int rc3 = oifits_write(f.path, &f.d, 1, &e);
    char e3[SL_ERRMSG_MAX];
    snprintf(e3, sizeof e3, "%s", e.msg);
    f.d.vis2 = f.v2;
    f.v2[1].vis2 = NAN;
    int rc4 = oifits_write(f.path, &f.d, 1, &e);
    int left = nfiles(f.dir);
    fx_stop(&f);
    CHECK(rc1 == SL_EIO && strstr(e1, "exists") && sb1.st_size == 8,
          "existing file: %d '%s', %lld bytes", rc1, e1, (long long)sb1.st_size);
    CHECK(rc2 == SL_OK && sb2.st_size > 2880, "overwrite: %d, %lld bytes", rc2,
          (long long)sb2.st_size);
    CHECK(rc3 == SL_EINVAL && strstr(e3, "rows"), "no rows: %d '%s'", rc3, e3);
    CHECK(rc4 == SL_EINVAL && strstr(e.msg, "OI_VIS2 row 2"), "NaN: %d '%s'", rc4, e.msg);
    CHECK(left == 1, "%d files left", left);
}

TEST(dates)
{
    double mjd = 0;
    sl_err e = {0};
    CHECK(utcdate_mjd("1858-11-17", &mjd, &e) == SL_OK && mjd == 0, "MJD 0: %g", mjd);
    CHECK(utcdate_mjd("2000-01-01T12:00:00", &mjd, &e) == SL_OK && mjd == 51544.5,
          "J2000: %.6f", mjd);
    CHECK(utcdate_mjd("2024-02-29T18:00:00.000", &mjd, &e) == SL_OK && mjd == 60369.75,
          "leap day: %.6f", mjd);
    /* B1950.0 = JD 2433282.4235 */
    CHECK_NEAR(utcdate_besselian_year(2433282.4235 - 2400000.5), 1950.0, 1e-6);
    CHECK(utcdate_mjd("2023-02-29", &mjd, &e) == SL_EINVAL && strstr(e.msg, "2023-02-29"),
          "not a leap year: %s", e.msg);
    CHECK(utcdate_mjd("2023-01-01T25:00:00", &mjd, &e) == SL_EINVAL, "25 o'clock");
    CHECK(utcdate_mjd("yesterday", &mjd, &e) == SL_EINVAL, "words");
    CHECK(utcdate_mjd("2023-01-01Tnoon", &mjd, &e) == SL_EINVAL, "no time");
}

TC_MAIN(TC_CASE(tables_read_back), TC_CASE(no_overwrite_without_asking), TC_CASE(dates))
