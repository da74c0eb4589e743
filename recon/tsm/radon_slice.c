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
 */
#include "radon_int.h"

#include <fftw3.h>
#include <math.h>
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

/* Frame / C into the grid rows, column x at grid column x - w/2 (wrapped:
 * the right half of the frame first, then the left half at the end); the
 * row factor rowf also carries the (-1)^(y - h/2) that centres ky. */
static void grid_load(const radon *r, float *grid, const float *img)
{
    int ng = r->ng, w = r->w, xa = w / 2;
    for (int y = 0; y < r->h; y++) {
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

/* 2-D FFT into the padded, centred spectrum (Forward layout), then its
 * pads: pad rows each end of every column (period ng in ky) and pad
 * columns each side (kx = -m and ng/2 + m, Hermitian images of kx = m and
 * ng/2 - m, with ky reversed).  Cost: the FFT, plus (nh + 2 pad) 2 pad
 * copies. */
static void grid_fft(const radon *r, radon_ws *ws)
{
    int ng = r->ng, nh = ng / 2 + 1, pad = r->spad, ha = r->h / 2;
    fftwf_complex *rows = (fftwf_complex *)ws->rows;
    fftwf_execute_dft_r2c(r->rows_a, ws->grid + (size_t)ha * ng, rows);
    if (ha)
        fftwf_execute_dft_r2c(r->rows_b, ws->grid, rows + (ng - ha));
    fftwf_execute_dft(r->cols_fwd, rows,
                      (fftwf_complex *)ws->spec + (size_t)pad * r->ld + pad);
    size_t pb = 2 * (size_t)pad * sizeof(float);
    for (int kx = 0; kx < nh; kx++) {
        float *col = spec_col(r, ws->spec, kx);
        memcpy(col, col + 2 * ng, pb);
        memcpy(col + 2 * (ng + pad), col + 2 * pad, pb);
    }
    for (int m = 1; m <= pad; m++)
        for (int side = 0; side < 2; side++) {
            const float *src = spec_col(r, ws->spec, side ? ng / 2 - m : m);
            float *dst = spec_col(r, ws->spec, side ? ng / 2 + m : -m);
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

int radon_slices_ws(const radon *r, radon_ws *ws, const float *img, float complex *spec)
{
    grid_load(r, ws->grid, img);
    grid_fft(r, ws);
    int kw = r->kw, c0 = r->ng / 2 + r->spad;
    size_t ld = r->ld, nsamp = (size_t)r->nang * r->nf;
    for (size_t i = 0; i < nsamp; i++) {
        const float *wx = r->twx + i * kw, *wy = r->twy + i * kw;
        const float *g = spec_col(r, ws->spec, r->tx0[i]) + 2 * (size_t)(r->ty0[i] + c0);
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
    return SL_OK;
}

int radon_slices(radon *r, const float *img, float complex *spec)
{
    if (!r->ws && !(r->ws = radon_ws_new(r, &r->err)))
        return SL_ENOMEM;
    return radon_slices_ws(r, r->ws, img, spec);
}

/* Add v at k and conj(v) at -k (the Hermitian image of the sample) to the
 * stored half plane, for every tap; a tap outside the half plane is implied
 * by its mirror, which the -k copy adds. */
static void grid_spread(radon *r, size_t s, float vr, float vi)
{
    int kw = r->kw, ng = r->ng, nh = ng / 2 + 1;
    size_t i = (size_t)r->tpos[s];
    const float *wx = r->twx + i * kw, *wy = r->twy + i * kw;
    int x0 = r->tx0[i], y0 = r->ty0[i];
    if (r->tconj[i])
        vi = -vi;
    if (x0 >= 1 && x0 + kw <= nh - 1) {   /* no tap on kx = 0 or ng/2 */
        for (int b = 0; b < kw; b++) {
            float *g = r->gspec + 2 * ((size_t)radon_wrap(y0 + b, ng) * nh + x0);
            for (int a = 0; a < kw; a++) {
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
            if (mx < nh) {
                r->gspec[2 * ((size_t)my * nh + mx)] += wgt * vr;
                r->gspec[2 * ((size_t)my * nh + mx) + 1] += wgt * vi;
            }
            int nx = (ng - mx) % ng, ny = (ng - my) % ng;
            if (nx < nh) {
                r->gspec[2 * ((size_t)ny * nh + nx)] += wgt * vr;
                r->gspec[2 * ((size_t)ny * nh + nx) + 1] -= wgt * vi;
            }
        }
}

int radon_fbp_slices(radon *r, const float complex *spec, float *img)
{
    int ng = r->ng;
    memset(r->gspec, 0, (size_t)ng * (ng / 2 + 1) * 2 * sizeof(float));
    for (int k = 0; k < r->nang; k++)
        for (int j = 0; j < r->nf; j++) {
            size_t s = (size_t)k * r->nf + j;
            float d = r->dens[j];
            grid_spread(r, s, d * crealf(spec[s]), d * cimagf(spec[s]));
        }
    fftwf_execute(r->cols_inv);
    fftwf_execute(r->irows_a);
    if (r->h / 2)
        fftwf_execute(r->irows_b);
    memset(img, 0, (size_t)r->w * r->h * sizeof *img);
    int xa = r->w / 2;
    for (int y = 0; y < r->h; y++) {
        const float *row = r->grid_out + (size_t)y * ng;
        float dy = r->deap_y[y];
        for (int x = r->xlo[y]; x <= r->xhi[y]; x++)
            img[(size_t)y * r->w + x] = row[x >= xa ? x - xa : ng - xa + x] * r->deap_x[x] * dy;
    }
    return SL_OK;
}

