/* usb_hotplug.c - see usb.h: hot-plug events, from libusb's callbacks when
 * the platform has them, else from rescans every interval_ms.  Events are
 * queued (QUEUE_CAP, overflow counted in dropped) and delivered by usb_poll,
 * never from inside libusb, so a callback may call back into usb_*.
 */
#include "usb_int.h"

#include <libusb.h>
#include <stdlib.h>
#include <string.h>

static void enqueue(usb *u, usb_event_kind kind, const usb_dev_info *d)
{
    if (u->q_len >= QUEUE_CAP) {
        u->dropped++;
        return;
    }
    u->queue[u->q_len].kind = kind;
    u->queue[u->q_len++].dev = *d;
}

static int same_device(const usb_dev_info *a, const usb_dev_info *b)
{
    return a->bus == b->bus && a->address == b->address && a->vid == b->vid &&
           a->pid == b->pid && a->n_ports == b->n_ports &&
           memcmp(a->port_path, b->port_path, (size_t)a->n_ports) == 0;
}

static void known_add(usb *u, const usb_dev_info *d)
{
    if (u->n_known < USB_HOTPLUG_MAX_DEVICES)
        u->known[u->n_known++] = *d;
}

static void known_remove(usb *u, int i)
{
    u->known[i] = u->known[--u->n_known];
}

static int LIBUSB_CALL on_hotplug(libusb_context *ctx, libusb_device *dev,
                                  libusb_hotplug_event ev, void *ud)
{
    usb *u = ud;
    usb_dev_info d;
    (void)ctx;
    /* The descriptor cache outlives the unplug, so LEFT still has
     * bus/address/vid/pid; strings come from the arrival record. */
    usb_fill_info(u, dev, &d);
    if (ev == LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED) {
        known_add(u, &d);
        enqueue(u, USB_EVENT_ARRIVED, &d);
        return 0;
    }
    for (int i = 0; i < u->n_known; i++)
        if (u->known[i].bus == d.bus && u->known[i].address == d.address) {
            d = u->known[i];
            known_remove(u, i);
            break;
        }
    enqueue(u, USB_EVENT_LEFT, &d);
    return 0; /* stay registered */
}

static int rescan(usb *u)
{
    int n = 0, r = usb_list(u, u->scan, USB_HOTPLUG_MAX_DEVICES, &n);
    if (r != SL_OK)
        return r;
    if (n > USB_HOTPLUG_MAX_DEVICES)
        n = USB_HOTPLUG_MAX_DEVICES;
    for (int i = u->n_known - 1; i >= 0; i--) {
        int still = 0;
        for (int j = 0; j < n && !still; j++)
            still = same_device(&u->known[i], &u->scan[j]);
        if (!still) {
            enqueue(u, USB_EVENT_LEFT, &u->known[i]);
            known_remove(u, i);
        }
    }
    for (int j = 0; j < n; j++) {
        int seen = 0;
        for (int i = 0; i < u->n_known && !seen; i++)
            seen = same_device(&u->known[i], &u->scan[j]);
        if (!seen) {
            known_add(u, &u->scan[j]);
            enqueue(u, USB_EVENT_ARRIVED, &u->scan[j]);
        }
    }
    u->last_scan_s = usb_now_s();
    return SL_OK;
}

static int hp_alloc(usb *u, usb_hotplug_fn fn, void *ud)
{
    if (u->hp_mode != USB_HOTPLUG_OFF)
        return sl_seterr(&u->err, SL_EINVAL, "usb: hot-plug already started");
    if (!fn)
        return sl_seterr(&u->err, SL_EINVAL, "usb: no hot-plug callback");
    u->known = calloc(USB_HOTPLUG_MAX_DEVICES, sizeof *u->known);
    u->scan = calloc(USB_HOTPLUG_MAX_DEVICES, sizeof *u->scan);
    u->queue = calloc(QUEUE_CAP, sizeof *u->queue);
    if (!u->known || !u->scan || !u->queue) {
        usb_hotplug_stop(u);
        return sl_seterr(&u->err, SL_ENOMEM, "usb: out of memory");
    }
    u->hp_fn = fn;
    u->hp_ud = ud;
    u->n_known = u->q_len = 0;
    u->dropped = 0;
    return SL_OK;
}

int usb_hotplug_start_rescan(usb *u, int interval_ms, usb_hotplug_fn fn,
                             void *ud)
{
    int r = hp_alloc(u, fn, ud);
    if (r != SL_OK)
        return r;
    u->hp_mode = USB_HOTPLUG_RESCAN;
    u->rescan_ms = interval_ms > 0 ? interval_ms : 0;
    r = rescan(u); /* devices present now arrive on the first poll */
    if (r != SL_OK)
        usb_hotplug_stop(u);
    return r;
}

int usb_hotplug_start(usb *u, usb_hotplug_fn fn, void *ud)
{
    int r;
    if (!libusb_has_capability(LIBUSB_CAP_HAS_HOTPLUG))
        return usb_hotplug_start_rescan(u, USB_RESCAN_DEFAULT_MS, fn, ud);
    r = hp_alloc(u, fn, ud);
    if (r != SL_OK)
        return r;
    /* ENUMERATE: libusb calls on_hotplug now for devices present. */
    r = libusb_hotplug_register_callback(
        u->ctx,
        LIBUSB_HOTPLUG_EVENT_DEVICE_ARRIVED | LIBUSB_HOTPLUG_EVENT_DEVICE_LEFT,
        LIBUSB_HOTPLUG_ENUMERATE, LIBUSB_HOTPLUG_MATCH_ANY,
        LIBUSB_HOTPLUG_MATCH_ANY, LIBUSB_HOTPLUG_MATCH_ANY, on_hotplug, u,
        &u->hp_handle);
    if (r != LIBUSB_SUCCESS) {
        usb_hotplug_stop(u);
        return sl_seterr(&u->err, SL_EIO, "usb: cannot register hot-plug "
                         "callback: %s", libusb_strerror(r));
    }
    u->hp_mode = USB_HOTPLUG_NATIVE;
    return SL_OK;
}

void usb_hotplug_stop(usb *u)
{
    if (!u)
        return;
    if (u->hp_mode == USB_HOTPLUG_NATIVE)
        libusb_hotplug_deregister_callback(u->ctx, u->hp_handle);
    u->hp_mode = USB_HOTPLUG_OFF;
    free(u->known);
    free(u->scan);
    free(u->queue);
    u->known = u->scan = NULL;
    u->queue = NULL;
    u->n_known = u->q_len = 0;
    u->hp_fn = NULL;
}

int usb_hotplug_mode(const usb *u) { return u->hp_mode; }
long usb_hotplug_dropped(const usb *u) { return u->dropped; }

int usb_poll(usb *u, int timeout_ms)
{
    struct timeval tv;
    int r;
    if (timeout_ms < 0)
        timeout_ms = 0;
    tv.tv_sec = timeout_ms / 1000;
    tv.tv_usec = (timeout_ms % 1000) * 1000;
    r = libusb_handle_events_timeout_completed(u->ctx, &tv, NULL);
    if (r != 0 && r != LIBUSB_ERROR_INTERRUPTED && r != LIBUSB_ERROR_TIMEOUT)
        return sl_seterr(&u->err, SL_EIO, "usb: event handling failed: %s",
                         libusb_strerror(r));
    if (u->hp_mode == USB_HOTPLUG_RESCAN &&
        usb_now_s() - u->last_scan_s >= 1e-3 * u->rescan_ms) {
        r = rescan(u);
        if (r != SL_OK)
            return r;
    }
    if (u->hp_mode == USB_HOTPLUG_OFF || u->delivering)
        return SL_OK;
    /* The callback may enqueue more (it may list devices): loop on the
     * live length, then empty the queue. */
    u->delivering = 1;
    for (int i = 0; i < u->q_len && u->hp_fn; i++)
        u->hp_fn(u->queue[i].kind, &u->queue[i].dev, u->hp_ud);
    u->q_len = 0;
    u->delivering = 0;
    return SL_OK;
}
