/* sim.c - see sim.h for the physics, sampling and photometry.  This file
 * plans (options, sampling, pupil, screen, object, detector); sim_frame.c
 * renders frames. */
#include "sim.h"

#include <complex.h>
#include <fftw3.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sim_int.h"

#define SCREEN_MAX_PX 2048 /* peak 80 MiB while generating; longer flows change lane */

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
    o->hot_level_adu = NAN;
    o->pixel_aspect = 1;
    o->phase_model = SIM_PHASE_SCREEN;
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
const detector *sim_detector(const sim *s) { return s->det; }

static void detector_opts_of(const sim_opts *o, detector_opts *d)
{
    detector_opts_defaults(d);
    d->photons_per_frame = o->photons_per_frame;
    d->read_noise_e = o->read_noise_e;
    d->gain_e_per_adu = o->gain_e_per_adu;
    d->bias_adu = o->bias_adu;
    d->saturation_adu = o->saturation_adu;
    d->adc_bits = o->adc_bits;
    d->hot_pixels = o->hot_pixels;
    d->dead_pixels = o->dead_pixels;
    d->hot_level_adu = o->hot_level_adu;
}

int sim_output_bitpix(const sim *s)
{
    detector_opts d;
    detector_opts_of(&s->o, &d);
    return detector_bitpix(&d);
}

/* Pointing, pixel shape and phase model. */
static int check_geometry(const sim_opts *o, sl_err *e)
{
    if (!(fabs(o->offset_x_px) <= o->width / 2.0 &&
          fabs(o->offset_y_px) <= o->height / 2.0))
        return sl_seterr(e, SL_EINVAL, "offset (%g, %g) px must be finite and "
                         "within half the %dx%d frame", o->offset_x_px,
                         o->offset_y_px, o->width, o->height);
    int small = o->width < o->height ? o->width : o->height;
    if (!(o->jitter_px >= 0 && o->jitter_px <= small / 4.0))
        return sl_seterr(e, SL_EINVAL, "jitter %g px rms must lie in [0, %g] "
                         "(a quarter of the frame's smaller side)",
                         o->jitter_px, small / 4.0);
    if (!(o->pixel_aspect >= 0.5 && o->pixel_aspect <= 2))
        return sl_seterr(e, SL_EINVAL, "pixel aspect %g (pixel height / "
                         "width) must lie in [0.5, 2]", o->pixel_aspect);
    if (o->phase_model != SIM_PHASE_SCREEN &&
        o->phase_model != SIM_PHASE_PISTON)
        return sl_seterr(e, SL_EINVAL, "phase model %d is neither screen (%d) "
                         "nor piston (%d)", o->phase_model, SIM_PHASE_SCREEN,
                         SIM_PHASE_PISTON);
    return SL_OK;
}

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
    if (o->photons_per_frame == 0 &&
        (o->adc_bits != 0 || o->hot_pixels != 0 || o->dead_pixels != 0))
        return sl_seterr(e, SL_EINVAL, "ADC bits (%d), hot (%d) and dead "
                         "(%d) pixels model the detector: they need photons "
                         "per frame > 0 (noiseless frames are relative flux)",
                         o->adc_bits, o->hot_pixels, o->dead_pixels);
    if (o->photons_per_frame > 0) {
        detector_opts d;
        detector_opts_of(o, &d);
        int rc = detector_check(&d, o->width, o->height, e);
        if (rc != SL_OK)
            return rc;
    }
    return check_geometry(o, e);
}

/* The undersampling warning: x pitch coarser than Nyquist (kn > 1), or
 * only the taller rows of non-square pixels. */
static void set_warning(sim *s, int kn)
{
    const sim_opts *o = &s->o;
    double ypitch = s->pscale * o->pixel_aspect;
    if (kn > 1)
        snprintf(s->warning, sizeof s->warning,
                 "plate scale %.4f arcsec/px undersamples the %.3f m pupil's "
                 "fringes at %.0f nm (Nyquist is %.4f arcsec/px): they alias; "
                 "simulating %dx finer and binning", s->pscale, s->E,
                 o->wavelength_m * 1e9, s->p_nyq, s->k);
    else if (ypitch > s->p_nyq * (1 + 1e-9))
        snprintf(s->warning, sizeof s->warning,
                 "pixel height %.4f arcsec (aspect %.3g) undersamples the "
                 "%.3f m pupil's fringes at %.0f nm (Nyquist is %.4f "
                 "arcsec/px): they alias along y; each pixel sums %.3g "
                 "Nyquist-sampled rows", ypitch, o->pixel_aspect, s->E,
                 o->wavelength_m * 1e9, s->p_nyq, s->ky);
}

/* Sampling: choose the plate scale, oversampling and grid (see sim.h). */
static int plan_sampling(sim *s, const mask *m)
{
    const sim_opts *o = &s->o;
    double A = o->pixel_aspect;
    s->E = mask_extent_m(m);
    if (!(s->E > 0))
        return sl_seterr(&s->err, SL_EINVAL, "pupil has no extent");
    s->p_nyq = o->wavelength_m / (2 * s->E) * ARCSEC_PER_RAD;
    s->pscale = o->plate_scale_arcsec > 0 ? o->plate_scale_arcsec : s->p_nyq;
    int kn = (int)ceil(s->pscale / s->p_nyq - 1e-9);
    s->k = kn < 1 ? 1 : kn;
    if (A < 1 && s->k < (int)ceil(1 / A - 1e-9))
        s->k = (int)ceil(1 / A - 1e-9); /* no output row thinner than a fine row */
    int side = o->width > o->height ? o->width : o->height;
    long M = (long)side * s->k;
    if (A != 1) {
        /* A k h fine rows and a margin row at each end */
        long rows = (long)ceil(A * s->k * o->height - 1e-9) + 2;
        M = (long)o->width * s->k > rows ? (long)o->width * s->k : rows;
    }
    if (M > 16384)
        return sl_seterr(&s->err, SL_ERANGE, "grid %ld x %ld needed for plate "
                         "scale %.4f arcsec/px is too large; choose a finer "
                         "plate scale or smaller frames", M, M, s->pscale);
    s->M = (int)M;
    s->ky = A == 1 ? s->k : A * s->k;
    s->oy = (s->M - s->ky * o->height) / 2;
    set_warning(s, kn);
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
    if (s->o.pixel_aspect != 1) /* centre of output row h/2, fine samples */
        cy = s->oy + (s->o.height / 2 + 0.5) * s->ky - 0.5;
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
    scene_render_rect(sc, s->truth, s->o.width, s->o.height, s->pscale,
                      s->pscale * s->o.pixel_aspect, 0);
    for (size_t i = 0; i < np; i++)
        s->truth[i] = (float)(s->truth[i] / F);
    return rc;
}

/* Every star must land inside the frame and every disk must overlap it:
 * a component outside is not imaged (or wraps round the FFT grid), so the
 * cube would not hold the scene its header describes.  A disk larger than
 * the field (a flat sky, a planet filling it) is fine. */
static int check_scene_in_frame(sim *s, const scene *sc)
{
    const sim_opts *o = &s->o;
    double py = s->pscale * o->pixel_aspect;
    for (int i = 0; i < scene_ncomp(sc); i++) {
        const scene_comp *c = scene_comp_at(sc, i);
        double r = c->kind == SCENE_DISK ? c->radius_arcsec : 0;
        double x = c->x_arcsec / s->pscale + o->offset_x_px;
        double y = c->y_arcsec / py + o->offset_y_px;
        if (fabs(x) - r / s->pscale < o->width / 2.0 &&
            fabs(y) - r / py < o->height / 2.0)
            continue;
        return sl_seterr(&s->err, SL_EINVAL, "component %d of scene '%s' "
                         "(x %.4g, y %.4g arcsec%s) falls at (%.1f, %.1f) px "
                         "from the centre, outside the %dx%d frame at %.4g "
                         "arcsec/px: a smaller separation, a larger frame or "
                         "a coarser plate scale", i + 1, scene_name(sc),
                         c->x_arcsec, c->y_arcsec, r > 0 ? ", a disk" : "",
                         x, y, o->width, o->height, s->pscale);
    }
    return SL_OK;
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
    s->rx = fftwf_alloc_complex((size_t)s->M / 2 + 1);
    s->ry = fftwf_alloc_complex((size_t)s->M);
    s->acc = calloc((size_t)s->o.width, sizeof *s->acc);
    if (!s->pupil || !s->phase || !s->truth || !s->fin || !s->fout ||
        !s->psf || !s->img || !s->otf || !s->obj || !s->rx || !s->ry ||
        !s->acc)
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
    if ((rc = plan_sampling(s, m)) != SL_OK ||
        (rc = check_scene_in_frame(s, sc)) != SL_OK || (rc = alloc_buffers(s)) != SL_OK
        || (rc = make_pupil(s, m)) != SL_OK || (rc = sim_make_labels(s, m)) != SL_OK
        || (rc = make_screen(s)) != SL_OK || (rc = make_object(s, sc)) != SL_OK)
        goto free_sim;
    if (o->photons_per_frame > 0) {
        detector_opts d;
        detector_opts_of(o, &d);
        rc = detector_new(&s->det, &d, o->width, o->height, o->seed, &s->err);
        if (rc != SL_OK)
            goto free_sim;
    }
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
    fftwf_free(s->rx);
    fftwf_free(s->ry);
    free(s->acc);
    free(s->hole);
    free(s->hsum);
    detector_free(s->det);
    screen_free(s->scr);
    free(s);
}

int sim_truth(sim *s, float *img)
{
    memcpy(img, s->truth, (size_t)s->o.width * s->o.height * sizeof *img);
    return SL_OK;
}
