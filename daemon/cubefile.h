/* cubefile.h - what the daemon does to an acquired cube after (or instead
 * of) recon's cube writer: salvage the frames on disk after a crash or a
 * full disk, append the FRAMES table, checksum, fsync and rename.
 *
 * Salvage.  The cube writer grows NAXIS3 before each frame's data, and
 * cfitsio may push a header block before the data it describes, so after
 * SIGKILL or ENOSPC/EFBIG the header can promise frames the file does not
 * hold.  cubefile_salvage rewrites the NAXIS3 card in place to the number
 * of whole frames present, zero-fills to the 2880-byte boundary and cuts
 * anything after it, without ever growing the file beyond its size (the
 * disk may be full): at most the frame in flight is lost.  Its CHECKSUM
 * and DATASUM (io/cube.h) are then made right in place when they fail:
 * one read of the cube (0.08 s for 1000 frames of 256^2 in the page
 * cache; the sha256 that follows reads it once more anyway).
 */
#ifndef SL_DAEMON_CUBEFILE_H
#define SL_DAEMON_CUBEFILE_H

#include <stdint.h>

#include "camera.h"
#include "status.h"

/* One buffer the camera delivered, good or damaged. */
typedef struct cubefile_row {
    uint64_t frame_id, cam_ts_ns, sys_ts_ns;
    int status;        /* camera_frame_status */
    int cube_idx;      /* 0-based frame in the cube, -1: not stored */
} cubefile_row;

/* Make path's primary HDU a valid 3-D cube of the whole frames on disk;
 * *nframes receives their number.  SL_EFORMAT when the primary header is
 * incomplete or not a 3-D image (nothing changed), SL_EIO on I/O errors. */
int cubefile_salvage(const char *path, int *nframes, sl_err *err);

/* Append the binary table extension FRAMES (FRAME_ID K, CAM_TS_NS K,
 * SYS_TS_NS K, STATUS 16A, CUBE_IDX J) with summary keywords from st
 * (may be NULL).  On failure the file is cut back to its size before the
 * call, so the cube stays as it was. */
int cubefile_frames_table(const char *path, const cubefile_row *rows, long n,
                          const camera_stats *st, sl_err *err);

/* 1 when path has a FRAMES binary table extension. */
int cubefile_has_table(const char *path);

/* 64 lowercase hex digits and a NUL. */
int cubefile_sha256(const char *path, char hex[65], sl_err *err);

/* fsync the file, and the directory that holds it (a rename or a new
 * name is durable only once its directory is). */
int cubefile_fsync(const char *path, sl_err *err);
int cubefile_fsync_dir(const char *path_in_dir, sl_err *err);

/* 1 when path, with symlinks resolved, lies inside directory dir (both
 * must exist): the guard before the daemon reads or writes a path that
 * came from the catalogue or a request. */
int cubefile_under(const char *dir, const char *path);

#endif
