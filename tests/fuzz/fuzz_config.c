/* fuzz_config.c - libFuzzer target: specklabd's configuration file
 * (daemon/config.c: GKeyFile over the embedded defaults, then checks).
 *
 * The input is the file, put in a memfd read as /proc/self/fd/N, loaded
 * as the daemon loads it (config_load, no overrides), then once more with
 * --data-dir and --socket overrides.  Contract checks abort (a finding):
 *   - a refusal carries SL_EINVAL or SL_EIO and a message that names the
 *     file (when GKeyFile cannot parse it: the harness's own GKeyFile
 *     parse decides) or a group in brackets, "[camera]" or the like;
 *   - a key of a known group that GKeyFile cannot read as a string
 *     (invalid escape, invalid UTF-8) is refused, never replaced by the
 *     default in silence (config.h: a typo must not fall back);
 *   - an accepted configuration has every value in the range
 *     specklabd.conf.example documents, 1..16 screens and masks with
 *     distinct slots in 0..15 (sorted) and distinct plain names that
 *     config_*_find finds by name and by slot, absolute canonical paths,
 *     a known reconstruction method;
 *   - [stage]'s serial keys are used as written: parity (N, E or O in
 *     either case, default E) and device;
 *   - the overrides: data_dir is the override, socket the override, and
 *     the catalogue follows the data directory unless the file named it;
 *   - no leak (libFuzzer's per-input leak check).
 */
#define _GNU_SOURCE
#include <glib.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "config.h"
#define FUZZ_NAME "fuzz_config"
#include "fuzz_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static const char *const groups[] = {"camera", "stage", "screens", "masks", "paths", "daemon",
                                     "calibration", "web"};

static int in(double x, double lo, double hi)
{
    return x >= lo && x <= hi;
}

/* The ranges specklabd.conf.example and config.c's checks promise. */
static void check_values(const config *c, const char *path)
{
    require(c->camera_backend && c->camera_address && c->stage_backend && c->stage_device,
            "strings set", path);
    require(!strcmp(c->pixel_format, "Mono16") || !strcmp(c->pixel_format, "Mono8"),
            "pixel_format", c->pixel_format);
    require(in(c->exposure_us, 1, 1e7) && (isnan(c->frame_rate_hz) ||
                                           in(c->frame_rate_hz, 0.01, 1e5)),
            "exposure_us, frame_rate_hz", path);
    require((c->roi[2] == 0 && c->roi[3] == 0 && c->roi[0] == 0 && c->roi[1] == 0) ||
                (c->roi[0] >= 0 && c->roi[1] >= 0 && c->roi[2] >= 8 && c->roi[3] >= 8),
            "roi", path);
    require(in(c->buffers, 2, 1024) && in(c->plate_scale_arcsec, 1e-6, 1e3) &&
                in(c->wavelength_m, 100e-9 * (1 - 1e-12), 30000e-9 * (1 + 1e-12)) &&
                in(c->lost_timeout_s, 0.5, 3600) && c->max_failed_frames >= 0 &&
                in(c->heartbeat_timeout_ms, 500, 600000),
            "camera numbers", path);
    require((isnan(c->gain_e_per_adu) || in(c->gain_e_per_adu, 1e-4, 1e4)) &&
                (isnan(c->read_noise_e) || in(c->read_noise_e, 0, 1e4)),
            "gain_e_per_adu, read_noise_e", path);
    require(!strcmp(c->stage_backend, "tcp") || !strcmp(c->stage_backend, "rtu"),
            "stage backend", c->stage_backend);
    if (!strcmp(c->stage_backend, "tcp"))
        require(c->stage_host && c->stage_host[0] && in(c->stage_port, 1, 65535),
                "stage host:port", path);
    require(in(c->stage_unit, 0, 247) && in(c->stage_baud, 300, 4000000) &&
                in(c->move_timeout_ms, 100, 600000) && in(c->settle_ms, 0, 60000) &&
                in(c->response_timeout_ms, 10, 60000) && in(c->call_timeout_ms, 10, 600000),
            "stage numbers", path);
    const config_slot *lists[2] = {c->screens, c->masks};
    const int ns[2] = {c->nscreens, c->nmasks};
    for (int l = 0; l < 2; l++) {
        require(in(ns[l], 1, CONFIG_MAX_SLOTS), "slot count", path);
        for (int i = 0; i < ns[l]; i++) {
            const config_slot *s = &lists[l][i];
            char num[16];
            snprintf(num, sizeof num, "%d", s->slot);
            require(in(s->slot, 0, CONFIG_MAX_SLOTS - 1) && (i == 0 || s[-1].slot < s->slot),
                    "slots in 0..15, sorted, distinct", path);
            size_t n = strlen(s->name);
            require(n >= 1 && n <= 64 && !strstr(s->name, "..") &&
                        strspn(s->name, "0123456789") != n &&
                        strspn(s->name, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"
                                        "0123456789_.+-") == n,
                    "slot name", s->name);
            require(!l || !s->file || s->file[0], "mask file", s->name);
            require(l || !s->file, "screens have no file", s->name);
            const config_slot *by_name = l ? config_mask_find(c, s->name)
                                           : config_screen_find(c, s->name);
            const config_slot *by_slot = l ? config_mask_find(c, num)
                                           : config_screen_find(c, num);
            const config_slot *at = l ? config_mask_at(c, s->slot)
                                      : config_screen_at(c, s->slot);
            require(by_name == s && by_slot == s && at == s, "find by name and slot", s->name);
        }
    }
    const char *paths[3] = {c->data_dir, c->catalog, c->socket};
    for (int i = 0; i < 3; i++) {
        char *canon = paths[i] ? g_canonicalize_filename(paths[i], "/") : NULL;
        require(canon && g_path_is_absolute(paths[i]) && !strcmp(canon, paths[i]),
                "absolute canonical path", paths[i] ? paths[i] : "(null)");
        g_free(canon);
    }
    require(config_method_valid(c->reconstruct) && in(c->projections, 0, 4096) &&
                in(c->max_clients, 1, 4096) && in(c->client_idle_timeout_ms, 100, 86400000) &&
                (c->fftw_measure == 0 || c->fftw_measure == 1) &&
                (c->tsm_corrected_phases == 0 || c->tsm_corrected_phases == 1) &&
                in(c->skips, 0, 15),
            "daemon values", path);
}

/* [stage]'s serial line (the RTU backend's): what an accepted file says
 * is what the daemon opens the port with, never a default in silence. */
static void check_serial(GKeyFile *kf, const config *c, const char *path)
{
    require(c->stage_parity && strchr("NEO", c->stage_parity), "stage parity", path);
    gchar *p = g_key_file_get_string(kf, "stage", "parity", NULL);
    if (p) {
        g_strstrip(p);
        require(strlen(p) == 1 && g_ascii_toupper(p[0]) == c->stage_parity,
                "parity as written", p);
    } else {
        require(c->stage_parity == 'E', "parity default E", path);
    }
    g_free(p);
    gchar *d = g_key_file_get_string(kf, "stage", "device", NULL);
    if (d)
        require(!strcmp(g_strstrip(d), c->stage_device), "device as written", d);
    g_free(d);
}

/* A refusal names the file or a group; a parse error names the file. */
static void check_refusal(int rc, const sl_err *e, GKeyFile *kf, int parsed, const char *path)
{
    check_failure(rc, e, "config_load");
    require(rc == SL_EINVAL || rc == SL_EIO, "status", e->msg);
    if (!parsed) {
        require(strstr(e->msg, path) != NULL, "parse error names the file", e->msg);
        return;
    }
    int named = 0;
    for (size_t i = 0; i < G_N_ELEMENTS(groups); i++) {
        char *g = g_strdup_printf("[%s]", groups[i]);
        named |= strstr(e->msg, g) != NULL;
        g_free(g);
    }
    /* An unknown group is named as the file wrote it: whole, or its
     * first 64 bytes and "..." when longer. */
    gchar **gs = g_key_file_get_groups(kf, NULL);
    for (int i = 0; gs[i] && !named; i++) {
        size_t n = strlen(gs[i]);
        char *g = n > 64 ? g_strdup_printf("[%.64s...]", gs[i]) : g_strdup_printf("[%s]", gs[i]);
        named |= strstr(e->msg, g) != NULL && strstr(e->msg, "unknown group") != NULL;
        g_free(g);
    }
    g_strfreev(gs);
    require(named, "refusal names a group", e->msg);
}

/* Known groups' keys that GKeyFile cannot read as strings. */
static int unreadable_key(GKeyFile *kf)
{
    int bad = 0;
    for (size_t g = 0; g < G_N_ELEMENTS(groups) && !bad; g++) {
        gchar **keys = g_key_file_get_keys(kf, groups[g], NULL, NULL);
        for (int k = 0; keys && keys[k] && !bad; k++) {
            GError *ge = NULL;
            gchar *v = g_key_file_get_string(kf, groups[g], keys[k], &ge);
            bad = v == NULL;
            g_free(v);
            if (ge)
                g_error_free(ge);
        }
        g_strfreev(keys);
    }
    return bad;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char path[64];
    int fd = mem_file(data, size, path, sizeof path);
    if (fd < 0)
        return 0;
    GKeyFile *kf = g_key_file_new();
    int parsed = g_key_file_load_from_data(kf, (const char *)data, size, G_KEY_FILE_NONE,
                                           NULL);
    config c;
    sl_err e = {0};
    int rc = config_load(&c, path, NULL, NULL, &e);
    if (rc != SL_OK) {
        check_refusal(rc, &e, kf, parsed, path);
    } else {
        require(parsed, "accepted a file GKeyFile cannot parse", path);
        require(!unreadable_key(kf), "a key that cannot be read fell back to its default",
                path);
        check_values(&c, path);
        check_serial(kf, &c, path);
        gchar *own = g_key_file_get_string(kf, "paths", "catalog", NULL);
        int own_catalog = own && *g_strstrip(own);
        char *catalog = g_strdup(c.catalog);
        g_free(own);
        config_clear(&c);
        /* --data-dir and --socket, as the daemon's options give them. */
        sl_err e2 = {0};
        rc = config_load(&c, path, "/run/specklab/x.sock", "/srv/specklab", &e2);
        require(rc == SL_OK, "overrides of an accepted file", e2.msg);
        check_values(&c, path);
        require(!strcmp(c.data_dir, "/srv/specklab") && !strcmp(c.socket, "/run/specklab/x.sock"),
                "overrides win", c.data_dir);
        char *derived = g_build_filename("/srv/specklab", "specklab.db", NULL);
        require(!strcmp(c.catalog, own_catalog ? catalog : derived),
                "catalogue follows the data directory unless named", c.catalog);
        g_free(derived);
        g_free(catalog);
        config_clear(&c);
    }
    g_key_file_free(kf);
    close(fd);
    return 0;
}
