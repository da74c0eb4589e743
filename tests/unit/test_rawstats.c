/* test_rawstats.c - what raw frames say about the detector: stuck, hot and
 * dead pixels, saturation, the sky and the cloud, on synthetic camera
 * frames whose defects are known exactly. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline/rawstats.h"
#include "base/rng.h"
#include "base/tpool.h"
#include "tcheck.h"

#define W 64
#define H 56

/* A camera-like frame k: a speckly blob of `flux` photons (a Gaussian
 * envelope modulated by frame-dependent speckle, moving with jitter) at
 * (cx, cy), Poisson noise, gain 2 e-/adu, read noise 3 e-, bias 100 adu,
 * 12-bit clip.  Integer ADU. */
static void camera_frame(float *f, int k, double cx, double cy, double flux,
                         double sigma_px)
{
    rng r;
    rng_init(&r, 7, (uint64_t)k);
    double jx = 1.5 * rng_normal(&r), jy = 1.5 * rng_normal(&r);
    double norm = 1.0 / (2 * M_PI * sigma_px * sigma_px);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            double dx = x - cx - jx, dy = y - cy - jy;
            double env = norm * exp(-(dx * dx + dy * dy) / (2 * sigma_px * sigma_px));
            double speckle = -log(1 - rng_uniform(&r)); /* exponential, mean 1 */
            double e = (double)rng_poisson(&r, flux * env * speckle) + 3 * rng_normal(&r);
            double adu = nearbyint(e / 2 + 100);
            f[(size_t)y * W + x] = (float)fmin(fmax(adu, 0), 4095);
        }
}

TEST(stuck_hot_and_dead_pixels_are_found_and_nothing_else)
{
    rawstats *rs = NULL;
    sl_err e;
    CHECK(rawstats_new(&rs, W, H, 65535, &e) == SL_OK, "%s", e.msg);
    float f[W * H];
    const int hot[][2] = {{3, 4}, {30, 28}, {50, 10}}, dead[][2] = {{33, 25}, {60, 50}};
    for (int k = 0; k < 32; k++) {
        camera_frame(f, k, 34, 26, 2e4, 4);
        for (int i = 0; i < 3; i++)
            f[hot[i][1] * W + hot[i][0]] = 4095;   /* stuck at full scale */
        for (int i = 0; i < 2; i++)
            f[dead[i][1] * W + dead[i][0]] = 0;    /* dead */
        CHECK(rawstats_add(rs, f) == SL_OK, "add");
    }
    rawstats_result res;
    CHECK(rawstats_finish(rs, &res) == SL_OK, "%s", rawstats_errmsg(rs));
    const uint8_t *bad = rawstats_badmap(rs);
    int nbad = 0;
    for (int i = 0; i < W * H; i++)
        nbad += bad[i];
    for (int i = 0; i < 3; i++)
        CHECK(bad[hot[i][1] * W + hot[i][0]], "hot pixel (%d, %d) missed", hot[i][0], hot[i][1]);
    for (int i = 0; i < 2; i++)
        CHECK(bad[dead[i][1] * W + dead[i][0]], "dead pixel (%d, %d) missed", dead[i][0], dead[i][1]);
    CHECK(nbad == 5, "%d bad pixels, want the 5 planted (stuck %d hot %d dead %d)", nbad,
          res.nstuck, res.nhot, res.ndead);
    /* 4095 is 2^12 - 1 in a 16-bit file: a 12-bit ADC's clip */
    CHECK(res.sat_source == RAWSTATS_SAT_ADC && res.sat_level == 4095, "saturation %g (source %d)",
          res.sat_level, res.sat_source);
    CHECK(res.integer_valued && res.quantum == 1, "quantum %g", res.quantum);
    CHECK(!res.static_scene, "speckle taken for a static scene");
    /* the bias, and the sky's temporal rms: read noise 1.5 adu and the
     * quantisation's 1/sqrt(12) adu */
    CHECK_NEAR(res.sky_level, 100, 0.05);
    CHECK_NEAR(res.sky_rms, sqrt(1.5 * 1.5 + 1.0 / 12), 0.15);
    CHECK_NEAR(res.cx_px, 34, 0.5);
    CHECK_NEAR(res.cy_px, 26, 0.5);
    /* the cloud: 1.5 x the radius holding 95 % of the flux above the
     * cut (sky + 5 sigma_t / sqrt(K), ~1.3 adu).  The long exposure is a
     * Gaussian of sigma sqrt(4^2 + 1.5^2) = 4.27 px, above the cut out to
     * ~12.6 px (peak ~100 adu), which holds 98.7 % of its flux: 95 % of
     * that lies within 4.27 sqrt(-2 ln 0.0623) = 10.06 px */
    CHECK_NEAR(res.cloud_radius_px, 1.5 * 10.06, 1.0);
    const uint8_t *sky = rawstats_skymask(rs);
    CHECK(!sky[26 * W + 34] && !sky[26 * W + 38], "the cloud is in the sky mask");
    CHECK(res.nsky > W * H / 2, "only %d sky pixels", res.nsky);
    rawstats_free(rs);
}

/* One fractional value anywhere (a vector block's first or last lane, a
 * row's scalar tail at an odd width, negative) makes the data non-integer;
 * integers stay integer up to 2^24 and beyond, where every float is one. */
TEST(one_fraction_anywhere_makes_the_data_non_integer)
{
    enum { FW = 61, FH = 9, NF = 8 };
    static const int at[] = {-1, 0, 3, 4, 60, 61, FW * FH - 1};
    static const float frac[] = {0.5f, 0.25f, -3.5f, 1e-3f, 7.75f, 1048575.5f, 0.5f};
    for (int c = 0; c < 7; c++) {
        rawstats *rs = NULL;
        sl_err e;
        CHECK(rawstats_new(&rs, FW, FH, 0, &e) == SL_OK, "%s", e.msg);
        float f[FW * FH];
        for (int k = 0; k < NF; k++) {
            for (int i = 0; i < FW * FH; i++)
                f[i] = (float)((i * 7 + k * 3) % 50 + 100);
            f[5] = 16777216.0f * 3, f[6] = -5; /* integers too */
            if (at[c] >= 0 && k == 3)
                f[at[c]] = frac[c];
            CHECK(rawstats_add(rs, f) == SL_OK, "add");
        }
        rawstats_result res;
        CHECK(rawstats_finish(rs, &res) == SL_OK, "%s", rawstats_errmsg(rs));
        CHECK(res.integer_valued == (at[c] < 0), "fraction %g at %d: integer_valued %d",
              at[c] < 0 ? 0.0 : frac[c], at[c], res.integer_valued);
        rawstats_free(rs);
    }
}

TEST(a_warm_pixel_with_noise_is_hot)
{
    rawstats *rs = NULL;
    sl_err e;
    CHECK(rawstats_new(&rs, W, H, 65535, &e) == SL_OK, "%s", e.msg);
    float f[W * H];
    rng r;
    rng_init(&r, 3, 0);
    for (int k = 0; k < 32; k++) {
        camera_frame(f, k, 30, 30, 2e4, 4);
        /* dark current: 400 e- a frame, Poisson, on a pixel in the cloud */
        f[28 * W + 33] += (float)nearbyint(rng_poisson(&r, 400) / 2.0);
        rawstats_add(rs, f);
    }
    rawstats_result res;
    rawstats_finish(rs, &res);
    CHECK(rawstats_badmap(rs)[28 * W + 33], "warm pixel missed");
    CHECK(res.nhot == 1 && res.nstuck == 0 && res.ndead == 0, "stuck %d hot %d dead %d",
          res.nstuck, res.nhot, res.ndead);
    rawstats_free(rs);
}

/* A star whose whole PSF falls in one pixel looks like a hot pixel in the
 * long exposure.  Static it is a static scene; jumping about (moving 1)
 * or on one pixel but for 4 frames in 32 (moving 2: a sharp core whose
 * long exposure is one bright pixel) it leaves the pixel dark at times,
 * which a hot pixel never does.  None may be flagged. */
TEST(an_undersampled_star_is_never_a_bad_pixel)
{
    for (int moving = 0; moving < 3; moving++) {
        rawstats *rs = NULL;
        sl_err e;
        CHECK(rawstats_new(&rs, W, H, 0, &e) == SL_OK, "%s", e.msg);
        float f[W * H];
        rng r;
        rng_init(&r, 11, (uint64_t)moving);
        for (int k = 0; k < 32; k++) {
            for (int i = 0; i < W * H; i++)
                f[i] = (float)(10 + rng_normal(&r));
            int x = 32 + (moving == 1 ? (int)lround(0.8 * rng_normal(&r)) : 0);
            int y = 28 + (moving == 1 ? (int)lround(0.8 * rng_normal(&r)) : 0);
            x += moving == 2 && k % 8 == 3;
            f[y * W + x] += 1000;
            rawstats_add(rs, f);
        }
        rawstats_result res;
        rawstats_finish(rs, &res);
        int nbad = 0;
        for (int i = 0; i < W * H; i++)
            nbad += rawstats_badmap(rs)[i];
        CHECK(nbad == 0, "star (moving %d): %d pixels flagged", moving, nbad);
        CHECK(res.static_scene == !moving, "static_scene %d", res.static_scene);
        CHECK(res.sat_source == RAWSTATS_SAT_NONE, "real-valued data saturated at %g", res.sat_level);
        rawstats_free(rs);
    }
}

TEST(flat_topped_peaks_and_the_data_step)
{
    rawstats *rs = NULL;
    sl_err e;
    CHECK(rawstats_new(&rs, W, H, 65535, &e) == SL_OK, "%s", e.msg);
    float f[W * H];
    for (int k = 0; k < 12; k++) {
        camera_frame(f, k, 30, 30, 2e4, 4);
        for (int i = 0; i < W * H; i++)
            f[i] = fminf(f[i], 3000) * 16; /* 12-bit data shifted into 16 bits */
        if (k % 4 == 0)                    /* clipped peaks in 3 frames */
            f[30 * W + 30] = f[30 * W + 31] = f[31 * W + 30] = 3000 * 16;
        rawstats_add(rs, f);
    }
    rawstats_result res;
    rawstats_finish(rs, &res);
    CHECK(res.quantum == 16, "quantum %g, want 16", res.quantum);
    CHECK(res.sat_source == RAWSTATS_SAT_FLAT && res.sat_level == 48000,
          "saturation %g (source %d), want the flat top 48000", res.sat_level, res.sat_source);
    rawstats_free(rs);
}

/* 32 camera frames with stuck pixels, a few NaN pixels, and a peak
 * flat-topped only across rows 2 and 3 (where the 16 bands of rows part,
 * H = 56) and rows 13 and 14, each in 2 frames, learnt on pool (NULL:
 * the caller alone). */
static rawstats *learn_banded(tpool *pool, rawstats_result *res)
{
    rawstats *rs = NULL;
    if (rawstats_new(&rs, W, H, 65535, NULL) != SL_OK)
        return NULL;
    rawstats_set_pool(rs, pool);
    float f[W * H];
    for (int k = 0; k < 32; k++) {
        camera_frame(f, k, 34, 26, 2e4, 4);
        for (int i = 0; i < W * H; i++)
            f[i] = fminf(f[i], 3000);
        f[4 * W + 3] = 2500, f[50 * W + 60] = 0;   /* stuck */
        if (k % 5 == 1)
            f[(k % H) * W + k % W] = NAN;
        if (k == 3 || k == 9)
            f[2 * W + 20] = f[3 * W + 20] = 3000;
        if (k == 17 || k == 20)
            f[13 * W + 40] = f[14 * W + 40] = 3000;
        rawstats_add(rs, f);
    }
    rawstats_finish(rs, res);
    rawstats_set_pool(rs, NULL);
    return rs;
}

/* The statistics on 2 and 3 threads are those of one, to the bit, and a
 * flat top split between two bands of rows is still found. */
TEST(a_pool_gives_the_same_result)
{
    rawstats_result r1, rn;
    rawstats *one = learn_banded(NULL, &r1);
    CHECK(one, "rawstats_new");
    CHECK(r1.sat_source == RAWSTATS_SAT_FLAT && r1.sat_level == 3000,
          "saturation %g (source %d), want the flat top 3000", r1.sat_level, r1.sat_source);
    CHECK(r1.nstuck == 2, "%d stuck pixels, want 2", r1.nstuck);
    for (int n = 2; n <= 3; n++) {
        tpool *pool = tpool_new(n, NULL);
        CHECK(pool, "tpool_new(%d)", n);
        rawstats *rs = learn_banded(pool, &rn);
        tpool_free(pool);
        CHECK(rs, "rawstats_new");
        CHECK(rn.nstuck == r1.nstuck && rn.nhot == r1.nhot && rn.ndead == r1.ndead &&
                  rn.sat_level == r1.sat_level && rn.sat_source == r1.sat_source &&
                  rn.quantum == r1.quantum && rn.integer_valued == r1.integer_valued &&
                  rn.nsky == r1.nsky && rn.sky_level == r1.sky_level &&
                  rn.sky_rms == r1.sky_rms && rn.cx_px == r1.cx_px && rn.cy_px == r1.cy_px &&
                  rn.cloud_radius_px == r1.cloud_radius_px,
              "%d threads: sky %.9g rms %.9g cloud (%.9g, %.9g), one thread %.9g %.9g (%.9g, %.9g)",
              n, rn.sky_level, rn.sky_rms, rn.cx_px, rn.cy_px, r1.sky_level, r1.sky_rms,
              r1.cx_px, r1.cy_px);
        CHECK(memcmp(rawstats_badmap(rs), rawstats_badmap(one), W * H) == 0 &&
                  memcmp(rawstats_skymask(rs), rawstats_skymask(one), W * H) == 0,
              "%d threads: other bad pixels or sky", n);
        rawstats_free(rs);
    }
    rawstats_free(one);
}

TEST(bad_arguments_are_named)
{
    rawstats *rs = NULL;
    sl_err e = {0};
    CHECK(rawstats_new(&rs, 2, 10, 0, &e) == SL_EINVAL && strstr(e.msg, "2x10"), "%s", e.msg);
    CHECK(rs == NULL, "handle on failure");
    rawstats_free(NULL);
}

TC_MAIN(TC_CASE(stuck_hot_and_dead_pixels_are_found_and_nothing_else),
        TC_CASE(one_fraction_anywhere_makes_the_data_non_integer),
        TC_CASE(a_warm_pixel_with_noise_is_hot), TC_CASE(an_undersampled_star_is_never_a_bad_pixel),
        TC_CASE(flat_topped_peaks_and_the_data_step), TC_CASE(a_pool_gives_the_same_result),
        TC_CASE(bad_arguments_are_named))
