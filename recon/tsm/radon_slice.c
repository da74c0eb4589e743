/* radon_slice.c - see radon.h: projection spectra as slices of one 2-D FFT
 * (Fourier-slice theorem) and the gridding adjoint used by the FBP.
 *
 * Non-uniform FFT details (radon_slices / radon_fbp_slices).  The frame is
 * placed on an ng x ng grid (ng >= sigma*max(w,h)) with its centre at index
 * (0, 0), wrapped, so that the spectrum of a centred object is smooth and
 * its phase refers to the centre.  A slice sample at frequency rho*n is the
 * point k = rho*ng*n in grid bins; it is sum_m phi(k - m) G(m) over the
 * kw x kw grid points nearest k, phi the Kaiser-Bessel kernel with Beatty's
 * shape beta(kw, sigma), G the FFT of frame/C, and C(X) = integral phi(u)
 * cos(2 pi u X / ng) du the kernel's transform (closed form, radon_new).
 * Only the half plane kx >= 0 is computed (r2c): a sample with
 * cos(theta) < 0 is taken at -k and conjugated.
 *
 * Forward layout (radon_slices).  The row transforms write their output
 * column-major (one column per kx, contiguous in ky), so the column
 * transforms run on contiguous data (measured 0.17 against 0.24 ms per
 * 300^2 grid for the row-major layout, which FFTW serves by copying); the
 * column stride ld = ng + 2 pad also keeps power-of-two grids off cache-set
 * conflicts.  The frame rows are multiplied by (-1)^(y - h/2), which moves
 * ky = 0 to the middle of each column, and the spectrum is padded by
 * pad = kw columns and rows with its periodic and Hermitian copies
 * (G(kx, ky) = G(kx, ky + ng) = conj G(-kx, -ky)), so every sample's kw x
 * kw taps are one block: no wrap, no mirror, no branch per sample.  The
 * adjoint (radon_fbp_slices) keeps the row-major half plane gspec.
 * Scratch of the forward path lives in a radon_ws, one per thread; the
 * plans and tables are shared read-only (FFTW's new-array execute).
 * One image on a pool (radon_slices, radon_fbp_slices): the same tasks
 * (row chunks, column chunks, pads, samples; the gridding by column
 * chunk, radon_batch.c) claimed by its threads in one job.
 */
#include "radon_int.h"

#include <fftw3.h>
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* ---- Fourier slices: forward scratch ------------------------------------ */

static size_t ws_grid_n(const radon *r) { return (size_t)r->h * r->ng; }
static size_t ws_rows_n(const radon *r) { return (size_t)(r->ng / 2 + 1) * r->ld * 2; }
static size_t ws_spec_n(const radon *r)
{
    return (size_t)(r->ng / 2 + 1 + 2 * r->spad) * r->ld * 2;
}

radon_ws *radon_ws_new(const radon *r, sl_err *err)
{
    radon_ws *ws = calloc(1, sizeof *ws);
    int ok = ws != NULL;
    if (ws) {
        ws->grid = radon_alloc(ws_grid_n(r) * sizeof(float), 1, &ok);
        ws->rows = radon_alloc(ws_rows_n(r) * sizeof(float), 1, &ok);
        ws->spec = radon_alloc(ws_spec_n(r) * sizeof(float), 1, &ok);
    }
    if (!ok) {
        sl_seterr(err, SL_ENOMEM, "radon_ws_new: out of memory (grid %d)", r->ng);
        radon_ws_free(ws);
        return NULL;
    }
    radon_ws_clear(r, ws);
    return ws;
}

void radon_ws_free(radon_ws *ws)
{
    if (!ws)
        return;
    fftwf_free(ws->grid);
    fftwf_free(ws->rows);
    fftwf_free(ws->spec);
    free(ws->sp_scratch);
    free(ws->proj);
    fftwf_free(ws->p_in);
    fftwf_free(ws->p_spec);
    free(ws);
}

/* The zero parts of grid and rows are never written by a transform. */
void radon_ws_clear(const radon *r, radon_ws *ws)
{
    memset(ws->grid, 0, ws_grid_n(r) * sizeof(float));
    memset(ws->rows, 0, ws_rows_n(r) * sizeof(float));
    memset(ws->spec, 0, ws_spec_n(r) * sizeof(float));
}

/* ---- Fourier slices ----------------------------------------------------- */

/* dst[i] = src[i] dx[i] dy, in blocks of 8 (a constant trip count: the
 * compiler vectorises it at -O2). */
static void scale_row(float *restrict dst, const float *restrict src,
                      const float *restrict dx, float dy, int n)
{
    int i = 0;
    for (; i + 8 <= n; i += 8)
        for (int k = 0; k < 8; k++)
            dst[i + k] = src[i + k] * dx[i + k] * dy;
    for (; i < n; i++)
        dst[i] = src[i] * dx[i] * dy;
}

/* Frame rows y0..y1-1 / C into their grid rows, column x at grid column
 * x - w/2 (wrapped: the right half of the frame first, then the left half
 * at the end); the row factor rowf also carries the (-1)^(y - h/2) that
 * centres ky. */
static void load_rows(const radon *r, float *grid, const float *img, int y0, int y1)
{
    int ng = r->ng, w = r->w, xa = w / 2;
    for (int y = y0; y < y1; y++) {
        float *row = grid + (size_t)y * ng;
        const float *src = img + (size_t)y * w;
        scale_row(row, src + xa, r->deap_x + xa, r->rowf[y], w - xa);
        scale_row(row + ng - xa, src, r->deap_x, r->rowf[y], xa);
    }
}

/* Column c of the padded spectrum (kx = c - pad), storage index P = ky +
 * ng/2 + pad. */
static float *spec_col(const radon *r, float *spec, int kx)
{
    return spec + 2 * (size_t)(kx + r->spad) * r->ld;
}

/* The 2-D FFT into the padded, centred spectrum (Forward layout) and its
 * pads, as tasks: row chunks (fwd_rows), column chunks with their pad
 * rows, pad rows each end of every column (period ng in ky: fwd_cols),
 * then the pad columns each side (kx = -m and ng/2 + m, Hermitian images
 * of kx = m and ng/2 - m, with ky reversed: pad_sides).  Cost: the FFT,
 * plus (nh + 2 pad) 2 pad copies. */
static int row_tasks(const radon *r) { return r->fr_a.nchunk + r->fr_b.nchunk; }

/* Row task t: block a's chunks, then block b's (frame rows y >= h/2 are
 * grid rows h/2.., transformed to ky rows 0..; rows y < h/2 to ng - h/2..). */
static void fwd_rows(const radon *r, radon_ws *ws, const float *img, int t)
{
    int ha = r->h / 2, ng = r->ng, in_a = t < r->fr_a.nchunk;
    int c = in_a ? t : t - r->fr_a.nchunk, y0 = (in_a ? ha : 0) + c * RADON_CHUNK;
    int y1 = y0 + RADON_CHUNK, end = in_a ? r->h : ha;
    load_rows(r, ws->grid, img, y0, y1 < end ? y1 : end);
    if (in_a)
        radon_batch_run(&r->fr_a, c, ws->grid + (size_t)ha * ng, ws->rows);
    else
        radon_batch_run(&r->fr_b, c, ws->grid, ws->rows + 2 * (size_t)(ng - ha));
}

static void fwd_cols(const radon *r, radon_ws *ws, int c)
{
    int ng = r->ng, nh = ng / 2 + 1, pad = r->spad;
    radon_batch_run(&r->fc, c, ws->rows, ws->spec + 2 * ((size_t)pad * r->ld + pad));
    size_t pb = 2 * (size_t)pad * sizeof(float);
    int k1 = (c + 1) * RADON_CHUNK < nh ? (c + 1) * RADON_CHUNK : nh;
    for (int kx = c * RADON_CHUNK; kx < k1; kx++) {
        float *col = spec_col(r, ws->spec, kx);
        memcpy(col, col + 2 * ng, pb);
        memcpy(col + 2 * (ng + pad), col + 2 * pad, pb);
    }
}

static void pad_sides(const radon *r, float *spec)
{
    int ng = r->ng, pad = r->spad;
    for (int m = 1; m <= pad; m++)
        for (int side = 0; side < 2; side++) {
            const float *src = spec_col(r, spec, side ? ng / 2 - m : m);
            float *dst = spec_col(r, spec, side ? ng / 2 + m : -m);
            for (int P = 0; P < ng + 2 * pad; P++) {
                int q = ng - (P - pad);   /* ky -> -ky, modulo ng */
                q += q >= ng ? -ng : q < 0 ? ng : 0;
                dst[2 * P] = src[2 * (q + pad)];
                dst[2 * P + 1] = -src[2 * (q + pad) + 1];
            }
        }
}

/* One slice sample: kw columns of kw contiguous taps (interleaved complex),
 * summed first across the columns with weight wx (vertical: 2 kw floats,
 * kw/2 vectors of 4 kept in registers), then along ky with wy.  KW a
 * compile-time constant (even) lets the compiler unroll. */
typedef float v4f __attribute__((vector_size(16)));

static inline void sample_taps(const float *restrict g, size_t ld, const float *wx,
                               const float *wy, int KW, float *re, float *im)
{
    v4f col[4] = {{0}, {0}, {0}, {0}};
    for (int a = 0; a < KW; a++) {
        const float *c = g + 2 * (size_t)a * ld;
        v4f w = {wx[a], wx[a], wx[a], wx[a]};
        for (int v = 0; v < KW / 2; v++) {
            v4f x;
            memcpy(&x, c + 4 * v, sizeof x);
            col[v] += w * x;
        }
    }
    v4f acc = {0, 0, 0, 0};
    for (int v = 0; v < KW / 2; v++) {
        v4f w = {wy[2 * v], wy[2 * v], wy[2 * v + 1], wy[2 * v + 1]};
        acc += w * col[v];
    }
    *re = acc[0] + acc[2], *im = acc[1] + acc[3];
}

/* Any kw (odd ones too), scalar. */
static void sample_taps_any(const float *g, size_t ld, const float *wx, const float *wy,
                            int kw, float *re, float *im)
{
    float ar = 0, ai = 0;
    for (int a = 0; a < kw; a++) {
        const float *c = g + 2 * (size_t)a * ld;
        float sr = 0, si = 0;
        for (int b = 0; b < kw; b++)
            sr += wy[b] * c[2 * b], si += wy[b] * c[2 * b + 1];
        ar += wx[a] * sr, ai += wx[a] * si;
    }
    *re = ar, *im = ai;
}

/* The samples in order of first tap column: a sample reads kw columns of
 * the padded spectrum, so in this order the columns in use stay in cache
 * (kw (ng + 2 pad) 8 bytes, 33 kB at 512^2) and each is loaded once,
 * where in angle order every line from the centre out swept the spectrum
 * (4 MB at 512^2, beyond L2): the taps were 8 % of a tsm-fourier run's
 * CPU at 512^2 on one thread and half as much again on two.  Each
 * sample's arithmetic is unchanged, so are its bits.  A counting sort,
 * stable: O(samples). */
int radon_order_samples(radon *r)
{
    size_t nsamp = (size_t)r->nang * r->nf, kw = (size_t)r->kw;
    int lo = r->tx0[0], hi = r->tx0[0];
    for (size_t s = 1; s < nsamp; s++) {
        lo = r->tx0[s] < lo ? r->tx0[s] : lo;
        hi = r->tx0[s] > hi ? r->tx0[s] : hi;
    }
    size_t nkey = (size_t)(hi - lo) + 2;
    int *cnt = calloc(nkey, sizeof *cnt), ok = cnt != NULL;
    int *tx0 = radon_alloc(nsamp * sizeof *tx0, 0, &ok);
    int *ty0 = radon_alloc(nsamp * sizeof *ty0, 0, &ok);
    unsigned char *tconj = radon_alloc(nsamp, 0, &ok);
    float *twx = radon_alloc(nsamp * kw * sizeof *twx, 0, &ok);
    float *twy = radon_alloc(nsamp * kw * sizeof *twy, 0, &ok);
    r->tord = radon_alloc(nsamp * sizeof *r->tord, 0, &ok);
    r->tpos = radon_alloc(nsamp * sizeof *r->tpos, 0, &ok);
    if (ok) {
        for (size_t s = 0; s < nsamp; s++)
            cnt[r->tx0[s] - lo + 1]++;
        for (size_t k = 1; k < nkey; k++)
            cnt[k] += cnt[k - 1];
        for (size_t s = 0; s < nsamp; s++) {
            size_t i = (size_t)cnt[r->tx0[s] - lo]++;
            r->tord[i] = (int)s, r->tpos[s] = (int)i;
            tx0[i] = r->tx0[s], ty0[i] = r->ty0[s], tconj[i] = r->tconj[s];
            memcpy(twx + i * kw, r->twx + s * kw, kw * sizeof *twx);
            memcpy(twy + i * kw, r->twy + s * kw, kw * sizeof *twy);
        }
        void *t;
        t = r->tx0, r->tx0 = tx0, tx0 = t;
        t = r->ty0, r->ty0 = ty0, ty0 = t;
        t = r->tconj, r->tconj = tconj, tconj = t;
        t = r->twx, r->twx = twx, twx = t;
        t = r->twy, r->twy = twy, twy = t;
    }
    free(cnt), free(tx0), free(ty0), free(tconj), free(twx), free(twy);
    return ok ? SL_OK : SL_ENOMEM;
}

/* The samples i0..i1-1 (table rows) from the padded spectrum. */
static void fwd_taps(const radon *r, const float *sp, float complex *spec, size_t i0, size_t i1)
{
    int kw = r->kw, c0 = r->ng / 2 + r->spad;
    size_t ld = r->ld;
    for (size_t i = i0; i < i1; i++) {
        const float *wx = r->twx + i * kw, *wy = r->twy + i * kw;
        const float *g = spec_col(r, (float *)sp, r->tx0[i]) + 2 * (size_t)(r->ty0[i] + c0);
        float re, im;
        if (kw == 4)
            sample_taps(g, ld, wx, wy, 4, &re, &im);
        else if (kw == 6)
            sample_taps(g, ld, wx, wy, 6, &re, &im);
        else if (kw == 8)
            sample_taps(g, ld, wx, wy, 8, &re, &im);
        else
            sample_taps_any(g, ld, wx, wy, kw, &re, &im);
        spec[r->tord[i]] = r->tconj[i] ? CMPLXF(re, -im) : CMPLXF(re, im);
    }
}

int radon_slices_ws(const radon *r, radon_ws *ws, const float *img, float complex *spec)
{
    for (int t = 0; t < row_tasks(r); t++)
        fwd_rows(r, ws, img, t);
    for (int c = 0; c < r->fc.nchunk; c++)
        fwd_cols(r, ws, c);
    pad_sides(r, ws->spec);
    fwd_taps(r, ws->spec, spec, 0, (size_t)r->nang * r->nf);
    return SL_OK;
}

/* One image's transform on the pool, as one job: the same tasks as the
 * serial loops, in phases (rows, columns, ...) claimed in order from one
 * counter; a thread that claims a task of phase p first waits for phase
 * p - 1's tasks to finish (spinning: they are running on the other
 * threads).  Each task computes its elements whole, so the bits are the
 * serial ones.  One wake-up per call: a job per phase cost ~30 us of
 * wake-up each on this VM, as much as the work of a 200^2 slicing. */
enum { TAPS_CLAIM = 1024, MAX_PHASES = 4 };
typedef struct slice_job slice_job;
typedef void (*slice_task)(slice_job *j, int t);
struct slice_job {
    radon *r;
    const float *img;
    float complex *spec;
    const float complex *cspec;
    float *out;
    int nphase, end[MAX_PHASES];   /* tasks before the end of each phase */
    slice_task task[MAX_PHASES];
    atomic_int next, done[MAX_PHASES];
};

static void phased_job(void *ctx, int tid, int n)
{
    slice_job *j = ctx;
    (void)tid, (void)n;
    for (int t; (t = atomic_fetch_add(&j->next, 1)) < j->end[j->nphase - 1];) {
        int p = 0, spins = 0;
        while (t >= j->end[p])
            p++;
        int first = p ? j->end[p - 1] : 0, before = p > 1 ? j->end[p - 2] : 0;
        while (p && atomic_load_explicit(&j->done[p - 1], memory_order_acquire) <
                        first - before)
            tpool_pause(&spins);
        j->task[p](j, t - first);
        atomic_fetch_add_explicit(&j->done[p], 1, memory_order_release);
    }
}

/* Add a phase of n tasks. */
static void add_phase(slice_job *j, slice_task fn, int n)
{
    int p = j->nphase++;
    j->task[p] = fn;
    j->end[p] = (p ? j->end[p - 1] : 0) + n;
}

static void run_phases(slice_job *j)
{
    if (j->r->pool)
        tpool_run(j->r->pool, phased_job, j);
    else
        phased_job(j, 0, 1);
}

static void rows_task(slice_job *j, int t) { fwd_rows(j->r, j->r->ws, j->img, t); }
static void cols_task(slice_job *j, int c) { fwd_cols(j->r, j->r->ws, c); }
static void sides_task(slice_job *j, int t) { (void)t, pad_sides(j->r, j->r->ws->spec); }

static void taps_task(slice_job *j, int t)
{
    size_t nsamp = (size_t)j->r->nang * j->r->nf, i0 = (size_t)t * TAPS_CLAIM;
    fwd_taps(j->r, j->r->ws->spec, j->spec, i0,
             i0 + TAPS_CLAIM < nsamp ? i0 + TAPS_CLAIM : nsamp);
}

int radon_slices(radon *r, const float *img, float complex *spec)
{
    if (!r->ws && !(r->ws = radon_ws_new(r, &r->err)))
        return SL_ENOMEM;
    if (!r->pool || tpool_size(r->pool) < 2)
        return radon_slices_ws(r, r->ws, img, spec);
    slice_job j = {.r = r, .img = img, .spec = spec};
    size_t nsamp = (size_t)r->nang * r->nf;
    add_phase(&j, rows_task, row_tasks(r));
    add_phase(&j, cols_task, r->fc.nchunk);
    add_phase(&j, sides_task, 1);
    add_phase(&j, taps_task, (int)((nsamp + TAPS_CLAIM - 1) / TAPS_CLAIM));
    run_phases(&j);
    return SL_OK;
}

/* An interior sample's kw x kw taps (even kw <= 8), two taps (one
 * complex pair each) per vector: element by element the scalar loop's
 * operations, wgt = wx[a] wy[b], then wgt v, then the add, so the bits
 * are the scalar path's; the baseline build runs the scalar loop one
 * float at a time (the gridding was ~0.8 ms of each FBP at 200^2, all of
 * it serial). */
static inline void spread_row_vec(float *gspec, int ng, int nh, int x0, int y0,
                                  const float *wx, const float *wy, int kw, float vr, float vi)
{
    v4f wxx[4], vv = {vr, vi, vr, vi};
    for (int v = 0; v < kw / 2; v++)
        wxx[v] = (v4f){wx[2 * v], wx[2 * v], wx[2 * v + 1], wx[2 * v + 1]};
    for (int b = 0; b < kw; b++) {
        int y = y0 + b;   /* |ky| <= ng/2 + kw: one period at most */
        y += y < 0 ? ng : y >= ng ? -ng : 0;
        float *g = gspec + 2 * ((size_t)y * nh + x0);
        v4f wb = {wy[b], wy[b], wy[b], wy[b]};
        for (int v = 0; v < kw / 2; v++) {
            v4f x, t = wxx[v] * wb;
            memcpy(&x, g + 4 * v, sizeof x);
            x += t * vv;
            memcpy(g + 4 * v, &x, sizeof x);
        }
    }
}

/* Add v at k and conj(v) at -k (the Hermitian image of the sample) to the
 * stored half plane, for every tap in columns c0..c1-1; a tap outside the
 * half plane is implied by its mirror, which the -k copy adds.  Within
 * one column chunk the taps go in the serial loop's order (b, a, then the
 * mirror), so every cell's sum is the serial one. */
static void grid_spread(radon *r, size_t s, float vr, float vi, int c0, int c1)
{
    int kw = r->kw, ng = r->ng, nh = ng / 2 + 1;
    size_t i = (size_t)r->tpos[s];
    const float *wx = r->twx + i * kw, *wy = r->twy + i * kw;
    int x0 = r->tx0[i], y0 = r->ty0[i];
    if (r->tconj[i])
        vi = -vi;
    if (x0 >= 1 && x0 + kw <= nh - 1) {   /* no tap on kx = 0 or ng/2: no mirror */
        if (x0 >= c0 && x0 + kw <= c1 && (kw == 4 || kw == 6 || kw == 8)) {
            if (kw == 4)   /* constants: unrolled */
                spread_row_vec(r->gspec, ng, nh, x0, y0, wx, wy, 4, vr, vi);
            else if (kw == 6)
                spread_row_vec(r->gspec, ng, nh, x0, y0, wx, wy, 6, vr, vi);
            else
                spread_row_vec(r->gspec, ng, nh, x0, y0, wx, wy, 8, vr, vi);
            return;
        }
        int a0 = c0 > x0 ? c0 - x0 : 0, a1 = c1 - x0 < kw ? c1 - x0 : kw;
        for (int b = 0; b < kw; b++) {
            int y = y0 + b;   /* |ky| <= ng/2 + kw: one period at most */
            y += y < 0 ? ng : y >= ng ? -ng : 0;
            float *g = r->gspec + 2 * ((size_t)y * nh + x0);
            for (int a = a0; a < a1; a++) {
                float wgt = wx[a] * wy[b];
                g[2 * a] += wgt * vr;
                g[2 * a + 1] += wgt * vi;
            }
        }
        return;
    }
    for (int b = 0; b < kw; b++)
        for (int a = 0; a < kw; a++) {
            float wgt = wx[a] * wy[b];
            int mx = radon_wrap(x0 + a, ng), my = radon_wrap(y0 + b, ng);
            if (mx < nh && mx >= c0 && mx < c1) {
                r->gspec[2 * ((size_t)my * nh + mx)] += wgt * vr;
                r->gspec[2 * ((size_t)my * nh + mx) + 1] += wgt * vi;
            }
            int nx = (ng - mx) % ng, ny = (ng - my) % ng;
            if (nx < nh && nx >= c0 && nx < c1) {
                r->gspec[2 * ((size_t)ny * nh + nx)] += wgt * vr;
                r->gspec[2 * ((size_t)ny * nh + nx) + 1] -= wgt * vi;
            }
        }
}

/* Column chunk c of the gridding: its columns zeroed, its samples
 * spread, then its column transforms. */
static void fbp_cols(radon *r, const float complex *spec, int c)
{
    int ng = r->ng, nh = ng / 2 + 1, c0 = c * RADON_CHUNK;
    int c1 = c0 + RADON_CHUNK < nh ? c0 + RADON_CHUNK : nh;
    for (int y = 0; y < ng; y++)
        memset(r->gspec + 2 * ((size_t)y * nh + c0), 0, 2 * (size_t)(c1 - c0) * sizeof(float));
    for (int k = r->goff[c]; k < r->goff[c + 1]; k++) {
        size_t s = (size_t)r->gsamp[k];
        float d = r->dens[r->gj[k]];
        grid_spread(r, s, d * crealf(spec[s]), d * cimagf(spec[s]), c0, c1);
    }
    radon_batch_run(&r->ic, c, r->gspec, r->gspec);
}

/* Row task t (block a's chunks, then block b's): the row transforms, then
 * those frame rows deapodised into img (zero outside the disc). */
static void fbp_rows(radon *r, float *img, int t)
{
    int ng = r->ng, nh = ng / 2 + 1, ha = r->h / 2, xa = r->w / 2;
    int in_a = t < r->ir_a.nchunk, c = in_a ? t : t - r->ir_a.nchunk;
    int y0 = (in_a ? ha : 0) + c * RADON_CHUNK, y1 = y0 + RADON_CHUNK, end = in_a ? r->h : ha;
    if (in_a)
        radon_batch_run(&r->ir_a, c, r->gspec, r->grid_out + (size_t)ha * ng);
    else
        radon_batch_run(&r->ir_b, c, r->gspec + 2 * (size_t)(ng - ha) * nh, r->grid_out);
    for (int y = y0; y < (y1 < end ? y1 : end); y++) {
        const float *row = r->grid_out + (size_t)y * ng;
        float dy = r->deap_y[y], *out = img + (size_t)y * r->w;
        memset(out, 0, (size_t)r->w * sizeof *out);
        for (int x = r->xlo[y]; x <= r->xhi[y]; x++)
            out[x] = row[x >= xa ? x - xa : ng - xa + x] * r->deap_x[x] * dy;
    }
}

static void fbp_cols_task(slice_job *j, int c) { fbp_cols(j->r, j->cspec, c); }
static void fbp_rows_task(slice_job *j, int t) { fbp_rows(j->r, j->out, t); }

int radon_fbp_slices(radon *r, const float complex *spec, float *img)
{
    slice_job j = {.r = r, .cspec = spec, .out = img};
    add_phase(&j, fbp_cols_task, r->ic.nchunk);
    add_phase(&j, fbp_rows_task, r->ir_a.nchunk + r->ir_b.nchunk);
    run_phases(&j);
    return SL_OK;
}
