/* radon.c - see radon.h.
 *
 * Non-uniform FFT details (radon_slices / radon_fbp_slices).  The frame is
 * placed on an ng x ng grid (ng >= sigma*max(w,h)) with its centre at index
 * (0, 0), wrapped, so that the spectrum of a centred object is smooth and
 * its phase refers to the centre.  A slice sample at frequency rho*n is the
 * point k = rho*ng*n in grid bins; it is sum_m phi(k - m) G(m) over the
 * kw x kw grid points nearest k, phi the Kaiser-Bessel kernel with Beatty's
 * shape beta(kw, sigma), G the FFT of frame/C, and C(X) = integral phi(u)
 * cos(2 pi u X / ng) du the kernel's transform (quadrature at radon_new).
 * Only the half plane kx >= 0 is stored (r2c): a sample with cos(theta) < 0
 * is computed at -k and conjugated, and taps falling outside the stored
 * half use G(m) = conj G(-m).
 */
#include "radon.h"
#include "radon_spatial.h"

#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct radon {
    int w, h, nang, ns, nf;
    radon_opts o;
    double *cs, *sn;          /* cos, sin per angle */
    int *xlo, *xhi;           /* per row: pixels inside the disc of nproj */
    sl_err err;
    /* Fourier slice */
    int ng, kw;
    float *deap_x, *deap_y;   /* 1/C per frame column, row */
    /* The frame fills only h of the ng grid rows, so the 2-D FFTs are done
     * by hand: 1-D row transforms on those rows only (two blocks: rows
     * y >= h/2 land at grid rows 0.., rows y < h/2 at ng - h/2..), and
     * column transforms over all nh = ng/2+1 columns.  Saves ~25%. */
    float *grid_in;           /* h x ng: frame rows placed, rest 0 */
    float *grid_out;          /* h x ng */
    float *fspec;             /* ng x nh: row spectra, other rows stay 0 */
    float *gspec;             /* ng x nh complex, interleaved */
    fftwf_plan rows_a, rows_b, cols_fwd;     /* forward */
    fftwf_plan cols_inv, irows_a, irows_b;   /* inverse (gridding) */
    int *tx0, *ty0;           /* per sample (k*nf+j): first tap */
    unsigned char *tconj;     /* sample taken at -k, conjugate it */
    float *twx, *twy;         /* kw weights per sample */
    float *dens;              /* nf: gridding FBP weight, window included */
    /* 1-D */
    float *p_in;
    float *p_spec;
    fftwf_plan p_r2c, p_c2r;
    radon_spatial *sp;        /* projector and FBP (radon_spatial.c) */
    /* iterative */
    float *it_x, *it_z, *it_g;
    float complex *it_spec;
    double lip;               /* Lipschitz constant, 0 until measured */
};

void radon_opts_default(radon_opts *o)
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

static double kb(double u, int kw, double beta)
{
    double t = 2.0 * u / kw;
    if (fabs(t) >= 1.0)
        return 0.0;
    return bessel_i0(beta * sqrt(1.0 - t * t)) / bessel_i0(beta);
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

static int wrap(int i, int n) { i %= n; return i < 0 ? i + n : i; }

/* malloc (fftw = 0) or fftwf_malloc (aligned), clearing *ok on failure so
 * that a constructor checks a whole batch once. */
static void *alloc(size_t n, int fftw, int *ok)
{
    void *p = fftw ? fftwf_malloc(n ? n : 1) : malloc(n ? n : 1);
    *ok &= p != NULL;
    return p;
}

void radon_free(radon *r)
{
    if (!r)
        return;
    radon_spatial_free(r->sp);
    fftwf_plan plans[] = {r->rows_a, r->rows_b, r->cols_fwd, r->cols_inv,
                          r->irows_a, r->irows_b, r->p_r2c, r->p_c2r};
    for (size_t i = 0; i < sizeof plans / sizeof plans[0]; i++)
        if (plans[i])
            fftwf_destroy_plan(plans[i]);
    void *fb[] = {r->grid_in, r->grid_out, r->fspec, r->gspec, r->p_in, r->p_spec};
    for (size_t i = 0; i < sizeof fb / sizeof fb[0]; i++)
        fftwf_free(fb[i]);
    void *mb[] = {r->cs, r->sn, r->xlo, r->xhi, r->deap_x, r->deap_y,
                  r->tx0, r->ty0, r->tconj, r->twx, r->twy, r->dens,
                  r->it_x, r->it_z, r->it_g, r->it_spec};
    for (size_t i = 0; i < sizeof mb / sizeof mb[0]; i++)
        free(mb[i]);
    free(r);
}

/* Kernel, deapodisation and the tap table of every slice sample. */
static void setup_nufft(radon *r, double sigma)
{
    int kw = r->kw, ng = r->ng;
    double a = (double)kw / sigma * (sigma - 0.5);
    double beta = M_PI * sqrt(fmax(a * a - 0.8, 1e-3));
    enum { NQ = 2048 };             /* midpoint quadrature of C(X) */
    double du = (double)kw / NQ;
    double phi[NQ];
    for (int q = 0; q < NQ; q++)
        phi[q] = kb(-0.5 * kw + (q + 0.5) * du, kw, beta);
    for (int pass = 0; pass < 2; pass++) {
        int n = pass ? r->h : r->w;
        float *d = pass ? r->deap_y : r->deap_x;
        for (int i = 0; i < n; i++) {
            double X = i - n / 2, c = 0.0;
            for (int q = 0; q < NQ; q++)
                c += phi[q] * cos(2 * M_PI * (-0.5 * kw + (q + 0.5) * du) * X / ng);
            d[i] = (float)(1.0 / (c * du));
        }
    }
    for (int k = 0; k < r->nang; k++)
        for (int j = 0; j < r->nf; j++) {
            size_t s = (size_t)k * r->nf + j;
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
                r->twx[s * kw + i] = (float)kb(kx - (x0 + i), kw, beta);
                r->twy[s * kw + i] = (float)kb(ky - (y0 + i), kw, beta);
            }
        }
}

radon *radon_new(int w, int h, int nangles, const radon_opts *opts,
                 sl_err *err)
{
    radon_opts o;
    if (opts)
        o = *opts;
    else
        radon_opts_default(&o);
    if (w < 4 || h < 4 || nangles < 1) {
        sl_seterr(err, SL_EINVAL, "radon_new: bad size %dx%d or %d angles", w, h, nangles);
        return NULL;
    }
    int ns = o.nproj ? o.nproj : (int)ceil(hypot(w, h)) + 2;
    ns += ns & 1;
    int nf = o.nfreq ? o.nfreq : ns / 2 + 1;
    /* Few angles: the FFT dominates, so a smaller grid with a wider kernel
     * (same ~1e-4 accuracy) is cheaper; many angles: the taps dominate. */
    double sigma = o.oversamp > 0 ? o.oversamp : nangles >= 60 ? 2.0 : 1.5;
    int kw = o.kernel_bins ? o.kernel_bins : (sigma < 1.9 ? 6 : 4);
    int up = o.bp_upsample ? o.bp_upsample : 1;
    if (ns < 4 || nf < 1 || nf > ns / 2 + 1 || sigma < 1.2 || sigma > 4 ||
        kw < 2 || kw > 8 || (up != 1 && up != 2 && up != 4)) {
        sl_seterr(err, SL_EINVAL,
                  "radon_new: bad options nproj %d nfreq %d oversamp %g "
                  "kernel %d upsample %d", ns, nf, sigma, kw, up);
        return NULL;
    }
    radon *r = calloc(1, sizeof *r);
    if (!r) {
        sl_seterr(err, SL_ENOMEM, "radon_new: out of memory");
        return NULL;
    }
    r->w = w, r->h = h, r->nang = nangles, r->ns = ns, r->nf = nf;
    r->o = o, r->kw = kw;
    int mx = w > h ? w : h;
    r->ng = fft_size((int)ceil(sigma * mx));
    if (r->ng < mx + kw)
        r->ng = fft_size(mx + kw);
    size_t ng = (size_t)r->ng, nh = ng / 2 + 1, nsamp = (size_t)nangles * nf;
    size_t npix = (size_t)w * h;
    unsigned flags = o.fftw_flags ? o.fftw_flags : FFTW_MEASURE;
    int ok = 1;
    r->cs = alloc(nangles * sizeof *r->cs, 0, &ok);
    r->sn = alloc(nangles * sizeof *r->sn, 0, &ok);
    r->xlo = alloc(h * sizeof *r->xlo, 0, &ok);
    r->xhi = alloc(h * sizeof *r->xhi, 0, &ok);
    r->deap_x = alloc(w * sizeof *r->deap_x, 0, &ok);
    r->deap_y = alloc(h * sizeof *r->deap_y, 0, &ok);
    r->tx0 = alloc(nsamp * sizeof *r->tx0, 0, &ok);
    r->ty0 = alloc(nsamp * sizeof *r->ty0, 0, &ok);
    r->tconj = alloc(nsamp, 0, &ok);
    r->twx = alloc(nsamp * kw * sizeof *r->twx, 0, &ok);
    r->twy = alloc(nsamp * kw * sizeof *r->twy, 0, &ok);
    r->dens = alloc(nf * sizeof *r->dens, 0, &ok);
    r->it_x = alloc(npix * sizeof *r->it_x, 0, &ok);
    r->it_z = alloc(npix * sizeof *r->it_z, 0, &ok);
    r->it_g = alloc(npix * sizeof *r->it_g, 0, &ok);
    r->it_spec = alloc(nsamp * sizeof *r->it_spec, 0, &ok);
    /* FFTW buffers (aligned); complex ones are interleaved float pairs. */
    r->grid_in = alloc((size_t)h * ng * sizeof(float), 1, &ok);
    r->grid_out = alloc((size_t)h * ng * sizeof(float), 1, &ok);
    r->fspec = alloc(ng * nh * 2 * sizeof(float), 1, &ok);
    r->gspec = alloc(ng * nh * 2 * sizeof(float), 1, &ok);
    r->p_in = alloc(ns * sizeof(float), 1, &ok);
    r->p_spec = alloc((ns / 2 + 1) * 2 * sizeof(float), 1, &ok);
    if (!ok) {
        sl_seterr(err, SL_ENOMEM, "radon_new: out of memory (%dx%d, %d angles)",
                  w, h, nangles);
        goto fail_free;
    }
    memset(r->grid_in, 0, (size_t)h * ng * sizeof(float));
    memset(r->fspec, 0, ng * nh * 2 * sizeof(float));
    /* Plans.  Out-of-place r2c and c2c keep their input (so the zero rows
     * and columns stay zero); the c2r ones destroy theirs, a scratch. */
    int n1 = (int)ng, hb = h - h / 2, ha = h / 2, inh = (int)nh;
    fftwf_complex *fs = (fftwf_complex *)r->fspec, *gs = (fftwf_complex *)r->gspec;
    r->rows_a = fftwf_plan_many_dft_r2c(1, &n1, hb, r->grid_in + (size_t)ha * ng, NULL, 1,
                                        n1, fs, NULL, 1, inh, flags);
    r->rows_b = fftwf_plan_many_dft_r2c(1, &n1, ha, r->grid_in, NULL, 1, n1,
                                        fs + (ng - ha) * nh, NULL, 1, inh, flags);
    r->cols_fwd = fftwf_plan_many_dft(1, &n1, inh, fs, NULL, inh, 1, gs, NULL, inh, 1,
                                      FFTW_FORWARD, flags);
    r->cols_inv = fftwf_plan_many_dft(1, &n1, inh, gs, NULL, inh, 1, gs, NULL, inh, 1,
                                      FFTW_BACKWARD, flags);
    r->irows_a = fftwf_plan_many_dft_c2r(1, &n1, hb, gs, NULL, 1, inh,
                                         r->grid_out + (size_t)ha * ng, NULL, 1, n1, flags);
    r->irows_b = fftwf_plan_many_dft_c2r(1, &n1, ha, gs + (ng - ha) * nh, NULL, 1, inh,
                                         r->grid_out, NULL, 1, n1, flags);
    r->p_r2c = fftwf_plan_dft_r2c_1d(ns, r->p_in, (fftwf_complex *)r->p_spec, flags);
    r->p_c2r = fftwf_plan_dft_c2r_1d(ns, (fftwf_complex *)r->p_spec, r->p_in, flags);
    if (!r->rows_a || !r->rows_b || !r->cols_fwd || !r->cols_inv ||
        !r->irows_a || !r->irows_b || !r->p_r2c || !r->p_c2r) {
        sl_seterr(err, SL_ENOMEM, "radon_new: FFTW planning failed");
        goto fail_free;
    }
    for (int k = 0; k < nangles; k++) {
        double th = radon_angle_rad(r, k);
        r->cs[k] = cos(th);
        r->sn[k] = sin(th);
    }
    /* Exact zeros at the axes keep theta = 0, 90 bit-exact. */
    if (nangles % 2 == 0)
        r->cs[nangles / 2] = 0.0;
    double R = 0.5 * ns;
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
    r->sp = radon_spatial_new(w, h, nangles, ns, &o, r->cs, r->sn, r->xlo, r->xhi, err);
    if (!r->sp)
        goto fail_free;
    setup_nufft(r, sigma);
    double fc = o.window_cut_cyc_px > 0 ? o.window_cut_cyc_px : 0.5;
    /* Gridding weights: polar area element |rho| drho dtheta; the disc
     * |rho| < drho/2 for j = 0, shared by the angles and halved because
     * the sample is also spread at -k. */
    for (int j = 0; j < nf; j++) {
        double rho = (double)j / ns, a = M_PI / ((double)nangles * ns);
        double d = j ? a * rho : a / (8.0 * ns);
        r->dens[j] = (float)(d * radon_window_gain(o.window, rho, fc));
    }
    return r;
fail_free:
    radon_free(r);
    return NULL;
}

/* ---- spatial forward and FBP: radon_spatial.c ------------------------- */

int radon_project(radon *r, const float *img, float *proj)
{
    if (!radon_spatial_can_project(r->sp))
        return sl_seterr(&r->err, SL_EINVAL, "radon_project: handle made with spatial = 0");
    radon_spatial_project(r->sp, img, proj);
    return SL_OK;
}

int radon_fbp(radon *r, const float *proj, float *img)
{
    radon_spatial_fbp(r->sp, proj, img);
    return SL_OK;
}

/* ---- Fourier slices ----------------------------------------------------- */

/* Frame / C into the grid rows, column x at grid column x - w/2 (wrapped:
 * the right half of the frame first, then the left half at the end). */
static void grid_load(radon *r, const float *img)
{
    int ng = r->ng, w = r->w, xa = w / 2;
    for (int y = 0; y < r->h; y++) {
        float *row = r->grid_in + (size_t)y * ng;
        const float *src = img + (size_t)y * w;
        float dy = r->deap_y[y];
        for (int x = xa; x < w; x++)
            row[x - xa] = src[x] * r->deap_x[x] * dy;
        for (int x = 0; x < xa; x++)
            row[ng - xa + x] = src[x] * r->deap_x[x] * dy;
    }
}

static void grid_fft(radon *r)
{
    fftwf_execute(r->rows_a);
    if (r->h / 2)
        fftwf_execute(r->rows_b);
    fftwf_execute(r->cols_fwd);
}

/* G(m) for any integer m, from the stored half plane. */
static void grid_get(const radon *r, int mx, int my, float *re, float *im)
{
    int ng = r->ng, nh = ng / 2 + 1;
    mx = wrap(mx, ng), my = wrap(my, ng);
    if (mx < nh) {
        *re = r->gspec[2 * ((size_t)my * nh + mx)];
        *im = r->gspec[2 * ((size_t)my * nh + mx) + 1];
    } else {
        size_t i = (size_t)((ng - my) % ng) * nh + (ng - mx);
        *re = r->gspec[2 * (i)];
        *im = -r->gspec[2 * (i) + 1];
    }
}

/* One slice sample from a kw x kw block that lies wholly in the stored
 * half plane; KW a compile-time constant lets the compiler unroll. */
static inline void sample_fast(const float *gspec, int ng, int nh, int x0, int y0,
                               const float *wx, const float *wy, int KW,
                               float *re, float *im)
{
    float ar = 0, ai = 0;
    for (int b = 0; b < KW; b++) {
        int row = y0 + b;
        row += row < 0 ? ng : row >= ng ? -ng : 0;
        const float *g = gspec + 2 * ((size_t)row * nh + x0);
        float sr = 0, si = 0;
        for (int a = 0; a < KW; a++) {
            sr += wx[a] * g[2 * a];
            si += wx[a] * g[2 * a + 1];
        }
        ar += wy[b] * sr;
        ai += wy[b] * si;
    }
    *re = ar, *im = ai;
}

int radon_slices(radon *r, const float *img, float complex *spec)
{
    grid_load(r, img);
    grid_fft(r);
    int kw = r->kw, ng = r->ng, nh = ng / 2 + 1;
    size_t nsamp = (size_t)r->nang * r->nf;
    for (size_t s = 0; s < nsamp; s++) {
        const float *wx = r->twx + s * kw, *wy = r->twy + s * kw;
        int x0 = r->tx0[s], y0 = r->ty0[s];
        float re = 0, im = 0;
        if (x0 >= 0 && x0 + kw <= nh) {   /* all taps stored: fast path */
            if (kw == 4)
                sample_fast(r->gspec, ng, nh, x0, y0, wx, wy, 4, &re, &im);
            else if (kw == 6)
                sample_fast(r->gspec, ng, nh, x0, y0, wx, wy, 6, &re, &im);
            else
                sample_fast(r->gspec, ng, nh, x0, y0, wx, wy, kw, &re, &im);
        } else {
            for (int b = 0; b < kw; b++)
                for (int a = 0; a < kw; a++) {
                    float gr, gi;
                    grid_get(r, x0 + a, y0 + b, &gr, &gi);
                    re += wx[a] * wy[b] * gr, im += wx[a] * wy[b] * gi;
                }
        }
        spec[s] = r->tconj[s] ? CMPLXF(re, -im) : CMPLXF(re, im);
    }
    return SL_OK;
}

/* Add v at k and conj(v) at -k (the Hermitian image of the sample) to the
 * stored half plane, for every tap; a tap outside the half plane is implied
 * by its mirror, which the -k copy adds. */
static void grid_spread(radon *r, size_t s, float vr, float vi)
{
    int kw = r->kw, ng = r->ng, nh = ng / 2 + 1;
    const float *wx = r->twx + s * kw, *wy = r->twy + s * kw;
    int x0 = r->tx0[s], y0 = r->ty0[s];
    if (r->tconj[s])
        vi = -vi;
    if (x0 >= 1 && x0 + kw <= nh - 1) {   /* no tap on kx = 0 or ng/2 */
        for (int b = 0; b < kw; b++) {
            float *g = r->gspec + 2 * ((size_t)wrap(y0 + b, ng) * nh + x0);
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
            int mx = wrap(x0 + a, ng), my = wrap(y0 + b, ng);
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

/* ---- 1-D transforms --------------------------------------------------- */

int radon_proj_to_spec(radon *r, const float *proj, float complex *spec)
{
    for (int k = 0; k < r->nang; k++) {
        memcpy(r->p_in, proj + (size_t)k * r->ns, r->ns * sizeof(float));
        fftwf_execute(r->p_r2c);
        for (int j = 0; j < r->nf; j++) {   /* (-1)^j: refer phase to s = 0 */
            float sg = (j & 1) ? -1.0f : 1.0f;
            spec[(size_t)k * r->nf + j] = CMPLXF(sg * r->p_spec[2 * (j)], sg * r->p_spec[2 * (j) + 1]);
        }
    }
    return SL_OK;
}

int radon_spec_to_proj(radon *r, const float complex *spec, float *proj)
{
    int nh = r->ns / 2 + 1;
    for (int k = 0; k < r->nang; k++) {
        for (int j = 0; j < nh; j++) {
            float sg = ((j & 1) ? -1.0f : 1.0f) / r->ns;
            float complex v = j < r->nf ? spec[(size_t)k * r->nf + j] : 0;
            r->p_spec[2 * j] = sg * crealf(v);
            r->p_spec[2 * j + 1] = sg * cimagf(v);
        }
        fftwf_execute(r->p_c2r);
        memcpy(proj + (size_t)k * r->ns, r->p_in, r->ns * sizeof(float));
    }
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
