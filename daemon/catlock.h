/* catlock.h - catalogue writes that record a run, outlasting another
 * process that holds the catalogue's write lock (an open sqlite3 shell,
 * a backup tool) and a full disk.
 *
 * Each write waits the busy timeout ([daemon] catalog_busy_timeout_ms),
 * then fails "catalogue PATH is locked by another process" (catalog.h's
 * words).  On a full disk it fails "disk full" (catalog_disk_full).  A
 * run's state, file and frame counts must not be dropped for either -
 * the catalogue would keep a run 'acquiring' that has ended, naming a
 * .part file that was renamed, and no client would hear of its end - so
 * the acquisition and reconstruction threads try such a write again,
 * logging why:
 *  - locked: until it lands or the daemon stops;
 *  - disk full: at once after releasing the catalogue's reserve
 *    (reserve.h), which is held for exactly this; without one, every
 *    FULL_RETRY_US until room is made or the daemon stops.
 * A daemon that stops meanwhile leaves the run non-terminal, recovered
 * as interrupted at the next start with its cube intact.  Events are
 * sent only after the write: nothing is announced that the catalogue
 * does not say.  Cost: nothing unless locked or full; a blocked thread
 * holds no lock of ours.
 */
#ifndef SL_DAEMON_CATLOCK_H
#define SL_DAEMON_CATLOCK_H

#include "catalog.h"
#include "reserve.h"

typedef int (*catlock_write_fn)(catalog *c, void *arg);
/* Nonzero: the daemon is stopping, give up. */
typedef int (*catlock_stop_fn)(void *user);

/* Who writes: the stop test (stop(user)) and the reserve to release on a
 * full disk (NULL: none). */
typedef struct catlock_ctx {
    catlock_stop_fn stop;
    void *user;
    reserve *rs;
} catlock_ctx;

/* 1 when c's last error is "locked by another process". */
int catlock_is_locked(const catalog *c);
/* write(c, arg) until it succeeds, fails otherwise, or x->stop while
 * locked or full; its last status (the message in c).  what names the
 * write in the log. */
int catlock_write(catalog *c, const catlock_ctx *x, const char *what, catlock_write_fn write,
                  void *arg);

/* The common writes, as catlock_write_fn with their arguments. */
typedef struct catlock_state {
    const char *uuid;
    catalog_state to;
    const char *reason;
} catlock_state;
int catlock_set_state(catalog *c, void *catlock_state_arg);

typedef struct catlock_file {
    const char *uuid, *path, *sha256;
    int counts;                        /* also write the counts below */
    int frames_acquired, frames_failed;
    int64_t packets_missing;
} catlock_file;
int catlock_set_file(catalog *c, void *catlock_file_arg);

#endif
