/* binmeas.h - the CLI's report of a measured binary (binmeas.c). */
#ifndef SL_BINMEAS_H
#define SL_BINMEAS_H

#include "cli.h"
#include "io/cube.h"
#include "pipeline/pipeline.h"

/* The verdict an image's header carries (MEAS*, CP*); status NONE when
 * the image was made without --binary. */
void binmeas_from_header(const cube_meta *m, pipeline_binary *r);
/* Members "binary" (the verdict) and, when fitted, "closure_phase" and
 * "fringe"; nothing when the status is NONE.  ps: arcsec per pixel or
 * NAN. */
void binmeas_json(JsonBuilder *b, const pipeline_binary *r, double ps);
/* "  binary: measured, from closure phases: sep ..." */
void binmeas_print(const pipeline_binary *r, double ps);

#endif
