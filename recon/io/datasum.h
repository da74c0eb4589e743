/* datasum.h - private to recon/io: the FITS DATASUM of a data unit kept
 * up to date as frames are appended, so that a growing cube's CHECKSUM can
 * be refreshed at every flush without reading the file back.
 *
 * DATASUM is the 32-bit ones' complement sum of the data unit's bytes
 * taken as big-endian words (FITS standard 4.0, Appendix J); the zero fill
 * after the data adds nothing.  The sum is kept as two 16-bit halves with
 * their carries folded in at the end, as cfitsio's ffcsum does; the order
 * of the words does not change a ones' complement sum, so appending a
 * frame only adds that frame's words, with the bytes that did not fill a
 * word carried over to the next frame.
 */
#ifndef SL_DATASUM_H
#define SL_DATASUM_H

#include <stddef.h>
#include <stdint.h>

typedef struct datasum {
    uint64_t hi, lo;        /* sums of the words' high and low halves */
    unsigned char pend[4];  /* bytes of a word not yet complete */
    int npend;
} datasum;

void datasum_init(datasum *s);
/* Add n bytes as they follow in the data unit. */
void datasum_add_bytes(datasum *s, const unsigned char *b, size_t n);
/* Add n pixels as cfitsio stores them for bitpix (the cube.h values,
 * including CUBE_BITPIX_U16/U32); integer types must already hold integer
 * values within range.  scratch holds n * datasum_pixel_bytes(bitpix). */
void datasum_add_pixels(datasum *s, const float *px, size_t n, int bitpix,
                        unsigned char *scratch);
/* Bytes per stored pixel for bitpix. */
size_t datasum_pixel_bytes(int bitpix);
/* The sum of everything added so far, zero fill included. */
uint32_t datasum_value(const datasum *s);

#endif
