/* test_status.c - the one code space of common/status.h: each module's
 * codes inside its declared range, every code named by sl_strstatus with a
 * name of its own, and the values callers and logs already rely on. */
#include <limits.h>
#include <string.h>

#include "status.h"
#include "tcheck.h"

#define GENERIC "unknown error"

/* The modules of status.h's table: each owns (next base, its base], and
 * declares codes whose values were given out before the ranges were
 * written down (logs keep them, tests compare them): `was` holds those. */
#define MAXCODES 8
typedef struct module {
    const char *name;
    int base, next, n;
    int codes[MAXCODES], was[MAXCODES];
} module;

static const module modules[] = {
    {"core", SL_EBASE_CORE, SL_EBASE_CAMERA, 7,
     {SL_EINVAL, SL_EIO, SL_ENOMEM, SL_EFORMAT, SL_EDATA, SL_ERANGE, SL_EEND},
     {-1, -2, -3, -4, -5, -6, -7}},
    {"camera", SL_EBASE_CAMERA, SL_EBASE_CLIENT, 3,
     {CAMERA_ETIMEOUT, CAMERA_ELOST, CAMERA_ENODEV}, {-20, -21, -22}},
    {"client", SL_EBASE_CLIENT, SL_EBASE_NEXT, 3,
     {CLIENT_EUNREACHABLE, CLIENT_ETIMEOUT, CLIENT_EREMOTE}, {-30, -31, -32}},
};
#define NMODULES ((int)(sizeof modules / sizeof modules[0]))

static int declared(int value)
{
    for (int m = 0; m < NMODULES; m++)
        for (int i = 0; i < modules[m].n; i++)
            if (modules[m].codes[i] == value)
                return 1;
    return 0;
}

TEST(ok_and_unknown)
{
    CHECK(SL_OK == 0, "SL_OK is %d", SL_OK);
    CHECK(strcmp(sl_strstatus(SL_OK), "ok") == 0, "SL_OK is named '%s'",
          sl_strstatus(SL_OK));
    static const int unknown[] = {1, 7, INT_MAX, INT_MIN, SL_EBASE_NEXT, -1000};
    for (size_t i = 0; i < sizeof unknown / sizeof unknown[0]; i++)
        CHECK(strcmp(sl_strstatus(unknown[i]), GENERIC) == 0, "%d is named '%s'",
              unknown[i], sl_strstatus(unknown[i]));
}

TEST(ranges_are_ordered_and_apart)
{
    for (int m = 0; m < NMODULES; m++) {
        const module *r = &modules[m];
        CHECK(r->next < r->base, "%s: range (%d, %d] is empty", r->name, r->next, r->base);
        CHECK(m == 0 || r->base == modules[m - 1].next,
              "%s: base %d is not where %s's range ends (%d)", r->name, r->base,
              modules[m - 1].name, modules[m - 1].next);
    }
}

TEST(codes_keep_their_values_in_their_range)
{
    for (int m = 0; m < NMODULES; m++)
        for (int i = 0; i < modules[m].n; i++) {
            const module *r = &modules[m];
            int c = r->codes[i];
            CHECK(c == r->was[i], "%s code %d is %d, was %d", r->name, i, c, r->was[i]);
            CHECK(c < 0 && c <= r->base && c > r->next, "%s code %d is outside (%d, %d]",
                  r->name, c, r->next, r->base);
        }
}

/* Distinct across modules too: the name alone says who failed. */
TEST(every_code_has_its_own_name)
{
    for (int v = SL_EBASE_NEXT; v < 0; v++) {
        if (!declared(v))
            continue;
        const char *n = sl_strstatus(v);
        CHECK(n && n[0] && strcmp(n, GENERIC) != 0 && strcmp(n, "ok") != 0,
              "%d has no name of its own: '%s'", v, n ? n : "(null)");
        for (int w = SL_EBASE_NEXT; w < v; w++)
            CHECK(!declared(w) || strcmp(n, sl_strstatus(w)) != 0,
                  "%d and %d are both named '%s'", v, w, n);
    }
}

/* A name given to a code nobody declared (or a code declared in status.h
 * but not here) would be a code outside the table above. */
TEST(only_declared_codes_are_named)
{
    for (int v = SL_EBASE_NEXT - 100; v < 0; v++)
        CHECK(declared(v) == (strcmp(sl_strstatus(v), GENERIC) != 0),
              "%d is named '%s' but %s in this test's table", v, sl_strstatus(v),
              declared(v) ? "is" : "is not");
}

TC_MAIN(TC_CASE(ok_and_unknown), TC_CASE(ranges_are_ordered_and_apart),
        TC_CASE(codes_keep_their_values_in_their_range),
        TC_CASE(every_code_has_its_own_name), TC_CASE(only_declared_codes_are_named))
