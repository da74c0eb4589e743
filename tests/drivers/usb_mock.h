/* usb_mock.h - the USB mock behind test_usb.c: a umockdev testbed whose
 * "handle-ioctl" handler answers usbfs ioctls (capabilities, reset,
 * control URBs for string descriptors) for fake devices described by
 * fake_dev, plus the fixtures that add and remove them.  Included by
 * test_usb.c only (its helpers are static).  See test_usb.c for how the
 * binary re-executes itself under the umockdev preload.
 */
#ifndef SL_TEST_USB_MOCK_H
#define SL_TEST_USB_MOCK_H

#include "preload_fx.h"
#include "tcheck.h"
#include "usb.h"

#include <errno.h>
#include <sys/ioctl.h>
#include <linux/usbdevice_fs.h>
#include <stdint.h>
#include <stdlib.h>
#include <time.h>
#include <umockdev.h>
#include <unistd.h>

#define NOBODY 65534

/* ---- the USB mock ---- */

typedef struct pending {
    UMockdevIoctlData *urb, *buf;
} pending;

typedef struct mock {
    UMockdevTestbed *tb;
    UMockdevIoctlBase *handler;
    char *root;
    int n_reset;          /* USBDEVFS_RESET seen (atomic) */
    int reset_errno;      /* answer RESET with this errno, 0 = success */
    int n_unknown;        /* ioctls the mock did not know (atomic) */
    char last_reset[64];  /* device node of the last reset */
    const char *strings[3]; /* string descriptors 1..3 */
    GMutex lock;
    GQueue urbs; /* submitted control URBs waiting to be reaped */
} mock;

typedef struct fake_dev {
    int bus, addr, port;
    uint16_t vid, pid, bcd_usb;
    int kind;        /* FAKE_U3V, FAKE_UVC (webcam), FAKE_DISK */
    int speed_mbit;  /* sysfs "speed" */
    const char *manufacturer, *product, *serial; /* sysfs; NULL: absent */
} fake_dev;

enum { FAKE_U3V, FAKE_UVC, FAKE_DISK };

/* Answer a GET_DESCRIPTOR(string) control request into buf (after the
 * 8-byte setup packet); returns the length or -1 to stall. */
static int string_descriptor(mock *m, const uint8_t *setup, uint8_t *out,
                             int cap)
{
    int idx = setup[2], len = 0;
    uint8_t d[2 + 2 * 64];
    if (setup[1] != 6 || setup[3] != 3) /* GET_DESCRIPTOR, type STRING */
        return -1;
    if (idx == 0) { /* language table: en-US */
        d[2] = 0x09; d[3] = 0x04; len = 4;
    } else if (idx <= 3 && m->strings[idx - 1]) {
        const char *s = m->strings[idx - 1];
        for (len = 2; *s && len < (int)sizeof d; s++, len += 2) {
            d[len] = (uint8_t)*s; d[len + 1] = 0;
        }
    } else
        return -1;
    d[0] = (uint8_t)len; d[1] = 3;
    int want = setup[6] | setup[7] << 8;
    len = len < want ? len : want;
    len = len < cap ? len : cap;
    memcpy(out, d, (size_t)len);
    return len;
}

static void submit_urb(mock *m, UMockdevIoctlClient *c, UMockdevIoctlData *arg)
{
    UMockdevIoctlData *ud = umockdev_ioctl_data_resolve(
        arg, 0, sizeof(struct usbdevfs_urb), NULL);
    struct usbdevfs_urb *urb = (struct usbdevfs_urb *)ud->data;
    if (urb->type != USBDEVFS_URB_TYPE_CONTROL || urb->buffer_length < 8) {
        umockdev_ioctl_data_unref(ud);
        umockdev_ioctl_client_complete(c, -1, EINVAL);
        return;
    }
    pending *p = g_new0(pending, 1);
    p->urb = ud;
    p->buf = umockdev_ioctl_data_resolve(
        ud, G_STRUCT_OFFSET(struct usbdevfs_urb, buffer),
        (gsize)urb->buffer_length, NULL);
    g_mutex_lock(&m->lock);
    g_queue_push_tail(&m->urbs, p);
    g_mutex_unlock(&m->lock);
    umockdev_ioctl_client_complete(c, 0, 0);
}

/* Complete the oldest URB: the data appears at reap time, as with the
 * kernel. */
static void reap_urb(mock *m, UMockdevIoctlClient *c, UMockdevIoctlData *arg)
{
    g_mutex_lock(&m->lock);
    pending *p = g_queue_pop_head(&m->urbs);
    g_mutex_unlock(&m->lock);
    if (!p) {
        umockdev_ioctl_client_complete(c, -1, EAGAIN);
        return;
    }
    struct usbdevfs_urb *urb = (struct usbdevfs_urb *)p->urb->data;
    int n = string_descriptor(m, p->buf->data, p->buf->data + 8,
                              urb->buffer_length - 8);
    urb->status = n < 0 ? -EPIPE : 0;
    urb->actual_length = n < 0 ? 0 : n;
    UMockdevIoctlData *ptr = umockdev_ioctl_data_resolve(arg, 0,
                                                         sizeof(void *), NULL);
    umockdev_ioctl_data_set_ptr(ptr, 0, p->urb);
    umockdev_ioctl_client_complete(c, 0, 0);
    umockdev_ioctl_data_unref(ptr);
    umockdev_ioctl_data_unref(p->buf);
    umockdev_ioctl_data_unref(p->urb);
    g_free(p);
}

static gboolean on_ioctl(UMockdevIoctlBase *h, UMockdevIoctlClient *c,
                         gpointer userdata)
{
    mock *m = userdata;
    UMockdevIoctlData *arg = umockdev_ioctl_client_get_arg(c);
    (void)h;
    switch (umockdev_ioctl_client_get_request(c)) {
    case USBDEVFS_GET_CAPABILITIES: {
        UMockdevIoctlData *d = umockdev_ioctl_data_resolve(arg, 0, 4, NULL);
        memset(d->data, 0, 4); /* no optional usbfs features */
        umockdev_ioctl_client_complete(c, 0, 0);
        umockdev_ioctl_data_unref(d);
        return TRUE;
    }
    case USBDEVFS_RESET:
        g_mutex_lock(&m->lock);
        g_strlcpy(m->last_reset, umockdev_ioctl_client_get_devnode(c),
                  sizeof m->last_reset);
        g_mutex_unlock(&m->lock);
        g_atomic_int_inc(&m->n_reset);
        umockdev_ioctl_client_complete(c, m->reset_errno ? -1 : 0,
                                       m->reset_errno);
        return TRUE;
    case USBDEVFS_CLAIMINTERFACE:
    case USBDEVFS_RELEASEINTERFACE:
        umockdev_ioctl_client_complete(c, 0, 0);
        return TRUE;
    case USBDEVFS_SUBMITURB:
        submit_urb(m, c, arg);
        return TRUE;
    case USBDEVFS_REAPURB:
    case USBDEVFS_REAPURBNDELAY:
        reap_urb(m, c, arg);
        return TRUE;
    default:
        g_atomic_int_inc(&m->n_unknown);
        umockdev_ioctl_client_complete(c, -1, ENOTTY);
        return TRUE;
    }
}

static int mock_init(mock *m)
{
    memset(m, 0, sizeof *m);
    if (!fx_preloaded())
        return -1;
    g_mutex_init(&m->lock);
    g_queue_init(&m->urbs);
    m->tb = umockdev_testbed_new();
    m->root = umockdev_testbed_get_root_dir(m->tb);
    m->handler = umockdev_ioctl_base_new();
    g_signal_connect(m->handler, "handle-ioctl", G_CALLBACK(on_ioctl), m);
    return 0;
}

static void mock_done(mock *m)
{
    pending *p;
    if (!m->tb)
        return;
    while ((p = g_queue_pop_head(&m->urbs))) {
        umockdev_ioctl_data_unref(p->buf);
        umockdev_ioctl_data_unref(p->urb);
        g_free(p);
    }
    g_object_unref(m->handler);
    g_object_unref(m->tb);
    g_free(m->root);
    g_mutex_clear(&m->lock);
}

static void hex(GString *s, const uint8_t *b, size_t n)
{
    for (size_t i = 0; i < n; i++)
        g_string_append_printf(s, "%02x", b[i]);
}

/* Device + configuration descriptors as the kernel exposes them in the
 * sysfs "descriptors" attribute. */
static void descriptors(const fake_dev *f, GString *s)
{
    static const uint8_t u3v[] = {
        8, 0x0B, 0, 3, 0xEF, 0x05, 0x00, 0,          /* IAD: U3V function */
        9, 4, 0, 0, 2, 0xEF, 0x05, 0x00, 0,          /* control */
        7, 5, 0x81, 2, 0x00, 0x04, 0, 7, 5, 0x01, 2, 0x00, 0x04, 0,
        9, 4, 1, 0, 1, 0xEF, 0x05, 0x01, 0,          /* event */
        7, 5, 0x82, 2, 0x00, 0x04, 0,
        9, 4, 2, 0, 1, 0xEF, 0x05, 0x02, 0,          /* streaming */
        7, 5, 0x83, 2, 0x00, 0x04, 0};
    static const uint8_t uvc[] = {
        8, 0x0B, 0, 2, 0x0E, 0x03, 0x00, 0,          /* IAD: video */
        9, 4, 0, 0, 1, 0x0E, 0x01, 0x00, 0,          /* video control */
        7, 5, 0x81, 3, 0x10, 0x00, 6,
        9, 4, 1, 0, 1, 0x0E, 0x02, 0x00, 0,          /* video streaming */
        7, 5, 0x82, 2, 0x00, 0x02, 0};
    static const uint8_t disk[] = {
        9, 4, 0, 0, 2, 0x08, 0x06, 0x50, 0,          /* mass storage */
        7, 5, 0x81, 2, 0x00, 0x02, 0, 7, 5, 0x02, 2, 0x00, 0x02, 0};
    const uint8_t *body = f->kind == FAKE_U3V   ? u3v
                          : f->kind == FAKE_UVC ? uvc
                                                : disk;
    size_t nb = f->kind == FAKE_U3V   ? sizeof u3v
                : f->kind == FAKE_UVC ? sizeof uvc
                                      : sizeof disk;
    uint8_t nif = f->kind == FAKE_U3V ? 3 : f->kind == FAKE_UVC ? 2 : 1;
    uint8_t cls = f->kind == FAKE_DISK ? 0x00 : 0xEF; /* IAD: EF/02/01 */
    uint8_t dev[18] = {18, 1, (uint8_t)f->bcd_usb, (uint8_t)(f->bcd_usb >> 8),
                       cls, cls ? 0x02 : 0, cls ? 0x01 : 0,
                       f->bcd_usb >= 0x300 ? 9 : 64,
                       (uint8_t)f->vid, (uint8_t)(f->vid >> 8),
                       (uint8_t)f->pid, (uint8_t)(f->pid >> 8), 0x00, 0x01,
                       1, 2, 3, 1};
    size_t total = 9 + nb;
    uint8_t cfg[9] = {9, 2, (uint8_t)total, (uint8_t)(total >> 8), nif, 1, 0,
                      0x80, 50};
    hex(s, dev, sizeof dev);
    hex(s, cfg, sizeof cfg);
    hex(s, body, nb);
}

static char *syspath_of(const fake_dev *f)
{
    return g_strdup_printf("/sys/devices/pci0000:00/0000:00:14.0/usb%d/%d-%d",
                           f->bus, f->bus, f->port);
}

/* Add f to the testbed: sysfs device, udev properties, device node and
 * the ioctl handler on it (attached first, so an "add" uevent never
 * announces a device whose node cannot answer yet). */
static int mock_add(mock *m, const fake_dev *f)
{
    GString *s = g_string_new(NULL);
    char *node = g_strdup_printf("/dev/bus/usb/%03d/%03d", f->bus, f->addr);
    char *sys = syspath_of(f);
    GError *e = NULL;
    int ok = umockdev_testbed_attach_ioctl(m->tb, node, m->handler, &e);
    g_string_append_printf(s, "P: %s\nN: %s\n", sys + 4, node + 5);
    g_string_append_printf(s, "E: SUBSYSTEM=usb\nE: DEVTYPE=usb_device\n"
                           "E: DRIVER=usb\nE: BUSNUM=%03d\nE: DEVNUM=%03d\n"
                           "E: DEVNAME=%s\n", f->bus, f->addr, node);
    g_string_append_printf(s, "A: busnum=%d\\n\nA: devnum=%d\\n\n"
                           "A: speed=%d\\n\nA: bConfigurationValue=1\\n\n",
                           f->bus, f->addr, f->speed_mbit);
    if (f->manufacturer)
        g_string_append_printf(s, "A: manufacturer=%s\\n\n", f->manufacturer);
    if (f->product)
        g_string_append_printf(s, "A: product=%s\\n\n", f->product);
    if (f->serial)
        g_string_append_printf(s, "A: serial=%s\\n\n", f->serial);
    g_string_append(s, "H: descriptors=");
    descriptors(f, s);
    g_string_append_c(s, '\n');
    if (ok)
        ok = umockdev_testbed_add_from_string(m->tb, s->str, &e);
    if (!ok)
        fprintf(stderr, "mock_add: %s\n", e ? e->message : "?");
    g_clear_error(&e);
    g_string_free(s, TRUE);
    g_free(node);
    g_free(sys);
    return ok ? 0 : -1;
}

/* Unplug: the "remove" uevent first (while sysfs still answers), then
 * the sysfs tree, as the kernel does. */
static void mock_remove(mock *m, const fake_dev *f)
{
    char *sys = syspath_of(f);
    umockdev_testbed_uevent(m->tb, sys, "remove");
    umockdev_testbed_remove_device(m->tb, sys);
    g_free(sys);
}

static const fake_dev CAM = {2, 3, 1, 0x1ab2, 0x0001, 0x0300, FAKE_U3V, 5000,
                             "Specklab", "SpeckCam U3", "SC0042"};
static const fake_dev CAM2 = {3, 2, 4, 0x2b1c, 0x0010, 0x0310, FAKE_U3V, 5000,
                              "OtherVision", "OV-5", "77"};
static const fake_dev WEBCAM = {1, 4, 2, 0x046d, 0x0825, 0x0200, FAKE_UVC,
                                480, "Logitech", "Webcam C270", NULL};
static const fake_dev DISK = {1, 5, 3, 0x0781, 0x5581, 0x0320, FAKE_DISK,
                              5000, "SanDisk", "Ultra", "4C53"};

/* A testbed holding devs[0..n) (NULL entries skipped) and a usb handle
 * on it.  1: not preloaded; -1: failed, nothing left behind. */
static int setup(mock *m, usb **u, const fake_dev *const *devs, int n)
{
    *u = NULL;
    if (mock_init(m) != 0)
        return 1;
    for (int i = 0; i < n; i++)
        if (devs[i] && mock_add(m, devs[i]) != 0) {
            mock_done(m);
            return -1;
        }
    if (usb_new(u, NULL) != SL_OK) {
        mock_done(m);
        return -1;
    }
    return 0;
}

#define SETUP(m, u, ...)                                                      \
    do {                                                                      \
        const fake_dev *devs_[] = {__VA_ARGS__};                              \
        int r_ = setup(m, u, devs_, (int)(sizeof devs_ / sizeof devs_[0]));   \
        if (r_ == 1)                                                          \
            SKIP("not running under " PRELOAD_LIB);                           \
        CHECK(r_ == 0, "cannot build the testbed");                           \
    } while (0)

static void teardown(mock *m, usb *u)
{
    usb_free(u);
    mock_done(m);
}

static const usb_dev_info *find(const usb_dev_info *d, int n, uint16_t vid)
{
    for (int i = 0; i < n; i++)
        if (d[i].vid == vid)
            return &d[i];
    return NULL;
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

#endif
