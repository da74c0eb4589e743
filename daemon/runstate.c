/* runstate.c - see runstate.h. */
#include "runstate.h"

#include <glib.h>
#include <stdio.h>

#include "proto.h"

int runstate_set(catalog *cat, const catlock_ctx *cl, server *srv, const char *uuid,
                 catalog_state st, const char *reason, runstate_note_fn note, void *user)
{
    catlock_state a = {uuid, st, reason};
    char what[80];
    snprintf(what, sizeof what, "run %s: %s", uuid, catalog_state_name(st));
    int rc = cl ? catlock_write(cat, cl, what, catlock_set_state, &a)
                : catlock_set_state(cat, &a);
    if (rc != SL_OK) {
        g_warning("run %s: %s", uuid, catalog_errmsg(cat));
        return rc;
    }
    if (reason)
        g_message("run %s: %s (%s)", uuid, catalog_state_name(st), reason);
    else
        g_message("run %s: %s", uuid, catalog_state_name(st));
    if (note)
        note(user, uuid, st);
    server_event_async(srv, uuid, proto_event_state(uuid, st, reason));
    return SL_OK;
}
