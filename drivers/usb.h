/* usb.h - libusb used directly for what users trip over with USB3 Vision
 * cameras: which devices are there, which are U3V cameras, is the camera
 * on a USB 2.0 link, may we open it (and the udev rule if not), is the
 * usbfs memory limit large enough, hot-plug events, and resetting a
 * wedged device.  Streaming itself is Aravis's job (drivers/camera).
 *
 * A U3V camera is recognised by its interfaces, not its vendor: USB3
 * Vision uses interface class 0xEF (miscellaneous) subclass 0x05 with
 * protocol 0x00 control, 0x01 event and 0x02 streaming.
 *
 * /sys paths (device strings, usbfs_memory_mb) are read under
 * $UMOCKDEV_DIR/sys when that variable is set (a umockdev testbed), else
 * under /sys.  One usb handle belongs to one thread: every callback runs
 * on the thread that calls usb_poll / usb_diagnose.
 */
#ifndef SL_USB_H
#define SL_USB_H

#include <stddef.h>
#include <stdint.h>

#include "status.h"

typedef struct usb usb;

/* Link speeds as libusb reports them (libusb_get_device_speed). */
enum {
    USB_SPEED_UNKNOWN = 0,
    USB_SPEED_LOW = 1,        /* 1.5 Mbit/s */
    USB_SPEED_FULL = 2,       /* 12 Mbit/s */
    USB_SPEED_HIGH = 3,       /* 480 Mbit/s: a USB 2.0 link */
    USB_SPEED_SUPER = 4,      /* 5 Gbit/s */
    USB_SPEED_SUPER_PLUS = 5  /* 10 Gbit/s */
};

/* Bits of usb_dev_info.u3v_ifaces: which U3V interfaces were found. */
#define USB_U3V_CONTROL 0x1u
#define USB_U3V_EVENT 0x2u
#define USB_U3V_STREAM 0x4u

#define USB_MAX_PORTS 7     /* USB allows at most 7 tiers of hubs */
#define USB_STR_MAX 128

typedef struct usb_dev_info {
    uint8_t bus, address;
    uint8_t port_path[USB_MAX_PORTS]; /* root-hub port first */
    int n_ports;                      /* 0 for a root hub */
    uint16_t vid, pid;
    uint16_t bcd_usb;                 /* 0x0300 and up: a USB3 device */
    uint8_t dev_class;                /* bDeviceClass */
    int speed;                        /* USB_SPEED_* negotiated link */
    double link_mbit_per_s;           /* 0 when unknown */
    int is_u3v;                       /* has a U3V control interface */
    unsigned u3v_ifaces;              /* USB_U3V_* bits */
    /* From sysfs (readable without permission); when sysfs lacks them,
     * usb_diagnose fills them from string descriptors if it can open
     * the device.  "" when unknown. */
    char manufacturer[USB_STR_MAX], product[USB_STR_MAX],
        serial[USB_STR_MAX];
} usb_dev_info;

/* Create / free a libusb context wrapper.  usb_free(NULL) is a no-op. */
int usb_new(usb **out, sl_err *err);
void usb_free(usb *u);
const char *usb_errmsg(const usb *u);

/* Enumerate: fill up to cap entries of devs, set *count to the number of
 * devices present (may exceed cap: call again with more room). */
int usb_list(usb *u, usb_dev_info *devs, int cap, int *count);

/* "port 2.1" style text, "root hub" for n_ports == 0. */
void usb_port_text(const usb_dev_info *d, char *buf, size_t n);
/* "SpeckCam U3 (1ab2:0001, serial 42) on bus 2 port 1". */
void usb_dev_label(const usb_dev_info *d, char *buf, size_t n);
/* The udev rule that lets group plugdev open vid:pid; returns SL_ERANGE
 * when n is too small. */
int usb_udev_rule(uint16_t vid, uint16_t pid, char *buf, size_t n);

/* ---- diagnosis ---- */

typedef enum usb_level {
    USB_LEVEL_OK = 0,   /* checked, fine */
    USB_LEVEL_INFO,     /* could not check, or worth knowing */
    USB_LEVEL_WARN,     /* works, but will hurt (USB 2.0 link, small usbfs) */
    USB_LEVEL_ERROR     /* will not work (no permission, device gone) */
} usb_level;

typedef enum usb_check {
    USB_CHECK_USBFS_MEMORY = 0, /* system-wide: dev == NULL */
    USB_CHECK_SPEED,
    USB_CHECK_ACCESS
} usb_check;

#define USB_FIX_MAX 1024
typedef struct usb_finding {
    usb_level level;
    usb_check check;
    char text[SL_ERRMSG_MAX]; /* one line: what was found */
    char fix[USB_FIX_MAX];    /* what to do (may span lines); "" if none */
} usb_finding;

/* "ok" "info" "warn" "error" / "usbfs_memory" "speed" "access" (JSON). */
const char *usb_level_name(usb_level lv);
const char *usb_check_name(usb_check c);

/* dev is NULL for system-wide findings.  Both pointers are valid only
 * during the call. */
typedef void (*usb_report_fn)(const usb_dev_info *dev, const usb_finding *f,
                              void *userdata);

/* usbfs caps the memory all usbfs transfers may pin at once (kernel
 * default 16 MB; 0 = unlimited).  A U3V stream keeps many large bulk
 * buffers queued (Aravis: several MB per frame buffer), so 16 MB starves
 * it into underruns; 256 MB covers a few cameras at full rate. */
#define USB_USBFS_MIN_MB 256
#define USB_USBFS_MEMORY_PATH "/sys/module/usbcore/parameters/usbfs_memory_mb"
#define USB_UDEV_RULES_FILE "/etc/udev/rules.d/99-specklab-camera.rules"

#define USB_DIAG_ALL_DEVICES 0x1u /* also non-camera devices */

/* Report, through fn: the usbfs memory limit first, then for each U3V
 * camera (every device with USB_DIAG_ALL_DEVICES) its link speed and
 * whether it can be opened.  Opening is the only way to know the
 * permission; it does not claim interfaces, so a camera streaming in
 * another process is not disturbed.  Returns SL_OK when the checks ran
 * (findings carry the problems), negative only when enumeration failed. */
int usb_diagnose(usb *u, unsigned flags, usb_report_fn fn, void *userdata);
/* The same two per-device checks for one device from usb_list. */
int usb_diagnose_device(usb *u, const usb_dev_info *dev, usb_report_fn fn,
                        void *userdata);
/* The usbfs check alone; *limit_mb = -1 when unreadable. */
int usb_check_usbfs_memory(usb *u, usb_finding *out, int *limit_mb);

/* ---- hot-plug ---- */

typedef enum usb_event_kind {
    USB_EVENT_ARRIVED = 1,
    USB_EVENT_LEFT = 2
} usb_event_kind;

/* dev is valid only during the call; for LEFT it is what was known at
 * arrival (strings included). The callback may call any usb_* function
 * except usb_hotplug_start/stop and usb_free. */
typedef void (*usb_hotplug_fn)(usb_event_kind kind, const usb_dev_info *dev,
                               void *userdata);

enum {
    USB_HOTPLUG_OFF = 0,
    USB_HOTPLUG_NATIVE = 1, /* libusb hot-plug callbacks (udev/netlink) */
    USB_HOTPLUG_RESCAN = 2  /* periodic re-enumeration in usb_poll */
};

#define USB_RESCAN_DEFAULT_MS 1000
#define USB_HOTPLUG_MAX_DEVICES 128 /* devices tracked; more are ignored */

/* Start delivering hot-plug events to fn.  Devices present now are
 * reported as arrivals too, so the caller's picture is complete.
 * Events are delivered only inside usb_poll, on the caller's thread.
 * Uses libusb hot-plug when libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG)
 * (Linux via udev/netlink, macOS; not Windows in libusb 1.0.26).
 * Without it, falls back to re-enumerating every USB_RESCAN_DEFAULT_MS
 * inside usb_poll: events then come up to that late, a device that
 * left and came back between two scans with a new address shows as
 * LEFT + ARRIVED, and one that came back with the same bus, address,
 * vid and pid is missed. */
int usb_hotplug_start(usb *u, usb_hotplug_fn fn, void *userdata);
/* Force the re-enumeration fallback with the given period (0: every
 * usb_poll), e.g. where udev events are not delivered (containers
 * without /run/udev). */
int usb_hotplug_start_rescan(usb *u, int interval_ms, usb_hotplug_fn fn,
                             void *userdata);
void usb_hotplug_stop(usb *u);
int usb_hotplug_mode(const usb *u);
/* Events lost because more than the queue held arrived in one poll. */
long usb_hotplug_dropped(const usb *u);

/* Pump libusb events for up to timeout_ms (0: do not block), then
 * deliver queued hot-plug events.  The caller's main loop stays in
 * charge; call it whenever the loop is idle. */
int usb_poll(usb *u, int timeout_ms);

/* ---- recovery ---- */

/* Reset (re-enumerate at the port) the device at bus/address via
 * libusb_reset_device.  The device may come back with a new address;
 * that is success.  err may be NULL; the message is also in usb_errmsg. */
int usb_reset(usb *u, int bus, int address, sl_err *err);

#endif
