/* test_sim.c - properties of the scene model and the speckle simulator. */
#include <complex.h>
#include <fftw3.h>
#include <stdlib.h>
#include <unistd.h>

#include "sim/mask.h"
#include "sim/scene.h"
#include "sim/sim.h"
#include "tcheck.h"

/* A small, fast configuration: 64x64 frames, 10 frames, Nyquist. */
static void small_opts(sim_opts *o)
{
    sim_opts_defaults(o);
    o->width = o->height = 64;
    o->nframes = 10;
    o->fftw_flags = FFTW_ESTIMATE;
}

static double sum_f(const float *a, size_t n)
{
    double s = 0;
    for (size_t i = 0; i < n; i++)
        s += a[i];
    return s;
}

TEST(psf_flux_is_conserved)
{
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    sim_opts o;
    small_opts(&o);
    CHECK(mask_named(&m, "nrm17", &e) == SL_OK, "%s", e.msg);
    CHECK(scene_named(&sc, "point", 0, 0, 0, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    int M = sim_grid(s);
    float *psf = malloc(sizeof(float) * M * M);
    float *fr = malloc(sizeof(float) * 64 * 64);
    for (int k = -1; k < 5; k++) {
        CHECK(sim_psf(s, k, psf) == SL_OK, "psf %d", k);
        CHECK_NEAR(sum_f(psf, (size_t)M * M), 1.0, 1e-4);
        CHECK(sim_frame(s, k < 0 ? 0 : k, fr) == SL_OK, "frame");
        /* 64x64 frames at M = 64: nothing is cropped, the point's image
         * keeps all its flux. */
        CHECK_NEAR(sum_f(fr, 64 * 64), 1.0, 1e-4);
    }
    free(psf);
    free(fr);
    sim_free(s);
    scene_free(sc);
    mask_free(m);
}

/* The cophased PSF must equal |FT(pupil)|^2: check pixels against a direct
 * (slow, independent) DFT of the rendered pupil. */
TEST(cophased_psf_is_pupil_power_spectrum)
{
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    sim_opts o;
    small_opts(&o);
    CHECK(mask_named(&m, "nrm17", &e) == SL_OK, "%s", e.msg);
    CHECK(scene_named(&sc, "point", 0, 0, 0, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    int M = sim_grid(s);
    float *psf = malloc(sizeof(float) * M * M);
    float *pup = calloc((size_t)M * M, sizeof(float));
    CHECK(sim_psf(s, -1, psf) == SL_OK, "psf");
    CHECK(mask_render(m, pup, M, sim_pupil_pitch_m(s), &e) == SL_OK, "render");
    double p2 = 0;
    for (int i = 0; i < M * M; i++)
        p2 += (double)pup[i] * pup[i];
    double maxrel = 0;
    for (int j = 0; j < 40; j++) {
        int u = (j * 7) % M - M / 2, v = (j * 13) % M - M / 2;
        double complex acc = 0;
        for (int y = 0; y < M; y++)
            for (int x = 0; x < M; x++)
                if (pup[y * M + x] != 0)
                    acc += pup[y * M + x] *
                           cexp(-2 * M_PI * I * ((double)u * x + (double)v * y) / M);
        double want = creal(acc * conj(acc)) / ((double)M * M * p2);
        double got = psf[(size_t)(v + M / 2) * M + (u + M / 2)];
        double rel = fabs(got - want) / (psf[(M / 2) * M + M / 2]);
        if (rel > maxrel)
            maxrel = rel;
    }
    CHECK(maxrel < 1e-5, "max deviation %.3g of the peak", maxrel);
    /* Peak of |FT(P)|^2 / (M^2 sum P^2) is (sum P)^2 / (M^2 sum P^2). */
    double s1 = sum_f(pup, (size_t)M * M);
    CHECK_NEAR(psf[(M / 2) * M + M / 2] / (s1 * s1 / ((double)M * M * p2)),
               1.0, 1e-4);
    free(psf);
    free(pup);
    sim_free(s);
    scene_free(sc);
    mask_free(m);
}

/* The flow tests' point source through nrm17 with small_opts, and the
 * pupil grid pitch dx (m) to set the wind in pixels per frame. */
static int flow_setup(sim_opts *o, mask **m, scene **sc, double *dx, sl_err *e)
{
    sim *s = NULL;
    small_opts(o);
    int rc = mask_named(m, "nrm17", e);
    if (rc == SL_OK)
        rc = scene_named(sc, "point", 0, 0, 0, e);
    if (rc == SL_OK)
        rc = sim_new(&s, o, *m, *sc, e);
    if (rc == SL_OK)
        *dx = sim_pupil_pitch_m(s);
    sim_free(s);
    return rc;
}

/* Frozen flow: with v dt = 3 pupil pixels, frame k+1's screen is frame k's
 * moved by 3 pixels along the wind. */
TEST(frozen_flow_shifts_the_screen)
{
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    sim_opts o;
    double dx = 0;
    CHECK(flow_setup(&o, &m, &sc, &dx, &e) == SL_OK, "%s", e.msg);
    for (int dir = 0; dir < 2; dir++) {
        o.wind_dir_deg = dir ? 90 : 0;
        o.wind_mps = 3 * dx / o.frame_interval_s;
        CHECK(sim_new(&s, &o, m, sc, &e) == SL_OK, "%s", e.msg);
        int W = sim_window_px(s);
        float *a = malloc(sizeof(float) * W * W), *b = malloc(sizeof(float) * W * W);
        CHECK(sim_phase_window(s, 4, a) == SL_OK && sim_phase_window(s, 5, b) == SL_OK, "window");
        double maxd = 0, rms = 0;
        for (int y = 0; y < W - 3 * dir; y++)
            for (int x = 0; x < W - 3 * (1 - dir); x++) {
                /* phi_{k+1}(x) = Phi(x - v t - v dt) = phi_k(x - 3 px) */
                int xs = x + 3 * (1 - dir), ys = y + 3 * dir;
                double d = fabs(b[ys * W + xs] - a[y * W + x]);
                if (d > maxd)
                    maxd = d;
                rms += (double)a[y * W + x] * a[y * W + x];
            }
        rms = sqrt(rms / ((W - 3) * W));
        CHECK(rms > 0.5, "screen rms %.3g rad: no turbulence?", rms);
        CHECK(maxd < 1e-4 * rms + 1e-4, "max shifted difference %.3g rad", maxd);
        /* and it really moved: unshifted frames differ */
        double diff = 0;
        for (int i = 0; i < W * W; i++)
            diff += fabs(a[i] - b[i]);
        CHECK(diff / (W * W) > 0.01 * rms, "frames identical");
        free(a);
        free(b);
        sim_free(s);
        s = NULL;
    }
    scene_free(sc);
    mask_free(m);
}

/* Correlation of the x-gradients of two windows: the gradient removes the
 * screen's non-periodic low-order part (sim.c: the analytic terms), so it
 * compares what the periodic grid contributes. */
static double gradient_corr(const float *a, const float *b, int W)
{
    double sab = 0, saa = 0, sbb = 0;
    for (int y = 0; y < W; y++)
        for (int x = 0; x + 1 < W; x++) {
            double ga = a[y * W + x + 1] - a[y * W + x], gb = b[y * W + x + 1] - b[y * W + x];
            sab += ga * gb, saa += ga * ga, sbb += gb * gb;
        }
    return sab / sqrt(saa * sbb);
}

/* A flow longer than the screen's grid (2048 px) must not replay it: one
 * lap of flow later the pupil sees other turbulence (a fresh lane), while
 * within a lap frozen flow holds (frozen_flow_shifts_the_screen).  Before
 * the lanes, frame 128 replayed frame 0 (gradient correlation 0.998). */
TEST(long_flow_changes_lane)
{
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    sim_opts o;
    double dx = 0;
    CHECK(flow_setup(&o, &m, &sc, &dx, &e) == SL_OK, "%s", e.msg);
    o.wind_mps = 16 * dx / o.frame_interval_s;   /* 16 px per frame */
    o.nframes = 300;                              /* 4784 px of flow */
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    int W = sim_window_px(s);
    float *a = malloc(sizeof(float) * W * W), *b = malloc(sizeof(float) * W * W);
    /* frame 0 at x; frame 128 one 2048 px lap later, frame 129 one frame
     * further: before the lanes 128 replayed 0 */
    CHECK(sim_phase_window(s, 0, a) == SL_OK && sim_phase_window(s, 128, b) == SL_OK, "window");
    double c_lap = gradient_corr(a, b, W);
    CHECK(sim_phase_window(s, 129, b) == SL_OK, "window");
    double c_next = gradient_corr(a, b, W);
    free(a);
    free(b);
    sim_free(s);
    scene_free(sc);
    mask_free(m);
    printf("    gradient correlation with frame 0: frame 128 %.3f, frame 129 %.3f\n", c_lap,
           c_next);
    CHECK(fabs(c_lap) < 0.5 && fabs(c_next) < 0.5, "a lap later the screen repeats: %.3f, %.3f",
          c_lap, c_next);
}

/* Same seed, same frames (in any order); another seed, other frames. */
TEST(seed_determines_output)
{
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s1 = NULL, *s2 = NULL, *s3 = NULL;
    sim_opts o;
    small_opts(&o);
    o.photons_per_frame = 500;
    CHECK(mask_named(&m, "nrm17", &e) == SL_OK, "%s", e.msg);
    CHECK(scene_named(&sc, "binary", 0.3, 40, 1, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&s1, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&s2, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    o.seed = 2;
    CHECK(sim_new(&s3, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    size_t n = 64 * 64;
    float *a = malloc(n * 4), *b = malloc(n * 4), *c = malloc(n * 4);
    sim_frame(s1, 7, a);
    sim_frame(s2, 3, b); /* another frame first: order must not matter */
    sim_frame(s2, 7, b);
    sim_frame(s3, 7, c);
    CHECK(memcmp(a, b, n * 4) == 0, "same seed gave different frames");
    CHECK(memcmp(a, c, n * 4) != 0, "different seeds gave identical frames");
    free(a); free(b); free(c);
    sim_free(s1); sim_free(s2); sim_free(s3);
    scene_free(sc);
    mask_free(m);
}

/* The binary's mean power spectrum over the point source's (same seed, so
 * the same speckle transfer function) is the binary's |O(f)|^2:
 * (1 + r^2 + 2 r cos(2 pi f . d)) / (1 + r)^2, the fringes at the spacing
 * and orientation of the separation vector d. */
TEST(binary_fringes_match_separation_and_pa)
{
    sl_err e;
    mask *m = NULL;
    scene *pt = NULL, *bin = NULL;
    sim *sp = NULL, *sb = NULL;
    sim_opts o;
    small_opts(&o);
    o.width = o.height = 64;
    double sep = 0.3, pa = 30, dm = 1, r = pow(10, -0.4 * dm);
    CHECK(mask_named(&m, "nrm17", &e) == SL_OK, "%s", e.msg);
    CHECK(scene_named(&pt, "point", 0, 0, 0, &e) == SL_OK, "%s", e.msg);
    CHECK(scene_named(&bin, "binary", sep, pa, dm, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&sp, &o, m, pt, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&sb, &o, m, bin, &e) == SL_OK, "%s", e.msg);
    int N = 64, H = N / 2 + 1;
    float *f = fftwf_alloc_real(N * N);
    fftwf_complex *F = fftwf_alloc_complex(N * H);
    fftwf_plan p = fftwf_plan_dft_r2c_2d(N, N, f, F, FFTW_ESTIMATE);
    double *psp = calloc(N * H, sizeof(double)), *psb = calloc(N * H, sizeof(double));
    for (int k = 0; k < o.nframes; k++) {
        for (int which = 0; which < 2; which++) {
            sim_frame(which ? sb : sp, k, f);
            fftwf_execute(p);
            double *ps = which ? psb : psp;
            for (int i = 0; i < N * H; i++)
                ps[i] += crealf(F[i] * conjf(F[i]));
        }
    }
    double dxs, dys, ps = sim_plate_scale_arcsec(sp);
    scene_pa_offset(sep / ps, pa, &dxs, &dys);
    double maxerr = 0;
    int used = 0;
    for (int v = 0; v < N; v++)
        for (int u = 0; u < H; u++) {
            int i = v * H + u;
            if (psp[i] < 1e-3 * psp[0])
                continue; /* outside the mask's support */
            double fu = (double)u / N, fv = (double)(v <= N / 2 ? v : v - N) / N;
            double want = (1 + r * r + 2 * r * cos(2 * M_PI * (fu * dxs + fv * dys))) /
                          ((1 + r) * (1 + r));
            double err = fabs(psb[i] / psp[i] - want);
            if (err > maxerr)
                maxerr = err;
            used++;
        }
    CHECK(used > 100, "only %d frequencies in the support", used);
    CHECK(maxerr < 2e-3, "fringe ratio deviates by %.3g", maxerr);
    fftwf_destroy_plan(p);
    fftwf_free(f); fftwf_free(F); free(psp); free(psb);
    sim_free(sp); sim_free(sb);
    scene_free(pt); scene_free(bin);
    mask_free(m);
}

TEST(detector_counts_photons)
{
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    sim_opts o;
    small_opts(&o);
    o.photons_per_frame = 2000;
    o.bias_adu = 100;
    o.gain_e_per_adu = 1; /* gain > 1 quantises single photons away */
    CHECK(mask_named(&m, "full", &e) == SL_OK, "%s", e.msg);
    CHECK(scene_named(&sc, "point", 0, 0, 0, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    float *f = malloc(64 * 64 * 4);
    double tot = 0;
    int nonint = 0;
    for (int k = 0; k < 10; k++) {
        sim_frame(s, k, f);
        for (int i = 0; i < 64 * 64; i++) {
            nonint += f[i] != floorf(f[i]);
            tot += (f[i] - o.bias_adu) * o.gain_e_per_adu;
        }
    }
    CHECK(nonint == 0, "%d non-integer ADU values", nonint);
    /* Poisson: the sum over 10 frames is 20000 +- 141. */
    CHECK(fabs(tot - 20000) < 5 * sqrt(20000), "photons %.0f", tot);
    /* Saturation clips: a tiny full well must clip every bright pixel. */
    sim_free(s);
    o.saturation_adu = 150;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    sim_frame(s, 0, f);
    float mx = 0;
    for (int i = 0; i < 64 * 64; i++)
        mx = f[i] > mx ? f[i] : mx;
    CHECK(mx == 150, "max %g with saturation 150", mx);
    free(f);
    sim_free(s);
    scene_free(sc);
    mask_free(m);
}

TEST(coarse_plate_scale_warns_and_bins)
{
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    sim_opts o;
    small_opts(&o);
    o.width = o.height = 32;
    o.plate_scale_arcsec = 0.2; /* the paper's: 4.3x coarser than Nyquist */
    CHECK(mask_named(&m, "nrm17", &e) == SL_OK, "%s", e.msg);
    CHECK(scene_named(&sc, "point", 0, 0, 0, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_oversample(s) == 5, "oversample %d", sim_oversample(s));
    CHECK(strstr(sim_warning(s), "undersamples") != NULL, "warning '%s'",
          sim_warning(s));
    float f[32 * 32];
    CHECK(sim_frame(s, 0, f) == SL_OK, "frame");
    CHECK(sum_f(f, 32 * 32) > 0.95, "flux %.3f", sum_f(f, 32 * 32));
    sim_free(s);
    o.plate_scale_arcsec = 0; /* Nyquist: no warning */
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_warning(s)[0] == 0 && sim_oversample(s) == 1, "warned at Nyquist");
    sim_free(s);
    scene_free(sc);
    mask_free(m);
}

TEST(bad_options_are_named)
{
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL;
    sim_opts o;
    CHECK(mask_named(&m, "nrm17", &e) == SL_OK, "%s", e.msg);
    CHECK(scene_named(&sc, "point", 0, 0, 0, &e) == SL_OK, "%s", e.msg);
    small_opts(&o); o.width = 0;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_EINVAL && strstr(e.msg, "frame size"), "%s", e.msg);
    small_opts(&o); o.r0_m = -1;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_EINVAL && strstr(e.msg, "r0"), "%s", e.msg);
    small_opts(&o); o.nframes = 0;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_EINVAL && strstr(e.msg, "frames"), "%s", e.msg);
    small_opts(&o); o.photons_per_frame = -5;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_EINVAL && strstr(e.msg, "photons"), "%s", e.msg);
    CHECK(s == NULL, "handle returned on error");
    scene *bad = NULL;
    CHECK(scene_named(&bad, "nebula", 0, 0, 0, &e) == SL_EINVAL && strstr(e.msg, "nebula"), "%s", e.msg);
    CHECK(scene_binary(&bad, 0.2, 0, -1, &e) == SL_EINVAL && strstr(e.msg, "dm"), "%s", e.msg);
    CHECK(bad == NULL, "handle returned on error");
    scene_free(sc);
    mask_free(m);
}

static void write_file(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    fputs(text, f);
    fclose(f);
}

TEST(scene_file_and_render)
{
    char path[] = "/tmp/sl_sceneXXXXXX";
    int fd = mkstemp(path);
    CHECK(fd >= 0, "mkstemp");
    close(fd);
    sl_err e;
    scene *sc = NULL;
    write_file(path, "# two stars and a planet\npoint 0 0 1\npoint -0.2 0.1 0.5 # east-north\n"
                     "disk 0.3 -0.2 0.15 2 0.4\n");
    CHECK(scene_read(&sc, path, &e) == SL_OK, "%s", e.msg);
    CHECK(scene_ncomp(sc) == 3, "%d components", scene_ncomp(sc));
    CHECK_NEAR(scene_total_flux(sc), 3.5, 1e-12);
    float img[64 * 64];
    scene_render(sc, img, 64, 64, 0.02, 0);
    CHECK_NEAR(sum_f(img, 64 * 64), 3.5, 1e-4);
    /* The east-north point lands left of and above the centre. */
    CHECK(img[(32 + 5) * 64 + (32 - 10)] > 0.49, "point at (-10, +5) px");
    scene_free(sc);
    write_file(path, "point 0 0\n");
    CHECK(scene_read(&sc, path, &e) == SL_EFORMAT && strstr(e.msg, ":1:"), "%s", e.msg);
    write_file(path, "star 0 0 1\n");
    CHECK(scene_read(&sc, path, &e) == SL_EFORMAT && strstr(e.msg, "star"), "%s", e.msg);
    write_file(path, "point 0 0 1\ndisk 0 0 -1 1\n");
    CHECK(scene_read(&sc, path, &e) == SL_EINVAL && strstr(e.msg, ":2:"), "%s", e.msg);
    unlink(path);
    CHECK(scene_read(&sc, path, &e) == SL_EIO && strstr(e.msg, path), "%s", e.msg);
}

/* PA convention: 0 deg = north (+y), 90 deg = east (-x). */
TEST(position_angle_convention)
{
    double dx, dy;
    scene_pa_offset(1, 0, &dx, &dy);
    CHECK(fabs(dx) < 1e-12 && fabs(dy - 1) < 1e-12, "PA 0 -> (%g, %g)", dx, dy);
    scene_pa_offset(1, 90, &dx, &dy);
    CHECK(fabs(dx + 1) < 1e-12 && fabs(dy) < 1e-12, "PA 90 -> (%g, %g)", dx, dy);
}

TC_MAIN(TC_CASE(psf_flux_is_conserved), TC_CASE(cophased_psf_is_pupil_power_spectrum),
        TC_CASE(frozen_flow_shifts_the_screen), TC_CASE(long_flow_changes_lane),
        TC_CASE(seed_determines_output),
        TC_CASE(binary_fringes_match_separation_and_pa), TC_CASE(detector_counts_photons),
        TC_CASE(coarse_plate_scale_warns_and_bins), TC_CASE(bad_options_are_named),
        TC_CASE(scene_file_and_render), TC_CASE(position_angle_convention))
