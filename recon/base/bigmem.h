/* bigmem.h - big buffers whose pages many threads hand back at the end.
 *
 * Why: freeing a few hundred MB of touched pages is ~20 ms of kernel
 * work, and one thread doing it at the end of a run (munmap) idled every
 * other core meanwhile.  MADV_DONTNEED frees a range under the mapping's
 * read lock, so the pool's threads can each free a share, and the unmap
 * after finds nothing left to free.
 *
 * bigmem_alloc: zero-filled anonymous pages (never touched here: each is
 * faulted by whoever writes it first), 2 MB aligned; with huge > 0 it
 * asks for transparent huge pages, else for small ones (hints).  NULL
 * when out of memory.
 * bigmem_touch_share: thread tid of n writes zeros over its share of the
 * buffer (cut at page boundaries), so that the pages' first-touch faults
 * are taken on many threads, not later by one (the zero-fill's cost on
 * this VM: 0.5-0.9 GB/s per thread for pages fresh to the process).
 * bigmem_release_share: thread tid of n frees its share of the buffer's
 * pages, cut likewise; the buffer then reads as zeros.
 * bigmem_free: unmaps it (NULL: nothing).  Sizes are the caller's bytes.
 */
#ifndef SL_BIGMEM_H
#define SL_BIGMEM_H

#include <stddef.h>

void *bigmem_alloc(size_t bytes, int huge);
void bigmem_touch_share(void *p, size_t bytes, int tid, int n);
void bigmem_release_share(void *p, size_t bytes, int tid, int n);
void bigmem_free(void *p, size_t bytes);

#endif
