/* catalog.c - see catalog.h: opening, the migrations, closing, integrity.
 */
#include "catalog_int.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <glib.h>

/* PRAGMA application_id set by 001_initial.sql: "SLKC". */
#define CATALOG_APPLICATION_ID 0x534C4B43
#define MIGRATIONS_DIR "/org/specklab/schema/migrations/"

/* ---- migrations ---- */

typedef struct migration {
    int version;
    char *name; /* "002_indexes.sql", owned */
} migration;

static void migrations_free(migration *m, int n)
{
    for (int i = 0; m && i < n; i++)
        g_free(m[i].name);
    g_free(m);
}

static int migration_cmp(const void *a, const void *b)
{
    const migration *x = a, *y = b;
    return (x->version > y->version) - (x->version < y->version);
}

/* The migrations compiled in, sorted by version, which must run 1..n with
 * no gap or repeat (a build mistake, caught here rather than half-applied). */
static int migrations_load(migration **out, int *n_out, sl_err *err)
{
    GError *gerr = NULL;
    char **names = g_resource_enumerate_children(
        catalog_res_get_resource(), MIGRATIONS_DIR,
        G_RESOURCE_LOOKUP_FLAGS_NONE, &gerr);
    int n = 0, rc = SL_OK;
    migration *m = NULL;
    *out = NULL;
    *n_out = 0;
    if (!names) {
        rc = sl_seterr(err, SL_EFORMAT, "no catalogue migrations compiled in "
                       "(%s)", gerr ? gerr->message : "?");
        g_clear_error(&gerr);
        return rc;
    }
    int count = (int)g_strv_length(names);
    m = g_new0(migration, count > 0 ? count : 1);
    for (int i = 0; i < count; i++) {
        const char *s = names[i];
        char *end = NULL;
        if (!isdigit((unsigned char)s[0]))
            goto bad_name;
        errno = 0;
        long v = strtol(s, &end, 10);
        if (errno || v < 1 || v > 9999 || *end != '_' ||
            !g_str_has_suffix(s, ".sql"))
            goto bad_name;
        m[n].version = (int)v;
        m[n].name = g_strdup(s);
        n++;
        continue;
    bad_name:
        rc = sl_seterr(err, SL_EFORMAT,
                       "catalogue migration '%s' is not named NNN_name.sql",
                       s);
        goto free_m;
    }
    qsort(m, (size_t)n, sizeof *m, migration_cmp);
    for (int i = 0; i < n; i++)
        if (m[i].version != i + 1) {
            rc = sl_seterr(err, SL_EFORMAT,
                           "catalogue migrations must be numbered 1..%d "
                           "without gaps or repeats; found %s at position %d",
                           n, m[i].name, i + 1);
            goto free_m;
        }
    if (n == 0) {
        rc = sl_seterr(err, SL_EFORMAT, "no catalogue migrations compiled in");
        goto free_m;
    }
    *out = m;
    *n_out = n;
    g_strfreev(names);
    return SL_OK;
free_m:
    migrations_free(m, n);
    g_strfreev(names);
    return rc;
}

int catalog_schema_latest(void)
{
    migration *m;
    int n, rc = migrations_load(&m, &n, NULL);
    if (rc != SL_OK)
        return rc;
    migrations_free(m, n);
    return n;
}

/* One integer from a one-row statement. */
static int query_int(catalog *c, int id, const char *what, int64_t *v)
{
    sqlite3_stmt *st = cat_stmt(c, id);
    int rc = sqlite3_step(st);
    int status = SL_OK;
    if (rc == SQLITE_ROW)
        *v = sqlite3_column_int64(st, 0);
    else
        status = cat_sqlerr(c, rc == SQLITE_DONE ? SQLITE_ERROR : rc, what);
    cat_done(st);
    return status;
}

static int apply_migration(catalog *c, const migration *m)
{
    char what[96], path[128];
    int64_t v = 0;
    char *emsg = NULL, *sql = NULL;
    GBytes *bytes = NULL;
    GError *gerr = NULL;
    int rc;

    snprintf(what, sizeof what, "applying migration %s", m->name);
    rc = cat_begin(c, what);
    if (rc != SL_OK)
        return rc;
    /* Another process may have applied it since we looked. */
    rc = query_int(c, CS_USER_VERSION, what, &v);
    if (rc != SL_OK)
        goto rollback;
    if (v >= m->version)
        return cat_commit(c, what);
    snprintf(path, sizeof path, MIGRATIONS_DIR "%s", m->name);
    bytes = g_resource_lookup_data(catalog_res_get_resource(), path,
                                   G_RESOURCE_LOOKUP_FLAGS_NONE, &gerr);
    if (!bytes) {
        rc = cat_seterr(c, SL_EFORMAT, "catalogue %s: %s: %s", c->path, what,
                        gerr ? gerr->message : "?");
        g_clear_error(&gerr);
        goto rollback;
    }
    gsize len = 0;
    const char *data = g_bytes_get_data(bytes, &len);
    sql = g_strndup(data, len); /* sqlite3_exec wants a C string */
    /* The one place SQL text runs unprepared: our own compiled-in script. */
    if (sqlite3_exec(c->db, sql, NULL, NULL, &emsg) != SQLITE_OK) {
        int xrc = sqlite3_extended_errcode(c->db);
        if ((xrc & 0xff) == SQLITE_BUSY || (xrc & 0xff) == SQLITE_LOCKED ||
            (xrc & 0xff) == SQLITE_FULL || (xrc & 0xff) == SQLITE_IOERR)
            rc = cat_sqlerr(c, xrc, what);
        else /* our script does not fit this database */
            rc = cat_seterr(c, SL_EFORMAT,
                            "catalogue %s: migration %s failed: %s", c->path,
                            m->name, emsg ? emsg : sqlite3_errstr(xrc));
        goto rollback;
    }
    rc = query_int(c, CS_USER_VERSION, what, &v);
    if (rc != SL_OK)
        goto rollback;
    if (v != m->version) {
        rc = cat_seterr(c, SL_EFORMAT,
                        "catalogue %s: migration %s must end with PRAGMA "
                        "user_version = %d (it left %lld)",
                        c->path, m->name, m->version, (long long)v);
        goto rollback;
    }
    rc = cat_commit(c, what);
    goto free_sql;
rollback:
    cat_rollback(c);
free_sql:
    sqlite3_free(emsg);
    g_free(sql);
    if (bytes)
        g_bytes_unref(bytes);
    return rc;
}

static int migrate(catalog *c)
{
    migration *m = NULL;
    int n = 0;
    int64_t version = 0, app = 0, objects = 0;
    int rc = migrations_load(&m, &n, &c->err);
    if (rc != SL_OK)
        return rc;
    rc = query_int(c, CS_USER_VERSION, "reading the schema version", &version);
    if (rc == SL_OK)
        rc = query_int(c, CS_APPLICATION_ID, "reading the application id",
                       &app);
    if (rc == SL_OK)
        rc = query_int(c, CS_OBJECT_COUNT, "reading the schema", &objects);
    if (rc != SL_OK)
        goto free_m;
    /* Refuse to write our tables into somebody else's database. */
    if ((version == 0 && objects > 0) ||
        (version > 0 && app != CATALOG_APPLICATION_ID)) {
        rc = cat_seterr(c, SL_EFORMAT,
                        "%s is not a specklab catalogue (application_id "
                        "0x%08llx, schema version %lld, %lld schema objects)",
                        c->path, (unsigned long long)app, (long long)version,
                        (long long)objects);
        goto free_m;
    }
    if (version > n) {
        rc = cat_seterr(c, SL_ERANGE,
                        "catalogue %s has schema version %lld, newer than "
                        "this program's %d: use a newer specklab",
                        c->path, (long long)version, n);
        goto free_m;
    }
    for (int i = (int)version; i < n && rc == SL_OK; i++)
        rc = apply_migration(c, &m[i]);
free_m:
    migrations_free(m, n);
    return rc;
}

/* ---- open / close ---- */

static int prepare_range(catalog *c, int from, int to)
{
    for (int i = from; i < to; i++) {
        int rc = sqlite3_prepare_v3(c->db, cat_sql[i], -1,
                                    SQLITE_PREPARE_PERSISTENT, &c->st[i],
                                    NULL);
        if (rc != SQLITE_OK) {
            char what[64];
            snprintf(what, sizeof what, "preparing statement %d", i);
            rc = cat_sqlerr(c, rc, what);
            /* The schema does not have what the code expects. */
            return rc == SL_EIO || rc == SL_EINVAL ? SL_EFORMAT : rc;
        }
    }
    return SL_OK;
}

/* A pragma that sets something, with its first result as text (or ""). */
static int pragma(catalog *c, const char *sql, char *res, size_t size)
{
    sqlite3_stmt *st = NULL;
    int rc = sqlite3_prepare_v2(c->db, sql, -1, &st, NULL);
    if (rc == SQLITE_OK) {
        rc = sqlite3_step(st);
        if (res) {
            const char *t = rc == SQLITE_ROW ? cat_col_text(st, 0) : NULL;
            snprintf(res, size, "%s", t ? t : "");
        }
        if (rc == SQLITE_ROW || rc == SQLITE_DONE)
            rc = SQLITE_OK;
    }
    sqlite3_finalize(st);
    return rc == SQLITE_OK ? SL_OK : cat_sqlerr(c, rc, sql);
}

static int configure(catalog *c)
{
    char mode[32], fk[8];
    int rc = pragma(c, "PRAGMA journal_mode = WAL", mode, sizeof mode);
    if (rc != SL_OK)
        return rc;
    if (strcmp(mode, "wal") != 0 && strcmp(mode, "memory") != 0)
        return cat_seterr(c, SL_EIO,
                          "catalogue %s: cannot use the WAL journal here "
                          "(journal_mode is '%s'; a network filesystem?)",
                          c->path, mode);
    rc = pragma(c, "PRAGMA foreign_keys = ON", NULL, 0);
    if (rc == SL_OK)
        rc = pragma(c, "PRAGMA foreign_keys", fk, sizeof fk);
    if (rc != SL_OK)
        return rc;
    if (strcmp(fk, "1") != 0)
        return cat_seterr(c, SL_EIO, "catalogue %s: this SQLite cannot "
                          "enforce foreign keys", c->path);
    /* See catalog.h for FULL over NORMAL.  (trusted_schema stays on: this
     * SQLite does not mark json_valid innocuous, so OFF would refuse our own
     * CHECK constraints; foreign files are refused by application_id.) */
    return pragma(c, "PRAGMA synchronous = FULL", NULL, 0);
}

int catalog_open(catalog **out, const char *path, sl_err *err)
{
    return catalog_open_opts(out, path, NULL, err);
}

int catalog_open_opts(catalog **out, const char *path,
                      const catalog_opts *opts, sl_err *err)
{
    catalog *c = NULL;
    int rc;
    if (!out || !path || !*path)
        return sl_seterr(err, SL_EINVAL, "catalog_open: no path given");
    *out = NULL;
    c = calloc(1, sizeof *c);
    if (!c || !(c->path = strdup(path))) {
        free(c);
        return sl_seterr(err, SL_ENOMEM, "catalog_open: out of memory");
    }
    c->busy_timeout_ms = opts && opts->busy_timeout_ms > 0
                             ? opts->busy_timeout_ms
                             : CATALOG_BUSY_TIMEOUT_MS;
    rc = sqlite3_open_v2(path, &c->db, SQLITE_OPEN_READWRITE |
                         SQLITE_OPEN_CREATE, NULL);
    if (rc != SQLITE_OK) {
        rc = cat_seterr(c, rc == SQLITE_NOMEM ? SL_ENOMEM : SL_EIO,
                        "cannot open catalogue %s: %s", path,
                        c->db ? sqlite3_errmsg(c->db) : sqlite3_errstr(rc));
        goto close_c;
    }
    sqlite3_extended_result_codes(c->db, 1);
    sqlite3_busy_timeout(c->db, c->busy_timeout_ms);
    rc = prepare_range(c, 0, CS_SCHEMA_FIRST);
    if (rc == SL_OK)
        rc = configure(c);
    if (rc == SL_OK)
        rc = migrate(c);
    if (rc == SL_OK)
        rc = prepare_range(c, CS_SCHEMA_FIRST, CS_COUNT);
    if (rc != SL_OK)
        goto close_c;
    *out = c;
    return SL_OK;
close_c:
    if (err)
        *err = c->err;
    catalog_close(c);
    return rc;
}

void catalog_close(catalog *c)
{
    if (!c)
        return;
    for (int i = 0; i < CS_COUNT; i++)
        sqlite3_finalize(c->st[i]);
    /* Every statement is finalized, so close cannot be busy; the last
     * connection to close checkpoints the WAL into the database. */
    sqlite3_close(c->db);
    free(c->path);
    free(c);
}

const char *catalog_errmsg(const catalog *c)
{
    return c ? c->err.msg : "no catalogue";
}

int catalog_disk_full(const catalog *c)
{
    return c && c->last_full;
}

int catalog_schema_version(catalog *c)
{
    int64_t v = 0;
    int rc = query_int(c, CS_USER_VERSION, "reading the schema version", &v);
    return rc == SL_OK ? (int)v : rc;
}

int catalog_integrity_check(catalog *c)
{
    sqlite3_stmt *st = cat_stmt(c, CS_INTEGRITY);
    int rc = sqlite3_step(st), status;
    if (rc != SQLITE_ROW) {
        status = cat_sqlerr(c, rc == SQLITE_DONE ? SQLITE_ERROR : rc,
                            "checking integrity");
    } else {
        const char *first = cat_col_text(st, 0);
        if (first && strcmp(first, "ok") == 0 &&
            sqlite3_step(st) == SQLITE_DONE)
            status = SL_OK;
        else
            status = cat_seterr(c, SL_EDATA,
                                "catalogue %s fails integrity_check: %s",
                                c->path, first ? first : "?");
    }
    cat_done(st);
    return status;
}

