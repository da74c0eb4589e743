/* test_skyfig.c - reconstruction figures read back: the size, the scale
 * bar's length from the plate scale and the enlargement, the compass
 * pointing north up and east left, the binary's two stars as separate
 * maxima where the position angle puts them, the colour bar, the cut
 * above the artifacts, the colour map's even lightness. */
#include <math.h>
#include <stdint.h>
#include <unistd.h>

#include "colormap.h"
#include "display.h"
#include "png_rgb.h"
#include "skyfig.h"
#include "tcheck.h"

#define W 128
#define H 128
#define PLATE 0.05     /* arcsec/px */
#define SEP_PX 12.0
#define PA_DEG 30.0
#define RATIO 0.4      /* companion / primary: dm 1 */
#define PI 3.14159265358979323846

/* Uniform in [0, 1) from a 64-bit LCG: the same image every run. */
static double lcg(uint64_t *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) / 9007199254740992.0;
}

static void star(float *img, double x0, double y0, double peak)
{
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            img[y * W + x] += (float)(peak * exp(-((x - x0) * (x - x0) + (y - y0) * (y - y0)) /
                                                 (2 * 1.1 * 1.1)));
}

/* A reconstruction-like binary: the primary at the centre, the companion
 * SEP_PX away at PA_DEG (from +y towards -x), sky noise of 0.005, and 300
 * one-pixel artifacts of 0.03-0.15 within 30 px (streaks, halo). */
static void binary_image(float *img, double *cx, double *cy)
{
    uint64_t s = 7;
    for (int i = 0; i < W * H; i++)
        img[i] = (float)(0.005 * (lcg(&s) + lcg(&s) + lcg(&s) - 1.5) * 2);
    for (int k = 0; k < 300; k++) {
        double r = 4 + 26 * lcg(&s), a = 2 * PI * lcg(&s);
        int x = W / 2 + (int)lround(r * cos(a)), y = H / 2 + (int)lround(r * sin(a));
        img[y * W + x] += (float)(0.03 + 0.12 * lcg(&s));
    }
    *cx = W / 2 - SEP_PX * sin(PA_DEG * PI / 180);
    *cy = H / 2 + SEP_PX * cos(PA_DEG * PI / 180);
    star(img, W / 2, H / 2, 1.0);
    star(img, *cx, *cy, RATIO);
}

static const char *tmp_png(char *buf, size_t n, const char *tag)
{
    snprintf(buf, n, "/tmp/test_skyfig_%ld_%s.png", (long)getpid(), tag);
    return buf;
}

/* Write img's figure, read it back with its layout; 1 on success. */
static int figure(const float *img, const skyfig_opts *o, const char *tag, rgb_image *im,
                  skyfig_layout *l, sl_err *e)
{
    char path[128];
    tmp_png(path, sizeof path, tag);
    int ok = skyfig_write_png(path, img, W, H, o, e) == SL_OK &&
             skyfig_layout_of(o, img, W, H, l, e) == SL_OK && png_rgb_read(path, im);
    unlink(path);
    return ok;
}

/* The PNG pixel at the centre of image pixel (x, y). */
static void screen_of(const skyfig_layout *l, double x, double y, int *px, int *py)
{
    *px = l->img_x + (int)floor((x - l->crop_x0 + 0.5) * l->upscale);
    *py = l->img_y + (int)floor((l->crop_y0 + l->crop_h - 1 - y + 0.5) * l->upscale);
}

TEST(scale_bar_is_the_plate_scale_times_the_enlargement)
{
    static float img[W * H];
    double cx, cy;
    binary_image(img, &cx, &cy);
    skyfig_opts o;
    skyfig_opts_init(&o);
    o.plate_scale_arcsec = PLATE;
    snprintf(o.title, sizeof o.title, "test binary");
    rgb_image im = {0};
    skyfig_layout l;
    sl_err e = {0};
    CHECK(figure(img, &o, "bar", &im, &l, &e), "%s", e.msg);
    int ok_size = im.w == l.width && im.h == l.height && l.img_w >= 512 - l.upscale;
    double v = l.bar_value, p = pow(10, floor(log10(v))), mant = v / p;
    int nice = fabs(mant - 1) < 1e-9 || fabs(mant - 2) < 1e-9 || fabs(mant - 5) < 1e-9;
    int want = (int)lround(v / PLATE * l.upscale);
    /* the drawn bar: the dark run starting at bar_x in its middle row */
    int row = l.bar_y + l.bar_thick_px / 2, run = 0;
    while (png_rgb_dark(&im, l.bar_x + run, row))
        run++;
    int above_white = png_rgb_white(&im, l.bar_x + want / 2, l.bar_y - 3);
    free(im.px);
    CHECK(ok_size, "PNG %d x %d, layout %d x %d, image %d px wide", im.w, im.h, l.width,
          l.height, l.img_w);
    CHECK(l.bar_in_arcsec && nice, "bar %g (in arcsec: %d)", v, l.bar_in_arcsec);
    CHECK(l.bar_len_px == want, "layout bar %d px, want %g\" / %g x %d = %d px",
          l.bar_len_px, v, PLATE, l.upscale, want);
    CHECK(abs(run - want) <= 1, "drawn bar %d px, want %d", run, want);
    CHECK(want <= 0.3 * l.img_w + 1 && want >= 0.1 * l.img_w, "bar %d of %d px", want, l.img_w);
    CHECK(above_white, "the bar is not on white");
}

TEST(compass_points_north_up_and_east_left)
{
    static float img[W * H];
    double cx, cy;
    binary_image(img, &cx, &cy);
    skyfig_opts o;
    skyfig_opts_init(&o);
    o.plate_scale_arcsec = PLATE;
    rgb_image im = {0};
    skyfig_layout l;
    sl_err e = {0};
    CHECK(figure(img, &o, "compass", &im, &l, &e), "%s", e.msg);
    int x = l.compass_x, y = l.compass_y, n = l.compass_len, up = 0, left = 0;
    for (int k = 3; k < n - 3; k++) {
        up += png_rgb_dark(&im, x, y - k);
        left += png_rgb_dark(&im, x - k, y);
    }
    int down = 0, right = 0;
    for (int k = 4; k < 20; k++) {
        down += png_rgb_dark(&im, x, y + k);
        right += png_rgb_dark(&im, x + k, y);
    }
    /* the N arrow's tip: the topmost dark pixel of its column */
    int top = y;
    while (top > y - n - 4 && (png_rgb_dark(&im, x, top - 1) || png_rgb_dark(&im, x, top - 2)))
        top--;
    free(im.px);
    CHECK(up >= n - 8 && left >= n - 8, "arms: %d up, %d left of %d", up, left, n - 6);
    CHECK(down == 0 && right == 0, "ink below (%d) or right (%d) of the corner", down, right);
    CHECK(abs(top - (y - n)) <= 2, "N tip at row %d, want %d", top, y - n);
}

TEST(binary_shows_as_two_maxima_where_the_pa_puts_them)
{
    static float img[W * H];
    double cx, cy;
    binary_image(img, &cx, &cy);
    skyfig_opts o;
    skyfig_opts_init(&o);
    o.plate_scale_arcsec = PLATE;
    rgb_image im = {0};
    skyfig_layout l;
    sl_err e = {0};
    CHECK(figure(img, &o, "stars", &im, &l, &e), "%s", e.msg);
    /* The brightest block, then the brightest block >= 4 px from it, read
     * from the PNG at each shown image pixel's centre. */
    int bx[2] = {-1, -1}, by[2] = {-1, -1};
    double best[2] = {-1, -1};
    for (int pass = 0; pass < 2; pass++)
        for (int y = l.crop_y0; y < l.crop_y0 + l.crop_h; y++)
            for (int x = l.crop_x0; x < l.crop_x0 + l.crop_w; x++) {
                int px, py;
                screen_of(&l, x, y, &px, &py);
                double v = png_rgb_luma(&im, px, py);
                if (pass == 1 && hypot(x - bx[0], y - by[0]) < 4)
                    continue;
                if (v > best[pass])
                    best[pass] = v, bx[pass] = x, by[pass] = y;
            }
    int p0x, p0y, p1x, p1y, mx, my;
    screen_of(&l, bx[0], by[0], &p0x, &p0y);
    screen_of(&l, bx[1], by[1], &p1x, &p1y);
    screen_of(&l, (W / 2 + cx) / 2, (H / 2 + cy) / 2, &mx, &my);
    double mid = png_rgb_luma(&im, mx, my);
    free(im.px);
    CHECK(bx[0] == W / 2 && by[0] == H / 2, "primary at (%d, %d), want (%d, %d)", bx[0],
          by[0], W / 2, H / 2);
    CHECK(fabs(bx[1] - cx) <= 1 && fabs(by[1] - cy) <= 1, "companion at (%d, %d), want "
          "(%.1f, %.1f)", bx[1], by[1], cx, cy);
    /* north up, east left: PA 30 deg is up and a little left on screen */
    CHECK(p1y < p0y - 8 * l.upscale && p1x < p0x - 4 * l.upscale,
          "companion at screen (%d, %d), primary (%d, %d)", p1x, p1y, p0x, p0y);
    CHECK(mid < best[1] - 40, "not separate: %.0f between, %.0f and %.0f at the peaks", mid,
          best[0], best[1]);
}

TEST(colour_bar_runs_dark_to_light)
{
    static float img[W * H];
    double cx, cy;
    binary_image(img, &cx, &cy);
    skyfig_opts o;
    skyfig_opts_init(&o);
    rgb_image im = {0};
    skyfig_layout l;
    sl_err e = {0};
    CHECK(figure(img, &o, "cbar", &im, &l, &e), "%s", e.msg);
    int x = l.cbar_x + l.cbar_w / 2, rises = 0, chroma = 0;
    for (int y = l.cbar_y + 1; y < l.cbar_y + l.cbar_h; y++) {
        rises += png_rgb_luma(&im, x, y) > png_rgb_luma(&im, x, y - 1) + 0.5;
        const unsigned char *p = png_rgb_at(&im, x, y);
        int mx = p[0] > p[1] ? (p[0] > p[2] ? p[0] : p[2]) : (p[1] > p[2] ? p[1] : p[2]);
        int mn = p[0] < p[1] ? (p[0] < p[2] ? p[0] : p[2]) : (p[1] < p[2] ? p[1] : p[2]);
        chroma = mx - mn > chroma ? mx - mn : chroma;
    }
    double top = png_rgb_luma(&im, x, l.cbar_y), bottom = png_rgb_luma(&im, x, l.cbar_y + l.cbar_h - 1);
    /* tick labels: ink right of the bar */
    int ink = 0;
    for (int y = l.cbar_y; y < l.cbar_y + l.cbar_h; y++)
        for (int k = l.cbar_x + l.cbar_w + 10; k < l.cbar_x + l.cbar_w + 40; k++)
            ink += png_rgb_dark(&im, k, y);
    /* no plate scale: the bar is in image pixels */
    int px_bar = !l.bar_in_arcsec && l.bar_len_px == (int)lround(l.bar_value * l.upscale);
    free(im.px);
    CHECK(rises == 0 && top > 230 && bottom < 20, "colour bar: %d rises downwards, top %.0f, "
          "bottom %.0f", rises, top, bottom);
    CHECK(chroma > 100, "colour bar has no colour (chroma %d)", chroma);
    CHECK(ink > 50, "no tick labels (%d dark pixels)", ink);
    CHECK(px_bar, "unknown scale: bar %g px, %d on screen at %d x", l.bar_value, l.bar_len_px,
          l.upscale);
}

TEST(cut_sits_above_the_artifacts_and_below_the_companion)
{
    static float img[W * H];
    double cx, cy;
    binary_image(img, &cx, &cy);
    display d;
    sl_err e = {0};
    CHECK(display_fit(&d, img, W, H, DISPLAY_CUT_ARTIFACTS, PREVIEW_ASINH, &e) == SL_OK, "%s",
          e.msg);
    CHECK(d.cut_from_artifacts && d.lo > 0.09 && d.lo < RATIO * 0.8 && d.hi == d.peak,
          "cut [%g, %g] from %d maxima (from artifacts: %d)", d.lo, d.hi, d.nmaxima,
          d.cut_from_artifacts);
    CHECK(fabs(display_value(&d, display_level(&d, 0.3)) - 0.3) < 1e-9, "inverse");
    display f;
    CHECK(display_fit(&f, img, W, H, DISPLAY_CUT_FULL, PREVIEW_LINEAR, &e) == SL_OK, "%s",
          e.msg);
    CHECK(f.lo < 0 && display_level(&f, f.lo) == 0 && display_level(&f, f.hi) == 1, "full");
    /* two stars on an exact 0: nothing to measure, the cut is the sky */
    static float two[W * H];
    two[40 * W + 40] = 1;
    two[50 * W + 60] = 0.1f;
    CHECK(display_fit(&d, two, W, H, DISPLAY_CUT_ARTIFACTS, PREVIEW_ASINH, &e) == SL_OK &&
          !d.cut_from_artifacts && d.lo == 0 && display_level(&d, 0.1) > 0.2,
          "two stars: cut %g, level of the faint one %g", d.lo, display_level(&d, 0.1));
}

/* CIELAB L* of an 8-bit sRGB colour. */
static double lightness(const unsigned char *c)
{
    double lin[3];
    for (int k = 0; k < 3; k++) {
        double v = c[k] / 255.0;
        lin[k] = v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
    }
    double y = 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2];
    return y > 216.0 / 24389 ? 116 * cbrt(y) - 16 : y * 24389.0 / 27;
}

TEST(colour_map_lightness_rises_evenly)
{
    colormap cm;
    colormap_init(&cm);
    double worst = 0, prev = -1;
    int falls = 0;
    for (int i = 0; i < COLORMAP_N; i++) {
        double L = lightness(cm.rgb[i]);
        worst = fmax(worst, fabs(L - colormap_lightness(i)));
        falls += L <= prev;
        prev = L;
    }
    CHECK(falls == 0 && worst < 1.0, "L* falls %d times, off the even ramp by %.2f", falls,
          worst);
}

TEST(bad_input_names_the_problem)
{
    static float img[W * H];
    skyfig_opts o;
    skyfig_opts_init(&o);
    sl_err e = {0};
    CHECK(skyfig_write_png("/nonexistent-dir/x.png", img, W, H, &o, &e) == SL_EIO &&
          strstr(e.msg, "/nonexistent-dir/x.png"), "unwritable path: %s", e.msg);
    CHECK(access("/nonexistent-dir/x.png", F_OK) != 0, "file left behind");
    for (int i = 0; i < W * H; i++)
        img[i] = NAN;
    CHECK(skyfig_write_png("/tmp/never.png", img, W, H, &o, &e) == SL_EDATA, "all NaN: %d",
          e.code);
    CHECK(skyfig_write_png("/tmp/never.png", img, 0, H, &o, &e) == SL_EINVAL, "0 wide");
}

TC_MAIN(TC_CASE(scale_bar_is_the_plate_scale_times_the_enlargement),
        TC_CASE(compass_points_north_up_and_east_left),
        TC_CASE(binary_shows_as_two_maxima_where_the_pa_puts_them),
        TC_CASE(colour_bar_runs_dark_to_light),
        TC_CASE(cut_sits_above_the_artifacts_and_below_the_companion),
        TC_CASE(colour_map_lightness_rises_evenly),
        TC_CASE(bad_input_names_the_problem))
