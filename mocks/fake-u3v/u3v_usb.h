/* u3v_usb.h - the U3V mock camera as a USB device in a umockdev testbed:
 * sysfs entry and descriptors (device, configuration, the U3V function's
 * IAD, control/event/streaming interfaces with the U3V device-info
 * descriptor), and a usbfs ioctl handler that serves control URBs
 * (string descriptors, endpoint halt), GenCP on the control bulk
 * endpoints (0x01 out, 0x81 in) and the stream on bulk 0x83 in.
 *
 * Programs under libumockdev-preload with UMOCKDEV_DIR = u3v_usb_root()
 * see the device in /sys and /dev/bus/usb and drive it through libusb as
 * a real camera (Aravis's ArvUvDevice included).  Unplug removes it from
 * the testbed (a "remove" uevent, then the sysfs tree); every pending and
 * later URB on an open handle fails with ENODEV, as usbfs does.  Plug
 * adds it back at the next device address.
 *
 * Threads: umockdev calls the ioctl handler on its own thread; the stream
 * producer pushes from another; everything shared is under one lock.
 */
#ifndef SL_U3V_USB_H
#define SL_U3V_USB_H

#include <stddef.h>
#include <stdint.h>

#include "status.h"
#include "u3v_regs.h"

typedef struct u3v_usb u3v_usb;

typedef struct u3v_ident {
    int bus, port, speed_mbit;   /* speed_mbit: sysfs "speed" (5000: USB 3) */
    uint16_t vid, pid;
    const char *vendor, *model, *serial, *guid;
    int node_mode;               /* device node permissions, e.g. 0666 */
} u3v_ident;

/* A testbed with the device plugged in at address 2. */
int u3v_usb_new(u3v_usb **out, u3v_regs *regs, const u3v_ident *id, sl_err *err);
void u3v_usb_free(u3v_usb *u);
/* The testbed's directory: UMOCKDEV_DIR for the programs that use it. */
const char *u3v_usb_root(const u3v_usb *u);
/* Set a sysfs/procfs-like file under the testbed (e.g. usbfs_memory_mb). */
int u3v_usb_set_file(u3v_usb *u, const char *rel_path, const char *text, sl_err *err);

int u3v_usb_plug(u3v_usb *u, sl_err *err);
void u3v_usb_unplug(u3v_usb *u);
int u3v_usb_plugged(u3v_usb *u);
/* "/dev/bus/usb/BBB/DDD" of the current (or last) plug. */
const char *u3v_usb_node(const u3v_usb *u);

/* Queue one stream transfer unit (leader, payload or trailer); each IN
 * URB on the stream endpoint takes the next bytes, a unit never spilling
 * into the next URB (a short packet ends the transfer).  Returns 0, or -1
 * when the queue holds max_units already (the frame is dropped, as a
 * camera with no host reading overflows). */
int u3v_usb_stream_push(u3v_usb *u, const void *data, size_t n, int max_units);
/* Units queued and not yet sent; drop them all (stream stopped). */
int u3v_usb_stream_queued(u3v_usb *u);
void u3v_usb_stream_flush(u3v_usb *u);

#endif
