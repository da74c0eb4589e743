/* pipeline_ahead.c - a pass over the frames with reading ahead
 * (pipeline_int.h, stream_feed_ahead): reader threads read, scale and
 * clean the next frames while the caller adds the current one.
 *
 * Why: reading (file I/O, conversion to float) and cleaning are serial
 * per frame, and every estimator's pass paid them before its own work:
 * 8-10 % of a run at 200^2 on one thread, all of it on the critical path
 * however many threads the estimator used.  Each reader does exactly what
 * the serial pass does to a frame (cube_reader_next, the scale,
 * prep_frame) with its own reader and cleaning copy, and the caller adds
 * the frames in order, so the frames, and every sum made from them, are
 * the same bits; only when and where the work happens changes.
 *
 * Why more than one reader: one costs ~0.5 ms a 512^2 frame (the page
 * cache copy, cfitsio's byte swap, the cleaning), so at 512^2 x 400 it
 * reads for ~0.2 s, while tsm-fourier's additions take 1.7 s of CPU: past
 * ~8 threads the caller would wait for one reader, capping that run near
 * 8x.  Reader j takes frames k0 + j, k0 + j + n, ... (n = s->readers,
 * 1 + (threads - 1) / 4: one up to 4 threads, four at 16).
 *
 * The ring is as long as the estimator asks (stream.ahead_want), within
 * AHEAD_MIN..AHEAD_MAX frames and AHEAD_BYTES: the direct method's add
 * returns only every batch of frames (up to 128), after the triple
 * kernel has held both cores for a batch's time.  A ring of 4 filled in
 * the first moments of that and the reader then waited, so the caller
 * waited for the rest of the next batch with one core idle: 0.17 s of a
 * 512^2 x 400 run on 2 threads.  A ring a batch long is read while the
 * kernel runs (the wait fell to 0.02-0.08 s).  The ring is the
 * stream's, kept for its later passes: fresh pages would cost their
 * first touch on every pass (16 MB at 200^2 x 100).  Frame k lives in
 * slot (k - k0) mod nslot; its reader waits until the frame nslot before
 * it has been added.
 *
 * A pass may be started before it is fed (stream_prefetch): the readers
 * fill the ring while the caller makes the estimator's plans, which are
 * mostly serial, so the first frames no longer wait for a reader once the
 * plan is done; the next feed of the same range takes the readers over,
 * and one of another range drops them.
 *
 * Memory: the ring (at most AHEAD_BYTES beyond AHEAD_MIN frames), until
 * stream_close; per extra reader, for the pass, a copy of the cleaning
 * (~5-13 bytes a pixel).  Threads: s->readers more than the caller's, for
 * the length of the pass; the pipeline uses them only when it was given
 * more than one thread.
 */
#include <pthread.h>
#include <stdlib.h>

#include "pipeline_int.h"

#define AHEAD_BYTES ((size_t)32 << 20)
#define AHEAD_MIN 4
#define AHEAD_MAX 128
#define AHEAD_READERS_MAX 8

typedef struct ahead ahead;

/* One reader thread and what it reads with. */
typedef struct reader {
    ahead *a;
    int j;                  /* frames k0 + j + i nread */
    cube_reader *rd;        /* reader 0: the stream's; others: a copy */
    prep *pp;               /* likewise (prep_frame writes its scratch) */
    pthread_t th;
} reader;

struct ahead {
    stream *s;
    float *ring;            /* nslot frames of w * h */
    int nslot, k0, k1, nread;
    int *slot_k;            /* the frame each slot holds, -1: none yet */
    int added;              /* frames k0..added-1 added: their slots are free */
    int bad_k, bad_rc, bad_j; /* the first frame a reader refused (k1: none),
                               * its code, and that reader */
    int stop;               /* an add failed, or the pass is over: stop */
    int running;            /* readers not finished */
    int running_started;    /* the readers were started (ahead_end joins) */
    pthread_mutex_t mu;
    pthread_cond_t free_cv, ready_cv;
    reader rdr[AHEAD_READERS_MAX];
};

/* Slot i of the ring. */
static float *slot(const ahead *a, int i)
{
    return a->ring + (size_t)i * a->s->w * a->s->h;
}

/* Frame k into f as the serial pass makes it; *pos: the reader's next
 * frame (a seek only when it is not k). */
static int read_frame(const stream *s, reader *me, int k, int *pos, float *f)
{
    int rc = *pos == k ? SL_OK : cube_reader_seek(me->rd, k);
    if (rc == SL_OK)
        rc = cube_reader_next(me->rd, f);
    *pos = rc == SL_OK ? k + 1 : -1;
    if (rc != SL_OK)
        return rc;
    size_t npx = (size_t)s->w * s->h;
    if (s->scale != 1.0)
        for (size_t p = 0; p < npx; p++)
            f[p] = (float)(f[p] * s->scale);
    if (me->pp)
        prep_frame(me->pp, f, NULL);
    return SL_OK;
}

/* A reader: its frames into their slots, in order. */
static void *ahead_run(void *arg)
{
    reader *me = arg;
    ahead *a = me->a;
    int pos = -1;
    for (int k = a->k0 + me->j; k < a->k1; k += a->nread) {
        int i = (k - a->k0) % a->nslot;
        pthread_mutex_lock(&a->mu);
        while (k >= a->added + a->nslot && !a->stop && k < a->bad_k)
            pthread_cond_wait(&a->free_cv, &a->mu);
        int go = !a->stop && k < a->bad_k;
        pthread_mutex_unlock(&a->mu);
        if (!go)
            break;
        int rc = read_frame(a->s, me, k, &pos, slot(a, i));
        pthread_mutex_lock(&a->mu);
        if (rc == SL_OK)
            a->slot_k[i] = k;
        else if (k < a->bad_k)
            a->bad_k = k, a->bad_rc = rc, a->bad_j = me->j;
        pthread_cond_signal(&a->ready_cv);
        pthread_mutex_unlock(&a->mu);
        if (rc != SL_OK)
            break;
    }
    pthread_mutex_lock(&a->mu);
    a->running--;
    pthread_cond_signal(&a->ready_cv);
    pthread_mutex_unlock(&a->mu);
    return NULL;
}

/* The caller's side: add each frame, in order, as it arrives; stops at
 * the first frame a reader refused (reported by the caller) or the first
 * failing add, which stops the readers.  SL_OK or the add's code. */
static int ahead_consume(ahead *a, add_fn add, void *h, const char *what, sl_err *err)
{
    for (int k = a->k0; k < a->k1; k++) {
        int i = (k - a->k0) % a->nslot;
        pthread_mutex_lock(&a->mu);
        while (a->slot_k[i] != k && k < a->bad_k && a->running > 0)
            pthread_cond_wait(&a->ready_cv, &a->mu);
        int have = a->slot_k[i] == k;
        pthread_mutex_unlock(&a->mu);
        if (!have)
            return SL_OK;
        int rc = add ? add(h, slot(a, i)) : SL_OK;
        pthread_mutex_lock(&a->mu);
        a->added = k + 1;
        a->stop = rc != SL_OK;
        pthread_cond_broadcast(&a->free_cv);
        pthread_mutex_unlock(&a->mu);
        if (rc != SL_OK)
            return sl_seterr(err, rc, "frame %d: %s", k, what);
    }
    return SL_OK;
}

/* The stream's ring, grown to the slots this pass wants when it can be;
 * the number of slots to use (0: none to be had).  Two slots a reader at
 * least, so that each can read while its last frame waits. */
static int ring_slots(stream *s, int k0, int k1)
{
    size_t bytes = sizeof(float) * s->w * s->h, fit = AHEAD_BYTES / bytes;
    int want = s->ahead_want > AHEAD_MIN ? s->ahead_want : AHEAD_MIN;
    want = want > 2 * s->readers ? want : 2 * s->readers;
    int cap = fit < AHEAD_MIN ? AHEAD_MIN : fit > AHEAD_MAX ? AHEAD_MAX : (int)fit;
    want = want < cap ? want : cap;
    if (k1 - k0 < want) /* never more slots than frames */
        want = k1 - k0 > 1 ? k1 - k0 : 1;
    if (s->ring_slots >= want)
        return want;
    float *r = malloc(bytes * want);
    if (!r)
        return s->ring_slots; /* the ring there is, if any */
    free(s->ring);
    s->ring = r;
    s->ring_slots = want;
    return want;
}

/* The readers' handles: reader 0 the stream's, the others copies, as many
 * as memory allows (a.nread is cut to those made). */
static void make_readers(ahead *a)
{
    stream *s = a->s;
    int want = s->readers < AHEAD_READERS_MAX ? s->readers : AHEAD_READERS_MAX;
    want = want < a->nslot / 2 ? want : a->nslot / 2;
    a->rdr[0] = (reader){.a = a, .j = 0, .rd = s->rd, .pp = s->pp};
    for (a->nread = 1; a->nread < want; a->nread++) {
        reader *r = &a->rdr[a->nread];
        *r = (reader){.a = a, .j = a->nread};
        if (cube_reader_dup(&r->rd, s->rd, NULL) != SL_OK ||
            (s->pp && prep_dup(&r->pp, s->pp, NULL) != SL_OK)) {
            cube_reader_free(r->rd);
            break;
        }
    }
}

/* Start the readers; 0 when one could not be (those started are stopped
 * and joined: the caller reads serially). */
static int start_readers(ahead *a)
{
    a->running = a->nread;
    for (int j = 0; j < a->nread; j++)
        if (pthread_create(&a->rdr[j].th, NULL, ahead_run, &a->rdr[j]) != 0) {
            pthread_mutex_lock(&a->mu);
            a->stop = 1;
            pthread_cond_broadcast(&a->free_cv);
            pthread_mutex_unlock(&a->mu);
            for (int i = 0; i < j; i++)
                pthread_join(a->rdr[i].th, NULL);
            return 0;
        }
    a->running_started = 1;
    return 1;
}

static int ahead_end(ahead *a, int rc, sl_err *err);

/* The readers of a pass over [k0, k1) started (on the heap: a prefetch
 * outlives its caller's frame); NULL when there is no ring or no thread
 * to be had (the caller reads serially). */
static ahead *ahead_start(stream *s, int k0, int k1)
{
    ahead *a = malloc(sizeof *a);
    if (!a)
        return NULL;
    *a = (ahead){.s = s, .k0 = k0, .k1 = k1, .added = k0, .bad_k = k1};
    if (!(a->nslot = ring_slots(s, k0, k1)) || !(a->slot_k = malloc(sizeof *a->slot_k * a->nslot))) {
        free(a);
        return NULL;
    }
    a->ring = s->ring;
    for (int i = 0; i < a->nslot; i++)
        a->slot_k[i] = -1;
    pthread_mutex_init(&a->mu, NULL);
    pthread_cond_init(&a->free_cv, NULL);
    pthread_cond_init(&a->ready_cv, NULL);
    make_readers(a);
    if (start_readers(a))
        return a;
    ahead_end(a, SL_OK, NULL);
    return NULL;
}

/* Stop and join a's readers (if they run), free a; rc, or the first
 * frame a reader refused when rc is SL_OK. */
static int ahead_end(ahead *a, int rc, sl_err *err)
{
    if (a->running_started) {
        pthread_mutex_lock(&a->mu); /* readers past a refused frame may wait */
        a->stop = 1;
        pthread_cond_broadcast(&a->free_cv);
        pthread_mutex_unlock(&a->mu);
        for (int j = 0; j < a->nread; j++)
            pthread_join(a->rdr[j].th, NULL);
        if (rc == SL_OK && a->bad_k < a->k1)
            rc = sl_seterr(err, a->bad_rc, "%s", cube_reader_errmsg(a->rdr[a->bad_j].rd));
    }
    for (int j = 1; j < a->nread; j++) {
        cube_reader_free(a->rdr[j].rd);
        prep_free(a->rdr[j].pp);
    }
    pthread_cond_destroy(&a->ready_cv);
    pthread_cond_destroy(&a->free_cv);
    pthread_mutex_destroy(&a->mu);
    free(a->slot_k);
    free(a);
    return rc;
}

void stream_prefetch(stream *s)
{
    if (s->ahead && !s->pb && !s->pre)
        s->pre = ahead_start(s, s->k0, s->k1);
}

void stream_prefetch_cancel(stream *s)
{
    if (s->pre)
        ahead_end(s->pre, SL_OK, NULL);
    s->pre = NULL;
}

int stream_feed_ahead(stream *s, int k0, int k1, add_fn add, void *h, const char *what,
                      sl_err *err, int *ran)
{
    ahead *a = s->pre;
    s->pre = NULL;
    if (a && (a->k0 != k0 || a->k1 != k1)) /* not this pass's: drop it */
        ahead_end(a, SL_OK, NULL), a = NULL;
    if (!a && !(a = ahead_start(s, k0, k1))) {
        *ran = 0;
        return SL_OK; /* no threads or ring: the caller reads serially */
    }
    *ran = 1;
    return ahead_end(a, ahead_consume(a, add, h, what, err), err);
}
