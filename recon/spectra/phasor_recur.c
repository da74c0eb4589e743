/* phasor_recur.c - phasor_solve's recursion (phasor.h), pipelined.
 *
 * The recursion must visit the targets in rank order, one after another:
 * each needs the phases of lower rank.  But most of its work does not
 * depend on phases: reading a triple's sums, removing the photon bias,
 * the modulus and the weight (phasor_triple: a square root, a division).
 * So the targets are taken in blocks of about PHASOR_BLOCK triples:
 * while this thread runs the recursion over one block's prepared triples
 * (two complex products each), the other threads prepare the next block,
 * and this one joins them when its recursion is done.
 * With one thread the same preparation runs inline.  Either way each
 * triple is prepared and used by the same arithmetic in the same order,
 * so the phases do not depend on the thread count.
 *
 * Memory: two blocks of (PHASOR_BLOCK + the most triples of one target)
 * x 40 bytes, ~2.7 MB.
 */
#include "phasor_int.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>

#define PHASOR_BLOCK 32768

/* A triple ready for the recursion: legs (l1 -1: never used, zero
 * weight), the mean bispectrum, the weight over |B| and |B|. */
typedef struct prepped {
    int32_t l1, l2;
    double br, bi, s, mod;
} prepped;

/* A block's preparation, cut into PREP_PARTS parts of its targets that
 * threads claim one at a time: the workers from the start, the caller
 * once its recursion over the previous block is done, so the two
 * stages balance whatever their costs. */
#define PREP_PARTS 16
typedef struct prep_job {
    const phasor_graph *g;
    int j0, j1;
    prepped *out;
    atomic_int next;        /* the next unclaimed part */
} prep_job;

/* Prepare targets [j0, j1) into out (indexed from tstart[j0]). */
static void prep(const phasor_graph *g, int j0, int j1, prepped *out)
{
    int64_t base = g->tstart[j0];
    for (int j = j0; j < j1; j++)
        for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++) {
            int l1, l2;
            double br, bi, w;
            phasor_triple(g, j, t, &l1, &l2, &br, &bi, &w);
            double mod = sqrt(br * br + bi * bi); /* not hypot: 10x slower */
            out[t - base] = (prepped){w > 0 ? l1 : -1, l2, br, bi,
                                      w > 0 && mod > 0 ? w / mod : 0, mod};
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
        prep(p->g, a, b, p->out + (p->g->tstart[a] - p->g->tstart[p->j0]));
    }
}

/* The recursion over targets [j0, j1), from their prepared triples. */
static void consume(const phasor_graph *g, int j0, int j1, const prepped *buf, double *E,
                    unsigned char *known, double *wsum, double *miss)
{
    int n = g->nfreq;
    int64_t base = g->tstart[j0];
    for (int j = j0; j < j1; j++) {
        if (g->seed[j]) {
            known[j] = 1;
            continue;
        }
        double zr = 0, zi = 0, mr = 0, mi = 0, ms = 0;
        for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++) {
            const prepped *q = &buf[t - base];
            int l1 = q->l1, l2 = q->l2;
            if (l1 < 0 || !known[l1 < n ? l1 : l1 - n] || !known[l2 < n ? l2 : l2 - n])
                continue;
            double e1r = E[2 * l1], e1i = E[2 * l1 + 1];
            double e2r = E[2 * l2], e2i = E[2 * l2 + 1];
            double pr = e1r * e2r - e1i * e2i, pi = e1r * e2i + e1i * e2r;
            double xr = pr * q->br + pi * q->bi, xi = pi * q->br - pr * q->bi;
            zr += q->s * xr;
            zi += q->s * xi;
            mr += xr;
            mi += xi;
            ms += q->mod;
        }
        double m = hypot(zr, zi);
        if (m > 0) {
            phasor_set(E, n, j, zr / m, zi / m);
            known[j] = 1;
            *wsum += ms;
            *miss += ms - (mr * zr + mi * zi) / m;
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
    if (!buf[0] || !buf[1]) {
        free(buf[0]);
        free(buf[1]);
        return SL_ENOMEM;
    }
    double wsum = 0, miss = 0;
    int j0 = 1, j1 = block_end(g, 1), cur = 0;
    prep(g, j0, j1, buf[0]);
    while (j0 < n) {
        int more = j1 < n, j2 = more ? block_end(g, j1) : n;
        prep_job next = {g, j1, j2, buf[1 - cur], 0};
        if (par && more)
            tpool_submit(g->pool, prep_job_run, &next);
        consume(g, j0, j1, buf[cur], E, known, &wsum, &miss);
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
    *misfit = wsum > 0 ? miss / wsum : 0;
    return SL_OK;
}
