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

#endif
