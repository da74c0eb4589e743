/* cmdrun_fx.h - run a `specklab` subcommand in-process in a test's own
 * temporary directory, its stdout and stderr captured (the CLI tests of
 * oifits and binary --wds). */
#ifndef SL_CMDRUN_FX_H
#define SL_CMDRUN_FX_H

#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "cli.h"
#include "tcheck.h"

typedef struct fx {
    char dir[64];
    char out[4096], err[4096]; /* the command's stdout and stderr, cut */
} fx;

static inline int fx_start(fx *f)
{
    snprintf(f->dir, sizeof f->dir, "/tmp/sl_cmdrun_XXXXXX");
    f->out[0] = f->err[0] = 0;
    return mkdtemp(f->dir) ? 0 : -1;
}

static inline void fx_stop(fx *f)
{
    char *cmd = g_strdup_printf("rm -rf '%s'", f->dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", f->dir);
    g_free(cmd);
}

static inline char *path_in(const fx *f, const char *name)
{
    return g_strdup_printf("%s/%s", f->dir, name);
}

static inline void slurp(const char *path, char *buf, size_t n)
{
    FILE *in = fopen(path, "r");
    size_t got = in ? fread(buf, 1, n - 1, in) : 0;
    buf[got] = 0;
    if (in)
        fclose(in);
}

/* Run fn("specklab NAME", ARGS... NULL) in-process; its exit status, its
 * stdout and stderr in f->out, f->err. */
static inline int run(fx *f, int (*fn)(int, char **), const char *name, ...)
{
    char *v[40], *argv[40];
    int n = 0;
    va_list ap;
    va_start(ap, name);
    v[n++] = g_strdup_printf("specklab %s", name);
    for (const char *a; n < 38 && (a = va_arg(ap, const char *));)
        v[n++] = g_strdup(a);
    va_end(ap);
    v[n] = NULL;
    memcpy(argv, v, sizeof v); /* GOption reorders argv */
    char *op = path_in(f, "stdout.txt"), *ep = path_in(f, "stderr.txt");
    fflush(stdout);
    fflush(stderr);
    int so = dup(1), se = dup(2);
    int fo = open(op, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    int fe = open(ep, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fo, 1);
    dup2(fe, 2);
    int rc = fn(n, argv);
    fflush(stdout);
    fflush(stderr);
    dup2(so, 1);
    dup2(se, 2);
    close(so), close(se), close(fo), close(fe);
    slurp(op, f->out, sizeof f->out);
    slurp(ep, f->err, sizeof f->err);
    g_free(op);
    g_free(ep);
    for (int i = 0; i < n; i++)
        g_free(v[i]);
    return rc;
}

#endif
