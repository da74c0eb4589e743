/* webview.h - the web page's images, computed on their own thread.
 *
 * One long-lived thread, at low priority (nice 10, as the worker), takes
 * frames from the acquisition's tap (webtap.h) and makes what viewers are
 * shown: the latest frame as a PNG in each stretch asked for recently, and
 * the running mean power spectrum of the frames taken (on a log scale,
 * reset when the run or the frame size changes) as a PNG of the frame's
 * size.  It works only while viewers ask (webview_demand: for the next
 * 3 s, at the highest rate asked, 0.2..30 Hz) and at most half of its
 * time, so the compute follows the viewers and never the camera, and a
 * large frame lowers the view's rate rather than taking a core.  The
 * acquisition never waits for it (webtap.h).
 *
 * Threads: every function may be called from any thread.  notify (may be
 * NULL) is called from the view's thread after new products are out.
 */
#ifndef SL_DAEMON_WEBVIEW_H
#define SL_DAEMON_WEBVIEW_H

#include <glib.h>

#include "webtap.h"

#define WEBVIEW_MAX_HZ 30.0
#define WEBVIEW_MIN_HZ 0.2

typedef struct webview webview;

typedef struct webview_info {
    guint64 seq;                 /* the frame shown (webtap seq); 0: none yet */
    int w, h;
    char uuid[WEBTAP_UUID_LEN + 1];   /* its run */
    double min, max, mean;       /* its finite pixels */
    long ps_frames;              /* frames in the power spectrum */
    guint64 taken, skipped;      /* frames taken from the tap; skipped busy */
    double hz;                   /* the rate viewers ask for; 0: idle */
} webview_info;

webview *webview_new(webtap *tap, void (*notify)(void *user), void *user);
/* Stop and join the thread. */
void webview_free(webview *v);

/* Keep the products fresh at hz for the next 3 s; stretch (web_stretch,
 * or -1) is rendered from now on while asked for (10 s). */
void webview_demand(webview *v, double hz, int stretch);

/* The latest PNG (a reference: g_bytes_unref), NULL when there is none
 * yet in that stretch; *seq (may be NULL) the frame it shows. */
GBytes *webview_frame_png(webview *v, int stretch, guint64 *seq);
GBytes *webview_powspec_png(webview *v, guint64 *seq, long *nframes);
void webview_info_get(webview *v, webview_info *out);

#endif
