/* bigmem.c - see bigmem.h.  A buffer of b bytes is the mapping of
 * span(b) = b rounded up to 2 MB, 2 MB aligned: whole huge pages. */
#include "bigmem.h"

#include <stdint.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#define BIG_ALIGN ((uintptr_t)2 << 20)

/* At least one huge page: a 0-byte buffer still maps one. */
static uintptr_t span(size_t bytes)
{
    return ((bytes ? bytes : 1) + BIG_ALIGN - 1) & ~(BIG_ALIGN - 1);
}

void *bigmem_alloc(size_t bytes, int huge)
{
    uintptr_t len = span(bytes) + BIG_ALIGN;
    char *m = mmap(NULL, len, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (m == MAP_FAILED)
        return NULL;
    uintptr_t a = ((uintptr_t)m + BIG_ALIGN - 1) & ~(BIG_ALIGN - 1), end = a + span(bytes);
    if (a > (uintptr_t)m) /* the slack either side goes back */
        munmap(m, a - (uintptr_t)m);
    if ((uintptr_t)m + len > end)
        munmap((void *)end, (uintptr_t)m + len - end);
#if defined(MADV_HUGEPAGE) && defined(MADV_NOHUGEPAGE)
    /* a hint either way; without huge, small pages even where THP is
     * "always", so that touching in page-cut shares faults only the share */
    madvise((void *)a, span(bytes), huge ? MADV_HUGEPAGE : MADV_NOHUGEPAGE);
#else
    (void)huge;
#endif
    return (void *)a;
}

/* Thread tid of n's share of the huge pages: [*b0, *b1) bytes from p. */
static void share(size_t bytes, int tid, int n, uintptr_t *b0, uintptr_t *b1)
{
    uintptr_t pages = span(bytes) / BIG_ALIGN;
    *b0 = pages * (uintptr_t)tid / (uintptr_t)n * BIG_ALIGN;
    *b1 = pages * (uintptr_t)(tid + 1) / (uintptr_t)n * BIG_ALIGN;
}

/* Touching is cut at pages, not huge pages: a buffer under 2 MB (TSM's
 * blocks at 200^2) would otherwise be one thread's whole share.  On a
 * huge-page buffer the first toucher of each 2 MB faults it whole; the
 * zeros are the same. */
void bigmem_touch_share(void *p, size_t bytes, int tid, int n)
{
    if (!p || n < 1 || tid < 0 || tid >= n)
        return;
    long pg = sysconf(_SC_PAGESIZE);
    uintptr_t unit = pg > 0 ? (uintptr_t)pg : 4096, pages = (bytes + unit - 1) / unit;
    uintptr_t b0 = pages * (uintptr_t)tid / (uintptr_t)n * unit;
    uintptr_t b1 = pages * (uintptr_t)(tid + 1) / (uintptr_t)n * unit;
    b1 = b1 < bytes ? b1 : bytes;
    if (b1 > b0)
        memset((char *)p + b0, 0, b1 - b0);
}

void bigmem_release_share(void *p, size_t bytes, int tid, int n)
{
    if (!p || n < 1 || tid < 0 || tid >= n)
        return;
    uintptr_t b0, b1;
    share(bytes, tid, n, &b0, &b1);
    if (b1 > b0)
        madvise((char *)p + b0, b1 - b0, MADV_DONTNEED);
}

void bigmem_free(void *p, size_t bytes)
{
    if (p)
        munmap(p, span(bytes));
}
