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
 * threads.  The chunks stay separate lists (16 bytes a triple, once).
 * The same pass sums each target's own proposals, which give the closure
 * misfit at the phasors it started from: one pass over the lists per
 * round, which both judges the last update and proposes the next.  The
 * planes' sum and the phasors' update run on the threads too, over
 * ranges of frequencies, and a plane is zeroed and summed only up to the
 * highest frequency its block reaches.
 *
 * Memory: the lists are counted first and allocated to size.  Within
 * phasor_graph.refine_bytes every target keeps its strong triples up to a
 * common cap, the largest that fits, and a target over it its strongest
 * (the weak ones, 1 % of its best, add least); without the bound the
 * lists took up to 2x the accumulators (a quarter of the triples at 16
 * bytes, against 8), outside the memory budget.  Counting costs one more
 * pass over the triples (two where one would do).
 */
#include "phasor_int.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#define REFINE_CHUNKS 16

/* One strong triple of the refinement, its target implied by where it
 * is listed: legs and u = w b/|B| (its weight times the unit
 * bispectrum).  16 bytes: a pass streams the lists, so their size is
 * its memory traffic. */
typedef struct strong {
    int32_t l1, l2;
    float ur, ui;
} strong;

/* Shared state of the jobs below. */
typedef struct refine_ctx {
    const phasor_graph *g;
    double inv;                  /* phasor_inv_nframes(g) */
    const unsigned char *known;
    double *wmax;                /* per target: its largest usable weight */
    int32_t *nstrong;            /* per target: its strong triples, then
                                  * how many it lists */
    int32_t most;                /* the most triples of one target */
    float *wbuf;                 /* count_job: most weights per thread */
    int32_t kcap;                /* per target at most this many listed */
    size_t scratch;              /* bytes of the selection's scratch, at most */
    strong *part[REFINE_CHUNKS]; /* strong triples of target block k */
    int64_t npart[REFINE_CHUNKS]; /* -1: out of memory */
    double wsum[REFINE_CHUNKS];  /* block k's sum of listed weights */
    int reach[REFINE_CHUNKS];    /* block k's plane holds frequencies < reach[k] */
    int order[REFINE_CHUNKS];    /* the blocks, longest list first */
    double *E;
    double *Z;                   /* 2 nfreq: the planes' sum */
    const unsigned char *fixed;  /* per target: keeps its phasor (a seed) */
    double *zc;                  /* REFINE_CHUNKS planes of 4 nfreq: both legs */
    double fit[REFINE_CHUNKS];   /* block k's sum Re(conj(E_j) P_j) */
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

/* The weight of triple t of target j when it may take part (legs known,
 * weight and |B| > 0), else 0; *q its record. */
static double usable(const refine_ctx *c, int j, int64_t t, strong *q)
{
    int n = c->g->nfreq, l1, l2;
    double br, bi, w;
    double mod = phasor_triple_mod_inv(c->g, c->inv, j, t, &l1, &l2, &br, &bi, &w);
    if (!c->known[l1 % n] || !c->known[l2 % n] || !(w > 0) || !(mod > 0))
        return 0;
    *q = (strong){l1, l2, (float)(w * br / mod), (float)(w * bi / mod)};
    return w;
}

/* A usable triple of weight w (as listed: in float) is strong when
 * w >= PHASOR_REFINE_REL x its target's largest.  count_job and list_job
 * must agree to the bit: the lists are allocated to count_job's size. */
static int is_strong(float w, double wmax) { return w > 0 && w >= PHASOR_REFINE_REL * wmax; }

/* tpool job: each known target's largest weight and its number of strong
 * triples, those of weight >= PHASOR_REFINE_REL x that largest, so every
 * frequency keeps its best constraints (a threshold on the global largest
 * weight kept only the few triples near the origin, where |B| is larger
 * by orders of magnitude).  The weights wait in the thread's wbuf, so
 * each triple is read once. */
static void count_job(void *ctx, int tid, int nthr)
{
    refine_ctx *c = ctx;
    const phasor_graph *g = c->g;
    float *wb = c->wbuf + (size_t)tid * (size_t)c->most;
    strong q;
    (void)nthr;
    for (int k; (k = atomic_fetch_add(&c->next, 1)) < REFINE_CHUNKS;)
        for (int j = chunk_start(g->nfreq, k); j < chunk_start(g->nfreq, k + 1); j++) {
            double wmax = 0;
            int32_t ns = 0, m = (int32_t)(g->tstart[j + 1] - g->tstart[j]);
            if (j > 0 && c->known[j]) {
                for (int32_t i = 0; i < m; i++) {
                    double w = usable(c, j, g->tstart[j] + i, &q);
                    wb[i] = (float)w;
                    wmax = fmax(wmax, w);
                }
                for (int32_t i = 0; i < m; i++)
                    ns += is_strong(wb[i], wmax);
            }
            c->wmax[j] = wmax, c->nstrong[j] = ns;
        }
}
/* Quickselect with a three-way partition (equal weights are common:
 * every triple of noiseless data weighs the same under SNR weights),
 * O(m) expected where sorting the target's triples took a third of a
 * noisy run. */
float phasor_kth_largest(float *v, int32_t m, int32_t k)
{
    int32_t lo = 0, hi = m, want = k - 1;   /* want: index in descending order */
    for (;;) {
        float x = v[lo], y = v[lo + (hi - lo) / 2], z = v[hi - 1];
        float p = x < y ? (y < z ? y : (x < z ? z : x)) : (x < z ? x : (y < z ? z : y));
        int32_t a = lo, i = lo, b = hi;   /* [lo,a) > p, [a,b) == p, [b,hi) < p */
        while (i < b) {
            float t = v[i];
            if (t > p)
                v[i++] = v[a], v[a++] = t;
            else if (t < p)
                v[i] = v[--b], v[b] = t;
            else
                i++;
        }
        if (want < a)
            hi = a;
        else if (want >= b)
            lo = b;
        else
            return p;
    }
}

/* Target j's strong triples into out, in storage order; with more than
 * kcap, its kcap strongest: by weight, ties to the lower index, so the
 * same ones on any run (scr, w, tmp: room for nstrong[j] when cut).  How many;
 * *wsum gets their weights added. */
static int32_t list_target(const refine_ctx *c, int j, strong *out, strong *scr, float *w,
                           float *tmp, double *wsum)
{
    const phasor_graph *g = c->g;
    strong q;
    int32_t m = 0;
    if (c->nstrong[j] <= c->kcap) {
        for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++) {
            float wt = (float)usable(c, j, t, &q);
            if (is_strong(wt, c->wmax[j]))
                out[m++] = q, *wsum += wt;
        }
        return m;
    }
    for (int64_t t = g->tstart[j]; t < g->tstart[j + 1]; t++) {
        float wt = (float)usable(c, j, t, &q);
        if (is_strong(wt, c->wmax[j]))
            scr[m] = q, w[m++] = wt;
    }
    memcpy(tmp, w, sizeof *tmp * (size_t)m);
    float v = phasor_kth_largest(tmp, m, c->kcap);
    int32_t above = 0, n = 0;
    for (int32_t i = 0; i < m; i++)
        above += w[i] > v;
    for (int32_t i = 0, ties = c->kcap - above; i < m; i++)
        if (w[i] > v || (w[i] == v && ties-- > 0)) {
            out[n++] = scr[i];
            *wsum += w[i];
        }
    return n;
}

/* One past the highest frequency a block's plane gets (its targets end
 * at j1; legs come before their targets in the graph's order, but the
 * bound is taken from the list, not assumed): the plane's zeroing and
 * its share of the sum stop there, half the planes' traffic. */
static int plane_reach(const strong *q, int64_t len, int n, int j1)
{
    int r = j1;
    for (int64_t i = 0; i < len; i++) {
        int a = q[i].l1 < n ? q[i].l1 : q[i].l1 - n, b = q[i].l2 < n ? q[i].l2 : q[i].l2 - n;
        r = a >= r ? a + 1 : r;
        r = b >= r ? b + 1 : r;
    }
    return r;
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
        /* a cut target's strong triples and their weights twice */
        void *scr = most ? malloc((sizeof(strong) + 2 * sizeof(float)) * (size_t)most) : NULL;
        float *w = (float *)((strong *)scr + most);
        c->npart[k] = c->part[k] && (scr || !most) ? 0 : -1;
        c->wsum[k] = 0;
        for (int j = j0; j < j1 && c->npart[k] >= 0; j++) {
            int32_t got = list_target(c, j, c->part[k] + c->npart[k], scr, w, w + most,
                                      &c->wsum[k]);
            c->npart[k] += got;
            c->nstrong[j] = got;
        }
        c->reach[k] = c->npart[k] >= 0 ? plane_reach(c->part[k], c->npart[k], n, j1) : 0;
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
 * scratch included (each thread holds one target's strong triples and
 * their weights); 0 when some block's could not be allocated, or none
 * fits. */
static int strong_triples(refine_ctx *c, size_t list_bytes)
{
    const phasor_graph *g = c->g;
    int nthr = g->pool ? tpool_size(g->pool) : 1;
    for (int j = 0; j < g->nfreq; j++)
        c->most = g->tstart[j + 1] - g->tstart[j] > c->most
                      ? (int32_t)(g->tstart[j + 1] - g->tstart[j]) : c->most;
    if (!(c->wbuf = malloc(sizeof *c->wbuf * (size_t)nthr * (size_t)(c->most ? c->most : 1))))
        return 0;
    run(c, count_job);
    free(c->wbuf), c->wbuf = NULL;
    int32_t most = 0;
    for (int j = 0; j < g->nfreq; j++)
        most = c->nstrong[j] > most ? c->nstrong[j] : most;
    c->scratch = (size_t)nthr * (size_t)most * (sizeof(strong) + 2 * sizeof(float));
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
    /* Longest first: the lists grow with |u| (from 1 % to 7 % of the
     * triples each on a 200^2 cube), and a long one claimed last left the
     * other threads idle at the end of every pass. */
    for (int k = 0; k < REFINE_CHUNKS; k++) {
        int i = k;
        for (; i > 0 && c->npart[c->order[i - 1]] < c->npart[k]; i--)
            c->order[i] = c->order[i - 1];
        c->order[i] = k;
    }
    return 1;
}

/* tpool job: one pass over chunk k's triples at the phasors E.  Each
 * triple proposes w E1 E2 conj(b) for its target (summed in a register,
 * P_j) and E_j conj(E2) w b, E_j conj(E1) w b for its legs, into plane
 * k (4 nfreq: a mirror leg n + l has its own slots, folded when the
 * planes are added).  fit[k] = sum_j Re(conj(E_j) P_j): the closure
 * misfit at E is the listed weights' sum minus it, so the pass that
 * proposes the next phasors also judges these. */
static void pass_job(void *ctx, int tid, int nthr)
{
    refine_ctx *c = ctx;
    int n = c->g->nfreq;
    const double *E = c->E;
    (void)tid, (void)nthr;
    for (int r; (r = atomic_fetch_add(&c->next, 1)) < REFINE_CHUNKS;) {
        int k = c->order[r];
        double *Z = c->zc + (size_t)k * 4 * n, fit = 0;
        memset(Z, 0, sizeof *Z * 2 * (size_t)c->reach[k]);
        memset(Z + 2 * (size_t)n, 0, sizeof *Z * 2 * (size_t)c->reach[k]);
        const strong *q = c->part[k];
        for (int j = chunk_start(n, k); j < chunk_start(n, k + 1); j++) {
            double ejr = E[2 * j], eji = E[2 * j + 1], pr = 0, pi = 0;
            for (const strong *end = q + c->nstrong[j]; q < end; q++) {
                double ur = q->ur, ui = q->ui;
                double e1r = E[2 * q->l1], e1i = E[2 * q->l1 + 1];
                double e2r = E[2 * q->l2], e2i = E[2 * q->l2 + 1];
                double sr = e1r * e2r - e1i * e2i, si = e1r * e2i + e1i * e2r;
                pr += sr * ur + si * ui;
                pi += si * ur - sr * ui;
                double ar = ejr * e2r + eji * e2i, ai = eji * e2r - ejr * e2i;
                double br = ejr * e1r + eji * e1i, bi = eji * e1r - ejr * e1i;
                Z[2 * q->l1] += ar * ur - ai * ui;
                Z[2 * q->l1 + 1] += ar * ui + ai * ur;
                Z[2 * q->l2] += br * ur - bi * ui;
                Z[2 * q->l2 + 1] += br * ui + bi * ur;
            }
            Z[2 * j] += pr;
            Z[2 * j + 1] += pi;
            fit += pr * ejr + pi * eji;
        }
        c->fit[k] = fit;
    }
}

/* tpool job: the planes summed into c->Z over the frequency ranges
 * claimed, each frequency's planes in block order (the same bits on any
 * thread count; a plane past its reach holds zeros and is skipped).
 * Serial, this sum and the update below held one core of two for 0.07 s
 * of a noisy 200^2 run's 0.74 s refinement. */
static void sum_job(void *ctx, int tid, int nthr)
{
    refine_ctx *c = ctx;
    int n = c->g->nfreq;
    (void)tid, (void)nthr;
    for (int r; (r = atomic_fetch_add(&c->next, 1)) < REFINE_CHUNKS;) {
        int i0 = chunk_start(n, r), i1 = chunk_start(n, r + 1);
        double *Z = c->Z;
        memset(Z + 2 * (size_t)i0, 0, sizeof *Z * 2 * (size_t)(i1 - i0));
        for (int k = 0; k < REFINE_CHUNKS; k++) { /* plane by plane: 2 streams */
            const double *P = c->zc + (size_t)k * 4 * n;
            for (int i = i0, e = i1 < c->reach[k] ? i1 : c->reach[k]; i < e; i++) {
                Z[2 * i] += P[2 * i] + P[2 * (n + i)];
                Z[2 * i + 1] += P[2 * i + 1] - P[2 * (n + i) + 1];
            }
        }
    }
}

/* tpool job: each known target not fixed takes its proposals' phasor. */
static void update_job(void *ctx, int tid, int nthr)
{
    refine_ctx *c = ctx;
    int n = c->g->nfreq;
    (void)tid, (void)nthr;
    for (int r; (r = atomic_fetch_add(&c->next, 1)) < REFINE_CHUNKS;)
        for (int j = chunk_start(n, r) > 1 ? chunk_start(n, r) : 1; j < chunk_start(n, r + 1); j++) {
            double m = hypot(c->Z[2 * j], c->Z[2 * j + 1]);
            if (c->known[j] && !c->fixed[j] && m > 0)
                phasor_set(c->E, n, j, c->Z[2 * j] / m, c->Z[2 * j + 1] / m);
        }
}

/* A pass at c->E: the summed proposals into c->Z (2 nfreq), and the
 * closure misfit at E returned. */
static double pass(refine_ctx *c)
{
    run(c, pass_job);
    double m = 0;
    for (int k = 0; k < REFINE_CHUNKS; k++)
        m += c->wsum[k] - c->fit[k];
    run(c, sum_job);
    return m;
}

/* Bytes the refinement needs besides the strong triples' lists. */
static size_t fixed_bytes(int n)
{
    return (size_t)n * (4 * sizeof(double) + 4 * REFINE_CHUNKS * sizeof(double) +
                        sizeof(double) + sizeof(int32_t));
}

void phasor_refine(const phasor_graph *g, int iters, double *E, double *Z,
                   const unsigned char *known)
{
    int n = g->nfreq;
    phasor_graph gr = *g;
    gr.weight = g->refine_weight;
    refine_ctx c = {.g = &gr, .inv = phasor_inv_nframes(&gr), .known = known, .E = E, .Z = Z,
                    .fixed = g->seed};
    size_t fixed = fixed_bytes(n);
    if (g->refine_used)
        *g->refine_used = 0;
    if (g->refine_bytes > 0 && g->refine_bytes <= fixed)
        return;   /* no room for a single list */
    double *keep = malloc(sizeof *keep * 4 * (size_t)n);
    c.zc = malloc(sizeof *c.zc * 4 * (size_t)n * REFINE_CHUNKS);
    c.wmax = malloc(sizeof *c.wmax * (size_t)n);
    c.nstrong = malloc(sizeof *c.nstrong * (size_t)n);
    if (!keep || !c.zc || !c.wmax || !c.nstrong ||
        !strong_triples(&c, g->refine_bytes ? g->refine_bytes - fixed : 0))
        goto free_all;
    if (g->refine_used) {
        size_t listed = 0;
        for (int k = 0; k < REFINE_CHUNKS; k++)
            listed += (size_t)c.npart[k];
        *g->refine_used = fixed + listed * sizeof(strong) + c.scratch;
    }
    double cost = pass(&c);
    for (int it = 0; it < iters; it++) {
        memcpy(keep, E, sizeof *keep * 4 * (size_t)n);
        run(&c, update_job);
        double cm = pass(&c);
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
    free(c.wbuf);
    free(keep);
    free(c.zc);
    free(c.wmax);
    free(c.nstrong);
}
