/* sim_file.h - a simulation's truth in FITS files, written in one place
 * for `specklab sim` and the bench: the TRUTH and COPHASED image
 * extensions of a cube, and a blind cube's sidecar. */
#ifndef SL_SIM_FILE_H
#define SL_SIM_FILE_H

#include "io/cube.h"
#include "sim.h"

/* Append TRUTH (the sky, unit flux) and COPHASED (the same pupil without
 * turbulence) to w after its last frame; buf: one frame of scratch.
 * Errors name the image. */
int sim_file_add_truth(sim *s, cube_writer *w, float *buf, sl_err *err);
/* A blind cube's sidecar at path: the truth as its one frame under md
 * (every simulation keyword), then TRUTH and COPHASED. */
int sim_file_write_sidecar(sim *s, const char *path, const cube_meta *md,
                           float *buf, sl_err *err);
/* The sidecar of cube_path: "X.fits" -> "X-truth.fits", anything else
 * gets "-truth.fits" appended.  malloc'd; NULL when out of memory. */
char *sim_file_sidecar_path(const char *cube_path);

#endif
