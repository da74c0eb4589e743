/* webtap.c - the acquisition thread's latest-frame slot; see webtap.h. */
#include "webtap.h"

#include <string.h>

struct webtap {
    gint want;             /* atomic: 1 = copy the next offered frame */
    gint skipped;          /* atomic (wraps after 2^32) */
    gint64 last_us;        /* the last copy: the offering thread's own */
    GMutex mu;             /* the slot: */
    float *pix;
    size_t cap;
    int w, h;
    guint64 seq;
    gint64 t_us;
    char uuid[WEBTAP_UUID_LEN + 1];
};

webtap *webtap_new(void)
{
    webtap *t = g_new0(webtap, 1);
    g_mutex_init(&t->mu);
    return t;
}

void webtap_free(webtap *t)
{
    if (!t)
        return;
    g_mutex_clear(&t->mu);
    g_free(t->pix);
    g_free(t);
}

void webtap_offer(webtap *t, const char *uuid, const float *pix, int w, int h)
{
    if (!t || w <= 0 || h <= 0)
        return;
    /* unasked, one frame a second keeps the slot recent for a new viewer */
    gint64 now = g_get_monotonic_time();
    if (!g_atomic_int_get(&t->want) && now - t->last_us < WEBTAP_IDLE_US)
        return;
    if (!g_mutex_trylock(&t->mu)) {
        g_atomic_int_inc(&t->skipped);
        return;
    }
    size_t n = (size_t)w * (size_t)h;
    if (n > t->cap) {      /* the first frame of a size only */
        g_free(t->pix);
        t->pix = g_try_new(float, n);
        t->cap = t->pix ? n : 0;
    }
    if (t->pix) {
        memcpy(t->pix, pix, n * sizeof *pix);
        t->w = w, t->h = h;
        t->seq++;
        t->t_us = now;
        t->last_us = now;
        g_strlcpy(t->uuid, uuid ? uuid : "", sizeof t->uuid);
        g_atomic_int_set(&t->want, 0);
    }
    g_mutex_unlock(&t->mu);
}

void webtap_want(webtap *t)
{
    if (t)
        g_atomic_int_set(&t->want, 1);
}

int webtap_take(webtap *t, webtap_frame *f)
{
    int got = 0;
    if (!t)
        return 0;
    g_mutex_lock(&t->mu);
    size_t n = (size_t)t->w * (size_t)t->h;
    if (t->seq > f->seq && n > 0) {
        if (n > f->cap) {
            g_free(f->pix);
            f->pix = g_new(float, n);
            f->cap = n;
        }
        memcpy(f->pix, t->pix, n * sizeof *f->pix);
        f->w = t->w, f->h = t->h, f->seq = t->seq, f->t_us = t->t_us;
        memcpy(f->uuid, t->uuid, sizeof f->uuid);
        got = 1;
    }
    g_mutex_unlock(&t->mu);
    return got;
}

guint64 webtap_seq(webtap *t)
{
    guint64 seq = 0;
    if (t) {
        g_mutex_lock(&t->mu);
        seq = t->seq;
        g_mutex_unlock(&t->mu);
    }
    return seq;
}

guint64 webtap_skipped(webtap *t)
{
    return t ? (guint64)(guint)g_atomic_int_get(&t->skipped) : 0;
}
