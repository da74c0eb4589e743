/* usb.c - see usb.h.
 *
 * Everything is read the way lsusb does: descriptors, speed and strings
 * come from libusb's sysfs-backed cache and sysfs attributes, which need
 * no permission; only the access check and the reset open the device.
 */
#include "usb.h"

#include <errno.h>
#include <libusb.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "usb_int.h"

double usb_now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* First line of a small text file into buf; "" when unreadable. */
static int read_line(const char *path, char *buf, size_t n)
{
    FILE *f = fopen(path, "r");
    buf[0] = '\0';
    if (!f)
        return -1;
    if (!fgets(buf, (int)n, f))
        buf[0] = '\0';
    fclose(f);
    buf[strcspn(buf, "\r\n")] = '\0';
    return 0;
}

/* sysfs names a device "usbB" (root hub) or "B-p1.p2...": the same name
 * libusb's Linux backend uses under /sys/bus/usb/devices. */
static void sysfs_attr(const usb *u, const usb_dev_info *d, const char *attr,
                       char *buf, size_t n)
{
    char name[64], path[1024];
    int k = d->n_ports == 0
                ? snprintf(name, sizeof name, "usb%d", d->bus)
                : snprintf(name, sizeof name, "%d-%d", d->bus, d->port_path[0]);
    for (int i = 1; i < d->n_ports && k > 0 && (size_t)k < sizeof name; i++)
        k += snprintf(name + k, sizeof name - (size_t)k, ".%d",
                      d->port_path[i]);
    snprintf(path, sizeof path, "%s/bus/usb/devices/%s/%s", u->sysfs_root, name,
             attr);
    read_line(path, buf, n);
}

static int map_speed(int s, double *mbit)
{
    switch (s) {
    case LIBUSB_SPEED_LOW: *mbit = 1.5; return USB_SPEED_LOW;
    case LIBUSB_SPEED_FULL: *mbit = 12; return USB_SPEED_FULL;
    case LIBUSB_SPEED_HIGH: *mbit = 480; return USB_SPEED_HIGH;
    case LIBUSB_SPEED_SUPER: *mbit = 5000; return USB_SPEED_SUPER;
    case LIBUSB_SPEED_UNKNOWN: *mbit = 0; return USB_SPEED_UNKNOWN;
    default: *mbit = 10000; return USB_SPEED_SUPER_PLUS; /* also 20G */
    }
}

/* U3V interfaces of the active configuration (or the first one when the
 * device is unconfigured). */
static unsigned u3v_ifaces(libusb_device *dev)
{
    struct libusb_config_descriptor *cfg = NULL;
    unsigned mask = 0;
    if (libusb_get_active_config_descriptor(dev, &cfg) != 0 &&
        libusb_get_config_descriptor(dev, 0, &cfg) != 0)
        return 0;
    for (int i = 0; i < cfg->bNumInterfaces; i++) {
        const struct libusb_interface *itf = &cfg->interface[i];
        for (int a = 0; a < itf->num_altsetting; a++) {
            const struct libusb_interface_descriptor *id = &itf->altsetting[a];
            if (id->bInterfaceClass != U3V_CLASS ||
                id->bInterfaceSubClass != U3V_SUBCLASS)
                continue;
            if (id->bInterfaceProtocol == 0x00) mask |= USB_U3V_CONTROL;
            if (id->bInterfaceProtocol == 0x01) mask |= USB_U3V_EVENT;
            if (id->bInterfaceProtocol == 0x02) mask |= USB_U3V_STREAM;
        }
    }
    libusb_free_config_descriptor(cfg);
    return mask;
}

void usb_fill_info(const usb *u, libusb_device *dev, usb_dev_info *d)
{
    struct libusb_device_descriptor dd;
    memset(d, 0, sizeof *d);
    d->bus = libusb_get_bus_number(dev);
    d->address = libusb_get_device_address(dev);
    int np = libusb_get_port_numbers(dev, d->port_path, USB_MAX_PORTS);
    d->n_ports = np > 0 ? np : 0;
    if (libusb_get_device_descriptor(dev, &dd) == 0) {
        d->vid = dd.idVendor;
        d->pid = dd.idProduct;
        d->bcd_usb = dd.bcdUSB;
        d->dev_class = dd.bDeviceClass;
    }
    d->speed = map_speed(libusb_get_device_speed(dev), &d->link_mbit_per_s);
    d->u3v_ifaces = u3v_ifaces(dev);
    d->is_u3v = (d->u3v_ifaces & USB_U3V_CONTROL) != 0;
    sysfs_attr(u, d, "manufacturer", d->manufacturer, sizeof d->manufacturer);
    sysfs_attr(u, d, "product", d->product, sizeof d->product);
    sysfs_attr(u, d, "serial", d->serial, sizeof d->serial);
}

int usb_new(usb **out, sl_err *err)
{
    usb *u;
    const char *umd = getenv("UMOCKDEV_DIR");
    int r, rc;
    *out = NULL;
    u = calloc(1, sizeof *u);
    if (!u)
        return sl_seterr(err, SL_ENOMEM, "usb: out of memory");
    r = snprintf(u->sysfs_root, sizeof u->sysfs_root, "%s/sys", umd ? umd : "");
    if (r < 0 || (size_t)r >= sizeof u->sysfs_root) {
        rc = sl_seterr(err, SL_ERANGE, "usb: $UMOCKDEV_DIR is too long");
        goto undo_alloc;
    }
    r = libusb_init(&u->ctx);
    if (r != 0) {
        rc = sl_seterr(err, SL_EIO, "usb: libusb_init failed: %s",
                       libusb_strerror(r));
        goto undo_alloc;
    }
    *out = u;
    return SL_OK;
undo_alloc:
    free(u);
    return rc;
}

void usb_free(usb *u)
{
    if (!u)
        return;
    usb_hotplug_stop(u);
    libusb_exit(u->ctx);
    free(u);
}

const char *usb_errmsg(const usb *u)
{
    return u ? u->err.msg : "no usb handle";
}

int usb_list(usb *u, usb_dev_info *devs, int cap, int *count)
{
    libusb_device **list;
    ssize_t n = libusb_get_device_list(u->ctx, &list);
    *count = 0;
    if (n < 0)
        return sl_seterr(&u->err, SL_EIO, "usb: cannot list devices: %s",
                         libusb_strerror((int)n));
    for (ssize_t i = 0; i < n && i < cap; i++)
        usb_fill_info(u, list[i], &devs[i]);
    *count = (int)n;
    libusb_free_device_list(list, 1);
    return SL_OK;
}

void usb_port_text(const usb_dev_info *d, char *buf, size_t n)
{
    int k = snprintf(buf, n, d->n_ports ? "port " : "root hub");
    for (int i = 0; i < d->n_ports && k > 0 && (size_t)k < n; i++)
        k += snprintf(buf + k, n - (size_t)k, i ? ".%d" : "%d",
                      d->port_path[i]);
}

void usb_dev_label(const usb_dev_info *d, char *buf, size_t n)
{
    char port[48];
    usb_port_text(d, port, sizeof port);
    snprintf(buf, n, "%s%s(%04x:%04x%s%s) on bus %d %s", d->product,
             d->product[0] ? " " : "", d->vid, d->pid,
             d->serial[0] ? ", serial " : "", d->serial, d->bus, port);
}

int usb_udev_rule(uint16_t vid, uint16_t pid, char *buf, size_t n)
{
    int k = snprintf(buf, n,
                     "SUBSYSTEM==\"usb\", ATTR{idVendor}==\"%04x\", "
                     "ATTR{idProduct}==\"%04x\", MODE=\"0660\", "
                     "GROUP=\"plugdev\"",
                     vid, pid);
    return (k < 0 || (size_t)k >= n) ? SL_ERANGE : SL_OK;
}

/* ---- diagnosis ---- */

const char *usb_level_name(usb_level lv)
{
    static const char *const names[] = {"ok", "info", "warn", "error"};
    return (unsigned)lv < 4 ? names[lv] : "?";
}

const char *usb_check_name(usb_check c)
{
    static const char *const names[] = {"usbfs_memory", "speed", "access"};
    return (unsigned)c < 3 ? names[c] : "?";
}

static void finding(usb_finding *f, usb_level lv, usb_check c)
{
    f->level = lv;
    f->check = c;
    f->text[0] = f->fix[0] = '\0';
}

int usb_check_usbfs_memory(usb *u, usb_finding *f, int *limit_mb)
{
    char path[1024], line[64], *end;
    long mb;
    snprintf(path, sizeof path, "%s/module/usbcore/parameters/usbfs_memory_mb",
             u->sysfs_root);
    *limit_mb = -1;
    finding(f, USB_LEVEL_INFO, USB_CHECK_USBFS_MEMORY);
    if (read_line(path, line, sizeof line) != 0) {
        snprintf(f->text, sizeof f->text,
                 "usbfs memory limit unknown: cannot read %s (%s)",
                 USB_USBFS_MEMORY_PATH, strerror(errno));
        return SL_OK;
    }
    errno = 0;
    mb = strtol(line, &end, 10);
    if (errno || end == line || mb < 0 || mb > 1L << 30) {
        snprintf(f->text, sizeof f->text, "usbfs memory limit unknown: %s "
                 "holds \"%.32s\"", USB_USBFS_MEMORY_PATH, line);
        return SL_OK;
    }
    *limit_mb = (int)mb;
    if (mb == 0) {
        f->level = USB_LEVEL_OK;
        snprintf(f->text, sizeof f->text, "usbfs memory limit: unlimited (0)");
    } else if (mb >= USB_USBFS_MIN_MB) {
        f->level = USB_LEVEL_OK;
        snprintf(f->text, sizeof f->text, "usbfs memory limit: %ld MB", mb);
    } else {
        f->level = USB_LEVEL_WARN;
        snprintf(f->text, sizeof f->text,
                 "usbfs memory limit is %ld MB (%s): too small for "
                 "high-bandwidth or multi-camera USB3 Vision streaming "
                 "(want >= %d MB or 0 = unlimited)",
                 mb, USB_USBFS_MEMORY_PATH, USB_USBFS_MIN_MB);
        snprintf(f->fix, sizeof f->fix,
                 "Until reboot: echo 1000 | sudo tee %s\n"
                 "Permanently: add usbcore.usbfs_memory_mb=1000 to "
                 "GRUB_CMDLINE_LINUX_DEFAULT in /etc/default/grub and run "
                 "sudo update-grub (if usbcore is a module instead: put "
                 "\"options usbcore usbfs_memory_mb=1000\" in "
                 "/etc/modprobe.d/usbcore.conf)",
                 USB_USBFS_MEMORY_PATH);
    }
    return SL_OK;
}

static void speed_finding(const usb_dev_info *d, usb_finding *f)
{
    char label[400];
    const char *what = d->is_u3v ? "camera" : "device";
    usb_dev_label(d, label, sizeof label);
    finding(f, USB_LEVEL_OK, USB_CHECK_SPEED);
    if (d->speed == USB_SPEED_UNKNOWN) {
        f->level = USB_LEVEL_INFO;
        snprintf(f->text, sizeof f->text, "link speed of %s %s is unknown",
                 what, label);
    } else if (d->bcd_usb >= 0x0300 && d->speed <= USB_SPEED_HIGH) {
        f->level = d->is_u3v ? USB_LEVEL_WARN : USB_LEVEL_INFO;
        snprintf(f->text, sizeof f->text,
                 "%s %s is on a USB %s link (%g Mbit/s): use a USB3 port/cable",
                 what, label, d->speed == USB_SPEED_HIGH ? "2.0" : "1.1",
                 d->link_mbit_per_s);
        snprintf(f->fix, sizeof f->fix,
                 "Plug it into a USB 3 port (blue or marked SS) with a USB 3 "
                 "cable, directly or through a USB 3 hub: any USB 2 cable, "
                 "hub or extension in the chain limits the link to 480 "
                 "Mbit/s.");
    } else {
        snprintf(f->text, sizeof f->text, "%s %s: %g Mbit/s link", what, label,
                 d->link_mbit_per_s);
    }
}

static void access_finding(const usb_dev_info *d, int r, usb_finding *f)
{
    char label[400], rule[256];
    usb_dev_label(d, label, sizeof label);
    finding(f, r == 0 ? USB_LEVEL_OK : USB_LEVEL_ERROR, USB_CHECK_ACCESS);
    if (r == 0) {
        snprintf(f->text, sizeof f->text,
                 "can open /dev/bus/usb/%03d/%03d (%s)", d->bus, d->address,
                 label);
    } else if (r == LIBUSB_ERROR_ACCESS) {
        usb_udev_rule(d->vid, d->pid, rule, sizeof rule);
        snprintf(f->text, sizeof f->text,
                 "no permission to open /dev/bus/usb/%03d/%03d (%s)", d->bus,
                 d->address, label);
        snprintf(f->fix, sizeof f->fix,
                 "Let group plugdev open it: put this line in %s\n"
                 "  %s\n"
                 "then run: sudo udevadm control --reload-rules && sudo "
                 "udevadm trigger (or replug the camera), and make sure you "
                 "are in group plugdev: sudo usermod -aG plugdev $USER, then "
                 "log in again.",
                 USB_UDEV_RULES_FILE, rule);
    } else {
        snprintf(f->text, sizeof f->text, "cannot open /dev/bus/usb/%03d/%03d "
                 "(%s): %s", d->bus, d->address, label, libusb_strerror(r));
    }
}

/* Strings from the device itself when sysfs had none (non-Linux, or an
 * old kernel); bounded by libusb's 1 s control-transfer timeout each. */
static void strings_from_device(libusb_device *dev, libusb_device_handle *h,
                                usb_dev_info *d)
{
    struct libusb_device_descriptor dd;
    if (libusb_get_device_descriptor(dev, &dd) != 0)
        return;
    uint8_t idx[3] = {dd.iManufacturer, dd.iProduct, dd.iSerialNumber};
    char *buf[3] = {d->manufacturer, d->product, d->serial};
    for (int i = 0; i < 3; i++) {
        if (buf[i][0] || idx[i] == 0)
            continue;
        int k = libusb_get_string_descriptor_ascii(
            h, idx[i], (unsigned char *)buf[i], USB_STR_MAX);
        buf[i][k > 0 ? (k < USB_STR_MAX ? k : USB_STR_MAX - 1) : 0] = '\0';
    }
}

static void diagnose_one(libusb_device *dev, const usb_dev_info *in,
                         usb_report_fn fn, void *ud)
{
    usb_dev_info d = *in;
    usb_finding f;
    libusb_device_handle *h = NULL;
    int r = libusb_open(dev, &h);
    if (r == 0) {
        strings_from_device(dev, h, &d);
        libusb_close(h);
    }
    speed_finding(&d, &f);
    fn(&d, &f, ud);
    access_finding(&d, r, &f);
    fn(&d, &f, ud);
}

int usb_diagnose(usb *u, unsigned flags, usb_report_fn fn, void *ud)
{
    usb_finding f;
    usb_dev_info d;
    libusb_device **list;
    int mb;
    ssize_t n;
    usb_check_usbfs_memory(u, &f, &mb);
    fn(NULL, &f, ud);
    n = libusb_get_device_list(u->ctx, &list);
    if (n < 0)
        return sl_seterr(&u->err, SL_EIO, "usb: cannot list devices: %s",
                         libusb_strerror((int)n));
    for (ssize_t i = 0; i < n; i++) {
        usb_fill_info(u, list[i], &d);
        if (d.is_u3v || (flags & USB_DIAG_ALL_DEVICES))
            diagnose_one(list[i], &d, fn, ud);
    }
    libusb_free_device_list(list, 1);
    return SL_OK;
}

/* The libusb device at bus/address from a fresh list (referenced; the
 * caller unrefs), or NULL. */
static libusb_device *find_device(usb *u, int bus, int address)
{
    libusb_device **list, *found = NULL;
    ssize_t n = libusb_get_device_list(u->ctx, &list);
    for (ssize_t i = 0; i < n && !found; i++)
        if (libusb_get_bus_number(list[i]) == bus &&
            libusb_get_device_address(list[i]) == address)
            found = libusb_ref_device(list[i]);
    if (n >= 0)
        libusb_free_device_list(list, 1);
    return found;
}

int usb_diagnose_device(usb *u, const usb_dev_info *d, usb_report_fn fn,
                        void *ud)
{
    libusb_device *dev = find_device(u, d->bus, d->address);
    if (!dev)
        return sl_seterr(&u->err, SL_EINVAL, "usb: no device at bus %d "
                         "address %d (unplugged, or re-enumerated with a new "
                         "address)", d->bus, d->address);
    diagnose_one(dev, d, fn, ud);
    libusb_unref_device(dev);
    return SL_OK;
}

/* ---- recovery ---- */

int usb_reset(usb *u, int bus, int address, sl_err *err)
{
    libusb_device_handle *h = NULL;
    usb_dev_info d;
    char label[400];
    int r, rc;
    libusb_device *dev = find_device(u, bus, address);
    if (!dev) {
        sl_seterr(&u->err, SL_EINVAL, "usb reset: no device at bus %d address "
                  "%d (unplugged, or re-enumerated with a new address: list "
                  "devices again)", bus, address);
        goto out;
    }
    usb_fill_info(u, dev, &d);
    usb_dev_label(&d, label, sizeof label);
    r = libusb_open(dev, &h);
    if (r != 0) {
        sl_seterr(&u->err, SL_EIO, "usb reset: %s /dev/bus/usb/%03d/%03d (%s)"
                  ": %s", r == LIBUSB_ERROR_ACCESS ? "no permission to open"
                  : "cannot open", bus, address, label,
                  r == LIBUSB_ERROR_ACCESS ? "add the udev rule that `specklab "
                  "devices` prints, or run as root" : libusb_strerror(r));
        goto undo_ref;
    }
    /* NOT_FOUND: the reset made the device re-enumerate (new address). */
    r = libusb_reset_device(h);
    if (r != 0 && r != LIBUSB_ERROR_NOT_FOUND)
        sl_seterr(&u->err, SL_EIO, "usb reset of %s failed: %s", label,
                  libusb_strerror(r));
    else
        sl_clearerr(&u->err);
    libusb_close(h);
undo_ref:
    libusb_unref_device(dev);
out:
    rc = u->err.code;
    if (err)
        *err = u->err;
    return rc;
}
