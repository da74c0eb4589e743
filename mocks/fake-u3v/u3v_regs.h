/* u3v_regs.h - the U3V mock camera's register space and its GenCP
 * control protocol (USB3 Vision 1.0 / GenCP 1.x, little-endian).
 *
 * Address map (the device's one 64-bit space, read and written with
 * GenCP ReadMem / WriteMem):
 *   0x000000  ABRM  technology-agnostic bootstrap (GenCP): names, serial,
 *                   response time, manifest table and SBRM addresses
 *   0x001000  SBRM  U3V bootstrap: transfer limits, SIRM address
 *   0x002000  SIRM  streaming interface: required leader/payload/trailer
 *                   sizes (read), transfer sizes and enable (written)
 *   0x003000  manifest table: one entry, the GenICam XML (uncompressed)
 *   0x010000  the camera's features: Aravis's ArvFakeCamera register
 *                   memory, 1:1 (Width, ExposureTime, AcquisitionStart...)
 *   0x100000  the GenICam XML: the fake camera's own, every <Address>
 *                   moved up by 0x010000 to land on the feature window
 * Anything else answers GenCP status INVALID_ADDRESS; writes into the
 * bootstrap outside SIRM's writable words answer WRITE_PROTECT.
 */
#ifndef SL_U3V_REGS_H
#define SL_U3V_REGS_H

#include <arv.h>
#include <stddef.h>
#include <stdint.h>

#include "status.h"

#define U3V_CMD_MAX 1024 /* SBRM max command / ack transfer, bytes */

typedef struct u3v_regs u3v_regs;

/* fake is borrowed (it outlives the handle); the strings are copied. */
int u3v_regs_new(u3v_regs **out, ArvFakeCamera *fake, const char *vendor,
                 const char *model, const char *serial, sl_err *err);
void u3v_regs_free(u3v_regs *r);

/* One GenCP command (what the host wrote to the control OUT endpoint) to
 * its acknowledge: returns the ack's length in ack (<= U3V_CMD_MAX), 0
 * when the command asks for no ack, -1 when cmd is no GenCP command. */
int u3v_regs_command(u3v_regs *r, const uint8_t *cmd, size_t n, uint8_t *ack);

/* Power-up state of the streaming interface: disabled, no transfer
 * sizes (a re-plugged camera has forgotten its host). */
void u3v_regs_reset(u3v_regs *r);
/* The host enabled the stream channel (SIRM control bit 0). */
int u3v_regs_stream_enabled(u3v_regs *r);
/* Payload bytes per frame the host was told (SIRM required payload). */
size_t u3v_regs_payload_size(u3v_regs *r);

#endif
