/* tsm_accum.c - see tsm_accum.h. */
#include "tsm_accum.h"

#include "base/bigmem.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* Frames taken together by the pair loop: each accumulator element is
 * loaded and stored once per group instead of once per frame.  The
 * addition's tasks (angle chunks) shrink as they go: each takes
 * 1/(TAPER nt) of the angles left, at least one, so the first are big
 * (a claim, one atomic add, is noise against them) and the last single
 * angles.  With equal chunks of 1/(4 nt) the job's last chunk ran on one
 * thread while the others waited, ~14 ms a run at 512^2 x 400
 * tsm-fourier on two (perf). */
enum { ACC_MAX_THREADS = 64, GROUP = 4, TAPER = 2 };

/* One block of frames and of their spectra. */
typedef struct block {
    int nb;                   /* frames filled */
    int nspec;                /* spectra made (or being made), not yet added */
    float *frames;            /* batch x w h: frames waiting for spectra */
    float complex *spec;      /* batch x nang x nf their spectra */
} block;

typedef void (*pairs_fn)(const tsm_accum *a, int nfr, const double *pr, const double *pi,
                         double *bre, double *bim);

struct tsm_accum {
    int w, h, nang, nf, np, batch, nframes, nthreads;
    int spatial;              /* spectra by projection, not by slices */
    pairs_fn pairs;           /* the pair loop's build for this CPU */
    const radon *rad;
    const int *off, *len;
    tpool *pool;
    block blk[2];             /* blk[cur] fills while the job runs */
    int cur, inflight;
    int pend;                 /* block whose spectra wait to be added, or -1 */
    /* The job in flight (a software pipeline, one job per block): the
     * spectra of block sl (one task a frame) and the addition of block
     * ac's spectra, made by the job before (one task per chunk of angles).
     * The two touch different buffers, so any thread takes any task, in
     * any order, with no wait inside the job: claimed by two atomic
     * counters, spectra first. */
    atomic_int s_next, a_next;
    int sl, ac, s_total, a_total, nchunk;
    int *astart;              /* nchunk + 1: chunk c is angles astart[c].. */
    radon_ws *ws[ACC_MAX_THREADS];
    double *scr;              /* nthreads x 2 GROUP (nf + 4): spectra in double */
    double *bre, *bim, *ps, *mre, *mim;
    int zero;                 /* the sums are all 0: nothing added since */
    tsm_sums sums;
};

static void finish(tsm_accum *a);
static pairs_fn pick_pairs(void);

/* The bispectrum sums' bytes (each of bre, bim: bigmem.h). */
static size_t bsum_bytes(const tsm_accum *a)
{
    return ((size_t)a->nang * a->np + 1) * sizeof(double);
}

/* A block's frames' and spectra's bytes (bigmem.h). */
static size_t frames_bytes(const tsm_accum *a)
{
    return (size_t)a->batch * a->w * a->h * sizeof(float);
}
static size_t spec_bytes(const tsm_accum *a)
{
    return (size_t)a->batch * a->nang * a->nf * sizeof(float complex);
}

/* tpool job: thread tid hands back its share of the bispectrum sums and
 * of the blocks (bigmem.h), and frees its own scratch.  At 512^2, 180
 * angles: sums 2 x 24 MB, blocks 2 x 11 MB, scratch 8.5 MB a thread, all
 * unmapped by one thread alone at the end of a run before. */
static void release_job(void *ctx, int tid, int nt)
{
    tsm_accum *a = ctx;
    bigmem_release_share(a->bre, bsum_bytes(a), tid, nt);
    bigmem_release_share(a->bim, bsum_bytes(a), tid, nt);
    for (int b = 0; b < 2; b++) {
        bigmem_release_share(a->blk[b].frames, frames_bytes(a), tid, nt);
        bigmem_release_share(a->blk[b].spec, spec_bytes(a), tid, nt);
    }
    radon_ws_free(a->ws[tid]);
    a->ws[tid] = NULL;
}

void tsm_accum_free(tsm_accum *a)
{
    if (!a)
        return;
    finish(a);
    if (a->pool && tpool_size(a->pool) > 1)
        tpool_run(a->pool, release_job, a);
    for (int i = 0; i < a->nthreads; i++)
        radon_ws_free(a->ws[i]);
    for (int b = 0; b < 2; b++) {
        bigmem_free(a->blk[b].frames, frames_bytes(a));
        bigmem_free(a->blk[b].spec, spec_bytes(a));
    }
    bigmem_free(a->bre, bsum_bytes(a));
    bigmem_free(a->bim, bsum_bytes(a));
    void *m[] = {a->scr, a->ps, a->mre, a->mim, a->astart};
    for (size_t i = 0; i < sizeof m / sizeof m[0]; i++)
        free(m[i]);
    free(a);
}

/* tpool job: thread tid zeroes its share of each sum. */
static void zero_job(void *ctx, int tid, int nt)
{
    tsm_accum *a = ctx;
    size_t nb = (size_t)a->nang * a->np + 1, ns = (size_t)a->nang * a->nf;
    double *p[5] = {a->bre, a->bim, a->ps, a->mre, a->mim};
    for (int i = 0; i < 5; i++) {
        size_t n = i < 2 ? nb : ns, i0 = n * tid / nt, i1 = n * (tid + 1) / nt;
        memset(p[i] + i0, 0, (i1 - i0) * sizeof *p[i]);
    }
}

/* The sums zeroed by the pool's threads.  Written, not calloc'd: a page
 * calloc leaves to the kernel is mapped to the zero page at the addition's
 * first read, and its first write then flushes that mapping from every
 * CPU running the process, an interprocessor interrupt per page (on this
 * VM a trap to the host): 5 % more CPU in a 512^2 tsm-fourier run on two
 * threads.  Writing first faults each page once, on the threads. */
static void zero_sums(tsm_accum *a)
{
    if (a->pool)
        tpool_run(a->pool, zero_job, a);
    else
        zero_job(a, 0, 1);
    a->zero = 1;
}

/* tpool job at tsm_accum_new: thread tid's scratch (a radon_ws, ~12
 * (sigma N)^2 bytes, zeroed: 11 MB at 512^2, whose page faults took ~8 ms
 * when one thread made them all), then its share of the sums and of the
 * blocks: the first block's frames were otherwise faulted in by the
 * caller alone as it staged them, while the other threads waited for
 * that block (~3 MB at 512^2). */
static void setup_job(void *ctx, int tid, int nt)
{
    tsm_accum *a = ctx;
    a->ws[tid] = a->spatial ? radon_ws_new_projector(a->rad, NULL) : radon_ws_new(a->rad, NULL);
    zero_job(a, tid, nt);
    for (int b = 0; b < 2; b++) {
        bigmem_touch_share(a->blk[b].frames, frames_bytes(a), tid, nt);
        bigmem_touch_share(a->blk[b].spec, spec_bytes(a), tid, nt);
    }
}

void tsm_accum_reset(tsm_accum *a)
{
    finish(a);
    a->blk[0].nb = a->blk[1].nb = a->nframes = 0;
    a->blk[0].nspec = a->blk[1].nspec = 0;
    a->pend = -1;
    if (!a->zero)
        zero_sums(a);
}

int tsm_accum_nframes(const tsm_accum *a) { return a->nframes; }

tsm_accum *tsm_accum_new(const radon *rad, int w, int h, int nang, int nf,
                         const int *off, const int *len, int np, int batch,
                         tpool *pool, sl_err *err)
{
    int nt = pool ? tpool_size(pool) : 1;
    if (!rad || w < 1 || h < 1 || nang < 1 || nf < 3 || np < 0 || batch < 1 ||
        nt > ACC_MAX_THREADS) {
        sl_seterr(err, SL_EINVAL, "tsm_accum_new: bad parameters (%s, %dx%d, %d angles, %d "
                  "frequencies, batch %d, %d threads)", rad ? "radon" : "no radon", w, h, nang,
                  nf, batch, nt);
        return NULL;
    }
    tsm_accum *a = calloc(1, sizeof *a);
    if (!a) {
        sl_seterr(err, SL_ENOMEM, "tsm_accum_new: out of memory");
        return NULL;
    }
    a->w = w, a->h = h, a->nang = nang, a->nf = nf, a->np = np, a->batch = batch;
    a->rad = rad, a->off = off, a->len = len, a->pool = pool, a->nthreads = nt;
    a->spatial = radon_can_project(rad);
    a->pairs = pick_pairs();
    if (!(a->astart = malloc(((size_t)nang + 1) * sizeof *a->astart))) {
        sl_seterr(err, SL_ENOMEM, "tsm_accum_new: out of memory");
        free(a);
        return NULL;
    }
    a->astart[0] = 0;
    for (a->nchunk = 0; a->astart[a->nchunk] < nang; a->nchunk++) {
        int left = nang - a->astart[a->nchunk], c = left / (TAPER * nt);
        a->astart[a->nchunk + 1] = a->astart[a->nchunk] + (c > 1 ? c : 1);
    }
    a->pend = -1;
    size_t nb = (size_t)nang * np, ns = (size_t)nang * nf;
    int ok = 1;
    for (int b = 0; b < 2; b++) {
        block *k = &a->blk[b];
        k->spec = bigmem_alloc(spec_bytes(a), 0);
        k->frames = bigmem_alloc(frames_bytes(a), 0);
        ok &= k->spec && k->frames;
    }
    a->scr = calloc((size_t)nt * 2 * GROUP * (nf + 4), sizeof *a->scr);
    a->bre = bigmem_alloc(bsum_bytes(a), 0);
    a->bim = bigmem_alloc(bsum_bytes(a), 0);
    a->ps = malloc(ns * sizeof *a->ps);
    a->mre = malloc(ns * sizeof *a->mre);
    a->mim = malloc(ns * sizeof *a->mim);
    ok &= a->scr && a->bre && a->bim && a->ps && a->mre && a->mim;
    if (ok) {   /* each thread's scratch made, and the sums zeroed, by the threads */
        if (pool)
            tpool_run(pool, setup_job, a);
        else
            setup_job(a, 0, 1);
        a->zero = 1;
        for (int i = 0; i < nt; i++)
            ok &= a->ws[i] != NULL;
    }
    if (!ok) {
        sl_seterr(err, SL_ENOMEM, "tsm_accum_new: out of memory (%zu bispectrum elements, "
                  "batch %d)", nb, batch);
        tsm_accum_free(a);
        return NULL;
    }
    a->sums = (tsm_sums){a->bre, a->bim, a->ps, a->mre, a->mim};
    return a;
}

/* ---- the block ---------------------------------------------------------- */

/* Four doubles: GCC and clang lower the arithmetic to whatever vectors the
 * target has (two SSE2 registers on baseline x86-64), where the plain loop
 * stays scalar at -O2.  On x86-64 the loop is also built for AVX2 and
 * chosen at tsm_accum_new when the CPU has it (measured 0.32 against 0.48
 * ms per frame at 180 angles); a plain function pointer, not an ifunc,
 * whose resolver would run before a sanitizer's runtime.  The lanes do the
 * same IEEE operations either way (no FMA: avx2 does not enable it, and
 * ISO C mode does not contract), so the sums are bit-identical on either
 * build of the loop. */
typedef double v4d __attribute__((vector_size(32)));

/* The group's nfr spectra (pr, pi: nfr x (nf + 4) doubles, zero-padded)
 * into one angle's bispectrum.  Each element receives its frames'
 * P1 P2 conj(P3) in frame order, the same additions in the same order as
 * one frame at a time, so the grouping and the 4-lane blocking change no
 * bit. */
static inline __attribute__((always_inline)) void
add_pairs_body(const tsm_accum *a, int nfr, const double *restrict pr,
               const double *restrict pi, double *restrict bre, double *restrict bim)
{
    int J = a->nf - 1, ld = a->nf + 4;
    for (int u1 = 1; u1 < J; u1++) {
        int n = a->len[u1], k = 0;
        double *restrict br = bre + a->off[u1], *restrict bi = bim + a->off[u1];
        for (; k + 4 <= n; k += 4) {
            v4d sr, si;
            memcpy(&sr, br + k, sizeof sr);
            memcpy(&si, bi + k, sizeof si);
            for (int f = 0; f < nfr; f++) {   /* P1 P2 conj(P3) */
                const double *qr = pr + f * ld, *qi = pi + f * ld;
                v4d ar = {qr[u1], qr[u1], qr[u1], qr[u1]};
                v4d ai = {qi[u1], qi[u1], qi[u1], qi[u1]};
                v4d x2r, x2i, x3r, x3i;
                memcpy(&x2r, qr + 1 + k, sizeof x2r);
                memcpy(&x2i, qi + 1 + k, sizeof x2i);
                memcpy(&x3r, qr + u1 + 1 + k, sizeof x3r);
                memcpy(&x3i, qi + u1 + 1 + k, sizeof x3i);
                v4d tr = ar * x2r - ai * x2i;
                v4d ti = ar * x2i + ai * x2r;
                sr = sr + (tr * x3r + ti * x3i);
                si = si + (ti * x3r - tr * x3i);
            }
            memcpy(br + k, &sr, sizeof sr);
            memcpy(bi + k, &si, sizeof si);
        }
        for (; k < n; k++)
            for (int f = 0; f < nfr; f++) {
                const double *qr = pr + f * ld, *qi = pi + f * ld;
                double tr = qr[u1] * qr[1 + k] - qi[u1] * qi[1 + k];
                double ti = qr[u1] * qi[1 + k] + qi[u1] * qr[1 + k];
                br[k] += tr * qr[u1 + 1 + k] + ti * qi[u1 + 1 + k];
                bi[k] += ti * qr[u1 + 1 + k] - tr * qi[u1 + 1 + k];
            }
    }
}

static void add_pairs_base(const tsm_accum *a, int nfr, const double *pr, const double *pi,
                           double *bre, double *bim)
{
    add_pairs_body(a, nfr, pr, pi, bre, bim);
}

#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("avx2")))
static void add_pairs_avx2(const tsm_accum *a, int nfr, const double *pr, const double *pi,
                           double *bre, double *bim)
{
    add_pairs_body(a, nfr, pr, pi, bre, bim);
}

static pairs_fn pick_pairs(void)
{
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx2") ? add_pairs_avx2 : add_pairs_base;
}
#else
static pairs_fn pick_pairs(void) { return add_pairs_base; }
#endif

/* Frames f0.. (nfr of them) of block b at angle k into its sums. */
static void add_group(tsm_accum *a, const block *b, int k, int f0, int nfr, double *pr,
                      double *pi)
{
    int nf = a->nf, ld = nf + 4;
    size_t i = (size_t)k * nf, q = (size_t)k * a->np;
    double *ps = a->ps + i, *mre = a->mre + i, *mim = a->mim + i;
    for (int f = 0; f < nfr; f++) {
        const float complex *s = b->spec + ((size_t)(f0 + f) * a->nang + k) * nf;
        double *qr = pr + f * ld, *qi = pi + f * ld;
        for (int j = 0; j < nf; j++) {
            qr[j] = crealf(s[j]), qi[j] = cimagf(s[j]);
            ps[j] += qr[j] * qr[j] + qi[j] * qi[j];
            mre[j] += qr[j], mim[j] += qi[j];
        }
    }
    a->pairs(a, nfr, pr, pi, a->bre + q, a->bim + q);
}

/* The job in flight: claim tasks until none is left.  A frame's spectra
 * depend on that frame only; an addition task adds block ac's spectra,
 * frame by frame, to angles nobody else touches, and the job that made
 * them had finished before this one began (finish() between jobs), so
 * each angle receives its frames in order and the sums do not depend on
 * who ran what.  Why a pipeline: with the spectra and the addition of
 * one block in one job, every thread waited at the end of the spectra
 * for the last frame (a 512^2 frame's are ~2.5 ms) and again at the end
 * of the addition: 0.18 s of one thread alone in a 512^2 x 400
 * tsm-fourier run on two. */
static void block_job(void *ctx, int tid, int nt)
{
    tsm_accum *a = ctx;
    size_t npix = (size_t)a->w * a->h, ns = (size_t)a->nang * a->nf;
    int ld = a->nf + 4;
    double *pr = a->scr + (size_t)tid * 2 * GROUP * ld, *pi = pr + GROUP * ld;
    (void)nt;
    for (int f; (f = atomic_fetch_add(&a->s_next, 1)) < a->s_total;) {
        const block *k = &a->blk[a->sl];
        if (a->spatial)
            radon_project_spec_ws(a->rad, a->ws[tid], k->frames + f * npix, k->spec + f * ns);
        else
            radon_slices_ws(a->rad, a->ws[tid], k->frames + f * npix, k->spec + f * ns);
    }
    for (int c; (c = atomic_fetch_add(&a->a_next, 1)) < a->a_total;) {
        const block *k = &a->blk[a->ac];
        for (int ang = a->astart[c]; ang < a->astart[c + 1]; ang++)
            for (int f = 0; f < k->nspec; f += GROUP)
                add_group(a, k, ang, f, k->nspec - f < GROUP ? k->nspec - f : GROUP, pr, pi);
    }
}

/* Wait for the job in flight, helping with what is left of it; then the
 * block it made spectra of waits for the next job to add them. */
static void finish(tsm_accum *a)
{
    if (!a->inflight)
        return;
    block_job(a, 0, a->nthreads);
    if (a->pool)
        tpool_wait(a->pool);
    if (a->ac >= 0)
        a->blk[a->ac].nspec = 0;
    a->pend = a->sl;
    a->inflight = 0;
}

/* The next job: blk[cur]'s spectra (if it has frames) and the addition
 * of the pending block's; the caller goes on to fill the other block
 * (whose frames that job no longer needs) meanwhile. */
static void submit(tsm_accum *a)
{
    finish(a);
    block *k = &a->blk[a->cur];
    a->sl = k->nb > 0 ? a->cur : -1;
    a->ac = a->pend;
    if (a->sl < 0 && a->ac < 0)
        return;
    a->pend = -1;
    atomic_store(&a->s_next, 0);
    atomic_store(&a->a_next, 0);
    a->s_total = k->nb;
    a->a_total = a->ac >= 0 ? a->nchunk : 0;
    if (a->sl >= 0) {
        k->nspec = k->nb;
        a->cur = !a->cur;
        a->blk[a->cur].nb = 0;
    }
    a->inflight = 1;
    if (a->pool)
        tpool_submit(a->pool, block_job, a);
}

float *tsm_accum_frame_slot(tsm_accum *a)
{
    block *k = &a->blk[a->cur];
    return k->frames + (size_t)k->nb * a->w * a->h;
}

void tsm_accum_commit_frame(tsm_accum *a)
{
    block *k = &a->blk[a->cur];
    a->nframes++;
    a->zero = 0;
    if (++k->nb == a->batch)
        submit(a);
}

const tsm_sums *tsm_accum_sums(tsm_accum *a)
{
    while (a->inflight || a->pend >= 0 || a->blk[a->cur].nb > 0) {
        submit(a);
        finish(a);
    }
    return &a->sums;
}

/* The five sums in the order of tsm_sums' fields. */
static void sum_parts(tsm_accum *a, double *part[5], size_t len[5])
{
    size_t nb = (size_t)a->nang * a->np, ns = (size_t)a->nang * a->nf;
    double *p[5] = {a->bre, a->bim, a->ps, a->mre, a->mim};
    for (int i = 0; i < 5; i++)
        part[i] = p[i], len[i] = i < 2 ? nb : ns;
}

size_t tsm_accum_pack(tsm_accum *a, double *buf)
{
    double *part[5];
    size_t len[5], n = 0;
    sum_parts(a, part, len);
    if (buf)
        tsm_accum_sums(a); /* the blocks still buffered */
    for (int i = 0; i < 5; n += len[i++])
        if (buf)
            memcpy(buf + n, part[i], len[i] * sizeof *buf);
    return n;
}

void tsm_accum_unpack(tsm_accum *a, const double *buf, int nframes)
{
    double *part[5];
    size_t len[5], n = 0;
    tsm_accum_sums(a);
    sum_parts(a, part, len);
    for (int i = 0; i < 5; n += len[i++])
        memcpy(part[i], buf + n, len[i] * sizeof *buf);
    a->nframes = nframes;
    a->zero = 0;
}
