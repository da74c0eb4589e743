/* test_bigmem.c - big buffers: 2 MB aligned, zero-filled, writable to
 * the byte asked for; the shares of any thread count cover the buffer
 * once, and a released buffer reads as zeros; a touched share is resident
 * and nothing else is. */
#include <stdint.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "base/bigmem.h"
#include "tcheck.h"

#define MB ((size_t)1 << 20)

/* Every byte of p[0..n) equal to v. */
static int all_equal(const unsigned char *p, size_t n, unsigned char v)
{
    for (size_t i = 0; i < n; i++)
        if (p[i] != v)
            return 0;
    return 1;
}

TEST(aligned_zeroed_and_writable)
{
    static const size_t sizes[] = {1, 4095, 2 * MB, 2 * MB + 1, 7 * MB + 123};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        size_t n = sizes[k];
        unsigned char *p = bigmem_alloc(n, k % 2);
        CHECK(p, "%zu bytes: no buffer", n);
        if (!p)
            continue;
        CHECK((uintptr_t)p % (2 * MB) == 0, "%zu bytes at %p: not 2 MB aligned", n, (void *)p);
        CHECK(all_equal(p, n, 0), "%zu bytes: not zero-filled", n);
        memset(p, 0xa5, n);
        CHECK(all_equal(p, n, 0xa5), "%zu bytes: not writable to the end", n);
        bigmem_free(p, n);
    }
    bigmem_free(NULL, 10); /* a no-op */
}

/* Each thread count's shares, released one at a time: share t ends at
 * its proportion of the buffer's huge pages, and the bytes beyond keep
 * their pattern, so the shares are in order, do not overlap and end at
 * the buffer's end; at the end it reads as zeros. */
TEST(shares_cover_the_buffer_once)
{
    size_t n = 9 * MB + 4000;
    for (int nt = 1; nt <= 7; nt++) {
        unsigned char *p = bigmem_alloc(n, 1);
        CHECK(p, "no buffer");
        if (!p)
            return;
        memset(p, 0x5a, n);
        size_t done = 0; /* bytes zeroed so far, from the start */
        for (int sh = 0; sh < nt; sh++) {
            bigmem_release_share(p, n, sh, nt);
            while (done < n && p[done] == 0)
                done++;
            size_t huge = (n + 2 * MB - 1) / (2 * MB), end = huge * (sh + 1) / nt * 2 * MB;
            end = end < n ? end : n; /* the share's end: its part of the huge pages */
            CHECK(done == end, "%d threads, share %d ends at %zu, not %zu", nt, sh, done, end);
            CHECK(all_equal(p + done, n - done, 0x5a), "%d threads, share %d: bytes beyond "
                  "%zu released too", nt, sh, done);
        }
        CHECK(done == n && all_equal(p, n, 0), "%d threads: %zu of %zu bytes released", nt,
              done, n);
        bigmem_release_share(p, n, nt, nt); /* out of range: nothing */
        bigmem_free(p, n);
    }
}

/* Pages of p[0..n) resident (mincore): *first, the first one (n pages
 * when none); the count. */
static size_t resident(const void *p, size_t n, size_t *first)
{
    size_t pg = (size_t)sysconf(_SC_PAGESIZE), np = (n + pg - 1) / pg, total = 0;
    unsigned char v[8192];
    *first = np;
    if (np > sizeof v || mincore((void *)p, n, v) != 0)
        return (size_t)-1;
    for (size_t i = np; i-- > 0;)
        if (v[i] & 1)
            total++, *first = i;
    return total;
}

/* Touched one share at a time from the last, the resident pages are
 * exactly those from each share's start to the buffer's last byte: no
 * page before the share, none past the buffer in its mapping; the
 * buffer reads as zeros.  Shares are cut at pages: with 6 threads a
 * 9 MB buffer's shares do not start at 2 MB boundaries, and a 1.5 MB one
 * (under one huge page) is split too. */
TEST(touched_shares_fault_their_pages_only)
{
    size_t pg = (size_t)sysconf(_SC_PAGESIZE);
    for (int k = 0; k < 12; k++) {
        int nt = 1 + k % 6;
        size_t n = k < 6 ? 9 * MB + 4000 : 3 * MB / 2, last = (n + pg - 1) / pg;
        size_t span = k < 6 ? 10 * MB : 2 * MB; /* the mapping */
        unsigned char *p = bigmem_alloc(n, 0);
        CHECK(p, "no buffer");
        if (!p)
            return;
        size_t first;
        CHECK(resident(p, span, &first) == 0, "%d threads: resident before", nt);
        for (int sh = nt - 1; sh >= 0; sh--) {
            bigmem_touch_share(p, n, sh, nt);
            size_t start = last * sh / nt, total = resident(p, span, &first);
            CHECK(total == last - start && first == start, "%d threads, share %d: %zu pages "
                  "resident from page %zu, not %zu from %zu", nt, sh, total, first,
                  last - start, start);
        }
        CHECK(all_equal(p, n, 0), "%d threads: touched buffer not zero", nt);
        bigmem_touch_share(p, n, nt, nt); /* out of range: nothing */
        bigmem_free(p, n);
    }
}

TC_MAIN(TC_CASE(aligned_zeroed_and_writable), TC_CASE(shares_cover_the_buffer_once),
        TC_CASE(touched_shares_fault_their_pages_only))
