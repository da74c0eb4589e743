/* stage_modbus.h - private to drivers/stage*.c: the Modbus link of a stage.
 *
 * The link owns the libmodbus context, picks the backend ("tcp", "rtu") from
 * a const table by name, connects lazily, verifies the stage's identity on
 * every (re)connection, retries "slave busy" (exception 0x06) until the
 * caller's deadline, and after a timeout / bad data / connection error
 * closes the connection and schedules the next attempt with exponential
 * backoff; a link the stage closed between requests is replaced before
 * the next one, and a read whose link drops mid-request is asked again
 * within its deadline; on a serial line (rtu) so is any request whose
 * reply was damaged (CRC, cut short).  Deadlines are absolute monotonic seconds
 * (stage_now_s()).
 * Messages written to e are the bare reason ("no reply within 500 ms
 * (reconnecting)"); stage.c prefixes the stage and the operation.
 */
#ifndef SL_STAGE_MODBUS_H
#define SL_STAGE_MODBUS_H

#include <stdint.h>

#include "stage.h"

typedef struct stage_link stage_link;

double stage_now_s(void);
/* Sleep d seconds (nothing if d <= 0). */
void stage_sleep_s(double d);

int stage_link_new(stage_link **out, const stage_config *cfg, sl_err *err);
void stage_link_free(stage_link *l);
const char *stage_link_label(const stage_link *l);
/* 1 while a verified connection is open and not closed by the stage
 * (checked on the socket, no request sent; a dead one is closed). */
int stage_link_connected(stage_link *l);
/* How the last request ended: done; the stage kept answering "busy"
 * until the deadline (it is there); the deadline came before it could be
 * sent (nothing learnt about the stage); failed (no connection, no
 * reply, a dropped link, an exception). */
enum { STAGE_LINK_DONE, STAGE_LINK_BUSY, STAGE_LINK_LATE, STAGE_LINK_FAILED };
int stage_link_outcome(const stage_link *l);
/* Identity read at the last successful connection (zeros before one). */
const stage_ident *stage_link_ident(const stage_link *l);
/* Replies a serial line damaged (bad CRC, cut short, not fitting the
 * request), each rejected and its link reset, since stage_link_new. */
unsigned stage_link_rejected(const stage_link *l);

/* Connect (and verify) if not connected, before deadline_s. */
int stage_link_ensure(stage_link *l, double deadline_s, sl_err *e);
/* Read / write n holding registers at addr.  *exc receives the Modbus
 * exception code the stage answered with (0 = none; busy is retried, not
 * reported here unless it outlasts the deadline).  SL_OK, or SL_EIO /
 * SL_EFORMAT with the reason in e. */
int stage_link_read(stage_link *l, int addr, int n, uint16_t *dst,
                    double deadline_s, int *exc, sl_err *e);
int stage_link_write(stage_link *l, int addr, int n, const uint16_t *src,
                     double deadline_s, int *exc, sl_err *e);

#endif
