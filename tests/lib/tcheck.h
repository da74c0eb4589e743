/* tcheck.h - the minimal test harness of specklab's C tests.
 *
 * A test is `TEST(name) { ... }` taking a `tc *t`.  CHECK(cond, fmt, ...)
 * records a failure with a message and returns from the test; SKIP(fmt, ...)
 * marks the test skipped with a reason.  main() is TC_MAIN(test1, test2...).
 * Each binary ends with "NAME: N passed, N failed, N skipped"; tests/run
 * sums the binaries into the final "N passed, N failed" line.
 * No globals: the state travels in the tc passed to each test.
 * tc_note and tc_main live in tcheck.c, compiled once into libsltest.a.
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

/* Record a failure (skip = 0: "file:line: (cond) " then the message) or
 * a skip (the message alone) in t. */
void tc_note(tc *t, int skip, const char *file, int line, const char *cond, const char *fmt,
             ...) __attribute__((format(printf, 6, 7)));

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

/* Run every case (or only the one named by argv[1]), print a line each
 * and the summary; 1 when any failed. */
int tc_main(const char *prog, int argc, char **argv, const tc_case *cases, int ncases);

#define TC_CASE(fn) {#fn, fn}
#define TC_MAIN(...)                                                          \
    int main(int argc, char **argv)                                           \
    {                                                                         \
        static const tc_case cases[] = {__VA_ARGS__};                         \
        return tc_main(argv[0], argc, argv, cases,                            \
                       (int)(sizeof cases / sizeof cases[0]));                \
    }

#endif
