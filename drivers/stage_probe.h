/* stage_probe.h - why a stage on a serial port (Modbus RTU) cannot be
 * used, in the words a lab needs: the device missing, this user not
 * allowed to open it (and the group that is), not a serial port, or no
 * reply at the configured baud rate and parity (and, when it answers at
 * others, which).
 *
 * stage_probe_serial looks at the device node first (nothing sent), then
 * asks the stage for its identity at cfg's settings.  With scan, a stage
 * that does not answer there is asked again at each of the common baud
 * rates (2400..115200) and parities, one short request each (~150 ms
 * without a reply: ~3 s when nothing answers at all), and the settings
 * it answers at are named.  Parity is found only where the line checks
 * it: an adapter that ignores parity answers at any.
 *
 * The port is opened like any handle of the driver (stage.h: its lock,
 * its settings restored), so a daemon's handles may share it meanwhile.
 */
#ifndef SL_STAGE_PROBE_H
#define SL_STAGE_PROBE_H

#include "stage.h"

typedef enum stage_probe_verdict {
    STAGE_PROBE_OK = 0,    /* the stage answers at cfg's settings */
    STAGE_PROBE_MISSING,   /* no such device (or a link to none) */
    STAGE_PROBE_DENIED,    /* this user may not open it */
    STAGE_PROBE_NOT_TTY,   /* it opens but is not a serial port */
    STAGE_PROBE_SETTINGS,  /* no reply at cfg's settings; it answers at baud, parity */
    STAGE_PROBE_SILENT,    /* no reply at any settings tried */
    STAGE_PROBE_ERROR      /* something else (an answer that is not our stage, ...) */
} stage_probe_verdict;

typedef struct stage_probe_result {
    stage_probe_verdict verdict;
    int baud;                  /* SETTINGS: where the stage answers */
    char parity;
    char what[SL_ERRMSG_MAX];  /* the finding, "stage DEVICE: ..." ("" when OK) */
    char fix[SL_ERRMSG_MAX];   /* what to do about it ("" when nothing) */
} stage_probe_result;

/* cfg->backend must be "rtu" (else SL_EINVAL).  SL_OK with out filled,
 * whatever the verdict. */
int stage_probe_serial(const stage_config *cfg, int scan, stage_probe_result *out);
/* "ok", "missing", "permission", "not-a-tty", "settings", "no-reply",
 * "error". */
const char *stage_probe_verdict_name(stage_probe_verdict v);

#endif
