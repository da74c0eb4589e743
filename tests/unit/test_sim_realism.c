/* test_sim_realism.c - the simulator's camera-like features: pointing
 * offset and jitter, non-square pixels, the piston phase model, the
 * obstructed amateur telescope, and their option errors. */
#include <complex.h>
#include <fftw3.h>
#include <stdlib.h>

#include "sim/mask.h"
#include "sim/scene.h"
#include "sim/sim.h"
#include "tcheck.h"

static void small_opts(sim_opts *o, int n)
{
    sim_opts_defaults(o);
    o->width = o->height = n;
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

/* Flux centroid on the periodic n x n frame along x (axis 0) or y: the
 * phase of the first Fourier harmonic.  At Nyquist (no binning) the frame
 * is the whole fine grid, and shifts are circular on it, so this moves by
 * exactly the shift; the plain centroid does not, because a PSF's r^-3
 * wings wrap across the edges (0.01-0.03 px at 64-128 px). */
static double circ_centroid(const float *f, int n, int axis)
{
    double complex acc = 0;
    for (int y = 0; y < n; y++)
        for (int x = 0; x < n; x++)
            acc += f[(size_t)y * n + x] * cexp(2 * M_PI * I * (axis ? y : x) / n);
    return carg(acc) * n / (2 * M_PI);
}

/* Centroid and second central moments over the ellipse of semi-axes rx, ry
 * around (x0, y0), pixels. */
static void moments(const float *f, int w, int h, double x0, double y0,
                    double rx, double ry, double c[2], double v[2])
{
    double s = 0, sx = 0, sy = 0, sxx = 0, syy = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double u = (x - x0) / rx, t = (y - y0) / ry;
            if (u * u + t * t > 1)
                continue;
            double p = f[(size_t)y * w + x];
            s += p, sx += p * x, sy += p * y;
            sxx += p * x * x, syy += p * y * y;
        }
    c[0] = sx / s;
    c[1] = sy / s;
    v[0] = sxx / s - c[0] * c[0];
    v[1] = syy / s - c[1] * c[1];
}

/* Render frame k of (o, m, sc) into f and its offset; SL_OK or the error. */
static int render(const sim_opts *o, const mask *m, const scene *sc, int k,
                  float *f, double off[2], sl_err *e)
{
    sim *s = NULL;
    int rc = sim_new(&s, o, m, sc, e);
    if (rc == SL_OK)
        rc = sim_frame(s, k, f);
    if (rc == SL_OK && off)
        rc = sim_frame_offset_px(s, k, &off[0], &off[1]);
    sim_free(s);
    return rc;
}

static scene *disk_scene(double radius_arcsec, sl_err *e)
{
    scene *sc = scene_new();
    scene_comp c = {.kind = SCENE_DISK, .flux = 1, .radius_arcsec = radius_arcsec};
    if (sc && scene_add(sc, &c, e) != SL_OK) {
        scene_free(sc);
        return NULL;
    }
    return sc;
}

/* A noiseless point-source speckle frame: the offset moves its flux
 * centroid by exactly (X, Y) and keeps its flux. */
TEST(offset_moves_the_centroid_exactly)
{
    enum { N = 64 };
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim_opts o;
    small_opts(&o, N);
    CHECK(mask_named(&m, "full", &e) == SL_OK, "%s", e.msg);
    CHECK(scene_named(&sc, "point", 0, 0, 0, &e) == SL_OK, "%s", e.msg);
    float *a = malloc(sizeof(float) * N * N), *b = malloc(sizeof(float) * N * N);
    CHECK(render(&o, m, sc, 2, a, NULL, &e) == SL_OK, "%s", e.msg);
    o.offset_x_px = 3.37;
    o.offset_y_px = -5.81;
    CHECK(render(&o, m, sc, 2, b, NULL, &e) == SL_OK, "%s", e.msg);
    double dx = remainder(circ_centroid(b, N, 0) - circ_centroid(a, N, 0), N);
    double dy = remainder(circ_centroid(b, N, 1) - circ_centroid(a, N, 1), N);
    double fa = sum_f(a, N * N), fb = sum_f(b, N * N);
    free(a);
    free(b);
    scene_free(sc);
    mask_free(m);
    CHECK(fabs(dx - 3.37) < 0.01 && fabs(dy + 5.81) < 0.01,
          "centroid moved (%.4f, %.4f) px for (3.37, -5.81)", dx, dy);
    CHECK_NEAR(fb, fa, 1e-5);
}

/* Jitter: frame k's shift is a pure function of (seed, k), Gaussian with
 * the requested rms per axis around the offset, and the rendered frame
 * moves by it. */
TEST(jitter_has_the_requested_rms_and_moves_frames)
{
    enum { N = 64, K = 2000 };
    const double S = 0.8;
    sl_err e;
    mask *m = NULL;
    scene *sc = NULL;
    sim *s = NULL, *s2 = NULL;
    sim_opts o;
    small_opts(&o, N);
    o.jitter_px = S;
    o.offset_x_px = 1.5;
    CHECK(mask_named(&m, "full", &e) == SL_OK, "%s", e.msg);
    CHECK(scene_named(&sc, "point", 0, 0, 0, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&s2, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    double mx = 0, my = 0, vx = 0, vy = 0, cxy = 0, x, y, x2, y2;
    int same = 1;
    for (int k = K - 1; k >= 0; k--) { /* any order */
        sim_frame_offset_px(s, k, &x, &y);
        sim_frame_offset_px(s2, (k * 7) % K, &x2, &y2);
        sim_frame_offset_px(s2, k, &x2, &y2);
        same &= x == x2 && y == y2;
        x -= 1.5;
        mx += x, my += y, vx += x * x, vy += y * y, cxy += x * y;
    }
    mx /= K, my /= K;
    double rx = sqrt(vx / K - mx * mx), ry = sqrt(vy / K - my * my);
    printf("    %d frames: mean (%.4f, %.4f) px, rms (%.4f, %.4f) px for %.2f\n", K, mx,
           my, rx, ry, S);
    CHECK(same, "frame offsets depend on the order they are asked for");
    /* standard errors: mean S/sqrt(K) = 0.018, rms S/sqrt(2K) = 0.013 */
    CHECK(fabs(mx) < 0.07 && fabs(my) < 0.07, "mean (%.3f, %.3f)", mx, my);
    CHECK(fabs(rx / S - 1) < 0.06 && fabs(ry / S - 1) < 0.06, "rms (%.3f, %.3f)", rx, ry);
    CHECK(fabs(cxy / K) < 0.1 * S * S, "x-y covariance %.3f", cxy / K);
    float *a = malloc(sizeof(float) * N * N), *b = malloc(sizeof(float) * N * N);
    sim_opts still = o;
    still.jitter_px = 0;
    still.offset_x_px = 0;
    double off[2];
    for (int k = 3; k < 6; k++) {
        CHECK(render(&still, m, sc, k, a, NULL, &e) == SL_OK, "%s", e.msg);
        CHECK(sim_frame(s, k, b) == SL_OK && sim_frame_offset_px(s, k, &off[0], &off[1]) == SL_OK,
              "frame %d", k);
        double dx = remainder(circ_centroid(b, N, 0) - circ_centroid(a, N, 0), N);
        double dy = remainder(circ_centroid(b, N, 1) - circ_centroid(a, N, 1), N);
        CHECK(fabs(dx - off[0]) < 0.01 && fabs(dy - off[1]) < 0.01, "frame %d moved (%.4f, "
              "%.4f), offset (%.4f, %.4f)", k, dx, dy, off[0], off[1]);
    }
    CHECK(sim_frame_offset_px(s, -1, &x, &y) == SL_EINVAL, "frame -1 has an offset");
    free(a);
    free(b);
    sim_free(s);
    sim_free(s2);
    scene_free(sc);
    mask_free(m);
}

/* A flat sky (a disk larger than the grid) through turbulence: every
 * output pixel is A times the square pixel's flux, to float precision.  A
 * wrong edge-row weight would make rows differ by up to 1/(A k). */
TEST(pixel_aspect_flat_field_weights)
{
    enum { N = 32 };
    static const double aspect[] = {0.5, 0.77, 1.3, 2};
    sl_err e;
    mask *m = NULL;
    sim_opts o;
    small_opts(&o, N);
    CHECK(mask_named(&m, "full", &e) == SL_OK, "%s", e.msg);
    /* Nyquist 0.047"/px: 2 x 1.6" covers every grid below (<= 66 px). */
    scene *sc = disk_scene(5.0, &e);
    CHECK(sc, "%s", e.msg);
    float *f = malloc(sizeof(float) * N * N);
    CHECK(render(&o, m, sc, 1, f, NULL, &e) == SL_OK, "%s", e.msg);
    double square = sum_f(f, N * N) / (N * N);
    for (int i = 0; i < 4; i++) {
        o.pixel_aspect = aspect[i];
        CHECK(render(&o, m, sc, 1, f, NULL, &e) == SL_OK, "A %g: %s", aspect[i], e.msg);
        double mean = sum_f(f, N * N) / (N * N), dev = 0;
        for (int p = 0; p < N * N; p++)
            dev = fmax(dev, fabs(f[p] / mean - 1));
        CHECK(dev < 1e-4, "A %g: pixels deviate %.3g from flat", aspect[i], dev);
        /* the disk's area sampling differs by grid: 1e-3, not exact */
        CHECK(fabs(mean / square / aspect[i] - 1) < 3e-3, "A %g: pixel flux %.6g = "
              "%.4f x the square pixel's", aspect[i], mean, mean / square);
    }
    free(f);
    scene_free(sc);
    mask_free(m);
}

/* A round source on pixels A times taller than wide: in pixels its rms
 * width along y is 1/A times that along x; its centroid sits at the frame
 * centre plus the offset, and the flux stays in the frame. */
TEST(pixel_aspect_scales_y_moments)
{
    enum { N = 64 };
    static const double aspect[] = {0.6, 1.6};
    sl_err e;
    mask *m = NULL;
    sim_opts o;
    small_opts(&o, N);
    o.turbulence = 0;
    CHECK(mask_named(&m, "full", &e) == SL_OK, "%s", e.msg);
    const double R_px = 8;
    scene *sc = disk_scene(R_px * 0.046875, &e); /* ~8 px at Nyquist */
    CHECK(sc, "%s", e.msg);
    float *f = malloc(sizeof(float) * N * N);
    for (int i = 0; i < 2; i++) {
        double A = aspect[i], c[2], v[2];
        o.pixel_aspect = A;
        o.offset_y_px = 2.25;
        CHECK(render(&o, m, sc, 0, f, NULL, &e) == SL_OK, "%s", e.msg);
        moments(f, N, N, N / 2, N / 2 + 2.25, 1.6 * R_px, 1.6 * R_px / A, c, v);
        double ratio = sqrt(v[1]) * A / sqrt(v[0]);
        printf("    A %.2f: centroid (%.4f, %.4f), rms x %.3f y %.3f px, y rms x A / x rms "
               "%.4f, flux %.5f\n", A, c[0], c[1], sqrt(v[0]), sqrt(v[1]), ratio,
               sum_f(f, N * N));
        CHECK(fabs(ratio - 1) < 0.02, "A %g: y rms x A / x rms = %.4f", A, ratio);
        CHECK(fabs(c[0] - N / 2) < 0.02 && fabs(c[1] - N / 2 - 2.25) < 0.02,
              "A %g: centroid (%.4f, %.4f), want (%d, %.2f)", A, c[0], c[1], N / 2,
              N / 2 + 2.25);
        CHECK(fabs(sum_f(f, N * N) - 1) < 5e-3, "A %g: flux %.5f", A, sum_f(f, N * N));
    }
    free(f);
    scene_free(sc);
    mask_free(m);
}

/* Mean phase of each of the two holes of m over the window of frame k,
 * weighted by transmission as the simulator does, pixels labelled by the
 * nearest centre; an independent reading of sim.h's piston model. */
static int hole_means(sim *s, const mask *m, int k, double p[2], sl_err *e)
{
    int M = sim_grid(s), W = sim_window_px(s), w0 = M / 2 - W / 2;
    double dx = sim_pupil_pitch_m(s), sum[2] = {0, 0}, wt[2] = {0, 0};
    float *pup = malloc(sizeof(float) * M * M), *ph = malloc(sizeof(float) * W * W);
    int rc = pup && ph ? mask_render(m, pup, M, dx, e) : SL_ENOMEM;
    if (rc == SL_OK)
        rc = sim_phase_window(s, k, ph);
    for (int y = 0; y < W && rc == SL_OK; y++)
        for (int x = 0; x < W; x++) {
            double t = pup[(size_t)(w0 + y) * M + w0 + x], d2[2];
            for (int h = 0; h < 2; h++) {
                double hx, hy;
                mask_hole(m, h, &hx, &hy);
                double u = (w0 + x - M / 2) * dx - hx, v = (w0 + y - M / 2) * dx - hy;
                d2[h] = u * u + v * v;
            }
            int h = d2[1] < d2[0];
            sum[h] += t * ph[y * W + x];
            wt[h] += t;
        }
    p[0] = sum[0] / wt[0];
    p[1] = sum[1] / wt[1];
    free(pup);
    free(ph);
    return rc;
}

/* Two holes, piston model: each hole has one phase, so the PSF is fringes
 * under the hole's envelope and its OTF at the baseline b = c1 - c0 (from
 * the autocorrelation sum_x f(x) f*(x + b)) has phase p0 - p1 exactly. */
TEST(piston_fringe_phase_is_the_piston_difference)
{
    enum { N = 64 };
    const double hx[2] = {-0.3, 0.25}, hy[2] = {0.05, -0.1};
    sl_err e;
    mask *m = mask_new_holes(hx, hy, 2, 0.1, &e);
    scene *sc = NULL;
    sim *s = NULL;
    sim_opts o;
    small_opts(&o, N);
    o.phase_model = SIM_PHASE_PISTON;
    CHECK(m, "%s", e.msg);
    CHECK(scene_named(&sc, "point", 0, 0, 0, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    int M = sim_grid(s), H = M / 2 + 1;
    double dx = sim_pupil_pitch_m(s);
    int u = (int)lround((hx[1] - hx[0]) / dx), v = (int)lround((hy[1] - hy[0]) / dx);
    float *psf = malloc(sizeof(float) * M * M), *p0 = fftwf_alloc_real((size_t)M * M);
    fftwf_complex *otf = fftwf_alloc_complex((size_t)M * H);
    fftwf_plan plan = fftwf_plan_dft_r2c_2d(M, M, p0, otf, FFTW_ESTIMATE);
    double worst = 0, spread = 0, first = 0;
    for (int k = 0; k < 4; k++) {
        double p[2];
        CHECK(hole_means(s, m, k, p, &e) == SL_OK, "%s", e.msg);
        CHECK(sim_psf(s, k, psf) == SL_OK, "psf %d", k);
        for (int y = 0; y < M; y++) /* back to the origin at [0] */
            for (int x = 0; x < M; x++)
                p0[y * M + x] = psf[((y + M / 2) % M) * M + (x + M / 2) % M];
        fftwf_execute(plan);
        double got = cargf(otf[(size_t)((v + M) % M) * H + u]);
        double err = fabs(remainder(got - (p[0] - p[1]), 2 * M_PI));
        worst = fmax(worst, err);
        first = k ? first : p[0] - p[1];
        spread = fmax(spread, fabs(remainder(p[0] - p[1] - first, 2 * M_PI)));
    }
    fftwf_destroy_plan(plan);
    fftwf_free(p0);
    fftwf_free(otf);
    free(psf);
    sim_free(s);
    scene_free(sc);
    mask_free(m);
    CHECK(spread > 0.1, "pistons barely change (%.3g rad): no test", spread);
    CHECK(worst < 1e-3, "fringe phase off the piston difference by %.3g rad", worst);
}

/* Piston frames differ from screen frames of the same seed, the cophased
 * frame (no phase at all) does not; a filled aperture refuses it. */
TEST(piston_changes_frames_not_the_cophased_image)
{
    enum { N = 64 };
    sl_err e;
    mask *m = NULL, *full = NULL;
    scene *sc = NULL;
    sim *a = NULL, *b = NULL;
    sim_opts o;
    small_opts(&o, N);
    CHECK(mask_named(&m, "nrm17", &e) == SL_OK, "%s", e.msg);
    CHECK(mask_named(&full, "full", &e) == SL_OK, "%s", e.msg);
    CHECK(scene_named(&sc, "binary", 0.3, 40, 1, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&a, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    o.phase_model = SIM_PHASE_PISTON;
    CHECK(sim_new(&b, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    size_t n = N * N;
    float *fa = malloc(n * 4), *fb = malloc(n * 4);
    CHECK(sim_frame(a, 1, fa) == SL_OK && sim_frame(b, 1, fb) == SL_OK, "frames");
    double diff = 0;
    for (size_t i = 0; i < n; i++)
        diff += fabs(fa[i] - fb[i]);
    CHECK(diff > 0.05, "piston and screen frames differ by %.3g of unit flux", diff);
    CHECK_NEAR(sum_f(fb, n), sum_f(fa, n), 1e-3);
    CHECK(sim_cophased(a, fa) == SL_OK && sim_cophased(b, fb) == SL_OK, "cophased");
    CHECK(memcmp(fa, fb, n * 4) == 0, "the cophased frame depends on the phase model");
    sim_free(b);
    b = NULL;
    CHECK(sim_new(&b, &o, full, sc, &e) == SL_EINVAL && strstr(e.msg, "piston") &&
          strstr(e.msg, "filled"), "%s", e.msg);
    free(fa);
    free(fb);
    sim_free(a);
    scene_free(sc);
    mask_free(m);
    mask_free(full);
}

static double pupil_sum(const float *p, int n)
{
    double s = 0;
    for (int i = 0; i < n * n; i++)
        s += p[i];
    return s;
}

/* The obstructed aperture: its annulus has the right area, a dark centre
 * and a clear ring; no obstruction renders exactly as mask_new_full. */
TEST(obstructed_aperture_renders_an_annulus)
{
    enum { N = 128 };
    const double D = 0.35, F = 0.3, dx = D / 100;
    sl_err e;
    mask *m = mask_new_full_obstructed(D, F, &e), *none = NULL, *plain = mask_new_full(D);
    CHECK(m && plain, "%s", e.msg);
    none = mask_new_full_obstructed(D, 0, &e);
    CHECK(none, "%s", e.msg);
    float *a = malloc(sizeof(float) * N * N), *b = malloc(sizeof(float) * N * N);
    CHECK(mask_render(m, a, N, dx, &e) == SL_OK, "%s", e.msg);
    double area = pupil_sum(a, N) * dx * dx, want = M_PI / 4 * D * D * (1 - F * F);
    int ring = (int)lround((1 + F) / 4 * D / dx); /* mid-annulus radius, px */
    CHECK(fabs(area / want - 1) < 0.01, "annulus area %.5g m^2, want %.5g", area, want);
    CHECK(a[(N / 2) * N + N / 2] == 0 && a[(N / 2) * N + N / 2 + ring] == 1 &&
          a[(N / 2 + ring) * N + N / 2] == 1, "centre %g, ring %g",
          a[(N / 2) * N + N / 2], a[(N / 2) * N + N / 2 + ring]);
    CHECK(mask_obstruction(m) == F && mask_extent_m(m) == D && mask_is_full(m),
          "obstruction %g extent %g", mask_obstruction(m), mask_extent_m(m));
    CHECK(mask_render(none, a, N, dx, &e) == SL_OK && mask_render(plain, b, N, dx, &e) == SL_OK,
          "%s", e.msg);
    CHECK(memcmp(a, b, sizeof(float) * N * N) == 0, "obstruction 0 differs from full");
    mask_free(m);
    mask_free(none);
    mask_free(plain);
    free(a);
    free(b);
    CHECK(!mask_new_full_obstructed(D, 0.95, &e) && strstr(e.msg, "obstruction"), "%s", e.msg);
    CHECK(!mask_new_full_obstructed(-1, 0.2, &e) && strstr(e.msg, "diameter"), "%s", e.msg);
}

/* The amateur setup, undersampled (0.2"/px for 35 cm at 550 nm is 1.2x
 * Nyquist): binned frames with every detector feature on are 8-bit codes,
 * hot pixels at 255 in every frame. */
TEST(amateur_telescope_with_every_feature)
{
    enum { N = 64 };
    sl_err e;
    mask *m = mask_new_full_obstructed(0.35, 0.3, &e);
    scene *sc = NULL;
    sim *s = NULL;
    sim_opts o;
    small_opts(&o, N);
    o.nframes = 3;
    o.wavelength_m = 550e-9;
    o.plate_scale_arcsec = 0.2;
    o.r0_m = 0.1;
    o.photons_per_frame = 1e5;
    o.gain_e_per_adu = 20;
    o.adc_bits = 8;
    o.hot_pixels = 3;
    o.dead_pixels = 2;
    o.offset_x_px = 1.5;
    o.offset_y_px = -2;
    o.jitter_px = 0.5;
    o.pixel_aspect = 1.2;
    CHECK(m, "%s", e.msg);
    CHECK(scene_named(&sc, "binary", 0.32, 30, 0.6, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_OK, "%s", e.msg);
    CHECK(sim_oversample(s) == 2 && strstr(sim_warning(s), "undersamples"),
          "oversample %d, warning '%s'", sim_oversample(s), sim_warning(s));
    CHECK(sim_output_bitpix(s) == 8, "BITPIX %d", sim_output_bitpix(s));
    float f[N * N];
    for (int k = 0; k < 3; k++) {
        CHECK(sim_frame(s, k, f) == SL_OK, "frame %d: %s", k, sim_errmsg(s));
        int bad = 0, x, y;
        for (int i = 0; i < N * N; i++)
            bad += f[i] != floorf(f[i]) || f[i] < 0 || f[i] > 255;
        CHECK(bad == 0, "frame %d: %d pixels are not 8-bit codes", k, bad);
        for (int i = 0; i < 5; i++)
            CHECK(detector_defect(sim_detector(s), i, &x, &y) >= 0 &&
                  f[y * N + x] == (i < 3 ? 255 : 0), "defect %d reads %g", i, f[y * N + x]);
        /* ~5000 ADU of signal; codes sum near it (clipping only lowers) */
        double adu = sum_f(f, N * N) - 3 * 255;
        CHECK(adu > 3000 && adu < 6000, "frame %d: %.0f ADU", k, adu);
    }
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
    small_opts(&o, 64); o.pixel_aspect = 0.3;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_EINVAL && strstr(e.msg, "pixel aspect"), "%s", e.msg);
    small_opts(&o, 64); o.pixel_aspect = 2.5;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_EINVAL && strstr(e.msg, "[0.5, 2]"), "%s", e.msg);
    small_opts(&o, 64); o.offset_x_px = 40;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_EINVAL && strstr(e.msg, "offset"), "%s", e.msg);
    small_opts(&o, 64); o.jitter_px = -1;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_EINVAL && strstr(e.msg, "jitter"), "%s", e.msg);
    small_opts(&o, 64); o.adc_bits = 8;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_EINVAL && strstr(e.msg, "photons"), "%s", e.msg);
    small_opts(&o, 64); o.photons_per_frame = 100; o.adc_bits = 40;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_EINVAL && strstr(e.msg, "ADC bits"), "%s", e.msg);
    small_opts(&o, 64); o.phase_model = 7;
    CHECK(sim_new(&s, &o, m, sc, &e) == SL_EINVAL && strstr(e.msg, "phase model"), "%s", e.msg);
    CHECK(s == NULL, "handle returned on error");
    scene_free(sc);
    mask_free(m);
}

TC_MAIN(TC_CASE(offset_moves_the_centroid_exactly),
        TC_CASE(jitter_has_the_requested_rms_and_moves_frames),
        TC_CASE(pixel_aspect_flat_field_weights), TC_CASE(pixel_aspect_scales_y_moments),
        TC_CASE(piston_fringe_phase_is_the_piston_difference),
        TC_CASE(piston_changes_frames_not_the_cophased_image),
        TC_CASE(obstructed_aperture_renders_an_annulus),
        TC_CASE(amateur_telescope_with_every_feature), TC_CASE(bad_options_are_named))
