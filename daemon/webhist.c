/* webhist.c - the web page's history JSON (r0 per screen over time, the
 * last reconstruction and its binary measure) and the reconstruction's
 * figure, from the catalogue through the web's own handle, cached 2 s.
 * Read-only: nothing here writes the catalogue.  Main thread only.
 */
#define _GNU_SOURCE
#include "webint.h"

#include <stdio.h>
#include <json-glib/json-glib.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "proto.h"

#define HISTORY_CACHE_US 2000000
#define HISTORY_DAYS 30
#define HISTORY_MAX_POINTS 2000
#define RECON_RUNS 20            /* done runs looked at for the last reconstruction */
#define RECON_MAX_BYTES (64 << 20)

typedef struct r0_point {
    char screen[72];
    int64_t t_ms;
    double r0_m, seeing_arcsec;
} r0_point;

static int collect_r0(const catalog_r0 *r, void *user)
{
    GArray *a = user;
    r0_point p = {{0}, r->measured_ms, r->r0_m, r->seeing_arcsec};
    g_strlcpy(p.screen, r->screen_name ? r->screen_name : "", sizeof p.screen);
    if (a->len == HISTORY_MAX_POINTS)   /* oldest first: keep the newest */
        g_array_remove_index(a, 0);
    g_array_append_val(a, p);
    return 0;
}

static void add_r0(JsonBuilder *b, web *w)
{
    GArray *a = g_array_new(FALSE, FALSE, sizeof(r0_point));
    int64_t since = catalog_now_ms() - (int64_t)HISTORY_DAYS * 86400000;
    if (w->cat && catalog_r0_list(w->cat, NULL, since, collect_r0, a) != SL_OK)
        g_message("web: r0 history: %s", catalog_errmsg(w->cat));
    json_builder_set_member_name(b, "r0");
    json_builder_begin_array(b);
    for (guint i = 0; i < a->len; i++) {
        const r0_point *p = &g_array_index(a, r0_point, i);
        json_builder_begin_object(b);
        proto_add_str(b, "screen", p->screen);
        proto_add_int(b, "t_ms", p->t_ms);
        proto_add_dbl(b, "r0_m", p->r0_m);
        proto_add_dbl(b, "seeing_arcsec", p->seeing_arcsec);
        json_builder_end_object(b);
    }
    json_builder_end_array(b);
    g_array_free(a, TRUE);
}

static int collect_uuid(const catalog_run *r, void *user)
{
    g_ptr_array_add(user, g_strdup(r->uuid));
    return 0;
}

/* The newest reconstruction of a run: copied out of the list's row. */
typedef struct last_recon {
    int found;
    gint64 id, started_ms;
    char method[32];
    double elapsed_s, sep_px, sep_err_px, pa_deg, pa_err_deg, dm_mag, dm_err_mag, sep_arcsec;
    char *params, *png;
} last_recon;

static int keep_recon(const catalog_recon *r, void *user)
{
    last_recon *l = user;
    g_free(l->params);
    g_free(l->png);
    *l = (last_recon){1, r->id, r->started_ms, "", r->elapsed_s, r->sep_px, r->sep_err_px,
                      r->pa_deg, r->pa_err_deg, r->dm_mag, r->dm_err_mag, r->sep_arcsec,
                      g_strdup(r->params_json), g_strdup(r->output_png)};
    g_strlcpy(l->method, r->method ? r->method : "", sizeof l->method);
    return 0;
}

/* params' members the page shows (worker.c writes them). */
static void add_params(JsonBuilder *b, const char *params)
{
    static const char *const keys[] = {"ran", "binary", "binary_status", "binary_why"};
    JsonNode *n = params ? proto_parse_object(params) : NULL;
    JsonObject *o = n ? json_node_get_object(n) : NULL;
    for (size_t i = 0; i < G_N_ELEMENTS(keys); i++) {
        JsonNode *m = o ? json_object_get_member(o, keys[i]) : NULL;
        proto_add_str(b, keys[i], m && JSON_NODE_HOLDS_VALUE(m) &&
                                          json_node_get_value_type(m) == G_TYPE_STRING
                                      ? json_node_get_string(m) : NULL);
    }
    if (n)
        json_node_unref(n);
}

/* A figure the worker wrote: a regular file under DATA_DIR/recon. */
static char *checked_png(const web *w, const char *path)
{
    char *dir = g_build_filename(w->cfg->data_dir, "recon", NULL);
    char *real = path ? realpath(path, NULL) : NULL, *rdir = realpath(dir, NULL);
    char *ok = NULL;
    struct stat st;
    if (real && rdir && g_str_has_prefix(real, rdir) && real[strlen(rdir)] == '/' &&
        stat(real, &st) == 0 && S_ISREG(st.st_mode) && st.st_size <= RECON_MAX_BYTES)
        ok = g_strdup(real);
    free(real);
    free(rdir);
    g_free(dir);
    return ok;
}

static void add_recon(JsonBuilder *b, web *w)
{
    GPtrArray *runs = g_ptr_array_new_with_free_func(g_free);
    catalog_run_filter f = {CATALOG_DONE, 0, 0, RECON_RUNS, CATALOG_KIND_ANY};
    last_recon l = {0};
    guint i = 0;
    if (w->cat)
        catalog_run_list(w->cat, &f, collect_uuid, runs);
    for (; i < runs->len && !l.found; i++)
        catalog_recon_list(w->cat, runs->pdata[i], keep_recon, &l);
    json_builder_set_member_name(b, "recon");
    g_clear_pointer(&w->recon_png, g_free);
    w->recon_id = 0;
    if (!l.found) {
        json_builder_add_null_value(b);
    } else {
        catalog_run r;
        int have = catalog_run_get(w->cat, runs->pdata[i - 1], &r) == SL_OK;
        json_builder_begin_object(b);
        proto_add_int(b, "id", l.id);
        proto_add_str(b, "run", runs->pdata[i - 1]);
        proto_add_str(b, "screen", have ? r.screen_name : NULL);
        proto_add_str(b, "mask", have ? r.mask_name : NULL);
        proto_add_str(b, "object", have ? r.object : NULL);
        proto_add_str(b, "method", l.method);
        proto_add_time(b, "started", l.started_ms);
        proto_add_dbl(b, "elapsed_s", l.elapsed_s);
        proto_add_dbl(b, "sep_arcsec", l.sep_arcsec);
        proto_add_dbl(b, "sep_px", l.sep_px);
        proto_add_dbl(b, "sep_err_px", l.sep_err_px);
        proto_add_dbl(b, "pa_deg", l.pa_deg);
        proto_add_dbl(b, "pa_err_deg", l.pa_err_deg);
        proto_add_dbl(b, "dm_mag", l.dm_mag);
        proto_add_dbl(b, "dm_err_mag", l.dm_err_mag);
        add_params(b, l.params);
        w->recon_png = checked_png(w, l.png);
        w->recon_id = l.id;
        proto_add_bool(b, "figure", w->recon_png != NULL);
        json_builder_end_object(b);
        if (have)
            catalog_run_clear(&r);
    }
    g_free(l.params);
    g_free(l.png);
    g_ptr_array_free(runs, TRUE);
}

const char *web_history_json(web *w)
{
    gint64 now = g_get_monotonic_time();
    if (w->history_json && now - w->history_us < HISTORY_CACHE_US)
        return w->history_json;
    JsonBuilder *b = json_builder_new();
    json_builder_begin_object(b);
    add_r0(b, w);
    add_recon(b, w);
    json_builder_end_object(b);
    JsonNode *n = json_builder_get_root(b);
    g_object_unref(b);
    g_free(w->history_json);
    w->history_json = proto_take_string(n);
    w->history_us = now;
    return w->history_json;
}

GBytes *web_recon_png(web *w)
{
    web_history_json(w);
    if (!w->recon_png)
        return NULL;
    if (!w->recon_bytes || g_strcmp0(w->recon_bytes_path, w->recon_png)) {
        gchar *data = NULL;
        gsize len = 0;
        if (!g_file_get_contents(w->recon_png, &data, &len, NULL) || len > RECON_MAX_BYTES) {
            g_free(data);
            return NULL;
        }
        if (w->recon_bytes)
            g_bytes_unref(w->recon_bytes);
        w->recon_bytes = g_bytes_new_take(data, len);
        g_free(w->recon_bytes_path);
        w->recon_bytes_path = g_strdup(w->recon_png);
    }
    return g_bytes_ref(w->recon_bytes);
}

void web_state_clear(web *w)
{
    g_clear_pointer(&w->status_json, g_free);
    g_clear_pointer(&w->history_json, g_free);
    g_clear_pointer(&w->recon_png, g_free);
    g_clear_pointer(&w->recon_bytes_path, g_free);
    if (w->recon_bytes)
        g_bytes_unref(w->recon_bytes);
    w->recon_bytes = NULL;
    g_clear_pointer(&w->run_screen, g_free);
    g_clear_pointer(&w->run_mask, g_free);
    g_clear_pointer(&w->run_object, g_free);
}
