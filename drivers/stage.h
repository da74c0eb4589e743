/* stage.h - the bench stage: two wheels (phase screens, masks) behind one
 * Modbus unit, over TCP or RTU (libmodbus).  Register map: stage_map.h.
 *
 * Every call is bounded in time.  A call that talks to the stage spends at
 * most cfg.call_timeout_ms (stage_wait: its timeout_ms) on connecting,
 * busy retries and replies; one request waits at most
 * cfg.response_timeout_ms for its reply.  libmodbus gets out of step after a
 * timeout (a late reply would answer the next request), so after a timeout,
 * a garbled reply or a connection error the connection is closed and the
 * next call reconnects, with an exponential backoff between attempts
 * (backoff_min_ms .. backoff_max_ms) that never runs past the call's
 * deadline.  MODBUS_ERROR_RECOVERY_LINK is never used: it can block forever.
 * A connection the stage closed between calls (it was restarted) is
 * replaced before the next request is sent, and a read (status, identity)
 * whose connection drops mid-request reconnects and asks again within the
 * call's bound: a read is idempotent, a command is not, so a command that
 * lost its link is reported.  While stage_wait polls, the stage may stop
 * answering for at most cfg.call_timeout_ms: a stage that refuses
 * connections or is gone fails the wait then, not at its own timeout.
 *
 * On rtu (a serial line) "connection" is the open port: reconnecting
 * reopens and flushes it, a line holding bytes nobody asked for between
 * calls is reset, and a reply the line damaged (bad CRC, a byte lost: the
 * frame stops short, found after a silence of 50 ms or 4 characters, not
 * the response timeout) resets it as a bad reply does, and the request is
 * sent again within the call's bound - a command too: it arrived whole
 * (else no reply), and each command of the map leaves the stage in the
 * same state when repeated (stage_rejected_replies counts them).  A
 * request the line damaged is not answered: a timeout.  Each call holds
 * the port's lock (flock), so several handles, in one process or more,
 * share a serial line one request at a time.
 *
 * Connecting is lazy: stage_new only builds the handle (so an RTU handle
 * can be made without its serial port, and a daemon can start before the
 * stage is powered).  Each (re)connection reads registers 0..2 and the
 * wheel blocks and refuses a device whose MAGIC is not STAGE_MAGIC.
 *
 * Status codes: SL_EINVAL bad argument or configuration; SL_ERANGE the stage
 * refused a command (slot out of range, wheel not homed, wheel faulted);
 * SL_EIO no reply, connection lost, busy past the deadline, not in position
 * in time; SL_EDATA the stage reports a fault (e.g. a stall); SL_EFORMAT the
 * device is not a specklab stage or speaks a newer map.  The message, read
 * with stage_errmsg(), names the stage, the wheel and what went wrong, e.g.
 *   stage 127.0.0.1:1502: move of wheel 0 (screen) to slot 7 refused:
 *   slot out of range 0..5
 * A handle is used from one thread at a time.
 */
#ifndef SL_STAGE_H
#define SL_STAGE_H

#include "stage_map.h"
#include "status.h"

typedef struct stage stage;

typedef struct stage_config {
    const char *backend;     /* "tcp" (default) or "rtu"; see stage_backend_name */
    const char *host;        /* tcp: IPv4 address (default "127.0.0.1") */
    int port;                /* tcp: port (default 1502) */
    const char *device;      /* rtu: serial device, e.g. "/dev/ttyUSB0" */
    int baud;                /* rtu: default 19200 */
    char parity;             /* rtu: 'N', 'E' (default) or 'O' */
    int data_bits;           /* rtu: 8 */
    int stop_bits;           /* rtu: 1 */
    int unit_id;             /* Modbus unit (slave) id, default 1 */
    int response_timeout_ms; /* one request's reply (default 500) */
    int call_timeout_ms;     /* one whole call (default 2000) */
    int move_timeout_ms;     /* default bound of stage_wait (default 10000) */
    int backoff_min_ms;      /* first reconnect delay (default 50) */
    int backoff_max_ms;      /* reconnect delay cap (default 1000) */
} stage_config;

/* What the stage says about itself (read at each connection). */
typedef struct stage_ident {
    unsigned magic;                /* STAGE_MAGIC */
    unsigned version;              /* register map version */
    unsigned nwheels;              /* STAGE_NWHEELS */
    int slots[STAGE_NWHEELS];      /* slots per wheel */
    int move_ms[STAGE_NWHEELS];    /* nominal time per slot step */
} stage_ident;

typedef struct stage_wheel_status {
    int wheel;              /* 0 screen, 1 mask */
    int slots;
    int position;           /* slot, or -1 between slots / not homed */
    int target;             /* TARGET register */
    unsigned status;        /* STAGE_ST_* bits */
    int busy, in_position, homed, faulted; /* the status bits, 0/1 */
    int fault;              /* STAGE_FAULT_*, 0 = none */
    const char *fault_text; /* stage_fault_text(fault), static */
    int move_ms;
} stage_wheel_status;

/* Fill cfg with the defaults above (tcp, 127.0.0.1:1502, unit 1). */
void stage_config_defaults(stage_config *cfg);
/* Build a handle (no I/O).  SL_EINVAL for an unknown backend or bad
 * values; the strings of cfg are copied. */
int stage_new(stage **out, const stage_config *cfg, sl_err *err);
void stage_free(stage *s);
const char *stage_errmsg(const stage *s);
/* "HOST:PORT" or the serial device: the prefix of every message. */
const char *stage_label(const stage *s);
/* Replies damaged on a serial line (rtu: a CRC that does not match, a
 * frame cut short, one that does not fit its request) since stage_new:
 * each was rejected, the line reset and the request sent again.  0 on
 * tcp. */
unsigned stage_rejected_replies(const stage *s);
/* 1 while a verified connection is open and the stage has not closed it
 * (a restarted stage closes it; checked on the socket, no request sent,
 * and a dead connection is closed so the next call opens a new one). */
int stage_connected(stage *s);

/* Connect if needed and report the identity registers. */
int stage_info(stage *s, stage_ident *out);
/* Start homing wheel (0, 1 or STAGE_WHEEL_ALL); returns once accepted. */
int stage_home(stage *s, int wheel);
/* Start a move of wheel (0 or 1) to slot; returns once accepted. */
int stage_move(stage *s, int wheel, int slot);
/* Wait until wheel (or STAGE_WHEEL_ALL) is at rest in position: at the
 * target of this handle's last move, or homed after its last home.  Polls
 * STATUS until timeout_ms (<= 0: cfg.move_timeout_ms); reports a fault
 * (SL_EDATA), a stop short of the target, or the timeout (SL_EIO). */
int stage_wait(stage *s, int wheel, int timeout_ms);
/* stage_move + stage_wait(timeout_ms). */
int stage_move_wait(stage *s, int wheel, int slot, int timeout_ms);
/* Stop wheel (or STAGE_WHEEL_ALL) on the nearest slot. */
int stage_stop(stage *s, int wheel);
/* Clear the fault of wheel (or STAGE_WHEEL_ALL). */
int stage_reset(stage *s, int wheel);
/* One wheel's registers, decoded. */
int stage_status(stage *s, int wheel, stage_wheel_status *out);

/* "none", "stall", "encoder", ... (static; unknown codes: "unknown"). */
const char *stage_fault_text(int code);
/* "screen", "mask", "all", or "?" */
const char *stage_wheel_name(int wheel);
/* "screen"|"mask"|"all"|"0"|"1" -> 0, 1, STAGE_WHEEL_ALL; SL_EINVAL else. */
int stage_wheel_parse(const char *text, int *wheel);
/* Backend names in table order ("tcp", "rtu"); NULL past the end. */
const char *stage_backend_name(int i);

#endif
