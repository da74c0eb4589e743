/* runstate.h - the one way a run changes state.
 *
 * Every transition of a catalogued run - queued to moving, acquiring,
 * stored, reconstructing, done, failed, aborted - goes through
 * runstate_set: the catalogue row first (through catlock, which outlasts
 * another process's lock and a full disk), then the log line, then the
 * clients' event, so nothing is announced that the catalogue does not
 * say.  The runner (its own thread, and acquire.c through it), the
 * reconstruction worker and the dispatcher (a run taken off the queue)
 * all call it; none writes a state otherwise.
 */
#ifndef SL_DAEMON_RUNSTATE_H
#define SL_DAEMON_RUNSTATE_H

#include "catalog.h"
#include "catlock.h"
#include "server.h"

/* Called after the row is written and before the event: the runner
 * updates the status it serves, so a client that hears the event and
 * asks sees the new state. */
typedef void (*runstate_note_fn)(void *user, const char *uuid, catalog_state st);

/* Move run uuid to st with reason (NULL: none).  cl: the caller's
 * catlock context (its stop test and reserve), or NULL for one attempt
 * that does not wait (the main loop must not block on another process's
 * lock).  note (may be NULL) as above.  SL_OK, or the catalogue's code
 * with its message logged (another process changed the run, the
 * catalogue stayed locked, the daemon is stopping); no event then. */
int runstate_set(catalog *cat, const catlock_ctx *cl, server *srv, const char *uuid,
                 catalog_state st, const char *reason, runstate_note_fn note, void *user);

#endif
