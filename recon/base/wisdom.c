/* wisdom.c - see wisdom.h. */
#include "wisdom.h"

#include <errno.h>
#include <fftw3.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

const char *wisdom_default_path(void)
{
    static char path[PATH_MAX]; /* written once per call; callers copy */
    const char *env = getenv("SPECKLAB_WISDOM");
    if (env && *env)
        return env;
    const char *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    if (xdg && *xdg)
        snprintf(path, sizeof path, "%s/specklab/fftw-wisdom", xdg);
    else if (home && *home)
        snprintf(path, sizeof path, "%s/.cache/specklab/fftw-wisdom", home);
    else
        return NULL;
    return path;
}

static int mkdirs(char *dir)
{
    for (char *p = dir + 1; *p; p++)
        if (*p == '/') {
            *p = '\0';
            if (mkdir(dir, 0755) != 0 && errno != EEXIST)
                return -1;
            *p = '/';
        }
    return mkdir(dir, 0755) != 0 && errno != EEXIST ? -1 : 0;
}

int wisdom_load(const char *path, int *loaded, sl_err *err)
{
    char p[PATH_MAX];
    int n = 0;
    snprintf(p, sizeof p, "%s.f", path);
    if (access(p, R_OK) == 0) {
        if (!fftwf_import_wisdom_from_filename(p))
            return sl_seterr(err, SL_EFORMAT, "FFTW wisdom %s is unreadable "
                             "or corrupt (delete it)", p);
        n++;
    }
    snprintf(p, sizeof p, "%s.d", path);
    if (access(p, R_OK) == 0) {
        if (!fftw_import_wisdom_from_filename(p))
            return sl_seterr(err, SL_EFORMAT, "FFTW wisdom %s is unreadable "
                             "or corrupt (delete it)", p);
        n++;
    }
    if (loaded)
        *loaded = n;
    return SL_OK;
}

int wisdom_save(const char *path, sl_err *err)
{
    char dir[PATH_MAX], tmp[PATH_MAX + 32], dst[PATH_MAX + 4];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash && slash != dir) {
        *slash = '\0';
        if (mkdirs(dir) != 0)
            return sl_seterr(err, SL_EIO, "cannot create %s: %s", dir,
                             strerror(errno));
    }
    for (int prec = 0; prec < 2; prec++) {
        snprintf(dst, sizeof dst, "%s.%c", path, prec ? 'd' : 'f');
        snprintf(tmp, sizeof tmp, "%s.tmp%ld", dst, (long)getpid());
        int ok = prec ? fftw_export_wisdom_to_filename(tmp)
                      : fftwf_export_wisdom_to_filename(tmp);
        if (!ok || rename(tmp, dst) != 0) {
            unlink(tmp);
            return sl_seterr(err, SL_EIO, "cannot write FFTW wisdom %s: %s",
                             dst, strerror(errno));
        }
    }
    return SL_OK;
}

void wisdom_plan_limit(double seconds)
{
    fftw_set_timelimit(seconds);
    fftwf_set_timelimit(seconds);
}
