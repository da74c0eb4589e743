/* camwatch.h - USB camera hot-plug for specklabd: a thread that watches
 * USB3 Vision cameras arrive and leave (drivers/usb: libusb hot-plug, or
 * re-enumeration where udev events do not come) and tells its callback,
 * and a check of whether a camera with a given serial is on the bus now.
 *
 * Why a thread: usb_poll must be called for events to flow, and neither
 * the main loop (the socket) nor the acquisition thread (camera_pop) may
 * wait on it.  The callback runs on the watch thread.
 */
#ifndef SL_DAEMON_CAMWATCH_H
#define SL_DAEMON_CAMWATCH_H

#include "status.h"
#include "usb.h"

typedef struct camwatch camwatch;

/* arrived: 1 arrived, 0 left; dev is valid during the call only. */
typedef void (*camwatch_fn)(int arrived, const usb_dev_info *dev, void *userdata);

/* Starts the thread and returns at once; cameras present when it is up
 * are reported as arrivals.  An error there (no USB support here) is not
 * fatal to the daemon: the thread logs it and ends, and the daemon goes
 * on without hot-plug.  SL_OK always (err unused: kept for the shape). */
int camwatch_new(camwatch **out, camwatch_fn fn, void *userdata, sl_err *err);
/* Stops and joins the thread; camwatch_free(NULL) is a no-op. */
void camwatch_free(camwatch *w);

/* 1: a U3V camera with this USB serial is enumerated now, 0: none is,
 * -1: cannot tell (no USB access).  Any thread; enumerates afresh. */
int camwatch_present(const char *serial);

#endif
