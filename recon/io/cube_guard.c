/* cube_guard.c - FITS files cfitsio must not parse; see cube_guard.h.
 *
 * cfitsio 4.2 (Debian 12) crashes on corrupt tile-compressed images:
 * SIGFPE merely moving to an HDU with ZTILEn = 0, SIGFPE / SIGSEGV reading
 * Rice tiles with BLOCKSIZE 0 / 7 (all found by tests/fuzz/fuzz_fits), and
 * its HCOMPRESS decoder has a published heap overflow.  A file from another
 * instrument must not kill the process, so a file with a tile-compressed
 * HDU (ZIMAGE = T) is refused before cfitsio parses it: funpack it first.
 *
 * The walk reads header blocks only and seeks over each data unit, sized
 * as cfitsio sizes it (cost: one 2880-byte read per header block and one
 * seek per HDU); it stops at what is no plain FITS header, and at a size
 * cfitsio rejects, leaving the verdict to cfitsio.  Names are taken as
 * cfitsio takes them (up to a blank or '='), so "ZIMAGE = T" counts.
 */
#include "cube_guard.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>

int cube_guard_check(const char *path, sl_err *err)
{
    char b[2881] = {0}; /* NUL after the block: the scans stop there */
    double bitpix = 0, naxis = 0, n = 1, pcount = 0, gcount = 1, groups = 0;
    int end = 1, zimage = 0, z1 = 0; /* z1: NAXIS1 = 0 (random groups?) */
    int bad = 0, hdu = 0;   /* bad: a card that is not FITS text */
    long long at = 0;       /* its first bad byte, from the file's start */
    FILE *f = fopen(path, "rb");
    while (f && !zimage && !bad && fread(b, 1, 2880, f) == 2880) {
        if (end && strncmp(b, "SIMPLE  ", 8) && strncmp(b, "XTENSION", 8))
            break;
        hdu += end;
        end = 0;
        for (const char *k = b; k < b + 2880 && !end && !bad; k += 80) {
            /* FITS 4.0 s4.1.2: cards are ASCII 0x20-0x7e, and a value
             * follows "= " in bytes 9-10.  cfitsio 4.2 copies a 71-byte
             * value after a bare "=" into a 70-byte column name (fortify
             * abort, tests/fuzz/fuzz_fits_list). */
            int i = 0;
            while (i < 80 && (unsigned char)k[i] >= 0x20 && (unsigned char)k[i] <= 0x7e)
                i++;
            if (i == 80 && k[8] == '=' && k[9] != ' ')
                i = 9;
            if (i < 80) {
                bad = 1;
                at = (long long)ftello(f) - 2880 + (k - b) + i;
                break;
            }
            /* the name as cfitsio takes it: up to a blank or '=' */
            size_t kl = strcspn(k, " =");
            const char *e = k + kl + strspn(k + kl, " ");
            char nm[9] = "";
            double v = 0;
            int t = 0;
            if (kl <= 8 && *e == '=') { /* then e + 1 is inside b */
                memcpy(nm, k, kl);
                v = strtod(e + 1, NULL);
                t = e[1 + strspn(e + 1, " ")] == 'T';
            }
            zimage |= !strcmp(nm, "ZIMAGE") && t;
            groups = !strcmp(nm, "GROUPS") ? t : groups;
            bitpix = !strcmp(nm, "BITPIX") ? v : bitpix;
            naxis = !strcmp(nm, "NAXIS") ? v : naxis;
            pcount = !strcmp(nm, "PCOUNT") ? v : pcount;
            gcount = !strcmp(nm, "GCOUNT") ? v : gcount;
            int ax = !strncmp(nm, "NAXIS", 5) && nm[5] >= '1' && nm[5] <= '9';
            z1 |= ax && v == 0 && !strcmp(nm, "NAXIS1");
            n *= ax && !(v == 0 && !strcmp(nm, "NAXIS1")) ? v : 1;
            end = !strncmp(k, "END     ", 8);
        }
        if (!end || zimage || bad)
            continue; /* next block of this header, or the verdict */
        double data = naxis > 0 && (!z1 || groups) ? n : 0;
        double bytes = fabs((data + pcount) * gcount * bitpix) / 8;
        if (!(bytes < 1e15) ||
            fseeko(f, (off_t)ceil(bytes / 2880) * 2880, SEEK_CUR))
            break;
        bitpix = naxis = pcount = groups = z1 = 0, n = gcount = 1;
    }
    if (f)
        fclose(f);
    if (bad)
        return sl_seterr(err, SL_EFORMAT, "%s: header of HDU %d is not FITS text (byte "
                         "%lld: a character outside ASCII 32-126, or a value not "
                         "after \"= \"); cfitsio 4.2 may crash on it", path, hdu, at);
    if (zimage)
        return sl_seterr(err, SL_EFORMAT, "%s: tile-compressed FITS is not "
                         "read (cfitsio 4.2 crashes on corrupt tiles); "
                         "funpack it first", path);
    return SL_OK;
}
