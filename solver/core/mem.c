/* vesica — large arrays on transparent huge pages.
 *
 * The LME tables (~1.4 GB at eps 0.01), the Hessian's block array and
 * MUMPS's factor workspace are aligned to 2 MiB and advised MADV_HUGEPAGE:
 * 512 times fewer page faults and TLB entries than on 4 KiB pages, -13% CPU
 * time (setup -20%) on the eps 0.01 oblate relaxation with the same iterates
 * (docs/results.md, "Performance and its scaling"; docs/design.md, "Numerical
 * choices and why"). The advice is a hint: without huge pages the memory is
 * plain, and nothing computed depends on it. Arrays below VES_BIG_MIN, and
 * what MUMPS, CHOLMOD and Ipopt allocate themselves, stay on plain malloc. */
#define _DEFAULT_SOURCE /* MADV_HUGEPAGE (Linux) beside the build's _XOPEN_SOURCE */
#include <malloc.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "core/mem_impl.h"

#define VES_HEAP_KEEP (1 << 30) /* ves_mem_keep_heap: 1 GiB */

void *ves_big_alloc(size_t bytes) {
  if (bytes < VES_BIG_MIN) return malloc(bytes ? bytes : 1);
  void *p = NULL;
  if (posix_memalign(&p, VES_HUGE_PAGE, bytes) != 0) return NULL;
#ifdef MADV_HUGEPAGE
  (void)madvise(p, bytes, MADV_HUGEPAGE); /* a hint: refused, the pages stay small */
#endif
  return p;
}

void *ves_big_calloc(size_t n, size_t size) {
  if (size && n > SIZE_MAX / size) return NULL;
  const size_t bytes = n * size;
  void *p = ves_big_alloc(bytes);
  if (p && bytes > 0) memset(p, 0, bytes);
  return p;
}

void *ves_big_realloc(void *old, size_t old_bytes, size_t new_bytes) {
  if (new_bytes < VES_BIG_MIN) return realloc(old, new_bytes ? new_bytes : 1);
  void *p = ves_big_alloc(new_bytes);
  if (!p) return NULL;
  if (old) memcpy(p, old, old_bytes < new_bytes ? old_bytes : new_bytes), free(old);
  return p;
}

/* Ipopt 3.11 hands MUMPS no workspace (WK_USER), so MUMPS allocates its
 * factor workspace anew at every Ipopt iteration. glibc serves a block above
 * its mmap threshold (dynamic, at most 32 MiB) with fresh pages and unmaps it
 * on free, so with the default thresholds every factorization faults its
 * workspace in and zero-fills it again: 1.5 million page faults and ~20% of
 * Ipopt's CPU over the default relaxation (docs/results.md, "Performance and
 * its scaling"). Raising the mmap and trim thresholds to VES_HEAP_KEEP makes
 * such blocks come from the heap and stay there for the next factorization.
 * Process-wide and lasting: it changes where glibc places large blocks (and
 * keeps up to VES_HEAP_KEEP bytes of freed memory resident), never a
 * result; a refused setting costs only the faults. newton's own MUMPS
 * (ldl.c, with WK_USER) gains nothing from it (eps 0.02, a dt* 100 step of
 * 23 factorizations: 77.2 / 76.0 CPU s), so only the ipopt backend calls
 * it. */
void ves_mem_keep_heap(void) {
  (void)mallopt(M_MMAP_THRESHOLD, VES_HEAP_KEEP);
  (void)mallopt(M_TRIM_THRESHOLD, VES_HEAP_KEEP);
}
