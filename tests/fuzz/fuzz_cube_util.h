/* fuzz_cube_util.h - the cube reader's contract checks, shared by
 * fuzz_fits.c and fuzz_fits_list.c (include after fuzz_util.h). */
#ifndef SL_FUZZ_CUBE_UTIL_H
#define SL_FUZZ_CUBE_UTIL_H

#include "io/cube.h"
#include "fuzz_util.h"

/* The harness owns the frame buffer: bounds of one pass, not the reader's. */
#define FUZZ_MAX_PIX (1 << 20)  /* 4 MB frames at most */
#define FUZZ_MAX_FRAMES 4096    /* bound on a pass, whatever NAXIS3 says */

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

#endif
