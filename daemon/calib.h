/* calib.h - the calibration frames a reconstruction uses: a dark, a flat
 * with its own dark, a bad-pixel map.
 *
 * Each comes from the configuration's [calibration] file when one is
 * named (the operator's choice wins), else, with catalogued=yes, from the
 * catalogue: the done dark or flat run that catalog_run_find_calibration
 * matches to the run (same camera, pixel format and ROI; a dark also the
 * same exposure), and for a catalogued flat the dark matched to the flat
 * run.  A bad-pixel map is a file only.  A science run is also given a
 * reference: the done calibrator run (a point source through the same
 * screen and mask: the companion laser off) nearest in time, for the
 * transfer-function calibration of recon --ref, unless the request names
 * another or "none".  What was used is written into the reconstruction's
 * params (calib_json), so the catalogue says which dark calibrated which
 * image and which calibrator which target.
 */
#ifndef SL_DAEMON_CALIB_H
#define SL_DAEMON_CALIB_H

#include <json-glib/json-glib.h>

#include "catalog.h"
#include "config.h"
#include "pipeline/pipeline.h"

enum { CALIB_DARK, CALIB_FLAT, CALIB_FLAT_DARK, CALIB_BADPIX, CALIB_REF, CALIB_N };

typedef struct calib_set {
    char *path[CALIB_N];                        /* NULL: none */
    char run[CALIB_N][CATALOG_UUID_LEN + 1];    /* "": a configured file */
} calib_set;

/* Fill *out for run uuid of kind `kind` (zeroed first; calib_clear frees
 * it).  ref: NULL for the nearest calibrator (science runs only), "none"
 * for no reference, or a calibrator run's uuid.  SL_OK also when nothing
 * is found; SL_EINVAL when ref names no done calibrator run with a cube;
 * an error when the catalogue cannot be read (message in err). */
int calib_find(catalog *cat, const config *cfg, const char *uuid, catalog_kind kind,
               const char *ref, calib_set *out, sl_err *err);
/* Point the options at the set's files (borrowed: keep the set alive). */
void calib_apply(const calib_set *c, pipeline_opts *po);
/* Members "dark", "flat", "flat_dark", "badpix" of the open object in b,
 * each {"file": path} with "run": uuid when catalogued; absent when none. */
void calib_json(const calib_set *c, JsonBuilder *b);
void calib_clear(calib_set *c);

#endif
