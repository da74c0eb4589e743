/* pipeline_ahead.c - a pass over the frames with reading ahead
 * (pipeline_int.h, stream_feed_ahead): one thread reads, scales and
 * cleans the next frames while the caller adds the current one.
 *
 * Why: reading (file I/O, conversion to float) and cleaning are serial
 * per frame, and every estimator's pass paid them before its own work:
 * 8-10 % of a run at 200^2 on one thread, all of it on the critical path
 * however many threads the estimator used.  The reader does exactly what
 * the serial pass does, frame by frame in order (cube_reader_next, the
 * scale, prep_frame), so the frames, and every sum made from them, are
 * the same bits; only when the work happens changes.
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
 * first touch on every pass (16 MB at 200^2 x 100).
 *
 * Memory: the ring (at most AHEAD_BYTES beyond AHEAD_MIN frames), until
 * stream_close.  Threads: one more than the caller's, for the length of
 * the pass; the pipeline uses it only when it was given more than one
 * thread.
 */
#include <pthread.h>
#include <stdlib.h>

#include "pipeline_int.h"

#define AHEAD_BYTES ((size_t)32 << 20)
#define AHEAD_MIN 4
#define AHEAD_MAX 128

typedef struct ahead {
    stream *s;
    float *ring;            /* nslot frames of w * h */
    int nslot, k0, k1;      /* ring size; frames [k0, k1) */
    int head, count;        /* next slot to fill; slots filled, not added */
    int done, stop, rc;     /* reader finished (rc: SL_EEND at the end) */
    pthread_mutex_t mu;
    pthread_cond_t cv;
} ahead;

/* Slot i of the ring. */
static float *slot(const ahead *a, int i)
{
    return a->ring + (size_t)i * a->s->w * a->s->h;
}

/* The reader: frames k0..k1-1 into the ring, in order. */
static void *ahead_run(void *arg)
{
    ahead *a = arg;
    stream *s = a->s;
    size_t npx = (size_t)s->w * s->h;
    int rc = cube_reader_seek(s->rd, a->k0);
    for (int k = a->k0; rc == SL_OK; k++) {
        pthread_mutex_lock(&a->mu);
        while (a->count == a->nslot && !a->stop)
            pthread_cond_wait(&a->cv, &a->mu);
        int i = a->head, stop = a->stop;
        pthread_mutex_unlock(&a->mu);
        if (stop || k >= a->k1) {
            rc = SL_EEND;
            break;
        }
        float *f = slot(a, i);
        if ((rc = cube_reader_next(s->rd, f)) != SL_OK)
            break;
        if (s->scale != 1.0)
            for (size_t p = 0; p < npx; p++)
                f[p] = (float)(f[p] * s->scale);
        if (s->pp)
            prep_frame(s->pp, f, NULL);
        pthread_mutex_lock(&a->mu);
        a->head = (i + 1) % a->nslot;
        a->count++;
        pthread_cond_signal(&a->cv);
        pthread_mutex_unlock(&a->mu);
    }
    pthread_mutex_lock(&a->mu);
    a->done = 1;
    a->rc = rc;
    pthread_cond_signal(&a->cv);
    pthread_mutex_unlock(&a->mu);
    return NULL;
}

/* The caller's side: add each frame as it arrives; the first failing
 * add stops the reader.  SL_OK, the add's code, or the reader's. */
static int ahead_consume(ahead *a, add_fn add, void *h, const char *what, sl_err *err)
{
    int k = a->k0, tail = 0;
    for (;; k++) {
        pthread_mutex_lock(&a->mu);
        while (a->count == 0 && !a->done)
            pthread_cond_wait(&a->cv, &a->mu);
        int have = a->count > 0;
        pthread_mutex_unlock(&a->mu);
        if (!have)
            return SL_OK;
        int rc = add ? add(h, slot(a, tail)) : SL_OK;
        pthread_mutex_lock(&a->mu);
        tail = (tail + 1) % a->nslot;
        a->count--;
        a->stop = rc != SL_OK;
        pthread_cond_signal(&a->cv);
        pthread_mutex_unlock(&a->mu);
        if (rc != SL_OK)
            return sl_seterr(err, rc, "frame %d: %s", k, what);
    }
}

/* The stream's ring, grown to the slots this pass wants when it can be;
 * the number of slots to use (0: none to be had). */
static int ring_slots(stream *s, int k0, int k1)
{
    size_t bytes = sizeof(float) * s->w * s->h, fit = AHEAD_BYTES / bytes;
    int want = s->ahead_want > AHEAD_MIN ? s->ahead_want : AHEAD_MIN;
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

int stream_feed_ahead(stream *s, int k0, int k1, add_fn add, void *h, const char *what,
                      sl_err *err, int *ran)
{
    ahead a = {.s = s, .k0 = k0, .k1 = k1, .ring = NULL};
    *ran = 0;
    if (!(a.nslot = ring_slots(s, k0, k1)))
        return SL_OK; /* no memory for a ring: read serially */
    a.ring = s->ring;
    pthread_t th;
    pthread_mutex_init(&a.mu, NULL);
    pthread_cond_init(&a.cv, NULL);
    int rc = SL_OK;
    if (pthread_create(&th, NULL, ahead_run, &a) != 0)
        goto destroy_sync; /* no thread: the caller reads serially instead */
    *ran = 1;
    rc = ahead_consume(&a, add, h, what, err);
    pthread_join(th, NULL);
    if (rc == SL_OK && a.rc != SL_EEND)
        rc = sl_seterr(err, a.rc, "%s", cube_reader_errmsg(s->rd));
destroy_sync:
    pthread_cond_destroy(&a.cv);
    pthread_mutex_destroy(&a.mu);
    return rc;
}
