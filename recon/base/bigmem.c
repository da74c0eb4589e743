/* bigmem.c - see bigmem.h.  A buffer of b bytes is the mapping of
 * span(b) = b rounded up to 2 MB, 2 MB aligned: whole huge pages. */
#include "bigmem.h"

#include <stdint.h>
#include <sys/mman.h>

#define BIG_ALIGN ((uintptr_t)2 << 20)

static uintptr_t span(size_t bytes) { return (bytes + BIG_ALIGN - 1) & ~(BIG_ALIGN - 1); }

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
    uintptr_t a = (uintptr_t)p, len = span(bytes), cut[2];
    for (int e = 0; e < 2; e++) /* share boundaries, rounded to 2 MB */
        cut[e] = a + span((size_t)(len / BIG_ALIGN * (uintptr_t)(tid + e) / (uintptr_t)n) *
                          BIG_ALIGN);
    if (cut[1] > cut[0])
        madvise((void *)cut[0], cut[1] - cut[0], MADV_DONTNEED);
}

void bigmem_free(void *p, size_t bytes)
{
    if (p)
        munmap(p, span(bytes));
}
