/* bispec.c - see bispec.h (what is stored, memory, streaming) and
 * phasor.h (phase recovery).
 *
 * Layout.  The F half-plane support frequencies are sorted by visiting
 * rank; legs 0..F-1 are +u_j, legs F..2F-1 are -u_j.  A dense lookup
 * table over |p| <= w/2 + R2, |q| <= h/2 + R2 maps a frequency to its leg
 * (-1 outside S), so u1 = u - u2 is lut[ubase[j] - doff[k]] with no
 * bounds test.  A triple stores only k, the u2 disk entry (uint16).
 * The batch buffer holds, per leg, BISPEC_BATCH real parts then
 * BISPEC_BATCH imaginary parts (conjugates pre-made for the minus legs),
 * so the triple kernel is branch-free SIMD over the frames of a batch.
 */
#include <complex.h>
#include <fftw3.h>

#include "bispec_int.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>


void bispec_opts_defaults(bispec_opts *o)
{
    memset(o, 0, sizeof *o);
    o->r2_px = 8;
    o->rcut_px = 0;
    o->window = POWSPEC_WIN_NONE;
    o->tukey_alpha = 0.25;
    o->weight = PHASOR_WEIGHT_MOD;
    o->refine_weight = PHASOR_WEIGHT_MOD;
    o->nthreads = 1;
    o->measure = 1;
    o->taper_frac = 0.2;
}

/* Zeroed allocation of `bytes` counted in b->mem; 64-byte aligned (the
 * SIMD batch needs it); never NULL for 0 bytes, which count as 0. */
static void *balloc(bispec *b, size_t bytes)
{
    size_t sz = (bytes + 63) / 64 * 64;
    void *p = aligned_alloc(64, sz ? sz : 64);
    if (p) {
        memset(p, 0, sz ? sz : 64);
        b->mem += bytes;
    }
    return p;
}

typedef struct hfreq {
    int p, q, r2;
} hfreq;

static int cmp_hfreq(const void *x, const void *y)
{
    const hfreq *a = x, *b = y;
    if (a->r2 != b->r2)
        return (a->r2 > b->r2) - (a->r2 < b->r2);
    if (a->q != b->q)
        return (a->q > b->q) - (a->q < b->q);
    return (a->p > b->p) - (a->p < b->p);
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
            if (rc > 0 && hypot(p, q) > rc)
                in = 0;
            if (in || (p == 0 && q == 0))
                hf[nf++] = (hfreq){p, q, p * p + q * q};
        }
    qsort(hf, (size_t)nf, sizeof *hf, cmp_hfreq);
    b->nf = nf;
    b->pm = w / 2 + r2;
    b->qm = h / 2 + r2;
    b->lw = 2 * b->pm + 1;
    b->lh = 2 * b->qm + 1;
    b->fp = balloc(b, (size_t)nf * sizeof *b->fp);
    b->fq = balloc(b, (size_t)nf * sizeof *b->fq);
    b->ubase = balloc(b, (size_t)nf * sizeof *b->ubase);
    b->seed = balloc(b, (size_t)nf);
    b->lut = balloc(b, (size_t)b->lw * b->lh * sizeof *b->lut);
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
    /* The u2 disk: offsets with 0 < |u2| <= R2 that are in S (room for
     * the whole (2 R2 + 1)^2 box: at most 0.5 MB, and one pass). */
    size_t box = (size_t)(2 * r2 + 1) * (2 * r2 + 1);
    b->doff = balloc(b, box * sizeof *b->doff);
    b->dleg = balloc(b, box * sizeof *b->dleg);
    if (!b->doff || !b->dleg)
        return SL_ENOMEM;
    b->nd = 0;
    for (int dq = -r2; dq <= r2; dq++)
        for (int dp = -r2; dp <= r2; dp++) {
            int leg = b->lut[(dq + b->qm) * b->lw + dp + b->pm];
            if (dp * dp + dq * dq <= r2 * r2 && leg > 0) {
                b->doff[b->nd] = dq * b->lw + dp;
                b->dleg[b->nd++] = leg;
            }
        }
    return SL_OK;
}

/* Count (pass 0) or store (pass 1) the triples; reach[] marks frequencies
 * the recursion can reach from DC and the seeds. */
static void scan_triples(bispec *b, int pass, unsigned char *reach)
{
    int nf = b->nf;
    int64_t t = 0;
    memset(reach, 0, (size_t)nf);
    reach[0] = 1;
    for (int j = 0; j < nf; j++) {
        if (pass)
            b->tstart[j] = t;
        if (j == 0 || b->seed[j]) {
            reach[j] = 1;
            continue;
        }
        int64_t t0 = t;
        for (size_t k = 0; k < b->nd; k++) {
            int l2 = b->dleg[k], h2 = l2 % nf;
            if (h2 >= j || !reach[h2])
                continue;
            int l1 = b->lut[b->ubase[j] - b->doff[k]];
            if (l1 < 0)
                continue;
            int h1 = l1 % nf;
            if (h1 >= j || h1 < h2 || (h1 == h2 && l1 != l2) || !reach[h1])
                continue;
            if (pass)
                b->tk[t] = (uint16_t)k;
            t++;
        }
        reach[j] = t > t0;
    }
    if (pass)
        b->tstart[nf] = t;
    b->nt = t;
}

/* Split the targets into nthr ranges of about equal triple counts. */
static void split_ranges(bispec *b)
{
    int j = 0;
    b->trange[0] = 0;
    for (int r = 1; r < b->nthr; r++) {
        int64_t goal = b->nt * r / b->nthr;
        while (j < b->nf && b->tstart[j] < goal)
            j++;
        b->trange[r] = j;
    }
    b->trange[b->nthr] = b->nf;
}

static int check_opts(const bispec_opts *o, int w, int h, sl_err *err)
{
    if (w < 8 || h < 8)
        return sl_seterr(err, SL_EINVAL, "bispec: frame %dx%d too small", w, h);
    if (o->r2_px < 1 || o->r2_px > BISPEC_R2_MAX || o->nthreads < 1 ||
        o->nthreads > 64)
        return sl_seterr(err, SL_ERANGE, "bispec: R2 = %d px (1..%d) or "
                         "%d threads (1..64)", o->r2_px, BISPEC_R2_MAX,
                         o->nthreads);
    int win_ok = o->window == POWSPEC_WIN_NONE ||
                 o->window == POWSPEC_WIN_HANN ||
                 (o->window == POWSPEC_WIN_TUKEY && o->tukey_alpha >= 0 &&
                  o->tukey_alpha <= 1);
    if (o->weight < PHASOR_WEIGHT_MOD || o->weight > PHASOR_WEIGHT_UNIT ||
        o->refine_weight < PHASOR_WEIGHT_MOD || o->refine_weight > PHASOR_WEIGHT_UNIT ||
        !(o->adu_per_photon >= 0) || !(o->read_noise_adu >= 0) || o->refine_iters < -1 ||
        !(o->taper_frac >= 0 && o->taper_frac <= 1) || !win_ok)
        return sl_seterr(err, SL_EINVAL, "bispec: bad option (weight %d, "
                         "gain %g, read noise %g, refine %d, taper %g, window %d)",
                         o->weight, o->adu_per_photon, o->read_noise_adu,
                         o->refine_iters, o->taper_frac, o->window);
    return SL_OK;
}

/* The triple graph: frequencies of the support, triples per target, the
 * threads' ranges.  SL_EDATA for a support of fewer than 4 frequencies
 * (message in err), SL_ENOMEM. */
static int build_graph(bispec *b, sl_err *err)
{
    int rc = build_freqs(b);
    b->o.support = NULL; /* not kept: the caller may free it */
    if (rc != SL_OK)
        return SL_ENOMEM;
    if (b->nf < 4)
        return sl_seterr(err, SL_EDATA, "bispec: support has only %d frequencies", b->nf);
    unsigned char *reach = malloc((size_t)b->nf);
    b->tstart = balloc(b, ((size_t)b->nf + 1) * sizeof *b->tstart);
    if (!reach || !b->tstart) {
        free(reach);
        return SL_ENOMEM;
    }
    scan_triples(b, 0, reach);
    b->tk = balloc(b, (size_t)b->nt * sizeof *b->tk);
    if (b->tk)
        scan_triples(b, 1, reach);
    free(reach);
    b->trange = b->tk ? balloc(b, ((size_t)b->nthr + 1) * sizeof *b->trange) : NULL;
    if (!b->trange)
        return SL_ENOMEM;
    split_ranges(b);
    return SL_OK;
}

/* Every buffer, from one table: what it is, its size, whether this
 * configuration needs it.  balloc's 64-byte alignment also suits FFTW's
 * SIMD codelets. */
static int alloc_buffers(bispec *b)
{
    const bispec_opts *o = &b->o;
    size_t nt = (size_t)b->nt, nf = (size_t)b->nf, npx = (size_t)b->w * b->h;
    size_t nh = (size_t)b->h * b->wc, asz = o->acc_float ? sizeof(float) : sizeof(double);
    int snr = o->weight == PHASOR_WEIGHT_SNR || o->refine_weight == PHASOR_WEIGHT_SNR;
    int ph = o->adu_per_photon > 0, win = o->window != POWSPEC_WIN_NONE;
    void *acc = NULL, *acc2 = NULL;
    const struct { void **slot; size_t bytes; int want; } bufs[] = {
        {&acc, 2 * nt * asz, 1},
        {&acc2, nt * asz, snr},
        {(void **)&b->fb, nf * 2 * 2 * K * sizeof(float), 1},
        {(void **)&b->psum, nf * sizeof(double), 1},
        {(void **)&b->xsum, 2 * nf * sizeof(double), ph},
        {(void **)&b->phi, nf * sizeof(double), 1},
        {(void **)&b->known, nf, 1},
        {(void **)&b->work, phasor_work_doubles((int)nf) * sizeof(double), 1},
        {(void **)&b->win, npx * sizeof(float), win},
        {(void **)&b->in, npx * sizeof(float), 1},
        {(void **)&b->out, nh * sizeof(fftwf_complex), 1},
        {(void **)&b->in2, npx * sizeof(float), ph && win},
        {(void **)&b->out2, nh * sizeof(fftwf_complex), ph && win},
        {(void **)&b->cin, nh * sizeof(fftw_complex), 1},
        {(void **)&b->cout, npx * sizeof(double), 1}};
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++)
        if (bufs[i].want && !(*bufs[i].slot = balloc(b, bufs[i].bytes)))
            return SL_ENOMEM;
    if (o->acc_float)
        b->accf = acc, b->acc2f = acc2;
    else
        b->accd = acc, b->acc2d = acc2;
    return SL_OK;
}

/* The window, the read noise's sums over it and the FFT plans. */
static int plan_transforms(bispec *b)
{
    const bispec_opts *o = &b->o;
    int w = b->w, h = b->h, nf = b->nf;
    size_t npx = (size_t)w * h;
    if (b->win)
        powspec_window(o->window, o->tukey_alpha, w, h, b->win);
    if (b->xsum) { /* white noise of variance s^2: s^2 sum w^2 in |F|^2, s^2 sum w^3 in X */
        double s2 = o->read_noise_adu * o->read_noise_adu;
        for (size_t i = 0; i < npx; i++) {
            double wv = b->win ? b->win[i] : 1.0;
            b->rw2 += s2 * wv * wv;
            b->rw3 += s2 * wv * wv * wv;
        }
    }
    unsigned flags = o->measure ? FFTW_MEASURE : FFTW_ESTIMATE;
    b->plan = fftwf_plan_dft_r2c_2d(h, w, b->in, b->out, flags);
    if (b->in2)
        b->plan2 = fftwf_plan_dft_r2c_2d(h, w, b->in2, b->out2, flags);
    if (b->plan2 && o->read_noise_adu > 0) {
        /* Windowed read noise N is correlated across frequencies:
         * E N(u) conj N(v) = rn^2 W2(u - v), W2 = FFT(w^2), so the mean
         * bispectrum gains rn^2 (S1 conj W2(u1) + S2 conj W2(u2) +
         * conj(S3 conj W2(u3))), the read-noise twin of Wirnitzer's
         * terms: folded into X per frame (bispec_add).  Zero without a
         * window (W2 = 0 off DC). */
        if (!(b->w2ft = balloc(b, 2 * (size_t)nf * sizeof(double))))
            return SL_ENOMEM;
        for (size_t i = 0; i < npx; i++)
            b->in2[i] = b->win[i] * b->win[i];
        fftwf_execute(b->plan2);
        double sc = o->read_noise_adu * o->read_noise_adu / o->adu_per_photon;
        for (int j = 0; j < nf; j++) {
            size_t q = (size_t)((b->fq[j] + h) % h) * b->wc + b->fp[j];
            b->w2ft[2 * j] = sc * crealf(b->out2[q]);
            b->w2ft[2 * j + 1] = -sc * cimagf(b->out2[q]);
        }
    }
    /* The image transform runs once per reconstruction: not worth
     * measuring. */
    b->iplan = fftw_plan_dft_c2r_2d(h, w, b->cin, b->cout, FFTW_ESTIMATE);
    return !b->plan || (b->in2 && !b->plan2) || !b->iplan ? SL_ENOMEM : SL_OK;
}

bispec *bispec_new(int w, int h, const bispec_opts *o, sl_err *err)
{
    bispec_opts def;
    if (!o) {
        bispec_opts_defaults(&def);
        o = &def;
    }
    if (check_opts(o, w, h, err) != SL_OK)
        return NULL;
    bispec *b = calloc(1, sizeof *b);
    int rc = SL_ENOMEM;
    if (!b)
        goto fail;
    b->w = w;
    b->h = h;
    b->wc = w / 2 + 1;
    b->o = *o;
    b->nthr = o->nthreads;
    if ((rc = build_graph(b, err)) != SL_OK || (rc = alloc_buffers(b)) != SL_OK ||
        (rc = plan_transforms(b)) != SL_OK)
        goto fail;
    return b;
fail:
    if (rc == SL_ENOMEM)
        sl_seterr(err, SL_ENOMEM, "bispec: out of memory (%dx%d, R2 %d, %lld "
                  "triples)", w, h, o->r2_px, b ? (long long)b->nt : 0LL);
    bispec_free(b);
    return NULL;
}

void bispec_free(bispec *b)
{
    if (!b)
        return;
    if (b->plan)
        fftwf_destroy_plan(b->plan);
    if (b->plan2)
        fftwf_destroy_plan(b->plan2);
    if (b->iplan)
        fftw_destroy_plan(b->iplan);
    void *bufs[] = {b->fp,   b->fq,    b->ubase, b->seed,  b->lut,  b->doff,
                    b->dleg, b->tstart, b->tk,   b->trange, b->accd, b->acc2d,
                    b->accf, b->acc2f, b->fb,    b->psum,  b->xsum, b->phi,
                    b->known, b->work, b->win,   b->in,    b->out,  b->in2,
                    b->out2, b->cin,   b->cout, b->w2ft};
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++)
        free(bufs[i]);
    free(b);
}

const char *bispec_errmsg(const bispec *b) { return b ? b->err.msg : "no bispec handle"; }
int bispec_nframes(const bispec *b) { return b ? b->n : 0; }
size_t bispec_ntriples(const bispec *b) { return b ? (size_t)b->nt : 0; }
int bispec_nfreq(const bispec *b) { return b ? b->nf : 0; }
size_t bispec_ndisk(const bispec *b) { return b ? b->nd : 0; }
size_t bispec_memory_bytes(const bispec *b) { return b ? b->mem : 0; }

/* Horizontal sum as a shallow tree (a serial lane-by-lane sum is a long
 * dependency chain per triple, which dominated the kernel).  By
 * pointer: passing a 64-byte vector by value draws an ABI note. */
typedef float v4 __attribute__((vector_size(4 * sizeof(float))));
static inline float hsum(const vk *v)
{
    v4 q[K / 4];
    memcpy(q, v, sizeof q);
    for (int s = K / 8; s >= 1; s /= 2)
        for (int i = 0; i < s; i++)
            q[i] += q[i + s];
    return (q[0][0] + q[0][2]) + (q[0][1] + q[0][3]);
}

/* One accumulator flavour of the hot loop (ACC: double or float; SNR:
 * keep the second moment).  For targets j0..j1-1 and each stored triple,
 * sum over the batch's frames I(u1) I(u2) conj I(u) in K float lanes and
 * add to the accumulators.  Per triple: 2 bytes of index, two small
 * gathers from cache-resident tables, three 128-byte leg blocks (mostly
 * cache hits: u1 lies near u, u2 near the origin), and one read-modify-
 * write of the accumulator, which streams through memory once per batch. */
#define KERNEL(NAME, ACC, ACCF, ACC2F)                                        \
    static void NAME(const bispec *b, int j0, int j1)                        \
    {                                                                        \
        const float *fb = b->fb;                                             \
        ACC *acc = b->ACCF;                                                  \
        ACC *acc2 = ACC2F;                                                   \
        (void)acc2;                                                          \
        for (int j = j0; j < j1; j++) {                                      \
            vk cr, ci;                                                       \
            memcpy(&cr, fb + (size_t)j * 2 * K, sizeof cr);                  \
            memcpy(&ci, fb + (size_t)j * 2 * K + K, sizeof ci);              \
            const int32_t *lut = b->lut + b->ubase[j];                       \
            for (int64_t t = b->tstart[j]; t < b->tstart[j + 1]; t++) {      \
                int k = b->tk[t];                                            \
                const float *pa = fb + (size_t)lut[-b->doff[k]] * 2 * K;     \
                const float *pb = fb + (size_t)b->dleg[k] * 2 * K;           \
                vk ar, ai, br, bi;                                           \
                memcpy(&ar, pa, sizeof ar);                                  \
                memcpy(&ai, pa + K, sizeof ai);                              \
                memcpy(&br, pb, sizeof br);                                  \
                memcpy(&bi, pb + K, sizeof bi);                              \
                vk abr = ar * br - ai * bi, abi = ar * bi + ai * br;         \
                vk xr = abr * cr + abi * ci, xi = abi * cr - abr * ci;       \
                acc[2 * t] += hsum(&xr);                                     \
                acc[2 * t + 1] += hsum(&xi);                                 \
                if (ACC2F) {                                                 \
                    vk x2 = xr * xr + xi * xi;                               \
                    acc2[t] += hsum(&x2);                                    \
                }                                                            \
            }                                                                \
        }                                                                    \
    }
KERNEL(kernel_d, double, accd, NULL)
KERNEL(kernel_ds, double, accd, b->acc2d)
KERNEL(kernel_f, float, accf, NULL)
KERNEL(kernel_fs, float, accf, b->acc2f)

static void kernel(const bispec *b, int j0, int j1)
{
    if (b->accd)
        (b->acc2d ? kernel_ds : kernel_d)(b, j0, j1);
    else
        (b->acc2f ? kernel_fs : kernel_f)(b, j0, j1);
}

typedef struct kjob { const bispec *b; int j0, j1; } kjob;

static void *kthread(void *arg)
{
    const kjob *k = arg;
    kernel(k->b, k->j0, k->j1);
    return NULL;
}

/* Run the kernel over the batch (empty slots zeroed: they add nothing). */
void bispec_flush(bispec *b)
{
    if (!b->nb)
        return;
    if (b->nb < K)
        for (size_t l = 0; l < 2 * (size_t)b->nf; l++)
            for (int c = 0; c < 2; c++)
                memset(b->fb + (l * 2 + c) * K + b->nb, 0,
                       (size_t)(K - b->nb) * sizeof(float));
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    pthread_t th[64];
    kjob jobs[64];
    int started = 0;
    for (int r = 0; r < b->nthr; r++)
        jobs[r] = (kjob){b, b->trange[r], b->trange[r + 1]};
    for (int r = 1; r < b->nthr; r++) {
        if (pthread_create(&th[r], NULL, kthread, &jobs[r]) != 0)
            break; /* no thread: run the rest here */
        started = r;
    }
    kernel(b, jobs[0].j0, jobs[0].j1);
    for (int r = started + 1; r < b->nthr; r++)
        kernel(b, jobs[r].j0, jobs[r].j1);
    for (int r = 1; r <= started; r++)
        pthread_join(th[r], NULL);
    b->nb = 0;
    clock_gettime(CLOCK_MONOTONIC, &t1);
    b->kernel_s += (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
}

double bispec_kernel_s(const bispec *b) { return b ? b->kernel_s : 0; }

int bispec_add(bispec *b, const float *frame)
{
    if (!b || !frame)
        return sl_seterr(b ? &b->err : NULL, SL_EINVAL,
                         "bispec_add: NULL argument");
    size_t npx = (size_t)b->w * b->h;
    double w2 = 0, w3 = 0;
    for (size_t i = 0; i < npx; i++) {
        float v = frame[i];
        if (!isfinite(v))
            return sl_seterr(&b->err, SL_EDATA,
                             "bispec_add: frame %d pixel %zu is not finite",
                             b->n, i);
        float wv = b->win ? b->win[i] : 1.0f;
        b->in[i] = wv * v;
        if (b->in2)
            b->in2[i] = wv * wv * v;
        w2 += (double)wv * wv * v;
        w3 += (double)wv * wv * wv * v;
    }
    fftwf_execute(b->plan);
    if (b->plan2)
        fftwf_execute(b->plan2);
    int nf = b->nf, s = b->nb;
    for (int j = 0; j < nf; j++) {
        size_t o = (size_t)((b->fq[j] + b->h) % b->h) * b->wc + b->fp[j];
        float re = crealf(b->out[o]), im = cimagf(b->out[o]);
        float *pj = b->fb + (size_t)j * 2 * K, *mj = pj + (size_t)nf * 2 * K;
        pj[s] = re;
        pj[K + s] = im;
        mj[s] = re;
        mj[K + s] = -im;
        double p2 = (double)re * re + (double)im * im;
        b->psum[j] += p2;
        if (b->xsum) {
            /* X = F_w conj(F_{w^2}); without a window that is |F|^2. */
            if (b->out2) {
                double r2 = crealf(b->out2[o]), i2 = cimagf(b->out2[o]);
                b->xsum[2 * j] += re * r2 + im * i2;
                b->xsum[2 * j + 1] += im * r2 - re * i2;
                if (b->w2ft) { /* F (rn^2 / g) conj W2 */
                    double wr = b->w2ft[2 * j], wi = b->w2ft[2 * j + 1];
                    b->xsum[2 * j] += re * wr - im * wi;
                    b->xsum[2 * j + 1] += re * wi + im * wr;
                }
            } else {
                b->xsum[2 * j] += p2;
            }
        }
    }
    b->w2sum += w2;
    b->w3sum += w3;
    b->n++;
    b->phased = 0;
    if (++b->nb == K)
        bispec_flush(b);
    return SL_OK;
}
