/* catalog_util.c - see catalog.h and catalog_int.h: run-state names, the
 * error mapping and helpers shared by catalog_*.c, and time.
 */
#include "catalog_int.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <glib.h>

static const char *const state_names[] = {
    [CATALOG_STATE_ANY] = NULL,
    [CATALOG_QUEUED] = "queued",
    [CATALOG_MOVING] = "moving",
    [CATALOG_ACQUIRING] = "acquiring",
    [CATALOG_STORED] = "stored",
    [CATALOG_RECONSTRUCTING] = "reconstructing",
    [CATALOG_DONE] = "done",
    [CATALOG_FAILED] = "failed",
    [CATALOG_ABORTED] = "aborted",
    [CATALOG_INTERRUPTED] = "interrupted",
};
#define NSTATE_NAMES ((int)(sizeof state_names / sizeof state_names[0]))

/* As 003_run_kind.sql's CHECK. */
static const char *const kind_names[] = {
    [CATALOG_KIND_ANY] = NULL,
    [CATALOG_SCIENCE] = "science",
    [CATALOG_DARK] = "dark",
    [CATALOG_FLAT] = "flat",
    [CATALOG_CALIBRATOR] = "calibrator",
};
#define NKIND_NAMES ((int)(sizeof kind_names / sizeof kind_names[0]))

const char *catalog_kind_name(catalog_kind k)
{
    return (int)k > 0 && (int)k < NKIND_NAMES ? kind_names[k] : NULL;
}

int catalog_kind_parse(const char *name, catalog_kind *out)
{
    for (int i = 1; name && i < NKIND_NAMES; i++)
        if (strcmp(name, kind_names[i]) == 0) {
            *out = (catalog_kind)i;
            return SL_OK;
        }
    return SL_EINVAL;
}

const char *catalog_state_name(catalog_state s)
{
    return (int)s > 0 && (int)s < NSTATE_NAMES ? state_names[s] : NULL;
}

int catalog_state_parse(const char *name, catalog_state *out)
{
    for (int i = 1; name && i < NSTATE_NAMES; i++)
        if (strcmp(name, state_names[i]) == 0) {
            *out = (catalog_state)i;
            return SL_OK;
        }
    return SL_EINVAL;
}

int catalog_state_is_terminal(catalog_state s)
{
    return s == CATALOG_DONE || s == CATALOG_FAILED || s == CATALOG_ABORTED ||
           s == CATALOG_INTERRUPTED;
}

/* ---- errors and helpers shared by catalog_*.c ---- */

int cat_seterr(catalog *c, int code, const char *fmt, ...)
{
    va_list ap;
    c->err.code = code;
    c->last_full = 0;
    va_start(ap, fmt);
    vsnprintf(c->err.msg, sizeof c->err.msg, fmt, ap);
    va_end(ap);
    return code;
}

int cat_sqlerr(catalog *c, int rc, const char *what)
{
    const char *msg = c->db ? sqlite3_errmsg(c->db) : sqlite3_errstr(rc);
    c->last_rc = rc;
    /* A file SQLite cannot grow (the -shm, a WAL write) may surface as an
     * I/O error; the OS error says it was the disk. */
    if ((rc & 0xff) == SQLITE_IOERR && c->db && sqlite3_system_errno(c->db) == ENOSPC)
        rc = SQLITE_FULL;
    switch (rc & 0xff) {
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
        return cat_seterr(c, SL_EIO,
                          "catalogue %s is locked by another process (gave up "
                          "after %d ms) while %s: %s",
                          c->path, c->busy_timeout_ms, what, msg);
    case SQLITE_CONSTRAINT:
    case SQLITE_TOOBIG:
    case SQLITE_RANGE:
    case SQLITE_MISMATCH:
        return cat_seterr(c, SL_EINVAL, "catalogue %s: %s: %s", c->path, what,
                          msg);
    case SQLITE_NOMEM:
        return cat_seterr(c, SL_ENOMEM, "catalogue %s: %s: out of memory",
                          c->path, what);
    case SQLITE_NOTADB:
        return cat_seterr(c, SL_EFORMAT,
                          "catalogue %s is not an SQLite database (%s)",
                          c->path, msg);
    case SQLITE_CORRUPT:
        return cat_seterr(c, SL_EFORMAT, "catalogue %s is corrupt (%s): %s",
                          c->path, what, msg);
    case SQLITE_FULL:
        cat_seterr(c, SL_EIO, "catalogue %s: %s: disk full (%s)", c->path, what, msg);
        c->last_full = 1;
        return SL_EIO;
    default:
        return cat_seterr(c, SL_EIO, "catalogue %s: %s: %s", c->path, what,
                          msg);
    }
}

sqlite3_stmt *cat_stmt(catalog *c, int id)
{
    sqlite3_stmt *st = c->st[id];
    sqlite3_reset(st);
    sqlite3_clear_bindings(st);
    return st;
}

void cat_done(sqlite3_stmt *st)
{
    sqlite3_reset(st);
    sqlite3_clear_bindings(st);
}

int cat_run(catalog *c, sqlite3_stmt *st, const char *what)
{
    int rc;
    while ((rc = sqlite3_step(st)) == SQLITE_ROW)
        ;
    /* The message is read before the reset, while it is the step's. */
    int status = rc == SQLITE_DONE ? SL_OK : cat_sqlerr(c, rc, what);
    cat_done(st);
    return status;
}

int cat_begin(catalog *c, const char *what)
{
    return cat_run(c, cat_stmt(c, CS_BEGIN), what);
}

int cat_commit(catalog *c, const char *what)
{
    int rc = cat_run(c, cat_stmt(c, CS_COMMIT), what);
    if (rc != SL_OK)
        cat_rollback(c);
    return rc;
}

void cat_rollback(catalog *c)
{
    if (!sqlite3_get_autocommit(c->db))
        (void)sqlite3_step(cat_stmt(c, CS_ROLLBACK));
    cat_done(c->st[CS_ROLLBACK]);
}

int cat_end(catalog *c, int rc, const char *what)
{
    if (rc != SL_OK) {
        cat_rollback(c);
        return rc;
    }
    return cat_commit(c, what);
}

int cat_insert(catalog *c, sqlite3_stmt *st, const char *what,
               int64_t *id_out)
{
    int rc = cat_begin(c, what);
    if (rc != SL_OK) {
        cat_done(st);
        return rc;
    }
    rc = cat_end(c, cat_run(c, st, what), what);
    if (rc == SL_OK && id_out)
        *id_out = sqlite3_last_insert_rowid(c->db);
    return rc;
}

int cat_each(catalog *c, sqlite3_stmt *st, const char *what, cat_row_fn row,
             void *ctx)
{
    int rc, ret = SL_OK;
    while ((rc = sqlite3_step(st)) == SQLITE_ROW)
        if ((ret = row(c, st, ctx)) != SL_OK)
            break;
    if (rc != SQLITE_ROW && rc != SQLITE_DONE)
        ret = cat_sqlerr(c, rc, what);
    cat_done(st);
    return ret;
}

int cat_bind_text(sqlite3_stmt *st, int i, const char *s)
{
    return s ? sqlite3_bind_text(st, i, s, -1, SQLITE_TRANSIENT)
             : sqlite3_bind_null(st, i);
}

int cat_bind_double(sqlite3_stmt *st, int i, double x)
{
    return isnan(x) ? sqlite3_bind_null(st, i) : sqlite3_bind_double(st, i, x);
}

int cat_bind_id(sqlite3_stmt *st, int i, int64_t id)
{
    return id ? sqlite3_bind_int64(st, i, id) : sqlite3_bind_null(st, i);
}

const char *cat_col_text(sqlite3_stmt *st, int i)
{
    return (const char *)sqlite3_column_text(st, i);
}

double cat_col_double(sqlite3_stmt *st, int i)
{
    return sqlite3_column_type(st, i) == SQLITE_NULL
               ? NAN
               : sqlite3_column_double(st, i);
}

int64_t cat_col_int64(sqlite3_stmt *st, int i)
{
    return sqlite3_column_int64(st, i); /* NULL reads as 0 */
}

int cat_uuid_norm(catalog *c, const char *uuid, char out[CATALOG_UUID_LEN + 1])
{
    if (!uuid)
        return cat_seterr(c, SL_EINVAL, "catalogue %s: no run uuid given",
                          c->path);
    if (strlen(uuid) != CATALOG_UUID_LEN || !g_uuid_string_is_valid(uuid))
        return cat_seterr(c, SL_EINVAL,
                          "catalogue %s: '%.64s' is not a run uuid "
                          "(8-4-4-4-12 hex digits)",
                          c->path, uuid);
    for (int i = 0; i < CATALOG_UUID_LEN; i++)
        out[i] = g_ascii_tolower(uuid[i]);
    out[CATALOG_UUID_LEN] = '\0';
    return SL_OK;
}

int64_t cat_time_or_now(int64_t t_ms)
{
    return t_ms > 0 ? t_ms : catalog_now_ms();
}

int cat_check_metric(catalog *c, const char *field, double x)
{
    if (isinf(x))
        return cat_seterr(c, SL_EINVAL,
                          "catalogue %s: %s is infinite (use NaN for unknown)",
                          c->path, field);
    return SL_OK;
}

/* ---- time ---- */

int64_t catalog_now_ms(void)
{
    return g_get_real_time() / 1000;
}

void catalog_time_format(int64_t t_ms, char buf[CATALOG_TIME_MAX])
{
    int64_t s = t_ms / 1000, ms = t_ms % 1000;
    if (ms < 0) { /* floor division: -1 ms is 23:59:59.999 the day before */
        ms += 1000;
        s -= 1;
    }
    time_t tt = (time_t)s;
    struct tm tm;
    size_t n = 0;
    if (gmtime_r(&tt, &tm))
        n = strftime(buf, CATALOG_TIME_MAX, "%Y-%m-%dT%H:%M:%S", &tm);
    if (n == 0) {
        snprintf(buf, CATALOG_TIME_MAX, "%lld ms", (long long)t_ms);
        return;
    }
    snprintf(buf + n, CATALOG_TIME_MAX - n, ".%03dZ", (int)ms);
}

int catalog_time_parse(const char *text, int64_t *t_ms, sl_err *err)
{
    GDateTime *dt = NULL;
    int y, mo, d, used = 0;
    if (!text || !*text)
        return sl_seterr(err, SL_EINVAL, "empty time");
    const char *p = text + (text[0] == '-');
    if (*p && strspn(p, "0123456789") == strlen(p)) {
        errno = 0;
        long long s = strtoll(text, NULL, 10);
        if (errno || s > INT64_MAX / 1000 || s < INT64_MIN / 1000)
            return sl_seterr(err, SL_ERANGE, "time '%.64s' is out of range",
                             text);
        *t_ms = (int64_t)s * 1000;
        return SL_OK;
    }
    if (strlen(text) == 10 &&
        sscanf(text, "%4d-%2d-%2d%n", &y, &mo, &d, &used) == 3 && used == 10)
        dt = g_date_time_new_utc(y, mo, d, 0, 0, 0);
    else {
        GTimeZone *utc = g_time_zone_new_utc();
        dt = g_date_time_new_from_iso8601(text, utc);
        g_time_zone_unref(utc);
    }
    if (!dt)
        return sl_seterr(err, SL_EINVAL,
                         "'%.64s' is not a time (ISO-8601 such as "
                         "2024-05-01T12:00:00Z, a date, or unix seconds)",
                         text);
    *t_ms = (int64_t)g_date_time_to_unix(dt) * 1000 +
            g_date_time_get_microsecond(dt) / 1000;
    g_date_time_unref(dt);
    return SL_OK;
}
