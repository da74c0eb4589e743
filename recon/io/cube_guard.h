/* cube_guard.h - private to recon/cube*.c: FITS files that cfitsio 4.2
 * must not be given (it crashes on them).
 */
#ifndef SL_CUBE_GUARD_H
#define SL_CUBE_GUARD_H

#include "status.h"

/* SL_OK, or SL_EFORMAT naming path and the reason when a header holds a
 * tile-compressed image (ZIMAGE = T).  A file that cannot be opened or
 * walked is SL_OK: cfitsio then gives the verdict.  Call it before every
 * fits_open_diskfile of a file from outside. */
int cube_guard_check(const char *path, sl_err *err);

#endif
