/* vesica — tests of mem.c: large arrays on huge pages behave as malloc,
 * calloc and realloc do (the advice itself is a hint and not observable). */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>

#include "core/mem_impl.h"

/* Below VES_BIG_MIN a plain block; from it on a block aligned to 2 MiB,
 * writable to its last byte. */
static void test_big_alloc(void **state) {
  (void)state;
  unsigned char *s = ves_big_alloc(100), *b = ves_big_alloc(VES_BIG_MIN + 12345);
  assert_non_null(s);
  assert_non_null(b);
  assert_int_equal((uintptr_t)b % VES_HUGE_PAGE, 0);
  memset(b, 0xab, VES_BIG_MIN + 12345);
  assert_int_equal(b[VES_BIG_MIN + 12344], 0xab);
  free(s), free(b);
  void *z = ves_big_alloc(0); /* served as 1 byte, freeable */
  assert_non_null(z);
  free(z);
}

/* Zeroed (the block is written first, freed, and asked again: with glibc's
 * mmap threshold raised by ves_mem_keep_heap, as the ipopt backend does,
 * the heap hands the same memory back, so a missing zeroing would show),
 * and NULL on n size overflow. */
static void test_big_calloc(void **state) {
  (void)state;
  ves_mem_keep_heap();
  const size_t n = VES_BIG_MIN / sizeof(double) + 7;
  double *a = ves_big_alloc(n * sizeof *a);
  assert_non_null(a);
  for (size_t i = 0; i < n; i++) a[i] = 1.0;
  free(a);
  double *c = ves_big_calloc(n, sizeof *c);
  assert_non_null(c);
  /* plain glibc hands the same block back (checked: without the zeroing
   * this test fails); under AddressSanitizer or valgrind, whose allocators
   * quarantine freed blocks, it is fresh memory and the test weaker */
  for (size_t i = 0; i < n; i++)
    if (c[i] != 0.0) fail_msg("entry %zu = %g, not zeroed", i, c[i]);
  free(c);
  assert_null(ves_big_calloc(SIZE_MAX / 2, 4));
}

/* Growth across VES_BIG_MIN keeps the contents: small -> big (copied into an
 * aligned block) -> bigger; NULL as the old block starts a new one. */
static void test_big_realloc(void **state) {
  (void)state;
  const size_t n0 = 1000, n1 = VES_BIG_MIN / sizeof(int) + 1, n2 = 2 * n1;
  int *p = ves_big_realloc(NULL, 0, n0 * sizeof *p);
  assert_non_null(p);
  for (size_t i = 0; i < n0; i++) p[i] = (int)i;
  p = ves_big_realloc(p, n0 * sizeof *p, n1 * sizeof *p);
  assert_non_null(p);
  assert_int_equal((uintptr_t)p % VES_HUGE_PAGE, 0);
  for (size_t i = 0; i < n0; i++) assert_int_equal(p[i], (int)i);
  for (size_t i = n0; i < n1; i++) p[i] = (int)i;
  p = ves_big_realloc(p, n1 * sizeof *p, n2 * sizeof *p);
  assert_non_null(p);
  for (size_t i = 0; i < n1; i++)
    if (p[i] != (int)i) fail_msg("entry %zu = %d after growth", i, p[i]);
  free(p);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_big_alloc),
      cmocka_unit_test(test_big_calloc),
      cmocka_unit_test(test_big_realloc),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
