/* reserve.h - room held on the catalogue's filesystem for the writes that
 * end a run.
 *
 * A run's end (its state, file, counts and reason) must reach the
 * catalogue even when the disk is full - the cube filled it, or another
 * program did.  Otherwise the run stays 'acquiring' for good: no client
 * hears of its end, `abort-run` and `reconstruct` answer `conflict`, and
 * only a restart settles it, as "interrupted", without the reason.  So
 * the daemon holds a preallocated file next to the catalogue
 * (<catalog>.reserve, RESERVE_BYTES); a catalogue write that fails "disk
 * full" deletes it and is tried again at once (catlock.h).  The runner
 * makes it again before each run and refuses to start a run while the
 * disk has no room for it: a run that could not record its own end is
 * not started.
 *
 * Size: ending a run is two small transactions (a few 4 KiB pages of WAL
 * each) and at most one WAL checkpoint into existing pages; 1 MiB covers
 * dozens of them.  The file outlives the daemon, so a restart on a full
 * disk finds room for its own recovery writes too.
 *
 * Thread-safe: the main, acquisition and reconstruction threads share one.
 */
#ifndef SL_DAEMON_RESERVE_H
#define SL_DAEMON_RESERVE_H

#include "status.h"

#define RESERVE_BYTES (1 << 20)

typedef struct reserve reserve;

/* The reserve beside catalog_path, made now when there is room (a full
 * disk is logged, not an error: reserve_hold tries again). */
reserve *reserve_new(const char *catalog_path);
/* Free the handle; the file stays for the next start.  NULL: no-op. */
void reserve_free(reserve *r);
/* Delete the file: 1 when that freed room, 0 when none was held (or r is
 * NULL). */
int reserve_release(reserve *r);
/* Make the file when it is missing: SL_OK when the room is held, SL_EIO
 * with a message naming the path when the disk has no room for it. */
int reserve_hold(reserve *r, sl_err *err);

#endif
