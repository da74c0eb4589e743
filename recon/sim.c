/* sim.c - see sim.h for the physics, sampling and photometry. */
#include "sim.h"

#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rng.h"
#include "screen.h"

#define ARCSEC_PER_RAD (180.0 * 3600.0 / M_PI)
#define SCREEN_MAX_PX 2048 /* peak 80 MiB while generating; longer flows change lane */

struct sim {
    sim_opts o;
    sl_err err;
    char warning[320];
    int M, k;            /* grid size, oversampling factor */
    int win, win0;       /* pupil window size and origin in the grid */
    double pscale;       /* arcsec per output pixel */
    double p_nyq;        /* Nyquist plate scale, arcsec */
    double dx, E;        /* pupil pitch and extent, m */
    double psf_scale;    /* 1 / sum |FFT(field)|^2 */
    float *pupil;        /* win x win transmission */
    float *phase;        /* win x win, radians */
    float *truth;        /* w x h, relative flux */
    fftwf_complex *fin, *fout;   /* M x M pupil field and its FFT */
    float *psf;                  /* M x M */
    fftwf_complex *otf, *obj;    /* M x (M/2+1) */
    float *img;                  /* M x M convolved image */
    fftwf_plan p_field, p_psf, p_img;
    screen *scr;
};

void sim_opts_defaults(sim_opts *o)
{
    memset(o, 0, sizeof *o);
    o->width = o->height = 256;
    o->nframes = 100;
    o->wavelength_m = 500e-9;
    o->plate_scale_arcsec = 0;
    o->r0_m = 0.2;
    o->L0_m = INFINITY;
    o->wind_mps = 10;
    o->wind_dir_deg = 0;
    o->frame_interval_s = 0.01;
    o->exposure_s = 0.01;
    o->turbulence = 1;
    o->seed = 1;
    o->photons_per_frame = 0;
    o->read_noise_e = 0;
    o->gain_e_per_adu = 1;
    o->bias_adu = 0;
    o->saturation_adu = 65535;
    o->fftw_flags = FFTW_MEASURE;
}

const char *sim_errmsg(const sim *s) { return s ? s->err.msg : "no simulator"; }
double sim_plate_scale_arcsec(const sim *s) { return s->pscale; }
double sim_nyquist_arcsec(const sim *s) { return s->p_nyq; }
int sim_oversample(const sim *s) { return s->k; }
int sim_grid(const sim *s) { return s->M; }
double sim_pupil_pitch_m(const sim *s) { return s->dx; }
double sim_pupil_extent_m(const sim *s) { return s->E; }
const char *sim_warning(const sim *s) { return s->warning; }
const sim_opts *sim_options(const sim *s) { return &s->o; }
int sim_window_px(const sim *s) { return s->win; }

static int check_opts(const sim_opts *o, sl_err *e)
{
    if (o->width < 8 || o->height < 8 || o->width > 8192 || o->height > 8192)
        return sl_seterr(e, SL_EINVAL, "frame size %dx%d: each side must lie "
                         "in [8, 8192] pixels", o->width, o->height);
    if (o->nframes < 1)
        return sl_seterr(e, SL_EINVAL, "frames = %d: need at least 1",
                         o->nframes);
    if (!(o->wavelength_m > 0 && o->wavelength_m < 1e-4))
        return sl_seterr(e, SL_EINVAL, "wavelength %g m is not a plausible "
                         "optical wavelength", o->wavelength_m);
    if (!(o->plate_scale_arcsec >= 0 && isfinite(o->plate_scale_arcsec)))
        return sl_seterr(e, SL_EINVAL, "plate scale %g arcsec/px must be >= 0 "
                         "(0 = Nyquist)", o->plate_scale_arcsec);
    if (o->turbulence && !(o->r0_m > 0 && isfinite(o->r0_m)))
        return sl_seterr(e, SL_EINVAL, "r0 = %g m must be > 0", o->r0_m);
    if (!(o->wind_mps >= 0 && isfinite(o->wind_mps)) ||
        !(o->frame_interval_s >= 0 && isfinite(o->frame_interval_s)))
        return sl_seterr(e, SL_EINVAL, "wind speed and frame interval must be "
                         ">= 0");
    if (!(o->photons_per_frame >= 0 && isfinite(o->photons_per_frame)))
        return sl_seterr(e, SL_EINVAL, "photons per frame %g must be >= 0",
                         o->photons_per_frame);
    if (o->photons_per_frame > 0 &&
        !(o->gain_e_per_adu > 0 && o->read_noise_e >= 0 &&
          o->saturation_adu > o->bias_adu))
        return sl_seterr(e, SL_EINVAL, "detector needs gain > 0, read noise "
                         ">= 0 and saturation above bias");
    return SL_OK;
}

/* Sampling: choose the plate scale, oversampling and grid (see sim.h). */
static int plan_sampling(sim *s, const mask *m)
{
    const sim_opts *o = &s->o;
    s->E = mask_extent_m(m);
    if (!(s->E > 0))
        return sl_seterr(&s->err, SL_EINVAL, "pupil has no extent");
    s->p_nyq = o->wavelength_m / (2 * s->E) * ARCSEC_PER_RAD;
    s->pscale = o->plate_scale_arcsec > 0 ? o->plate_scale_arcsec : s->p_nyq;
    s->k = (int)ceil(s->pscale / s->p_nyq - 1e-9);
    if (s->k < 1)
        s->k = 1;
    if (s->k > 1)
        snprintf(s->warning, sizeof s->warning,
                 "plate scale %.4f arcsec/px undersamples the %.3f m pupil's "
                 "fringes at %.0f nm (Nyquist is %.4f arcsec/px): they alias; "
                 "simulating %dx finer and binning", s->pscale, s->E,
                 o->wavelength_m * 1e9, s->p_nyq, s->k);
    int side = o->width > o->height ? o->width : o->height;
    if ((long)side * s->k > 16384)
        return sl_seterr(&s->err, SL_ERANGE, "grid %d x %d needed for plate "
                         "scale %.4f arcsec/px is too large; choose a finer "
                         "plate scale or smaller frames", side * s->k,
                         side * s->k, s->pscale);
    s->M = side * s->k;
    double p_int_rad = s->pscale / s->k / ARCSEC_PER_RAD;
    s->dx = o->wavelength_m / (s->M * p_int_rad);
    s->win = (int)ceil(s->E / s->dx) + 4;
    if (s->win > s->M)
        s->win = s->M;
    s->win0 = s->M / 2 - s->win / 2;
    return SL_OK;
}

static int make_pupil(sim *s, const mask *m)
{
    size_t MM = (size_t)s->M * s->M;
    float *full = calloc(MM, sizeof *full);
    if (!full)
        return sl_seterr(&s->err, SL_ENOMEM, "out of memory for the pupil");
    int rc = mask_render(m, full, s->M, s->dx, &s->err);
    if (rc != SL_OK)
        goto free_full;
    double total = 0, inwin = 0;
    for (size_t i = 0; i < MM; i++)
        total += full[i];
    for (int y = 0; y < s->win; y++)
        for (int x = 0; x < s->win; x++) {
            float v = full[(size_t)(s->win0 + y) * s->M + s->win0 + x];
            s->pupil[(size_t)y * s->win + x] = v;
            inwin += v;
        }
    if (!(total > 0) || fabs(inwin - total) > 1e-6 * total) {
        rc = sl_seterr(&s->err, SL_EINVAL, "pupil transmission is empty or "
                       "outside its window");
        goto free_full;
    }
    /* Parseval: sum |FFT(field)|^2 = M^2 sum |pupil|^2, for any phase. */
    double p2 = 0;
    for (int i = 0; i < s->win * s->win; i++)
        p2 += (double)s->pupil[i] * s->pupil[i];
    s->psf_scale = 1.0 / ((double)MM * p2);
free_full:
    free(full);
    return rc;
}

static int make_screen(sim *s)
{
    const sim_opts *o = &s->o;
    if (!o->turbulence)
        return SL_OK;
    double travel_px = o->wind_mps * o->frame_interval_s *
                       (o->nframes - 1) / s->dx;
    int need = (int)ceil(travel_px) + s->win;
    if (need < 2 * s->win)
        need = 2 * s->win;
    int n = 64;
    while (n < need && n < SCREEN_MAX_PX)
        n *= 2;
    /* Past SCREEN_MAX_PX the flow changes lane each lap of the grid
     * (sim_phase_window) instead of repeating it. */
    screen_opts so;
    screen_opts_defaults(&so);
    so.n = n;
    so.dx_m = s->dx;
    so.r0_m = o->r0_m;
    so.L0_m = o->L0_m;
    so.seed = o->seed * 0x9E3779B97F4A7C15ULL + 1;
    return screen_new(&s->scr, &so, &s->err);
}

/* Object spectrum (r2c layout), centred where the output frame centre falls
 * on the fine grid, scaled so that c2r(otf * obj) has unit total flux. */
static int make_object(sim *s, const scene *sc)
{
    int M = s->M, H = M / 2 + 1, rc = SL_OK;
    double F = scene_total_flux(sc);
    if (!(F > 0))
        return sl_seterr(&s->err, SL_EINVAL, "scene has no flux");
    double pfine = s->pscale / s->k;
    /* Fine-grid position of the output centre pixel (w/2, h/2). */
    double cx = (M - s->k * s->o.width) / 2 + (s->o.width / 2) * s->k +
                (s->k - 1) / 2.0;
    double cy = (M - s->k * s->o.height) / 2 + (s->o.height / 2) * s->k +
                (s->k - 1) / 2.0;
    float *r = fftwf_alloc_real((size_t)M * M);
    if (!r)
        return sl_seterr(&s->err, SL_ENOMEM, "out of memory for the object");
    fftwf_plan p = fftwf_plan_dft_r2c_2d(M, M, r, s->obj, FFTW_ESTIMATE);
    scene_render(sc, r, M, M, pfine, 1); /* disks, centred at M/2 */
    fftwf_execute(p);
    double sx = cx - M / 2, sy = cy - M / 2, norm = 1.0 / (F * M * (double)M);
    for (int v = 0; v < M; v++) {
        double fv = (v <= M / 2 ? v : v - M) / (double)M;
        for (int u = 0; u < H; u++) {
            double fu = u / (double)M;
            double complex o = s->obj[(size_t)v * H + u];
            o *= cexp(-2 * M_PI * I * (fu * sx + fv * sy));
            for (int i = 0; i < scene_ncomp(sc); i++) {
                const scene_comp *c = scene_comp_at(sc, i);
                if (c->kind != SCENE_POINT)
                    continue;
                double X = cx + c->x_arcsec / pfine, Y = cy + c->y_arcsec / pfine;
                o += c->flux * cexp(-2 * M_PI * I * (fu * X + fv * Y));
            }
            s->obj[(size_t)v * H + u] = (float complex)(o * norm);
        }
    }
    fftwf_destroy_plan(p);
    fftwf_free(r);
    /* The truth on the output grid. */
    size_t np = (size_t)s->o.width * s->o.height;
    scene_render(sc, s->truth, s->o.width, s->o.height, s->pscale, 0);
    for (size_t i = 0; i < np; i++)
        s->truth[i] = (float)(s->truth[i] / F);
    return rc;
}

static int alloc_buffers(sim *s)
{
    size_t MM = (size_t)s->M * s->M, MH = (size_t)s->M * (s->M / 2 + 1);
    s->pupil = calloc((size_t)s->win * s->win, sizeof(float));
    s->phase = calloc((size_t)s->win * s->win, sizeof(float));
    s->truth = calloc((size_t)s->o.width * s->o.height, sizeof(float));
    s->fin = fftwf_alloc_complex(MM);
    s->fout = fftwf_alloc_complex(MM);
    s->psf = fftwf_alloc_real(MM);
    s->img = fftwf_alloc_real(MM);
    s->otf = fftwf_alloc_complex(MH);
    s->obj = fftwf_alloc_complex(MH);
    if (!s->pupil || !s->phase || !s->truth || !s->fin || !s->fout ||
        !s->psf || !s->img || !s->otf || !s->obj)
        return sl_seterr(&s->err, SL_ENOMEM, "out of memory for a %d x %d "
                         "simulation grid", s->M, s->M);
    int M = s->M;
    unsigned fl = s->o.fftw_flags;
    s->p_field = fftwf_plan_dft_2d(M, M, s->fin, s->fout, FFTW_FORWARD, fl);
    s->p_psf = fftwf_plan_dft_r2c_2d(M, M, s->psf, s->otf, fl);
    s->p_img = fftwf_plan_dft_c2r_2d(M, M, s->otf, s->img, fl);
    if (!s->p_field || !s->p_psf || !s->p_img)
        return sl_seterr(&s->err, SL_ENOMEM, "FFTW could not plan %d x %d", M,
                         M);
    memset(s->fin, 0, MM * sizeof *s->fin); /* planning may scribble */
    return SL_OK;
}

int sim_new(sim **out, const sim_opts *o, const mask *m, const scene *sc,
            sl_err *err)
{
    *out = NULL;
    int rc = check_opts(o, err);
    if (rc != SL_OK)
        return rc;
    sim *s = calloc(1, sizeof *s);
    if (!s)
        return sl_seterr(err, SL_ENOMEM, "out of memory");
    s->o = *o;
    if ((rc = plan_sampling(s, m)) != SL_OK || (rc = alloc_buffers(s)) != SL_OK
        || (rc = make_pupil(s, m)) != SL_OK || (rc = make_screen(s)) != SL_OK
        || (rc = make_object(s, sc)) != SL_OK)
        goto free_sim;
    *out = s;
    return SL_OK;
free_sim:
    sl_seterr(err, rc, "%s", s->err.msg);
    sim_free(s);
    return rc;
}

void sim_free(sim *s)
{
    if (!s)
        return;
    if (s->p_field)
        fftwf_destroy_plan(s->p_field);
    if (s->p_psf)
        fftwf_destroy_plan(s->p_psf);
    if (s->p_img)
        fftwf_destroy_plan(s->p_img);
    fftwf_free(s->fin);
    fftwf_free(s->fout);
    fftwf_free(s->psf);
    fftwf_free(s->img);
    fftwf_free(s->otf);
    fftwf_free(s->obj);
    free(s->pupil);
    free(s->phase);
    free(s->truth);
    screen_free(s->scr);
    free(s);
}

int sim_phase_window(sim *s, int k, float *phase)
{
    size_t n = (size_t)s->win * s->win;
    if (!s->scr) {
        memset(phase, 0, n * sizeof *phase);
        return SL_OK;
    }
    /* Frozen flow along dir.  The screen's fine grid repeats every n dx
     * (22.5 m at 200^2 and Nyquist), so after each such lap of flow the
     * pupil moves sideways to a fresh lane (win + 2 px over): a long
     * sequence (more frames, a longer frame interval) sees new turbulence
     * for n / (win + 2) laps instead of the same frames again.  Within a
     * lap the flow is continuous; sequences shorter than one lap (the
     * default 100 frames at 10 ms, 10 m/s) are unchanged. */
    double t = k * s->o.frame_interval_s, dir = s->o.wind_dir_deg * M_PI / 180;
    double d = s->o.wind_mps * t, period = screen_n(s->scr) * s->dx;
    double lane = floor(d / period) * (s->win + 2) * s->dx;
    double x0 = (s->win0 - s->M / 2) * s->dx - d * cos(dir) + lane * sin(dir);
    double y0 = (s->win0 - s->M / 2) * s->dx - d * sin(dir) - lane * cos(dir);
    return screen_sample(s->scr, phase, s->win, s->win, x0, y0, s->dx);
}

/* PSF of frame k (k < 0: cophased) into s->psf, unit sum, origin at [0]. */
static int compute_psf(sim *s, int k)
{
    int rc = SL_OK;
    if (k >= 0)
        rc = sim_phase_window(s, k, s->phase);
    else
        memset(s->phase, 0, (size_t)s->win * s->win * sizeof *s->phase);
    if (rc != SL_OK)
        return rc;
    for (int y = 0; y < s->win; y++) {
        fftwf_complex *row = s->fin + (size_t)(s->win0 + y) * s->M + s->win0;
        const float *pu = s->pupil + (size_t)y * s->win;
        const float *ph = s->phase + (size_t)y * s->win;
        for (int x = 0; x < s->win; x++)
            row[x] = pu[x] * (cosf(ph[x]) + I * sinf(ph[x]));
    }
    fftwf_execute(s->p_field);
    size_t MM = (size_t)s->M * s->M;
    float sc = (float)s->psf_scale;
    for (size_t i = 0; i < MM; i++) {
        float re = crealf(s->fout[i]), im = cimagf(s->fout[i]);
        s->psf[i] = (re * re + im * im) * sc;
    }
    return SL_OK;
}

/* Convolve s->psf with the object into s->img (fine grid), then bin and
 * crop into out (w x h). */
static void convolve_bin(sim *s, float *out)
{
    size_t MH = (size_t)s->M * (s->M / 2 + 1);
    fftwf_execute(s->p_psf);
    for (size_t i = 0; i < MH; i++)
        s->otf[i] *= s->obj[i];
    fftwf_execute(s->p_img); /* destroys otf, by FFTW's c2r contract */
    int w = s->o.width, h = s->o.height, k = s->k;
    int ox = (s->M - k * w) / 2, oy = (s->M - k * h) / 2;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double sum = 0;
            for (int j = 0; j < k; j++) {
                const float *row = s->img + (size_t)(oy + y * k + j) * s->M +
                                   ox + x * k;
                for (int i = 0; i < k; i++)
                    sum += row[i];
            }
            out[(size_t)y * w + x] = (float)sum;
        }
}

static void detect(const sim *s, int k, float *frame)
{
    const sim_opts *o = &s->o;
    rng r;
    rng_init(&r, o->seed, 0x100000ULL + (uint64_t)k);
    size_t n = (size_t)o->width * o->height;
    for (size_t i = 0; i < n; i++) {
        double lam = frame[i] > 0 ? frame[i] * o->photons_per_frame : 0;
        double e = (double)rng_poisson(&r, lam);
        if (o->read_noise_e > 0)
            e += o->read_noise_e * rng_normal(&r);
        double adu = nearbyint(e / o->gain_e_per_adu + o->bias_adu);
        if (adu < 0)
            adu = 0;
        if (adu > o->saturation_adu)
            adu = o->saturation_adu;
        frame[i] = (float)adu;
    }
}

int sim_frame(sim *s, int k, float *frame)
{
    if (k < 0)
        return sl_seterr(&s->err, SL_EINVAL, "frame index %d < 0", k);
    int rc = compute_psf(s, k);
    if (rc != SL_OK)
        return rc;
    convolve_bin(s, frame);
    if (s->o.photons_per_frame > 0)
        detect(s, k, frame);
    return SL_OK;
}

int sim_cophased(sim *s, float *img)
{
    int rc = compute_psf(s, -1);
    if (rc == SL_OK)
        convolve_bin(s, img);
    return rc;
}

int sim_truth(sim *s, float *img)
{
    memcpy(img, s->truth, (size_t)s->o.width * s->o.height * sizeof *img);
    return SL_OK;
}

int sim_psf(sim *s, int k, float *psf)
{
    int rc = compute_psf(s, k < 0 ? -1 : k), M = s->M;
    if (rc != SL_OK)
        return rc;
    for (int y = 0; y < M; y++)
        for (int x = 0; x < M; x++)
            psf[(size_t)((y + M / 2) % M) * M + (x + M / 2) % M] =
                s->psf[(size_t)y * M + x];
    return SL_OK;
}
