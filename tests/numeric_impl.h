/* vesica — small numerical helpers of the linear-algebra tests (test_ldl.c,
 * test_project.c): the unit roundoff, deterministic random numbers, the
 * 2-norm. */
#ifndef VES_TEST_NUMERIC_IMPL_H
#define VES_TEST_NUMERIC_IMPL_H

#include <math.h>
#include <stdint.h>

#define U 0x1.0p-52 /* double unit roundoff (2u, machine epsilon) */

/* Deterministic uniform numbers in [0, 1) (xorshift64*). */
static inline double urand(uint64_t *s) {
  *s ^= *s >> 12;
  *s ^= *s << 25;
  *s ^= *s >> 27;
  return (double)((*s * 2685821657736338717ULL) >> 11) * 0x1.0p-53;
}

/* |x|_2 of x[n]. */
static inline double norm2(int n, const double *x) {
  double s = 0.0;
  for (int i = 0; i < n; i++) s += x[i] * x[i];
  return sqrt(s);
}

#endif
