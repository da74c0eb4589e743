/* catlock.c - catalogue writes that outlast another process's lock and a
 * full disk; see catlock.h. */
#include "catlock.h"

#include <glib.h>
#include <string.h>

int catlock_is_locked(const catalog *c)
{
    return strstr(catalog_errmsg(c), "is locked by another process") != NULL;
}

/* A full disk is polled: nothing signals that room was made. */
#define FULL_RETRY_US 500000

int catlock_write(catalog *c, const catlock_ctx *x, const char *what, catlock_write_fn write,
                  void *arg)
{
    gint64 t0 = g_get_monotonic_time();
    int tries = 0, rc;
    while ((rc = write(c, arg)) != SL_OK) {
        int full = catalog_disk_full(c);
        if (!full && !catlock_is_locked(c))
            break;
        if (full && reserve_release(x->rs)) {
            g_warning("%s: %s; released the catalogue's reserve to record it", what,
                      catalog_errmsg(c));
            continue;
        }
        /* The first failure, then every 12th (a minute at the default
         * 5 s busy timeout, 6 s on a full disk), not one line per try. */
        if (tries++ % 12 == 0)
            g_warning("%s: %s; waiting for %s", what, catalog_errmsg(c),
                      full ? "room on the disk" : "it");
        if (x->stop && x->stop(x->user)) {
            g_warning("%s: given up, the daemon is stopping", what);
            return rc;
        }
        if (full)   /* a lock is waited out inside the write (busy timeout) */
            g_usleep(FULL_RETRY_US);
    }
    if (rc == SL_OK && tries > 0)
        g_message("%s: recorded after %.1f s", what, (g_get_monotonic_time() - t0) * 1e-6);
    return rc;
}

int catlock_set_state(catalog *c, void *catlock_state_arg)
{
    const catlock_state *a = catlock_state_arg;
    return catalog_run_set_state(c, a->uuid, a->to, a->reason);
}

int catlock_set_file(catalog *c, void *catlock_file_arg)
{
    const catlock_file *a = catlock_file_arg;
    int rc = catalog_run_set_file(c, a->uuid, a->path, a->sha256);
    if (rc == SL_OK && a->counts)
        rc = catalog_run_update_progress(c, a->uuid, a->frames_acquired, a->frames_failed,
                                         a->packets_missing);
    return rc;
}
