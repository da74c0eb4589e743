/* bigmem.c - see bigmem.h.  A buffer of b bytes is the mapping of
 * span(b) = b rounded up to 2 MB, 2 MB aligned: whole huge pages. */
#include "bigmem.h"

#include <stdint.h>
#include <sys/mman.h>

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
#ifdef MADV_HUGEPAGE
    if (huge)
        madvise((void *)a, span(bytes), MADV_HUGEPAGE); /* a hint */
#else
    (void)huge;
#endif
    return (void *)a;
}

void bigmem_release_share(void *p, size_t bytes, int tid, int n)
{
    if (!p || n < 1 || tid < 0 || tid >= n)
        return;
    uintptr_t a = (uintptr_t)p, pages = span(bytes) / BIG_ALIGN; /* huge pages */
    uintptr_t p0 = pages * (uintptr_t)tid / (uintptr_t)n, p1 = pages * (uintptr_t)(tid + 1) / (uintptr_t)n;
    if (p1 > p0)
        madvise((void *)(a + p0 * BIG_ALIGN), (p1 - p0) * BIG_ALIGN, MADV_DONTNEED);
}

void bigmem_free(void *p, size_t bytes)
{
    if (p)
        munmap(p, span(bytes));
}
