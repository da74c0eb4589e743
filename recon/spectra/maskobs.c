/* maskobs.c - see maskobs.h; the sampling plan is maskobs_plan.c. */
#include <complex.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "maskobs_int.h"

void maskobs_opts_defaults(maskobs_opts *o)
{
    memset(o, 0, sizeof *o);
    o->wavelength_m = 500e-9;
    o->plate_scale_arcsec = NAN;
    o->clean_max = MASKOBS_CLEAN_MAX;
    o->measure = 1;
}

const char *maskobs_errmsg(const maskobs *m)
{
    return m ? m->err.msg : "out of memory";
}

void maskobs_free(maskobs *m)
{
    if (!m)
        return;
    if (m->plan)
        fftwf_destroy_plan(m->plan);
    fftwf_free(m->in);
    fftwf_free(m->out);
    free(m->vis2);
    free(m->t3);
    free(m->t3_transfer);
    free(m->vtap);
    free(m->ttap);
    free(m->vacc);
    free(m->tacc);
    free(m->vblk);
    free(m->tblk);
    free(m->vbacc);
    free(m->tbacc);
    free(m);
}

static int check_args(const double *x_m, const double *y_m, int nholes,
                      double d, int w, int h, const maskobs_opts *o,
                      sl_err *err)
{
    if (!x_m || !y_m || !o || nholes < 3)
        return sl_seterr(err, SL_EINVAL, "mask observables: need at least "
                         "3 holes (%d given)", nholes);
    if (w < 8 || h < 8)
        return sl_seterr(err, SL_EINVAL, "mask observables: frame %dx%d is "
                         "below 8x8", w, h);
    if (!(o->wavelength_m > 0) || !isfinite(o->wavelength_m))
        return sl_seterr(err, SL_EINVAL, "mask observables: wavelength %g m "
                         "is not finite and > 0", o->wavelength_m);
    if (!(o->plate_scale_arcsec > 0) || !isfinite(o->plate_scale_arcsec))
        return sl_seterr(err, SL_EINVAL, "mask observables: plate scale %g "
                         "arcsec/px is not finite and > 0", o->plate_scale_arcsec);
    if (!(d > 0) || !isfinite(d))
        return sl_seterr(err, SL_EINVAL, "mask observables: hole diameter %g "
                         "m is not finite and > 0", d);
    if (!(o->adu_per_photon >= 0) || !(o->read_noise_adu >= 0))
        return sl_seterr(err, SL_EINVAL, "mask observables: photon gain %g "
                         "ADU/photon and read noise %g ADU must be >= 0",
                         o->adu_per_photon, o->read_noise_adu);
    return SL_OK;
}

/* The FFT plan and its buffers, then the accumulators (zeroed). */
static int make_buffers(maskobs *m)
{
    size_t n = (size_t)m->w * m->h, nh = (size_t)m->h * m->wc;
    m->in = fftwf_alloc_real(n);
    m->out = fftwf_alloc_complex(nh);
    size_t nv = (size_t)(m->nvis2 ? m->nvis2 : 1), nt = (size_t)m->nt3;
    m->vacc = calloc(2 * nv, sizeof *m->vacc);
    m->tacc = calloc(5 * nt, sizeof *m->tacc);
    m->vblk = calloc(nv, sizeof *m->vblk);
    m->tblk = calloc(2 * nt, sizeof *m->tblk);
    m->vbacc = calloc(2 * nv, sizeof *m->vbacc);
    m->tbacc = calloc(5 * nt, sizeof *m->tbacc);
    if (!m->in || !m->out || !m->vacc || !m->tacc || !m->vblk || !m->tblk ||
        !m->vbacc || !m->tbacc)
        return sl_seterr(&m->err, SL_ENOMEM, "mask observables: out of "
                         "memory for a %dx%d frame", m->w, m->h);
    /* MEASURE overwrites the buffers while planning: nothing is in them. */
    m->plan = fftwf_plan_dft_r2c_2d(m->h, m->w, m->in, m->out,
                                    m->o.measure ? FFTW_MEASURE : FFTW_ESTIMATE);
    if (!m->plan)
        return sl_seterr(&m->err, SL_ENOMEM, "mask observables: no FFT plan "
                         "for %dx%d", m->w, m->h);
    return SL_OK;
}

maskobs *maskobs_new(const double *x_m, const double *y_m, int nholes,
                     double hole_diameter_m, int w, int h,
                     const maskobs_opts *o, sl_err *err)
{
    if (check_args(x_m, y_m, nholes, hole_diameter_m, w, h, o, err) != SL_OK)
        return NULL;
    maskobs *m = calloc(1, sizeof *m);
    if (!m) {
        sl_seterr(err, SL_ENOMEM, "mask observables: out of memory");
        return NULL;
    }
    m->o = *o;
    m->w = w, m->h = h, m->wc = w / 2 + 1, m->nholes = nholes;
    m->block = o->block_frames > 0 ? o->block_frames : MASKOBS_BLOCK;
    if (maskobs_plan(m, x_m, y_m, hole_diameter_m) != SL_OK ||
        make_buffers(m) != SL_OK) {
        sl_seterr(err, m->err.code, "%s", m->err.msg);
        maskobs_free(m);
        return NULL;
    }
    return m;
}

static inline double complex tap_value(const maskobs *m, mo_tap t)
{
    double complex z = m->out[t.idx];
    return t.conj ? conj(z) : z;
}

/* The five moments of a complex sample: re, im, re^2, im^2, re im. */
static inline void moments_add(double *a, double complex b)
{
    a[0] += creal(b), a[1] += cimag(b);
    a[2] += creal(b) * creal(b), a[3] += cimag(b) * cimag(b);
    a[4] += creal(b) * cimag(b);
}

/* This frame's V2 (before the transfer) and triple products into the
 * sums and the running block; f0 > 0 its flux. */
static void accumulate(maskobs *m, double f0)
{
    double g = m->o.adu_per_photon;
    double rn2 = g > 0 ? m->o.read_noise_adu * m->o.read_noise_adu : 0;
    double pbias = g * f0 + (double)m->w * m->h * rn2, dc2 = f0 * f0 - g * f0;
    for (int i = 0; i < m->nvis2; i++) {
        double complex z = tap_value(m, m->vtap[i]);
        double v = (creal(z) * creal(z) + cimag(z) * cimag(z) - pbias) / dc2;
        m->vacc[2 * i] += v;
        m->vacc[2 * i + 1] += v * v;
        m->vblk[i] += v;
    }
    double f3 = f0 * f0 * f0;
    for (int i = 0; i < m->nt3; i++) {
        const mo_tap *t = &m->ttap[3 * (size_t)i];
        double complex z1 = tap_value(m, t[0]), z2 = tap_value(m, t[1]);
        double complex z3 = tap_value(m, t[2]);
        double complex b = z1 * z2 * conj(z3);
        if (g > 0) /* Wirnitzer: the photon bias is real */
            b -= g * (cabs(z1) * cabs(z1) + cabs(z2) * cabs(z2) +
                      cabs(z3) * cabs(z3)) - 2.0 * g * g * f0;
        b /= f3;
        moments_add(&m->tacc[5 * (size_t)i], b);
        m->tblk[2 * i] += creal(b);
        m->tblk[2 * i + 1] += cimag(b);
    }
}

/* A whole block: its means into the block moments, the block restarted. */
static void close_block(maskobs *m)
{
    for (int i = 0; i < m->nvis2; i++) {
        double v = m->vblk[i] / m->block;
        m->vbacc[2 * i] += v;
        m->vbacc[2 * i + 1] += v * v;
        m->vblk[i] = 0;
    }
    for (int i = 0; i < m->nt3; i++) {
        double *b = &m->tblk[2 * (size_t)i];
        moments_add(&m->tbacc[5 * (size_t)i], (b[0] + I * b[1]) / m->block);
        b[0] = b[1] = 0;
    }
    m->nblocks++;
    m->inblock = 0;
}

int maskobs_add(maskobs *m, const float *frame)
{
    size_t n = (size_t)m->w * m->h;
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(frame[i]))
            return sl_seterr(&m->err, SL_EDATA, "mask observables: pixel "
                             "(%zu, %zu) of frame %d is not finite", i % m->w,
                             i / m->w, m->nframes + m->nskipped);
        m->in[i] = frame[i];
    }
    fftwf_execute(m->plan);
    double f0 = crealf(m->out[0]);
    if (!(f0 > 0)) {
        m->nskipped++;
        return SL_OK;
    }
    accumulate(m, f0);
    m->nframes++;
    if (++m->inblock == m->block)
        close_block(m);
    return SL_OK;
}

/* Mean and variance of n samples from a sum and a sum of squares. */
static void mean_var(double s, double s2, int n, double *mean, double *var)
{
    *mean = s / n;
    *var = fmax((s2 - n * *mean * *mean) / (n - 1), 0);
}

/* Variances of n complex samples (moments a) across and along
 * direction th: *vperp, *vpar. */
static void perp_par(const double *a, int n, double th, double *vperp,
                     double *vpar)
{
    double mr = a[0] / n, mi = a[1] / n;
    double vrr = (a[2] - n * mr * mr) / (n - 1), vii = (a[3] - n * mi * mi) / (n - 1);
    double vri = (a[4] - n * mr * mi) / (n - 1), c = cos(th), s = sin(th);
    *vperp = fmax(vrr * s * s - 2 * vri * s * c + vii * c * c, 0);
    *vpar = fmax(vrr * c * c + 2 * vri * s * c + vii * s * s, 0);
}

static int by_value(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median of the n finite ratios in r (sorted in place), at least 1; 1
 * when none. */
static double pooled_factor(double *r, int n)
{
    int k = 0;
    for (int i = 0; i < n; i++)
        if (isfinite(r[i]))
            r[k++] = r[i];
    if (k == 0)
        return 1.0;
    qsort(r, (size_t)k, sizeof *r, by_value);
    double med = k % 2 ? r[k / 2] : 0.5 * (r[k / 2 - 1] + r[k / 2]);
    return fmax(med, 1.0);
}

/* The correlation factors (maskobs.h, Errors) into out; scratch: one
 * double per row. */
static void correlation_factors(const maskobs *m, double *scratch,
                                maskobs_result *out)
{
    out->corr_vis2 = out->corr_phi = out->corr_amp = 1.0;
    if (m->nblocks < 4)
        return;
    int nb = m->nblocks, n = m->nframes, B = m->block;
    for (int i = 0; i < m->nvis2; i++) {
        double mf, vf, mb, vb;
        mean_var(m->vacc[2 * i], m->vacc[2 * i + 1], n, &mf, &vf);
        mean_var(m->vbacc[2 * i], m->vbacc[2 * i + 1], nb, &mb, &vb);
        scratch[i] = vb * B / vf;
    }
    out->corr_vis2 = pooled_factor(scratch, m->nvis2);
    for (int pass = 0; pass < 2; pass++) {
        for (int i = 0; i < m->nt3; i++) {
            const double *a = &m->tacc[5 * (size_t)i];
            double th = atan2(a[1], a[0]), fp, fa, bp, ba;
            perp_par(a, n, th, &fp, &fa);
            perp_par(&m->tbacc[5 * (size_t)i], nb, th, &bp, &ba);
            scratch[i] = pass == 0 ? bp * B / fp : ba * B / fa;
        }
        *(pass == 0 ? &out->corr_phi : &out->corr_amp) = pooled_factor(scratch, m->nt3);
    }
}

static void t3_result(const maskobs *m, int i, const maskobs_result *res,
                      maskobs_t3 *r)
{
    const double *a = &m->tacc[5 * (size_t)i];
    int n = m->nframes;
    double mod = hypot(a[0], a[1]) / n, th = atan2(a[1], a[0]), vperp, vpar;
    perp_par(a, n, th, &vperp, &vpar);
    double tr = m->t3_transfer[i];
    r->phi_deg = th * 180.0 / M_PI;
    /* beyond 180 deg the phase is simply unknown */
    r->phi_err_deg = sqrt(vperp * res->corr_phi / n) / mod * 180.0 / M_PI;
    if (!(r->phi_err_deg <= 180.0))
        r->phi_err_deg = 180.0;
    r->amp = mod / tr;
    r->amp_err = sqrt(vpar * res->corr_amp / n) / tr;
}

int maskobs_result_get(maskobs *m, maskobs_result *out)
{
    memset(out, 0, sizeof *out);
    if (m->nframes < 2)
        return sl_seterr(&m->err, SL_EDATA, "mask observables: %d usable "
                         "frames (%d without flux); errors need at least 2",
                         m->nframes, m->nskipped);
    int nmax = m->nvis2 > m->nt3 ? m->nvis2 : m->nt3;
    double *scratch = malloc((size_t)(nmax ? nmax : 1) * sizeof *scratch);
    out->vis2 = malloc((size_t)(m->nvis2 ? m->nvis2 : 1) * sizeof *out->vis2);
    out->t3 = malloc((size_t)m->nt3 * sizeof *out->t3);
    if (!scratch || !out->vis2 || !out->t3) {
        free(scratch);
        maskobs_result_clear(out);
        return sl_seterr(&m->err, SL_ENOMEM, "mask observables: out of memory");
    }
    *out = (maskobs_result){m->nholes, m->nframes, m->nskipped, m->nvis2, m->nt3,
                            m->nvis2_lost, m->nt3_lost, m->nblocks, 1, 1, 1,
                            out->vis2, out->t3};
    correlation_factors(m, scratch, out);
    free(scratch);
    for (int i = 0; i < m->nvis2; i++) {
        maskobs_vis2 *v = &out->vis2[i];
        *v = m->vis2[i];
        double t2 = v->transfer * v->transfer, var;
        mean_var(m->vacc[2 * i], m->vacc[2 * i + 1], m->nframes, &v->vis2, &var);
        v->vis2 /= t2;
        v->vis2_err = sqrt(var * out->corr_vis2 / m->nframes) / t2;
    }
    for (int i = 0; i < m->nt3; i++) {
        out->t3[i] = m->t3[i];
        t3_result(m, i, out, &out->t3[i]);
    }
    return SL_OK;
}

void maskobs_result_clear(maskobs_result *r)
{
    free(r->vis2);
    free(r->t3);
    memset(r, 0, sizeof *r);
}
