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
 * Memory: AHEAD_SLOTS frames.  Threads: one more than the caller's, for
 * the length of the pass; the pipeline uses it only when it was given
 * more than one thread.
 */
#include <pthread.h>
#include <stdlib.h>

#include "pipeline_int.h"

#define AHEAD_SLOTS 4

typedef struct ahead {
    stream *s;
    float *slot[AHEAD_SLOTS];
    int head, count;        /* next slot to fill; slots filled, not added */
    int done, stop, rc;     /* reader finished (rc: SL_EEND at the end) */
    pthread_mutex_t mu;
    pthread_cond_t cv;
} ahead;

/* The reader: frames k0..k1-1 into the ring, in order. */
static void *ahead_run(void *arg)
{
    ahead *a = arg;
    stream *s = a->s;
    size_t npx = (size_t)s->w * s->h;
    int rc = cube_reader_seek(s->rd, s->k0);
    for (int k = s->k0; rc == SL_OK; k++) {
        pthread_mutex_lock(&a->mu);
        while (a->count == AHEAD_SLOTS && !a->stop)
            pthread_cond_wait(&a->cv, &a->mu);
        int i = a->head, stop = a->stop;
        pthread_mutex_unlock(&a->mu);
        if (stop || k >= s->k1) {
            rc = SL_EEND;
            break;
        }
        float *f = a->slot[i];
        if ((rc = cube_reader_next(s->rd, f)) != SL_OK)
            break;
        if (s->scale != 1.0)
            for (size_t p = 0; p < npx; p++)
                f[p] = (float)(f[p] * s->scale);
        if (s->pp)
            prep_frame(s->pp, f, NULL);
        pthread_mutex_lock(&a->mu);
        a->head = (i + 1) % AHEAD_SLOTS;
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
    int k = a->s->k0, tail = 0;
    for (;; k++) {
        pthread_mutex_lock(&a->mu);
        while (a->count == 0 && !a->done)
            pthread_cond_wait(&a->cv, &a->mu);
        int have = a->count > 0;
        pthread_mutex_unlock(&a->mu);
        if (!have)
            return SL_OK;
        int rc = add ? add(h, a->slot[tail]) : SL_OK;
        pthread_mutex_lock(&a->mu);
        tail = (tail + 1) % AHEAD_SLOTS;
        a->count--;
        a->stop = rc != SL_OK;
        pthread_cond_signal(&a->cv);
        pthread_mutex_unlock(&a->mu);
        if (rc != SL_OK)
            return sl_seterr(err, rc, "frame %d: %s", k, what);
    }
}

int stream_feed_ahead(stream *s, add_fn add, void *h, const char *what, sl_err *err,
                      int *ran)
{
    ahead a = {.s = s};
    *ran = 0;
    size_t bytes = sizeof(float) * s->w * s->h;
    int rc = SL_OK, i = 0;
    for (; i < AHEAD_SLOTS; i++)
        if (!(a.slot[i] = malloc(bytes)))
            goto free_slots; /* no memory for the ring: read serially */
    pthread_t th;
    pthread_mutex_init(&a.mu, NULL);
    pthread_cond_init(&a.cv, NULL);
    if (pthread_create(&th, NULL, ahead_run, &a) != 0) {
        rc = SL_OK; /* no thread: the caller reads serially instead */
        goto destroy_sync;
    }
    *ran = 1;
    rc = ahead_consume(&a, add, h, what, err);
    pthread_join(th, NULL);
    if (rc == SL_OK && a.rc != SL_EEND)
        rc = sl_seterr(err, a.rc, "%s", cube_reader_errmsg(s->rd));
destroy_sync:
    pthread_cond_destroy(&a.cv);
    pthread_mutex_destroy(&a.mu);
free_slots:
    while (i-- > 0)
        free(a.slot[i]);
    return rc;
}
