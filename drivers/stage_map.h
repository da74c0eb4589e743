/* stage_map.h - the Modbus register map of the specklab bench stage.
 *
 * One Modbus unit (default unit id 1) drives two wheels ("changers"):
 *   wheel 0: the phase-screen wheel (glycerine-sprayed glass screens);
 *   wheel 1: the aperture-mask wheel (e.g. open pupil, 17-hole mask).
 * All registers are 16-bit HOLDING registers (function codes 0x03 read,
 * 0x06/0x10 write), 0-based addresses as on the wire (mbpoll -0 / -r N+1).
 *
 *   addr  name                 access  meaning
 *   0     STAGE_REG_MAGIC      r       0x534C ("SL"): this is a specklab stage
 *   1     STAGE_REG_VERSION    r       register map version (1)
 *   2     STAGE_REG_NWHEELS    r       number of wheels (2)
 *   3     STAGE_REG_COMMAND    w       command, applies to the wheel in 4:
 *                                       1 HOME, 2 MOVE (to TARGET), 3 STOP,
 *                                       4 RESET (clear a fault)
 *   4     STAGE_REG_CMD_WHEEL  rw      wheel the command acts on; 0xFFFF = all
 *   per wheel w (base = 16 + 16*w):
 *   base+0 SLOTS               r       number of slots on the wheel
 *   base+1 TARGET              rw      target slot (0-based) for MOVE
 *   base+2 POSITION            r       current slot; 0xFFFF while between
 *                                       slots or not homed
 *   base+3 STATUS              r       bits: STAGE_ST_BUSY, _INPOS, _HOMED,
 *                                       _FAULT
 *   base+4 FAULT               r       fault code (STAGE_FAULT_*), 0 = none
 *   base+5 MOVE_MS             r       nominal time per slot step, ms
 *
 * A MOVE to a slot outside [0, SLOTS) or on an unhomed wheel is refused
 * with a Modbus exception 0x03 (illegal data value) and sets no fault.
 * A move that never completes (stall) sets FAULT=STALL and STATUS_FAULT.
 * A device that is busy may answer any request with exception 0x06
 * (slave device busy): clients retry within their deadline.
 */
#ifndef SL_STAGE_MAP_H
#define SL_STAGE_MAP_H

#define STAGE_MAGIC 0x534C
#define STAGE_MAP_VERSION 1
#define STAGE_NWHEELS 2
#define STAGE_WHEEL_SCREEN 0
#define STAGE_WHEEL_MASK 1
#define STAGE_WHEEL_ALL 0xFFFF

#define STAGE_REG_MAGIC 0
#define STAGE_REG_VERSION 1
#define STAGE_REG_NWHEELS 2
#define STAGE_REG_COMMAND 3
#define STAGE_REG_CMD_WHEEL 4

#define STAGE_REG_WHEEL_BASE(w) (16 + 16 * (w))
#define STAGE_WREG_SLOTS 0
#define STAGE_WREG_TARGET 1
#define STAGE_WREG_POSITION 2
#define STAGE_WREG_STATUS 3
#define STAGE_WREG_FAULT 4
#define STAGE_WREG_MOVE_MS 5
#define STAGE_WHEEL_NREGS 6

#define STAGE_NREGS 64          /* registers 0..63 are the public map */
#define STAGE_POSITION_UNKNOWN 0xFFFF

#define STAGE_CMD_HOME 1
#define STAGE_CMD_MOVE 2
#define STAGE_CMD_STOP 3
#define STAGE_CMD_RESET 4

#define STAGE_ST_BUSY (1u << 0)
#define STAGE_ST_INPOS (1u << 1)
#define STAGE_ST_HOMED (1u << 2)
#define STAGE_ST_FAULT (1u << 3)

#define STAGE_FAULT_NONE 0
#define STAGE_FAULT_STALL 1      /* motion did not reach the target */
#define STAGE_FAULT_ENCODER 2    /* position lost; home again */
#define STAGE_FAULT_OVERTEMP 3   /* driver over temperature */
#define STAGE_FAULT_LIMIT 4      /* limit switch hit */

/* Behaviour details (map version 1), as drivers/stage.c relies on them and
 * mocks/fake-stage implements them:
 *
 * Commands.  Write COMMAND and CMD_WHEEL with one 0x10 request at 3..4
 *   (mbpoll: `-0 -r 3 HOST 2 0` = MOVE wheel 0); the command runs once the
 *   whole request has landed, and COMMAND reads back 0.  Write TARGET
 *   (base+1) before MOVE.  HOME or MOVE on a wheel with STATUS_FAULT is
 *   refused with exception 0x04 (server device failure) until RESET; a
 *   refused command changes nothing.  STOP settles a running move on the
 *   nearest slot and abandons homing (the wheel stays unhomed).  A stalled
 *   wheel stops between slots (POSITION 0xFFFF) and keeps HOMED, so after
 *   RESET a MOVE is accepted again.  Writes to read-only or unmapped
 *   registers are refused with exception 0x02.  Function codes 0x03, 0x06
 *   and 0x10 only.
 * Status.  INPOS = at rest on a slot (POSITION valid); a move is complete
 *   when !BUSY && INPOS && POSITION == TARGET.  BUSY is set by the command
 *   itself, so a status read right after an accepted command never shows a
 *   stale INPOS from before it.
 * Addresses.  mbpoll -0 uses these addresses as they are (`mbpoll -m tcp
 *   -a 1 -0 -r 0 -c 3 -1 -p PORT HOST` prints 21324, 1, 2); without -0,
 *   mbpoll's reference N+1 is register N.
 *
 * Reserved registers 100..127: fault injection, fake stage only (a real
 * stage may refuse them with exception 0x02).  Constants in
 * mocks/fake-stage/fake_regs.h; the fake's flags set their initial values.
 *   100 BUSY_COUNT        rw  answer the next N requests with exception 0x06
 *   101 BUSY              rw  nonzero: answer every request with 0x06
 *   102 STALL             rw  nonzero: HOME/MOVE started now never complete
 *   103 STALL_MS          rw  then FAULT=STALL after this many ms (1000)
 *   104 SLOW_MS           rw  delay every reply by this many ms
 *   105 DISCONNECT_AFTER  rw  N > 0 counts down per request; the request
 *                             reaching 0 is dropped with its connection
 *   106 DISCONNECT        rw  nonzero: drop each connection at its first
 *                             request
 *   107 FAULT_SCREEN      w   write code: FAULT=code + STATUS_FAULT on wheel
 *   108 FAULT_MASK        w   0 / 1, motion stops (ENCODER clears HOMED;
 *                             0 clears); reads 0
 *   the serial line (specklab-fake-stage --rtu; no effect on TCP), each
 *   counting down per frame it damages:
 *   109 LINE_NOISE        rw  the next N replies get one byte corrupted
 *   110 LINE_DROP         rw  the next N replies lose one byte
 *   111 LINE_NOISE_RX     rw  the next N requests get one byte corrupted
 *   112 LINE_DROP_RX      rw  the next N requests lose one byte
 *   On the line, DISCONNECT(_AFTER) leaves the request unanswered.
 * "Requests" above are those touching any register below 100: requests
 * addressed only to 100..127 ignore the switches, so a test can always
 * switch a fault off again over Modbus.
 */

#endif
