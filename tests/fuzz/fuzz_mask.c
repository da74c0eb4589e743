/* fuzz_mask.c - libFuzzer target: the mask file parser (mask_read) and,
 * when a file parses, the geometry behind it (mask_render, mask_write).
 *
 * The input is the file's text, put in a memfd read as /proc/self/fd/N.
 * A mask that parses is then
 *   - rendered into a 32x32 grid with a pitch that makes the whole layout
 *     fit (so huge, tiny and far-off-centre holes reach render_disk), and
 *     with a fixed 0.05 m pitch (the "does not fit" path);
 *   - written with mask_write and read back: the header promises
 *     bit-identical centres.
 * Inputs that could make a mask of 65..MASK_MAX_HOLES holes are skipped
 * (see the cost note at LLVMFuzzerTestOneInput).
 * Contract checks abort (a finding): failures carry a negative code and a
 * message; a parsed mask has 2..MASK_MAX_HOLES finite centres and a
 * positive hole diameter; rendered pixels lie in [0, 1]; the round trip
 * is exact.
 */
#define _GNU_SOURCE
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "sim/mask.h"
#define FUZZ_NAME "fuzz_mask"
#include "fuzz_util.h"

#define GRID 32

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void render(const mask *m, double dx_m, int must_fit, float *pupil)
{
    sl_err e = {0};
    int rc = mask_render(m, pupil, GRID, dx_m, &e);
    require(rc == SL_OK || !must_fit, "mask_render with a pitch that fits",
            e.msg);
    if (rc != SL_OK) {
        check_failure(rc, &e, "mask_render");
        return;
    }
    for (int i = 0; i < GRID * GRID; i++)
        require(pupil[i] >= 0.0f && pupil[i] <= 1.0f, "mask_render",
                "pixel outside [0, 1]");
}

/* mask_write then mask_read: the same centres, bit for bit. */
static void round_trip(const mask *m)
{
    char path[64];
    int fd = mem_file(NULL, 0, path, sizeof path);
    if (fd < 0)
        return;
    mask *back = NULL;
    sl_err e = {0};
    int rc = mask_write(m, path, &e);
    if (rc == SL_OK)
        rc = mask_read(&back, path, &e);
    require(rc == SL_OK, "round trip", e.msg);
    require(mask_nholes(back) == mask_nholes(m) &&
                mask_hole_diameter_m(back) == mask_hole_diameter_m(m),
            "round trip", "hole count or diameter changed");
    for (int i = 0; i < mask_nholes(m); i++) {
        double x0, y0, x1, y1;
        mask_hole(m, i, &x0, &y0);
        mask_hole(back, i, &x1, &y1);
        require(x0 == x1 && y0 == y1, "round trip", "centre changed");
    }
    mask_free(back);
    close(fd);
}

/* Lines mask_read would not skip: text before '#', CR, LF or NUL that is
 * not all blanks. */
static int content_lines(const uint8_t *data, size_t size)
{
    int lines = 0, content = 0, cut = 0;
    for (size_t i = 0; i <= size; i++) {
        int c = i < size ? data[i] : '\n';
        if (c == '\n') {
            lines += content;
            content = cut = 0;
        } else if (c == '#' || c == '\r' || c == '\0') {
            cut = 1;
        } else if (!cut && !strchr(" \t\v\f", c)) {
            content = 1;
        }
    }
    return lines;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    /* Building a mask costs O(nholes^4) (the redundancy count, by design:
     * ~1 s optimised at MASK_MAX_HOLES, 10 s and more instrumented, with
     * nothing new to cover past 64 holes).  So an input that could hold
     * 65..MASK_MAX_HOLES holes is skipped; more lines still run: they fail
     * cheaply at hole MASK_MAX_HOLES + 1 (SL_ERANGE). */
    int lines = content_lines(data, size);
    if (lines > 65 && lines <= MASK_MAX_HOLES + 1)
        return 0;
    char path[64];
    int fd = mem_file(data, size, path, sizeof path);
    if (fd < 0)
        return 0;
    mask *m = NULL;
    sl_err e = {0};
    int rc = mask_read(&m, path, &e);
    close(fd);
    if (rc != SL_OK) {
        require(m == NULL, "mask_read", "mask left on failure");
        check_failure(rc, &e, "mask_read");
        return 0;
    }
    int n = mask_nholes(m);
    double d = mask_hole_diameter_m(m), reach = 0;
    require(n >= 2 && n <= MASK_MAX_HOLES && isfinite(d) && d > 0,
            "mask_read", "invariants of a hole mask");
    for (int i = 0; i < n; i++) {
        double x, y;
        mask_hole(m, i, &x, &y);
        require(isfinite(x) && isfinite(y), "mask_read", "centre not finite");
        reach = fmax(reach, fmax(fabs(x), fabs(y)));
    }
    if (n <= 64) { /* a bigger one would be a skipped input */
        float *pupil = malloc(GRID * GRID * sizeof *pupil);
        if (pupil) {
            /* Every hole edge within GRID/2 - 1 pixels of the centre; far
             * from denormals, where pixel offsets lose their precision. */
            double fit = (reach + d) / (GRID / 2 - 1);
            if (isfinite(fit) && fit > 0)
                render(m, fit, fit > 1e-290, pupil);
            render(m, 0.05, 0, pupil);
            free(pupil);
        }
        round_trip(m);
    }
    mask_free(m);
    return 0;
}
