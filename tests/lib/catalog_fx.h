/* catalog_fx.h - the fixture shared by tests/catalog/test_*.c: a fresh
 * temporary directory per test ($TMPDIR or /tmp), removed afterwards, and a
 * raw sqlite3 connection for checking facts about the file independently
 * of the code under test.
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

int fx_setup(tc *t, fx *f);

void fx_teardown(fx *f);

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
long long raw_int(const char *path, const char *sql);

int raw_exec(const char *path, const char *sql);

int same_str(const char *a, const char *b);

/* Same double, NaN equal to NaN (a round trip must be exact). */
int same_dbl(double a, double b);

#endif
