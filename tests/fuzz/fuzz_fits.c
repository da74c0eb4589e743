/* fuzz_fits.c - libFuzzer target: the FITS reader of recon/cube.c on one
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

#include "cube.h"

#define FUZZ_MAX_PIX (1 << 20)  /* 4 MB frames at most */
#define FUZZ_MAX_FRAMES 4096    /* bound on a pass, whatever NAXIS3 says */

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* A memfd holding the bytes, path "/proc/self/fd/N"; -1 on failure. */
static int mem_file(const uint8_t *data, size_t size, char *path, size_t n)
{
    int fd = memfd_create("fuzz_fits", MFD_CLOEXEC);
    if (fd < 0)
        return -1;
    for (size_t off = 0; off < size;) {
        ssize_t w = write(fd, data + off, size - off);
        if (w <= 0) {
            close(fd);
            return -1;
        }
        off += (size_t)w;
    }
    snprintf(path, n, "/proc/self/fd/%d", fd);
    return fd;
}

static void require(int cond, const char *what, const char *msg)
{
    if (!cond) {
        fprintf(stderr, "fuzz_fits: contract broken: %s (%s)\n", what, msg);
        abort();
    }
}

static void check_failure(int rc, const sl_err *e, const char *what)
{
    require(rc < 0 && rc >= SL_EEND, what, "status outside SL_E*");
    require(e->code == rc, what, "sl_err code differs from the status");
    require(memchr(e->msg, '\0', sizeof e->msg) && e->msg[0], what,
            "empty or unterminated message");
}

static void check_meta(const cube_meta *m)
{
    const char *s[] = {m->date_obs, m->instrume, m->object, m->bunit};
    for (size_t i = 0; i < sizeof s / sizeof s[0]; i++)
        require(memchr(s[i], '\0', CUBE_STR_MAX) != NULL, "meta string",
                "unterminated");
    require(m->nextra >= 0 && m->nextra <= CUBE_META_MAX_EXTRA, "meta",
            "nextra out of range");
    for (int i = 0; i < m->nextra; i++) {
        const cube_kv *kv = &m->extra[i];
        require(memchr(kv->key, '\0', CUBE_KEY_MAX) && kv->key[0] &&
                    memchr(kv->str, '\0', CUBE_STR_MAX) &&
                    memchr(kv->comment, '\0', CUBE_COMMENT_MAX),
                "meta extra", "bad key/string/comment");
    }
}

/* One pass over the sequence of paths (shared with fuzz_fits_list.c by
 * copy: each target stays one file). */
static void read_all(const char *const *paths, int npaths)
{
    cube_reader *r = NULL;
    sl_err e = {0};
    int rc = cube_reader_open(&r, paths, npaths, 0, &e);
    if (rc != SL_OK) {
        require(r == NULL, "open", "handle left on failure");
        check_failure(rc, &e, "cube_reader_open");
        return;
    }
    int w = cube_reader_width(r), h = cube_reader_height(r);
    int n = cube_reader_nframes(r);
    require(w >= 1 && h >= 1 && n >= 1, "open", "size < 1");
    check_meta(cube_reader_meta(r));
    if ((size_t)w * (size_t)h > FUZZ_MAX_PIX)
        goto free_reader;
    float *frame = malloc((size_t)w * (size_t)h * sizeof *frame);
    if (!frame)
        goto free_reader;
    int got = 0, k;
    for (k = 0; k < n && k < FUZZ_MAX_FRAMES; k++) {
        rc = cube_reader_next(r, frame);
        if (rc == SL_OK || rc == SL_EDATA) {
            got++;
            continue;
        }
        sl_err copy = {rc, ""};
        snprintf(copy.msg, sizeof copy.msg, "%s", cube_reader_errmsg(r));
        check_failure(rc, &copy, "cube_reader_next");
        require(rc != SL_EEND, "next", "SL_EEND before nframes");
        break;
    }
    if (got == n) {
        rc = cube_reader_next(r, frame);
        require(rc == SL_EEND, "next", "no SL_EEND after nframes frames");
    }
    cube_reader_rewind(r);
    rc = cube_reader_next(r, frame);
    require(rc != SL_EEND, "rewind", "SL_EEND at frame 0");
    free(frame);
free_reader:
    cube_reader_free(r);
}

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
