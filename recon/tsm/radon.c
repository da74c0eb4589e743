/* radon.c - see radon.h: the handle (plans, Kaiser-Bessel tables, sample
 * taps), the 1-D transforms and the iterative few-angle inverse.  The
 * Fourier-slice forward transform and its gridding adjoint are in
 * radon_slice.c (with the non-uniform FFT's details), the spatial projector
 * and FBP in radon_spatial.c; the handle's insides in radon_int.h.
 */
#include "radon_int.h"

#include <fftw3.h>
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>


void radon_opts_defaults(radon_opts *o)
{
    memset(o, 0, sizeof *o);
    o->window = RADON_WIN_RAMLAK;
    o->bp_interp = RADON_INTERP_CUBIC;
    o->bp_upsample = 2;
    o->spatial = 1;
}

const char *radon_errmsg(const radon *r) { return r ? r->err.msg : ""; }
int radon_nangles(const radon *r) { return r->nang; }
int radon_nproj(const radon *r) { return r->ns; }
int radon_nfreq(const radon *r) { return r->nf; }
double radon_angle_rad(const radon *r, int k) { return k * M_PI / r->nang; }

static double bessel_i0(double x)
{
    double sum = 1.0, term = 1.0, q = 0.25 * x * x;
    for (int k = 1; k < 200 && term > 1e-17 * sum; k++) {
        term *= q / ((double)k * k);
        sum += term;
    }
    return sum;
}

/* The Kaiser-Bessel kernel phi(u) = I0(beta sqrt(1 - t^2)) / I0(beta),
 * t = 2u/kw, |t| < 1, as the polynomial sum_k c_k v^k in v = 1 - t^2 with
 * c_k = (beta^2/4)^k / (k!)^2 / I0(beta): every term is positive, so
 * Horner's rule is accurate to rounding, and it costs n multiply-adds with
 * no division (the tap tables need 2 kw values per slice sample: 1.5e5 at
 * 180 angles).  Cut where the terms fall below 1e-17 of the sum (n <= 40
 * for beta <= 22, i.e. any kw <= 8, sigma <= 4). */
enum { KB_TERMS = 64 };
typedef struct kb_poly {
    int n;
    double c[KB_TERMS];
} kb_poly;

static void kb_poly_init(kb_poly *k, double beta)
{
    double q = 0.25 * beta * beta, i0 = bessel_i0(beta), term = 1.0;
    k->n = 0;
    for (int m = 0; m < KB_TERMS; m++) {
        if (m)
            term *= q / ((double)m * m);
        k->c[k->n++] = term / i0;
        if ((double)m * m > q && term < 1e-17 * i0)
            break;
    }
}

/* acc[i] = phi at v[i] = 1 - t_i^2 for n lanes: Horner across all lanes at
 * once (blocks of 8, which the compiler vectorises), so its cost is
 * throughput, not the latency of one chain. */
static inline void kb_eval_body(const kb_poly *k, const double *restrict v,
                                double *restrict acc, int n)
{
    for (int i = 0; i < n; i++)
        acc[i] = k->c[k->n - 1];
    for (int m = k->n - 2; m >= 0; m--) {
        double c = k->c[m];
        int i = 0;
        for (; i + 8 <= n; i += 8)
            for (int l = 0; l < 8; l++)
                acc[i + l] = acc[i + l] * v[i + l] + c;
        for (; i < n; i++)
            acc[i] = acc[i] * v[i] + c;
    }
}

/* The same operations 4 lanes at a time where the CPU has AVX2 (no FMA:
 * a multiply, then an add, as the baseline's two lanes do): the same
 * bits, half the time of the tables' main cost. */
__attribute__((target("avx2"))) static void kb_eval_avx2(const kb_poly *k,
                                                        const double *restrict v,
                                                        double *restrict acc, int n)
{
    kb_eval_body(k, v, acc, n);
}

static void kb_eval_base(const kb_poly *k, const double *restrict v, double *restrict acc,
                         int n)
{
    kb_eval_body(k, v, acc, n);
}

/* C(X) = integral of phi(u) cos(2 pi u X / ng) du over |u| < kw/2, in
 * closed form: kw sinh(z) / z / I0(beta) with z^2 = beta^2 - (pi kw X /
 * ng)^2 (sin |z| / |z| past the kernel's main lobe).  Agrees with a
 * 2048-point quadrature to 3e-8 (the quadrature's own error). */
static double kb_transform(double X, int kw, int ng, double beta)
{
    double a = M_PI * kw * X / ng, z2 = beta * beta - a * a, z = sqrt(fabs(z2));
    double sh = z2 > 0 ? sinh(z) / z : z2 < 0 ? sin(z) / z : 1.0;
    return kw * sh / bessel_i0(beta);
}

/* The default grid for few angles: the smallest n >= 1.25 mx of the forms
 * 2^k, 3 2^k, 5 2^k (k >= 1), FFTW's fastest sizes.  Measured at 200^2
 * (one slice set, 18 angles): n = 256 0.13 ms, against 0.18-0.30 for 250,
 * 270, 288, 300.  With kw 8 below sigma 1.6 (6 above) the slices are the
 * pixels' DFT to ~2e-6 of F(0) (sigma 1.28, kw 8), against 4e-5 for the
 * sigma 1.5, kw 6 used before. */
static int few_angle_grid(int mx)
{
    int lo = (int)ceil(1.25 * mx), best = 0;
    for (int f = 1; f <= 5; f += 2)
        for (int n = 2 * f; n < 8 * lo; n *= 2)
            if (n >= lo) {
                best = !best || n < best ? n : best;
                break;
            }
    return best;
}

/* Smallest even n >= m whose only prime factors are 2, 3, 5, 7. */
static int fft_size(int m)
{
    for (int n = m + (m & 1);; n += 2) {
        int k = n;
        for (int p = 2; p <= 7; p++)
            while (k % p == 0)
                k /= p;
        if (k == 1)
            return n;
    }
}


/* malloc (fftw = 0) or fftwf_malloc (aligned), clearing *ok on failure so
 * that a constructor checks a whole batch once. */

void radon_free(radon *r)
{
    if (!r)
        return;
    radon_spatial_free(r->sp);
    radon_batch *bt[] = {&r->fr_a, &r->fr_b, &r->fc, &r->ic, &r->ir_a, &r->ir_b};
    for (size_t i = 0; i < sizeof bt / sizeof bt[0]; i++)
        radon_batch_free(bt[i]);
    fftwf_plan plans[] = {r->p_r2c, r->p_c2r};
    for (size_t i = 0; i < sizeof plans / sizeof plans[0]; i++)
        if (plans[i])
            fftwf_destroy_plan(plans[i]);
    radon_ws_free(r->ws);
    void *fb[] = {r->grid_out, r->gspec, r->p_in, r->p_spec};
    for (size_t i = 0; i < sizeof fb / sizeof fb[0]; i++)
        fftwf_free(fb[i]);
    for (int t = 1; t < r->np1; t++)
        fftwf_free(r->p1_in[t]), fftwf_free(r->p1_spec[t]);
    void *mb[] = {r->cs, r->sn, r->xlo, r->xhi, r->deap_x, r->deap_y,
                  r->tx0, r->ty0, r->tconj, r->twx, r->twy, r->tord, r->tpos, r->dens,
                  r->it_x, r->it_z, r->it_g, r->it_spec, r->rowf, r->goff, r->gsamp, r->gj};
    for (size_t i = 0; i < sizeof mb / sizeof mb[0]; i++)
        free(mb[i]);
    free(r);
}

/* The tap tables of samples s0..s1-1, CHUNK samples at a time: 2 kw
 * lanes each (x, then y). */
typedef void (*kb_eval_fn)(const kb_poly *, const double *restrict, double *restrict, int);
static void taps_range(radon *r, const kb_poly *kp, kb_eval_fn eval, size_t s0, size_t s1)
{
    enum { CHUNK = 32 };
    int kw = r->kw, ng = r->ng;
    double v[CHUNK * 16], acc[CHUNK * 16];
    for (size_t c0 = s0; c0 < s1; c0 += CHUNK) {
        int ns = s1 - c0 < CHUNK ? (int)(s1 - c0) : CHUNK;
        for (int c = 0; c < ns; c++) {
            size_t s = c0 + c;
            int k = (int)(s / r->nf), j = (int)(s % r->nf);
            double rho = (double)j / r->ns * ng;
            double kx = rho * r->cs[k], ky = rho * r->sn[k];
            r->tconj[s] = kx < 0;
            if (kx < 0) {
                kx = -kx;
                ky = -ky;
            }
            int x0 = (int)floor(kx - 0.5 * kw) + 1, y0 = (int)floor(ky - 0.5 * kw) + 1;
            r->tx0[s] = x0;
            r->ty0[s] = y0;
            for (int i = 0; i < kw; i++) {
                double tx = 2.0 * (kx - (x0 + i)) / kw, ty = 2.0 * (ky - (y0 + i)) / kw;
                v[c * 2 * kw + i] = 1.0 - tx * tx;
                v[c * 2 * kw + kw + i] = 1.0 - ty * ty;
            }
        }
        eval(kp, v, acc, ns * 2 * kw);
        for (int c = 0; c < ns; c++)
            for (int i = 0; i < kw; i++) {   /* phi = 0 for |t| >= 1 */
                int lx = c * 2 * kw + i, ly = lx + kw;
                r->twx[(c0 + c) * kw + i] = v[lx] > 0 ? (float)acc[lx] : 0.0f;
                r->twy[(c0 + c) * kw + i] = v[ly] > 0 ? (float)acc[ly] : 0.0f;
            }
    }
}

/* The tables in tasks of TAPS_TASK samples, claimed by the pool's threads
 * (each sample's values are its own: the same bits on any thread). */
enum { TAPS_TASK = 2048 };
typedef struct taps_job {
    radon *r;
    const kb_poly *kp;
    kb_eval_fn eval;
    atomic_size_t next;
} taps_job;

static void taps_run(void *ctx, int tid, int n)
{
    taps_job *j = ctx;
    size_t nsamp = (size_t)j->r->nang * j->r->nf;
    (void)tid, (void)n;
    for (size_t s0; (s0 = atomic_fetch_add(&j->next, TAPS_TASK)) < nsamp;)
        taps_range(j->r, j->kp, j->eval, s0, s0 + TAPS_TASK < nsamp ? s0 + TAPS_TASK : nsamp);
}

/* Kernel, deapodisation and the tap table of every slice sample.  Cost:
 * (w + h) closed-form transforms and nangles nfreq 2 kw kernel values (~3
 * ms of one thread at 200^2, 180 angles, with AVX2; it was 20 ms with a
 * quadrature of C and a Bessel series per tap), on the pool's threads. */
static void setup_nufft(radon *r, double sigma)
{
    int kw = r->kw, ng = r->ng;
    double a = (double)kw / sigma * (sigma - 0.5);
    double beta = M_PI * sqrt(fmax(a * a - 0.8, 1e-3));
    kb_poly kp;
    kb_poly_init(&kp, beta);
    for (int pass = 0; pass < 2; pass++) {
        int n = pass ? r->h : r->w;
        float *d = pass ? r->deap_y : r->deap_x;
        for (int i = 0; i < n; i++)
            d[i] = (float)(1.0 / kb_transform(i - n / 2, kw, ng, beta));
    }
    /* the forward path's row weights also centre ky (Forward layout) */
    for (int y = 0; y < r->h; y++)
        r->rowf[y] = ((y - r->h / 2) & 1) ? -r->deap_y[y] : r->deap_y[y];
    taps_job j = {.r = r, .kp = &kp,
                  .eval = __builtin_cpu_supports("avx2") ? kb_eval_avx2 : kb_eval_base};
    atomic_init(&j.next, 0);
    if (r->pool)
        tpool_run(r->pool, taps_run, &j);
    else
        taps_run(&j, 0, 1);
}

/* The geometry the options and sizes imply: projection length ns,
 * frequencies nf, oversampling sigma, kernel width kw, grid ng0 (0:
 * from sigma).  SL_EINVAL (in err) naming the bad value. */
static int radon_plan_sizes(int w, int h, int nangles, const radon_opts *o,
                            int *ns, int *nf, double *sigma, int *kw, int *ng0,
                            sl_err *err)
{
    if (w < 4 || h < 4 || nangles < 1)
        return sl_seterr(err, SL_EINVAL, "radon_new: bad size %dx%d or %d angles",
                         w, h, nangles);
    *ns = o->nproj ? o->nproj : (int)ceil(hypot(w, h)) + 2;
    *ns += *ns & 1;
    *nf = o->nfreq ? o->nfreq : *ns / 2 + 1;
    int mx = w > h ? w : h;
    /* Few angles: the FFT dominates, so a small grid (few_angle_grid) with
     * a wide kernel; many angles: the taps dominate (sigma 2, kw 4). */
    *ng0 = 0;
    *sigma = o->oversamp > 0 ? o->oversamp : nangles >= 60 ? 2.0 : 1.5;
    if (!(o->oversamp > 0) && nangles < 60) {
        *ng0 = few_angle_grid(mx);
        *sigma = (double)*ng0 / mx;
    }
    *kw = o->kernel_bins ? o->kernel_bins : *ng0 ? (*sigma < 1.6 ? 8 : 6) : (*sigma < 1.9 ? 6 : 4);
    int up = o->bp_upsample ? o->bp_upsample : 1;
    if (*ns < 4 || *nf < 1 || *nf > *ns / 2 + 1 || *sigma < 1.2 || *sigma > 4 ||
        *kw < 2 || *kw > 8 || (up != 1 && up != 2 && up != 4))
        return sl_seterr(err, SL_EINVAL, "radon_new: bad options nproj %d nfreq %d "
                         "oversamp %g kernel %d upsample %d", *ns, *nf, *sigma, *kw, up);
    return SL_OK;
}

/* Every table and buffer; ok stays 1 while each allocation succeeds. */
static void radon_alloc_all(radon *r, radon_ws **pws, int *ok)
{
    int w = r->w, h = r->h, nangles = r->nang, nf = r->nf, kw = r->kw, ns = r->ns;
    size_t ng = (size_t)r->ng, nh = ng / 2 + 1, nsamp = (size_t)nangles * nf;
    size_t npix = (size_t)w * h;
    r->cs = radon_alloc(nangles * sizeof *r->cs, 0, ok);
    r->sn = radon_alloc(nangles * sizeof *r->sn, 0, ok);
    r->xlo = radon_alloc(h * sizeof *r->xlo, 0, ok);
    r->xhi = radon_alloc(h * sizeof *r->xhi, 0, ok);
    r->deap_x = radon_alloc(w * sizeof *r->deap_x, 0, ok);
    r->deap_y = radon_alloc(h * sizeof *r->deap_y, 0, ok);
    r->rowf = radon_alloc(h * sizeof *r->rowf, 0, ok);
    r->tx0 = radon_alloc(nsamp * sizeof *r->tx0, 0, ok);
    r->ty0 = radon_alloc(nsamp * sizeof *r->ty0, 0, ok);
    r->tconj = radon_alloc(nsamp, 0, ok);
    r->twx = radon_alloc(nsamp * kw * sizeof *r->twx, 0, ok);
    r->twy = radon_alloc(nsamp * kw * sizeof *r->twy, 0, ok);
    r->dens = radon_alloc(nf * sizeof *r->dens, 0, ok);
    r->it_x = radon_alloc(npix * sizeof *r->it_x, 0, ok);
    r->it_z = radon_alloc(npix * sizeof *r->it_z, 0, ok);
    r->it_g = radon_alloc(npix * sizeof *r->it_g, 0, ok);
    r->it_spec = radon_alloc(nsamp * sizeof *r->it_spec, 0, ok);
    /* FFTW buffers (aligned); complex ones are interleaved float pairs. */
    r->spad = kw;
    r->ld = r->ng + 2 * kw;
    /* planned on a radon_ws that radon_new then keeps as the handle's own
     * (radon_slices; tsm brings one per thread for its frames) */
    *pws = radon_ws_new(r, NULL);
    *ok &= *pws != NULL;
    r->grid_out = radon_alloc((size_t)h * ng * sizeof(float), 1, ok);
    r->gspec = radon_alloc(ng * nh * 2 * sizeof(float), 1, ok);
    r->p_in = radon_alloc(ns * sizeof(float), 1, ok);
    r->p_spec = radon_alloc((ns / 2 + 1) * 2 * sizeof(float), 1, ok);
    /* the other pool threads' 1-D scratch (radon_spec_to_proj) */
    int nt = r->pool ? tpool_size(r->pool) : 1;
    r->np1 = nt < RADON_MAX_POOL ? nt : RADON_MAX_POOL;
    for (int t = 1; t < r->np1; t++) {
        r->p1_in[t] = radon_alloc(ns * sizeof(float), 1, ok);
        r->p1_spec[t] = radon_alloc((ns / 2 + 1) * 2 * sizeof(float), 1, ok);
    }
}

/* The angles' cosines and sines, and each row's extent inside the disc
 * of diameter ns. */
static void radon_geometry(radon *r)
{
    int w = r->w, h = r->h, nangles = r->nang;
    for (int k = 0; k < nangles; k++) {
        double th = radon_angle_rad(r, k);
        r->cs[k] = cos(th);
        r->sn[k] = sin(th);
    }
    /* Exact zeros at the axes keep theta = 0, 90 bit-exact. */
    if (nangles % 2 == 0)
        r->cs[nangles / 2] = 0.0;
    double R = 0.5 * r->ns;
    for (int y = 0; y < h; y++) {
        double Y = y - h / 2, hw = R * R - Y * Y;
        int lo = w, hi = -1;
        if (hw >= 0) {
            double dx = sqrt(hw);
            lo = (int)ceil(w / 2 - dx), hi = (int)floor(w / 2 + dx);
            lo = lo < 0 ? 0 : lo;
            hi = hi > w - 1 ? w - 1 : hi;
        }
        r->xlo[y] = lo, r->xhi[y] = hi;
    }
}

/* Gridding weights: polar area element |rho| drho dtheta; the disc |rho|
 * < drho/2 for j = 0, shared by the angles and halved because the sample
 * is also spread at -k. */
static void radon_density(radon *r)
{
    double fc = r->o.window_cut_cyc_px > 0 ? r->o.window_cut_cyc_px : 0.5;
    int ns = r->ns;
    for (int j = 0; j < r->nf; j++) {
        double rho = (double)j / ns, a = M_PI / ((double)r->nang * ns);
        double d = j ? a * rho : a / (8.0 * ns);
        r->dens[j] = (float)(d * radon_window_gain(r->o.window, rho, fc));
    }
}

radon *radon_new(int w, int h, int nangles, const radon_opts *opts,
                 sl_err *err)
{
    radon_opts o;
    if (opts)
        o = *opts;
    else
        radon_opts_defaults(&o);
    int ns = 0, nf = 0, kw = 0, ng0 = 0;
    double sigma = 0;
    if (radon_plan_sizes(w, h, nangles, &o, &ns, &nf, &sigma, &kw, &ng0, err) != SL_OK)
        return NULL;
    radon *r = calloc(1, sizeof *r);
    radon_ws *pws = NULL;
    if (!r) {
        sl_seterr(err, SL_ENOMEM, "radon_new: out of memory");
        return NULL;
    }
    int mx = w > h ? w : h, ok = 1;
    r->w = w, r->h = h, r->nang = nangles, r->ns = ns, r->nf = nf;
    r->o = o, r->kw = kw, r->pool = o.pool;
    r->ng = ng0 ? ng0 : fft_size((int)ceil(sigma * mx));
    if (r->ng < mx + kw)
        r->ng = fft_size(mx + kw);
    radon_alloc_all(r, &pws, &ok);
    if (!ok) {
        sl_seterr(err, SL_ENOMEM, "radon_new: out of memory (%dx%d, %d angles)",
                  w, h, nangles);
        goto fail_free;
    }
    if (!radon_plan_ffts(r, pws, o.fftw_flags ? o.fftw_flags : FFTW_MEASURE)) {
        sl_seterr(err, SL_ENOMEM, "radon_new: FFTW planning failed");
        goto fail_free;
    }
    /* the planning scratch becomes the handle's own (radon_slices): its
     * pages are mapped already, where a fresh one faulted them again at
     * the result (11 MB at 512^2, ~4 ms) */
    radon_ws_clear(r, pws);
    r->ws = pws;
    pws = NULL;
    radon_geometry(r);
    if (o.spatial &&
        !(r->sp = radon_spatial_new(w, h, nangles, ns, &o, r->cs, r->sn, r->xlo, r->xhi, err)))
        goto fail_free;
    setup_nufft(r, sigma);
    if (radon_order_samples(r) != SL_OK || radon_grid_lists(r) != SL_OK) {
        sl_seterr(err, SL_ENOMEM, "radon_new: out of memory (%d angles)", nangles);
        goto fail_free;
    }
    radon_density(r);
    return r;
fail_free:
    radon_ws_free(pws);
    radon_free(r);
    return NULL;
}

/* ---- spatial forward and FBP: radon_spatial.c ------------------------- */

int radon_project(radon *r, const float *img, float *proj)
{
    if (!radon_can_project(r))
        return sl_seterr(&r->err, SL_EINVAL, "radon_project: handle made with spatial = 0");
    radon_spatial_project(r->sp, img, proj);
    return SL_OK;
}

/* Without the projector (spatial = 0) the FBP's filter and plans are made
 * at the first call: the Fourier-slice path inverts by gridding, and their
 * two 1-D MEASURE plans cost ~3 ms of a tsm-fourier run's serial planning
 * at 200^2 even from wisdom. */
int radon_fbp(radon *r, const float *proj, float *img)
{
    if (!r->sp && !(r->sp = radon_spatial_new(r->w, r->h, r->nang, r->ns, &r->o, r->cs, r->sn,
                                              r->xlo, r->xhi, &r->err)))
        return r->err.code;
    radon_spatial_fbp(r->sp, proj, img);
    return SL_OK;
}

int radon_can_project(const radon *r) { return r->sp && radon_spatial_can_project(r->sp); }

radon_ws *radon_ws_new_projector(const radon *r, sl_err *err)
{
    if (!radon_can_project(r)) {
        sl_seterr(err, SL_EINVAL, "radon_ws_new_projector: handle made with spatial = 0");
        return NULL;
    }
    radon_ws *ws = calloc(1, sizeof *ws);
    int ok = ws != NULL;
    if (ws) {
        ok = (ws->sp_scratch = radon_spatial_scratch_new(r->sp)) != NULL;
        ws->proj = radon_alloc((size_t)r->nang * r->ns * sizeof *ws->proj, 0, &ok);
        /* fftwf_malloc: the 1-D plans' alignment, for new-array execute */
        ws->p_in = radon_alloc(r->ns * sizeof *ws->p_in, 1, &ok);
        ws->p_spec = radon_alloc((r->ns / 2 + 1) * 2 * sizeof *ws->p_spec, 1, &ok);
    }
    if (!ok) {
        sl_seterr(err, SL_ENOMEM, "radon_ws_new_projector: out of memory (%dx%d)", r->w, r->h);
        radon_ws_free(ws);
        return NULL;
    }
    return ws;
}

/* ---- 1-D transforms --------------------------------------------------- */

/* Each angle's projection through the 1-D r2c plan on in/out (the plan's
 * arrays or others of their alignment). */
static void proj_to_spec(const radon *r, float *in, float *out, const float *proj,
                         float complex *spec)
{
    for (int k = 0; k < r->nang; k++) {
        memcpy(in, proj + (size_t)k * r->ns, r->ns * sizeof(float));
        fftwf_execute_dft_r2c(r->p_r2c, in, (fftwf_complex *)out);
        for (int j = 0; j < r->nf; j++) {   /* (-1)^j: refer phase to s = 0 */
            float sg = (j & 1) ? -1.0f : 1.0f;
            spec[(size_t)k * r->nf + j] = CMPLXF(sg * out[2 * j], sg * out[2 * j + 1]);
        }
    }
}

int radon_proj_to_spec(radon *r, const float *proj, float complex *spec)
{
    proj_to_spec(r, r->p_in, r->p_spec, proj, spec);
    return SL_OK;
}

int radon_project_spec_ws(const radon *r, radon_ws *ws, const float *img,
                          float complex *spec)
{
    if (!ws || !ws->sp_scratch)
        return SL_EINVAL;
    radon_spatial_project_with(r->sp, ws->sp_scratch, img, ws->proj);
    proj_to_spec(r, ws->p_in, ws->p_spec, ws->proj, spec);
    return SL_OK;
}

/* ---- iterative few-angle inverse ---------------------------------------- */

/* g = A^T D (A x - y) restricted to the disc; y NULL means y = 0. */
static void normal_grad(radon *r, const float *x, const float complex *y, float *g)
{
    size_t nsamp = (size_t)r->nang * r->nf;
    radon_slices(r, x, r->it_spec);
    if (y)
        for (size_t s = 0; s < nsamp; s++)
            r->it_spec[s] -= y[s];
    radon_fbp_slices(r, r->it_spec, g);
}

static double norm2(const float *a, size_t n)
{
    double s = 0;
    for (size_t i = 0; i < n; i++)
        s += (double)a[i] * a[i];
    return sqrt(s);
}

int radon_invert_iter(radon *r, const float complex *spec, int niter,
                      int nonneg, float *img)
{
    size_t n = (size_t)r->w * r->h;
    if (niter < 0)
        return sl_seterr(&r->err, SL_EINVAL, "radon_invert_iter: niter %d", niter);
    if (r->lip <= 0) {   /* power iteration on A^T D A, from a smooth start */
        radon_fbp_slices(r, spec, r->it_x);
        for (size_t i = 0; i < n; i++)
            r->it_x[i] = fabsf(r->it_x[i]) + 1e-6f;
        double lam = 1.0;
        for (int it = 0; it < 20; it++) {
            double nx = norm2(r->it_x, n);
            if (nx <= 0)
                break;
            normal_grad(r, r->it_x, NULL, r->it_g);
            lam = norm2(r->it_g, n) / nx;
            for (size_t i = 0; i < n; i++)
                r->it_x[i] = (float)(r->it_g[i] / (lam * nx));
        }
        r->lip = 1.1 * lam;
    }
    float *x = r->it_x, *z = r->it_z, *g = r->it_g;
    radon_fbp_slices(r, spec, x);
    for (size_t i = 0; i < n; i++) {
        if (nonneg && x[i] < 0)
            x[i] = 0;
        z[i] = x[i];
    }
    double t = 1.0, step = 1.0 / r->lip;
    for (int it = 0; it < niter; it++) {
        normal_grad(r, z, spec, g);
        double tn = 0.5 * (1 + sqrt(1 + 4 * t * t)), mom = (t - 1) / tn;
        for (size_t i = 0; i < n; i++) {
            float xn = (float)(z[i] - step * g[i]);
            if (nonneg && xn < 0)
                xn = 0;
            z[i] = (float)(xn + mom * (xn - x[i]));
            x[i] = xn;
        }
        t = tn;
    }
    /* radon_fbp_slices zeroed everything outside the disc, so x is zero
     * there too. */
    memcpy(img, x, n * sizeof *img);
    return SL_OK;
}
