/* tmpdir_fx.c - see tmpdir_fx.h. */
#include "tmpdir_fx.h"

int tmp_make(tmpdir *d)
{
    snprintf(d->dir, sizeof d->dir, "/tmp/sl_unit.XXXXXX");
    return mkdtemp(d->dir) != NULL;
}

void tmp_remove(tmpdir *d)
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

const char *tmp_path(tmpdir *d, int i, const char *name)
{
    char tmp[sizeof d->path[0]]; /* via a copy: d->dir is in *d too */
    snprintf(tmp, sizeof tmp, "%s/%s", d->dir, name);
    memcpy(d->path[i], tmp, sizeof tmp);
    return d->path[i];
}
