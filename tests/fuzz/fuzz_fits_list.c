/* fuzz_fits_list.c - libFuzzer target: the FITS reader of recon/cube.c on
 * a frame LIST of two files (cube_reader_open with npaths = 2).
 *
 * The input is split at the first "\n--8<--\n" (FITS headers hold no
 * newline, so a seed is two files joined by that line); without it the
 * input is cut in half.  Each part goes to its own memfd, /proc/self/fd/N.
 * One input runs cube_reader_open over [a, b], every frame, a rewind and
 * one frame, then the same over [b, a] so that either file can be the one
 * whose metadata and size rule.  The contract checks are fuzz_fits.c's
 * (copied: each target stays one file).
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
    int fd = memfd_create("fuzz_fits_list", MFD_CLOEXEC);
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
        fprintf(stderr, "fuzz_fits_list: contract broken: %s (%s)\n", what,
                msg);
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

/* One pass over the sequence of paths. */
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

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char sep[] = "\n--8<--\n";
    const size_t seplen = sizeof sep - 1;
    size_t cut = size / 2, next = size / 2;
    const uint8_t *at = memmem(data, size, sep, seplen);
    if (at) {
        cut = (size_t)(at - data);
        next = cut + seplen;
    }
    char pa[64], pb[64];
    int fa = mem_file(data, cut, pa, sizeof pa);
    int fb = mem_file(data + next, size - next, pb, sizeof pb);
    if (fa >= 0 && fb >= 0) {
        const char *ab[2] = {pa, pb}, *ba[2] = {pb, pa};
        read_all(ab, 2);
        read_all(ba, 2);
    }
    if (fa >= 0)
        close(fa);
    if (fb >= 0)
        close(fb);
    return 0;
}
