/* fuzz_fits.c - libFuzzer target: the FITS reader of recon/io/cube.c on one
 * arbitrary file.
 *
 * The input is the whole file.  cfitsio wants a path, so the bytes go to a
 * memfd (a RAM file with no name in any directory: nothing to clean up
 * after a crash) opened as /proc/self/fd/N.  One input runs:
 *   cube_reader_open, every frame with cube_reader_next (a NaN/Inf frame is
 *   consumed and skipped, any other error ends the pass), a rewind and one
 *   more frame; then cube_read_ext(..., "TRUTH").
 * Besides "no crash, no sanitizer report", it checks the reader's contract
 * and aborts (a finding) when it breaks: sizes >= 1 after a successful
 * open, exactly nframes frames then SL_EEND, every failure with a negative
 * code and a message, the metadata strings NUL-terminated.
 * The caller of the reader owns the frame buffer, so frames larger than
 * FUZZ_MAX_PIX are not read (the open is still exercised): that bound is
 * the harness's, not the reader's.
 */
#define _GNU_SOURCE
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "io/cube.h"
#define FUZZ_NAME "fuzz_fits"
#include "fuzz_util.h"
#include "fuzz_cube_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* One pass over the sequence of paths (shared with fuzz_fits_list.c by
 * copy: each target stays one file). */

static void read_ext(const char *path)
{
    seq *s = NULL;
    sl_err e = {0};
    int rc = cube_read_ext(&s, path, "TRUTH", &e);
    if (rc == SL_OK)
        require(s && s->width >= 1 && s->height >= 1 && s->nframes == 1,
                "cube_read_ext", "bad seq");
    else
        check_failure(rc, &e, "cube_read_ext");
    seq_free(s);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    char path[64];
    int fd = mem_file(data, size, path, sizeof path);
    if (fd < 0)
        return 0;
    const char *paths[1] = {path};
    read_all(paths, 1);
    read_ext(path);
    close(fd);
    return 0;
}
