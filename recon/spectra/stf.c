/* stf.c - see stf.h. */
#include "stf.h"

#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "base/tpool.h"

/* The realisations are summed in STF_GROUPS contiguous groups, each into
 * its own partial sums, and the groups added in group order: the grouping,
 * not the thread count, fixes the rounding, so 1 thread and 7 give the
 * same bits.  8 keeps up to 8 threads busy (the group is the unit of
 * work) for 24 g^2 bytes a group: 1.0 MB in all at dp 32, 1.9 MB at 48. */
enum { STF_GROUPS = 8, STF_MAX_THREADS = 64 };

/* One thread's buffers: each its own fftw_alloc_complex, so that every
 * one has the alignment the plan was made with (g may be odd). */
typedef struct stf_scratch {
    fftw_complex *buf;     /* g x g */
    fftw_complex *ramp;    /* 2 g: one realisation's alignment ramps */
} stf_scratch;

struct stf_model {
    int dp, g, nreal, npup, nthr;
    int *pup;              /* npup indices of the pupil's pixels in g x g */
    double *screen;        /* nreal x npup unit-r0 (1 px) phases, rad */
    double *gp2;           /* STF_GROUPS x g x g: each group's sum of |T|^2 */
    fftw_complex *gle;     /* STF_GROUPS x g x g: each group's sum of T */
    stf_scratch *scr;      /* nthr */
    tpool *pool;           /* nthr = min(nthreads, STF_GROUPS) threads */
    fftw_plan plan;        /* in place, forward, on scr[0].buf's alignment */
    double *t0;            /* nbins: diffraction OTF */
};

/* The least n' >= n with no prime factor above 5: FFTW's fast sizes (a
 * factor of 17 made the fit's transforms several times slower). */
static int fft_size(int n)
{
    for (;; n++) {
        int r = n;
        while (r % 2 == 0)
            r /= 2;
        while (r % 3 == 0)
            r /= 3;
        while (r % 5 == 0)
            r /= 5;
        if (r == 1)
            return n;
    }
}

/* Three levels of subharmonics (Lane et al. 1992) added to the complex
 * screen pair k, k + 1 at the pupil's pixels: a periodic grid G across
 * has no power at scales past G, which the long exposure's tilt-free part
 * still feels at the pupil's scale. */
static void add_subharmonics(stf_model *m, rng *r, int G, int off, int k)
{
    double complex c[3][3];
    for (int l = 1; l <= 3; l++) {
        double df = 1.0 / (G * pow(3, l));
        for (int b = -1; b <= 1; b++)
            for (int a = -1; a <= 1; a++) {
                double f = hypot(a, b) * df;
                double amp = f > 0 ? sqrt(0.023 * pow(f, -11.0 / 3)) * df : 0;
                double re = rng_normal(r), im = rng_normal(r);
                c[b + 1][a + 1] = amp * (re + I * im);
            }
        for (int t = 0; t < m->npup; t++) {
            int x = m->pup[t] % m->g - off, y = m->pup[t] / m->g - off;
            double complex ex = cexp(2 * M_PI * I * df * x), ey = cexp(2 * M_PI * I * df * y);
            double complex exs[3] = {conj(ex), 1, ex}, eys[3] = {conj(ey), 1, ey}, v = 0;
            for (int b = 0; b < 3; b++)
                for (int a = 0; a < 3; a++)
                    v += c[b][a] * exs[a] * eys[b];
            m->screen[(size_t)k * m->npup + t] += creal(v);
            if (k + 1 < m->nreal)
                m->screen[(size_t)(k + 1) * m->npup + t] += cimag(v);
        }
    }
}

/* The screens' draw, shared by the threads: the spectrum's amplitudes,
 * the transform (executed on each thread's own buffer) and the next pair
 * to claim. */
typedef struct draw_job {
    stf_model *m;
    const double *amp;
    fftw_plan plan;
    fftw_complex *buf[STF_GROUPS];
    int G, off;
    uint64_t seed;
    atomic_int next;
} draw_job;

/* Screen pair k, k + 1: the real and imaginary parts of one transform of
 * white noise shaped by amp, each from the pair's own random stream, so
 * that the pairs come out the same whichever thread draws them. */
static void draw_pair(draw_job *d, fftw_complex *s, int k)
{
    stf_model *m = d->m;
    size_t nn = (size_t)d->G * d->G;
    rng r;
    rng_init(&r, d->seed, 0x57f + (uint64_t)k);
    for (size_t t = 0; t < nn; t++) {
        double re = rng_normal(&r), im = rng_normal(&r);
        s[t] = d->amp[t] * (re + I * im);
    }
    fftw_execute_dft(d->plan, s, s);
    for (int t = 0; t < m->npup; t++) {
        int x = m->pup[t] % m->g - d->off, y = m->pup[t] / m->g - d->off;
        fftw_complex v = s[(size_t)y * d->G + x];
        m->screen[(size_t)k * m->npup + t] = creal(v);
        if (k + 1 < m->nreal)
            m->screen[(size_t)(k + 1) * m->npup + t] = cimag(v);
    }
    add_subharmonics(m, &r, d->G, d->off, k);
}

/* tpool job: draw the pairs claimed. */
static void draw_run(void *ctx, int tid, int n)
{
    draw_job *d = ctx;
    (void)n;
    for (int k; (k = 2 * atomic_fetch_add(&d->next, 1)) < d->m->nreal;)
        draw_pair(d, d->buf[tid], k);
}

/* Unit screens: r0 = 1 px, Kolmogorov phase spectrum 0.023 r0^(-5/3)
 * f^(-11/3) drawn on a periodic grid twice the pupil across, with
 * subharmonics for the larger scales, and cut to the pupil.  The real and
 * imaginary parts of one transform are two independent screens.  Drawn
 * on the model's threads, a pair at a time: serially they were 17 ms of
 * the fine model's 29 (dp 48, 64 screens), on the critical path. */
static int draw_screens(stf_model *m, uint64_t seed)
{
    int G = fft_size(2 * m->dp), rc = SL_ENOMEM;
    size_t nn = (size_t)G * G;
    draw_job d = {.m = m, .G = G, .seed = seed, .off = m->g / 2 - m->dp / 2 - 1};
    double *amp = malloc(nn * sizeof *amp);
    for (int i = 0; i < m->nthr; i++)
        if (!(d.buf[i] = fftw_alloc_complex(nn)))
            goto free_bufs;
    /* every buffer has fftw_malloc's alignment, as the plan's */
    if (!amp || !(d.plan = fftw_plan_dft_2d(G, G, d.buf[0], d.buf[0], FFTW_FORWARD,
                                            FFTW_ESTIMATE)))
        goto free_bufs;
    for (int j = 0; j < G; j++)
        for (int i = 0; i < G; i++) {
            double fx = (i <= G / 2 ? i : i - G) / (double)G;
            double fy = (j <= G / 2 ? j : j - G) / (double)G;
            double f = hypot(fx, fy);
            amp[(size_t)j * G + i] = f > 0 ? sqrt(0.023 * pow(f, -11.0 / 3)) / G : 0;
        }
    d.amp = amp;
    tpool_run(m->pool, draw_run, &d);
    fftw_destroy_plan(d.plan);
    rc = SL_OK;
free_bufs:
    for (int i = 0; i < m->nthr; i++)
        fftw_free(d.buf[i]);
    free(amp);
    return rc;
}

/* Mean of |v|^2 (or v) over the rings of radius i px, i <= dp. */
static void radial(const stf_model *m, const double *v, double *out)
{
    int nb = m->dp + 1;
    double *cnt = calloc((size_t)nb, sizeof *cnt);
    memset(out, 0, (size_t)nb * sizeof *out);
    if (!cnt)
        return;
    for (int j = 0; j < m->g; j++)
        for (int i = 0; i < m->g; i++) {
            int p = i <= m->g / 2 ? i : i - m->g, q = j <= m->g / 2 ? j : j - m->g;
            long b = lround(hypot(p, q));
            if (b < nb) {
                out[b] += v[(size_t)j * m->g + i];
                cnt[b]++;
            }
        }
    for (int b = 0; b < nb; b++)
        out[b] = cnt[b] > 0 ? out[b] / cnt[b] : 0;
    free(cnt);
}

/* The transfer function of pupil field phases phi (or none), normalised to
 * 1 at 0, into sc->buf; aligned on its first-harmonic centroid.  Any
 * thread, on its own scratch: the new-array execute is thread-safe. */
static void transfer(const stf_model *m, stf_scratch *sc, const double *phi,
                     double scale)
{
    size_t n = (size_t)m->g * m->g;
    fftw_complex *buf = sc->buf;
    memset(buf, 0, n * sizeof *buf);
    for (int t = 0; t < m->npup; t++)
        buf[m->pup[t]] = phi ? cexp(I * scale * phi[t]) : 1.0;
    fftw_execute_dft(m->plan, buf, buf);
    for (size_t k = 0; k < n; k++)
        buf[k] = creal(buf[k]) * creal(buf[k]) + cimag(buf[k]) * cimag(buf[k]);
    fftw_execute_dft(m->plan, buf, buf);
    double dc = creal(buf[0]);
    double ax = carg(buf[1]), ay = carg(buf[m->g]);
    fftw_complex *ex = sc->ramp, *ey = sc->ramp + m->g;
    for (int i = 0; i < m->g; i++) {
        int p = i <= m->g / 2 ? i : i - m->g;
        ex[i] = cexp(-I * p * ax) / dc;
        ey[i] = cexp(-I * p * ay);
    }
    for (int j = 0; j < m->g; j++)
        for (int i = 0; i < m->g; i++)
            buf[(size_t)j * m->g + i] *= ex[i] * ey[j];
}

/* The arrays of m: pupil indices, group sums, t0, and nthr scratches. */
static int alloc_arrays(stf_model *m, int nthr)
{
    size_t n = (size_t)m->g * m->g;
    m->pup = malloc(n * sizeof *m->pup);
    m->gp2 = malloc(STF_GROUPS * n * sizeof *m->gp2);
    m->gle = malloc(STF_GROUPS * n * sizeof *m->gle);
    m->t0 = malloc((size_t)(m->dp + 1) * sizeof *m->t0);
    m->scr = calloc((size_t)nthr, sizeof *m->scr);
    if (!m->pup || !m->gp2 || !m->gle || !m->t0 || !m->scr)
        return SL_ENOMEM;
    m->nthr = nthr;
    for (int i = 0; i < nthr; i++) {
        m->scr[i].buf = fftw_alloc_complex(n);
        m->scr[i].ramp = fftw_alloc_complex(2 * (size_t)m->g);
        if (!m->scr[i].buf || !m->scr[i].ramp)
            return SL_ENOMEM;
    }
    return SL_OK;
}

stf_model *stf_model_new(int dp, int nreal, int nthreads, uint64_t seed,
                         sl_err *err)
{
    if (dp < 16 || dp > 128 || nreal < 8) {
        sl_seterr(err, SL_EINVAL, "stf_model_new: pupil %d px (16..128), "
                  "%d realisations (>= 8)", dp, nreal);
        return NULL;
    }
    if (nthreads < 1 || nthreads > STF_MAX_THREADS) {
        sl_seterr(err, SL_EINVAL, "stf_model_new: %d threads (1..%d)",
                  nthreads, STF_MAX_THREADS);
        return NULL;
    }
    stf_model *m = calloc(1, sizeof *m);
    if (!m)
        goto fail_nomem;
    m->dp = dp;
    m->g = fft_size(2 * dp + 4); /* the OTF's support, 2 dp + 1, does not wrap */
    m->nreal = nreal;
    /* threads past the groups' count would have nothing to do */
    int nthr = nthreads < STF_GROUPS ? nthreads : STF_GROUPS;
    if (alloc_arrays(m, nthr) != SL_OK)
        goto fail_nomem;
    if (!(m->pool = tpool_new(nthr, err)))
        goto free_model;
    for (int y = 0; y < m->g; y++)
        for (int x = 0; x < m->g; x++)
            if (hypot(x + 0.5 - m->g / 2, y + 0.5 - m->g / 2) <= 0.5 * dp)
                m->pup[m->npup++] = y * m->g + x;
    m->screen = malloc((size_t)nreal * m->npup * sizeof *m->screen);
    /* planned here, on the caller: FFTW's planner is not thread-safe */
    m->plan = fftw_plan_dft_2d(m->g, m->g, m->scr[0].buf, m->scr[0].buf,
                               FFTW_FORWARD, FFTW_ESTIMATE);
    if (!m->screen || !m->plan || draw_screens(m, seed) != SL_OK)
        goto fail_nomem;
    transfer(m, &m->scr[0], NULL, 0);
    double *re = m->gp2; /* scratch: g x g doubles */
    for (size_t k = 0, n = (size_t)m->g * m->g; k < n; k++)
        re[k] = creal(m->scr[0].buf[k]);
    radial(m, re, m->t0);
    return m;
fail_nomem:
    sl_seterr(err, SL_ENOMEM, "stf_model_new: out of memory");
free_model:
    stf_model_free(m);
    return NULL;
}

void stf_model_free(stf_model *m)
{
    if (!m)
        return;
    tpool_free(m->pool);
    if (m->plan)
        fftw_destroy_plan(m->plan);
    for (int i = 0; m->scr && i < m->nthr; i++) {
        fftw_free(m->scr[i].buf);
        fftw_free(m->scr[i].ramp);
    }
    free(m->scr);
    free(m->gp2);
    free(m->gle);
    free(m->pup);
    free(m->screen);
    free(m->t0);
    free(m);
}

int stf_model_nbins(const stf_model *m) { return m ? m->dp + 1 : 0; }

typedef struct eval_job {
    stf_model *m;
    double scale;
} eval_job;

/* Group c's realisations [c nreal / G, (c + 1) nreal / G) summed into its
 * own slices of gp2 and gle, on the scratch of thread tid. */
static void sum_group(stf_model *m, int tid, int c, double scale)
{
    size_t n = (size_t)m->g * m->g;
    double *p2 = m->gp2 + c * n;
    fftw_complex *ls = m->gle + c * n, *buf = m->scr[tid].buf;
    memset(p2, 0, n * sizeof *p2);
    memset(ls, 0, n * sizeof *ls);
    int r0 = (int)((long)c * m->nreal / STF_GROUPS);
    int r1 = (int)((long)(c + 1) * m->nreal / STF_GROUPS);
    for (int r = r0; r < r1; r++) {
        transfer(m, &m->scr[tid], m->screen + (size_t)r * m->npup, scale);
        for (size_t k = 0; k < n; k++) {
            double re = creal(buf[k]), im = cimag(buf[k]);
            p2[k] += re * re + im * im;
            ls[k] += buf[k];
        }
    }
}

/* Group c on thread c mod nthreads. */
static void eval_groups(void *ctx, int tid, int nthreads)
{
    eval_job *j = ctx;
    for (int c = tid; c < STF_GROUPS; c += nthreads)
        sum_group(j->m, tid, c, j->scale);
}

int stf_model_eval(stf_model *m, double d_r0, double *stf, double *le,
                   double *t0)
{
    if (!m || !(d_r0 > 0))
        return SL_EINVAL;
    size_t n = (size_t)m->g * m->g;
    int nb = m->dp + 1;
    double *l2 = malloc(n * sizeof *l2);
    if (!l2)
        return SL_ENOMEM;
    /* phase scales as r0^(-5/6); r0 = dp / (D/r0) px */
    eval_job job = {m, pow(m->dp / d_r0, -5.0 / 6)};
    tpool_run(m->pool, eval_groups, &job);
    /* the groups in group order into group 0's slices */
    double *p2 = m->gp2, inv = 1.0 / m->nreal;
    fftw_complex *ls = m->gle;
    for (int c = 1; c < STF_GROUPS; c++)
        for (size_t k = 0; k < n; k++) {
            p2[k] += m->gp2[c * n + k];
            ls[k] += m->gle[c * n + k];
        }
    /* |mean|^2 is biased by var / nreal: the unbiased form */
    for (size_t k = 0; k < n; k++) {
        double mean2 = creal(ls[k]) * creal(ls[k]) + cimag(ls[k]) * cimag(ls[k]);
        mean2 *= inv * inv;
        p2[k] *= inv;
        l2[k] = mean2 - (p2[k] - mean2) / (m->nreal - 1);
    }
    if (stf)
        radial(m, p2, stf);
    if (le)
        radial(m, l2, le);
    if (t0)
        memcpy(t0, m->t0, (size_t)nb * sizeof *t0);
    free(l2);
    return SL_OK;
}

/* Squared misfit of the model's eps at d_r0 to eps over 0 < i <= dp / 2,
 * less a constant offset b in [0, 0.5] fitted with it: frames that are
 * not independent (wind carries one screen across many of them) leave
 * |<I>|^2 biased by <|I|^2> (1 / n_eff - 1 / n), a constant in the
 * ratio.  40 frames of 10 m/s wind read eps ~0.1 where it is 0. */
static double misfit(stf_model *m, const double *eps, double d_r0,
                     double *stf, double *le, double *b_out)
{
    if (stf_model_eval(m, d_r0, stf, le, NULL) != SL_OK)
        return INFINITY;
    double num = 0, den = 0, s = 0;
    for (int i = 1; i <= m->dp / 2; i++)
        if (isfinite(eps[i]) && stf[i] > 0) {
            double e = le[i] / stf[i];   /* eps - e = b (1 - e): least squares */
            num += (eps[i] - e) * (1 - e);
            den += (1 - e) * (1 - e);
        }
    double b = den > 0 ? fmin(fmax(num / den, 0), 0.5) : 0;
    for (int i = 1; i <= m->dp / 2; i++)
        if (isfinite(eps[i]) && stf[i] > 0) {
            double d = eps[i] - (b + (1 - b) * le[i] / stf[i]);
            s += d * d;
        }
    if (b_out)
        *b_out = b;
    return s;
}

int stf_model_fit(stf_model *m, const double *eps, double *d_r0, double *rms)
{
    if (!m || !eps || !d_r0)
        return SL_EINVAL;
    int nok = 0, nb = m->dp + 1;
    for (int i = 1; i <= m->dp / 2; i++)
        nok += isfinite(eps[i]);
    if (nok < 4)
        return SL_EDATA;
    double *stf = malloc((size_t)nb * sizeof *stf), *le = malloc((size_t)nb * sizeof *le);
    if (!stf || !le) {
        free(stf), free(le);
        return SL_ENOMEM;
    }
    /* A log grid over [1, 40], then golden section around its best. */
    enum { NGRID = 13 };
    double lo = log(1.0), hi = log(40.0), step = (hi - lo) / (NGRID - 1);
    double best = INFINITY;
    int ib = 0;
    for (int i = 0; i < NGRID; i++) {
        double c = misfit(m, eps, exp(lo + i * step), stf, le, NULL);
        if (c < best)
            best = c, ib = i;
    }
    double a = lo + (ib > 0 ? ib - 1 : 0) * step;
    double b = lo + (ib < NGRID - 1 ? ib + 1 : NGRID - 1) * step;
    const double gr = 0.5 * (sqrt(5.0) - 1);
    double x1 = b - gr * (b - a), x2 = a + gr * (b - a);
    double f1 = misfit(m, eps, exp(x1), stf, le, NULL), f2 = misfit(m, eps, exp(x2), stf, le, NULL);
    for (int it = 0; it < 8; it++) {
        if (f1 < f2) {
            b = x2, x2 = x1, f2 = f1;
            x1 = b - gr * (b - a);
            f1 = misfit(m, eps, exp(x1), stf, le, NULL);
        } else {
            a = x1, x1 = x2, f1 = f2;
            x2 = a + gr * (b - a);
            f2 = misfit(m, eps, exp(x2), stf, le, NULL);
        }
    }
    double xm = f1 < f2 ? x1 : x2, fm = f1 < f2 ? f1 : f2;
    *d_r0 = fm <= best ? exp(xm) : exp(lo + ib * step);
    if (rms)
        *rms = sqrt(fmin(fm, best) / nok);
    free(stf), free(le);
    return SL_OK;
}

/* rho / rho_c of the frequency (x, y) in cycles per pixel, in bins of
 * 1 / dp. */
static double bin_pos(double x, double y, double rc_cyc, int nbins)
{
    return hypot(x, y) / rc_cyc * (nbins - 1);
}

void stf_spectral_ratio(const double *ps, const double *le, int w, int h,
                        double rc_cyc, int nbins, double *eps)
{
    double *sp = calloc((size_t)nbins, sizeof *sp), *sl = calloc((size_t)nbins, sizeof *sl);
    for (int b = 0; b < nbins; b++)
        eps[b] = NAN;
    if (!sp || !sl || !(rc_cyc > 0)) {
        free(sp), free(sl);
        return;
    }
    double k = (nbins - 1) / rc_cyc;
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            /* the nearest bin, by bin_pos only within STF_MARGIN of a
             * half-integer (stf.h) */
            double x, y;
            stf_freq_cyc(i, j, w, h, &x, &y);
            double pos = sqrt(x * x + y * y) * k, fr = pos - floor(pos);
            long b = fabs(fr - 0.5) < STF_MARGIN ? lround(bin_pos(x, y, rc_cyc, nbins))
                                                 : (long)floor(pos + 0.5);
            if (b < nbins) {
                sp[b] += ps[(size_t)j * w + i];
                sl[b] += le[(size_t)j * w + i];
            }
        }
    for (int b = 0; b < nbins; b++)
        if (sp[b] > 0)
            eps[b] = sl[b] / sp[b];
    free(sp), free(sl);
}

void stf_modulus(const double *ps, int w, int h, double rc_cyc,
                 const double *stf, const double *t0, int nbins, double *mod)
{
    for (int j = 0; j < h; j++)
        for (int i = 0; i < w; i++) {
            size_t k = (size_t)j * w + i;
            double fx, fy;
            stf_freq_cyc(i, j, w, h, &fx, &fy);
            if (fx * fx + fy * fy > rc_cyc * rc_cyc * (1 + STF_MARGIN)) {
                mod[k] = 0; /* beyond the cut-off: bin_pos >= nbins - 1 */
                continue;
            }
            double x = bin_pos(fx, fy, rc_cyc, nbins);
            int b = (int)x;
            if (b >= nbins - 1) {
                mod[k] = 0;
                continue;
            }
            double f = x - b;
            double s = (1 - f) * stf[b] + f * stf[b + 1];
            double t = (1 - f) * t0[b] + f * t0[b + 1];
            mod[k] = s > 0 ? sqrt(fmax(ps[k], 0.0) / s) * t : 0;
        }
}
