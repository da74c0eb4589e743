/* cube_header.c - the keywords of an image HDU written by recon/io; see
 * cube_header.h and cube.h ("The standard header", "WCS"). */
#include "cube_header.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/version.h"

/* Shortest %G precision that reads back as v exactly. */
static int round_trip_digits(double v)
{
    char buf[40];
    for (int d = 1; d < 17; d++) {
        snprintf(buf, sizeof buf, "%.*G", d, v);
        if (strtod(buf, NULL) == v)
            return d;
    }
    return 17;
}

static void put_num(fitsfile *fp, const char *key, double v,
                    const char *comment, int *st)
{
    if (v == floor(v) && fabs(v) < 9.0e15)
        fits_update_key_lng(fp, key, (LONGLONG)v, comment, st);
    else
        fits_update_key_dbl(fp, key, v, -round_trip_digits(v), comment, st);
}

static void put_str(fitsfile *fp, const char *key, const char *s,
                    const char *comment, int *st)
{
    if (s[0] != '\0')
        fits_update_key_str(fp, key, s, comment, st);
}

/* DATE-OBS for "now": ISO-8601 UTC with milliseconds. */
static void now_iso(char *out, size_t n)
{
    struct timespec ts;
    struct tm tm;
    char sec[32];
    clock_gettime(CLOCK_REALTIME, &ts);
    gmtime_r(&ts.tv_sec, &tm);
    strftime(sec, sizeof sec, "%Y-%m-%dT%H:%M:%S", &tm);
    snprintf(out, n, "%s.%03ld", sec, ts.tv_nsec / 1000000L);
}

/* The standard fields (when set), then the extras, into the current HDU.
 * with_date: write DATE-OBS even when m lacks one (primary). */
static void put_meta(fitsfile *fp, const cube_meta *m, int with_date,
                     int *st)
{
    char date[CUBE_STR_MAX];
    if (m && m->date_obs[0])
        snprintf(date, sizeof date, "%s", m->date_obs);
    else
        now_iso(date, sizeof date);
    if (with_date || (m && m->date_obs[0]))
        put_str(fp, "DATE-OBS", date, "[UTC] start of the observation", st);
    if (!m)
        return;
    if (isfinite(m->exptime_s))
        put_num(fp, "EXPTIME", m->exptime_s, "[s] exposure time", st);
    put_str(fp, "INSTRUME", m->instrume, "instrument / camera", st);
    put_str(fp, "OBJECT", m->object, "target", st);
    put_str(fp, "BUNIT", m->bunit, "physical unit of the pixel values", st);
    if (isfinite(m->plate_scale_arcsec))
        put_num(fp, "PLTSCALE", m->plate_scale_arcsec,
                "[arcsec/pixel] plate scale (x pitch)", st);
    if (isfinite(m->pixel_aspect))
        put_num(fp, "PIXASPCT", m->pixel_aspect, "pixel height / width", st);
    if (isfinite(m->wavelength_m))
        put_num(fp, "WAVELEN", m->wavelength_m, "[m] wavelength", st);
    if (isfinite(m->ra_deg))
        put_num(fp, "RA", m->ra_deg, "[deg] right ascension at the centre (ICRS)", st);
    if (isfinite(m->dec_deg))
        put_num(fp, "DEC", m->dec_deg, "[deg] declination at the centre (ICRS)", st);
    for (int i = 0; i < m->nextra && i < CUBE_META_MAX_EXTRA; i++) {
        const cube_kv *kv = &m->extra[i];
        const char *c = kv->comment[0] ? kv->comment : NULL;
        if (kv->type == CUBE_KV_STR)
            fits_update_key_str(fp, kv->key, kv->str, c, st);
        else if (kv->type == CUBE_KV_BOOL)
            fits_update_key_log(fp, kv->key, kv->num != 0.0, c, st);
        else
            put_num(fp, kv->key, kv->num, c, st);
    }
}

/* ---- WCS ---------------------------------------------------------------- */

/* One description of the two image axes (cube.h, WCS). */
typedef struct wcs_desc {
    const char *name, *ctype1, *ctype2, *cunit;
    const char *cname1, *cname2;   /* NULL: none */
    double crval1, crval2, cdelt1, cdelt2;
    int celestial;
} wcs_desc;

/* key with the alternate letter alt ("" or "A") into out. */
static const char *wkey(char out[FLEN_KEYWORD], const char *key, const char *alt)
{
    snprintf(out, FLEN_KEYWORD, "%s%s", key, alt);
    return out;
}

static void put_wcs_desc(fitsfile *fp, const wcs_desc *d, const char *alt,
                         double crpix1, double crpix2, int *st)
{
    char k[FLEN_KEYWORD];
    fits_update_key_str(fp, wkey(k, "WCSNAME", alt), d->name, NULL, st);
    fits_update_key_str(fp, wkey(k, "CTYPE1", alt), d->ctype1, NULL, st);
    fits_update_key_str(fp, wkey(k, "CTYPE2", alt), d->ctype2, NULL, st);
    fits_update_key_str(fp, wkey(k, "CUNIT1", alt), d->cunit, NULL, st);
    fits_update_key_str(fp, wkey(k, "CUNIT2", alt), d->cunit, NULL, st);
    if (d->cname1) {
        fits_update_key_str(fp, wkey(k, "CNAME1", alt), d->cname1, NULL, st);
        fits_update_key_str(fp, wkey(k, "CNAME2", alt), d->cname2, NULL, st);
    }
    put_num(fp, wkey(k, "CRPIX1", alt), crpix1, "image centre (reconstructions' object)", st);
    put_num(fp, wkey(k, "CRPIX2", alt), crpix2, "image centre (reconstructions' object)", st);
    put_num(fp, wkey(k, "CRVAL1", alt), d->crval1, NULL, st);
    put_num(fp, wkey(k, "CRVAL2", alt), d->crval2, NULL, st);
    put_num(fp, wkey(k, "CDELT1", alt), d->cdelt1, "negative: east is -x (east left)", st);
    put_num(fp, wkey(k, "CDELT2", alt), d->cdelt2, "north is +y (north up)", st);
    if (d->celestial)
        fits_update_key_str(fp, wkey(k, "RADESYS", alt), "ICRS", NULL, st);
}

/* The WCS of a width x height image from m's plate scale (cube.h): none
 * without one; offsets in arcsec; celestial first when RA/DEC are known. */
static void put_wcs(fitsfile *fp, const cube_meta *m, int width, int height,
                    int *st)
{
    if (!m || !isfinite(m->plate_scale_arcsec) || m->plate_scale_arcsec <= 0)
        return;
    double s = m->plate_scale_arcsec;
    double sy = s * (isfinite(m->pixel_aspect) && m->pixel_aspect > 0
                     ? m->pixel_aspect : 1.0);
    double crpix1 = width / 2 + 1, crpix2 = height / 2 + 1;
    wcs_desc off = {"offsets from the image centre", "EOFFSET", "NOFFSET",
                    "arcsec", "offset towards the east", "offset towards the north",
                    0.0, 0.0, -s, sy, 0};
    if (!isfinite(m->ra_deg) || !isfinite(m->dec_deg)) {
        put_wcs_desc(fp, &off, "", crpix1, crpix2, st);
        return;
    }
    wcs_desc sky = {"sky (ICRS)", "RA---TAN", "DEC--TAN", "deg", NULL, NULL,
                    m->ra_deg, m->dec_deg, -s / 3600.0, sy / 3600.0, 1};
    put_wcs_desc(fp, &sky, "", crpix1, crpix2, st);
    put_wcs_desc(fp, &off, "A", crpix1, crpix2, st);
}

/* 1 when p is digits, then at most one alternate letter, then the end. */
static int index_alt(const char *p)
{
    size_t n = strspn(p, "0123456789");
    return n > 0 && (p[n] == '\0' || (p[n] >= 'A' && p[n] <= 'Z' && p[n + 1] == '\0'));
}

/* 1 when p is an optional alternate letter, then the end. */
static int alt_only(const char *p)
{
    return p[0] == '\0' || (p[0] >= 'A' && p[0] <= 'Z' && p[1] == '\0');
}

static int is_wcs(const char *key)
{
    static const char *const axis[] = {"CTYPE", "CUNIT", "CRPIX", "CRVAL", "CDELT",
                                       "CROTA", "CNAME", "CRDER", "CSYER"};
    static const char *const whole[] = {"WCSAXES", "WCSNAME", "RADESYS", "RADECSYS",
                                        "EQUINOX", "LONPOLE", "LATPOLE"};
    static const char *const matrix[] = {"PC", "CD", "PV", "PS"};
    for (size_t i = 0; i < sizeof axis / sizeof axis[0]; i++)
        if (!strncmp(key, axis[i], 5) && index_alt(key + 5))
            return 1;
    for (size_t i = 0; i < sizeof whole / sizeof whole[0]; i++) {
        size_t n = strlen(whole[i]);
        if (!strncmp(key, whole[i], n) && alt_only(key + n))
            return 1;
    }
    for (size_t i = 0; i < sizeof matrix / sizeof matrix[0]; i++) {
        if (strncmp(key, matrix[i], 2) != 0)
            continue;
        size_t n = strspn(key + 2, "0123456789");
        if (n > 0 && key[2 + n] == '_' && index_alt(key + 3 + n))
            return 1;
    }
    return 0;
}

int cube_header_is_derived(const char *key)
{
    return !strcmp(key, "DATE") || !strcmp(key, "CREATOR") || is_wcs(key);
}

/* ---- HISTORY ------------------------------------------------------------ */

/* One entry as cards: cut at the last blank within a card when that blank
 * is past the card's middle, else at the card's width. */
static void put_history_entry(fitsfile *fp, const char *e, size_t n, int *st)
{
    char card[CUBE_HISTORY_CARD + 1];
    while (n > 0 && !*st) {
        size_t take = n;
        if (take > CUBE_HISTORY_CARD) {
            take = CUBE_HISTORY_CARD;
            for (size_t k = CUBE_HISTORY_CARD; k > CUBE_HISTORY_CARD / 2; k--)
                if (e[k] == ' ') {
                    take = k;
                    break;
                }
        }
        for (size_t i = 0; i < take; i++)
            card[i] = e[i] >= ' ' && e[i] <= '~' ? e[i] : '?';
        card[take] = '\0';
        fits_write_history(fp, card, st);
        e += take, n -= take;
        while (n > 0 && *e == ' ') /* the blank the cut was made at */
            e++, n--;
    }
}

static void put_history(fitsfile *fp, const char *h, int *st)
{
    while (*h && !*st) {
        size_t n = strcspn(h, "\n");
        put_history_entry(fp, h, n, st);
        h += n + (h[n] == '\n');
    }
}

void cube_header_take_history(cube_meta *m, const char *text)
{
    size_t used = strnlen(m->history, sizeof m->history);
    size_t n = strlen(text);
    while (n > 0 && text[n - 1] == ' ')
        n--;
    if (used + n + 2 > CUBE_HISTORY_MAX / 2) {
        m->ndropped++;
        return;
    }
    memcpy(m->history + used, text, n);
    m->history[used + n] = '\n';
    m->history[used + n + 1] = '\0';
}

/* ---- the whole header --------------------------------------------------- */

void cube_header_write(fitsfile *fp, const cube_meta *m, int width,
                       int height, int with_date_obs, int *st)
{
    char creator[CUBE_STR_MAX];
    if (m && m->creator[0])
        snprintf(creator, sizeof creator, "%s", m->creator);
    else
        snprintf(creator, sizeof creator, "specklab %s", SPECKLAB_VERSION);
    put_meta(fp, m, with_date_obs, st);
    fits_write_date(fp, st);
    fits_update_key_str(fp, "CREATOR", creator, "software that wrote this file", st);
    put_wcs(fp, m, width, height, st);
    if (m)
        put_history(fp, m->history, st);
}

/* ---- reading ------------------------------------------------------------ */

/* FITS string value 'it''s  ' -> it's (trailing blanks are not
 * significant in FITS strings, leading ones are). */
static void unquote(const char *val, char out[CUBE_STR_MAX])
{
    size_t n = 0;
    for (const char *p = val + 1; *p && n < CUBE_STR_MAX - 1; p++) {
        if (*p == '\'' && p[1] != '\'')
            break;
        if (*p == '\'')
            p++;
        out[n++] = *p;
    }
    while (n > 0 && out[n - 1] == ' ')
        n--;
    out[n] = '\0';
}

/* Numeric value text to double; FITS allows a Fortran 'D' exponent. */
static int parse_num(const char *val, double *out)
{
    char buf[FLEN_VALUE];
    char *end;
    snprintf(buf, sizeof buf, "%s", val);
    for (char *p = buf; *p; p++)
        if (*p == 'D' || *p == 'd')
            *p = 'E';
    *out = strtod(buf, &end);
    while (*end == ' ')
        end++;
    return end != buf && *end == '\0';
}

/* Standard field for key with value text val: 1 taken (or dropped as
 * unusable), 0 not a standard keyword.  Lenient on purpose: a metadata
 * quirk (OBJECT = 123, EXPTIME = '0.01') must not make frames unreadable. */
static int take_standard(cube_meta *m, const char *key, const char *val,
                         char dtype)
{
    char *s = !strcmp(key, "DATE-OBS") ? m->date_obs
            : !strcmp(key, "INSTRUME") ? m->instrume
            : !strcmp(key, "OBJECT")   ? m->object
            : !strcmp(key, "BUNIT")    ? m->bunit : NULL;
    double *d = !strcmp(key, "EXPTIME")    ? &m->exptime_s
              : !strcmp(key, "PLTSCALE") ? &m->plate_scale_arcsec
              : !strcmp(key, "PIXASPCT") ? &m->pixel_aspect
              : !strcmp(key, "WAVELEN")  ? &m->wavelength_m
              : !strcmp(key, "RA")       ? &m->ra_deg
              : !strcmp(key, "DEC")      ? &m->dec_deg : NULL;
    char txt[CUBE_STR_MAX];
    if (dtype == 'C')
        unquote(val, txt);
    else
        snprintf(txt, sizeof txt, "%.*s", (int)sizeof txt - 1, val);
    if (s)
        memcpy(s, txt, sizeof txt);
    else if (d && !parse_num(txt, d))
        m->ndropped++; /* stays NaN */
    return s || d;
}

/* Logicals enter as numbers 0/1 (the public setters have no logical);
 * flag them so that writing restores T/F. */
static void mark_bool(cube_meta *m, const char *key)
{
    for (int i = 0; i < m->nextra; i++)
        if (strcasecmp(m->extra[i].key, key) == 0)
            m->extra[i].type = CUBE_KV_BOOL;
}

/* One header card into m: a standard field, an extra, or skipped. */
static void take_card(cube_meta *m, const char *key, const char *val,
                      const char *comment, int compressed)
{
    char dtype = 0;
    int st = 0;
    if (!strcmp(key, "HISTORY")) {
        cube_header_take_history(m, comment);
        return;
    }
    if (val[0] == '\0')
        return; /* other commentary card */
    /* A tile-compressed image exposes its binary-table keywords. */
    if (compressed && (key[0] == 'Z' || !strcmp(key, "TFIELDS") ||
                       !strncmp(key, "TTYPE", 5) || !strncmp(key, "TFORM", 5)))
        return;
    fits_get_keytype(val, &dtype, &st);
    if (take_standard(m, key, val, dtype))
        return;
    int rc;
    char str[CUBE_STR_MAX];
    double num = dtype == 'L' ? (val[0] == 'T') : 0.0;
    if (dtype == 'C') {
        unquote(val, str);
        rc = cube_meta_set_str(m, key, str, comment);
    } else if (!st && (dtype == 'L' || parse_num(val, &num))) {
        rc = cube_meta_set_num(m, key, num, comment);
    } else {
        rc = SL_ERANGE; /* complex or unparsable value */
    }
    if (rc == SL_OK && dtype == 'L')
        mark_bool(m, key);
    if (rc == SL_ERANGE)
        m->ndropped++;
    /* SL_EINVAL: structural or unusable name (HIERARCH): not an extra */
}

int cube_header_read(fitsfile *fp, cube_meta *m, const char *path, sl_err *err)
{
    int nkeys = 0, st = 0, rc = SL_OK;
    cube_meta_init(m);
    int compressed = fits_is_compressed_image(fp, &st);
    fits_get_hdrspace(fp, &nkeys, NULL, &st);
    for (int i = 1; i <= nkeys && !st; i++) {
        char key[FLEN_KEYWORD], val[FLEN_VALUE], com[FLEN_COMMENT];
        if (fits_read_keyn(fp, i, key, val, com, &st) == 0)
            take_card(m, key, val, com, compressed);
    }
    if (st) {
        char msg[FLEN_STATUS];
        fits_get_errstatus(st, msg);
        rc = sl_seterr(err, SL_EFORMAT, "%s: cannot read the header (%s)",
                       path, msg);
    }
    return rc;
}
