/* vesica — private: large arrays on transparent huge pages (mem.c;
 * docs/design.md, "Numerical choices and why"). */
#ifndef VES_MEM_IMPL_H
#define VES_MEM_IMPL_H

#include <stddef.h>

/* Arrays of at least this many bytes are placed on huge pages (mem.c). */
#define VES_BIG_MIN ((size_t)4 << 20)

/* x86-64's transparent huge page: the alignment of those arrays. */
#define VES_HUGE_PAGE ((size_t)2 << 20)

/* malloc(bytes) for a large array: from VES_BIG_MIN bytes on, aligned to a
 * 2 MiB huge page and advised to the kernel as huge-page memory
 * (madvise MADV_HUGEPAGE); smaller requests are plain malloc. Freed with
 * free(). NULL when out of memory. bytes 0 is served as 1. */
void *ves_big_alloc(size_t bytes);

/* calloc(n, size) as ves_big_alloc: zeroed; NULL on overflow or out of
 * memory. */
void *ves_big_calloc(size_t n, size_t size);

/* realloc for a growing large array: a new ves_big_alloc(new_bytes) block
 * with the first old_bytes of old copied, old freed; on failure NULL and
 * old untouched. */
void *ves_big_realloc(void *old, size_t old_bytes, size_t new_bytes);

/* Keep large freed blocks in the heap: glibc's mmap and trim thresholds
 * raised to VES_HEAP_KEEP (process-wide; mem.c). */
void ves_mem_keep_heap(void);

#endif
