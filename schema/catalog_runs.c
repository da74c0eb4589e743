/* catalog_runs.c - see catalog.h: runs, their state machine, and their
 * reconstructions.
 *
 * Every write is BEGIN IMMEDIATE ... COMMIT, so a check (the run's current
 * state) and the write that depends on it see the same database even with
 * another process writing, and a failure leaves nothing half-done.
 */
#include "catalog_int.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include <glib.h>

/* One row of RUN_COLS (catalog_sql.c) into r, strings borrowed from st. */
static int run_from_row(catalog *c, sqlite3_stmt *st, catalog_run *r)
{
    const char *uuid = cat_col_text(st, 0), *state = cat_col_text(st, 1);
    memset(r, 0, sizeof *r);
    snprintf(r->uuid, sizeof r->uuid, "%s", uuid ? uuid : "");
    if (catalog_state_parse(state, &r->state) != SL_OK)
        return cat_seterr(c, SL_EFORMAT, "catalogue %s: run %s has unknown "
                          "state '%s'", c->path, r->uuid, state ? state : "");
    r->exit_reason = (char *)cat_col_text(st, 2);
    r->created_ms = cat_col_int64(st, 3);
    r->started_ms = cat_col_int64(st, 4);
    r->ended_ms = cat_col_int64(st, 5);
    r->updated_ms = cat_col_int64(st, 6);
    r->operator_name = (char *)cat_col_text(st, 7);
    r->object = (char *)cat_col_text(st, 8);
    r->screen_id = cat_col_int64(st, 9);
    r->screen_name = (char *)cat_col_text(st, 10);
    r->mask_id = cat_col_int64(st, 11);
    r->mask_name = (char *)cat_col_text(st, 12);
    r->camera_serial = (char *)cat_col_text(st, 13);
    r->camera_settings_json = (char *)cat_col_text(st, 14);
    r->frames_requested = (int)cat_col_int64(st, 15);
    r->frames_acquired = (int)cat_col_int64(st, 16);
    r->frames_failed = (int)cat_col_int64(st, 17);
    r->packets_missing = cat_col_int64(st, 18);
    r->file_path = (char *)cat_col_text(st, 19);
    r->file_sha256 = (char *)cat_col_text(st, 20);
    const char *kind = cat_col_text(st, 21);
    if (catalog_kind_parse(kind, &r->kind) != SL_OK)
        return cat_seterr(c, SL_EFORMAT, "catalogue %s: run %s has unknown "
                          "kind '%s'", c->path, r->uuid, kind ? kind : "");
    return SL_OK;
}

int catalog_run_insert(catalog *c, const catalog_run_spec *spec,
                       char uuid_out[CATALOG_UUID_LEN + 1])
{
    char id[CATALOG_UUID_LEN + 1], what[96];
    int rc;
    if (!spec)
        return cat_seterr(c, SL_EINVAL, "catalog_run_insert: no spec");
    if (spec->kind != CATALOG_KIND_ANY && !catalog_kind_name(spec->kind))
        return cat_seterr(c, SL_EINVAL, "catalogue %s: %d is not a run kind",
                          c->path, (int)spec->kind);
    if (spec->uuid) {
        rc = cat_uuid_norm(c, spec->uuid, id);
        if (rc != SL_OK)
            return rc;
    } else {
        char *u = g_uuid_string_random();
        snprintf(id, sizeof id, "%s", u);
        g_free(u);
    }
    snprintf(what, sizeof what, "inserting run %s", id);
    sqlite3_stmt *st = cat_stmt(c, CS_RUN_INSERT);
    cat_bind_text(st, 1, id);
    sqlite3_bind_int64(st, 2, cat_time_or_now(spec->created_ms));
    cat_bind_text(st, 3, spec->operator_name);
    cat_bind_text(st, 4, spec->object);
    cat_bind_id(st, 5, spec->screen_id);
    cat_bind_id(st, 6, spec->mask_id);
    cat_bind_text(st, 7, spec->camera_serial);
    cat_bind_text(st, 8, spec->camera_settings_json);
    sqlite3_bind_int(st, 9, spec->frames_requested);
    cat_bind_text(st, 10, catalog_kind_name(spec->kind ? spec->kind : CATALOG_SCIENCE));
    rc = cat_insert(c, st, what, NULL);
    if (rc != SL_OK && c->last_rc == SQLITE_CONSTRAINT_FOREIGNKEY)
        rc = cat_seterr(c, SL_EINVAL,
                        "catalogue %s: %s: screen id %lld or mask id %lld "
                        "is not in the catalogue",
                        c->path, what, (long long)spec->screen_id,
                        (long long)spec->mask_id);
    if (rc == SL_OK && uuid_out)
        memcpy(uuid_out, id, sizeof id);
    return rc;
}

/* The run's state (as text, into buf) inside the caller's transaction;
 * SL_EINVAL when there is no such run. */
static int run_state(catalog *c, const char *id, char *buf, size_t size,
                     const char *what)
{
    sqlite3_stmt *st = cat_stmt(c, CS_RUN_STATE);
    cat_bind_text(st, 1, id);
    int rc = sqlite3_step(st), status = SL_OK;
    if (rc == SQLITE_ROW) {
        const char *s = cat_col_text(st, 0);
        snprintf(buf, size, "%s", s ? s : "");
    } else if (rc == SQLITE_DONE)
        status = cat_seterr(c, SL_EINVAL, "catalogue %s: %s: no run %s in "
                            "the catalogue", c->path, what, id);
    else
        status = cat_sqlerr(c, rc, what);
    cat_done(st);
    return status;
}

/* SL_OK if run_transitions has from -> to; otherwise SL_EINVAL with the
 * legal targets in the message. */
static int check_transition(catalog *c, const char *id, const char *from,
                            const char *to, const char *what)
{
    sqlite3_stmt *st = cat_stmt(c, CS_TRANSITION_OK);
    cat_bind_text(st, 1, from);
    cat_bind_text(st, 2, to);
    int rc = sqlite3_step(st);
    int status = rc == SQLITE_ROW    ? SL_OK
                 : rc == SQLITE_DONE ? SL_EINVAL
                                     : cat_sqlerr(c, rc, what);
    cat_done(st);
    if (status != SL_EINVAL)
        return status;
    char legal[160] = "";
    size_t used = 0;
    st = cat_stmt(c, CS_TRANSITIONS_FROM);
    cat_bind_text(st, 1, from);
    while ((rc = sqlite3_step(st)) == SQLITE_ROW && used < sizeof legal) {
        const char *t = cat_col_text(st, 0);
        int n = snprintf(legal + used, sizeof legal - used, "%s%s",
                         used ? ", " : "", t ? t : "");
        used += n > 0 ? (size_t)n : 0;
    }
    cat_done(st);
    return cat_seterr(c, SL_EINVAL,
                      "catalogue %s: run %s: illegal state transition %s -> "
                      "%s (from %s: %s)",
                      c->path, id, from, to, from,
                      legal[0] ? legal : "none, it is final");
}

int catalog_run_set_state(catalog *c, const char *uuid, catalog_state to,
                          const char *reason)
{
    char id[CATALOG_UUID_LEN + 1], what[128], from[32];
    const char *to_name = catalog_state_name(to);
    int rc;
    if (!to_name)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: %d is not a run "
                          "state", c->path, (int)to);
    rc = cat_uuid_norm(c, uuid, id);
    if (rc != SL_OK)
        return rc;
    if ((to == CATALOG_FAILED || to == CATALOG_ABORTED ||
         to == CATALOG_INTERRUPTED) && (!reason || !*reason))
        return cat_seterr(c, SL_EINVAL, "catalogue %s: run %s: a run that "
                          "ends %s needs a reason", c->path, id, to_name);
    snprintf(what, sizeof what, "setting run %s to %s", id, to_name);
    rc = cat_begin(c, what);
    if (rc != SL_OK)
        return rc;
    rc = run_state(c, id, from, sizeof from, what);
    if (rc == SL_OK)
        rc = check_transition(c, id, from, to_name, what);
    if (rc == SL_OK) {
        sqlite3_stmt *st = cat_stmt(c, CS_RUN_SET_STATE);
        cat_bind_text(st, 1, id);
        cat_bind_text(st, 2, to_name);
        cat_bind_text(st, 3, reason);
        sqlite3_bind_int64(st, 4, catalog_now_ms());
        rc = cat_run(c, st, what);
    }
    return cat_end(c, rc, what);
}

int catalog_run_update_progress(catalog *c, const char *uuid,
                                int frames_acquired, int frames_failed,
                                int64_t packets_missing)
{
    char id[CATALOG_UUID_LEN + 1], what[128], state[32];
    catalog_state s;
    int rc = cat_uuid_norm(c, uuid, id);
    if (rc != SL_OK)
        return rc;
    snprintf(what, sizeof what, "updating the progress of run %s", id);
    rc = cat_begin(c, what);
    if (rc != SL_OK)
        return rc;
    rc = run_state(c, id, state, sizeof state, what);
    if (rc == SL_OK && catalog_state_parse(state, &s) == SL_OK &&
        catalog_state_is_terminal(s))
        rc = cat_seterr(c, SL_EINVAL, "catalogue %s: run %s is %s: its "
                        "counters are final", c->path, id, state);
    if (rc == SL_OK) {
        sqlite3_stmt *st = cat_stmt(c, CS_RUN_PROGRESS);
        cat_bind_text(st, 1, id);
        sqlite3_bind_int(st, 2, frames_acquired);
        sqlite3_bind_int(st, 3, frames_failed);
        sqlite3_bind_int64(st, 4, packets_missing);
        sqlite3_bind_int64(st, 5, catalog_now_ms());
        rc = cat_run(c, st, what);
    }
    return cat_end(c, rc, what);
}

int catalog_run_set_file(catalog *c, const char *uuid, const char *path,
                         const char *sha256_hex)
{
    char id[CATALOG_UUID_LEN + 1], what[128], state[32];
    int rc = cat_uuid_norm(c, uuid, id);
    if (rc != SL_OK)
        return rc;
    snprintf(what, sizeof what, "recording the file of run %s", id);
    rc = cat_begin(c, what);
    if (rc != SL_OK)
        return rc;
    rc = run_state(c, id, state, sizeof state, what);
    if (rc == SL_OK) {
        sqlite3_stmt *st = cat_stmt(c, CS_RUN_SET_FILE);
        cat_bind_text(st, 1, id);
        cat_bind_text(st, 2, path);
        cat_bind_text(st, 3, sha256_hex);
        sqlite3_bind_int64(st, 4, catalog_now_ms());
        rc = cat_run(c, st, what);
    }
    return cat_end(c, rc, what);
}

void catalog_run_clear(catalog_run *r)
{
    if (!r)
        return;
    g_free(r->exit_reason);
    g_free(r->operator_name);
    g_free(r->object);
    g_free(r->screen_name);
    g_free(r->mask_name);
    g_free(r->camera_serial);
    g_free(r->camera_settings_json);
    g_free(r->file_path);
    g_free(r->file_sha256);
    memset(r, 0, sizeof *r);
}

int catalog_run_get(catalog *c, const char *uuid, catalog_run *out)
{
    char id[CATALOG_UUID_LEN + 1];
    memset(out, 0, sizeof *out);
    int rc = cat_uuid_norm(c, uuid, id);
    if (rc != SL_OK)
        return rc;
    sqlite3_stmt *st = cat_stmt(c, CS_RUN_GET);
    cat_bind_text(st, 1, id);
    rc = sqlite3_step(st);
    if (rc == SQLITE_ROW) {
        catalog_run b;
        rc = run_from_row(c, st, &b);
        if (rc == SL_OK) {
            *out = b;
            out->exit_reason = g_strdup(b.exit_reason);
            out->operator_name = g_strdup(b.operator_name);
            out->object = g_strdup(b.object);
            out->screen_name = g_strdup(b.screen_name);
            out->mask_name = g_strdup(b.mask_name);
            out->camera_serial = g_strdup(b.camera_serial);
            out->camera_settings_json = g_strdup(b.camera_settings_json);
            out->file_path = g_strdup(b.file_path);
            out->file_sha256 = g_strdup(b.file_sha256);
        }
    } else if (rc == SQLITE_DONE)
        rc = cat_seterr(c, SL_EINVAL, "catalogue %s: no run %s in the "
                        "catalogue", c->path, id);
    else
        rc = cat_sqlerr(c, rc, "reading a run");
    cat_done(st);
    return rc;
}

int catalog_run_resolve(catalog *c, const char *prefix,
                        char uuid_out[CATALOG_UUID_LEN + 1])
{
    char p[CATALOG_UUID_LEN + 1];
    size_t n = prefix ? strlen(prefix) : 0;
    if (n < 4 || n > CATALOG_UUID_LEN ||
        strspn(prefix, "0123456789abcdefABCDEF-") != n)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: '%.64s' is not a run "
                          "id or its first 4+ hex digits", c->path,
                          prefix ? prefix : "");
    for (size_t i = 0; i <= n; i++)
        p[i] = g_ascii_tolower(prefix[i]);
    sqlite3_stmt *st = cat_stmt(c, CS_RUN_RESOLVE);
    cat_bind_text(st, 1, p);
    int rc = sqlite3_step(st), found = 0;
    char first[CATALOG_UUID_LEN + 1] = "";
    while (rc == SQLITE_ROW) {
        const char *u = cat_col_text(st, 0);
        if (found++ == 0)
            snprintf(first, sizeof first, "%s", u ? u : "");
        rc = sqlite3_step(st);
    }
    int status = SL_OK;
    if (rc != SQLITE_DONE)
        status = cat_sqlerr(c, rc, "resolving a run id");
    else if (found == 0)
        status = cat_seterr(c, SL_EINVAL, "catalogue %s: no run id starts "
                            "with %s", c->path, p);
    else if (found > 1)
        status = cat_seterr(c, SL_EINVAL, "catalogue %s: %s is ambiguous "
                            "(several runs start with it)", c->path, p);
    else
        memcpy(uuid_out, first, sizeof first);
    cat_done(st);
    return status;
}

/* One row of the run list, handed to the caller's fn. */
typedef struct run_each { catalog_run_fn fn; void *user; } run_each;

static int run_row(catalog *c, sqlite3_stmt *st, void *ctx)
{
    const run_each *e = ctx;
    catalog_run r;
    int rc = run_from_row(c, st, &r);
    return rc == SL_OK ? e->fn(&r, e->user) : rc;
}

int catalog_run_list(catalog *c, const catalog_run_filter *f,
                     catalog_run_fn fn, void *user)
{
    catalog_run_filter all = {0};
    if (!f)
        f = &all;
    if (f->state != CATALOG_STATE_ANY && !catalog_state_name(f->state))
        return cat_seterr(c, SL_EINVAL, "catalogue %s: %d is not a run "
                          "state", c->path, (int)f->state);
    sqlite3_stmt *st = cat_stmt(c, CS_RUN_LIST);
    cat_bind_text(st, 1, catalog_state_name(f->state));
    cat_bind_id(st, 2, f->screen_id);
    sqlite3_bind_int64(st, 3, f->since_ms > 0 ? f->since_ms : INT64_MIN);
    sqlite3_bind_int(st, 4, f->limit > 0 ? f->limit : -1);
    cat_bind_text(st, 5, catalog_kind_name(f->kind));
    run_each e = {fn, user};
    return cat_each(c, st, "listing runs", run_row, &e);
}

int catalog_run_find_calibration(catalog *c, const char *uuid, catalog_kind kind,
                                 char uuid_out[CATALOG_UUID_LEN + 1])
{
    char id[CATALOG_UUID_LEN + 1], state[32], what[96];
    const char *name = catalog_kind_name(kind);
    if (!name || kind == CATALOG_SCIENCE)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: %d is not a calibration "
                          "kind", c->path, (int)kind);
    int rc = cat_uuid_norm(c, uuid, id);
    if (rc != SL_OK)
        return rc;
    snprintf(what, sizeof what, "finding a %s for run %s", name, id);
    if ((rc = run_state(c, id, state, sizeof state, what)) != SL_OK)
        return rc;
    sqlite3_stmt *st = cat_stmt(c, CS_RUN_CALIBRATION);
    cat_bind_text(st, 1, id);
    cat_bind_text(st, 2, name);
    rc = sqlite3_step(st);
    int status = SL_OK;
    if (rc == SQLITE_ROW) {
        const char *u = cat_col_text(st, 0);
        snprintf(uuid_out, CATALOG_UUID_LEN + 1, "%s", u ? u : "");
    } else if (rc == SQLITE_DONE) {
        status = SL_EEND;
    } else {
        status = cat_sqlerr(c, rc, what);
    }
    cat_done(st);
    return status;
}

int catalog_runs_mark_interrupted(catalog *c)
{
    const char *what = "marking unfinished runs interrupted";
    int rc = cat_begin(c, what);
    if (rc != SL_OK)
        return rc;
    sqlite3_stmt *st = cat_stmt(c, CS_RUNS_INTERRUPT);
    cat_bind_text(st, 1, "daemon restarted while ");
    sqlite3_bind_int64(st, 2, catalog_now_ms());
    rc = cat_run(c, st, what);
    int n = sqlite3_changes(c->db);
    rc = cat_end(c, rc, what);
    return rc == SL_OK ? n : rc;
}

/* ---- reconstructions ---- */

void catalog_recon_init(catalog_recon *r)
{
    memset(r, 0, sizeof *r);
    r->elapsed_s = r->sep_px = r->sep_err_px = r->pa_deg = r->pa_err_deg =
        r->dm_mag = r->dm_err_mag = r->sep_arcsec = r->c_cophased = NAN;
}

int catalog_recon_insert(catalog *c, const catalog_recon *r, int64_t *id_out)
{
    char id[CATALOG_UUID_LEN + 1], what[128];
    if (!r || !r->method || !*r->method)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: a reconstruction "
                          "needs a method", c->path);
    int rc = cat_uuid_norm(c, r->run_uuid, id);
    const double m[] = {r->elapsed_s, r->sep_px, r->sep_err_px, r->pa_deg,
                        r->pa_err_deg, r->dm_mag, r->dm_err_mag,
                        r->sep_arcsec, r->c_cophased};
    const char *names[] = {"elapsed_s", "sep_px", "sep_err_px", "pa_deg",
                           "pa_err_deg", "dm_mag", "dm_err_mag",
                           "sep_arcsec", "c_cophased"};
    for (int i = 0; rc == SL_OK && i < (int)(sizeof m / sizeof m[0]); i++)
        rc = cat_check_metric(c, names[i], m[i]);
    if (rc != SL_OK)
        return rc;
    snprintf(what, sizeof what, "inserting a reconstruction of run %s", id);
    sqlite3_stmt *st = cat_stmt(c, CS_RECON_INSERT);
    cat_bind_text(st, 1, id);
    cat_bind_text(st, 2, r->method);
    cat_bind_text(st, 3, r->params_json);
    sqlite3_bind_int64(st, 4, cat_time_or_now(r->started_ms));
    cat_bind_double(st, 5, r->elapsed_s);
    cat_bind_text(st, 6, r->output_fits);
    cat_bind_text(st, 7, r->output_png);
    for (int i = 1; i < (int)(sizeof m / sizeof m[0]); i++)
        cat_bind_double(st, 7 + i, m[i]); /* sep_px .. c_cophased: 8..15 */
    cat_bind_text(st, 16, r->quality_json);
    rc = cat_insert(c, st, what, id_out);
    if (rc != SL_OK && c->last_rc == SQLITE_CONSTRAINT_FOREIGNKEY)
        rc = cat_seterr(c, SL_EINVAL, "catalogue %s: %s: run %s is not "
                        "in the catalogue", c->path, what, id);
    return rc;
}

/* One row of the reconstruction list, handed to the caller's fn. */
typedef struct recon_each { catalog_recon_fn fn; void *user; } recon_each;

static int recon_row(catalog *c, sqlite3_stmt *st, void *ctx)
{
    const recon_each *e = ctx;
    (void)c;
    catalog_recon r;
    r.id = cat_col_int64(st, 0);
    r.run_uuid = cat_col_text(st, 1);
    r.method = cat_col_text(st, 2);
    r.params_json = cat_col_text(st, 3);
    r.started_ms = cat_col_int64(st, 4);
    r.elapsed_s = cat_col_double(st, 5);
    r.output_fits = cat_col_text(st, 6);
    r.output_png = cat_col_text(st, 7);
    r.sep_px = cat_col_double(st, 8);
    r.sep_err_px = cat_col_double(st, 9);
    r.pa_deg = cat_col_double(st, 10);
    r.pa_err_deg = cat_col_double(st, 11);
    r.dm_mag = cat_col_double(st, 12);
    r.dm_err_mag = cat_col_double(st, 13);
    r.sep_arcsec = cat_col_double(st, 14);
    r.c_cophased = cat_col_double(st, 15);
    r.quality_json = cat_col_text(st, 16);
    return e->fn(&r, e->user);
}

int catalog_recon_list(catalog *c, const char *run_uuid, catalog_recon_fn fn,
                       void *user)
{
    char id[CATALOG_UUID_LEN + 1];
    int rc = cat_uuid_norm(c, run_uuid, id);
    if (rc != SL_OK)
        return rc;
    sqlite3_stmt *st = cat_stmt(c, CS_RECON_LIST);
    cat_bind_text(st, 1, id);
    recon_each e = {fn, user};
    return cat_each(c, st, "listing reconstructions", recon_row, &e);
}
