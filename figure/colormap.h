/* colormap.h - the colour map of the sky figures: dark is faint, light is
 * bright, and equal steps of the value look like equal steps.
 *
 * Entry i of 256 (t = i / 255) has CIELAB lightness L* = 2 + 96 t: L*
 * rises evenly, so the eye reads brightness in proportion to the stretched
 * value (a rainbow's bright yellow band or grey's gamma would invent
 * edges), and in grey print or to a colour-blind reader the order stays.
 * The hue turns from violet (t = 0, -70 deg in CIELAB) through red to
 * yellow (t = 1, 95 deg) so neighbouring levels also differ in colour; the
 * chroma, 70 sin(pi t)^0.8 at most, is reduced at constant L* and hue
 * where sRGB cannot show it.  The ends are nearly grey: a black sky and
 * near-white peaks.
 */
#ifndef SL_COLORMAP_H
#define SL_COLORMAP_H

#define COLORMAP_N 256

typedef struct colormap {
    unsigned char rgb[COLORMAP_N][3]; /* sRGB, 8 bits */
} colormap;

/* Fill cm (a few thousand colour conversions: build one per figure). */
void colormap_init(colormap *cm);
/* The colour of t in [0, 1] (clamped; NaN reads as 0). */
const unsigned char *colormap_rgb(const colormap *cm, double t);
/* L* of entry i as built (for the tests' and the colour bar's sake). */
double colormap_lightness(int i);

#endif
