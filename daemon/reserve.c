/* reserve.c - the catalogue's room for ending runs on a full disk; see
 * reserve.h. */
#define _GNU_SOURCE
#include "reserve.h"

#include <errno.h>
#include <fcntl.h>
#include <glib.h>
#include <sys/stat.h>
#include <unistd.h>

struct reserve {
    GMutex mu;          /* guards held and the file */
    char *path;
    int held;
};

/* Under mu.  A file of the right size already allocated counts as held
 * (a previous daemon's); anything else is made anew. */
static int hold_locked(reserve *r, sl_err *err)
{
    struct stat st;
    if (r->held)
        return SL_OK;
    if (stat(r->path, &st) == 0 && st.st_size == RESERVE_BYTES &&
        st.st_blocks * 512 >= RESERVE_BYTES) {
        r->held = 1;
        return SL_OK;
    }
    int fd = open(r->path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0640);
    int e = fd < 0 ? errno : posix_fallocate(fd, 0, RESERVE_BYTES);
    if (fd >= 0 && close(fd) != 0 && e == 0)
        e = errno;
    if (e != 0) {
        if (fd >= 0)
            unlink(r->path);
        return sl_seterr(err, SL_EIO, "%s: no room for the catalogue's %d KiB reserve: %s",
                         r->path, RESERVE_BYTES >> 10, g_strerror(e));
    }
    r->held = 1;
    return SL_OK;
}

reserve *reserve_new(const char *catalog_path)
{
    reserve *r = g_new0(reserve, 1);
    sl_err e = {0};
    g_mutex_init(&r->mu);
    r->path = g_strconcat(catalog_path, ".reserve", NULL);
    g_mutex_lock(&r->mu);
    if (hold_locked(r, &e) != SL_OK)
        g_warning("%s", e.msg);
    g_mutex_unlock(&r->mu);
    return r;
}

void reserve_free(reserve *r)
{
    if (!r)
        return;
    g_mutex_clear(&r->mu);
    g_free(r->path);
    g_free(r);
}

int reserve_release(reserve *r)
{
    if (!r)
        return 0;
    g_mutex_lock(&r->mu);
    int freed = r->held && unlink(r->path) == 0;
    r->held = 0;
    g_mutex_unlock(&r->mu);
    return freed;
}

int reserve_hold(reserve *r, sl_err *err)
{
    if (!r)
        return SL_OK;
    g_mutex_lock(&r->mu);
    int rc = hold_locked(r, err);
    g_mutex_unlock(&r->mu);
    return rc;
}
