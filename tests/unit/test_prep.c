/* test_prep.c - pre-processing: dark, flat, sky, bad pixels, window. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "io/cube.h"
#include "pipeline/prep.h"
#include "pipeline/rawstats.h"
#include "tcheck.h"

#define W 48
#define H 40

/* A smooth centred blob: the "object" the cleaning must preserve. */
static float blob(int x, int y)
{
    double dx = x - W / 2, dy = y - H / 2;
    return (float)(100 * exp(-(dx * dx + dy * dy) / 18.0));
}

TEST(dark_flat_and_sky_are_removed)
{
    float dark[W * H], flat[W * H], f[W * H];
    for (int i = 0; i < W * H; i++) {
        dark[i] = 90 + (i % 7);           /* structured bias */
        flat[i] = 0.8f + 0.4f * ((i * 37) % 11) / 10.0f;
    }
    prep_opts o;
    prep_opts_defaults(&o);
    o.window = PREP_WIN_NONE;
    o.dark = dark;
    o.flat = flat;
    o.sky = PREP_SKY_BORDER;
    prep *p = NULL;
    sl_err e;
    CHECK(prep_new(&p, W, H, &o, &e) == SL_OK, "%s", e.msg);
    double mflat = 0;
    for (int i = 0; i < W * H; i++)
        mflat += flat[i];
    mflat /= W * H;
    /* raw = flat/mean * (object + sky) + dark */
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            int i = y * W + x;
            f[i] = (float)(flat[i] / mflat * (blob(x, y) + 25) + dark[i]);
        }
    prep_stats st;
    CHECK(prep_frame(p, f, &st) == SL_OK, "%s", prep_errmsg(p));
    CHECK_NEAR(st.sky, 25, 1e-3);
    double maxd = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            maxd = fmax(maxd, fabs(f[y * W + x] - blob(x, y)));
    CHECK(maxd < 1e-3, "max deviation from the object %.3g", maxd);
    prep_free(p);
}

TEST(hot_dead_nan_and_saturated_pixels_are_repaired)
{
    prep_opts o;
    prep_opts_defaults(&o);
    o.window = PREP_WIN_NONE;
    o.sky = PREP_SKY_NONE;
    o.saturation_adu = 1000;
    prep *p = NULL;
    rawstats *rs = NULL;
    sl_err e;
    CHECK(prep_new(&p, W, H, &o, &e) == SL_OK, "%s", e.msg);
    CHECK(rawstats_new(&rs, W, H, 0, &e) == SL_OK, "%s", e.msg);
    float f[W * H];
    for (int k = 0; k < 20; k++) {
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++)
                f[y * W + x] = blob(x, y) + 10 + (float)((x * 13 + y * 7 + k) % 5);
        f[5 * W + 7] = 500;        /* hot */
        f[30 * W + 40] = 0;        /* dead */
        rawstats_add(rs, f);
    }
    CHECK(rawstats_finish(rs, NULL) == SL_OK, "%s", rawstats_errmsg(rs));
    prep_set_badmap(p, rawstats_badmap(rs));
    rawstats_free(rs);
    CHECK(prep_nbad(p) == 2, "marked %d pixels, want the hot and the dead one", prep_nbad(p));
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            f[y * W + x] = blob(x, y) + 10;
    f[5 * W + 7] = 500;
    f[30 * W + 40] = 0;
    f[12 * W + 12] = NAN;
    f[13 * W + 30] = INFINITY;
    f[H / 2 * W + W / 2] = 5000; /* saturated at the blob peak */
    prep_stats st;
    CHECK(prep_frame(p, f, &st) == SL_OK, "frame");
    CHECK(st.nonfinite == 2 && st.saturated == 1 && st.badmap == 2,
          "nonfinite %d saturated %d badmap %d", st.nonfinite, st.saturated, st.badmap);
    int idx[] = {5 * W + 7, 30 * W + 40, 12 * W + 12, 13 * W + 30};
    for (int j = 0; j < 4; j++) {
        int x = idx[j] % W, y = idx[j] / W;
        CHECK(fabs(f[idx[j]] - (blob(x, y) + 10)) < 2, "pixel (%d,%d) = %g, want ~%g", x, y,
              f[idx[j]], blob(x, y) + 10);
    }
    /* the saturated peak is replaced by its neighbours: below the true peak */
    CHECK(f[H / 2 * W + W / 2] < 110 && f[H / 2 * W + W / 2] > 80, "peak %g", f[H / 2 * W + W / 2]);
    prep_free(p);
}

TEST(windows_taper_the_edges)
{
    prep_opts o;
    prep_opts_defaults(&o);
    prep *p = NULL;
    sl_err e;
    for (int kind = PREP_WIN_HANN; kind <= PREP_WIN_TUKEY; kind++) {
        o.window = kind;
        CHECK(prep_new(&p, W, H, &o, &e) == SL_OK, "%s", e.msg);
        const float *w = prep_window(p);
        CHECK(w[0] < 0.01 && w[W * H - 1] < 0.01, "corner %g", w[0]);
        CHECK(w[H / 2 * W + W / 2] > 0.99, "centre %g", w[H / 2 * W + W / 2]);
        /* symmetric */
        for (int x = 0; x < W; x++)
            CHECK_NEAR(w[H / 2 * W + x], w[H / 2 * W + (W - 1 - x)], 1e-6);
        if (kind == PREP_WIN_TUKEY) /* flat over the middle (1 - alpha) */
            CHECK(w[H / 2 * W + W / 4] == 1.0f, "Tukey not flat: %g", w[H / 2 * W + W / 4]);
        prep_free(p);
    }
}

TEST(choices_are_recorded_and_bad_options_named)
{
    prep_opts o;
    prep_opts_defaults(&o);
    prep *p = NULL;
    sl_err e;
    CHECK(prep_new(&p, W, H, &o, &e) == SL_OK, "%s", e.msg);
    pipeline_prep_report r;
    prep_report_fill(p, &r);
    CHECK(r.on && r.sky == 1 && !r.dark && !r.flat && !r.recentred && r.nbad == 0 &&
          r.border_px == 2, "sky %d dark %d flat %d border %d", r.sky, r.dark, r.flat,
          r.border_px);
    prep_free(p);
    float dark[W * H] = {0};
    o.dark = dark;
    CHECK(prep_new(&p, W, H, &o, &e) == SL_OK, "%s", e.msg);
    prep_report_fill(p, &r);
    CHECK(r.dark && r.sky == 3, "with a dark: dark %d sky %d", r.dark, r.sky);
    prep_free(p);
    o.dark = NULL;
    o.tukey_alpha = 0;
    CHECK(prep_new(&p, W, H, &o, &e) == SL_EINVAL && strstr(e.msg, "alpha"), "%s", e.msg);
    prep_opts_defaults(&o);
    float flat[W * H] = {0};
    o.flat = flat;
    CHECK(prep_new(&p, W, H, &o, &e) == SL_EDATA && strstr(e.msg, "flat"), "%s", e.msg);
}

/* Real frames (A 258): the background is clipped at ~16 ADU with sparse
 * noise spikes; the border median is the sky, and after cleaning it sits at
 * zero while the star keeps its flux. */
static int cmpf(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

TEST(real_frames_clean_to_zero_background)
{
    const char *pat = "../shared/data/a258/a258_f*.fit";
    cube_reader *r = NULL;
    sl_err e;
    if (cube_reader_open(&r, &pat, 1, 0, &e) != SL_OK)
        SKIP("../shared/data/a258 is absent (a user's clone): %s", e.msg);
    int w = cube_reader_width(r), h = cube_reader_height(r), k = 0;
    float *f = malloc(sizeof(float) * w * h), row[4096];
    prep_opts o;
    prep_opts_defaults(&o);
    o.window = PREP_WIN_NONE;
    prep *p = NULL;
    int rc = prep_new(&p, w, h, &o, &e);
    while (rc == SL_OK && cube_reader_next(r, f) == SL_OK) {
        prep_stats st;
        prep_frame(p, f, &st);
        memcpy(row, f, sizeof(float) * w);
        qsort(row, (size_t)w, sizeof(float), cmpf);
        if (!(st.sky > 10 && st.sky < 25) || !(st.flux > 0) || fabsf(row[w / 2]) > 1)
            break;
        k++;
    }
    free(f);
    prep_free(p);
    cube_reader_free(r);
    CHECK(rc == SL_OK, "%s", e.msg);
    CHECK(k == 12, "frame %d: sky, flux or cleaned border median wrong", k);
}

/* ---- the sky's clipped mean and the recentring, against their
 * definitions summed pixel by pixel (prep.c sums on 4 chains and cuts
 * each row of the disc at its ends) ---------------------------------- */

#define DCX 9.3
#define DCY 21.6
#define DR 12.35

static double rim(int x, int y) /* d^2 - r^2: < 0 inside the disc */
{
    return (x - DCX) * (x - DCX) + (y - DCY) * (y - DCY) - DR * DR;
}

/* The clipped mean as defined: three passes, 4 rms about the last mean. */
static double ref_sky(const float *f, const uint8_t *sky)
{
    double mean = 0, rms = INFINITY;
    for (int pass = 0; pass < 3; pass++) {
        double s1 = 0, s2 = 0, c = 0;
        for (int i = 0; i < W * H; i++)
            if (sky[i] && isfinite(f[i]) && fabs(f[i] - mean) <= 4 * rms)
                s1 += f[i], s2 += (double)f[i] * f[i], c++;
        mean = s1 / c;
        rms = sqrt(fmax(s2 / c - mean * mean, 0)) + 1e-30;
    }
    return (float)mean;
}

/* The shift recentring makes, from the positive pixels of the disc of g
 * (the frame less its sky) but pixel `skip`, and pixel `also`, as
 * prep.h defines it. */
static int ref_shift_x(const float *g, int skip, int also)
{
    double s = 0, sx = 0, sy = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            if (y * W + x != skip && g[y * W + x] > 0 && (rim(x, y) <= 0 || y * W + x == also))
                s += g[y * W + x], sx += g[y * W + x] * x, sy += g[y * W + x] * y;
    double tol = fmax(3, DR / 10), cx = DCX, cy = DCY;
    if (hypot(sx / s - cx, sy / s - cy) > tol)
        cx = sx / s, cy = sy / s;
    int dx = ((W / 2 - (int)lround(cx)) % W + W) % W;
    return dx > W / 2 ? dx - W : dx;
}

/* A sky of 1 + 4k pixels with two NaNs and a 1e6 outlier; a disc cut by
 * the frame's left edge, with a bright pixel at the end of one row just
 * inside the rim (A, above the centre) and one just outside (B, below):
 * an end off by one either way moves the shift. */
TEST(sky_and_centroid_follow_their_definitions)
{
    float f[W * H], g[W * H];
    uint8_t sky[W * H];
    int nsky = 0, a = -1, b = -1;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            int i = y * W + x;
            sky[i] = rim(x, y) > 40 && i % 3 != 0;
            nsky += sky[i];
            f[i] = (float)(20 + ((i * 13) % 7) * 0.37 + (rim(x, y) <= 0 ? 5 : 0));
            if (x > 0 && rim(x, y) <= 0 && y < DCY && (a < 0 || rim(x, y) > rim(a % W, a / W)))
                a = i;
            if (rim(x, y) > 0 && y > DCY && (b < 0 || rim(x, y) < rim(b % W, b / W)))
                b = i;
        }
    if (nsky % 4 != 1)   /* a count past a multiple of 4 */
        for (int i = 0; i < W * H && nsky % 4 != 1; i += 3)
            if (rim(i % W, i / W) > 40)
                sky[i] = 1, nsky++;
    int sk[3], k = 0;
    for (int i = W * H - 1; i >= 0 && k < 3; i--)
        if (sky[i])
            sk[k++] = i;
    f[sk[0]] = NAN, f[sk[1]] = NAN, f[sk[2]] = 1e6f;
    f[a] += 5000, f[b] += 5000;
    prep_opts o;
    prep_opts_defaults(&o);
    o.window = PREP_WIN_NONE;
    prep *p = NULL;
    sl_err e;
    CHECK(prep_new(&p, W, H, &o, &e) == SL_OK, "%s", e.msg);
    CHECK(prep_set_sky(p, sky) == SL_OK && prep_set_centre(p, DCX, DCY, DR) == SL_OK, "set");
    float sky_want = (float)ref_sky(f, sky);
    for (int i = 0; i < W * H; i++)
        g[i] = f[i] - sky_want;
    int want = ref_shift_x(g, -1, -1), no_a = ref_shift_x(g, a, -1), with_b = ref_shift_x(g, -1, b);
    prep_stats st;
    CHECK(prep_frame(p, f, &st) == SL_OK, "%s", prep_errmsg(p));
    CHECK_NEAR(st.sky, sky_want, 1e-6 * sky_want);
    CHECK(want != no_a && want != with_b, "the test cannot see A or B (shifts %d, %d, %d)",
          want, no_a, with_b);
    CHECK(st.shift_x == want, "shift %d, defined %d (%d without A, %d with B)", st.shift_x,
          want, no_a, with_b);
    printf("    sky %.6f (%d pixels), shift %d (%d without A, %d with B)\n", st.sky, nsky,
           st.shift_x, no_a, with_b);
    prep_free(p);
}

TC_MAIN(TC_CASE(dark_flat_and_sky_are_removed), TC_CASE(hot_dead_nan_and_saturated_pixels_are_repaired),
        TC_CASE(windows_taper_the_edges), TC_CASE(choices_are_recorded_and_bad_options_named),
        TC_CASE(real_frames_clean_to_zero_background),
        TC_CASE(sky_and_centroid_follow_their_definitions))
