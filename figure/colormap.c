/* colormap.c - the sky figures' colour map; see colormap.h. */
#include "colormap.h"

#include <math.h>

#define PI 3.14159265358979323846
#define L_LO 2.0
#define L_HI 98.0
#define HUE_LO_DEG (-70.0)
#define HUE_HI_DEG 95.0
#define CHROMA_MAX 70.0

double colormap_lightness(int i)
{
    return L_LO + (L_HI - L_LO) * (double)i / (COLORMAP_N - 1);
}

/* CIELAB (D65 white) to linear sRGB. */
static void lab_to_linear(double L, double a, double b, double rgb[3])
{
    double fy = (L + 16.0) / 116.0, f[3] = {fy + a / 500.0, fy, fy - b / 200.0};
    const double white[3] = {0.95047, 1.0, 1.08883};
    double xyz[3];
    for (int k = 0; k < 3; k++) {
        double v = f[k] > 6.0 / 29.0 ? f[k] * f[k] * f[k]
                                     : 3.0 * (6.0 / 29.0) * (6.0 / 29.0) * (f[k] - 4.0 / 29.0);
        xyz[k] = white[k] * v;
    }
    rgb[0] = 3.2406 * xyz[0] - 1.5372 * xyz[1] - 0.4986 * xyz[2];
    rgb[1] = -0.9689 * xyz[0] + 1.8758 * xyz[1] + 0.0415 * xyz[2];
    rgb[2] = 0.0557 * xyz[0] - 0.2040 * xyz[1] + 1.0570 * xyz[2];
}

static int in_gamut(const double rgb[3])
{
    for (int k = 0; k < 3; k++)
        if (rgb[k] < -1e-9 || rgb[k] > 1.0 + 1e-9)
            return 0;
    return 1;
}

/* The largest chroma up to c_max that sRGB shows at (L, hue): bisection. */
static double fit_chroma(double L, double hue, double c_max)
{
    double rgb[3], lo = 0.0, hi = c_max;
    lab_to_linear(L, hi * cos(hue), hi * sin(hue), rgb);
    if (in_gamut(rgb))
        return hi;
    for (int it = 0; it < 30; it++) {
        double mid = 0.5 * (lo + hi);
        lab_to_linear(L, mid * cos(hue), mid * sin(hue), rgb);
        if (in_gamut(rgb))
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

static unsigned char encode_srgb(double v)
{
    v = v < 0.0 ? 0.0 : v > 1.0 ? 1.0 : v;
    v = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
    return (unsigned char)lround(255.0 * v);
}

void colormap_init(colormap *cm)
{
    for (int i = 0; i < COLORMAP_N; i++) {
        double t = (double)i / (COLORMAP_N - 1), L = colormap_lightness(i);
        double hue = (HUE_LO_DEG + (HUE_HI_DEG - HUE_LO_DEG) * t) * PI / 180.0;
        double c = fit_chroma(L, hue, CHROMA_MAX * pow(sin(PI * t), 0.8));
        double rgb[3];
        lab_to_linear(L, c * cos(hue), c * sin(hue), rgb);
        for (int k = 0; k < 3; k++)
            cm->rgb[i][k] = encode_srgb(rgb[k]);
    }
}

const unsigned char *colormap_rgb(const colormap *cm, double t)
{
    int i = isfinite(t) ? (int)lround(t * (COLORMAP_N - 1)) : 0;
    i = i < 0 ? 0 : i >= COLORMAP_N ? COLORMAP_N - 1 : i;
    return cm->rgb[i];
}
