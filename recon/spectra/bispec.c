/* bispec.c - see bispec.h (what is stored, memory, streaming) and
 * phasor.h (phase recovery): options, the handle's buffers and FFT plans.
 * The triple graph is built in bispec_graph.c, the accumulation runs in
 * bispec_kernel.c, phases and the image come from bispec_result.c.
 */
#include <complex.h>
#include <fftw3.h>

#include "base/bigmem.h"
#include "bispec_int.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>


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
void *bispec_alloc(bispec *b, size_t bytes)
{
    size_t sz = (bytes + 63) / 64 * 64;
    void *p = aligned_alloc(64, sz ? sz : 64);
    if (p) {
        memset(p, 0, sz ? sz : 64);
        b->mem += bytes;
    }
    return p;
}

/* The same without the zeroing, for a buffer its maker writes whole (the
 * frame slots and their spectra). */
void *bispec_alloc_unzeroed(bispec *b, size_t bytes)
{
    size_t sz = (bytes + 63) / 64 * 64;
    void *p = aligned_alloc(64, sz ? sz : 64);
    if (p)
        b->mem += bytes;
    return p;
}

/* A big zeroed buffer (the accumulators, the batch buffer, the triple
 * list): fresh anonymous pages, 2 MB aligned, with transparent huge pages
 * asked for when huge (bigmem.h).  The kernel zeroes them when first
 * touched, which the threads that fill them do, each on its own range,
 * instead of a serial memset here; and huge pages spare the TLB the batch
 * buffer's scattered u1 reads (one 2 MB entry instead of 512).  Counted
 * in b->mem; handed back by the pool's threads and unmapped by
 * bispec_free. */
void *bispec_alloc_big(bispec *b, size_t bytes, int huge)
{
    if (b->nmap == BISPEC_NMAP)
        return NULL;
    void *p = bigmem_alloc(bytes, huge);
    if (!p)
        return NULL;
    b->map[b->nmap] = p;
    b->maplen[b->nmap++] = bytes;
    b->mem += bytes;
    return p;
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
    if (o->simd < BISPEC_SIMD_AUTO || o->simd > BISPEC_SIMD_AVX512 || !bispec_simd_has(o->simd))
        return sl_seterr(err, SL_EINVAL, "bispec: this CPU cannot run the %s kernel "
                         "(simd %d)", bispec_simd_name(o->simd), o->simd);
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

int bispec_batch_frames(int nf, size_t batch_bytes)
{
    size_t cap = batch_bytes ? batch_bytes : BISPEC_BATCH_BYTES;
    int kb = BISPEC_BATCH_MAX;
    while (kb > BISPEC_LANES && (size_t)nf * 2 * 2 * kb * sizeof(float) > cap)
        kb /= 2;
    return kb;
}

/* Every buffer, from one table: what it is, its size, whether this
 * configuration needs it.  bispec_alloc's 64-byte alignment also suits FFTW's
 * SIMD codelets. */
static int alloc_buffers(bispec *b)
{
    const bispec_opts *o = &b->o;
    size_t nt = (size_t)b->nt, nf = (size_t)b->nf, npx = (size_t)b->w * b->h;
    size_t nh = (size_t)b->h * b->wc, asz = o->acc_float ? sizeof(float) : sizeof(double);
    int snr = o->weight == PHASOR_WEIGHT_SNR || o->refine_weight == PHASOR_WEIGHT_SNR;
    int ph = o->adu_per_photon > 0, win = o->window != POWSPEC_WIN_NONE;
    void *acc = NULL, *acc2 = NULL;
    /* The frame slots and their spectra, each 64-byte aligned as the
     * FFT plans were made for (the first slot). */
    size_t ns = BISPEC_SLOTS;
    b->npad = (npx + 15) / 16 * 16;
    b->nhp = (nh + 7) / 8 * 8;
    if (!(acc = bispec_alloc_big(b, 2 * nt * asz, 1)) ||
        (snr && !(acc2 = bispec_alloc_big(b, nt * asz, 1))) ||
        !(b->fb = bispec_alloc_big(b, nf * 2 * 2 * (size_t)b->kb * sizeof(float), 1)))
        return SL_ENOMEM;
    if (o->acc_float)
        b->accf = acc, b->acc2f = acc2;
    else
        b->accd = acc, b->acc2d = acc2;
    /* The slots and their spectra (raw: each frame and transform is
     * written whole before it is read) are first touched by the threads
     * that fill them: a serial memset of ~20 MB at 512^2 cost ~24 ms of
     * one thread here, fresh pages being slow to fault on this VM. */
    const struct { void **slot; size_t bytes; int want, raw; } bufs[] = {
        {(void **)&b->psum, nf * sizeof(double), 1, 0},
        {(void **)&b->xsum, 2 * nf * sizeof(double), ph, 0},
        {(void **)&b->phi, nf * sizeof(double), 1, 0},
        {(void **)&b->known, nf, 1, 0},
        {(void **)&b->work, phasor_work_doubles((int)nf) * sizeof(double), 1, 0},
        {(void **)&b->win, npx * sizeof(float), win, 0},
        {(void **)&b->in, ns * b->npad * sizeof(float), 1, 1},
        {(void **)&b->out, ns * b->nhp * sizeof(fftwf_complex), 1, 1},
        {(void **)&b->in2, ns * b->npad * sizeof(float), ph && win, 1},
        {(void **)&b->out2, ns * b->nhp * sizeof(fftwf_complex), ph && win, 1},
        {(void **)&b->cin, nh * sizeof(fftw_complex), 1, 0},
        {(void **)&b->cout, npx * sizeof(double), 1, 0}};
    for (size_t i = 0; i < sizeof bufs / sizeof bufs[0]; i++)
        if (bufs[i].want &&
            !(*bufs[i].slot = bufs[i].raw ? bispec_alloc_unzeroed(b, bufs[i].bytes)
                                          : bispec_alloc(b, bufs[i].bytes)))
            return SL_ENOMEM;
    return (b->pipe = bispec_pipe_new(b)) ? SL_OK : SL_ENOMEM;
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
        if (!(b->w2ft = bispec_alloc(b, 2 * (size_t)nf * sizeof(double))))
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
    b->simd = o->simd ? o->simd : bispec_simd_best();
    if (!(b->pool = tpool_new(b->nthr, err))) {
        rc = SL_EINVAL; /* the message is tpool_new's */
        goto fail;
    }
    if ((rc = bispec_build_graph(b, err)) != SL_OK)
        goto fail;
    b->kb = bispec_batch_frames(b->nf, o->batch_bytes);
    if ((rc = alloc_buffers(b)) != SL_OK ||
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

/* tpool job: thread tid hands its share of each big buffer back
 * (bigmem.h: one thread freeing ~450 MB at 512^2 spent ~20 ms alone at
 * the end of a run). */
static void release_job(void *ctx, int tid, int n)
{
    bispec *b = ctx;
    for (int i = 0; i < b->nmap; i++)
        bigmem_release_share(b->map[i], b->maplen[i], tid, n);
}

void bispec_free(bispec *b)
{
    if (!b)
        return;
    slotpipe_free(b->pipe); /* a job in flight uses the slots and fb */
    if (b->pool && tpool_size(b->pool) > 1)
        tpool_run(b->pool, release_job, b);
    if (b->plan)
        fftwf_destroy_plan(b->plan);
    if (b->plan2)
        fftwf_destroy_plan(b->plan2);
    if (b->iplan)
        fftw_destroy_plan(b->iplan);
    tpool_free(b->pool);
    for (int i = 0; i < b->nmap; i++)
        bigmem_free(b->map[i], b->maplen[i]);
    void *bufs[] = {b->fp,   b->fq,    b->ubase, b->seed,  b->lut,  b->doff,
                    b->dleg, b->tstart, b->kunit, b->order, b->sorder, b->tbeg, b->drow, b->dfirst, b->psum,  b->xsum, b->phi,
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
int bispec_batch(const bispec *b) { return b ? b->kb : 0; }
int bispec_simd(const bispec *b) { return b ? b->simd : 0; }
