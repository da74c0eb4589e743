/* tpool.c - see tpool.h.
 *
 * One mutex and two condition variables: workers sleep on `go` until the
 * generation counter moves, run the job, and the last one to finish
 * signals `done`.  The caller runs tid 0 itself between the two.
 */
#include "tpool.h"

#include <pthread.h>
#include <sched.h>
#include <stdlib.h>
#include <unistd.h>

enum { TPOOL_MAX = 64 };

typedef struct worker {
    tpool *pool;
    int tid;
} worker;

struct tpool {
    int n, nstarted;
    pthread_mutex_t mu;
    pthread_cond_t go, done;
    unsigned long gen;        /* job number; workers run each one once */
    int pending;              /* workers still on the current job */
    int stop;
    tpool_fn fn;
    void *ctx;
    pthread_t th[TPOOL_MAX];
    worker wk[TPOOL_MAX];
};

int tpool_default_threads(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : n > 4 ? 4 : (int)n;
}

static void *worker_main(void *arg)
{
    worker *w = arg;
    tpool *p = w->pool;
    unsigned long seen = 0;
    pthread_mutex_lock(&p->mu);
    for (;;) {
        while (!p->stop && p->gen == seen)
            pthread_cond_wait(&p->go, &p->mu);
        if (p->stop)
            break;
        seen = p->gen;
        tpool_fn fn = p->fn;
        void *ctx = p->ctx;
        pthread_mutex_unlock(&p->mu);
        fn(ctx, w->tid, p->n);
        pthread_mutex_lock(&p->mu);
        if (--p->pending == 0)
            pthread_cond_signal(&p->done);
    }
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

tpool *tpool_new(int nthreads, sl_err *err)
{
    int n = nthreads ? nthreads : tpool_default_threads();
    if (n < 1 || n > TPOOL_MAX) {
        sl_seterr(err, SL_EINVAL, "tpool_new: %d threads (1..%d)", n, TPOOL_MAX);
        return NULL;
    }
    tpool *p = calloc(1, sizeof *p);
    if (!p) {
        sl_seterr(err, SL_ENOMEM, "tpool_new: out of memory");
        return NULL;
    }
    p->n = n;
    pthread_mutex_init(&p->mu, NULL);
    pthread_cond_init(&p->go, NULL);
    pthread_cond_init(&p->done, NULL);
    for (int i = 1; i < n; i++) {
        p->wk[i].pool = p, p->wk[i].tid = i;
        if (pthread_create(&p->th[i], NULL, worker_main, &p->wk[i]) != 0) {
            sl_seterr(err, SL_ENOMEM, "tpool_new: cannot create thread %d of %d", i, n);
            tpool_free(p);
            return NULL;
        }
        p->nstarted = i;
    }
    return p;
}

void tpool_free(tpool *p)
{
    if (!p)
        return;
    pthread_mutex_lock(&p->mu);
    p->stop = 1;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
    for (int i = 1; i <= p->nstarted; i++)
        pthread_join(p->th[i], NULL);
    pthread_mutex_destroy(&p->mu);
    pthread_cond_destroy(&p->go);
    pthread_cond_destroy(&p->done);
    free(p);
}

int tpool_size(const tpool *p) { return p->n; }

void tpool_submit(tpool *p, tpool_fn fn, void *ctx)
{
    if (p->n == 1)
        return;
    pthread_mutex_lock(&p->mu);
    p->fn = fn, p->ctx = ctx;
    p->pending = p->n - 1;
    p->gen++;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
}

void tpool_wait(tpool *p)
{
    if (p->n == 1)
        return;
    pthread_mutex_lock(&p->mu);
    while (p->pending > 0)
        pthread_cond_wait(&p->done, &p->mu);
    pthread_mutex_unlock(&p->mu);
}

void tpool_run(tpool *p, tpool_fn fn, void *ctx)
{
    tpool_submit(p, fn, ctx);
    fn(ctx, 0, p->n);
    tpool_wait(p);
}

void tpool_pause(int *spins)
{
    if (++*spins > 64)
        sched_yield();
}
