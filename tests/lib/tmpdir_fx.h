/* tmpdir_fx.h - a scratch directory for a unit test: made fresh
 * (mkdtemp), four path slots in it, removed with its files. */
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

int tmp_make(tmpdir *d);

/* The directory's files, then the directory (no subdirectories). */
void tmp_remove(tmpdir *d);

/* d->path[i] = dir/name */
const char *tmp_path(tmpdir *d, int i, const char *name);

#endif
