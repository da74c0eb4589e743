/* fuzz_fits_list.c - libFuzzer target: the FITS reader of recon/io/cube.c on
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

#include "io/cube.h"
#define FUZZ_NAME "fuzz_fits_list"
#include "fuzz_util.h"
#include "fuzz_cube_util.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

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
