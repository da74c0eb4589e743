/* stage_backend.h - private to drivers/stage*.c: the transports of the
 * Modbus link (stage_modbus.h), picked by name from a const table.
 *
 * A backend makes its libmodbus context, says what to do once a
 * connection is up and when an open one can no longer carry a request,
 * and whether damaged replies are line errors (a serial line) rather than
 * symptoms of a connection gone wrong.
 *
 * The serial port (rtu) is shared: the daemon's runner and its device
 * queries each hold a handle on it, and a CLI command may open it too.
 * Modbus RTU has one master per line, so every handle takes the port's
 * lock (flock on its descriptor: every open of the port contends, in this
 * process or another) around each call's traffic, connection and flush
 * included, waiting for it within the call's deadline.  And since
 * libmodbus restores a port's earlier settings when it closes it, which a
 * handle opened earlier may still be using, the holder of the lock puts
 * back the settings it connected with when they changed meanwhile.
 * On tcp the lock is a no-op: every handle has its own connection.
 */
#ifndef SL_STAGE_BACKEND_H
#define SL_STAGE_BACKEND_H

#include <stddef.h>
#include <termios.h>

#include <modbus.h>

#include "stage.h"

/* RTU: the longest silence inside a frame, at least (USB serial adapters
 * deliver in chunks up to 16 ms apart); 4 characters if that is longer. */
#define RTU_GAP_MS 50

typedef struct stage_backend {
    const char *name;
    /* The context (no I/O); label gets the stage's name in messages. */
    modbus_t *(*create)(const stage_config *cfg, char *label, size_t n,
                        sl_err *e);
    void (*on_connect)(modbus_t *ctx);
    /* Why an open connection can no longer carry a request; NULL: it can. */
    const char *(*dead)(modbus_t *ctx);
    /* A damaged reply is a line error (retried for reads), the port is
     * shared (locked around each call) and frames end at a gap. */
    int serial;
} stage_backend;

/* The backend called name, or NULL. */
const stage_backend *stage_backend_find(const char *name);
/* The longest silence inside a reply, ms: the response timeout on tcp,
 * RTU_GAP_MS or 4 characters at cfg->baud on rtu (never above it). */
int stage_backend_byte_ms(const stage_backend *be, const stage_config *cfg);

/* A handle's hold on its serial port. */
typedef struct stage_port {
    int locked;          /* the lock is held on the current descriptor */
    int have_tios;       /* tios holds the settings connected with */
    struct termios tios;
} stage_port;

/* Right after a (re)connection: the descriptor fd is new and not locked
 * yet; its settings (just applied by libmodbus) are the ones to keep. */
void stage_port_opened(stage_port *p, const stage_backend *be, int fd);
/* Take the lock on fd, waiting until deadline_s (monotonic; <= now: one
 * try), then put the settings back if someone changed them (flushing
 * what they garbled).  0, or -1 when another handle held the port until
 * then. */
int stage_port_take(stage_port *p, const stage_backend *be, int fd,
                    double deadline_s);
/* Release the lock (closing the descriptor releases it too). */
void stage_port_give(stage_port *p, int fd);
/* For a connection refused with EINVAL: Linux ptys have no parity bit and
 * (Debian's) glibc calls a tcsetattr that changed nothing but a dropped
 * PARENB an error, which every open after the first of a pty set to E or
 * O gets.  Toggle IXANY (no effect without IXON, which libmodbus clears)
 * on device so that libmodbus's next setting changes something.  0 when
 * toggled. */
int stage_port_nudge(const char *device);

#endif
