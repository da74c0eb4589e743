/* mask.h - telescope pupils: a filled circular aperture or an aperture mask
 * of circular holes (non-redundant masking, after Surya & Saha: 17 holes of
 * 10 cm within a 1 m maximum baseline, 20 cm minimum centre spacing).
 *
 * Pupil-plane coordinates are metres from the pupil centre: +y is north and
 * +x is east, east to the RIGHT in the pupil plane.  mask_render maps +x_m to
 * increasing pixel column x and +y_m to increasing row y, with the origin at
 * pixel (n/2, n/2); how the pupil's orientation carries to the sky image
 * (where east is -x) is the propagator's business, not this module's.
 *
 * Redundancy.  The n(n-1)/2 baselines are b = c_j - c_i (i < j); b and -b
 * are the same u-v point.  Two distinct baselines are redundant when
 * min(|b_k - b_l|, |b_k + b_l|) < hole diameter d, and the redundancy of a
 * mask is the number of such unordered baseline pairs.  Because holes never
 * overlap (every centre distance >= d), at most one of the two distances
 * can be below d for any pair.  Note this threshold is d, not 2d: each
 * baseline's MTF patch has radius d, so patches of two baselines closer than
 * d share over 39% of their area; pairs between d and 2d overlap only in
 * their faint rims and are not counted.
 *
 * Every mask object satisfies: nholes >= 2 (or 0 for a filled aperture),
 * finite centres, hole diameter > 0, and no two holes overlap (centre
 * distance >= hole diameter).  Numbers in files are parsed and printed in the
 * C locale's format (the process must not have switched LC_NUMERIC).
 */
#ifndef SL_MASK_H
#define SL_MASK_H

#include <stdint.h>

#include "status.h"

typedef struct mask mask;

/* Largest hole count a mask may have: counting redundancy at construction
 * costs O(nholes^4), about 5e8 baseline-pair tests at this limit. */
#define MASK_MAX_HOLES 256

/* A filled circular aperture of the given diameter; NULL if diameter_m is
 * not finite and > 0, or out of memory. */
mask *mask_new_full(double diameter_m);
/* A filled aperture with a central obstruction (a secondary mirror) of
 * obstruction * diameter_m across, obstruction in [0,
 * MASK_MAX_OBSTRUCTION]; 0 is mask_new_full.  The extent stays the outer
 * diameter.  NULL with err set (SL_EINVAL, SL_ENOMEM). */
#define MASK_MAX_OBSTRUCTION 0.9
mask *mask_new_full_obstructed(double diameter_m, double obstruction,
                               sl_err *err);
/* Holes of one diameter at centres (x_m[i], y_m[i]); NULL with err set on
 * fewer than 2 or more than MASK_MAX_HOLES holes (SL_EINVAL), non-finite
 * numbers or overlapping holes (SL_EDATA), out of memory (SL_ENOMEM). */
mask *mask_new_holes(const double *x_m, const double *y_m, int nholes,
                     double hole_diameter_m, sl_err *err);
void mask_free(mask *m);

/* Read a mask file:
 *     # comments run from '#' to the end of the line; blank lines ignored
 *     hole_diameter_m 0.1      (required, before any hole)
 *     0.25 -0.1                (x_m y_m, one line per hole)
 * Errors name the file and line: SL_EIO (cannot open/read), SL_EFORMAT
 * (syntax, missing or repeated hole_diameter_m, fewer than 2 holes), SL_EDATA
 * (non-finite or non-positive numbers, overlapping holes), SL_ERANGE (more
 * than MASK_MAX_HOLES holes). */
int mask_read(mask **out, const char *path, sl_err *err);
/* Write a hole mask in mask_read's format with %.17g, so reading it back
 * gives bit-identical centres.  SL_EINVAL for a filled aperture (the format
 * has no way to say it), SL_EIO on any write failure. */
int mask_write(const mask *m, const char *path, sl_err *err);

#define MASK_GEN_RESTARTS 4
#define MASK_GEN_MAX_HOLES 64

typedef struct mask_gen_opts {
    int nholes;             /* 2..MASK_GEN_MAX_HOLES */
    double hole_diameter_m; /* d */
    double max_baseline_m;  /* centres lie in a disk of this diameter */
    double min_spacing_m;   /* least centre distance, >= hole_diameter_m */
    uint64_t seed;          /* same seed, same mask (given the same libm:
                             * exp, pow and log steer the search) */
    int iterations;         /* annealing moves per restart; 0 = the best of
                             * the random initial layouts, unimproved */
} mask_gen_opts;

/* The Surya & Saha setup: 17 holes, 0.10 m, 1.0 m, 0.20 m, seed 17, and
 * 3500 iterations: about 40 ms (4 x 3500 moves of ~2.7 us, each an
 * O(nholes * nbaselines) energy update).  It reaches redundancy 60 for seed
 * 17 (65 on average over seeds 17..32, from ~230 for random layouts);
 * 50x more iterations reach ~52, so zero is far out of reach. */
void mask_gen_defaults(mask_gen_opts *o);
/* Search for a least-redundant layout: MASK_GEN_RESTARTS random layouts
 * (random sequential placement), each improved by simulated annealing with
 * single-hole moves; the result is the best layout seen, so it is never
 * worse than the random layouts it started from.  Zero redundancy is NOT
 * guaranteed: mask_redundancy reports what was reached, recounted from
 * scratch.  The name is "custom".  SL_EINVAL on bad options, SL_ERANGE if
 * the holes cannot be placed at that spacing in that disk. */
int mask_generate(mask **out, const mask_gen_opts *o, sl_err *err);

/* Built-in pupils: "nrm17" = mask_generate with the defaults; "full" = a
 * filled 1.1 m aperture, the outer diameter of nrm17's design disk
 * (1.0 m baseline + 0.1 m hole).  Unknown names: SL_EINVAL listing these. */
int mask_named(mask **out, const char *name, sl_err *err);

/* Accessors (never fail on a valid mask). */
int mask_nholes(const mask *m);            /* 0 for a filled aperture */
/* Centre of hole i (0 <= i < nholes), metres. */
void mask_hole(const mask *m, int i, double *x_m, double *y_m);
double mask_hole_diameter_m(const mask *m); /* 0 for a filled aperture */
int mask_is_full(const mask *m);
double mask_diameter_m(const mask *m);     /* filled: D; holes: 0 */
/* Central obstruction as a fraction of D; 0 for holes or none. */
double mask_obstruction(const mask *m);
/* Outer diameter of the pupil: the longest centre distance + d for holes,
 * D for a filled aperture. */
double mask_extent_m(const mask *m);
/* Longest / shortest centre distance (filled aperture: D and 0). */
double mask_max_baseline_m(const mask *m);
double mask_min_spacing_m(const mask *m);
/* Redundant baseline pairs (see above); -1 for a filled aperture, where the
 * count is undefined (every baseline is redundant). */
long mask_redundancy(const mask *m);
/* "nrm17", "full", or "custom". */
const char *mask_name(const mask *m);

/* Rasterize the transmission (0..1) into pupil[n*n] (pixel (x, y) at
 * pupil[y*n + x]) with pitch dx_m and the pupil origin at pixel (n/2, n/2).
 * Interior pixels are exactly 1, outside pixels (and those behind a central
 * obstruction) exactly 0, edge pixels the covered fraction from 8x8
 * supersampling.  Costs O(n^2) to clear plus
 * O(pixels inside the holes' bounding boxes).  SL_ERANGE (message in err)
 * if any part of the pupil falls outside the grid, e.g. extent > n*dx_m.
 * The grid spans pixel offsets -n/2 - 0.5 .. n - 1 - n/2 + 0.5 from the
 * centre, so a centred disk fits up to diameter (n - 1) * dx_m for even n.
 * SL_EINVAL on bad arguments. */
int mask_render(const mask *m, float *pupil, int n, double dx_m,
                sl_err *err);

#endif
