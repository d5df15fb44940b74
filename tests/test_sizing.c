/* vesica — tests of the node sizing field: h_band in the band, the linear
 * growth away from it, h_far far away, a refused parameter. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>

#include "ves/shape.h"
#include "ves/sizing.h"

static void test_sizing(void **state) {
  (void)state;
  ves_shape_params p;
  ves_shape_params_default(&p);
  ves_shape *s = NULL;
  assert_int_equal(ves_shape_create(&p, &s), VES_OK);
  ves_sizing_params zp = {.eps = 0.04, .h_band = 0.02, .band = 4, .slope = 0.15, .h_far = 0.2};
  ves_sizing *z = NULL;
  assert_int_equal(ves_sizing_create(s, &zp, 2.0, 2.0, &z), VES_OK);
  double X1[2] = {0.3, 0.95}; /* |d| < 0.16: in the band */
  double d1 = fabs(1 - hypot(X1[0], X1[1]));
  assert_true(d1 < 0.16);
  assert_true(fabs(ves_sizing_eval(X1, z) - 0.02) < 1e-15);
  double X2[2] = {1.5, 0.5}; /* |d| = 0.581: 0.02 + 0.15 * 0.421 */
  double d2 = hypot(1.5, 0.5) - 1;
  /* bilinear |d| on a 0.04 grid: error <= g^2 kappa / 8 = 2e-4 -> 3e-5 in h */
  assert_true(fabs(ves_sizing_eval(X2, z) - (0.02 + 0.15 * (d2 - 0.16))) < 1e-4);
  double X3[2] = {2.0, 2.0};
  assert_true(fabs(ves_sizing_eval(X3, z) - 0.2) < 1e-15);
  ves_sizing_destroy(&z);
  assert_null(z);
  zp.slope = 0;
  assert_int_equal(ves_sizing_create(s, &zp, 2.0, 2.0, &z), VES_ERR_ARG);
  ves_shape_destroy(&s);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_sizing)};
  return cmocka_run_group_tests_name("sizing", tests, NULL, NULL);
}
