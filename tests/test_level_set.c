/* vesica — tests of the sharp interface of a nodal field: exact on a
 * plane, the signed volume through a fold, second order on a sphere, the
 * argument checks. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "ves/level_set.h"

/* A structured grid on [0, L] x [-H, H], nr x nz nodes, two CCW triangles
 * a cell; x[2 nr nz], tri[6 (nr-1)(nz-1)] allocated here. */
static void grid(int nr, int nz, double L, double H, double **x, int **tri) {
  *x = malloc(2 * (size_t)nr * nz * sizeof **x);
  *tri = malloc(6 * (size_t)(nr - 1) * (nz - 1) * sizeof **tri);
  assert_true(*x && *tri);
  for (int j = 0; j < nz; j++)
    for (int i = 0; i < nr; i++)
      (*x)[2 * (j * nr + i)] = L * i / (nr - 1),
                         (*x)[2 * (j * nr + i) + 1] = -H + 2 * H * j / (nz - 1);
  int t = 0;
  for (int j = 0; j + 1 < nz; j++)
    for (int i = 0; i + 1 < nr; i++) {
      const int a = j * nr + i, b = a + 1, c = a + nr + 1, d = a + nr;
      int *T = *tri + 6 * t++;
      T[0] = a, T[1] = b, T[2] = c, T[3] = a, T[4] = c, T[5] = d;
    }
}

/* ves_level_set_eval: exact where the piecewise-linear interpolant is the
 * field (phi linear in z: the region below a plane of a cylinder, its disc),
 * the signed volume kept through a fold (the image's degree), second-order
 * on a sphere, and its argument checks. */
static void test_level_set(void **state) {
  (void)state;
  const int nr = 9, nz = 13, n = nr * nz, ntri = 2 * (nr - 1) * (nz - 1);
  const double L = 1.5, H = 2.0, z0 = 0.37;
  double *x, *phi = malloc((size_t)n * sizeof *phi);
  int *tri;
  grid(nr, nz, L, H, &x, &tri);
  assert_non_null(phi);
  ves_level_set ls;
  /* phi = z0 - z: the cylinder below z = z0 and its cross-section, exact up
   * to rounding (1e-13: sums of ~200 terms of size 1) */
  for (int a = 0; a < n; a++) phi[a] = z0 - x[2 * a + 1];
  assert_int_equal(ves_level_set_eval(n, ntri, tri, x, phi, &ls), VES_OK);
  const double vex = M_PI * L * L * (z0 + H), aex = M_PI * L * L;
  printf("# plane: volume %.15f (exact %.15f), area %.15f (exact %.15f), inverted %d\n", ls.volume,
         vex, ls.area, aex, ls.inverted);
  assert_true(fabs(ls.volume - vex) <= 1e-13 * vex && fabs(ls.area - aex) <= 1e-13 * aex);
  assert_int_equal(ls.inverted, 0);
  /* all inside: the box's volume and no interface; all outside: nothing */
  for (int a = 0; a < n; a++) phi[a] = 1;
  assert_int_equal(ves_level_set_eval(n, ntri, tri, x, phi, &ls), VES_OK);
  const double box = M_PI * L * L * 2 * H;
  assert_true(fabs(ls.volume - box) <= 1e-13 * box && ls.area == 0);
  /* a fold: an interior node pushed across its neighbours flips triangles,
   * and the signed volume of the image is still the box's (the boundary is
   * unchanged: the degree of the map is 1) */
  const int m = 4 * nr + 4; /* an interior node */
  x[2 * m] += 2.5 * L / (nr - 1), x[2 * m + 1] += 1.5 * 2 * H / (nz - 1);
  assert_int_equal(ves_level_set_eval(n, ntri, tri, x, phi, &ls), VES_OK);
  printf("# fold: %d triangles inverted, signed volume %.15f (box %.15f)\n", ls.inverted, ls.volume,
         box);
  assert_true(ls.inverted >= 1);
  assert_true(fabs(ls.volume - box) <= 1e-13 * box);
  for (int a = 0; a < n; a++) phi[a] = -1;
  assert_int_equal(ves_level_set_eval(n, ntri, tri, x, phi, &ls), VES_OK);
  assert_true(ls.volume == 0 && ls.area == 0);
  /* errors */
  assert_int_equal(ves_level_set_eval(n, 0, tri, x, phi, &ls), VES_ERR_ARG);
  assert_int_equal(ves_level_set_eval(n, ntri, NULL, x, phi, &ls), VES_ERR_ARG);
  assert_int_equal(ves_level_set_eval(n - 1, ntri, tri, x, phi, &ls), VES_ERR_ARG); /* index n-1 */
  phi[0] = NAN;
  assert_int_equal(ves_level_set_eval(n, ntri, tri, x, phi, &ls), VES_ERR_ARG);
  free(x), free(tri), free(phi);
  /* the unit sphere, phi = 1 - rho: the inscribed polygon's volume and area
   * err by O(h^2) (h = 0.02: 1e-4 expected; asserted 1e-3), and halving h
   * divides the volume error by ~4 (asserted > 3) */
  double err_prev = 0;
  for (int c = 0; c < 2; c++) {
    const int k = c ? 151 : 76;
    grid(k, 2 * k - 1, 1.5, 1.5, &x, &tri);
    const int n2 = k * (2 * k - 1), nt2 = 2 * (k - 1) * (2 * k - 2);
    double *ph = malloc((size_t)n2 * sizeof *ph);
    assert_non_null(ph);
    for (int a = 0; a < n2; a++) ph[a] = 1 - hypot(x[2 * a], x[2 * a + 1]);
    assert_int_equal(ves_level_set_eval(n2, nt2, tri, x, ph, &ls), VES_OK);
    const double ev = ls.volume / (4 * M_PI / 3) - 1, ea = ls.area / (4 * M_PI) - 1;
    printf("# sphere, h = %.4f: volume error %.2e, area error %.2e\n", 1.5 / (k - 1), ev, ea);
    assert_true(fabs(ev) <= 1e-3 && fabs(ea) <= 1e-3);
    if (c) assert_true(fabs(err_prev / ev) > 3);
    err_prev = ev;
    free(x), free(tri), free(ph);
  }
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_level_set)};
  return cmocka_run_group_tests_name("level_set", tests, NULL, NULL);
}
