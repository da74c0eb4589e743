/* outfile.h - the files specklab writes, without destroying data.
 *
 * Three rules, for every output of every command:
 *   1. an output that is one of the inputs (the same file: device and
 *      inode, so another name or a link to it counts) is refused, even
 *      with --overwrite;
 *   2. an existing output is refused unless the command was given
 *      --overwrite;
 *   3. the output is written to a temporary name in its own directory and
 *      renamed over the final name only when complete (rename(2) is atomic
 *      within a file system), so a failed or interrupted write leaves the
 *      old file, if any, untouched and no half-written one.
 * Streaming captures that must keep every frame on failure (camera grab)
 * use rule 1 and 2 only (outfile_check).
 */
#ifndef SL_OUTFILE_H
#define SL_OUTFILE_H

#include <glib.h>

typedef struct outfile {
    char *path;  /* the file asked for */
    char *tmp;   /* where it is written until outfile_commit */
} outfile;

/* Rules 1 and 2 for path against inputs[0..ninputs) (paths or quoted
 * globs, as the FITS reader takes them; NULL entries are skipped).
 * FALSE with error set naming both files. */
gboolean outfile_check(const char *path, gboolean overwrite,
                       const char *const *inputs, int ninputs, GError **error);
/* outfile_check, then reserve the temporary name f->tmp (a fresh name in
 * path's directory, not created: the writer creates it). */
gboolean outfile_begin(outfile *f, const char *path, gboolean overwrite,
                       const char *const *inputs, int ninputs, GError **error);
/* Rename f->tmp over f->path. */
gboolean outfile_commit(outfile *f, GError **error);
/* Remove the temporary if it is still there and free; a zeroed outfile
 * and one already committed are fine. */
void outfile_clear(outfile *f);

#endif
