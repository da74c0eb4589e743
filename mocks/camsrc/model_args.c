/* model_args.c - the camera mocks' shared option parsing: sensor size,
 * r0 per screen slot and the mask slots (fakecam_app.h).
 */
#include <math.h>
#include <stdlib.h>

#include "fakecam_app.h"

int fakecam_parse_size(const char *text, int *w, int *h, sl_err *e)
{
    char *end = NULL;
    long a = strtol(text, &end, 10), b = a;
    if (end != text && (*end == 'x' || *end == 'X')) {
        const char *rest = end + 1;
        b = strtol(rest, &end, 10);
        if (end == rest)
            b = -1;
    }
    if (end == text || *end || a < 8 || b < 8 || a > 4096 || b > 4096)
        return sl_seterr(e, SL_EINVAL, "--size '%s': expected N or WxH, 8..4096", text);
    *w = (int)a;
    *h = (int)b;
    return SL_OK;
}

/* "inf,0.25,0.15": one r0 per screen slot; inf/open = no turbulence. */
int fakecam_parse_r0(const char *text, fakecam_model *m, sl_err *e)
{
    gchar **v = g_strsplit(text, ",", -1);
    int n = 0, rc = SL_OK;
    for (; v[n] && rc == SL_OK; n++) {
        char *s = g_strstrip(v[n]), *end = NULL;
        if (n >= FAKECAM_MAX_SLOTS) {
            rc = sl_seterr(e, SL_EINVAL, "--screen-r0: at most %d slots", FAKECAM_MAX_SLOTS);
        } else if (!g_ascii_strcasecmp(s, "inf") || !g_ascii_strcasecmp(s, "open")) {
            m->r0_m[n] = INFINITY;
        } else {
            m->r0_m[n] = g_ascii_strtod(s, &end);
            if (end == s || *end || !(m->r0_m[n] > 0) || !isfinite(m->r0_m[n]))
                rc = sl_seterr(e, SL_EINVAL, "--screen-r0: '%s' is not an r0 in metres "
                               "(or inf)", s);
        }
    }
    g_strfreev(v);
    if (rc == SL_OK && n == 0)
        rc = sl_seterr(e, SL_EINVAL, "--screen-r0: no slots");
    m->n_screens = n;
    return rc;
}

int fakecam_load_masks(const char *text, mask **masks, int *n, sl_err *e)
{
    gchar **v = g_strsplit(text, ",", -1);
    int rc = SL_OK;
    *n = 0;
    for (int i = 0; v[i] && rc == SL_OK; i++) {
        char *s = g_strstrip(v[i]);
        if (*n >= FAKECAM_MAX_SLOTS)
            rc = sl_seterr(e, SL_EINVAL, "--mask-slots: at most %d slots", FAKECAM_MAX_SLOTS);
        else if ((rc = fakecam_mask(s, &masks[*n], e)) == SL_OK)
            (*n)++;
    }
    g_strfreev(v);
    if (rc == SL_OK && *n == 0)
        rc = sl_seterr(e, SL_EINVAL, "--mask-slots: no slots");
    return rc;
}

int fakecam_model_from_args(const char *size, const char *screen_r0, const char *mask_slots,
                            fakecam_model *m, mask **masks, int *nmasks, sl_err *e)
{
    fakecam_model_defaults(m);
    *nmasks = 0;
    int rc = fakecam_parse_size(size, &m->sensor_w, &m->sensor_h, e);
    if (rc == SL_OK)
        rc = fakecam_parse_r0(screen_r0, m, e);
    if (rc == SL_OK)
        rc = fakecam_load_masks(mask_slots, masks, nmasks, e);
    if (rc != SL_OK) {
        for (int i = 0; i < *nmasks; i++)
            mask_free(masks[i]);
        *nmasks = 0;
    }
    return rc;
}
