/* webtap.h - frames handed from the acquisition thread to the web view
 * (webview.h) without the acquisition ever waiting on it.
 *
 * A latest-frame slot: the web side asks for a frame (webtap_want, at the
 * viewers' rate); the acquisition thread copies the next good frame it
 * offers into the slot, but only when one was asked for and only when it
 * gets the slot's mutex at once (g_mutex_trylock): when the web side is
 * copying out at that moment the frame is skipped (counted), never waited
 * for.  When nobody asked, one frame a second is copied all the same, so
 * that a viewer arriving during or after a run sees a recent frame at
 * once; any other offer costs a clock read and an atomic read.  So the
 * copies follow the viewers' rate, not the camera's, and a slow, stuck or
 * absent web side cannot delay a frame.  The slot keeps the last frame
 * after the run ends.
 */
#ifndef SL_DAEMON_WEBTAP_H
#define SL_DAEMON_WEBTAP_H

#include <glib.h>
#include <stddef.h>

#define WEBTAP_UUID_LEN 36
#define WEBTAP_IDLE_US 1000000   /* a copy at least this often, asked or not */

typedef struct webtap webtap;

webtap *webtap_new(void);
void webtap_free(webtap *t);

/* Acquisition thread: a good frame (w x h floats, row y at pix + y*w) of
 * run uuid.  t may be NULL. */
void webtap_offer(webtap *t, const char *uuid, const float *pix, int w, int h);

/* Web side: copy the next offered frame. */
void webtap_want(webtap *t);

typedef struct webtap_frame {
    float *pix;            /* owned by the caller (g_free); grown as needed */
    size_t cap;            /* pixels pix can hold */
    int w, h;
    guint64 seq;           /* 1, 2, ... per copied frame */
    gint64 t_us;           /* g_get_monotonic_time of the copy */
    char uuid[WEBTAP_UUID_LEN + 1];
} webtap_frame;

/* When the slot holds a newer frame than f->seq, copy it into f and
 * return 1; else 0. */
int webtap_take(webtap *t, webtap_frame *f);
/* The slot's frame count (0: never a frame). */
guint64 webtap_seq(webtap *t);
/* Frames asked for but skipped because the slot was busy. */
guint64 webtap_skipped(webtap *t);

#endif
