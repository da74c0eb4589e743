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
 * This thread joins the others once its block is done.
 * With one thread the same steps run inline.  Either way every target's
 * sum is its early triples in storage order, then its late ones, by the
 * same arithmetic, so the phases do not depend on the thread count.
 *
 * Memory: two blocks of (PHASOR_BLOCK + the most triples of one target)
 * x 40 bytes, ~2.7 MB, and 44 bytes per target.
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

/* A block's preparation, cut into PREP_PARTS parts of its targets that
 * threads claim one at a time: the workers from the start, the caller
 * once its recursion over the previous block is done, so the two
 * stages balance whatever their costs. */
#define PREP_PARTS 16
typedef struct prep_job {
    const phasor_graph *g;
    const recur_state *rs;
    int j0, j1, cut;        /* targets [j0, j1); legs before cut are final */
    prepped *out;
    atomic_int next;        /* the next unclaimed part */
} prep_job;

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
 * tstart[j0]).  A triple of zero weight is never used. */
static void prep(const phasor_graph *g, const recur_state *rs, int j0, int j1, int cut,
                 prepped *out)
{
    int n = g->nfreq;
    int64_t base = g->tstart[j0];
    for (int j = j0; j < j1; j++) {
        early e = {0, 0, 0, 0, 0, 0};
        prepped *late = out + (g->tstart[j] - base);
        for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++) {
            int l1, l2;
            double br, bi, w;
            double mod = phasor_triple_mod(g, j, t, &l1, &l2, &br, &bi, &w);
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

/* tpool job (and the caller's share): claim and prepare parts until none
 * is left. */
static void prep_job_run(void *ctx, int tid, int n)
{
    prep_job *p = ctx;
    (void)tid, (void)n;
    int64_t span = p->j1 - p->j0;
    for (int k; (k = atomic_fetch_add(&p->next, 1)) < PREP_PARTS;) {
        int a = p->j0 + (int)(span * k / PREP_PARTS), b = p->j0 + (int)(span * (k + 1) / PREP_PARTS);
        prep(p->g, p->rs, a, b, p->cut, p->out + (p->g->tstart[a] - p->g->tstart[p->j0]));
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

int phasor_recur(const phasor_graph *g, double *E, unsigned char *known, double *misfit)
{
    int n = g->nfreq, par = g->pool && tpool_size(g->pool) > 1;
    int64_t most = 0;
    for (int j = 0; j < n; j++)
        most = g->tstart[j + 1] - g->tstart[j] > most ? g->tstart[j + 1] - g->tstart[j] : most;
    size_t cap = (size_t)PHASOR_BLOCK + (size_t)most;
    prepped *buf[2] = {malloc(cap * sizeof(prepped)), malloc(cap * sizeof(prepped))};
    recur_state rs = {E, known, malloc((size_t)n * sizeof(early))};
    if (!buf[0] || !buf[1] || !rs.ea) {
        free(buf[0]);
        free(buf[1]);
        free(rs.ea);
        return SL_ENOMEM;
    }
    double wsum = 0, miss = 0;
    int j0 = 1, j1 = block_end(g, 1), cur = 0;
    prep(g, &rs, j0, j1, 1, buf[0]);
    while (j0 < n) {
        int more = j1 < n, j2 = more ? block_end(g, j1) : n;
        /* block j1..j2 runs beside the recursion over j0..j1: its legs
         * before j0 are final */
        prep_job next = {g, &rs, j1, j2, j0, buf[1 - cur], 0};
        if (par && more)
            tpool_submit(g->pool, prep_job_run, &next);
        consume(g, &rs, j0, j1, buf[cur], &wsum, &miss);
        if (more) {
            prep_job_run(&next, 0, 1); /* the caller's share: what is left */
            if (par)
                tpool_wait(g->pool);
        }
        j0 = j1;
        j1 = j2;
        cur = 1 - cur;
    }
    free(buf[0]);
    free(buf[1]);
    free(rs.ea);
    *misfit = wsum > 0 ? miss / wsum : 0;
    return SL_OK;
}
