/* server.h - the control socket: one Unix-domain stream socket served from
 * the GLib main loop (g_unix_fd_add on non-blocking fds), line-delimited
 * JSON per daemon/PROTOCOL.md.
 *
 * The server knows framing, not commands.  Each complete line becomes a
 * request with a token (client id, reply slot); the handler (main thread)
 * must complete every token exactly once, at once or later, from any
 * thread (server_complete_async).  Replies leave in request order: a
 * client's later replies wait behind a pending one (e.g. `reconstruct`);
 * events are not held back.  Blank lines are not requests and get no
 * reply.  A line longer than SERVER_MAX_LINE bytes gets a `too-large`
 * error, after which the server stops reading that client and closes it
 * once its replies are out.  A client that stops reading is cut off when
 * SERVER_MAX_OUTPUT bytes are waiting for it (a subscriber must keep up).
 *
 * Idle clients: a client is idle while it has nothing in hand (no request
 * pending, no reply waiting, no subscription).  One idle for idle_ms
 * since its last request or reply (a partial line does not count, so a
 * client trickling bytes is idle too) is sent an `idle` error line and
 * closed.  With max_clients connected, a newcomer takes the slot of the
 * client idle longest (told the same); only when none is idle is the
 * newcomer refused with `busy`.  So idle and slow clients cannot lock the
 * daemon's slots: only working clients and subscribers keep theirs.
 *
 * Access: the socket is created 0660 (umask held at 0117 across bind, so
 * it is never wider) and chowned to the daemon's euid/egid: the group is
 * the access control.  A stale socket (nobody listening) is replaced; a
 * live one or a non-socket at the path is an error.
 *
 * Threads: everything but server_complete_async and server_event_async
 * runs on the thread of the main context.  Join every thread that may call
 * the _async functions, then run the context dry, before server_free.
 */
#ifndef SL_DAEMON_SERVER_H
#define SL_DAEMON_SERVER_H

#include <glib.h>

#include "status.h"

#define SERVER_MAX_LINE 65536
#define SERVER_MAX_OUTPUT (16u << 20)

typedef struct server server;

typedef struct server_token {
    guint64 client;  /* 0: none */
    guint64 slot;
} server_token;

/* line is NUL-terminated (len bytes, no newline) and valid during the call. */
typedef void (*server_request_fn)(server *s, server_token tok, const char *line,
                                  size_t len, void *user);

int server_new(server **out, const char *path, int max_clients, int idle_ms,
               server_request_fn fn, void *user, sl_err *err);
/* Close the listening socket and unlink its path (idempotent). */
void server_stop_listening(server *s);
void server_free(server *s);
const char *server_path(const server *s);
int server_nclients(const server *s);

/* Complete a request with its reply line (owned; no newline).  After
 * server_complete_subscribe the client receives events (of run only, when
 * run is not NULL) from the moment this reply is written. */
void server_complete(server *s, server_token tok, char *line);
void server_complete_subscribe(server *s, server_token tok, char *line,
                               const char *run);
/* Any thread: the same, delivered through the main context. */
void server_complete_async(server *s, server_token tok, char *line);

/* Send an event line (no newline) to every subscriber of run (or of all
 * runs).  server_event copies line; _async takes ownership. */
void server_event(server *s, const char *run, const char *line);
void server_event_async(server *s, const char *run, char *line);

#endif
