/* test_detector.c - the simulator's camera: converter clip, integer codes,
 * hot and dead pixels, output type, option errors. */
#include <stdlib.h>

#include "io/cube.h"
#include "sim/detector.h"
#include "tcheck.h"

enum { W = 48, H = 40, N = W * H };

/* A flat frame in relative flux: every pixel expects photons / N. */
static void flat(float *f)
{
    for (int i = 0; i < N; i++)
        f[i] = 1.0f / N;
}

/* A ramp from 0 to twice the mean: bright pixels to clip, dark ones too. */
static void ramp(float *f)
{
    for (int i = 0; i < N; i++)
        f[i] = 2.0f * i / ((float)N * N);
}

/* About 1000 e- per pixel, gain 10: codes 200 +- 3 ADU with bias 100, far
 * from both 0 and an 8-bit full scale, so only defects reach them. */
static void quiet_opts(detector_opts *o)
{
    detector_opts_defaults(o);
    o->photons_per_frame = 1000.0 * N;
    o->gain_e_per_adu = 10;
    o->bias_adu = 100;
    o->read_noise_e = 5;
    o->adc_bits = 8;
}

TEST(adc_clips_to_full_scale_with_integer_codes)
{
    static const int bits[] = {8, 10, 12};
    float f[N];
    for (int b = 0; b < 3; b++) {
        detector_opts o;
        detector_opts_defaults(&o);
        o.adc_bits = bits[b];
        /* mean 1.5x full scale: the bright half of the ramp clips */
        o.photons_per_frame = 1.5 * ldexp(1.0, bits[b]) * N;
        o.read_noise_e = 3;
        sl_err e;
        detector *d = NULL;
        CHECK(detector_new(&d, &o, W, H, 5, &e) == SL_OK, "%s", e.msg);
        double fs = ldexp(1.0, bits[b]) - 1;
        CHECK(detector_full_scale_adu(d) == fs, "full scale %g, want %g",
              detector_full_scale_adu(d), fs);
        ramp(f);
        detector_read(d, 3, f);
        int nonint = 0, out = 0, atmax = 0;
        for (int i = 0; i < N; i++) {
            nonint += f[i] != floorf(f[i]);
            out += f[i] < 0 || f[i] > fs;
            atmax += f[i] == fs;
        }
        detector_free(d);
        CHECK(nonint == 0 && out == 0, "%d bits: %d non-integer, %d out of "
              "[0, %g]", bits[b], nonint, out, fs);
        CHECK(atmax > N / 10, "%d bits: only %d pixels clipped", bits[b], atmax);
    }
    /* a saturation below the converter's maximum clips first */
    detector_opts o;
    detector_opts_defaults(&o);
    o.adc_bits = 8;
    o.saturation_adu = 200;
    o.photons_per_frame = 400.0 * N;
    sl_err e;
    detector *d = NULL;
    CHECK(detector_new(&d, &o, W, H, 5, &e) == SL_OK, "%s", e.msg);
    ramp(f);
    detector_read(d, 0, f);
    float mx = 0;
    for (int i = 0; i < N; i++)
        mx = f[i] > mx ? f[i] : mx;
    CHECK(detector_full_scale_adu(d) == 200 && mx == 200, "max %g, full "
          "scale %g", mx, detector_full_scale_adu(d));
    detector_free(d);
}

/* Pixels reading exactly v. */
static int count_at(const float *f, float v)
{
    int c = 0;
    for (int i = 0; i < N; i++)
        c += f[i] == v;
    return c;
}

TEST(hot_and_dead_pixels_fixed_distinct_and_exact)
{
    detector_opts o;
    quiet_opts(&o);
    o.hot_pixels = 7;
    o.dead_pixels = 5;
    sl_err e;
    detector *d = NULL, *d2 = NULL, *other = NULL;
    CHECK(detector_new(&d, &o, W, H, 11, &e) == SL_OK, "%s", e.msg);
    CHECK(detector_new(&d2, &o, W, H, 11, &e) == SL_OK, "%s", e.msg);
    CHECK(detector_new(&other, &o, W, H, 12, &e) == SL_OK, "%s", e.msg);
    CHECK(detector_hot_level_adu(d) == 255, "hot level %g",
          detector_hot_level_adu(d));
    float f[N];
    int x[12], y[12], samepos = 0, moved = 0;
    for (int i = 0; i < 12; i++) {
        int x2, y2, xo, yo;
        CHECK(detector_defect(d, i, &x[i], &y[i]) == (i < 7), "defect %d kind", i);
        detector_defect(d2, i, &x2, &y2);
        detector_defect(other, i, &xo, &yo);
        samepos += x2 == x[i] && y2 == y[i];
        moved += xo != x[i] || yo != y[i];
        for (int j = 0; j < i; j++)
            CHECK(x[j] != x[i] || y[j] != y[i], "defects %d and %d share "
                  "pixel (%d, %d)", j, i, x[i], y[i]);
    }
    CHECK(detector_defect(d, 12, &x[0], &y[0]) == -1, "defect 12 exists");
    CHECK(samepos == 12 && moved > 6, "same seed: %d of 12 in place; other "
          "seed moved %d", samepos, moved);
    for (int k = 0; k < 6; k++) {
        flat(f);
        detector_read(d, k * 7, f);
        CHECK(count_at(f, 255) == 7 && count_at(f, 0) == 5, "frame %d: %d at "
              "full scale, %d at 0", k * 7, count_at(f, 255), count_at(f, 0));
        for (int i = 0; i < 12; i++)
            CHECK(f[y[i] * W + x[i]] == (i < 7 ? 255 : 0), "frame %d defect "
                  "%d at (%d, %d) reads %g", k * 7, i, x[i], y[i],
                  f[y[i] * W + x[i]]);
    }
    detector_free(d);
    detector_free(d2);
    detector_free(other);
}

/* Defects change only their own pixels (the noise of the others is drawn
 * as before), adding dead pixels does not move hot ones, and a warm level
 * replaces full scale. */
TEST(defects_touch_only_their_pixels)
{
    detector_opts o;
    quiet_opts(&o);
    sl_err e;
    detector *clean = NULL, *hot = NULL, *both = NULL;
    CHECK(detector_new(&clean, &o, W, H, 3, &e) == SL_OK, "%s", e.msg);
    o.hot_pixels = 4;
    o.hot_level_adu = 230.4;
    CHECK(detector_new(&hot, &o, W, H, 3, &e) == SL_OK, "%s", e.msg);
    o.dead_pixels = 9;
    CHECK(detector_new(&both, &o, W, H, 3, &e) == SL_OK, "%s", e.msg);
    float a[N], b[N];
    flat(a);
    flat(b);
    detector_read(clean, 4, a);
    detector_read(both, 4, b);
    int differ = 0, warm = 0;
    for (int i = 0; i < N; i++) {
        differ += a[i] != b[i];
        warm += b[i] == 230;
    }
    int same_hot = 1;
    for (int i = 0; i < 4; i++) {
        int x1, y1, x2, y2;
        detector_defect(hot, i, &x1, &y1);
        detector_defect(both, i, &x2, &y2);
        same_hot &= x1 == x2 && y1 == y2;
    }
    detector_free(clean);
    detector_free(hot);
    detector_free(both);
    CHECK(differ <= 13, "%d pixels changed by 13 defects", differ);
    CHECK(warm == 4, "%d pixels at the warm level 230, want the 4 hot ones", warm);
    CHECK(same_hot, "adding dead pixels moved a hot pixel");
}

TEST(output_type_follows_the_converter)
{
    detector_opts o;
    detector_opts_defaults(&o);
    static const int bits[] = {0, 1, 8, 9, 12, 16, 17, 24};
    static const int want[] = {-32, 8, 8, CUBE_BITPIX_U16, CUBE_BITPIX_U16,
                               CUBE_BITPIX_U16, -32, -32};
    for (int i = 0; i < 8; i++) {
        o.adc_bits = bits[i];
        CHECK(detector_bitpix(&o) == want[i], "%d bits: BITPIX %d, want %d",
              bits[i], detector_bitpix(&o), want[i]);
    }
    o.adc_bits = 8;
    o.photons_per_frame = 0; /* no detector: relative flux */
    CHECK(detector_bitpix(&o) == -32, "noiseless frames are float");
}

TEST(bad_options_are_named)
{
    detector_opts o;
    sl_err e;
    detector *d = NULL;
    quiet_opts(&o);
    o.adc_bits = 25;
    CHECK(detector_new(&d, &o, W, H, 1, &e) == SL_EINVAL &&
          strstr(e.msg, "ADC bits"), "%s", e.msg);
    quiet_opts(&o);
    o.hot_pixels = N / 4;
    o.dead_pixels = N / 4 + 1;
    CHECK(detector_new(&d, &o, W, H, 1, &e) == SL_EINVAL &&
          strstr(e.msg, "hot"), "%s", e.msg);
    quiet_opts(&o);
    o.hot_pixels = 1;
    o.hot_level_adu = 256;
    CHECK(detector_new(&d, &o, W, H, 1, &e) == SL_EINVAL &&
          strstr(e.msg, "hot pixel level"), "%s", e.msg);
    quiet_opts(&o);
    o.bias_adu = 300;
    o.saturation_adu = 1000;
    CHECK(detector_new(&d, &o, W, H, 1, &e) == SL_EINVAL &&
          strstr(e.msg, "bias"), "%s", e.msg);
    quiet_opts(&o);
    o.photons_per_frame = 0;
    CHECK(detector_new(&d, &o, W, H, 1, &e) == SL_EINVAL &&
          strstr(e.msg, "photons"), "%s", e.msg);
    CHECK(d == NULL, "handle returned on error");
}

TC_MAIN(TC_CASE(adc_clips_to_full_scale_with_integer_codes),
        TC_CASE(hot_and_dead_pixels_fixed_distinct_and_exact),
        TC_CASE(defects_touch_only_their_pixels),
        TC_CASE(output_type_follows_the_converter), TC_CASE(bad_options_are_named))
