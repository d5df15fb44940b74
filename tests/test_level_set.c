/* vesica — tests of the sharp interface of a nodal field: exact on a
 * plane, the signed volume through a fold, second order on a sphere, the
 * argument checks; its zero set as ordered curves whose segments give the
 * same volume and area (sphere, oblate, two pieces, a closed loop, phi = 0
 * at nodes and along edges, pieces ending on the box). */
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

/* V and A of the pieces of c by the segment sums of level_set.h (each piece
 * has the region it encloses on its right). */
static void curve_measures(const ves_level_set_curves *c, double *V, double *A) {
  double v = 0, a = 0;
  for (int i = 0; i < c->npieces; i++)
    for (int j = c->start[i]; j + 1 < c->start[i + 1]; j++) {
      const double *p = c->rz + 2 * j, *q = p + 2;
      v += (p[0] * p[0] + p[0] * q[0] + q[0] * q[0]) * (p[1] - q[1]) / 3;
      a += 0.5 * (p[0] + q[0]) * hypot(q[0] - p[0], q[1] - p[1]);
    }
  *V = M_PI * v, *A = 2 * M_PI * a;
}

/* The structural promises of one result: offsets increasing, no point equal
 * to another of its piece (but a loop's last to its first), an open piece
 * starting at its end of larger z, a loop clockwise from its top, pieces
 * sorted by their largest z. */
static void check_curves(const ves_level_set_curves *c) {
  assert_int_equal(c->start[0], 0);
  double zprev = INFINITY;
  for (int i = 0; i < c->npieces; i++) {
    const int s = c->start[i], e = c->start[i + 1], m = e - s;
    const double *P = c->rz + 2 * s;
    assert_true(m >= 2);
    const int distinct = c->closed[i] ? m - 1 : m;
    if (c->closed[i]) assert_true(P[0] == P[2 * (m - 1)] && P[1] == P[2 * (m - 1) + 1]);
    for (int a = 0; a < distinct; a++)
      for (int b = a + 1; b < distinct; b++)
        assert_false(P[2 * a] == P[2 * b] && P[2 * a + 1] == P[2 * b + 1]);
    double zmax = -INFINITY, area2 = 0;
    for (int a = 0; a < m; a++) zmax = fmax(zmax, P[2 * a + 1]);
    assert_true(zmax <= zprev);
    zprev = zmax;
    if (c->closed[i]) {
      for (int a = 0; a + 1 < m; a++)
        area2 += P[2 * a] * P[2 * a + 3] - P[2 * a + 2] * P[2 * a + 1];
      assert_true(area2 < 0);    /* clockwise */
      assert_true(P[1] == zmax); /* from the top */
    } else {
      const double *q = P + 2 * (m - 1);
      assert_true(P[1] > q[1] || (P[1] == q[1] && P[0] < q[0]));
    }
  }
}

/* eval and curves_eval on one field: the segment sums equal eval's volume
 * and area up to rounding (1e-12 relative: sums of ~1e3 terms, each exact to
 * ~1e-16, the crossing points of a shared edge computed once here and twice,
 * from either end, in eval); prints and returns the pieces. */
static void compare_eval(int n, int ntri, const int *tri, const double *x, const double *phi,
                         const char *what, ves_level_set_curves *c) {
  ves_level_set ls;
  assert_int_equal(ves_level_set_eval(n, ntri, tri, x, phi, &ls), VES_OK);
  assert_int_equal(ves_level_set_curves_eval(n, ntri, tri, x, phi, c), VES_OK);
  check_curves(c);
  double V, A;
  curve_measures(c, &V, &A);
  printf("# %s: %d pieces, %d points; volume %.15f (eval %.15f), area %.15f (eval %.15f)\n", what,
         c->npieces, c->start[c->npieces], V, ls.volume, A, ls.area);
  assert_true(fabs(V - ls.volume) <= 1e-12 * ls.volume);
  assert_true(fabs(A - ls.area) <= 1e-12 * ls.area);
}

/* ves_level_set_curves_eval: a sphere and an oblate closed by the axis (one
 * piece, north pole to south pole), two separate vesicles (two pieces, the
 * upper first), a torus-like closed loop, phi = 0 exactly at nodes and along
 * edges (a diamond whose upper half passes through nodes and lower half runs
 * along edges: no duplicate point, one piece), a plane ending on the box. */
static void test_level_set_curves(void **state) {
  (void)state;
  const int k = 49, nr = k, nz = 2 * k - 1, n = nr * nz, ntri = 2 * (nr - 1) * (nz - 1);
  double *x, *phi = malloc((size_t)n * sizeof *phi);
  int *tri;
  grid(nr, nz, 1.5, 1.5, &x, &tri); /* h = 1.5 / 48 = 1/32: the nodes exact */
  assert_non_null(phi);
  ves_level_set_curves c;
  /* sphere */
  for (int a = 0; a < n; a++) phi[a] = 1 - hypot(x[2 * a], x[2 * a + 1]);
  compare_eval(n, ntri, tri, x, phi, "sphere", &c);
  assert_int_equal(c.npieces, 1);
  assert_int_equal(c.closed[0], 0);
  const int m = c.start[1];
  /* from the north pole to the south pole on the axis (the grid nodes
   * (0, +-1) have phi = 0 exactly) */
  assert_true(c.rz[0] == 0 && c.rz[1] == 1 && c.rz[2 * (m - 1)] == 0 && c.rz[2 * m - 1] == -1);
  ves_level_set_curves_free(&c);
  assert_null(c.rz);
  /* oblate: semi-axes 1.2 in r, 0.6 in z */
  for (int a = 0; a < n; a++) phi[a] = 1 - hypot(x[2 * a] / 1.2, x[2 * a + 1] / 0.6);
  compare_eval(n, ntri, tri, x, phi, "oblate", &c);
  assert_int_equal(c.npieces, 1);
  assert_true(c.rz[0] == 0 && c.rz[1] > 0 && c.rz[2 * c.start[1] - 2] == 0);
  ves_level_set_curves_free(&c);
  /* two vesicles: radius 0.5 about z = 0.8, radius 0.4 about z = -0.7 */
  for (int a = 0; a < n; a++) {
    const double r = x[2 * a], z = x[2 * a + 1];
    phi[a] = fmax(0.5 - hypot(r, z - 0.8), 0.4 - hypot(r, z + 0.7));
  }
  compare_eval(n, ntri, tri, x, phi, "two pieces", &c);
  assert_int_equal(c.npieces, 2);
  assert_true(c.closed[0] == 0 && c.closed[1] == 0);
  assert_true(c.rz[1] > 1.2 && c.rz[2 * c.start[1] + 1] < -0.2); /* the upper first */
  ves_level_set_curves_free(&c);
  /* a torus: the disc of radius 0.3 about (0.8, 0.1) */
  for (int a = 0; a < n; a++) phi[a] = 0.3 - hypot(x[2 * a] - 0.8, x[2 * a + 1] - 0.1);
  compare_eval(n, ntri, tri, x, phi, "torus", &c);
  assert_int_equal(c.npieces, 1);
  assert_int_equal(c.closed[0], 1);
  ves_level_set_curves_free(&c);
  /* the diamond phi = 1 - r - |z|: exact in the interpolant (linear on each
   * triangle, the kink on the row z = 0), so the measures are the double
   * cone's, V = 2 pi / 3, A = 2 pi sqrt 2 (1e-13: rounding); for z > 0 the
   * zero line crosses the cells' diagonals through the 33 nodes r + z = 1,
   * for z < 0 it runs along the diagonals: 33 nodes + 32 midpoints above and
   * 32 more nodes below, 97 points, none twice */
  for (int a = 0; a < n; a++) phi[a] = 1 - x[2 * a] - fabs(x[2 * a + 1]);
  compare_eval(n, ntri, tri, x, phi, "diamond", &c);
  assert_int_equal(c.npieces, 1);
  assert_int_equal(c.start[1], 97);
  double V, A;
  curve_measures(&c, &V, &A);
  assert_true(fabs(V - 2 * M_PI / 3) <= 1e-13 && fabs(A - 2 * M_PI * sqrt(2)) <= 1e-13);
  ves_level_set_curves_free(&c);
  /* a plane on a row of nodes (phi = 0 along the row's edges) and between
   * rows: one open piece from the axis to the box at r = 1.5, nr points on
   * the row (each edge once), 2 nr - 1 between (nodes' edges and diagonals) */
  for (int pass = 0; pass < 2; pass++) {
    const double z0 = pass ? 0.25 : 0.25 + 1.0 / 64;
    for (int a = 0; a < n; a++) phi[a] = z0 - x[2 * a + 1];
    assert_int_equal(ves_level_set_curves_eval(n, ntri, tri, x, phi, &c), VES_OK);
    check_curves(&c);
    assert_int_equal(c.npieces, 1);
    assert_int_equal(c.start[1], pass ? nr : 2 * nr - 1);
    const double *e = c.rz + 2 * (c.start[1] - 1);
    assert_true(c.rz[0] == 0 && c.rz[1] == z0 && e[0] == 1.5 && e[1] == z0);
    ves_level_set_curves_free(&c);
  }
  /* nothing: no pieces; errors as eval's */
  for (int a = 0; a < n; a++) phi[a] = -1;
  assert_int_equal(ves_level_set_curves_eval(n, ntri, tri, x, phi, &c), VES_OK);
  assert_int_equal(c.npieces, 0);
  ves_level_set_curves_free(&c);
  assert_int_equal(ves_level_set_curves_eval(n, 0, tri, x, phi, &c), VES_ERR_ARG);
  assert_int_equal(ves_level_set_curves_eval(n, ntri, NULL, x, phi, &c), VES_ERR_ARG);
  assert_int_equal(ves_level_set_curves_eval(n - 1, ntri, tri, x, phi, &c), VES_ERR_ARG);
  phi[0] = NAN;
  assert_int_equal(ves_level_set_curves_eval(n, ntri, tri, x, phi, &c), VES_ERR_ARG);
  ves_level_set_curves_free(NULL);
  free(x), free(tri), free(phi);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_level_set),
                                     cmocka_unit_test(test_level_set_curves)};
  return cmocka_run_group_tests_name("level_set", tests, NULL, NULL);
}
