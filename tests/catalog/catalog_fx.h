/* catalog_fx.h - the fixture shared by tests/catalog/test_*.c: a fresh
 * temporary directory per test ($TMPDIR or /tmp), removed afterwards, and a
 * raw sqlite3 connection for checking facts about the file independently
 * of the code under test.  Static functions: each test binary includes it
 * once.
 */
#ifndef SL_CATALOG_FX_H
#define SL_CATALOG_FX_H

#include <dirent.h>
#include <limits.h>
#include <math.h>
#include <sqlite3.h>
#include <stdint.h>
#include <stdlib.h>
#include <unistd.h>

#include "catalog.h"
#include "tcheck.h"

typedef struct fx {
    char dir[256];
    char path[320];
    catalog *c;
} fx;

static inline int fx_setup(tc *t, fx *f)
{
    const char *tmp = getenv("TMPDIR");
    memset(f, 0, sizeof *f);
    snprintf(f->dir, sizeof f->dir, "%s/test_catalog.XXXXXX",
             tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(f->dir)) {
        tc_note(t, 0, __FILE__, __LINE__, "mkdtemp", "cannot create %s",
                f->dir);
        f->dir[0] = '\0';
        return -1;
    }
    snprintf(f->path, sizeof f->path, "%s/specklab.db", f->dir);
    return 0;
}

static inline void fx_teardown(fx *f)
{
    catalog_close(f->c);
    DIR *d = f->dir[0] ? opendir(f->dir) : NULL;
    struct dirent *e;
    char p[600];
    while (d && (e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) {
            snprintf(p, sizeof p, "%s/%s", f->dir, e->d_name);
            unlink(p);
        }
    if (d) {
        closedir(d);
        rmdir(f->dir);
    }
}

/* A test with a fresh temporary directory in f, cleaned up whatever the
 * body's CHECKs do. */
#define FXTEST(name)                                                          \
    static void name##_body(tc *t, fx *f);                                    \
    TEST(name)                                                                \
    {                                                                         \
        fx f;                                                                 \
        if (fx_setup(t, &f) == 0)                                             \
            name##_body(t, &f);                                               \
        fx_teardown(&f);                                                      \
    }                                                                         \
    static void name##_body(tc *t, fx *f)

#define OPEN_OK(f)                                                            \
    do {                                                                      \
        sl_err e_ = {0};                                                      \
        int rc_ = catalog_open(&(f)->c, (f)->path, &e_);                      \
        CHECK(rc_ == SL_OK, "open: %d %s", rc_, e_.msg);                      \
    } while (0)

/* One integer from sql on a separate raw connection; LLONG_MIN on error. */
static inline long long raw_int(const char *path, const char *sql)
{
    sqlite3 *db = NULL;
    sqlite3_stmt *st = NULL;
    long long v = LLONG_MIN;
    if (sqlite3_open_v2(path, &db, SQLITE_OPEN_READWRITE, NULL) == SQLITE_OK &&
        sqlite3_prepare_v2(db, sql, -1, &st, NULL) == SQLITE_OK &&
        sqlite3_step(st) == SQLITE_ROW)
        v = sqlite3_column_int64(st, 0);
    sqlite3_finalize(st);
    sqlite3_close(db);
    return v;
}

static inline int raw_exec(const char *path, const char *sql)
{
    sqlite3 *db = NULL;
    int rc = sqlite3_open_v2(path, &db, SQLITE_OPEN_READWRITE |
                             SQLITE_OPEN_CREATE, NULL);
    if (rc == SQLITE_OK)
        rc = sqlite3_exec(db, sql, NULL, NULL, NULL);
    sqlite3_close(db);
    return rc;
}

static inline int same_str(const char *a, const char *b)
{
    return (!a && !b) || (a && b && strcmp(a, b) == 0);
}

/* Same double, NaN equal to NaN (a round trip must be exact). */
static inline int same_dbl(double a, double b)
{
    return (isnan(a) && isnan(b)) || a == b;
}

#endif
