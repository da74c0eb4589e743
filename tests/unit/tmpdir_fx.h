/* tmpdir_fx.h - a scratch directory for a unit test: made fresh
 * (mkdtemp), four path slots in it, removed with its files.  Static
 * functions: include once per test. */
#ifndef SL_TMPDIR_FX_H
#define SL_TMPDIR_FX_H

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct tmpdir {
    char dir[64];
    char path[4][256]; /* tmp_path's results */
} tmpdir;

static inline int tmp_make(tmpdir *d)
{
    snprintf(d->dir, sizeof d->dir, "/tmp/sl_unit.XXXXXX");
    return mkdtemp(d->dir) != NULL;
}

/* The directory's files, then the directory (no subdirectories). */
static inline void tmp_remove(tmpdir *d)
{
    DIR *dp = opendir(d->dir);
    struct dirent *e;
    char p[512];
    while (dp && (e = readdir(dp))) {
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) {
            snprintf(p, sizeof p, "%s/%s", d->dir, e->d_name);
            unlink(p);
        }
    }
    if (dp)
        closedir(dp);
    rmdir(d->dir);
}

/* d->path[i] = dir/name */
static inline const char *tmp_path(tmpdir *d, int i, const char *name)
{
    char tmp[sizeof d->path[0]]; /* via a copy: d->dir is in *d too */
    snprintf(tmp, sizeof tmp, "%s/%s", d->dir, name);
    memcpy(d->path[i], tmp, sizeof tmp);
    return d->path[i];
}

#endif
