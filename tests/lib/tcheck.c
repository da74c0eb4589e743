/* tcheck.c - the harness's functions; see tcheck.h. */
#include "tcheck.h"

void tc_note(tc *t, int skip, const char *file, int line, const char *cond, const char *fmt,
             ...)
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

int tc_main(const char *prog, int argc, char **argv, const tc_case *cases, int ncases)
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
