/* phasor_refine.c - phasor_solve's least-squares refinement (phasor.h)
 * on the graph's threads.
 *
 * Least squares, Jacobi on phasors: from E(u_j) ~ E1 E2 conj(b) follow
 * E1 ~ E(u_j) conj(E2) b and E2 ~ E(u_j) conj(E1) b (b = B/|B|); each
 * frequency takes the phasor of its proposals' sum.  Undamped it
 * converged 2.5x faster than with the current phasor added (c 0.954 after
 * 20 passes against 0.932 on a piston-phase six-star); the misfit is
 * watched and a pass that raises it is undone, which ends the refinement,
 * as does one that lowers it by less than 1e-3 of itself.  Only the
 * strong triples (PHASOR_REFINE_REL) take part: at 0.01 about a quarter
 * of them, and with them the piston-phase six-star reaches c 0.952 in 30
 * passes where 0.1 (6 %) left it at 0.850.
 *
 * Threads: a pass scatters every strong triple's three proposals, so
 * the strong triples are listed in REFINE_CHUNKS fixed chunks (blocks of
 * targets), each summed whole into its own proposal plane, and the
 * planes are added in chunk order: the same bits on any number of
 * threads.  The chunks stay separate lists (24 bytes a triple, once).
 *
 * Memory: the lists are counted first and allocated to size.  Within
 * phasor_graph.refine_bytes every target keeps its strong triples up to a
 * common cap, the largest that fits, and a target over it its strongest
 * (the weak ones, 1 % of its best, add least); without the bound the
 * lists took up to 3x the accumulators (a quarter of the triples at 24
 * bytes, against 8), outside the memory budget.  Counting costs one more
 * pass over the triples (three where two were).
 */
#include "phasor_int.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#define REFINE_CHUNKS 16

/* One strong triple of the refinement: target, legs, unit bispectrum
 * and weight. */
typedef struct strong {
    int32_t j, l1, l2;
    float br, bi, w;
} strong;

/* Proposal for E(u_j) from one triple: w * E1 E2 conj(b). */
static void propose(const double *E, const strong *q, double *zr, double *zi)
{
    double e1r = E[2 * q->l1], e1i = E[2 * q->l1 + 1];
    double e2r = E[2 * q->l2], e2i = E[2 * q->l2 + 1];
    double pr = e1r * e2r - e1i * e2i, pi = e1r * e2i + e1i * e2r;
    *zr = q->w * (pr * q->br + pi * q->bi);
    *zi = q->w * (pi * q->br - pr * q->bi);
}

/* Add a proposal for leg l (conjugated onto its half-plane frequency). */
static void add_leg(double *Z, int n, int l, double zr, double zi)
{
    if (l >= n) {
        l -= n;
        zi = -zi;
    }
    Z[2 * l] += zr;
    Z[2 * l + 1] += zi;
}

/* Shared state of the jobs below. */
typedef struct refine_ctx {
    const phasor_graph *g;
    const unsigned char *known;
    double *wmax;                /* per target: its largest usable weight */
    int32_t *nstrong;            /* per target: its strong triples */
    int32_t kcap;                /* per target at most this many listed */
    size_t scratch;              /* bytes of the selection's scratch, at most */
    strong *part[REFINE_CHUNKS]; /* strong triples of target block k */
    int64_t npart[REFINE_CHUNKS]; /* -1: out of memory */
    const double *E;
    double *zc;                  /* REFINE_CHUNKS planes of 2 nfreq */
    double cost[REFINE_CHUNKS];
    atomic_int next;             /* the next chunk to claim (run() resets) */
} refine_ctx;

/* job on the pool, its chunks claimed by whichever thread is free (each
 * chunk is computed whole by one thread: the same bits on any count; the
 * chunks' triple counts grow with |u|, so round robin did not balance). */
static void run(refine_ctx *c, tpool_fn job)
{
    atomic_store(&c->next, 0);
    tpool_run_or_inline(c->g->pool, job, c);
}

static int chunk_start(int n, int k) { return (int)((int64_t)n * k / REFINE_CHUNKS); }

/* Triple t of target j as a strong one, or 0 when it is not: legs known,
 * weight and |B| > 0, weight >= PHASOR_REFINE_REL x wmax (wmax 0: any);
 * *w its weight. */
static int strong_at(const refine_ctx *c, int j, int64_t t, double wmax, strong *q, double *w)
{
    int n = c->g->nfreq, l1, l2;
    double br, bi;
    phasor_triple(c->g, j, t, &l1, &l2, &br, &bi, w);
    double mod = sqrt(br * br + bi * bi);
    if (!c->known[l1 % n] || !c->known[l2 % n] || !(*w > 0) || !(mod > 0) ||
        *w < PHASOR_REFINE_REL * wmax)
        return 0;
    *q = (strong){j, l1, l2, (float)(br / mod), (float)(bi / mod), (float)*w};
    return 1;
}

/* tpool job: each known target's largest weight and its number of strong
 * triples, those of weight >= PHASOR_REFINE_REL x that largest, so every
 * frequency keeps its best constraints (a threshold on the global largest
 * weight kept only the few triples near the origin, where |B| is larger
 * by orders of magnitude). */
static void count_job(void *ctx, int tid, int nthr)
{
    refine_ctx *c = ctx;
    const phasor_graph *g = c->g;
    strong q;
    double w;
    (void)tid, (void)nthr;
    for (int k; (k = atomic_fetch_add(&c->next, 1)) < REFINE_CHUNKS;)
        for (int j = chunk_start(g->nfreq, k); j < chunk_start(g->nfreq, k + 1); j++) {
            double wmax = 0;
            int32_t ns = 0;
            if (j > 0 && c->known[j]) {
                for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++)
                    if (strong_at(c, j, t, 0, &q, &w))
                        wmax = fmax(wmax, w);
                for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++)
                    ns += strong_at(c, j, t, wmax, &q, &w);
            }
            c->wmax[j] = wmax, c->nstrong[j] = ns;
        }
}

/* In the selection's scratch a triple's j holds its index among its
 * target's triples.  Weight descending, then that index: a total order,
 * so the kcap strongest are the same on any run. */
static int cmp_strength(const void *x, const void *y)
{
    const strong *a = x, *b = y;
    if (a->w != b->w)
        return a->w < b->w ? 1 : -1;
    return (a->j > b->j) - (a->j < b->j);
}

static int cmp_index(const void *x, const void *y)
{
    const strong *a = x, *b = y;
    return (a->j > b->j) - (a->j < b->j);
}

/* Target j's strong triples into out, in storage order; with more than
 * kcap, its kcap strongest (scr: room for nstrong[j]).  How many. */
static int32_t list_target(const refine_ctx *c, int j, strong *out, strong *scr)
{
    const phasor_graph *g = c->g;
    strong q;
    double w;
    int32_t m = 0;
    if (c->nstrong[j] <= c->kcap) {
        for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++)
            if (strong_at(c, j, t, c->wmax[j], &q, &w))
                out[m++] = q;
        return m;
    }
    for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++)
        if (strong_at(c, j, t, c->wmax[j], &q, &w)) {
            scr[m] = q;
            scr[m++].j = (int32_t)(t - g->tstart[j]);
        }
    qsort(scr, (size_t)m, sizeof *scr, cmp_strength);
    qsort(scr, (size_t)c->kcap, sizeof *scr, cmp_index);
    for (int32_t i = 0; i < c->kcap; i++)
        out[i] = scr[i], out[i].j = j;
    return c->kcap;
}

/* tpool job: chunk k's list, allocated to its exact size. */
static void list_job(void *ctx, int tid, int nthr)
{
    refine_ctx *c = ctx;
    int n = c->g->nfreq;
    (void)tid, (void)nthr;
    for (int k; (k = atomic_fetch_add(&c->next, 1)) < REFINE_CHUNKS;) {
        int j0 = chunk_start(n, k), j1 = chunk_start(n, k + 1);
        int64_t len = 0, most = 0;
        for (int j = j0; j < j1; j++) {
            len += c->nstrong[j] < c->kcap ? c->nstrong[j] : c->kcap;
            most = c->nstrong[j] > c->kcap && c->nstrong[j] > most ? c->nstrong[j] : most;
        }
        c->part[k] = malloc(sizeof(strong) * (size_t)(len ? len : 1));
        strong *scr = most ? malloc(sizeof(strong) * (size_t)most) : NULL;
        c->npart[k] = c->part[k] && (scr || !most) ? 0 : -1;
        for (int j = j0; j < j1 && c->npart[k] >= 0; j++)
            c->npart[k] += list_target(c, j, c->part[k] + c->npart[k], scr);
        free(scr);
    }
}

/* The most triples a target may list so that all of them take at most
 * bytes (0: no bound): every target keeps its strong triples up to a
 * common cap, the largest that fits. */
static int32_t strong_cap(const refine_ctx *c, size_t bytes)
{
    int n = c->g->nfreq;
    int32_t hi = 0;
    int64_t total = 0;
    for (int j = 0; j < n; j++)
        total += c->nstrong[j], hi = c->nstrong[j] > hi ? c->nstrong[j] : hi;
    int64_t room = (int64_t)(bytes / sizeof(strong));
    if (bytes == 0 || total <= room)
        return hi;
    int32_t lo = 0;   /* fits; hi: does not */
    while (hi - lo > 1) {
        int32_t mid = lo + (hi - lo) / 2;
        int64_t sum = 0;
        for (int j = 0; j < n; j++)
            sum += c->nstrong[j] < mid ? c->nstrong[j] : mid;
        if (sum <= room)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

/* Every block's list within list_bytes (0: no bound), the selection's
 * scratch included (each thread one target's strong triples); 0 when some
 * block's could not be allocated, or none fits. */
static int strong_triples(refine_ctx *c, size_t list_bytes)
{
    run(c, count_job);
    int32_t most = 0;
    for (int j = 0; j < c->g->nfreq; j++)
        most = c->nstrong[j] > most ? c->nstrong[j] : most;
    int nthr = c->g->pool ? tpool_size(c->g->pool) : 1;
    c->scratch = (size_t)nthr * (size_t)most * sizeof(strong);
    if (list_bytes > 0 && list_bytes <= c->scratch)
        return 0;
    if ((c->kcap = strong_cap(c, list_bytes ? list_bytes - c->scratch : 0)) < 1)
        return 0;
    if (c->kcap == most)
        c->scratch = 0;   /* no target is cut: no selection */
    run(c, list_job);
    for (int k = 0; k < REFINE_CHUNKS; k++)
        if (c->npart[k] < 0)
            return 0;
    return 1;
}

/* tpool job: chunk k's proposals into plane k. */
static void scatter_job(void *ctx, int tid, int nthr)
{
    refine_ctx *c = ctx;
    int n = c->g->nfreq;
    (void)tid, (void)nthr;
    for (int k; (k = atomic_fetch_add(&c->next, 1)) < REFINE_CHUNKS;) {
        double *Z = c->zc + (size_t)k * 2 * n;
        memset(Z, 0, sizeof *Z * 2 * (size_t)n);
        for (int64_t t = 0; t < c->npart[k]; t++) {
            const strong *q = &c->part[k][t];
            double pr, pi, ur = q->w * q->br, ui = q->w * q->bi;
            double ejr = c->E[2 * q->j], eji = c->E[2 * q->j + 1];
            propose(c->E, q, &pr, &pi);
            Z[2 * q->j] += pr;
            Z[2 * q->j + 1] += pi;
            for (int side = 0; side < 2; side++) {
                int lo_leg = side ? q->l1 : q->l2, lt = side ? q->l2 : q->l1;
                double cr = c->E[2 * lo_leg], ci = -c->E[2 * lo_leg + 1];
                double xr = ejr * cr - eji * ci, xi = ejr * ci + eji * cr;
                add_leg(Z, n, lt, xr * ur - xi * ui, xr * ui + xi * ur);
            }
        }
    }
}

/* tpool job: chunk k's weighted closure misfit, sum w (1 - Re(E_j
 * conj(E1 E2 conj b))). */
static void misfit_job(void *ctx, int tid, int nthr)
{
    refine_ctx *c = ctx;
    (void)tid, (void)nthr;
    for (int k; (k = atomic_fetch_add(&c->next, 1)) < REFINE_CHUNKS;) {
        double m = 0;
        for (int64_t t = 0; t < c->npart[k]; t++) {
            const strong *q = &c->part[k][t];
            double pr, pi;
            propose(c->E, q, &pr, &pi);
            m += q->w - (pr * c->E[2 * q->j] + pi * c->E[2 * q->j + 1]);
        }
        c->cost[k] = m;
    }
}

static double misfit(refine_ctx *c)
{
    run(c, misfit_job);
    double m = 0;
    for (int k = 0; k < REFINE_CHUNKS; k++)
        m += c->cost[k];
    return m;
}

/* Bytes the refinement needs besides the strong triples' lists. */
static size_t fixed_bytes(int n)
{
    return (size_t)n * (4 * sizeof(double) + 2 * REFINE_CHUNKS * sizeof(double) +
                        sizeof(double) + sizeof(int32_t));
}

void phasor_refine(const phasor_graph *g, int iters, double *E, double *Z,
                   const unsigned char *known)
{
    int n = g->nfreq;
    phasor_graph gr = *g;
    gr.weight = g->refine_weight;
    refine_ctx c = {.g = &gr, .known = known, .E = E};
    size_t fixed = fixed_bytes(n);
    if (g->refine_used)
        *g->refine_used = 0;
    if (g->refine_bytes > 0 && g->refine_bytes <= fixed)
        return;   /* no room for a single list */
    double *keep = malloc(sizeof *keep * 4 * (size_t)n);
    c.zc = malloc(sizeof *c.zc * 2 * (size_t)n * REFINE_CHUNKS);
    c.wmax = malloc(sizeof *c.wmax * (size_t)n);
    c.nstrong = malloc(sizeof *c.nstrong * (size_t)n);
    if (!keep || !c.zc || !c.wmax || !c.nstrong ||
        !strong_triples(&c, g->refine_bytes ? g->refine_bytes - fixed : 0))
        goto free_all;
    free(c.wmax), c.wmax = NULL;
    free(c.nstrong), c.nstrong = NULL;
    if (g->refine_used) {
        size_t listed = 0;
        for (int k = 0; k < REFINE_CHUNKS; k++)
            listed += (size_t)c.npart[k];
        *g->refine_used = fixed + listed * sizeof(strong) + c.scratch;
    }
    double cost = misfit(&c);
    for (int it = 0; it < iters; it++) {
        memcpy(keep, E, sizeof *keep * 4 * (size_t)n);
        run(&c, scatter_job);
        for (size_t i = 0; i < 2 * (size_t)n; i++) {
            double z = 0;
            for (int k = 0; k < REFINE_CHUNKS; k++)
                z += c.zc[(size_t)k * 2 * n + i];
            Z[i] = z;
        }
        for (int j = 1; j < n; j++) {
            double m = hypot(Z[2 * j], Z[2 * j + 1]);
            if (known[j] && !g->seed[j] && m > 0)
                phasor_set(E, n, j, Z[2 * j] / m, Z[2 * j + 1] / m);
        }
        double cm = misfit(&c);
        if (!(cm < cost)) {
            memcpy(E, keep, sizeof *keep * 4 * (size_t)n);
            break;
        }
        int small = cost - cm < 1e-3 * cost;
        cost = cm;
        if (small)
            break;
    }
free_all:
    for (int k = 0; k < REFINE_CHUNKS; k++)
        free(c.part[k]);
    free(keep);
    free(c.zc);
    free(c.wmax);
    free(c.nstrong);
}
