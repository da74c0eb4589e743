/* datasum.c - the running DATASUM of a data unit; see datasum.h. */
#include "datasum.h"

#include <string.h>

#include "cube.h"

void datasum_init(datasum *s)
{
    memset(s, 0, sizeof *s);
}

static void add_word(datasum *s, const unsigned char *w)
{
    s->hi += (uint64_t)((unsigned)w[0] << 8 | w[1]);
    s->lo += (uint64_t)((unsigned)w[2] << 8 | w[3]);
}

void datasum_add_bytes(datasum *s, const unsigned char *b, size_t n)
{
    size_t i = 0;
    while (s->npend > 0 && i < n) {
        s->pend[s->npend++] = b[i++];
        if (s->npend == 4) {
            add_word(s, s->pend);
            s->npend = 0;
        }
    }
    for (; i + 4 <= n; i += 4)
        add_word(s, b + i);
    while (i < n)
        s->pend[s->npend++] = b[i++];
}

size_t datasum_pixel_bytes(int bitpix)
{
    switch (bitpix) {
    case 8: return 1;
    case 16: case CUBE_BITPIX_U16: return 2;
    case -64: return 8;
    default: return 4; /* 32, -32, CUBE_BITPIX_U32 */
    }
}

static void put_be(unsigned char *p, uint64_t v, int nbytes)
{
    for (int k = nbytes - 1; k >= 0; k--, v >>= 8)
        p[k] = (unsigned char)(v & 0xFF);
}

/* The stored bits of one pixel: two's complement for the signed types,
 * value - BZERO for the unsigned conventions (the top bit flipped), the
 * IEEE bits for the float types.  Through int32/int64 so that a value the
 * writer's range check let through as a float rounded up (2^31 for
 * BITPIX 32) converts without undefined behaviour; cfitsio refuses to
 * write such a frame, and a frame not written is never summed. */
static uint64_t stored_bits(float v, int bitpix)
{
    uint32_t f32;
    uint64_t f64;
    double d = v;
    switch (bitpix) {
    case 8: return (uint8_t)(int32_t)v;
    case 16: return (uint16_t)(int32_t)v;
    case CUBE_BITPIX_U16: return (uint16_t)((uint32_t)(int32_t)v ^ 0x8000u);
    case 32: return (uint32_t)(int64_t)v;
    case CUBE_BITPIX_U32: return (uint32_t)((uint32_t)(int64_t)v ^ 0x80000000u);
    case -64: memcpy(&f64, &d, sizeof f64); return f64;
    default: memcpy(&f32, &v, sizeof f32); return f32;
    }
}

/* Word-aligned sums straight from the pixels, no bytes written: 16-bit
 * pixels pair into words, 32-bit ones are words, 64-bit ones two words,
 * 8-bit ones four to a word.  Returns the pixels summed; the caller sends
 * the rest (an odd tail) through the bytes. */
static size_t add_aligned(datasum *s, const float *px, size_t n, int bitpix)
{
    size_t i = 0;
    uint64_t hi = s->hi, lo = s->lo;
    switch (bitpix) {
    case 8:
        for (; i + 4 <= n; i += 4) {
            hi += (uint64_t)(stored_bits(px[i], 8) << 8 | stored_bits(px[i + 1], 8));
            lo += (uint64_t)(stored_bits(px[i + 2], 8) << 8 | stored_bits(px[i + 3], 8));
        }
        break;
    case 16:
        for (; i + 2 <= n; i += 2) {
            hi += stored_bits(px[i], 16);
            lo += stored_bits(px[i + 1], 16);
        }
        break;
    case CUBE_BITPIX_U16:
        for (; i + 2 <= n; i += 2) {
            hi += stored_bits(px[i], CUBE_BITPIX_U16);
            lo += stored_bits(px[i + 1], CUBE_BITPIX_U16);
        }
        break;
    case -64:
        for (; i < n; i++) {
            uint64_t u = stored_bits(px[i], -64);
            hi += (u >> 48) + ((u >> 16) & 0xFFFF);
            lo += ((u >> 32) & 0xFFFF) + (u & 0xFFFF);
        }
        break;
    case -32:
        for (; i < n; i++) {
            uint64_t u = stored_bits(px[i], -32);
            hi += u >> 16;
            lo += u & 0xFFFF;
        }
        break;
    default: /* 32, CUBE_BITPIX_U32 */
        for (; i < n; i++) {
            uint64_t u = stored_bits(px[i], bitpix);
            hi += u >> 16;
            lo += u & 0xFFFF;
        }
    }
    s->hi = hi, s->lo = lo;
    return i;
}

void datasum_add_pixels(datasum *s, const float *px, size_t n, int bitpix,
                        unsigned char *scratch)
{
    int nb = (int)datasum_pixel_bytes(bitpix);
    size_t done = s->npend == 0 ? add_aligned(s, px, n, bitpix) : 0;
    for (size_t i = done; i < n; i++)
        put_be(scratch + (i - done) * (size_t)nb, stored_bits(px[i], bitpix), nb);
    datasum_add_bytes(s, scratch, (n - done) * (size_t)nb);
}

uint32_t datasum_value(const datasum *s)
{
    uint64_t hi = s->hi, lo = s->lo;
    if (s->npend > 0) { /* the zero fill completes the last word */
        unsigned char w[4] = {0, 0, 0, 0};
        memcpy(w, s->pend, (size_t)s->npend);
        hi += (uint64_t)((unsigned)w[0] << 8 | w[1]);
        lo += (uint64_t)((unsigned)w[2] << 8 | w[3]);
    }
    uint64_t hicarry = hi >> 16, locarry = lo >> 16;
    while (hicarry || locarry) {
        hi = (hi & 0xFFFF) + locarry;
        lo = (lo & 0xFFFF) + hicarry;
        hicarry = hi >> 16;
        locarry = lo >> 16;
    }
    return (uint32_t)(hi << 16 | lo);
}
