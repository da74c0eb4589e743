/* cube_header.h - private to recon/io: an image HDU's header as the
 * writer writes it and the reader keeps it (cube.h, "The standard header"
 * and "WCS"): the metadata's keywords, DATE, CREATOR, the WCS derived
 * from the plate scale, and HISTORY.  CHECKSUM and DATASUM are the
 * writer's (cube_write.c): they depend on when the data are complete.
 */
#ifndef SL_CUBE_HEADER_H
#define SL_CUBE_HEADER_H

#include <fitsio.h>

#include "cube.h"

/* 1 when the writer derives key (DATE, CREATOR, a WCS keyword of the
 * primary or an alternate description: CTYPE1, CDELT2A, PC1_2, WCSNAME,
 * RADESYS, ...): never an extra, never kept by a read. */
int cube_header_is_derived(const char *key);

/* m's keywords (m may be NULL) and the standard header into fp's current
 * HDU, an image of width x height pixels.  with_date_obs: DATE-OBS = now
 * when m has none (a cube's primary HDU).  cfitsio status in *st. */
void cube_header_write(fitsfile *fp, const cube_meta *m, int width,
                       int height, int with_date_obs, int *st);

/* The metadata of fp's current HDU into m (cube.h: which keywords are
 * kept, which derived ones dropped); SL_EFORMAT naming path when the
 * header cannot be read. */
int cube_header_read(fitsfile *fp, cube_meta *m, const char *path, sl_err *err);

/* One HISTORY card's text read from a file into m (cube.h: at most
 * CUBE_HISTORY_MAX / 2 bytes are kept, the rest counted in ndropped). */
void cube_header_take_history(cube_meta *m, const char *text);

#endif
