/* usb_int.h - the usb handle's insides, shared by usb.c (listing,
 * diagnosis, reset) and usb_hotplug.c.  Not part of the public API.
 */
#ifndef SL_USB_INT_H
#define SL_USB_INT_H

#include "usb.h"

#include <libusb.h>

#define U3V_CLASS 0xEF
#define U3V_SUBCLASS 0x05
#define QUEUE_CAP (2 * USB_HOTPLUG_MAX_DEVICES)

typedef struct queued {
    usb_event_kind kind;
    usb_dev_info dev;
} queued;

struct usb {
    libusb_context *ctx;
    sl_err err;
    char sysfs_root[512]; /* "/sys" or "$UMOCKDEV_DIR/sys" */
    /* hot-plug: allocated at start, reused by every poll */
    int hp_mode;
    usb_hotplug_fn hp_fn;
    void *hp_ud;
    libusb_hotplug_callback_handle hp_handle;
    int rescan_ms;
    double last_scan_s;
    usb_dev_info *known; /* devices seen (for LEFT details / rescans) */
    int n_known;
    usb_dev_info *scan; /* rescan scratch, USB_HOTPLUG_MAX_DEVICES */
    queued *queue;      /* QUEUE_CAP, drained by every usb_poll */
    int q_len;
    long dropped;
    int delivering; /* usb_poll called from a hot-plug callback */
};

/* Monotonic seconds. */
double usb_now_s(void);
/* Describe dev from libusb's cache and sysfs (no permission needed). */
void usb_fill_info(const usb *u, libusb_device *dev, usb_dev_info *d);

#endif
