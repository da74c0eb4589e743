/* line.h - the fake stage's serial line (--rtu): a pseudo-terminal whose
 * slave side is the stage's RS-485 port as a client sees it (/dev/pts/N,
 * optionally behind a symlink), and a relay between the pty's master side
 * (the wire) and the socket libmodbus's RTU backend serves on.  The relay
 * is where the line misbehaves:
 *   - a byte of a frame corrupted (noise) or lost, either direction, on
 *     the fault registers FAKE_REG_LINE_* (fake_regs.h);
 *   - bytes sent at another speed than the stage's (--baud), or with
 *     another parity when one was given (--parity), are not understood:
 *     they are discarded and the stage stays silent, as a real one would
 *     after its UART's framing and CRC errors.
 * A pty has no baud rate or parity of its own, but keeps the speed a
 * client set, and of the parity what libmodbus marks (INPCK on for E and
 * O, PARODD for O; Linux clears PARENB and forces 8 data bits on a pty),
 * so both are read from the pty's termios as each chunk arrives.
 * The line keeps a slave descriptor of its own open: the pty never hangs
 * up when a client closes it, its raw mode stays, and bytes written while
 * no client is there wait in the pty (a client flushes them on opening).
 */
#ifndef SL_FAKE_LINE_H
#define SL_FAKE_LINE_H

#include <stddef.h>
#include <stdint.h>

enum { LINE_CLEAN, LINE_NOISE, LINE_DROP };

typedef struct fake_line {
    int master;     /* pty master: the wire */
    int hold;       /* a slave descriptor kept open (see above) */
    int near, far;  /* socketpair: libmodbus serves on near, relay on far */
    char pts[64];   /* the slave's path */
    char link[512]; /* symlink made to pts ("" = none), removed at close */
    int baud;       /* the stage's speed */
    char parity;    /* 'N', 'E', 'O', or 0: not checked */
    unsigned long misheard; /* chunks discarded: wrong speed or parity */
} fake_line;

/* Open the pty in raw mode, make link (NULL/"" = none; an existing
 * symlink is replaced, anything else refused) and the socketpair.
 * 0, or -1 with the reason in why. */
int fake_line_open(fake_line *l, const char *link, int baud, char parity,
                   char *why, size_t nwhy);
void fake_line_close(fake_line *l);
/* The wire has bytes (master readable): pass them to near, with the
 * inbound faults of regs (the fake's register image) applied. */
void fake_line_inbound(fake_line *l, uint16_t *regs);
/* Right after libmodbus wrote a reply to near: put it on the wire, with
 * fault (LINE_*) applied. */
void fake_line_outbound(fake_line *l, int fault);
/* The fault an ordinary reply gets: counts FAKE_REG_LINE_NOISE /
 * FAKE_REG_LINE_DROP down, LINE_CLEAN when both are 0. */
int fake_line_reply_fault(uint16_t *regs);
/* Discard what waits on near (after a frame libmodbus rejected). */
void fake_line_drain(fake_line *l);
/* 1 if baud is a rate a serial port can be set to. */
int fake_line_baud_ok(int baud);

#endif
