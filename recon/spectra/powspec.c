/* powspec.c - see powspec.h.
 *
 * The frame FFT is a single-precision r2c transform planned once; the
 * accumulators hold only the non-redundant half plane (h x (w/2+1)) in
 * double, and powspec_result/mean_ft expand to the full plane with
 * Hermitian symmetry.  Per frame: one r2c FFT plus O(wh) sums, no
 * allocation.
 */
#include <complex.h>
#include <fftw3.h>

#include "powspec_int.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>


void powspec_opts_defaults(powspec_opts *o)
{
    memset(o, 0, sizeof *o);
    o->window = POWSPEC_WIN_NONE;
    o->tukey_alpha = 0.25;
    o->bias = POWSPEC_BIAS_NONE;
    o->adu_per_photon = 1.0;
    o->floor_rho = 1.0;
    o->measure = 1;
}

/* One axis of the window: Tukey with taper fraction alpha (Hann = 1). */
static double win1(int x, int n, double alpha)
{
    if (alpha <= 0)
        return 1.0;
    double t = (double)x / n; /* periodic form: x = 0 is the edge */
    double a = alpha > 1 ? 1 : alpha;
    if (t < a / 2)
        return 0.5 * (1 - cos(2 * M_PI * t / a));
    if (t > 1 - a / 2)
        return 0.5 * (1 - cos(2 * M_PI * (1 - t) / a));
    return 1.0;
}

int powspec_window(int kind, double alpha, int w, int h, float *win)
{
    if (!win || w <= 0 || h <= 0)
        return SL_EINVAL;
    double a;
    switch (kind) {
    case POWSPEC_WIN_NONE: a = 0; break;
    case POWSPEC_WIN_HANN: a = 1; break;
    case POWSPEC_WIN_TUKEY:
        if (!(alpha >= 0 && alpha <= 1))
            return SL_EINVAL;
        a = alpha;
        break;
    default: return SL_EINVAL;
    }
    for (int y = 0; y < h; y++) {
        double wy = win1(y, h, a);
        for (int x = 0; x < w; x++)
            win[(size_t)y * w + x] = (float)(wy * win1(x, w, a));
    }
    return SL_OK;
}

/* The slots, their per-slot values and the sums (p->w, h, wc, o set);
 * 0 when out of memory (powspec_free frees what was made).  A slot per
 * frame in flight: with one thread a frame is summed as it comes (one a
 * group); with more, as many as threads, 4..POWSPEC_SLOTS a group. */
static int alloc_sums(powspec *p)
{
    int nt = p->o.nthreads;
    size_t n = (size_t)p->w * p->h, nh = (size_t)p->h * p->wc;
    p->ns = nt > 1 ? (nt < 4 ? 4 : nt > POWSPEC_SLOTS ? POWSPEC_SLOTS : nt) : 1;
    p->npad = (n + 15) / 16 * 16;
    p->nhp = (nh + 7) / 8 * 8;
    size_t nslot = 2 * (size_t)p->ns;
    p->in = fftwf_alloc_real(nslot * p->npad);
    p->out = fftwf_alloc_complex(nslot * p->nhp);
    p->sflux = malloc(nslot * sizeof *p->sflux);
    p->sw2 = malloc(nslot * sizeof *p->sw2);
    p->ps = calloc(nh, sizeof *p->ps);
    p->ft = calloc(nh, sizeof *p->ft);
    if (!p->in || !p->out || !p->sflux || !p->sw2 || !p->ps || !p->ft)
        return 0;
    if (p->o.aligned) {
        p->aft = calloc(nh, sizeof *p->aft);
        p->ex = malloc(nslot * p->wc * sizeof *p->ex);
        p->ey = malloc(nslot * p->h * sizeof *p->ey);
        if (!p->aft || !p->ex || !p->ey)
            return 0;
    }
    return 1;
}

powspec *powspec_new(int w, int h, const powspec_opts *o, sl_err *err)
{
    powspec_opts def;
    if (!o) {
        powspec_opts_defaults(&def);
        o = &def;
    }
    if (w < 4 || h < 4) {
        sl_seterr(err, SL_EINVAL, "powspec: frame %dx%d too small", w, h);
        return NULL;
    }
    if (o->window < POWSPEC_WIN_NONE || o->window > POWSPEC_WIN_TUKEY ||
        (o->window == POWSPEC_WIN_TUKEY &&
         !(o->tukey_alpha >= 0 && o->tukey_alpha <= 1))) {
        sl_seterr(err, SL_EINVAL, "powspec: bad window %d (alpha %g)",
                  o->window, o->tukey_alpha);
        return NULL;
    }
    if (o->bias < POWSPEC_BIAS_NONE || o->bias > POWSPEC_BIAS_FLOOR ||
        (o->bias == POWSPEC_BIAS_PHOTON && !(o->adu_per_photon > 0)) ||
        !(o->read_noise_adu >= 0) ||
        (o->bias == POWSPEC_BIAS_FLOOR && !(o->floor_rho > 0))) {
        sl_seterr(err, SL_EINVAL,
                  "powspec: bad bias mode %d (gain %g, read noise %g, "
                  "floor rho %g)", o->bias, o->adu_per_photon,
                  o->read_noise_adu, o->floor_rho);
        return NULL;
    }
    if (o->nthreads < 0 || o->nthreads > 64) {
        sl_seterr(err, SL_EINVAL, "powspec: %d threads (0..64)", o->nthreads);
        return NULL;
    }
    powspec *p = calloc(1, sizeof *p);
    if (!p)
        goto fail_nomem;
    size_t n = (size_t)w * h;
    p->w = w;
    p->h = h;
    p->wc = w / 2 + 1;
    p->o = *o;
    if (!alloc_sums(p))
        goto fail_alloc;
    if (!(p->pool = tpool_new(o->nthreads > 1 ? o->nthreads : 1, err)))
        goto fail_pool;
    if (!(p->pipe = powspec_pipe_new(p)))
        goto fail_alloc;
    if (o->window != POWSPEC_WIN_NONE) {
        p->win = malloc(n * sizeof *p->win);
        if (!p->win)
            goto fail_alloc;
        powspec_window(o->window, o->tukey_alpha, w, h, p->win);
    }
    double w2 = 0; /* white noise of variance s^2 adds s^2 sum w^2 */
    for (size_t i = 0; i < n; i++)
        w2 += p->win ? (double)p->win[i] * p->win[i] : 1.0;
    p->w2 = w2;
    p->rbias = o->read_noise_adu * o->read_noise_adu * w2;
    /* MEASURE overwrites the buffers while planning: nothing is in them. */
    p->plan = fftwf_plan_dft_r2c_2d(h, w, p->in, p->out,
                                    o->measure ? FFTW_MEASURE : FFTW_ESTIMATE);
    if (!p->plan)
        goto fail_alloc;
    return p;
fail_alloc:
    sl_seterr(err, SL_ENOMEM, "powspec: out of memory for %dx%d", w, h);
fail_pool: /* tpool_new said why */
    powspec_free(p);
    return NULL;
fail_nomem:
    sl_seterr(err, SL_ENOMEM, "powspec: out of memory for %dx%d", w, h);
    return NULL;
}

void powspec_free(powspec *p)
{
    if (!p)
        return;
    slotpipe_free(p->pipe); /* a job in flight uses the plan and buffers */
    if (p->plan)
        fftwf_destroy_plan(p->plan);
    tpool_free(p->pool);
    fftwf_free(p->in);
    fftwf_free(p->out);
    free(p->sflux);
    free(p->sw2);
    free(p->win);
    free(p->ps);
    free(p->ft);
    free(p->aft);
    free(p->ex);
    free(p->ey);
    free(p);
}

const char *powspec_errmsg(const powspec *p)
{
    return p ? p->err.msg : "no powspec handle";
}

int powspec_nframes(const powspec *p) { return p ? p->nadded : 0; }

double powspec_mean_flux(powspec *p)
{
    if (p)
        powspec_flush(p);
    return p && p->n ? p->flux / p->n : 0.0;
}

/* Half-plane index of full-plane index (i, j), and whether it is the
 * conjugate mirror. */
static size_t half_index(const powspec *p, int i, int j, int *mirror)
{
    *mirror = i >= p->wc;
    if (*mirror) {
        i = (p->w - i) % p->w;
        j = (p->h - j) % p->h;
    }
    return (size_t)j * p->wc + i;
}

/* rho (hypot of the frequency over Nyquist on each axis) beyond rho0,
 * with hypot (and its divisions) only within 1e-9 of rho0^2: the sum of
 * squares made with reciprocals is within a few ulps of rho^2, so away
 * from the circle it decides as hypot does (the same answers; hypot at
 * every frequency of the floor's passes was ~5 ms of serial planning at
 * 512^2, and the divisions ~4 ms more). */
typedef struct rho_test {
    int w, h;
    double rho0, sx, sy, lo, hi;
} rho_test;

static rho_test rho_test_make(int w, int h, double rho0)
{
    double c2 = rho0 * rho0;
    return (rho_test){w, h, rho0, 2.0 / w, 2.0 / h, c2 * (1 - 1e-9), c2 * (1 + 1e-9)};
}

static int rho_beyond(const rho_test *t, int i, int j)
{
    int pf = i <= (t->w - 1) / 2 ? i : i - t->w;
    int qf = j <= (t->h - 1) / 2 ? j : j - t->h;
    double x = pf * t->sx, y = qf * t->sy, r2 = x * x + y * y;
    if (t->rho0 < 0 || r2 > t->hi)
        return 1;
    if (r2 < t->lo)
        return 0;
    return hypot(pf / (0.5 * t->w), qf / (0.5 * t->h)) > t->rho0;
}

/* Row j's frequencies beyond rho0 are those whose signed column
 * frequency pf has |pf| >= the cut this returns (w/2 + 1: none), since
 * rho grows with |pf| and is the same for -pf: in pixel order the one
 * run of columns cut .. w - cut (row_run).  Found by bisection on the
 * same test, so the same frequencies as testing each (a test per
 * frequency was ~3 ms of serial planning at 512^2). */
static int row_cut(const rho_test *t, int j)
{
    int lo = 0, hi = t->w / 2 + 1;
    while (lo < hi) {
        int mid = lo + (hi - lo) / 2; /* column mid has |pf| = mid */
        if (rho_beyond(t, mid, j))
            hi = mid;
        else
            lo = mid + 1;
    }
    return lo;
}

/* The run of columns [*i0, *i1) with |pf| >= cut. */
static void row_run(int w, int cut, int *i0, int *i1)
{
    *i0 = cut;
    *i1 = w - cut + 1 < w ? w - cut + 1 : w;
}

/* |pf| of column i. */
static int col_freq(int w, int i) { return i <= (w - 1) / 2 ? i : w - i; }

/* Mean (and optionally std) of the full-plane spectrum over rho > rho0;
 * returns the number of frequencies there. */
static size_t floor_stats(const double *ps, int w, int h, double rho0,
                          double *mean, double *sd)
{
    double s = 0, s2 = 0;
    size_t m = 0;
    rho_test t = rho_test_make(w, h, rho0);
    for (int j = 0; j < h; j++) {
        int i0, i1;
        row_run(w, row_cut(&t, j), &i0, &i1);
        for (int i = i0; i < i1; i++) {
            double v = ps[(size_t)j * w + i];
            s += v;
            s2 += v * v;
            m++;
        }
    }
    *mean = m ? s / m : 0;
    if (sd)
        *sd = m > 1 ? sqrt(fmax(s2 / m - *mean * *mean, 0)) : 0;
    return m;
}

/* The measured floor per frame (BIAS_FLOOR); *speckle: speckle reaches
 * the floor's region, *outer: the outer part's level alone (0: none). */
static double floor_level(const powspec *p, int *speckle, double *outer)
{
    /* The floor_stats region, read through the half plane, in two
     * parts: up to and beyond 1.2 x floor_rho.  White noise is flat;
     * when the inner part stands 10 % above the outer one, speckle
     * reaches the corners (sampling coarser than Nyquist) and only
     * the outer part, the least of it, stands for the floor. */
    double s[2] = {0, 0};
    size_t m[2] = {0, 0};
    rho_test t1 = rho_test_make(p->w, p->h, p->o.floor_rho);
    rho_test t2 = rho_test_make(p->w, p->h, 1.2 * p->o.floor_rho);
    for (int j = 0; j < p->h; j++) {
        int i0, i1, c2 = row_cut(&t2, j);
        row_run(p->w, row_cut(&t1, j), &i0, &i1);
        for (int i = i0; i < i1; i++) {
            int mir, k = col_freq(p->w, i) >= c2;
            s[k] += p->ps[half_index(p, i, j, &mir)];
            m[k]++;
        }
    }
    double in = m[0] ? s[0] / m[0] : 0, out = m[1] ? s[1] / m[1] : in;
    *speckle = m[1] && in > 1.1 * out;
    *outer = m[1] ? out / p->n : 0;
    if (*speckle)
        return out / p->n;
    return m[0] + m[1] ? (s[0] + s[1]) / (m[0] + m[1]) / p->n : 0.0;
}

double powspec_bias(powspec *p)
{
    if (p)
        powspec_flush(p);
    if (!p || !p->n)
        return 0.0;
    if (p->o.bias == POWSPEC_BIAS_PHOTON)
        return p->pbias / p->n;
    if (p->o.bias == POWSPEC_BIAS_FLOOR) {
        int speckle;
        double outer;
        return floor_level(p, &speckle, &outer);
    }
    return 0.0;
}

int powspec_floor_gain(powspec *p, double white_adu, double *adu_per_photon)
{
    *adu_per_photon = 0;
    if (p)
        powspec_flush(p);
    if (!p || !p->n || p->o.bias != POWSPEC_BIAS_FLOOR || !(p->w2flux > 0))
        return SL_EDATA;
    int speckle;
    double fl;
    floor_level(p, &speckle, &fl);
    double white = white_adu * white_adu * p->w2, shot = fl - white;
    /* The outer part of the floor's region only: speckle a few per cent
     * above the floor near the cut-off passes the bias's 10 % test, and
     * there it would read as photons.  Refused: speckle over the region,
     * no outer part, and a floor the white noise owns (the photons' share
     * then carries the white noise's error many times over). */
    if (speckle || !(fl > 0) || !(shot > 0.2 * fl))
        return SL_EDATA;
    *adu_per_photon = shot / (p->w2flux / p->n);
    return SL_OK;
}

int powspec_result(powspec *p, double *ps)
{
    if (!p || !ps)
        return sl_seterr(p ? &p->err : NULL, SL_EINVAL,
                         "powspec_result: NULL argument");
    powspec_flush(p);
    if (!p->n)
        return sl_seterr(&p->err, SL_EDATA, "powspec_result: no frames");
    double b = powspec_bias(p), inv = 1.0 / p->n;
    for (int j = 0; j < p->h; j++)
        for (int i = 0; i < p->w; i++) {
            int mir;
            ps[(size_t)j * p->w + i] =
                p->ps[half_index(p, i, j, &mir)] * inv - b;
        }
    return SL_OK;
}

int powspec_mean_ft(powspec *p, double complex *ft)
{
    if (p)
        powspec_flush(p);
    if (!p || !ft || !p->n)
        return SL_EINVAL;
    double inv = 1.0 / p->n;
    for (int j = 0; j < p->h; j++)
        for (int i = 0; i < p->w; i++) {
            int mir;
            double complex v = p->ft[half_index(p, i, j, &mir)] * inv;
            ft[(size_t)j * p->w + i] = mir ? conj(v) : v;
        }
    return SL_OK;
}

int powspec_aligned_power(powspec *p, double *le)
{
    if (p)
        powspec_flush(p);
    if (!p || !le || !p->aft || p->n < 2)
        return SL_EINVAL;
    double inv = 1.0 / p->n;
    for (int j = 0; j < p->h; j++)
        for (int i = 0; i < p->w; i++) {
            int mir;
            size_t k = half_index(p, i, j, &mir);
            double complex m = p->aft[k] * inv;
            double m2 = creal(m) * creal(m) + cimag(m) * cimag(m);
            le[(size_t)j * p->w + i] = m2 - (p->ps[k] * inv - m2) / (p->n - 1);
        }
    return SL_OK;
}

int powspec_modulus(const double *ps_obj, const double *ps_ref, int w, int h,
                    double eps_rel, double *modulus)
{
    if (!ps_obj || !modulus || w <= 0 || h <= 0)
        return SL_EINVAL;
    size_t n = (size_t)w * h;
    if (!ps_ref) {
        for (size_t k = 0; k < n; k++)
            modulus[k] = sqrt(fmax(ps_obj[k], 0.0));
        return SL_OK;
    }
    if (!(ps_ref[0] > 0) || !(eps_rel > 0))
        return SL_EINVAL;
    double t0 = 1.0 / ps_ref[0];
    for (size_t k = 0; k < n; k++) {
        double t = fmax(ps_ref[k] * t0, 0.0);
        modulus[k] = sqrt(fmax(ps_obj[k], 0.0) / (t + eps_rel));
    }
    return SL_OK;
}

int powspec_support(const double *ps, int w, int h, double nsigma,
                    double rel_min, double floor_rho, double noise_sd,
                    unsigned char *mask, double *rcut_px)
{
    if (!ps || !mask || w < 4 || h < 4)
        return SL_EINVAL;
    double fm, fsd;
    size_t m = floor_stats(ps, w, h, floor_rho, &fm, &fsd);
    double thr = fmax(m ? fm + nsigma * fsd : 0.0, rel_min * ps[0]);
    if (noise_sd > 0)
        thr = fmax(nsigma * noise_sd, rel_min * ps[0]);
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            int nyq = (w % 2 == 0 && i == w / 2) || (h % 2 == 0 && j == h / 2);
            mask[(size_t)j * w + i] = !nyq && ps[(size_t)j * w + i] > thr;
        }
    /* Drop isolated pixels: a real patch of the transfer function is
     * several pixels wide, a lone noise spike is not.  The test reads the
     * mask as it was (neighbours are checked against ps, not the edited
     * mask), so the result is independent of scan order and symmetric. */
    double rmax = 0;
    long r2max = -1;   /* hypot is monotonic in the integer |u|^2 */
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            size_t k = (size_t)j * w + i;
            if (!mask[k] || k == 0)
                continue;
            int nb = 0;
            int ii[4] = {(i + 1) % w, (i + w - 1) % w, i, i};
            int jj[4] = {j, j, (j + 1) % h, (j + h - 1) % h};
            for (int t = 0; t < 4; t++) {
                int nyq = (w % 2 == 0 && ii[t] == w / 2) ||
                          (h % 2 == 0 && jj[t] == h / 2);
                nb += !nyq && ps[(size_t)jj[t] * w + ii[t]] > thr;
            }
            if (!nb)
                mask[k] = 2; /* marked; cleared below */
        }
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            size_t k = (size_t)j * w + i;
            if (mask[k] == 2)
                mask[k] = 0;
            if (mask[k]) {   /* hypot only where |u|^2 reaches the largest so far */
                int pf = i <= (w - 1) / 2 ? i : i - w;
                int qf = j <= (h - 1) / 2 ? j : j - h;
                long r2 = (long)pf * pf + (long)qf * qf;
                if (r2 >= r2max) {
                    double r = hypot(pf, qf);
                    rmax = r2 > r2max || r > rmax ? r : rmax;
                    r2max = r2;
                }
            }
        }
    mask[0] = 1;
    if (rcut_px)
        *rcut_px = rmax;
    return SL_OK;
}

/* Layout: ps (nh), ft (2 nh: re, im), aft (2 nh, opts.aligned only),
 * flux, pbias, n, w2flux. */
static void complex_out(const double complex *z, size_t n, double *buf)
{
    for (size_t k = 0; k < n; k++)
        buf[2 * k] = creal(z[k]), buf[2 * k + 1] = cimag(z[k]);
}

static void complex_in(const double *buf, size_t n, double complex *z)
{
    for (size_t k = 0; k < n; k++)
        z[k] = buf[2 * k] + I * buf[2 * k + 1];
}

size_t powspec_partial(powspec *p, double *buf)
{
    powspec_flush(p);
    size_t nh = (size_t)p->h * p->wc, na = p->aft ? 2 * nh : 0, e = 3 * nh + na;
    if (buf) {
        memcpy(buf, p->ps, nh * sizeof *buf);
        complex_out(p->ft, nh, buf + nh);
        if (p->aft)
            complex_out(p->aft, nh, buf + 3 * nh);
        buf[e] = p->flux;
        buf[e + 1] = p->pbias;
        buf[e + 2] = p->n;
        buf[e + 3] = p->w2flux;
    }
    return e + 4;
}

void powspec_partial_load(powspec *p, const double *buf)
{
    powspec_flush(p); /* the staged frames are replaced too */
    size_t nh = (size_t)p->h * p->wc, na = p->aft ? 2 * nh : 0, e = 3 * nh + na;
    memcpy(p->ps, buf, nh * sizeof *buf);
    complex_in(buf + nh, nh, p->ft);
    if (p->aft)
        complex_in(buf + 3 * nh, nh, p->aft);
    p->flux = buf[e];
    p->pbias = buf[e + 1];
    p->n = p->nadded = (int)buf[e + 2];
    p->w2flux = buf[e + 3];
}
