/* scene.h - what the simulated telescope looks at.
 *
 * A scene is a list of components on the sky, in arcseconds relative to the
 * field centre with +y north and -x east (east left), fluxes relative.
 * Components are points (stars, lasers) and disks (planet-like: linear limb
 * darkening and sinusoidal bands along y).  Named scenes:
 *   point    one star at the centre;
 *   binary   two stars, separation sep_arcsec, position angle pa_deg of the
 *            fainter from the brighter (from +y/north towards -x/east), and
 *            magnitude difference dm; the flux centroid sits at the centre;
 *   six-star a compact group of six stars of unequal brightness;
 *   extended a limb-darkened banded disk (a planet).
 * Scene files (see scene_read) hold points and disks, one per line.
 */
#ifndef SL_SCENE_H
#define SL_SCENE_H

#include "status.h"

typedef struct scene scene;

enum scene_kind { SCENE_POINT = 0, SCENE_DISK = 1 };

typedef struct scene_comp {
    int kind;               /* SCENE_POINT or SCENE_DISK */
    double x_arcsec;        /* offset east is NEGATIVE x (east left) */
    double y_arcsec;        /* offset north is positive y */
    double flux;            /* relative total flux of the component */
    double radius_arcsec;   /* disks only */
    double limb_u;          /* linear limb darkening I = 1 - u(1 - mu) */
    double band_amp;        /* band contrast, 0 = none */
    double band_period_arcsec;
} scene_comp;

scene *scene_new(void);
void scene_free(scene *s);
/* Copy the name into the scene ("binary", file name, ...). */
void scene_set_name(scene *s, const char *name);
const char *scene_name(const scene *s);
int scene_add(scene *s, const scene_comp *c, sl_err *err);
int scene_ncomp(const scene *s);
const scene_comp *scene_comp_at(const scene *s, int i);
double scene_total_flux(const scene *s);
/* Largest distance of any component edge from the field centre. */
double scene_radius_arcsec(const scene *s);

/* Companion offset of a binary, by the PA convention: dx = -sep sin(pa),
 * dy = sep cos(pa) (arcsec or pixels alike). */
void scene_pa_offset(double sep, double pa_deg, double *dx, double *dy);

int scene_binary(scene **out, double sep_arcsec, double pa_deg, double dm_mag,
                 sl_err *err);
/* The named scenes of the header comment; params used only by "binary". */
int scene_named(scene **out, const char *name, double sep_arcsec,
                double pa_deg, double dm_mag, sl_err *err);
/* Scene file: '#' comments; lines
 *   point X_ARCSEC Y_ARCSEC FLUX
 *   disk  X_ARCSEC Y_ARCSEC RADIUS_ARCSEC FLUX [LIMB_U [BAND_AMP BAND_PERIOD_ARCSEC]]
 * Errors name the file and line. */
int scene_read(scene **out, const char *path, sl_err *err);

/* Render the true sky on a w x h grid of pscale_arcsec pixels with the
 * field centre at pixel (w/2, h/2): points split bilinearly over the four
 * nearest pixels and disks area-sampled 4x4 per pixel, so the image sum is
 * the scene's total flux (for everything inside the grid).  Points are
 * omitted when omit_points is set: the simulator adds them analytically
 * in the Fourier domain (exact sub-pixel positions).  SL_EINVAL for a bad
 * grid; SL_ERANGE, with an all-zero image, when a disk that touches the
 * grid has a radius over SCENE_MAX_DISK_RADIUS_PX pixels (its whole-disk
 * normalisation would cost O(radius^2) samples). */
#define SCENE_MAX_DISK_RADIUS_PX 1024
int scene_render(const scene *s, float *img, int w, int h,
                 double pscale_arcsec, int omit_points);
/* The same on pixels psx_arcsec wide and psy_arcsec tall (a detector with
 * non-square pixels); scene_render is psx = psy = pscale_arcsec. */
int scene_render_rect(const scene *s, float *img, int w, int h,
                      double psx_arcsec, double psy_arcsec, int omit_points);

#endif
