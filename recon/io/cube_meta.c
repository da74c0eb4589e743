/* cube_meta.c - the metadata of a FITS image (cube_meta: the standard
 * fields, the extras, HISTORY); see cube.h.  The reader (cube.c) fills it,
 * the writer (cube_write.c, cube_header.c) writes it. */
#include "cube.h"
#include "cube_header.h"

#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

/* Keywords that describe the HDU's structure, not the observation: never
 * extras (a stale NAXIS3 or DATASUM copied to another file would lie). */
static int is_structural(const char *key)
{
    static const char *const names[] = {
        "SIMPLE", "BITPIX", "NAXIS", "EXTEND", "BSCALE", "BZERO", "BLANK",
        "PCOUNT", "GCOUNT", "XTENSION", "EXTNAME", "COMMENT", "HISTORY",
        "END", "CONTINUE", "CHECKSUM", "DATASUM"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (strcmp(key, names[i]) == 0)
            return 1;
    if (strncmp(key, "NAXIS", 5) == 0 && key[5] != '\0')
        return strspn(key + 5, "0123456789") == strlen(key + 5);
    return 0;
}

static int is_standard(const char *key)
{
    static const char *const names[] = {"DATE-OBS", "EXPTIME", "INSTRUME",
                                        "OBJECT", "BUNIT", "PLTSCALE",
                                        "WAVELEN", "PIXASPCT", "RA", "DEC"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (strcmp(key, names[i]) == 0)
            return 1;
    return 0;
}

/* Upper-case key into out; 0 when it is not a usable extra name. */
static int normalise_key(const char *key, char out[CUBE_KEY_MAX])
{
    size_t n = key ? strlen(key) : 0;
    if (n == 0 || n > CUBE_KEY_MAX - 1)
        return 0;
    for (size_t i = 0; i <= n; i++)
        out[i] = (char)toupper((unsigned char)key[i]);
    if (strspn(out, "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-") != n)
        return 0;
    return !is_structural(out) && !is_standard(out) &&
           !cube_header_is_derived(out);
}

void cube_meta_init(cube_meta *m)
{
    memset(m, 0, sizeof *m);
    m->exptime_s = NAN;
    m->plate_scale_arcsec = NAN;
    m->wavelength_m = NAN;
    m->pixel_aspect = NAN;
    m->ra_deg = NAN;
    m->dec_deg = NAN;
}

static cube_kv *find_kv(const cube_meta *m, const char *key)
{
    char k[CUBE_KEY_MAX];
    size_t n = key ? strlen(key) : 0;
    if (n == 0 || n >= CUBE_KEY_MAX)
        return NULL;
    for (size_t i = 0; i <= n; i++)
        k[i] = (char)toupper((unsigned char)key[i]);
    for (int i = 0; i < m->nextra; i++)
        if (strcmp(m->extra[i].key, k) == 0)
            return (cube_kv *)&m->extra[i];
    return NULL;
}

/* The slot for key (existing or new), NULL when the list is full. */
static cube_kv *slot_kv(cube_meta *m, const char *key)
{
    cube_kv *kv = find_kv(m, key);
    if (kv || m->nextra >= CUBE_META_MAX_EXTRA)
        return kv;
    kv = &m->extra[m->nextra++];
    memset(kv, 0, sizeof *kv);
    return kv;
}

static int set_kv(cube_meta *m, const char *key, cube_kv_type type,
                  double num, const char *str, const char *comment)
{
    char k[CUBE_KEY_MAX];
    if (!m || !normalise_key(key, k))
        return SL_EINVAL;
    if (type == CUBE_KV_STR && strlen(str) >= CUBE_STR_MAX)
        return SL_ERANGE;
    cube_kv *kv = slot_kv(m, k);
    if (!kv)
        return SL_ERANGE;
    memcpy(kv->key, k, sizeof k);
    kv->type = type;
    kv->num = num;
    snprintf(kv->str, sizeof kv->str, "%s", str ? str : "");
    snprintf(kv->comment, sizeof kv->comment, "%s", comment ? comment : "");
    return SL_OK;
}

int cube_meta_set_num(cube_meta *m, const char *key, double value,
                      const char *comment)
{
    if (!isfinite(value))
        return SL_EINVAL;
    return set_kv(m, key, CUBE_KV_NUM, value, NULL, comment);
}

int cube_meta_set_str(cube_meta *m, const char *key, const char *value,
                      const char *comment)
{
    if (!value)
        return SL_EINVAL;
    return set_kv(m, key, CUBE_KV_STR, 0.0, value, comment);
}

int cube_meta_get_num(const cube_meta *m, const char *key, double *out)
{
    const cube_kv *kv = find_kv(m, key);
    if (!kv)
        return SL_EINVAL;
    if (kv->type == CUBE_KV_STR)
        return SL_EDATA;
    *out = kv->num;
    return SL_OK;
}

int cube_meta_get_str(const cube_meta *m, const char *key, const char **out)
{
    const cube_kv *kv = find_kv(m, key);
    if (!kv)
        return SL_EINVAL;
    if (kv->type != CUBE_KV_STR)
        return SL_EDATA;
    *out = kv->str;
    return SL_OK;
}


int cube_meta_add_history(cube_meta *m, const char *fmt, ...)
{
    char text[CUBE_HISTORY_MAX];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    size_t used = strnlen(m->history, sizeof m->history);
    /* the entry, its '\n' and the NUL */
    if (n < 0 || used + (size_t)n + 2 > sizeof m->history)
        return SL_ERANGE;
    memcpy(m->history + used, text, (size_t)n);
    m->history[used + (size_t)n] = '\n';
    m->history[used + (size_t)n + 1] = '\0';
    return SL_OK;
}
