/* slotpipe.c - see slotpipe.h. */
#include "slotpipe.h"

#include <stdatomic.h>
#include <stdlib.h>

struct slotpipe {
    tpool *pool;
    int gsize, ntake;
    slotpipe_ops ops;
    void *ctx;
    int cur, nstaged;       /* the group filling and its frames */
    int inflight, submitted;
    /* the job: group fg's fn slots to make, group sg's sn to take,
     * claimed from f_next and s_next; pend (pendn slots, 0: none) is
     * made and waits to be taken */
    int fg, fn, sg, sn, pend, pendn;
    atomic_int f_next, s_next;
};

slotpipe *slotpipe_new(tpool *pool, int gsize, int ntake, const slotpipe_ops *ops,
                       void *ctx)
{
    if (!pool || gsize < 1 || ntake < 0 || !ops)
        return NULL;
    slotpipe *q = calloc(1, sizeof *q);
    if (q)
        q->pool = pool, q->gsize = gsize, q->ntake = ntake, q->ops = *ops, q->ctx = ctx;
    return q;
}

/* Joins the job in flight (frames still staged are left). */
static void finish(slotpipe *q);

void slotpipe_free(slotpipe *q)
{
    if (!q)
        return;
    finish(q);
    free(q);
}

int slotpipe_slot(const slotpipe *q) { return q->cur * q->gsize + q->nstaged; }

/* tpool job: the makes claimed, then the takes claimed. */
static void job(void *arg, int tid, int n)
{
    slotpipe *q = arg;
    (void)tid, (void)n;
    for (int k; (k = atomic_fetch_add(&q->f_next, 1)) < q->fn;)
        q->ops.make(q->ctx, q->fg * q->gsize + k);
    for (int t; q->sn && (t = atomic_fetch_add(&q->s_next, 1)) < q->ntake;)
        q->ops.take(q->ctx, t, q->sg * q->gsize, q->sn);
}

/* Join the job: what is left of it on this thread, then its end; the
 * group it made waits to be taken. */
static void finish(slotpipe *q)
{
    if (!q->inflight)
        return;
    job(q, 0, 1);
    if (q->submitted)
        tpool_wait(q->pool);
    if (q->sn)
        q->ops.done(q->ctx, q->sg * q->gsize, q->sn);
    q->pend = q->fg, q->pendn = q->fn;
    q->inflight = q->submitted = 0;
}

/* The next job: the filling group's frames to make, the pending group's
 * to take, started on the workers; the other group fills meanwhile. */
static void submit(slotpipe *q)
{
    finish(q);
    q->fg = q->cur, q->fn = q->nstaged;
    q->sg = q->pend, q->sn = q->pendn;
    q->pendn = 0;
    atomic_store(&q->f_next, 0);
    atomic_store(&q->s_next, 0);
    q->cur ^= 1;
    q->nstaged = 0;
    q->inflight = 1;
    q->submitted = tpool_size(q->pool) > 1;
    if (q->submitted)
        tpool_submit(q->pool, job, q);
}

void slotpipe_filled(slotpipe *q)
{
    if (++q->nstaged == q->gsize)
        submit(q);
}

void slotpipe_drain(slotpipe *q)
{
    while (q->inflight || q->nstaged || q->pendn) {
        if (q->nstaged || q->pendn)
            submit(q);
        finish(q);
    }
}
