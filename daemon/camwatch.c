/* camwatch.c - the USB hot-plug thread of specklabd (camwatch.h). */
#include "camwatch.h"

#include <glib.h>
#include <stdlib.h>
#include <string.h>

/* usb_poll blocks this long at most: the stop flag's latency. */
#define POLL_MS 200

struct camwatch {
    camwatch_fn fn;
    void *ud;
    GThread *th;
    int stop;           /* atomic */
    GMutex mu;
    GCond cv;
    int started;        /* 1 running, -1 failed (err holds why), under mu */
    sl_err err;
};

static void on_event(usb_event_kind kind, const usb_dev_info *dev, void *userdata)
{
    camwatch *w = userdata;
    if (dev->is_u3v)
        w->fn(kind == USB_EVENT_ARRIVED, dev, w->ud);
}

static void set_started(camwatch *w, int how)
{
    g_mutex_lock(&w->mu);
    w->started = how;
    g_cond_signal(&w->cv);
    g_mutex_unlock(&w->mu);
}

/* The usb handle belongs to this thread (usb.h): made, polled and freed
 * here. */
static gpointer watch_main(gpointer data)
{
    camwatch *w = data;
    usb *u = NULL;
    if (usb_new(&u, &w->err) != SL_OK || usb_hotplug_start(u, on_event, w) != SL_OK) {
        if (u)
            sl_seterr(&w->err, SL_EIO, "USB hot-plug: %s", usb_errmsg(u));
        g_message("no USB hot-plug: %s", w->err.msg);
        usb_free(u);
        set_started(w, -1);
        return NULL;
    }
    set_started(w, 1);
    while (!g_atomic_int_get(&w->stop))
        usb_poll(u, POLL_MS);
    usb_hotplug_stop(u);
    usb_free(u);
    return NULL;
}

int camwatch_new(camwatch **out, camwatch_fn fn, void *userdata, sl_err *err)
{
    (void)err;
    camwatch *w = g_new0(camwatch, 1);
    w->fn = fn;
    w->ud = userdata;
    g_mutex_init(&w->mu);
    g_cond_init(&w->cv);
    /* Not waited for: libusb's start-up (udev enumeration) is not the
     * daemon's start-up's business; the thread says itself when USB
     * hot-plug cannot run. */
    w->th = g_thread_new("camwatch", watch_main, w);
    *out = w;
    return SL_OK;
}

void camwatch_free(camwatch *w)
{
    if (!w)
        return;
    g_atomic_int_set(&w->stop, 1);
    g_thread_join(w->th);
    g_mutex_clear(&w->mu);
    g_cond_clear(&w->cv);
    g_free(w);
}

int camwatch_present(const char *serial)
{
    usb *u = NULL;
    usb_dev_info devs[64];
    int n = 0, found = 0;
    if (usb_new(&u, NULL) != SL_OK || usb_list(u, devs, 64, &n) != SL_OK) {
        usb_free(u);
        return -1;
    }
    for (int i = 0; i < n && i < 64; i++)
        found |= devs[i].is_u3v && strcmp(devs[i].serial, serial) == 0;
    usb_free(u);
    return found;
}
