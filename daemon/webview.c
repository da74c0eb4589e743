/* webview.c - the web page's images on their own thread; see webview.h. */
#define _GNU_SOURCE
#include "webview.h"

#include <errno.h>
#include <math.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "webfft.h"
#include "webpng.h"

#define DEMAND_US 3000000       /* a demand keeps the view working this long */
#define STRETCH_US 10000000     /* a stretch is rendered this long after asked */
#define VIEW_NICE 10

struct webview {
    webtap *tap;
    void (*notify)(void *);
    void *user;
    GThread *th;
    /* The thread's own. */
    webtap_frame fr;
    webps *ps;
    float *logps;
    size_t logps_cap;
    guint64 rendered[WEB_NSTRETCH];   /* seq of each stretch's last render */
    /* Shared, under mu. */
    GMutex mu;
    GCond cv;
    int stop;
    gint64 demand_until, hz_t, stretch_t[WEB_NSTRETCH];
    double hz;
    GBytes *png[WEB_NSTRETCH], *ps_png;
    guint64 png_seq[WEB_NSTRETCH], ps_seq;
    webview_info info;
};

/* A new frame into the power spectrum (a new accumulator for a new run or
 * size); its statistics into *info. */
static void take_frame(webview *v, webview_info *info)
{
    webtap_frame *f = &v->fr;
    size_t n = (size_t)f->w * (size_t)f->h;
    int fresh = strcmp(info->uuid, f->uuid) || info->w != f->w || info->h != f->h;
    double lo;
    if (!webpng_range(f->pix, n, 0.5, &lo, &info->max, &info->mean, &info->min))
        info->max = info->mean = info->min = NAN;
    if (fresh || !v->ps) {
        webps_free(v->ps);
        v->ps = webps_new(f->w, f->h);
        memset(v->rendered, 0, sizeof v->rendered);
    }
    if (v->ps)
        webps_add(v->ps, f->pix);
    info->seq = f->seq, info->w = f->w, info->h = f->h;
    memcpy(info->uuid, f->uuid, sizeof info->uuid);
    info->ps_frames = webps_count(v->ps);
    info->taken++;
}

static GBytes *render_powspec(webview *v)
{
    size_t n = (size_t)v->fr.w * (size_t)v->fr.h;
    double lo, hi, mean, min;
    if (n > v->logps_cap) {
        g_free(v->logps);
        v->logps = g_new(float, n);
        v->logps_cap = n;
    }
    if (!webps_log_mean(v->ps, v->logps) || !webpng_range(v->logps, n, 1.0, &lo, &hi, &mean, &min))
        return NULL;
    return webpng_gray(v->logps, v->fr.w, v->fr.h, WEB_STRETCH_LINEAR, lo, hi);
}

/* One round: a new frame if the tap has one, the PNGs it needs, published. */
static void tick(webview *v, const int want[WEB_NSTRETCH])
{
    webview_info info;
    g_mutex_lock(&v->mu);
    info = v->info;
    g_mutex_unlock(&v->mu);
    int got = webtap_take(v->tap, &v->fr);
    webtap_want(v->tap);   /* the next frame, for the next round */
    if (got)
        take_frame(v, &info);
    info.skipped = webtap_skipped(v->tap);
    GBytes *png[WEB_NSTRETCH] = {0}, *ps = NULL;
    int any = got, ranged = 0;
    double lo = NAN, hi = NAN, mean, min;
    for (int s = 0; s < WEB_NSTRETCH && v->fr.seq > 0; s++)
        if (want[s] && v->rendered[s] != v->fr.seq) {
            if (!ranged++ && !webpng_range(v->fr.pix, (size_t)v->fr.w * (size_t)v->fr.h, 0.5,
                                           &lo, &hi, &mean, &min))
                lo = hi = NAN;
            png[s] = webpng_gray(v->fr.pix, v->fr.w, v->fr.h, s, lo, hi);
            v->rendered[s] = v->fr.seq;
            any = 1;
        }
    if (got)
        ps = render_powspec(v);
    g_mutex_lock(&v->mu);
    for (int s = 0; s < WEB_NSTRETCH; s++)
        if (png[s]) {
            if (v->png[s])
                g_bytes_unref(v->png[s]);
            v->png[s] = png[s];
            v->png_seq[s] = v->fr.seq;
        }
    if (ps) {
        if (v->ps_png)
            g_bytes_unref(v->ps_png);
        v->ps_png = ps;
        v->ps_seq = v->fr.seq;
    }
    double hz = v->info.hz;
    v->info = info;
    v->info.hz = hz;
    g_mutex_unlock(&v->mu);
    if (any && v->notify)
        v->notify(v->user);
}

static void lower_priority(void)
{
    pid_t tid = (pid_t)syscall(SYS_gettid);
    if (setpriority(PRIO_PROCESS, (id_t)tid, VIEW_NICE) != 0)
        g_message("web view thread: cannot lower its priority: %s", g_strerror(errno));
}

static gpointer view_main(gpointer data)
{
    webview *v = data;
    gint64 next = 0;
    lower_priority();
    g_mutex_lock(&v->mu);
    while (!v->stop) {
        gint64 now = g_get_monotonic_time();
        if (now >= v->demand_until) {           /* nobody looks: sleep */
            v->info.hz = 0;
            g_cond_wait_until(&v->cv, &v->mu, now + DEMAND_US);
            continue;
        }
        if (now < next) {
            g_cond_wait_until(&v->cv, &v->mu, next);
            continue;
        }
        int want[WEB_NSTRETCH];
        for (int s = 0; s < WEB_NSTRETCH; s++)
            want[s] = v->stretch_t[s] > 0 && now - v->stretch_t[s] < STRETCH_US;
        v->info.hz = v->hz;
        gint64 period = (gint64)(1e6 / v->hz);
        g_mutex_unlock(&v->mu);
        tick(v, want);
        gint64 end = g_get_monotonic_time();
        /* at the asked rate, and busy at most half of the time */
        next = MAX(now + period, end + (end - now));
        g_mutex_lock(&v->mu);
    }
    g_mutex_unlock(&v->mu);
    return NULL;
}

webview *webview_new(webtap *tap, void (*notify)(void *user), void *user)
{
    webview *v = g_new0(webview, 1);
    v->tap = tap;
    v->notify = notify;
    v->user = user;
    v->hz = 1;
    v->info.min = v->info.max = v->info.mean = NAN;
    g_mutex_init(&v->mu);
    g_cond_init(&v->cv);
    v->th = g_thread_new("webview", view_main, v);
    return v;
}

void webview_free(webview *v)
{
    if (!v)
        return;
    g_mutex_lock(&v->mu);
    v->stop = 1;
    g_cond_signal(&v->cv);
    g_mutex_unlock(&v->mu);
    g_thread_join(v->th);
    for (int s = 0; s < WEB_NSTRETCH; s++)
        if (v->png[s])
            g_bytes_unref(v->png[s]);
    if (v->ps_png)
        g_bytes_unref(v->ps_png);
    webps_free(v->ps);
    g_free(v->fr.pix);
    g_free(v->logps);
    g_mutex_clear(&v->mu);
    g_cond_clear(&v->cv);
    g_free(v);
}

void webview_demand(webview *v, double hz, int stretch)
{
    gint64 now = g_get_monotonic_time();
    hz = !(hz >= WEBVIEW_MIN_HZ) ? WEBVIEW_MIN_HZ : hz > WEBVIEW_MAX_HZ ? WEBVIEW_MAX_HZ : hz;
    g_mutex_lock(&v->mu);
    int woke = now >= v->demand_until;
    v->demand_until = now + DEMAND_US;
    if (hz >= v->hz || now - v->hz_t > DEMAND_US) {
        woke |= hz > v->hz;
        v->hz = hz;
        v->hz_t = now;
    }
    if (stretch >= 0 && stretch < WEB_NSTRETCH) {
        woke |= !(v->stretch_t[stretch] > 0 && now - v->stretch_t[stretch] < STRETCH_US);
        v->stretch_t[stretch] = now;
    }
    if (woke)
        g_cond_signal(&v->cv);
    g_mutex_unlock(&v->mu);
}

GBytes *webview_frame_png(webview *v, int stretch, guint64 *seq)
{
    GBytes *b = NULL;
    if (stretch < 0 || stretch >= WEB_NSTRETCH)
        return NULL;
    g_mutex_lock(&v->mu);
    if (v->png[stretch])
        b = g_bytes_ref(v->png[stretch]);
    if (seq)
        *seq = v->png_seq[stretch];
    g_mutex_unlock(&v->mu);
    return b;
}

GBytes *webview_powspec_png(webview *v, guint64 *seq, long *nframes)
{
    GBytes *b = NULL;
    g_mutex_lock(&v->mu);
    if (v->ps_png)
        b = g_bytes_ref(v->ps_png);
    if (seq)
        *seq = v->ps_seq;
    if (nframes)
        *nframes = v->info.ps_frames;
    g_mutex_unlock(&v->mu);
    return b;
}

void webview_info_get(webview *v, webview_info *out)
{
    g_mutex_lock(&v->mu);
    *out = v->info;
    g_mutex_unlock(&v->mu);
}
