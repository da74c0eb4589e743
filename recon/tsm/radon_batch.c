/* radon_batch.c - the radon handle's FFT plans as batches in chunks
 * (radon_int.h, radon_batch), and the gridding's sample lists per column
 * chunk: what lets one image's Fourier slices and gridding FBP run on
 * every thread of a pool (radon_slice.c); and radon_spec_to_proj, by
 * angles on the pool (each thread with its own 1-D scratch).
 *
 * Why chunks: a single image's transforms (the reprojection rounds'
 * slices and FBPs, the result's FBP) ran on one thread while the other
 * waited: ~35 ms of a 512^2 tsm-fourier run.  A plan for RADON_CHUNK
 * transforms runs any chunk on any thread; the chunk and tail plans cost
 * ~0.02 ms each from wisdom, and running a batch chunk by chunk costs
 * what the whole batch did (measured at 400 and 1024 grids).
 */
#include "radon_int.h"

#include <complex.h>
#include <fftw3.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

/* Floats per element of the kind's input and output. */
static int in_floats(radon_kind k) { return k == RADON_R2C ? 1 : 2; }
static int out_floats(radon_kind k) { return k == RADON_C2R ? 1 : 2; }

static fftwf_plan plan_one(radon_kind kind, int n, int howmany, float *in, int is, int idist,
                           float *out, int os, int odist, unsigned flags)
{
    fftwf_complex *ci = (fftwf_complex *)in, *co = (fftwf_complex *)out;
    switch (kind) {
    case RADON_R2C:
        return fftwf_plan_many_dft_r2c(1, &n, howmany, in, NULL, is, idist, co, NULL, os,
                                       odist, flags);
    case RADON_C2R:
        return fftwf_plan_many_dft_c2r(1, &n, howmany, ci, NULL, is, idist, out, NULL, os,
                                       odist, flags);
    default:
        return fftwf_plan_many_dft(1, &n, howmany, ci, NULL, is, idist, co, NULL, os, odist,
                                   kind == RADON_C2C_FWD ? FFTW_FORWARD : FFTW_BACKWARD,
                                   flags);
    }
}

int radon_batch_plan(radon_batch *b, radon_kind kind, int n, int count, float *in, int is,
                     int idist, float *out, int os, int odist, unsigned flags)
{
    memset(b, 0, sizeof *b);
    b->kind = kind, b->in = in, b->out = out;
    if (count < 1)
        return 1;   /* an empty block (a 1-row frame's half): nothing to run */
    b->nchunk = (count + RADON_CHUNK - 1) / RADON_CHUNK;
    b->in_step = (size_t)RADON_CHUNK * idist * in_floats(kind);
    b->out_step = (size_t)RADON_CHUNK * odist * out_floats(kind);
    int full = count < RADON_CHUNK ? count : RADON_CHUNK, last = count % RADON_CHUNK;
    b->full = plan_one(kind, n, full, in, is, idist, out, os, odist, flags);
    if (last && b->nchunk > 1) {
        size_t c = (size_t)b->nchunk - 1;
        b->tail = plan_one(kind, n, last, in + c * b->in_step, is, idist,
                           out + c * b->out_step, os, odist, flags);
        return b->full && b->tail;
    }
    return b->full != NULL;
}

void radon_batch_run(const radon_batch *b, int c, float *in, float *out)
{
    fftwf_plan p = c == b->nchunk - 1 && b->tail ? b->tail : b->full;
    float *i = in + (size_t)c * b->in_step, *o = out + (size_t)c * b->out_step;
    switch (b->kind) {
    case RADON_R2C: fftwf_execute_dft_r2c(p, i, (fftwf_complex *)o); break;
    case RADON_C2R: fftwf_execute_dft_c2r(p, (fftwf_complex *)i, o); break;
    default: fftwf_execute_dft(p, (fftwf_complex *)i, (fftwf_complex *)o); break;
    }
}

int radon_batch_like(radon_batch *b, const radon_batch *like, float *in, float *out)
{
    if (!like->full || fftwf_alignment_of(in) != fftwf_alignment_of(like->in) ||
        fftwf_alignment_of(out) != fftwf_alignment_of(like->out))
        return 0;
    *b = *like;
    b->in = in, b->out = out, b->shared = 1;
    return 1;
}

void radon_batch_free(radon_batch *b)
{
    if (b->full && !b->shared)
        fftwf_destroy_plan(b->full);
    if (b->tail && !b->shared)
        fftwf_destroy_plan(b->tail);
    b->full = b->tail = NULL;
}

/* The FFT plans.  Out-of-place r2c and c2c keep their input (so the zero
 * rows and columns stay zero); the c2r ones destroy theirs, a scratch.
 * Forward: frame rows y >= h/2 (block a) to ky rows 0.., rows y < h/2
 * (block b) to ng - h/2..; column-major output, column stride ld.
 * Inverse: gspec's columns in place (stride nh), then its ky rows 0..
 * (block a) to grid rows h/2.., rows ng - h/2.. (block b) to rows 0.. */
int radon_plan_ffts(radon *r, radon_ws *pws, unsigned flags)
{
    size_t ng = (size_t)r->ng, nh = ng / 2 + 1;
    int h = r->h, kw = r->kw, ns = r->ns;
    int n1 = (int)ng, hb = h - h / 2, ha = h / 2, inh = (int)nh, ild = r->ld;
    float *gs = r->gspec, *wr = pws->rows, *wsp = pws->spec;
    /* block b shares block a's plans when the frame height is even and
     * the alignments agree (fewer plans to measure on a cold start) */
    int ok = radon_batch_plan(&r->fr_a, RADON_R2C, n1, hb, pws->grid + (size_t)ha * ng, 1, n1,
                              wr, ild, 1, flags);
    if (ha != hb || !radon_batch_like(&r->fr_b, &r->fr_a, pws->grid, wr + 2 * (ng - ha)))
        ok &= radon_batch_plan(&r->fr_b, RADON_R2C, n1, ha, pws->grid, 1, n1,
                               wr + 2 * (ng - ha), ild, 1, flags);
    ok &= radon_batch_plan(&r->fc, RADON_C2C_FWD, n1, inh, wr, 1, ild,
                           wsp + 2 * ((size_t)kw * ild + kw), 1, ild, flags);
    ok &= radon_batch_plan(&r->ic, RADON_C2C_INV, n1, inh, gs, inh, 1, gs, inh, 1, flags);
    ok &= radon_batch_plan(&r->ir_a, RADON_C2R, n1, hb, gs, 1, inh,
                           r->grid_out + (size_t)ha * ng, 1, n1, flags);
    if (ha != hb || !radon_batch_like(&r->ir_b, &r->ir_a, gs + 2 * (ng - ha) * nh, r->grid_out))
        ok &= radon_batch_plan(&r->ir_b, RADON_C2R, n1, ha, gs + 2 * (ng - ha) * nh, 1, inh,
                               r->grid_out, 1, n1, flags);
    r->p_r2c = fftwf_plan_dft_r2c_1d(ns, r->p_in, (fftwf_complex *)r->p_spec, flags);
    r->p_c2r = fftwf_plan_dft_c2r_1d(ns, (fftwf_complex *)r->p_spec, r->p_in, flags);
    return ok && r->p_r2c && r->p_c2r;
}

/* The first and last column chunks that table row i's taps or their
 * mirrors reach (kw <= 8 columns span two chunks at most; a mirrored tap
 * lands within kw of kx = 0 or ng/2, where its sample's own taps are). */
static void sample_chunks(const radon *r, size_t i, int *first, int *last)
{
    int kw = r->kw, ng = r->ng, nh = ng / 2 + 1, lo = nh, hi = -1, x0 = r->tx0[i];
    if (x0 >= 1 && x0 + kw <= nh - 1) {   /* interior: no wrap, no mirror */
        *first = x0 / RADON_CHUNK, *last = (x0 + kw - 1) / RADON_CHUNK;
        return;
    }
    for (int a = 0; a < kw; a++) {
        int mx = radon_wrap(r->tx0[i] + a, ng), nx = (ng - mx) % ng;
        if (mx < nh)
            lo = mx < lo ? mx : lo, hi = mx > hi ? mx : hi;
        if (nx < nh)
            lo = nx < lo ? nx : lo, hi = nx > hi ? nx : hi;
    }
    *first = lo / RADON_CHUNK, *last = hi / RADON_CHUNK;
}

/* The lists, in sample order (so that every grid cell is summed in the
 * order the serial loop used: its bits), a sample in every chunk whose
 * columns its taps or their mirrors reach.  Cost: two passes over the
 * samples' kw columns. */
int radon_grid_lists(radon *r)
{
    size_t nsamp = (size_t)r->nang * r->nf;
    int nc = r->ic.nchunk, ok = 1;
    r->goff = radon_alloc(((size_t)nc + 1) * sizeof *r->goff, 0, &ok);
    int *fill = calloc((size_t)nc + 1, sizeof *fill);
    if (!ok || !fill) {
        free(fill);
        return SL_ENOMEM;
    }
    for (int pass = 0; pass < 2; pass++) {
        for (size_t s = 0; s < nsamp; s++) {
            int c0, c1;
            sample_chunks(r, (size_t)r->tpos[s], &c0, &c1);
            for (int c = c0; c <= c1; c++)
                if (pass) {
                    int k = r->goff[c] + fill[c]++;
                    r->gsamp[k] = (int)s, r->gj[k] = (int)(s % r->nf);
                } else
                    fill[c + 1]++;
        }
        if (pass)
            break;
        r->goff[0] = 0;
        for (int c = 0; c < nc; c++)
            r->goff[c + 1] = r->goff[c] + fill[c + 1];
        memset(fill, 0, ((size_t)nc + 1) * sizeof *fill);
        r->gsamp = radon_alloc((size_t)r->goff[nc] * sizeof *r->gsamp, 0, &ok);
        r->gj = radon_alloc((size_t)r->goff[nc] * sizeof *r->gj, 0, &ok);
        if (!ok)
            break;
    }
    free(fill);
    return ok ? SL_OK : SL_ENOMEM;
}

/* ---- spectra to projections, per angle on the pool --------------------- */

/* Angles k0..k1-1 through the 1-D c2r plan on one thread's scratch. */
static void to_proj(const radon *r, float *in, float *sp, const float complex *spec,
                    float *proj, int k0, int k1)
{
    int nh = r->ns / 2 + 1;
    for (int k = k0; k < k1; k++) {
        for (int j = 0; j < nh; j++) {
            float sg = ((j & 1) ? -1.0f : 1.0f) / r->ns;
            float complex v = j < r->nf ? spec[(size_t)k * r->nf + j] : 0;
            sp[2 * j] = sg * crealf(v);
            sp[2 * j + 1] = sg * cimagf(v);
        }
        fftwf_execute_dft_c2r(r->p_c2r, (fftwf_complex *)sp, in);
        memcpy(proj + (size_t)k * r->ns, in, r->ns * sizeof(float));
    }
}

enum { PROJ_TASK = 16 };
typedef struct proj_job {
    radon *r;
    const float complex *spec;
    float *proj;
    atomic_int next;
} proj_job;

static void proj_run(void *ctx, int tid, int n)
{
    proj_job *j = ctx;
    radon *r = j->r;
    float *in = tid ? r->p1_in[tid] : r->p_in, *sp = tid ? r->p1_spec[tid] : r->p_spec;
    (void)n;
    for (int k0; (k0 = atomic_fetch_add(&j->next, PROJ_TASK)) < r->nang;)
        to_proj(r, in, sp, j->spec, j->proj, k0,
                k0 + PROJ_TASK < r->nang ? k0 + PROJ_TASK : r->nang);
}

int radon_spec_to_proj(radon *r, const float complex *spec, float *proj)
{
    proj_job j = {.r = r, .spec = spec, .proj = proj};
    atomic_init(&j.next, 0);
    if (r->pool && tpool_size(r->pool) > 1 && tpool_size(r->pool) == r->np1)
        tpool_run(r->pool, proj_run, &j);
    else
        to_proj(r, r->p_in, r->p_spec, spec, proj, 0, r->nang);
    return SL_OK;
}
