/* fake_regs.h - the fake stage's reserved fault-switch registers.
 *
 * These live above the public map of drivers/stage_map.h (addresses
 * >= 100, documented there too) and exist only in bin/specklab-fake-stage:
 * a test or mbpoll writes them at run time to make the fake misbehave.
 * Requests that touch only these registers are never subject to the fault
 * switches, so a fault can always be switched off again over Modbus.
 * Header-only constants: tests may include it without linking the mock.
 */
#ifndef SL_FAKE_REGS_H
#define SL_FAKE_REGS_H

#define FAKE_REG_FIRST 100
/* rw: answer the next N ordinary requests with exception 0x06 (counts down) */
#define FAKE_REG_BUSY_COUNT 100
/* rw: nonzero = answer every ordinary request with exception 0x06 */
#define FAKE_REG_BUSY 101
/* rw: nonzero = every HOME or MOVE started from now on stalls */
#define FAKE_REG_STALL 102
/* rw: ms a stalled motion stays busy before FAULT=STALL (default 1000) */
#define FAKE_REG_STALL_MS 103
/* rw: delay every ordinary reply by this many ms (0 = off) */
#define FAKE_REG_SLOW_MS 104
/* rw: N > 0 counts down per ordinary request; the request that brings it
 * to 0 is not answered and its connection is closed (1 = the next one;
 * on the serial line, which has no connection, it is only not answered) */
#define FAKE_REG_DISCONNECT_AFTER 105
/* rw: nonzero = close a connection at its first ordinary request (on the
 * serial line: answer no ordinary request) */
#define FAKE_REG_DISCONNECT 106
/* w: writing code x sets FAULT=x and STATUS_FAULT on wheel 0 / wheel 1 and
 * stops it (x = 0 clears like RESET; ENCODER also clears HOMED); reads 0 */
#define FAKE_REG_FAULT_SCREEN 107
#define FAKE_REG_FAULT_MASK 108
/* The serial line (--rtu only; no effect on TCP, which has its own
 * checksums).  Each counts down per frame it damages:
 * rw: the next N ordinary replies each get one byte corrupted on the wire
 * (the client's CRC check must reject them) */
#define FAKE_REG_LINE_NOISE 109
/* rw: the next N ordinary replies each lose one byte on the wire (a short
 * frame: the client's byte timeout must end it) */
#define FAKE_REG_LINE_DROP 110
/* rw: the next N frames arriving on the wire each get one byte corrupted
 * (the fake's CRC check rejects them: no reply) */
#define FAKE_REG_LINE_NOISE_RX 111
/* rw: the next N frames arriving on the wire each lose one byte (the fake
 * waits out its byte timeout, rejects the frame: no reply) */
#define FAKE_REG_LINE_DROP_RX 112
#define FAKE_REG_LAST 112

#define FAKE_NREGS 128 /* holding registers 0..127 are mapped */

#endif
