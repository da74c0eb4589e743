/* bispec_graph.c - the triple graph of bispec.h: the support's
 * frequencies in visiting rank, the lookup table, the u2 disk, the stored
 * triples per target and the kernel's target order.
 *
 * Layout.  The F half-plane support frequencies are sorted by visiting
 * rank; legs 0..F-1 are +u_j, legs F..2F-1 are -u_j.  A dense lookup
 * table over |p| <= w/2 + R2, |q| <= h/2 + R2 maps a frequency to its leg
 * (-1 outside S), so u1 = u - u2 is lut[ubase[j] - doff[k]] with no
 * bounds test.  A triple stores only k, the u2 disk entry (uint16).
 *
 * Cost.  Listing the triples tests every (target, disk entry) pair, F nd
 * of them (3.8e7 at 200^2, R2 = 28), once: it runs on the handle's
 * threads, each block of targets into its own list (a transient copy of
 * the list, 2 bytes per triple).  Only which targets are reachable depends on
 * the visiting order; that is settled first, serially, stopping at each
 * target's first usable triple (a few tests each).
 */
#include "bispec_int.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

typedef struct hfreq {
    int p, q, r2;
} hfreq;

/* hypot(p, q) > rc, calling hypot only near the circle: integer r2 far
 * from rc^2 cannot round across it (the same answers; hypot on every
 * frequency was ~3 ms of serial planning at 512^2). */
static int beyond(int p, int q, double rc)
{
    double r2 = (double)p * p + (double)q * q;
    if (r2 < (rc - 1) * (rc - 1) && rc > 1)
        return 0;
    if (r2 > (rc + 1) * (rc + 1))
        return 1;
    return hypot(p, q) > rc;
}

/* The frequencies in rank order, by |u|^2, then q, then p: a counting
 * sort on r2 keeps the input's (q, p) order within equal r2 (the keys
 * are distinct, so it is the order qsort gave; qsort of ~1e5 entries was
 * ~10 ms of serial planning at 512^2).  SL_ENOMEM. */
static int sort_by_radius(hfreq **hf, int nf)
{
    int rmax = 0;
    for (int i = 0; i < nf; i++)
        rmax = (*hf)[i].r2 > rmax ? (*hf)[i].r2 : rmax;
    int *cnt = calloc((size_t)rmax + 2, sizeof *cnt);
    hfreq *out = malloc((size_t)(nf ? nf : 1) * sizeof *out);
    if (!cnt || !out) {
        free(cnt), free(out);
        return SL_ENOMEM;
    }
    for (int i = 0; i < nf; i++)
        cnt[(*hf)[i].r2 + 1]++;
    for (int r = 0; r <= rmax; r++)
        cnt[r + 1] += cnt[r];
    for (int i = 0; i < nf; i++)
        out[cnt[(*hf)[i].r2]++] = (*hf)[i];
    free(cnt);
    free(*hf);
    *hf = out;
    return SL_OK;
}

/* The u2 disk: offsets with 0 < |u2| <= R2 that are in S, by row, and
 * each row's first entry at or past each dp (dfirst). */
static int build_disk(bispec *b)
{
    int r2 = b->o.r2_px;
    /* room for the whole (2 R2 + 1)^2 box: at most 0.5 MB, and one pass */
    size_t box = (size_t)(2 * r2 + 1) * (2 * r2 + 1);
    b->doff = bispec_alloc(b, box * sizeof *b->doff);
    b->dleg = bispec_alloc(b, box * sizeof *b->dleg);
    b->nrow = 2 * r2 + 1;
    b->drow = bispec_alloc(b, ((size_t)b->nrow + 1) * sizeof *b->drow);
    if (!b->doff || !b->dleg || !b->drow)
        return SL_ENOMEM;
    b->nd = 0;
    for (int dq = -r2; dq <= r2; dq++)
        for (int dp = -r2, first = 1; dp <= r2; dp++, first = 0) {
            if (first)
                b->drow[dq + r2] = (int32_t)b->nd;
            int leg = b->lut[(dq + b->qm) * b->lw + dp + b->pm];
            if (dp * dp + dq * dq <= r2 * r2 && leg > 0) {
                b->doff[b->nd] = dq * b->lw + dp;
                b->dleg[b->nd++] = leg;
            }
        }
    b->drow[b->nrow] = (int32_t)b->nd;
    /* dfirst[r][dp + R2]: row r's first entry with an offset >= dp (one
     * past the row's end for dp = R2 + 1) */
    size_t rw = (size_t)2 * r2 + 2;
    if (!(b->dfirst = bispec_alloc(b, (size_t)b->nrow * rw * sizeof *b->dfirst)))
        return SL_ENOMEM;
    for (int r = 0; r < b->nrow; r++) {
        int k = b->drow[r], dq = r - r2;
        for (int dp = -r2; dp <= r2 + 1; dp++) {
            while (k < b->drow[r + 1] && b->doff[k] - dq * b->lw < dp)
                k++;
            b->dfirst[(size_t)r * rw + dp + r2] = k;
        }
    }
    return SL_OK;
}

/* The support's half-plane frequencies in rank order, the lut, the disk
 * and the seeds. */
static int build_freqs(bispec *b)
{
    int w = b->w, h = b->h, r2 = b->o.r2_px;
    const unsigned char *m = b->o.support;
    int pmax = (w - 1) / 2, qmax = (h - 1) / 2; /* no Nyquist */
    double rc = b->o.rcut_px;
    hfreq *hf = malloc((size_t)(pmax + 1) * (2 * qmax + 1) * sizeof *hf);
    if (!hf)
        return SL_ENOMEM;
    int nf = 0;
    for (int q = -qmax; q <= qmax; q++)
        for (int p = 0; p <= pmax; p++) {
            if (p == 0 && q < 0)
                continue;
            int in = !m || m[bispec_fidx(p, q, w, h)] || m[bispec_fidx(-p, -q, w, h)];
            if (rc > 0 && beyond(p, q, rc))
                in = 0;
            if (in || (p == 0 && q == 0))
                hf[nf++] = (hfreq){p, q, p * p + q * q};
        }
    if (sort_by_radius(&hf, nf) != SL_OK) {
        free(hf);
        return SL_ENOMEM;
    }
    b->nf = nf;
    b->pm = w / 2 + r2;
    b->qm = h / 2 + r2;
    b->lw = 2 * b->pm + 1;
    b->lh = 2 * b->qm + 1;
    b->fp = bispec_alloc(b, (size_t)nf * sizeof *b->fp);
    b->fq = bispec_alloc(b, (size_t)nf * sizeof *b->fq);
    b->ubase = bispec_alloc(b, (size_t)nf * sizeof *b->ubase);
    b->seed = bispec_alloc(b, (size_t)nf);
    b->lut = bispec_alloc(b, (size_t)b->lw * b->lh * sizeof *b->lut);
    if (!b->fp || !b->fq || !b->ubase || !b->seed || !b->lut) {
        free(hf);
        return SL_ENOMEM;
    }
    for (size_t i = 0; i < (size_t)b->lw * b->lh; i++)
        b->lut[i] = -1;
    for (int j = 0; j < nf; j++) {
        int p = hf[j].p, q = hf[j].q;
        b->fp[j] = p;
        b->fq[j] = q;
        b->ubase[j] = (q + b->qm) * b->lw + (p + b->pm);
        b->lut[b->ubase[j]] = j;
        if (j > 0)
            b->lut[(-q + b->qm) * b->lw + (-p + b->pm)] = nf + j;
        b->seed[j] = (p == 1 && q == 0) || (p == 0 && q == 1);
    }
    free(hf);
    return build_disk(b);
}

/* Is disk entry k a stored triple of target j (legs of lower rank,
 * u2 the shortest, both reachable)?  Without branches: about half the
 * entries qualify, in no pattern a predictor learns, and a mispredicted
 * branch cost more than every load here (the lut covers u - u2 for all
 * k; a leg outside S, -1, reads reach[0]). */
static inline int usable(const bispec *b, int j, size_t k, const unsigned char *reach)
{
    int nf = b->nf, l2 = b->dleg[k], h2 = l2 < nf ? l2 : l2 - nf;
    int l1 = b->lut[b->ubase[j] - b->doff[k]], in = l1 >= 0;
    int l1c = in ? l1 : 0, h1 = l1c < nf ? l1c : l1c - nf;
    return in & (h2 < j) & (h1 < j) & (h1 >= h2) & ((h1 != h2) | (l1 == l2)) &
           (reach[h2] != 0) & (reach[h1] != 0);
}

/* The disk entries of row r that can be triples of target j = u: a
 * stored triple has |u2| <= |u| and |u - u2| <= |u| (its legs rank below
 * u, and rank follows |.|^2 first), so dp lies in the intersection of two
 * intervals; usable() decides within them.  The bounds are widened by a
 * pixel, so rounding cannot drop a triple.  This skips about half the
 * disk for a target far out and most of it for one near the origin: the
 * scan tested every entry of every target, 3.8e7 tests at 200^2. */
static void row_span(const bispec *b, int j, int r, int *k0, int *k1)
{
    int r2 = b->o.r2_px, dq = r - r2;
    double p = b->fp[j], q = b->fq[j], uu = p * p + q * q;
    double d1 = p * p + 2 * q * dq - (double)dq * dq; /* (dp - p)^2 <= d1 */
    double d2 = uu - (double)dq * dq;                 /* dp^2 <= d2 */
    *k0 = *k1 = b->drow[r];
    if (d1 < 0 || d2 < 0)
        return;
    /* d1, d2 >= 0: no NaN, so plain compares (fmax and fmin were calls,
     * two for each of the ~1e6 rows a plan scans at 200^2) */
    double s1 = sqrt(d1), s2 = sqrt(d2), lo1 = p - s1, hi1 = p + s1;
    double lo = lo1 > -s2 ? lo1 : -s2, hi = hi1 < s2 ? hi1 : s2;
    int ilo = (int)floor(lo) - 1, ihi = (int)ceil(hi) + 1;
    ilo = ilo < -r2 ? -r2 : ilo;
    ihi = ihi > r2 ? r2 : ihi;
    if (ilo > ihi)
        return;
    const int32_t *first = b->dfirst + (size_t)r * (2 * r2 + 2);
    *k0 = first[ilo + r2];
    *k1 = first[ihi + r2 + 1];
}

/* reach[j]: the recursion can reach u_j from DC and the seeds (some
 * triple of j has reachable legs).  Serial: it follows the rank order.
 * Rows are tried from the disk's middle out, within row_span: a short u2
 * next to u (u - (1, 0), say) nearly always ranks below it, so the first
 * few tests decide; from the disk's first row it took ~500 at 512^2
 * (0.1 s, most of bispec_new's serial time). */
static void scan_reach(const bispec *b, unsigned char *reach)
{
    int r2 = b->o.r2_px;
    memset(reach, 0, (size_t)b->nf);
    for (int j = 0; j < b->nf; j++) {
        if (j == 0 || b->seed[j]) {
            reach[j] = 1;
            continue;
        }
        for (int i = 0; i < b->nrow && !reach[j]; i++) {
            int r = r2 + (i % 2 ? (i + 1) / 2 : -(i / 2)), k0, k1;
            row_span(b, j, r, &k0, &k1);
            for (int k = k0; k < k1 && !reach[j]; k++)
                reach[j] = (unsigned char)usable(b, j, (size_t)k, reach);
        }
    }
}

/* Targets are claimed in blocks of SCAN_BLOCK by whichever thread is
 * free: the triple count grows with |u|, so fixed shares would not
 * balance (dealt round robin, one thread scanned alone for the last
 * ~10 % at 512^2).  Each block's triples go to a list of its own (one
 * pass, no count first), joined in order once every block is done, so
 * the list does not depend on who scanned what. */
#define SCAN_BLOCK 64
typedef struct scan_job {
    bispec *b;
    const unsigned char *reach;
    uint16_t **list;        /* per block: its triples' disk entries (NULL:
                               not allocated) */
    atomic_int next;        /* the next unclaimed block */
} scan_job;

/* tpool job: list the triples of the blocks this thread claims, each
 * target's count in tstart[j + 1].  Every disk entry is written and the
 * cursor advances past the usable ones only: no branch on usable(). */
static void scan_run(void *ctx, int tid, int nthr)
{
    scan_job *s = ctx;
    bispec *b = s->b;
    (void)tid, (void)nthr;
    for (int j0; (j0 = atomic_fetch_add(&s->next, 1) * SCAN_BLOCK) < b->nf;) {
        int j1 = j0 + SCAN_BLOCK < b->nf ? j0 + SCAN_BLOCK : b->nf;
        uint16_t *row = malloc(((size_t)(j1 - j0) * b->nd + 1) * sizeof *row);
        if (!(s->list[j0 / SCAN_BLOCK] = row))
            return; /* scan_triples sees the NULL */
        int64_t t = 0;
        for (int j = j0; j < j1; j++) {
            int64_t t0 = t;
            if (s->reach[j] && j > 0 && !b->seed[j])
                for (int r = 0; r < b->nrow; r++) {
                    int k0, k1;
                    row_span(b, j, r, &k0, &k1);
                    for (int k = k0; k < k1; k++) {
                        row[t] = (uint16_t)k;
                        t += usable(b, j, (size_t)k, s->reach);
                    }
                }
            b->tstart[j + 1] = t - t0;
        }
    }
}

/* tpool job: copy thread tid's blocks' lists to tk, and free them (the
 * lists hold nd entries a target, ~40 MB at 512^2: freed by the caller
 * alone they were ~5 ms with the other threads idle). */
static void join_run(void *ctx, int tid, int nthr)
{
    scan_job *s = ctx;
    bispec *b = s->b;
    for (int j0 = tid * SCAN_BLOCK; j0 < b->nf; j0 += nthr * SCAN_BLOCK) {
        int j1 = j0 + SCAN_BLOCK < b->nf ? j0 + SCAN_BLOCK : b->nf;
        memcpy(b->tk + b->tstart[j0], s->list[j0 / SCAN_BLOCK],
               (size_t)(b->tstart[j1] - b->tstart[j0]) * sizeof *b->tk);
        free(s->list[j0 / SCAN_BLOCK]);
        s->list[j0 / SCAN_BLOCK] = NULL;
    }
}

/* The triples of every target: tstart and tk.  SL_ENOMEM. */
static int scan_triples(bispec *b, const unsigned char *reach)
{
    size_t nblk = ((size_t)b->nf + SCAN_BLOCK - 1) / SCAN_BLOCK;
    scan_job job = {b, reach, calloc(nblk, sizeof *job.list), 0};
    if (!job.list)
        return SL_ENOMEM;
    tpool_run(b->pool, scan_run, &job);
    int fail = 0;
    for (size_t i = 0; i < nblk; i++)
        fail |= !job.list[i];
    if (!fail) {
        for (int j = 0; j < b->nf; j++) /* counts to starts */
            b->tstart[j + 1] += b->tstart[j];
        b->nt = b->tstart[b->nf];
        /* join_run fills it; the pool hands it back (76 MB at 512^2) */
        b->tk = bispec_alloc_big(b, (size_t)b->nt * sizeof *b->tk, 0);
        if (b->tk)
            tpool_run(b->pool, join_run, &job);
    }
    for (size_t i = 0; i < nblk; i++)
        free(job.list[i]);
    free(job.list);
    return fail || !b->tk ? SL_ENOMEM : SL_OK;
}

/* The kernel's target order: tiles of BISPEC_TILE x BISPEC_TILE
 * frequencies, row by row, so that consecutive targets share most u1 legs
 * (u1 = u - u2 lies within R2 of u), and within a tile row by row too:
 * the next target in a row takes the same u1 legs of a disk segment but
 * one, still in L1 (bispec_kernel.c).  Any order gives the same bits:
 * each triple is summed by one thread, batch after batch. */
/* The frequencies j in increasing order of key[j] (distinct, in
 * 0..nkey-1) into ord: a table of size nkey scanned once (O(nkey + nf),
 * where qsort took ~15 ms each of serial planning at 512^2).  SL_ENOMEM. */
static int order_by_key(const int64_t *key, int nf, int64_t nkey, int32_t *ord)
{
    int32_t *slot = malloc((size_t)nkey * sizeof *slot);
    if (!slot)
        return SL_ENOMEM;
    memset(slot, 0xff, (size_t)nkey * sizeof *slot);   /* -1: no frequency */
    for (int j = 0; j < nf; j++)
        slot[key[j]] = j;
    int n = 0;
    for (int64_t k = 0; k < nkey; k++)
        if (slot[k] >= 0)
            ord[n++] = slot[k];
    free(slot);
    return SL_OK;
}

static int tile_order(bispec *b)
{
    int64_t *key = malloc((size_t)b->nf * sizeof *key);
    if (!key)
        return SL_ENOMEM;
    int64_t ntp = b->lw / BISPEC_TILE + 1, ntq = b->lh / BISPEC_TILE + 1;
    int64_t tt = (int64_t)BISPEC_TILE * BISPEC_TILE;
    for (int j = 0; j < b->nf; j++) {
        int64_t tile = (int64_t)((b->fq[j] + b->qm) / BISPEC_TILE) * ntp +
                       (b->fp[j] + b->pm) / BISPEC_TILE;
        int64_t in = (int64_t)((b->fq[j] + b->qm) % BISPEC_TILE) * BISPEC_TILE +
                     (b->fp[j] + b->pm) % BISPEC_TILE;
        key[j] = tile * tt + in;
    }
    int rc = order_by_key(key, b->nf, ntq * ntp * tt, b->order);
    for (int j = 0; rc == SL_OK && j < b->nf; j++)
        b->tbeg[j] = j == 0 || key[b->order[j]] / tt != key[b->order[j - 1]] / tt;
    free(key);
    return rc;
}

/* sorder: the frequencies by their place in the half spectrum (row q mod
 * h, then p), the order in which bispec_kernel.c spreads them. */
static int spectrum_order(bispec *b)
{
    int64_t *key = malloc((size_t)b->nf * sizeof *key);
    if (!key)
        return SL_ENOMEM;
    for (int j = 0; j < b->nf; j++)
        key[j] = (int64_t)((b->fq[j] + b->h) % b->h) * b->wc + b->fp[j];
    int rc = order_by_key(key, b->nf, (int64_t)b->h * b->wc, b->sorder);
    free(key);
    return rc;
}

/* Split order[] into BISPEC_KUNITS units of about equal triple counts,
 * at tile starts (a unit may be empty). */
static void split_units(bispec *b)
{
    int o = 0;
    int64_t done = 0;
    b->kunit[0] = 0;
    for (int r = 1; r < BISPEC_KUNITS; r++) {
        int64_t goal = b->nt * r / BISPEC_KUNITS;
        for (; o < b->nf && (done < goal || !b->tbeg[o]); o++)
            done += b->tstart[b->order[o] + 1] - b->tstart[b->order[o]];
        b->kunit[r] = o;
    }
    b->kunit[BISPEC_KUNITS] = b->nf;
}

int bispec_build_graph(bispec *b, sl_err *err)
{
    int rc = build_freqs(b);
    b->o.support = NULL; /* not kept: the caller may free it */
    if (rc != SL_OK)
        return SL_ENOMEM;
    if (b->nf < 4)
        return sl_seterr(err, SL_EDATA, "bispec: support has only %d frequencies", b->nf);
    unsigned char *reach = malloc((size_t)b->nf);
    b->tstart = bispec_alloc(b, ((size_t)b->nf + 1) * sizeof *b->tstart);
    if (!reach || !b->tstart) {
        free(reach);
        return SL_ENOMEM;
    }
    scan_reach(b, reach);
    rc = scan_triples(b, reach);
    free(reach);
    if (rc != SL_OK)
        return rc;
    b->kunit = bispec_alloc(b, ((size_t)BISPEC_KUNITS + 1) * sizeof *b->kunit);
    b->order = b->kunit ? bispec_alloc(b, (size_t)b->nf * sizeof *b->order) : NULL;
    b->tbeg = b->order ? bispec_alloc(b, (size_t)b->nf) : NULL;
    b->sorder = b->tbeg ? bispec_alloc(b, (size_t)b->nf * sizeof *b->sorder) : NULL;
    if (!b->sorder || tile_order(b) != SL_OK || spectrum_order(b) != SL_OK)
        return SL_ENOMEM;
    split_units(b);
    return SL_OK;
}
