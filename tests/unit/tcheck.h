/* tcheck.h - the minimal test harness of specklab's C tests.
 *
 * A test is `TEST(name) { ... }` taking a `tc *t`.  CHECK(cond, fmt, ...)
 * records a failure with a message and returns from the test; SKIP(fmt, ...)
 * marks the test skipped with a reason.  main() is TC_MAIN(test1, test2...).
 * Each binary ends with "NAME: N passed, N failed, N skipped"; tests/run
 * sums the binaries into the final "N passed, N failed" line.
 * No globals: the state travels in the tc passed to each test.
 */
#ifndef SL_TCHECK_H
#define SL_TCHECK_H

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

typedef struct tc {
    int failed;       /* current test failed */
    int skipped;      /* current test skipped */
    char msg[1024];
} tc;

static inline void tc_note(tc *t, int skip, const char *file, int line,
                           const char *cond, const char *fmt, ...)
    __attribute__((format(printf, 6, 7)));
static inline void tc_note(tc *t, int skip, const char *file, int line,
                           const char *cond, const char *fmt, ...)
{
    int n = 0;
    if (skip)
        t->skipped = 1;
    else {
        t->failed = 1;
        n = snprintf(t->msg, sizeof t->msg, "%s:%d: (%s) ", file, line, cond);
    }
    if (n < 0 || (size_t)n >= sizeof t->msg)
        n = 0;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(t->msg + n, sizeof t->msg - (size_t)n, fmt, ap);
    va_end(ap);
}

#define TEST(name) static void name(tc *t)
#define CHECK(cond, ...)                                                      \
    do {                                                                      \
        if (!(cond)) {                                                        \
            tc_note(t, 0, __FILE__, __LINE__, #cond, __VA_ARGS__);           \
            return;                                                           \
        }                                                                     \
    } while (0)
#define SKIP(...)                                                             \
    do {                                                                      \
        tc_note(t, 1, __FILE__, __LINE__, "", __VA_ARGS__);                  \
        return;                                                               \
    } while (0)
/* |a-b| <= tol, with the values in the message. */
#define CHECK_NEAR(a, b, tol)                                                 \
    CHECK(fabs((double)(a) - (double)(b)) <= (double)(tol),                   \
          "%s = %.9g, %s = %.9g, tolerance %.3g", #a, (double)(a), #b,       \
          (double)(b), (double)(tol))

typedef void (*tc_fn)(tc *);
typedef struct tc_case {
    const char *name;
    tc_fn fn;
} tc_case;

static inline int tc_main(const char *prog, int argc, char **argv,
                          const tc_case *cases, int ncases)
{
    int pass = 0, fail = 0, skip = 0;
    const char *only = argc > 1 ? argv[1] : NULL; /* run one test by name */
    const char *base = strrchr(prog, '/');
    base = base ? base + 1 : prog;
    for (int i = 0; i < ncases; i++) {
        if (only && strcmp(only, cases[i].name) != 0)
            continue;
        tc t = {0};
        cases[i].fn(&t);
        if (t.failed) {
            fail++;
            printf("FAIL %s/%s: %s\n", base, cases[i].name, t.msg);
        } else if (t.skipped) {
            skip++;
            printf("skip %s/%s: %s\n", base, cases[i].name, t.msg);
        } else {
            pass++;
            printf("ok   %s/%s\n", base, cases[i].name);
        }
        fflush(stdout);
    }
    printf("%s: %d passed, %d failed, %d skipped\n", base, pass, fail, skip);
    return fail ? 1 : 0;
}

#define TC_CASE(fn) {#fn, fn}
#define TC_MAIN(...)                                                          \
    int main(int argc, char **argv)                                           \
    {                                                                         \
        static const tc_case cases[] = {__VA_ARGS__};                         \
        return tc_main(argv[0], argc, argv, cases,                            \
                       (int)(sizeof cases / sizeof cases[0]));                \
    }

#endif
