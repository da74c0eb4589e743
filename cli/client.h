/* client.h - a client of specklabd's control socket (daemon/PROTOCOL.md).
 *
 * One handle = one connection to the daemon's Unix-domain socket.  The
 * wire is line-delimited JSON, read and written with json-glib.  A request
 * gets an integer id chosen here (1, 2, 3... per connection); the daemon
 * echoes it, so client_wait_reply matches replies by id.  While waiting,
 * whatever else arrives is kept, never dropped: events (after `subscribe`)
 * go to a FIFO read by client_next_event, replies to other pipelined
 * requests to a table read by their own client_wait_reply.
 *
 * Errors follow common/status.h: SL_OK or a negative code, the message in
 * the handle (client_errmsg) or, for client_connect, in the caller's
 * sl_err.  Besides the SL_E* codes there are three client codes, declared
 * in the client's range of status.h (sl_strstatus names them):
 *   CLIENT_EUNREACHABLE  no daemon listening at the path (ENOENT,
 *                        ECONNREFUSED, EACCES...): the message says how
 *                        to start it or what to check;
 *   CLIENT_ETIMEOUT      nothing within the deadline;
 *   CLIENT_EREMOTE       the daemon answered {"ok": false}: the message is
 *                        the daemon's, client_errcode gives its code
 *                        ("not-found", "bad-request"...).
 * A connection closed by the daemon is SL_EIO, unless the daemon said why
 * before closing (`busy`: all its slots taken; `idle`: this connection
 * sat idle): that is CLIENT_EREMOTE with its code and message, also when
 * the close came before the request could be sent.  A line that is not a
 * JSON object, or longer than CLIENT_LINE_MAX, is SL_EFORMAT.
 *
 * Ownership: JsonObjects handed out carry a reference for the caller
 * (json_object_unref); args passed in are borrowed.  Timeouts are in ms,
 * < 0 meaning no limit.  One thread per handle; SIGPIPE is never raised
 * (writes use MSG_NOSIGNAL).
 */
#ifndef SL_CLIENT_H
#define SL_CLIENT_H

#include <json-glib/json-glib.h>

#include "status.h"

/* The system daemon's socket: the unit's RuntimeDirectory and the
 * installed configuration (make install) say the same. */
#define CLIENT_SYSTEM_SOCKET "/run/specklab/specklabd.sock"
/* A daemon started in a source tree (make demo, bin/specklabd). */
#define CLIENT_DEFAULT_SOCKET "./var/specklabd.sock"
/* The daemon refuses longer request lines (PROTOCOL.md): refuse them here
 * first, with a message naming the size. */
#define CLIENT_REQUEST_MAX 65536
/* Replies can hold many runs; 64 MiB bounds memory against a runaway peer. */
#define CLIENT_LINE_MAX (64u << 20)

typedef struct client client;

/* The socket to use: path when non-empty, else $SPECKLAB_SOCKET when set
 * and non-empty, else CLIENT_SYSTEM_SOCKET when it exists, else
 * CLIENT_DEFAULT_SOCKET.  Never NULL. */
const char *client_socket_path(const char *path);

/* Connect within timeout_ms (a full listen backlog is retried until then;
 * a missing socket or refused connection fails at once). */
int client_connect(client **out, const char *path, int timeout_ms, sl_err *e);
void client_free(client *c);
const char *client_errmsg(const client *c);
/* The daemon's error code of the last CLIENT_EREMOTE, else NULL. */
const char *client_errcode(const client *c);
const char *client_path(const client *c);
/* The daemon's process id (SO_PEERCRED), or -1.  Lets a client on the same
 * host resolve relative paths the daemon reports (/proc/PID/cwd). */
long client_peer_pid(const client *c);

/* Send {"id", "cmd", "args"} (args may be NULL); *id gets the id. */
int client_send(client *c, const char *cmd, JsonObject *args, gint64 *id);
/* Wait for the reply to id: SL_OK with *result its "result" object (an
 * empty object when the daemon sent none), or CLIENT_EREMOTE with the
 * daemon's message.  Events arriving meanwhile are queued. */
int client_wait_reply(client *c, gint64 id, int timeout_ms,
                      JsonObject **result);
/* client_send + client_wait_reply. */
int client_call(client *c, const char *cmd, JsonObject *args, int timeout_ms,
                JsonObject **result);
/* The next event (queued ones first): SL_OK with *event the whole event
 * object, or SL_OK with *event = NULL when timeout_ms passed quietly. */
int client_next_event(client *c, int timeout_ms, JsonObject **event);

#endif
