/* config.c - GKeyFile configuration over embedded defaults; see config.h.
 *
 * Reading is two-layered: the defaults text is parsed first, the file's
 * values replace them key by key (screens/masks list by list), and only
 * then is anything validated, so an error names the key that is wrong
 * whichever layer set it.
 */
#include "config.h"
#include "pipeline/pipeline.h"
#include "webconf.h"

#include <errno.h>
#include <glib.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char *const known_keys[][20] = {
    {"camera", "backend", "address", "exposure_us", "pixel_format",
     "frame_rate_hz", "roi", "buffers", "plate_scale_arcsec", "wavelength_nm",
     "lost_timeout_s", "max_failed_frames", "gain_e_per_adu", "read_noise_e",
     "heartbeat_timeout_ms", "source", "source_args", NULL},
    {"stage", "backend", "address", "unit", "device", "baud", "parity",
     "move_timeout_ms", "settle_ms", "response_timeout_ms", "call_timeout_ms",
     NULL},
    {"paths", "data_dir", "catalog", NULL},
    {"daemon", "socket", "reconstruct", "projections", "tsm_phases", "skips", "fftw", "max_clients",
     "client_idle_timeout_ms", "catalog_busy_timeout_ms", NULL},
    {"calibration", "dark", "flat", "flat_dark", "badpix", "catalogued", NULL},
    {"web", "listen", "allow_remote", "max_connections", NULL},
};

/* The CLI's names (pipeline_method_parse), so that both accept the same
 * methods and auto is the default of both; "none": no reconstruction. */
int config_method_valid(const char *name)
{
    int m;
    return name && (!strcmp(name, "none") || pipeline_method_parse(name, &m) == SL_OK);
}

/* Names become catalogue keys and FITS values, never paths; still, keep
 * them plain so they can never be mistaken for one.  Nor for a slot
 * number as find() reads one: "1", but also "+1" or "-0" (found by
 * fuzzing: start-run's screen "+1" meant slot 1, not the screen "+1"). */
static int name_ok(const char *s)
{
    size_t n = strlen(s);
    char *end = NULL;
    (void)strtol(s, &end, 10);
    return n >= 1 && n <= 64 && strspn(s, "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                          "abcdefghijklmnopqrstuvwxyz"
                                          "0123456789_.+-") == n &&
           !strstr(s, "..") && *end != '\0';
}

/* Every key of the file is known (slot groups: keys are slot numbers). */
/* The bytes of an unknown group's name an error message shows. */
#define CONFIG_GROUP_SHOWN 64

static int check_keys(GKeyFile *kf, const char *path, sl_err *err)
{
    gsize ng = 0;
    gchar **groups = g_key_file_get_groups(kf, &ng);
    int rc = SL_OK;
    for (gsize g = 0; g < ng && rc == SL_OK; g++) {
        const char *const *known = NULL;
        int slots = !strcmp(groups[g], "screens") || !strcmp(groups[g], "masks");
        for (size_t i = 0; i < G_N_ELEMENTS(known_keys); i++)
            if (!strcmp(known_keys[i][0], groups[g]))
                known = known_keys[i] + 1;
        if (!known && !slots) {
            /* A name longer than CONFIG_GROUP_SHOWN is cut here, so the
             * message, not the buffer, decides what is dropped. */
            size_t n = strlen(groups[g]);
            rc = sl_seterr(err, SL_EINVAL, "%s: unknown group [%.*s%s", path,
                           (int)(n > CONFIG_GROUP_SHOWN ? CONFIG_GROUP_SHOWN : n), groups[g],
                           n > CONFIG_GROUP_SHOWN ? "...] (a name of over 64 bytes)" : "]");
            break;
        }
        gchar **keys = g_key_file_get_keys(kf, groups[g], NULL, NULL);
        for (int k = 0; keys && keys[k] && rc == SL_OK; k++) {
            int ok = 0;
            if (slots) {
                char *end = NULL;
                long v = strtol(keys[k], &end, 10);
                ok = end != keys[k] && !*end && v >= 0 && v < CONFIG_MAX_SLOTS;
            }
            for (int i = 0; !slots && known[i]; i++)
                ok |= !strcmp(known[i], keys[k]);
            if (!ok)
                rc = sl_seterr(err, SL_EINVAL, "%s: [%s] %s: unknown key%s", path,
                               groups[g], keys[k],
                               slots ? " (expected a slot number 0..15)" : "");
        }
        g_strfreev(keys);
    }
    g_strfreev(groups);
    return rc;
}

/* Copy every key of src over dst; a slot group replaces dst's as a whole. */
static void overlay(GKeyFile *dst, GKeyFile *src)
{
    gchar **groups = g_key_file_get_groups(src, NULL);
    for (int g = 0; groups[g]; g++) {
        if (!strcmp(groups[g], "screens") || !strcmp(groups[g], "masks"))
            g_key_file_remove_group(dst, groups[g], NULL);
        gchar **keys = g_key_file_get_keys(src, groups[g], NULL, NULL);
        for (int k = 0; keys && keys[k]; k++) {
            gchar *v = g_key_file_get_value(src, groups[g], keys[k], NULL);
            g_key_file_set_value(dst, groups[g], keys[k], v);
            g_free(v);
        }
        g_strfreev(keys);
    }
    g_strfreev(groups);
}

/* The key's value, unescaped and stripped, or NULL when the key is
 * absent.  A key that is there but unreadable (not UTF-8, a bad escape)
 * is an error naming it: it must not fall back to the default (found by
 * fuzzing). */
static int get_value(GKeyFile *kf, const char *g, const char *k, char **out, sl_err *err)
{
    GError *ge = NULL;
    *out = g_key_file_get_string(kf, g, k, &ge);
    if (*out) {
        g_strstrip(*out);
        return SL_OK;
    }
    int rc = SL_OK;
    if (g_key_file_has_key(kf, g, k, NULL))
        rc = sl_seterr(err, SL_EINVAL, "config [%s] %s: %s", g, k,
                       ge ? ge->message : "unreadable value");
    if (ge)
        g_error_free(ge);
    return rc;
}

/* Typed getters: a missing key gives def; a bad value is an error naming
 * the key.  Numbers are parsed in the C locale (g_ascii_strtod). */
static int get_str(GKeyFile *kf, const char *g, const char *k, const char *def,
                   char **out, sl_err *err)
{
    int rc = get_value(kf, g, k, out, err);
    if (!*out)
        *out = g_strdup(def);
    return rc;
}

static int get_num(GKeyFile *kf, const char *g, const char *k, double def,
                   double lo, double hi, double *out, sl_err *err)
{
    gchar *v = NULL;
    char *end = NULL;
    int rc = get_value(kf, g, k, &v, err);
    *out = def;
    if (!v)
        return rc;
    double x = g_ascii_strtod(v, &end);
    if (end == v || *end || !(x >= lo && x <= hi))
        rc = sl_seterr(err, SL_EINVAL, "config [%s] %s = '%s': expected a number in "
                       "%g..%g", g, k, v, lo, hi);
    else
        *out = x;
    g_free(v);
    return rc;
}

/* A two-way choice: *out = 1 for yes (also the default), 0 for no. */
static int get_flag(GKeyFile *kf, const char *g, const char *k, const char *yes,
                    const char *no, int *out, sl_err *err)
{
    char *v = NULL;
    int rc = get_str(kf, g, k, yes, &v, err);
    *out = rc == SL_OK && !strcmp(v, yes);
    if (rc == SL_OK && !*out && strcmp(v, no))
        rc = sl_seterr(err, SL_EINVAL, "config [%s] %s = '%s': expected %s or %s", g, k, v,
                       yes, no);
    g_free(v);
    return rc;
}

static int get_int(GKeyFile *kf, const char *g, const char *k, int def, int lo,
                   int hi, int *out, sl_err *err)
{
    double x;
    int rc = get_num(kf, g, k, def, lo, hi, &x, err);
    if (rc == SL_OK && x != floor(x))
        rc = sl_seterr(err, SL_EINVAL, "config [%s] %s = %g: expected an integer", g, k, x);
    *out = (int)x;
    return rc;
}

static int slot_cmp(const void *a, const void *b)
{
    return ((const config_slot *)a)->slot - ((const config_slot *)b)->slot;
}

static int get_slots(GKeyFile *kf, const char *g, int masks, config_slot *out,
                     int *n, sl_err *err)
{
    gchar **keys = g_key_file_get_keys(kf, g, NULL, NULL);
    int rc = SL_OK;
    *n = 0;
    for (int k = 0; keys && keys[k] && rc == SL_OK; k++) {
        char *end = NULL;
        long slot = strtol(keys[k], &end, 10);
        gchar *v = NULL;
        if ((rc = get_value(kf, g, keys[k], &v, err)) != SL_OK)
            break;
        char *colon = v && masks ? strchr(v, ':') : NULL;
        if (colon)
            *colon = '\0';
        if (v)
            g_strstrip(v);
        if (end == keys[k] || *end || slot < 0 || slot >= CONFIG_MAX_SLOTS || !v ||
            !name_ok(v)) {
            rc = sl_seterr(err, SL_EINVAL, "config [%s] %s = '%s': expected SLOT=NAME with "
                           "slot 0..%d and a non-numeric name of 1..64 characters "
                           "[A-Za-z0-9_.+-]%s",
                           g, keys[k], v ? v : "", CONFIG_MAX_SLOTS - 1,
                           masks ? " (optionally :MASKFILE)" : "");
        } else {
            for (int i = 0; i < *n && rc == SL_OK; i++)
                if (!strcmp(out[i].name, v))
                    rc = sl_seterr(err, SL_EINVAL, "config [%s]: name '%s' in slots %d "
                                   "and %ld", g, v, out[i].slot, slot);
                else if (out[i].slot == slot)   /* "1" and "01" (found by fuzzing) */
                    rc = sl_seterr(err, SL_EINVAL, "config [%s] %s: slot %ld is given "
                                   "twice ('%s' and '%s')", g, keys[k], slot, out[i].name,
                                   v);
        }
        if (rc == SL_OK) {
            out[*n].slot = (int)slot;
            out[*n].name = g_strdup(v);
            out[*n].file = colon && *g_strstrip(colon + 1) ? g_strdup(g_strstrip(colon + 1)) : NULL;
            (*n)++;
        }
        g_free(v);
    }
    g_strfreev(keys);
    if (rc == SL_OK && *n == 0)
        rc = sl_seterr(err, SL_EINVAL, "config [%s]: no slots", g);
    qsort(out, (size_t)*n, sizeof *out, slot_cmp);
    return rc;
}

/* "x,y,w,h" or empty. */
static int get_roi(GKeyFile *kf, int roi[4], sl_err *err)
{
    gchar *v = NULL;
    int rc = get_value(kf, "camera", "roi", &v, err);
    char tail;
    memset(roi, 0, 4 * sizeof *roi);
    if (v && *v &&
        (sscanf(v, "%d,%d,%d,%d%c", &roi[0], &roi[1], &roi[2], &roi[3], &tail) != 4 ||
         roi[0] < 0 || roi[1] < 0 || roi[2] < 8 || roi[3] < 8))
        rc = sl_seterr(err, SL_EINVAL, "config [camera] roi = '%s': expected X,Y,W,H "
                       "with W, H >= 8", v);
    g_free(v);
    return rc;
}

/* "HOST:PORT" -> host, port. */
static int split_address(const char *a, char **host, int *port, sl_err *err)
{
    const char *colon = strrchr(a, ':');
    char *end = NULL;
    long p = colon ? strtol(colon + 1, &end, 10) : -1;
    if (!colon || colon == a || end == colon + 1 || *end || p < 1 || p > 65535)
        return sl_seterr(err, SL_EINVAL, "config [stage] address = '%s': expected "
                         "HOST:PORT", a);
    *host = g_strndup(a, (size_t)(colon - a));
    *port = (int)p;
    return SL_OK;
}

static char *absolute(const char *p)
{
    if (g_path_is_absolute(p))
        return g_canonicalize_filename(p, NULL);
    gchar *cwd = g_get_current_dir();
    gchar *r = g_canonicalize_filename(p, cwd);
    g_free(cwd);
    return r;
}

/* A path; empty: DIR/LEAF. */
static int get_path(GKeyFile *kf, const char *g, const char *k, const char *dir,
                    const char *leaf, char **out, sl_err *err)
{
    char *s = NULL;
    int rc = get_str(kf, g, k, "", &s, err);
    if (rc == SL_OK)
        *out = *s ? absolute(s) : g_build_filename(dir, leaf, NULL);
    g_free(s);
    return rc;
}

/* [stage]; parity one of N, E, O (either case). */
static int read_stage(config *c, GKeyFile *kf, sl_err *err)
{
    int rc;
    char *s = NULL;
    if ((rc = get_str(kf, "stage", "backend", "tcp", &c->stage_backend, err)) ||
        (rc = get_str(kf, "stage", "device", "", &c->stage_device, err)))
        return rc;
    if (strcmp(c->stage_backend, "tcp") && strcmp(c->stage_backend, "rtu"))
        return sl_seterr(err, SL_EINVAL, "config [stage] backend = '%s': expected tcp or rtu",
                         c->stage_backend);
    if ((rc = get_str(kf, "stage", "address", "127.0.0.1:1502", &s, err)) == SL_OK &&
        !strcmp(c->stage_backend, "tcp"))
        rc = split_address(s, &c->stage_host, &c->stage_port, err);
    g_free(s);
    if (rc || (rc = get_int(kf, "stage", "unit", 1, 0, 247, &c->stage_unit, err)) ||
        (rc = get_int(kf, "stage", "baud", 19200, 300, 4000000, &c->stage_baud, err)) ||
        (rc = get_int(kf, "stage", "move_timeout_ms", 15000, 100, 600000, &c->move_timeout_ms,
                      err)) ||
        (rc = get_int(kf, "stage", "settle_ms", 250, 0, 60000, &c->settle_ms, err)) ||
        (rc = get_int(kf, "stage", "response_timeout_ms", 500, 10, 60000,
                      &c->response_timeout_ms, err)) ||
        (rc = get_int(kf, "stage", "call_timeout_ms", 2000, 10, 600000, &c->call_timeout_ms,
                      err)))
        return rc;
    if ((rc = get_str(kf, "stage", "parity", "E", &s, err)) == SL_OK) {
        c->stage_parity = (char)g_ascii_toupper(s[0]);
        if (strlen(s) != 1 || !strchr("NEO", c->stage_parity))
            rc = sl_seterr(err, SL_EINVAL, "config [stage] parity = '%s': expected N "
                           "(none), E (even) or O (odd)", s);
    }
    g_free(s);
    return rc;
}

static int read_values(config *c, GKeyFile *kf, sl_err *err)
{
    int rc = SL_OK;
    char *s = NULL;
    if ((rc = get_str(kf, "camera", "backend", "aravis", &c->camera_backend, err)) ||
        (rc = get_str(kf, "camera", "address", "127.0.0.1", &c->camera_address, err)) ||
        (rc = get_str(kf, "camera", "pixel_format", "Mono16", &c->pixel_format, err)))
        return rc;
    if (strcmp(c->pixel_format, "Mono16") && strcmp(c->pixel_format, "Mono8"))
        return sl_seterr(err, SL_EINVAL, "config [camera] pixel_format = '%s': expected "
                         "Mono16 or Mono8", c->pixel_format);
    if ((rc = get_str(kf, "camera", "source", NULL, &c->camera_source, err)) ||
        (rc = get_str(kf, "camera", "source_args", "", &c->camera_source_args, err)))
        return rc;
    if (c->camera_source && !c->camera_source[0])
        g_clear_pointer(&c->camera_source, g_free);
    if (c->camera_source && strcmp(c->camera_backend, "fake") != 0)
        return sl_seterr(err, SL_EINVAL, "config [camera] source = '%s': only the fake "
                         "backend takes a source (backend = %s)", c->camera_source,
                         c->camera_backend);
    if ((rc = get_num(kf, "camera", "exposure_us", 10000, 1, 1e7, &c->exposure_us, err)) ||
        (rc = get_num(kf, "camera", "frame_rate_hz", NAN, 0.01, 1e5, &c->frame_rate_hz, err)) ||
        (rc = get_roi(kf, c->roi, err)) ||
        (rc = get_int(kf, "camera", "buffers", 32, 2, 1024, &c->buffers, err)) ||
        (rc = get_num(kf, "camera", "plate_scale_arcsec", 0.0593480101610963, 1e-6, 1e3,
                      &c->plate_scale_arcsec, err)) ||
        (rc = get_num(kf, "camera", "wavelength_nm", 633, 100, 30000, &c->wavelength_m, err)) ||
        (rc = get_num(kf, "camera", "lost_timeout_s", 10, 0.5, 3600, &c->lost_timeout_s, err)) ||
        (rc = get_int(kf, "camera", "heartbeat_timeout_ms", 6000, 500, 600000,
                      &c->heartbeat_timeout_ms, err)) ||
        (rc = get_int(kf, "camera", "max_failed_frames", 0, 0, INT_MAX, &c->max_failed_frames,
                      err)) ||
        (rc = get_num(kf, "camera", "gain_e_per_adu", NAN, 1e-4, 1e4, &c->gain_e_per_adu, err)) ||
        (rc = get_num(kf, "camera", "read_noise_e", NAN, 0, 1e4, &c->read_noise_e, err)))
        return rc;
    c->wavelength_m *= 1e-9;
    if ((rc = read_stage(c, kf, err)))
        return rc;
    if ((rc = get_slots(kf, "screens", 0, c->screens, &c->nscreens, err)) ||
        (rc = get_slots(kf, "masks", 1, c->masks, &c->nmasks, err)))
        return rc;
    if ((rc = get_str(kf, "paths", "data_dir", "./var", &s, err)) == SL_OK)
        c->data_dir = absolute(*s ? s : ".");
    g_free(s);
    if (rc || (rc = get_path(kf, "paths", "catalog", c->data_dir, "specklab.db", &c->catalog,
                             err)) ||
        (rc = get_path(kf, "daemon", "socket", c->data_dir, "specklabd.sock", &c->socket,
                       err)) ||
        (rc = get_str(kf, "daemon", "reconstruct", "auto", &c->reconstruct, err)))
        return rc;
    if (!config_method_valid(c->reconstruct))
        return sl_seterr(err, SL_EINVAL, "config [daemon] reconstruct = '%s': expected auto, "
                         "direct, tsm, tsm-fourier or none", c->reconstruct);
    if ((rc = get_flag(kf, "daemon", "tsm_phases", "corrected", "raw",
                       &c->tsm_corrected_phases, err)) ||
        (rc = get_flag(kf, "daemon", "fftw", "measure", "estimate", &c->fftw_measure, err)))
        return rc;
    if ((rc = get_str(kf, "daemon", "skips", "reject,crop,support", &s, err)) == SL_OK &&
        pipeline_skips_parse(s, &c->skips) != SL_OK)
        rc = sl_seterr(err, SL_EINVAL, "config [daemon] skips = '%s': expected a list of "
                       "reject, crop, support, angles, or all, none", s);
    g_free(s);
    if (rc)
        return rc;
    if ((rc = get_int(kf, "daemon", "projections", 0, 0, 4096, &c->projections, err)) ||
        (rc = get_int(kf, "daemon", "max_clients", 64, 1, 4096, &c->max_clients, err)) ||
        (rc = get_int(kf, "daemon", "client_idle_timeout_ms", 30000, 100, 86400000,
                      &c->client_idle_timeout_ms, err)) ||
        (rc = get_int(kf, "daemon", "catalog_busy_timeout_ms", 5000, 10, 600000,
                      &c->catalog_busy_timeout_ms, err)))
        return rc;
    return SL_OK;
}

/* A calibration file: absolute, and there now (a typo found at start-up,
 * not at the end of every run); "" is none. */
static int get_calibration(GKeyFile *kf, const char *k, char **out, sl_err *err)
{
    char *s = NULL;
    int rc = get_str(kf, "calibration", k, "", &s, err);
    if (rc == SL_OK && *s) {
        *out = absolute(s);
        if (!g_file_test(*out, G_FILE_TEST_IS_REGULAR))
            rc = sl_seterr(err, SL_EINVAL, "config [calibration] %s = '%s': no such file",
                           k, *out);
    }
    g_free(s);
    return rc;
}

static int read_calibrations(config *c, GKeyFile *kf, sl_err *err)
{
    int rc;
    if ((rc = get_calibration(kf, "dark", &c->calib_dark, err)) ||
        (rc = get_calibration(kf, "flat", &c->calib_flat, err)) ||
        (rc = get_calibration(kf, "flat_dark", &c->calib_flat_dark, err)) ||
        (rc = get_calibration(kf, "badpix", &c->calib_badpix, err)) ||
        (rc = get_flag(kf, "calibration", "catalogued", "yes", "no", &c->calib_catalogued, err)))
        return rc;
    if (c->calib_flat_dark && !c->calib_flat)
        return sl_seterr(err, SL_EINVAL, "config [calibration] flat_dark = '%s' without a "
                         "flat", c->calib_flat_dark);
    return SL_OK;
}

/* [web]: the listener is checked by webconf.c (loopback unless allowed). */
static int read_web(config *c, GKeyFile *kf, sl_err *err)
{
    char *listen = NULL;
    int local_only = 1;   /* get_flag: 1 for its first choice, the default */
    int rc = get_flag(kf, "web", "allow_remote", "no", "yes", &local_only, err);
    if (rc == SL_OK && (rc = get_str(kf, "web", "listen", "", &listen, err)) == SL_OK &&
        (rc = get_int(kf, "web", "max_connections", 32, 1, 1024, &c->web_max_connections,
                      err)) == SL_OK)
        rc = webconf_set(c, "config [web] listen", listen, !local_only,
                         "[web] allow_remote = yes", err);
    g_free(listen);
    return rc;
}

int config_load(config *c, const char *path, const char *socket_override,
                const char *data_dir_override, sl_err *err)
{
    GKeyFile *kf = g_key_file_new(), *file = NULL;
    GError *ge = NULL;
    int rc = SL_OK;
    memset(c, 0, sizeof *c);
    if (!g_key_file_load_from_data(kf, config_defaults_text(), (gsize)-1,
                                   G_KEY_FILE_NONE, &ge)) {
        rc = sl_seterr(err, SL_EINVAL, "built-in defaults: %s", ge->message);
        goto free_kf;
    }
    if (path) {
        file = g_key_file_new();
        if (!g_key_file_load_from_file(file, path, G_KEY_FILE_NONE, &ge)) {
            rc = sl_seterr(err, ge->domain == G_FILE_ERROR ? SL_EIO : SL_EINVAL,
                           "config %s: %s", path, ge->message);
            goto free_kf;
        }
        if ((rc = check_keys(file, path, err)) != SL_OK)
            goto free_kf;
        overlay(kf, file);
    }
    if (data_dir_override) {
        g_key_file_set_string(kf, "paths", "data_dir", data_dir_override);
        /* The derived paths follow the new data directory unless the file
         * named them explicitly. */
        if (!file || !g_key_file_has_key(file, "paths", "catalog", NULL))
            g_key_file_set_string(kf, "paths", "catalog", "");
        if (!file || !g_key_file_has_key(file, "daemon", "socket", NULL))
            g_key_file_set_string(kf, "daemon", "socket", "");
    }
    if (socket_override)
        g_key_file_set_string(kf, "daemon", "socket", socket_override);
    if ((rc = read_values(c, kf, err)) == SL_OK && (rc = read_calibrations(c, kf, err)) == SL_OK)
        rc = read_web(c, kf, err);
free_kf:
    if (ge)
        g_error_free(ge);
    if (file)
        g_key_file_free(file);
    g_key_file_free(kf);
    if (rc != SL_OK)
        config_clear(c);
    return rc;
}

void config_clear(config *c)
{
    g_free(c->camera_backend);
    g_free(c->camera_address);
    g_free(c->pixel_format);
    g_free(c->camera_source);
    g_free(c->camera_source_args);
    g_free(c->stage_backend);
    g_free(c->stage_host);
    g_free(c->stage_device);
    for (int i = 0; i < c->nscreens; i++)
        g_free(c->screens[i].name), g_free(c->screens[i].file);
    for (int i = 0; i < c->nmasks; i++)
        g_free(c->masks[i].name), g_free(c->masks[i].file);
    g_free(c->data_dir);
    g_free(c->catalog);
    g_free(c->socket);
    g_free(c->reconstruct);
    g_free(c->calib_dark);
    g_free(c->calib_flat);
    g_free(c->calib_flat_dark);
    g_free(c->calib_badpix);
    g_free(c->web_host);
    memset(c, 0, sizeof *c);
}

static const config_slot *find(const config_slot *v, int n, const char *key)
{
    char *end = NULL;
    long slot = key ? strtol(key, &end, 10) : -1;
    int numeric = key && end != key && !*end;
    for (int i = 0; key && i < n; i++)
        if (numeric ? v[i].slot == slot : !strcmp(v[i].name, key))
            return &v[i];
    return NULL;
}

const config_slot *config_screen_find(const config *c, const char *name_or_slot)
{
    return find(c->screens, c->nscreens, name_or_slot);
}

const config_slot *config_mask_find(const config *c, const char *name_or_slot)
{
    return find(c->masks, c->nmasks, name_or_slot);
}

const config_slot *config_screen_at(const config *c, int slot)
{
    for (int i = 0; i < c->nscreens; i++)
        if (c->screens[i].slot == slot)
            return &c->screens[i];
    return NULL;
}

const config_slot *config_mask_at(const config *c, int slot)
{
    for (int i = 0; i < c->nmasks; i++)
        if (c->masks[i].slot == slot)
            return &c->masks[i];
    return NULL;
}
