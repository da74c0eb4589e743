/* phasor_recur.c - phasor_solve's recursion (phasor.h), pipelined.
 *
 * The recursion must visit the targets in rank order, one after another:
 * each needs the phases of lower rank.  But most of its work need not
 * wait for the target before it.  The targets are cut into blocks of
 * about PHASOR_BLOCK triples (a cut fixed by the graph alone).  While
 * this thread runs the recursion over block b, the other threads take
 * block b + 1 in parts: they read each triple's sums, remove the photon
 * bias, take the modulus and the weight (phasor_triple: a square root, a
 * division), and when both legs lie before block b, whose phases are
 * final by then, they also sum the triple's proposal into the target's
 * "early" sums.  Only the rest, triples with a leg in block b or b + 1
 * (a few per cent: legs in the same arc of the same ring), is left for
 * the recursion proper, which starts each target from its early sums.
 * With one thread the same steps run inline.  Either way every target's
 * sum is its early triples in storage order, then its late ones, by the
 * same arithmetic, so the phases do not depend on the thread count.
 *
 * The threads meet once for the whole recursion, not once a block: a
 * block's preparation is ~0.1 ms a thread, and meeting per block (a
 * wake-up, then a wait for the slower thread) held the recursion at 1.34x
 * on two threads at 512^2 (0.26 -> 0.19 s; now 0.14-0.15 s).  The parts
 * are tickets, taken in order by every thread; a
 * ticket of block p waits (spinning, then yielding) until the recursion
 * has passed block p - 2, whose phases its cut needs and whose buffer it
 * reuses; the recursion waits for block p's parts, taking tickets of
 * blocks p and p + 1 itself meanwhile.
 *
 * Memory: two blocks of (PHASOR_BLOCK + the most triples of one target)
 * x 40 bytes, ~2.7 MB, and 52 bytes per target (the blocks' bounds and counts
 * sized for the most blocks there can be, one a target).
 */
#include "phasor_int.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>

#define PHASOR_BLOCK 32768

/* A triple left for the recursion: legs, the mean bispectrum, the
 * weight over |B| and |B|. */
typedef struct prepped {
    int32_t l1, l2;
    double br, bi, s, mod;
} prepped;

/* A target's sums over its early triples (consume's z, m and |B| sums),
 * and how many late ones its slots in the block's buffer hold. */
typedef struct early {
    double zr, zi, mr, mi, ms;
    int32_t nlate;
} early;

/* What the recursion reads and the preparation may read early: phasors
 * and known flags of the targets before cut are final. */
typedef struct recur_state {
    double *E;
    unsigned char *known;
    early *ea;              /* per target */
} recur_state;

/* Each block's preparation is cut into PREP_PARTS parts of its targets,
 * the tickets the threads take. */
#define PREP_PARTS 16

/* Add one triple's proposal, from legs l1, l2 with phasors in E, to the
 * sums *e: two complex products. */
static inline void propose(const double *E, int l1, int l2, const prepped *q, early *e)
{
    double e1r = E[2 * l1], e1i = E[2 * l1 + 1];
    double e2r = E[2 * l2], e2i = E[2 * l2 + 1];
    double pr = e1r * e2r - e1i * e2i, pi = e1r * e2i + e1i * e2r;
    double xr = pr * q->br + pi * q->bi, xi = pi * q->br - pr * q->bi;
    e->zr += q->s * xr;
    e->zi += q->s * xi;
    e->mr += xr;
    e->mi += xi;
    e->ms += q->mod;
}

/* Prepare targets [j0, j1): early triples (both legs before cut) summed
 * into rs->ea, late ones into target j's slots of out (indexed from
 * tstart[j0]).  A triple of zero weight is never used.  Kept out of line:
 * inlined into prep_ticket, GCC 12's triple loop ran 30 % slower (0.100
 * -> 0.130 s at 200^2 on one thread). */
__attribute__((noinline)) static void prep(const phasor_graph *g, const recur_state *rs, int j0, int j1, int cut,
                 prepped *out)
{
    int n = g->nfreq;
    int64_t base = g->tstart[j0];
    double inv = phasor_inv_nframes(g);
    for (int j = j0; j < j1; j++) {
        early e = {0, 0, 0, 0, 0, 0};
        prepped *late = out + (g->tstart[j] - base);
        for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++) {
            int l1, l2;
            double br, bi, w;
            double mod = phasor_triple_mod_inv(g, inv, j, t, &l1, &l2, &br, &bi, &w);
            if (!(w > 0))
                continue;
            /* |B| weights: w / mod is 1 (exactly), without the division */
            double s = !(mod > 0) ? 0 : g->weight == PHASOR_WEIGHT_MOD ? 1.0 : w / mod;
            prepped q = {l1, l2, br, bi, s, mod};
            int a1 = l1 < n ? l1 : l1 - n, a2 = l2 < n ? l2 : l2 - n;
            if (a1 >= cut || a2 >= cut)
                late[e.nlate++] = q;
            else if (rs->known[a1] && rs->known[a2])
                propose(rs->E, l1, l2, &q, &e);
        }
        rs->ea[j] = e;
    }
}

/* The recursion over targets [j0, j1): each from its early sums, then
 * its late triples. */
static void consume(const phasor_graph *g, const recur_state *rs, int j0, int j1,
                    const prepped *buf, double *wsum, double *miss)
{
    int n = g->nfreq;
    int64_t base = g->tstart[j0];
    double *E = rs->E;
    unsigned char *known = rs->known;
    for (int j = j0; j < j1; j++) {
        if (g->seed[j]) {
            known[j] = 1;
            continue;
        }
        early e = rs->ea[j];
        const prepped *late = buf + (g->tstart[j] - base);
        for (int k = 0; k < e.nlate; k++) {
            const prepped *q = &late[k];
            int l1 = q->l1, l2 = q->l2;
            if (known[l1 < n ? l1 : l1 - n] && known[l2 < n ? l2 : l2 - n])
                propose(E, l1, l2, q, &e);
        }
        double m = hypot(e.zr, e.zi);
        if (m > 0) {
            phasor_set(E, n, j, e.zr / m, e.zi / m);
            known[j] = 1;
            *wsum += e.ms;
            *miss += e.ms - (e.mr * e.zr + e.mi * e.zi) / m;
        }
    }
}

/* First target after j0 whose block would pass PHASOR_BLOCK triples. */
static int block_end(const phasor_graph *g, int j0)
{
    int j = j0;
    while (j < g->nfreq && (j == j0 || g->tstart[j + 1] - g->tstart[j0] <= PHASOR_BLOCK))
        j++;
    return j;
}

/* The recursion's shared state: block p holds targets [bs[p], bs[p + 1]);
 * its cut, the first target whose phase it may not read, is bs[p - 1]
 * (bs[0] for p = 0); it is prepared into buf[p % 2]. */
typedef struct recur_job {
    const phasor_graph *g;
    recur_state rs;
    int nb, *bs;
    prepped *buf[2];
    atomic_int ticket;      /* the next part to take: block ticket / PREP_PARTS */
    atomic_int consumed;    /* blocks the recursion has passed */
    atomic_int *done;       /* per block: its parts prepared */
} recur_job;

/* Prepare part t % PREP_PARTS of block t / PREP_PARTS, once the
 * recursion has passed the block two before it. */
static void prep_ticket(recur_job *r, int t)
{
    int p = t / PREP_PARTS, k = t % PREP_PARTS, spins = 0;
    while (atomic_load_explicit(&r->consumed, memory_order_acquire) < p - 1)
        tpool_pause(&spins);
    int j0 = r->bs[p], cut = r->bs[p > 0 ? p - 1 : 0];
    int64_t span = r->bs[p + 1] - j0;
    int a = j0 + (int)(span * k / PREP_PARTS), b = j0 + (int)(span * (k + 1) / PREP_PARTS);
    prep(r->g, &r->rs, a, b, cut, r->buf[p % 2] + (r->g->tstart[a] - r->g->tstart[j0]));
    atomic_fetch_add_explicit(&r->done[p], 1, memory_order_release);
}

/* tpool job (the workers): every ticket left, in order. */
static void ticket_run(void *ctx, int tid, int n)
{
    recur_job *r = ctx;
    (void)tid, (void)n;
    for (int t; (t = atomic_fetch_add(&r->ticket, 1)) < r->nb * PREP_PARTS;)
        prep_ticket(r, t);
}

/* The caller: the recursion block by block; while a block's parts are
 * still out, it takes tickets of that block and the next itself. */
static void recur_run(recur_job *r, double *wsum, double *miss)
{
    for (int p = 0; p < r->nb; p++) {
        int spins = 0;
        while (atomic_load_explicit(&r->done[p], memory_order_acquire) < PREP_PARTS) {
            int t = atomic_load(&r->ticket);
            if (t < r->nb * PREP_PARTS && t / PREP_PARTS <= p + 1) {
                if (atomic_compare_exchange_weak(&r->ticket, &t, t + 1))
                    prep_ticket(r, t);
            } else {
                tpool_pause(&spins);
            }
        }
        consume(r->g, &r->rs, r->bs[p], r->bs[p + 1], r->buf[p % 2], wsum, miss);
        atomic_store_explicit(&r->consumed, p + 1, memory_order_release);
    }
}

int phasor_recur(const phasor_graph *g, double *E, unsigned char *known, double *misfit)
{
    int n = g->nfreq, nb = 0, par = g->pool && tpool_size(g->pool) > 1;
    int64_t most = 0;
    for (int j = 0; j < n; j++)
        most = g->tstart[j + 1] - g->tstart[j] > most ? g->tstart[j + 1] - g->tstart[j] : most;
    size_t cap = (size_t)PHASOR_BLOCK + (size_t)most;
    recur_job r = {.g = g, .rs = {E, known, malloc((size_t)n * sizeof(early))},
                   .bs = malloc((size_t)(n > 1 ? n : 2) * sizeof(int)), /* nb + 1 <= n */
                   .buf = {malloc(cap * sizeof(prepped)), malloc(cap * sizeof(prepped))},
                   .done = calloc((size_t)(n > 1 ? n : 1), sizeof(atomic_int))};
    double wsum = 0, miss = 0;
    int rc = SL_ENOMEM;
    if (!r.rs.ea || !r.bs || !r.buf[0] || !r.buf[1] || !r.done)
        goto free_all;
    for (int j = 1; j < n; j = block_end(g, j))
        r.bs[nb++] = j;
    r.bs[nb] = n > 1 ? n : 1;
    r.nb = nb;
    atomic_init(&r.ticket, 0);
    atomic_init(&r.consumed, 0);
    if (par)
        tpool_submit(g->pool, ticket_run, &r);
    recur_run(&r, &wsum, &miss);
    if (par)
        tpool_wait(g->pool);
    *misfit = wsum > 0 ? miss / wsum : 0;
    rc = SL_OK;
free_all:
    free(r.buf[0]);
    free(r.buf[1]);
    free(r.rs.ea);
    free(r.bs);
    free(r.done);
    return rc;
}
