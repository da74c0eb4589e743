/* u3v_usb.c - the U3V camera as a usbfs device behind umockdev (see
 * u3v_usb.h).  URBs: a submitted URB is either answered at once (control
 * requests, GenCP commands on OUT) or parked on its endpoint until data
 * exists (GenCP acks on 0x81, stream units on 0x83); answered URBs wait in
 * `done` until the host reaps them, and their data is written into the
 * host's buffer at reap time, as the kernel does.  A timed-out transfer is
 * discarded by libusb (DISCARDURB): it is reaped with -ENOENT.
 */
#include <errno.h>
#include <linux/usbdevice_fs.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <umockdev.h>

#include "u3v_usb.h"

#define EP_CTRL_OUT 0x01
#define EP_CTRL_IN 0x81
#define EP_STREAM_IN 0x83

typedef struct urb_rec {
    UMockdevIoctlClient *client; /* the open file it came on: only it reaps it */
    UMockdevIoctlData *urb;   /* the host's struct usbdevfs_urb */
    GByteArray *data;         /* bytes for the host's buffer, or NULL */
    int data_off;             /* 8 for control (after the setup packet) */
    int status, actual;
} urb_rec;

struct u3v_usb {
    UMockdevTestbed *tb;
    UMockdevIoctlBase *handler;
    u3v_regs *regs;
    u3v_ident id;
    char *root;
    char node[64], sys[256];
    int addr;
    GMutex lock;
    int plugged;
    GQueue ctrl_in, stream_in, done; /* urb_rec */
    GQueue acks, units;              /* GByteArray */
    size_t unit_off;                 /* bytes of the head unit sent */
};

static void rec_free(urb_rec *r)
{
    if (!r)
        return;
    umockdev_ioctl_data_unref(r->urb);
    g_object_unref(r->client);
    if (r->data)
        g_byte_array_unref(r->data);
    g_free(r);
}

static void finish(u3v_usb *u, urb_rec *r, int status, GByteArray *data)
{
    r->status = status;
    r->data = data;
    r->actual = data ? (int)data->len : r->actual;
    g_queue_push_tail(&u->done, r);
}

/* Pair parked IN URBs with what is ready.  Caller holds the lock. */
static void match(u3v_usb *u)
{
    while (u->ctrl_in.length && u->acks.length) {
        urb_rec *r = g_queue_pop_head(&u->ctrl_in);
        GByteArray *a = g_queue_pop_head(&u->acks);
        struct usbdevfs_urb *urb = (struct usbdevfs_urb *)r->urb->data;
        if ((int)a->len > urb->buffer_length)
            g_byte_array_set_size(a, (guint)urb->buffer_length);
        finish(u, r, 0, a);
    }
    while (u->stream_in.length && u->units.length) {
        urb_rec *r = g_queue_pop_head(&u->stream_in);
        GByteArray *unit = g_queue_peek_head(&u->units);
        struct usbdevfs_urb *urb = (struct usbdevfs_urb *)r->urb->data;
        size_t left = unit->len - u->unit_off;
        size_t n = left < (size_t)urb->buffer_length ? left : (size_t)urb->buffer_length;
        GByteArray *piece = g_byte_array_sized_new((guint)n);
        g_byte_array_append(piece, unit->data + u->unit_off, (guint)n);
        u->unit_off += n;
        if (u->unit_off == unit->len) {
            g_byte_array_unref(g_queue_pop_head(&u->units));
            u->unit_off = 0;
        }
        finish(u, r, 0, piece);
    }
}

/* GET_DESCRIPTOR(string): 1 vendor, 2 model, 3 serial, 4 GUID. */
static GByteArray *string_desc(const u3v_usb *u, const uint8_t *setup)
{
    const char *s[] = {u->id.vendor, u->id.model, u->id.serial, u->id.guid};
    int idx = setup[2];
    GByteArray *d = g_byte_array_new();
    uint8_t head[2] = {0, 3};
    g_byte_array_append(d, head, 2);
    if (idx == 0) {
        static const uint8_t en_us[2] = {0x09, 0x04};
        g_byte_array_append(d, en_us, 2);
    } else if (idx <= 4 && s[idx - 1]) {
        for (const char *p = s[idx - 1]; *p && d->len < 254; p++) {
            uint8_t c[2] = {(uint8_t)*p, 0};
            g_byte_array_append(d, c, 2);
        }
    } else {
        g_byte_array_unref(d);
        return NULL;
    }
    d->data[0] = (uint8_t)d->len;
    unsigned want = setup[6] | (unsigned)setup[7] << 8;
    if (d->len > want)
        g_byte_array_set_size(d, want);
    return d;
}

static void submit_control(u3v_usb *u, urb_rec *r, const uint8_t *setup)
{
    int get_string = setup[0] == 0x80 && setup[1] == 6 && setup[3] == 3;
    if (get_string) {
        GByteArray *d = string_desc(u, setup);
        r->data_off = 8;
        if (d)
            finish(u, r, 0, d);
        else
            finish(u, r, -EPIPE, NULL);
        return;
    }
    /* SET/CLEAR_FEATURE(ENDPOINT_HALT) and other no-data requests: done. */
    r->actual = 0;
    finish(u, r, (setup[6] | setup[7]) ? -EPIPE : 0, NULL);
}

/* Returns the errno to answer the SUBMITURB ioctl with. */
static int submit(u3v_usb *u, UMockdevIoctlClient *c, UMockdevIoctlData *arg)
{
    UMockdevIoctlData *ud = umockdev_ioctl_data_resolve(
        arg, 0, sizeof(struct usbdevfs_urb), NULL);
    if (!ud)
        return EFAULT;
    struct usbdevfs_urb *urb = (struct usbdevfs_urb *)ud->data;
    urb->status = 0;
    urb->actual_length = 0;
    urb_rec *r = g_new0(urb_rec, 1);
    r->client = g_object_ref(c);
    r->urb = ud;
    int out = urb->type == USBDEVFS_URB_TYPE_CONTROL ||
              (urb->type == USBDEVFS_URB_TYPE_BULK && urb->endpoint == EP_CTRL_OUT);
    UMockdevIoctlData *buf = NULL;
    if (out && urb->buffer_length > 0)
        buf = umockdev_ioctl_data_resolve(ud, G_STRUCT_OFFSET(struct usbdevfs_urb, buffer),
                                          (gsize)urb->buffer_length, NULL);
    int e = 0;
    g_mutex_lock(&u->lock);
    /* Checked again under the lock: an unplug between the ioctl's arrival
     * and here must not leave this URB parked for ever. */
    if (!u->plugged || g_strcmp0(umockdev_ioctl_client_get_devnode(c), u->node)) {
        e = ENODEV;
    } else if (urb->type == USBDEVFS_URB_TYPE_CONTROL && buf && urb->buffer_length >= 8) {
        submit_control(u, r, buf->data);
    } else if (urb->type == USBDEVFS_URB_TYPE_BULK && urb->endpoint == EP_CTRL_OUT && buf) {
        uint8_t ack[U3V_CMD_MAX];
        int n = u3v_regs_command(u->regs, buf->data, (size_t)urb->buffer_length, ack);
        if (n > 0) {
            GByteArray *a = g_byte_array_sized_new((guint)n);
            g_byte_array_append(a, ack, (guint)n);
            g_queue_push_tail(&u->acks, a);
        }
        r->actual = urb->buffer_length;
        finish(u, r, 0, NULL);
    } else if (urb->type == USBDEVFS_URB_TYPE_BULK && urb->endpoint == EP_CTRL_IN) {
        g_queue_push_tail(&u->ctrl_in, r);
    } else if (urb->type == USBDEVFS_URB_TYPE_BULK && urb->endpoint == EP_STREAM_IN) {
        g_queue_push_tail(&u->stream_in, r);
    } else {
        e = EINVAL;
    }
    if (!e)
        match(u);
    g_mutex_unlock(&u->lock);
    if (buf)
        umockdev_ioctl_data_unref(buf);
    if (e)
        rec_free(r);
    return e;
}

static void reap(u3v_usb *u, UMockdevIoctlClient *c, UMockdevIoctlData *arg)
{
    g_mutex_lock(&u->lock);
    urb_rec *r = NULL;
    for (GList *l = u->done.head; l && !r; l = l->next)
        if (((urb_rec *)l->data)->client == c) {
            r = l->data;
            g_queue_delete_link(&u->done, l);
        }
    int gone = !u->plugged || g_strcmp0(umockdev_ioctl_client_get_devnode(c), u->node);
    g_mutex_unlock(&u->lock);
    if (!r) {
        umockdev_ioctl_client_complete(c, -1, gone ? ENODEV : EAGAIN);
        return;
    }
    struct usbdevfs_urb *urb = (struct usbdevfs_urb *)r->urb->data;
    if (r->data && r->data->len) {
        UMockdevIoctlData *buf = umockdev_ioctl_data_resolve(
            r->urb, G_STRUCT_OFFSET(struct usbdevfs_urb, buffer),
            (gsize)(r->data_off + (int)r->data->len), NULL);
        if (buf) {
            memcpy(buf->data + r->data_off, r->data->data, r->data->len);
            umockdev_ioctl_data_unref(buf);
        }
    }
    urb->status = r->status;
    urb->actual_length = r->status == 0 ? r->actual : 0;
    UMockdevIoctlData *ptr = umockdev_ioctl_data_resolve(arg, 0, sizeof(void *), NULL);
    umockdev_ioctl_data_set_ptr(ptr, 0, r->urb);
    umockdev_ioctl_client_complete(c, 0, 0);
    umockdev_ioctl_data_unref(ptr);
    rec_free(r);
}

static int discard_in(u3v_usb *u, GQueue *q, UMockdevIoctlClient *c, gulong addr)
{
    for (GList *l = q->head; l; l = l->next) {
        urb_rec *r = l->data;
        if (r->client == c && r->urb->client_addr == addr) {
            g_queue_delete_link(q, l);
            finish(u, r, -ENOENT, NULL);
            return 1;
        }
    }
    return 0;
}

static int discard(u3v_usb *u, UMockdevIoctlClient *c, UMockdevIoctlData *arg)
{
    gulong addr = 0;
    memcpy(&addr, arg->data, sizeof addr < (size_t)arg->data_len ? sizeof addr
                                                                  : (size_t)arg->data_len);
    g_mutex_lock(&u->lock);
    int found = discard_in(u, &u->ctrl_in, c, addr) || discard_in(u, &u->stream_in, c, addr);
    g_mutex_unlock(&u->lock);
    return found ? 0 : EINVAL;
}

/* A handle opened on the device as it is plugged now; one opened before
 * an unplug stays stale (ENODEV) even after the re-plug, as in usbfs. */
static int current(u3v_usb *u, UMockdevIoctlClient *c)
{
    g_mutex_lock(&u->lock);
    int ok = u->plugged && !g_strcmp0(umockdev_ioctl_client_get_devnode(c), u->node);
    g_mutex_unlock(&u->lock);
    return ok;
}

static void answer(UMockdevIoctlClient *c, int e)
{
    umockdev_ioctl_client_complete(c, e ? -1 : 0, e);
}

static gboolean on_ioctl(UMockdevIoctlBase *h, UMockdevIoctlClient *c, gpointer userdata)
{
    u3v_usb *u = userdata;
    UMockdevIoctlData *arg = umockdev_ioctl_client_get_arg(c);
    (void)h;
    gulong req = umockdev_ioctl_client_get_request(c);
    int reaping = req == USBDEVFS_REAPURB || req == USBDEVFS_REAPURBNDELAY;
    /* A handle from before the unplug may still reap what the unplug
     * completed (-ENODEV), then gets ENODEV for everything: libusb then
     * ends its transfers as NO_DEVICE instead of waiting for them. */
    if (!current(u, c) && !reaping) {
        answer(c, ENODEV);
        return TRUE;
    }
    switch (req) {
    case USBDEVFS_GET_CAPABILITIES: {
        /* As current kernels: one URB per transfer whatever its length
         * (libusb otherwise splits it into 16 KB URBs, and a short packet
         * would end only the first). */
        uint32_t caps = USBDEVFS_CAP_BULK_SCATTER_GATHER | USBDEVFS_CAP_NO_PACKET_SIZE_LIM |
                        USBDEVFS_CAP_REAP_AFTER_DISCONNECT;
        UMockdevIoctlData *d = umockdev_ioctl_data_resolve(arg, 0, 4, NULL);
        memcpy(d->data, &caps, 4);
        answer(c, 0);
        umockdev_ioctl_data_unref(d);
        return TRUE;
    }
    case USBDEVFS_GETDRIVER:
    case USBDEVFS_IOCTL:      /* libusb's auto-detach: DISCONNECT */
        answer(c, ENODATA);   /* no kernel driver bound: nothing to detach */
        return TRUE;
    case USBDEVFS_CLAIMINTERFACE:
    case USBDEVFS_RELEASEINTERFACE:
    case USBDEVFS_CLEAR_HALT:
    case USBDEVFS_RESET:
        answer(c, 0);
        return TRUE;
    case USBDEVFS_SUBMITURB:
        answer(c, submit(u, c, arg));
        return TRUE;
    case USBDEVFS_DISCARDURB:
        answer(c, discard(u, c, arg));
        return TRUE;
    case USBDEVFS_REAPURB:
    case USBDEVFS_REAPURBNDELAY:
        reap(u, c, arg);
        return TRUE;
    default:
        answer(c, ENOTTY);
        return TRUE;
    }
}

static void hex(GString *s, const uint8_t *b, size_t n)
{
    for (size_t i = 0; i < n; i++)
        g_string_append_printf(s, "%02x", b[i]);
}

/* Device and configuration descriptors as sysfs "descriptors" holds them.
 * The control interface carries the U3V device-info descriptor
 * (CS_INTERFACE 0x24, subtype 1): GenCP and U3V versions, then string
 * indexes (GUID 4, vendor 1, model 2, family -, version -, info -,
 * serial 3, user name -) and the speeds supported (SuperSpeed). */
static void descriptors(const u3v_ident *id, GString *s)
{
    static const uint8_t body[] = {
        8, 0x0B, 0, 3, 0xEF, 0x05, 0x00, 0,               /* IAD: U3V function */
        9, 4, 0, 0, 2, 0xEF, 0x05, 0x00, 0,               /* control */
        20, 0x24, 0x01, 0, 0, 1, 0, 0, 0, 1, 0,          /* device info */
        4, 1, 2, 0, 0, 0, 3, 0, 0x08,
        7, 5, EP_CTRL_IN, 2, 0x00, 0x04, 0, 7, 5, EP_CTRL_OUT, 2, 0x00, 0x04, 0,
        9, 4, 1, 0, 1, 0xEF, 0x05, 0x01, 0,               /* event */
        7, 5, 0x82, 2, 0x00, 0x04, 0,
        9, 4, 2, 0, 1, 0xEF, 0x05, 0x02, 0,               /* streaming */
        7, 5, EP_STREAM_IN, 2, 0x00, 0x04, 0};
    uint16_t bcd = 0x0300; /* a USB 3 camera, whatever link it got */
    uint8_t dev[18] = {18, 1, (uint8_t)bcd, (uint8_t)(bcd >> 8), 0xEF, 0x02, 0x01, 9,
                       (uint8_t)id->vid, (uint8_t)(id->vid >> 8), (uint8_t)id->pid,
                       (uint8_t)(id->pid >> 8), 0x00, 0x01, 1, 2, 3, 1};
    size_t total = 9 + sizeof body;
    uint8_t cfg[9] = {9, 2, (uint8_t)total, (uint8_t)(total >> 8), 3, 1, 0, 0x80, 50};
    hex(s, dev, sizeof dev);
    hex(s, cfg, sizeof cfg);
    hex(s, body, sizeof body);
}

int u3v_usb_plug(u3v_usb *u, sl_err *err)
{
    if (u3v_usb_plugged(u))
        return SL_OK;
    g_mutex_lock(&u->lock);
    u->addr++;
    snprintf(u->node, sizeof u->node, "/dev/bus/usb/%03d/%03d", u->id.bus, u->addr);
    g_mutex_unlock(&u->lock);
    snprintf(u->sys, sizeof u->sys, "/sys/devices/pci0000:00/0000:00:14.0/usb%d/%d-%d",
             u->id.bus, u->id.bus, u->id.port);
    GError *e = NULL;
    GString *s = g_string_new(NULL);
    g_string_append_printf(s, "P: %s\nN: %s\n", u->sys + 4, u->node + 5);
    g_string_append_printf(s, "E: SUBSYSTEM=usb\nE: DEVTYPE=usb_device\nE: DRIVER=usb\n"
                           "E: BUSNUM=%03d\nE: DEVNUM=%03d\nE: DEVNAME=%s\n",
                           u->id.bus, u->addr, u->node);
    g_string_append_printf(s, "A: busnum=%d\\n\nA: devnum=%d\\n\nA: speed=%d\\n\n"
                           "A: bConfigurationValue=1\\n\nA: manufacturer=%s\\n\n"
                           "A: product=%s\\n\nA: serial=%s\\n\nH: descriptors=",
                           u->id.bus, u->addr, u->id.speed_mbit, u->id.vendor,
                           u->id.model, u->id.serial);
    descriptors(&u->id, s);
    g_string_append_c(s, '\n');
    g_mutex_lock(&u->lock);
    u->plugged = 1;   /* before the node exists: the first ioctl is answered */
    g_mutex_unlock(&u->lock);
    /* The handler first, so an "add" uevent never announces a device whose
     * node cannot answer yet. */
    int ok = umockdev_testbed_attach_ioctl(u->tb, u->node, u->handler, &e) &&
             umockdev_testbed_add_from_string(u->tb, s->str, &e);
    g_string_free(s, TRUE);
    if (ok && u->id.node_mode) {
        char *path = g_strconcat(u->root, u->node, NULL);
        ok = chmod(path, (mode_t)u->id.node_mode) == 0;
        g_free(path);
    }
    if (!ok) {
        g_mutex_lock(&u->lock);
        u->plugged = 0;
        g_mutex_unlock(&u->lock);
        int rc = sl_seterr(err, SL_EIO, "cannot add the USB device %s to the testbed: %s",
                           u->node, e ? e->message : "chmod failed");
        g_clear_error(&e);
        return rc;
    }
    return SL_OK;
}

static void drop_bytes(GQueue *q)
{
    GByteArray *a;
    while ((a = g_queue_pop_head(q)))
        g_byte_array_unref(a);
}

/* Unplug as the kernel does: the "remove" uevent while sysfs still
 * answers, then the tree.  Parked URBs complete with -ENODEV; later
 * ioctls on open handles fail with ENODEV. */
void u3v_usb_unplug(u3v_usb *u)
{
    if (!u3v_usb_plugged(u))
        return;
    g_mutex_lock(&u->lock);
    u->plugged = 0;
    urb_rec *r;
    while ((r = g_queue_pop_head(&u->ctrl_in)))
        finish(u, r, -ENODEV, NULL);
    while ((r = g_queue_pop_head(&u->stream_in)))
        finish(u, r, -ENODEV, NULL);
    drop_bytes(&u->acks);
    drop_bytes(&u->units);
    u->unit_off = 0;
    g_mutex_unlock(&u->lock);
    umockdev_testbed_uevent(u->tb, u->sys, "remove");
    umockdev_testbed_remove_device(u->tb, u->sys);
    /* The handler stays attached to the old node: detaching it would
     * leave a host blocked in an ioctl without an answer. */
}

int u3v_usb_plugged(u3v_usb *u)
{
    g_mutex_lock(&u->lock);
    int p = u->plugged;
    g_mutex_unlock(&u->lock);
    return p;
}

const char *u3v_usb_node(const u3v_usb *u)
{
    return u->node;
}

const char *u3v_usb_root(const u3v_usb *u)
{
    return u->root;
}

int u3v_usb_set_file(u3v_usb *u, const char *rel_path, const char *text, sl_err *err)
{
    char *path = g_build_filename(u->root, rel_path, NULL);
    char *dir = g_path_get_dirname(path);
    GError *e = NULL;
    int ok = g_mkdir_with_parents(dir, 0755) == 0 &&
             g_file_set_contents(path, text, -1, &e);
    int rc = ok ? SL_OK : sl_seterr(err, SL_EIO, "cannot write %s: %s", path,
                                    e ? e->message : g_strerror(errno));
    g_clear_error(&e);
    g_free(dir);
    g_free(path);
    return rc;
}

int u3v_usb_new(u3v_usb **out, u3v_regs *regs, const u3v_ident *id, sl_err *err)
{
    *out = NULL;
    u3v_usb *u = g_new0(u3v_usb, 1);
    u->regs = regs;
    u->id = *id;
    u->addr = 1;
    g_mutex_init(&u->lock);
    g_queue_init(&u->ctrl_in);
    g_queue_init(&u->stream_in);
    g_queue_init(&u->done);
    g_queue_init(&u->acks);
    g_queue_init(&u->units);
    u->tb = umockdev_testbed_new();
    u->root = umockdev_testbed_get_root_dir(u->tb);
    u->handler = umockdev_ioctl_base_new();
    g_signal_connect(u->handler, "handle-ioctl", G_CALLBACK(on_ioctl), u);
    int rc = u3v_usb_plug(u, err);
    if (rc != SL_OK) {
        u3v_usb_free(u);
        return rc;
    }
    *out = u;
    return SL_OK;
}

void u3v_usb_free(u3v_usb *u)
{
    if (!u)
        return;
    u3v_usb_unplug(u);
    urb_rec *r;
    while ((r = g_queue_pop_head(&u->done)))
        rec_free(r);
    g_object_unref(u->handler);
    g_object_unref(u->tb);   /* removes the testbed directory */
    g_free(u->root);
    g_mutex_clear(&u->lock);
    g_free(u);
}

int u3v_usb_stream_push(u3v_usb *u, const void *data, size_t n, int max_units)
{
    g_mutex_lock(&u->lock);
    int ok = u->plugged && (int)u->units.length < max_units;
    if (ok) {
        GByteArray *a = g_byte_array_sized_new((guint)n);
        g_byte_array_append(a, data, (guint)n);
        g_queue_push_tail(&u->units, a);
        match(u);
    }
    g_mutex_unlock(&u->lock);
    return ok ? 0 : -1;
}

int u3v_usb_stream_queued(u3v_usb *u)
{
    g_mutex_lock(&u->lock);
    int n = (int)u->units.length;
    g_mutex_unlock(&u->lock);
    return n;
}

void u3v_usb_stream_flush(u3v_usb *u)
{
    g_mutex_lock(&u->lock);
    drop_bytes(&u->units);
    u->unit_off = 0;
    g_mutex_unlock(&u->lock);
}
