/* framelog.h - a run's FRAMES rows kept on disk while it acquires, in a
 * sidecar DATA/runs/<uuid>.frames beside the .part cube.  Two reasons:
 *  - a daemon killed mid-run leaves its rows behind, and the restart
 *    rebuilds the cube's FRAMES table from them (frame ids, timestamps,
 *    per-frame status: without them frames_failed cannot be checked
 *    against the file);
 *  - the sidecar is preallocated at the start to the size of the whole
 *    table (every row the run may deliver), so the room for the table is
 *    held from the first frame: when the cube fills the disk, deleting
 *    the sidecar frees what the table needs.  A run that cannot get that
 *    room fails before its first frame.
 * Format: a 32-byte header (magic "SLFRAME1", row size, row count, all
 * host order: the file never leaves the machine) and cubefile_row
 * records.  The count is written after the rows it covers, so whatever
 * kills the daemon, the sidecar holds a consistent prefix.  Rows are
 * appended after each flush of the cube, so every row with a CUBE_IDX
 * names a frame already handed to the kernel.  Cost: two pwrite calls
 * per flush (100 ms); no fsync (the cube is not fsynced before it is
 * stored either).
 */
#ifndef SL_DAEMON_FRAMELOG_H
#define SL_DAEMON_FRAMELOG_H

#include "cubefile.h"

typedef struct framelog framelog;

/* The sidecar of a cube: ".../<uuid>.fits[.part]" -> ".../<uuid>.frames". */
char *framelog_path(const char *cube_path);

/* Create path with room for max_rows rows and the FITS table they make;
 * SL_EIO naming the path and the size when the disk cannot hold it. */
int framelog_create(framelog **out, const char *path, long max_rows, sl_err *err);
/* Append n rows (beyond max_rows: SL_ERANGE, nothing written). */
int framelog_append(framelog *f, const cubefile_row *rows, long n, sl_err *err);
/* Close the descriptor; the file stays.  NULL is a no-op. */
void framelog_close(framelog *f);

/* The rows of a sidecar: *rows (g_free) and *n.  SL_EFORMAT when it is
 * not one (or a truncated one), SL_EIO when it cannot be read. */
int framelog_read(const char *path, cubefile_row **rows, long *n, sl_err *err);

/* Write cube's FRAMES table from rows, each CUBE_IDX at or beyond
 * on_disk (the frames the cube holds) turned to -1 first: the table never
 * names a frame that is not in the cube.  When the disk is full, the
 * sidecar at log_path (may be NULL) is deleted to make room and the write
 * tried again; the sidecar is removed in any case. */
int framelog_table(const char *cube, const char *log_path, cubefile_row *rows, long n,
                   int on_disk, const camera_stats *st, sl_err *err);

/* After a restart: give a salvaged cube of on_disk frames the FRAMES
 * table its sidecar holds (when it has none yet) and remove the sidecar.
 * SL_OK when there was no sidecar. */
int framelog_recover(const char *cube, int on_disk, sl_err *err);

#endif
