/* vesica — tests of geom: Delaunay, spacing, exact node-wise-radius search, adapted node sets. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifdef _OPENMP
#include <omp.h>
#endif
#include "ves/geom.h"

/* splitmix64 in [0, 1): seeded, so every test is deterministic. */
static double uni(uint64_t *s) {
  uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return (double)(z >> 11) * (1.0 / 9007199254740992.0);
}

static int cmp_dbl(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* orient(a, b, c) = twice the signed area of abc. */
static double orient(const double *a, const double *b, const double *c) {
  return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Number of convex hull vertices (Andrew's monotone chain, strict turns). */
static int hull_count(int n, const double *x) {
  int *ord = malloc(sizeof(int) * (size_t)n), *st = malloc(sizeof(int) * 2 * (size_t)(n + 1));
  assert_non_null(ord);
  assert_non_null(st);
  for (int i = 0; i < n; i++) ord[i] = i;
  for (int i = 1; i < n; i++) /* insertion sort by (x, y) */
    for (int j = i; j > 0; j--) {
      const double *p = x + 2 * ord[j - 1], *q = x + 2 * ord[j];
      if (p[0] > q[0] || (p[0] == q[0] && p[1] > q[1])) {
        int t = ord[j];
        ord[j] = ord[j - 1], ord[j - 1] = t;
      } else
        break;
    }
  int k = 0;
  for (int i = 0; i < n; i++) { /* lower hull */
    while (k >= 2 && orient(x + 2 * st[k - 2], x + 2 * st[k - 1], x + 2 * ord[i]) <= 0) k--;
    st[k++] = ord[i];
  }
  for (int i = n - 2, t = k + 1; i >= 0; i--) { /* upper hull */
    while (k >= t && orient(x + 2 * st[k - 2], x + 2 * st[k - 1], x + 2 * ord[i]) <= 0) k--;
    st[k++] = ord[i];
  }
  free(ord), free(st);
  return k - 1;
}

/* incircle(a, b, c, d) > 0 iff d is inside the circumcircle of the CCW triangle abc. */
static double incircle(const double *a, const double *b, const double *c, const double *d) {
  double adx = a[0] - d[0], ady = a[1] - d[1], bdx = b[0] - d[0], bdy = b[1] - d[1];
  double cdx = c[0] - d[0], cdy = c[1] - d[1];
  double al = adx * adx + ady * ady, bl = bdx * bdx + bdy * bdy, cl = cdx * cdx + cdy * cdy;
  return adx * (bdy * cl - bl * cdy) - ady * (bdx * cl - bl * cdx) + al * (bdx * cdy - bdy * cdx);
}

/* Delaunay of 500 random points: Euler count, CCW, empty circumcircles, every index used. */
static void test_delaunay_random(void **state) {
  (void)state;
  enum { N = 500 };
  double *x = malloc(sizeof(double) * 2 * N);
  assert_non_null(x);
  uint64_t s = 42;
  for (int i = 0; i < 2 * N; i++) x[i] = uni(&s);
  int ntri = 0, *tri = NULL;
  assert_int_equal(ves_geom_delaunay(N, x, &ntri, &tri), VES_OK);
  int b = hull_count(N, x);
  assert_int_equal(ntri, 2 * N - 2 - b); /* Euler: exact for points in general position */
  int used[N] = {0};
  for (int t = 0; t < ntri; t++) {
    const double *p = x + 2 * tri[3 * t], *q = x + 2 * tri[3 * t + 1], *r = x + 2 * tri[3 * t + 2];
    /* CCW with positive area; random points in [0,1]^2 have no degenerate triangles */
    assert_true(orient(p, q, r) > 0.0);
    for (int k = 0; k < 3; k++) used[tri[3 * t + k]] = 1;
    for (int i = 0; i < N; i++) {
      if (i == tri[3 * t] || i == tri[3 * t + 1] || i == tri[3 * t + 2]) continue;
      /* empty circle: the determinant's terms are O(1) here, its rounding ~1e-15; 1e-12
       * leaves room for that and still catches any real violation (O(area^2) >> 1e-12) */
      assert_true(incircle(p, q, r, x + 2 * i) <= 1e-12);
    }
  }
  for (int i = 0; i < N; i++) assert_int_equal(used[i], 1);
  free(tri), free(x);
}

/* Duplicates are VES_ERR_GEOM, too few / collinear / bad arguments are errors. */
static void test_delaunay_errors(void **state) {
  (void)state;
  double x[10] = {0, 0, 1, 0, 0, 1, 1, 1, 1, 0}; /* point 4 duplicates point 1 */
  int ntri = -1, *tri = NULL;
  assert_int_equal(ves_geom_delaunay(5, x, &ntri, &tri), VES_ERR_GEOM);
  assert_null(tri);
  double h[5];
  assert_int_equal(ves_geom_spacing(5, x, h), VES_ERR_GEOM);
  assert_int_equal(ves_geom_delaunay(2, x, &ntri, &tri), VES_ERR_ARG);
  assert_int_equal(ves_geom_delaunay(4, NULL, &ntri, &tri), VES_ERR_ARG);
  double line[6] = {0, 0, 1, 1, 2, 2};
  assert_int_equal(ves_geom_delaunay(3, line, &ntri, &tri), VES_ERR_GEOM);
  double bad[6] = {0, 0, 1, 0, NAN, 1};
  assert_int_equal(ves_geom_delaunay(3, bad, &ntri, &tri), VES_ERR_ARG);
  assert_int_equal(ves_geom_spacing(1, x, h), VES_ERR_ARG);
  /* four points of a square: two triangles whatever the diagonal */
  assert_int_equal(ves_geom_delaunay(4, x, &ntri, &tri), VES_OK);
  assert_int_equal(ntri, 2);
  free(tri);
}

/* Spacing on a regular hex lattice of spacing h is h at interior nodes. */
static void test_spacing_hex(void **state) {
  (void)state;
  enum { NI = 20, NJ = 24, N = NI * NJ };
  const double hh = 0.037;
  double *x = malloc(sizeof(double) * 2 * N), *h = malloc(sizeof(double) * N);
  assert_non_null(x);
  assert_non_null(h);
  for (int j = 0; j < NJ; j++)
    for (int i = 0; i < NI; i++) {
      x[2 * (j * NI + i)] = (i + 0.5 * (j % 2)) * hh;
      x[2 * (j * NI + i) + 1] = j * hh * sqrt(3.0) / 2;
    }
  assert_int_equal(ves_geom_spacing(N, x, h), VES_OK);
  int checked = 0;
  /* the two smoothing passes carry the hull nodes' values two rings inwards:
   * check from the fourth ring on */
  for (int j = 4; j < NJ - 4; j++)
    for (int i = 4; i < NI - 4; i++, checked++)
      /* six edges of length h up to the rounding of the coordinates (~1e-17): 1e-12 relative */
      assert_true(fabs(h[j * NI + i] - hh) <= 1e-12 * hh);
  assert_true(checked > 150);
  free(x), free(h);
}

/* All a with |X - x_a| <= r_a, sorted: the brute-force reference. */
static int brute(int n, const double *x, const double *r, const double *X, int *idx) {
  int c = 0;
  for (int a = 0; a < n; a++) {
    double dR = X[0] - x[2 * a], dZ = X[1] - x[2 * a + 1];
    if (dR * dR + dZ * dZ <= r[a] * r[a]) idx[c++] = a;
  }
  return c;
}

/* Search with radii spread by 20x equals brute force exactly; count > cap;
 * candidates near a centre filtered at points around it; errors.
 * Kept whole (105 lines): one scenario whose checks build on each other. */
static void test_search(void **state) {
  (void)state;
  enum { N = 2002, Q = 1000 };
  double *x = malloc(sizeof(double) * 2 * N), *r = malloc(sizeof(double) * N);
  int *got = malloc(sizeof(int) * N), *ref = malloc(sizeof(int) * N);
  assert_non_null(x);
  assert_non_null(r);
  assert_non_null(got);
  assert_non_null(ref);
  uint64_t s = 7;
  for (int a = 0; a < N - 2; a++) {
    x[2 * a] = uni(&s), x[2 * a + 1] = uni(&s);
    r[a] = 0.01 * pow(20.0, uni(&s)); /* 0.01 .. 0.2 */
  }
  /* two nodes whose circle passes exactly through a query point (binary-exact numbers) */
  x[2 * (N - 2)] = 0.5, x[2 * (N - 2) + 1] = 0.5, r[N - 2] = 0.25;
  x[2 * (N - 1)] = 0.25, x[2 * (N - 1) + 1] = 0.5, r[N - 1] = 0.0078125;
  ves_geom_search *sr = NULL;
  assert_int_equal(ves_geom_search_create(N, x, r, &sr), VES_OK);
  long total = 0;
  for (int q = 0; q <= Q + 1; q++) {
    double X[2] = {-0.1 + 1.2 * uni(&s), -0.1 + 1.2 * uni(&s)};
    if (q == Q) X[0] = 0.75, X[1] = 0.5;           /* on the circle of node N-2 */
    if (q == Q + 1) X[0] = 0.25, X[1] = 0.5078125; /* on the circle of node N-1 */
    int c = -1;
    assert_int_equal(ves_geom_search_query(sr, X, N, got, &c), VES_OK);
    int cr = brute(N, x, r, X, ref);
    assert_int_equal(c, cr); /* exact: same set, same order */
    for (int k = 0; k < c; k++) assert_int_equal(got[k], ref[k]);
    if (q >= Q) assert_true(c >= 1 && got[c - 1] == (q == Q ? N - 2 : N - 1));
    total += c;
  }
  printf("search: %d nodes, %d queries, mean %.1f hits\n", N, Q, (double)total / Q);
  /* count > cap: the true count comes back, then a big enough buffer gives the set */
  double X[2] = {0.5, 0.5};
  int c = -1, small[3];
  assert_int_equal(ves_geom_search_query(sr, X, 3, small, &c), VES_OK);
  int cr = brute(N, x, r, X, ref);
  assert_true(cr > 3);
  assert_int_equal(c, cr);
  assert_int_equal(ves_geom_search_query(sr, X, 0, NULL, &c), VES_OK);
  assert_int_equal(c, cr);
  assert_int_equal(ves_geom_search_query(sr, X, c, got, &c), VES_OK);
  for (int k = 0; k < c; k++) assert_int_equal(got[k], ref[k]);
  /* clusters: the candidates within rho of a centre, filtered at each of
   * six points within rho of it, give exactly the brute-force set of that
   * point (also for points on a circle through the node, and rho = 0 is the
   * plain query) */
  int *cand = malloc(sizeof(int) * N);
  assert_non_null(cand);
  long ncand = 0, nexact = 0;
  for (int q = 0; q < Q / 10; q++) {
    const double rho = q % 2 ? 0.02 : 0.002;
    double C[2] = {-0.1 + 1.2 * uni(&s), -0.1 + 1.2 * uni(&s)};
    if (q == 0) C[0] = 0.75 - rho, C[1] = 0.5; /* (0.75, 0.5) at distance rho: on a circle */
    int nc = -1;
    assert_int_equal(ves_geom_search_query_near(sr, C, rho, N, cand, &nc), VES_OK);
    for (int k = 1; k < nc; k++) assert_true(cand[k] > cand[k - 1]);
    ncand += nc;
    for (int p = 0; p < 6; p++) {
      const double t = 2 * M_PI * uni(&s), d = p ? rho * uni(&s) : rho;
      double Xp[2] = {C[0] + d * cos(t), C[1] + d * sin(t)};
      if (q == 0 && p == 0) Xp[0] = 0.75, Xp[1] = 0.5;
      if (hypot(Xp[0] - C[0], Xp[1] - C[1]) > rho) continue; /* rounding pushed it out */
      int cf = -1, cb = brute(N, x, r, Xp, ref);
      assert_int_equal(ves_geom_search_filter(sr, Xp, nc, cand, got, &cf), VES_OK);
      assert_int_equal(cf, cb);
      for (int k = 0; k < cf; k++) assert_int_equal(got[k], ref[k]);
      nexact += cb;
    }
    int c0 = -1, c1 = -1;
    assert_int_equal(ves_geom_search_query_near(sr, C, 0.0, N, cand, &c0), VES_OK);
    assert_int_equal(ves_geom_search_query(sr, C, N, got, &c1), VES_OK);
    assert_int_equal(c0, c1);
    for (int k = 0; k < c0; k++) assert_int_equal(cand[k], got[k]);
  }
  printf("search near: %.1f candidates per centre, %.1f hits per point\n", ncand / (Q / 10.0),
         nexact / (6.0 * Q / 10.0));
  /* the filter in place (idx = cand) */
  int nc = -1, cf = -1;
  assert_int_equal(ves_geom_search_query_near(sr, X, 0.01, N, cand, &nc), VES_OK);
  assert_int_equal(ves_geom_search_filter(sr, X, nc, cand, cand, &cf), VES_OK);
  assert_int_equal(cf, brute(N, x, r, X, ref));
  for (int k = 0; k < cf; k++) assert_int_equal(cand[k], ref[k]);
  /* errors */
  assert_int_equal(ves_geom_search_query(sr, X, 3, NULL, &c), VES_ERR_ARG);
  assert_int_equal(ves_geom_search_query_near(sr, X, -1.0, N, cand, &c), VES_ERR_ARG);
  assert_int_equal(ves_geom_search_query_near(sr, X, NAN, N, cand, &c), VES_ERR_ARG);
  assert_int_equal(ves_geom_search_query_near(NULL, X, 0.1, N, cand, &c), VES_ERR_ARG);
  cand[0] = N;
  assert_int_equal(ves_geom_search_filter(sr, X, 1, cand, got, &c), VES_ERR_ARG);
  assert_int_equal(ves_geom_search_filter(sr, X, 1, NULL, got, &c), VES_ERR_ARG);
  assert_int_equal(ves_geom_search_filter(sr, X, 0, NULL, NULL, &c), VES_OK);
  assert_int_equal(c, 0);
  free(cand);
  ves_geom_search_destroy(&sr);
  assert_null(sr);
  ves_geom_search_destroy(&sr);
  ves_geom_search_destroy(NULL);
  r[5] = -1.0;
  assert_int_equal(ves_geom_search_create(N, x, r, &sr), VES_ERR_ARG);
  assert_null(sr);
  assert_int_equal(ves_geom_search_create(0, x, r, &sr), VES_ERR_ARG);
  free(x), free(r), free(got), free(ref);
}

/* Sizing of the sphere test: h_band in |d| < 4 eps, slope s beyond, capped at h_far. */
typedef struct {
  double eps, h_band, s, h_far;
} sphere_sizing;

static double sphere_h(const double X[2], void *ctx) {
  const sphere_sizing *c = ctx;
  double d = 1.0 - hypot(X[0], X[1]); /* signed distance, > 0 inside */
  double h = c->h_band + c->s * fmax(0.0, fabs(d) - 4 * c->eps);
  return fmin(h, c->h_far);
}

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

/* Percentile p in [0, 1] of a sorted array. */
static double pct(const double *v, int n, double p) { return v[(int)floor(p * (n - 1) + 0.5)]; }

/* The adapted node set for a sphere: spacing, walls, corners, axis regularity, ghosts.
 * Kept whole (153 lines): one scenario whose checks build on each other. */
static void test_nodes_sphere(void **state) {
  (void)state;
  sphere_sizing sz = {0.04, 0.02, 0.15, 0.2};
  ves_nodes_params par;
  ves_nodes_params_default(&par);
  par.LR = 2, par.LZ = 2, par.h = sphere_h, par.h_ctx = &sz;
  ves_nodes *nd = NULL;
  double t0 = now();
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_OK);
  double tg = now() - t0;
  const int n = nd->n;
  int nl = 0, nw = 0, na = 0, nf = 0;
  for (int a = 0; a < n; a++) {
    nl += (nd->flag[a] & VES_NODE_LATTICE) != 0, nw += (nd->flag[a] & VES_NODE_WALL) != 0;
    na += (nd->flag[a] & VES_NODE_AXIS) != 0, nf += nd->flag[a] == 0;
  }
  printf("nodes: n %d (lattice %d, wall %d, axis %d, free %d), ghosts %d, %.2f s\n", n, nl, nw, na,
         nf, nd->ng, tg);

  /* all in the box; R exactly 0 <=> AXIS; corners present */
  int corners = 0;
  for (int a = 0; a < n; a++) {
    double R = nd->x[2 * a], Z = nd->x[2 * a + 1];
    assert_true(R >= 0.0 && R <= par.LR && Z >= -par.LZ && Z <= par.LZ);
    assert_int_equal(R == 0.0, (nd->flag[a] & VES_NODE_AXIS) != 0);
    if ((R == 0.0 || R == par.LR) && fabs(Z) == par.LZ) {
      corners++;
      assert_true(nd->flag[a] & VES_NODE_WALL);
    }
  }
  assert_int_equal(corners, 4);

  /* ghosts: exactly the real nodes with R > 0, mirrored exactly */
  int *seen = calloc((size_t)n, sizeof(int));
  double *xe = malloc(sizeof(double) * 2 * (size_t)(n + nd->ng));
  assert_non_null(seen);
  assert_non_null(xe);
  ves_nodes_extended(nd, xe);
  for (int k = 0; k < nd->ng; k++) {
    int a = nd->ghost_of[k];
    assert_true(a >= 0 && a < n && nd->x[2 * a] > 0.0 && !seen[a]);
    seen[a] = 1;
    assert_true(xe[2 * (n + k)] == -nd->x[2 * a] && xe[2 * (n + k) + 1] == nd->x[2 * a + 1]);
  }
  for (int a = 0; a < n; a++) assert_int_equal(seen[a], nd->x[2 * a] > 0.0);

  /* no two nodes closer than 0.3 h: the nearest neighbour is a Delaunay neighbour */
  int ntri = 0, *tri = NULL;
  assert_int_equal(ves_geom_delaunay(n, nd->x, &ntri, &tri), VES_OK);
  double dmin = INFINITY;
  for (int t = 0; t < ntri; t++)
    for (int k = 0; k < 3; k++) {
      const double *p = nd->x + 2 * tri[3 * t + k], *q = nd->x + 2 * tri[3 * t + (k + 1) % 3];
      double m[2] = {0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])};
      double d = hypot(p[0] - q[0], p[1] - q[1]) / sphere_h(m, &sz);
      dmin = fmin(dmin, d);
    }
  printf("nodes: min distance / h = %.3f\n", dmin);
  assert_true(dmin >= 0.3); /* the spec's bound: a well-shaped set has ~0.6 h or more */
  free(tri);

  /* wall gaps <= 1.5 h along each edge (bottom, top, right) */
  double *w = malloc(sizeof(double) * (size_t)n);
  assert_non_null(w);
  double gmax = 0.0;
  for (int e = 0; e < 3; e++) {
    int m = 0;
    for (int a = 0; a < n; a++) {
      double R = nd->x[2 * a], Z = nd->x[2 * a + 1];
      if (e == 0 && Z == -par.LZ) w[m++] = R;
      if (e == 1 && Z == par.LZ) w[m++] = R;
      if (e == 2 && R == par.LR) w[m++] = Z;
    }
    qsort(w, (size_t)m, sizeof(double), cmp_dbl);
    assert_true(m >= 2 && w[0] == (e == 2 ? -par.LZ : 0.0) &&
                w[m - 1] == (e == 2 ? par.LZ : par.LR));
    for (int i = 0; i + 1 < m; i++) {
      double c = 0.5 * (w[i] + w[i + 1]);
      double X[2] = {e == 2 ? par.LR : c, e == 0 ? -par.LZ : (e == 1 ? par.LZ : c)};
      gmax = fmax(gmax, (w[i + 1] - w[i]) / sphere_h(X, &sz));
    }
  }
  printf("nodes: max wall gap / h = %.3f\n", gmax);
  assert_true(gmax <= 1.5); /* graded placement rescaled by < 1%, h varies < 0.2 h per step */

  /* spacing ratio h_a / h(X_a) of the free nodes */
  double *ratio = malloc(sizeof(double) * (size_t)(nf > 0 ? nf : 1));
  assert_non_null(ratio);
  int m = 0, inside = 0;
  for (int a = 0; a < n; a++)
    if (nd->flag[a] == 0) {
      ratio[m] = nd->h[a] / sphere_h(nd->x + 2 * a, &sz);
      inside += ratio[m] >= 0.75 && ratio[m] <= 1.33;
      m++;
    }
  qsort(ratio, (size_t)m, sizeof(double), cmp_dbl);
  printf("nodes: free h_a/h: p1 %.3f p5 %.3f p50 %.3f p95 %.3f p99 %.3f; in [0.75,1.33] %.1f%%\n",
         pct(ratio, m, 0.01), pct(ratio, m, 0.05), pct(ratio, m, 0.5), pct(ratio, m, 0.95),
         pct(ratio, m, 0.99), 100.0 * inside / m);
  assert_true(inside >= 0.95 * m); /* a CVT has h_a within ~10% of h; 95% leaves room for
                                      the nodes touching the strip and the walls */

  /* regular lattice where the interface meets the axis: the window R < 8 h_band,
   * |Z -+ 1| < 4 eps, and its inner part two spacings away from the band's edges on the axis */
  double lo = INFINITY, hi = 0.0, ilo = INFINITY, ihi = 0.0;
  int cnt = 0, icnt = 0, lat = 0;
  for (int a = 0; a < n; a++) {
    double R = nd->x[2 * a], Z = nd->x[2 * a + 1], dz = fabs(fabs(Z) - 1);
    if (R < 8 * sz.h_band && dz < 4 * sz.eps) {
      double q = nd->h[a] / sz.h_band;
      lo = fmin(lo, q), hi = fmax(hi, q), cnt++;
      lat += (nd->flag[a] & VES_NODE_LATTICE) != 0;
      if (dz < 4 * sz.eps - 2 * sz.h_band) ilo = fmin(ilo, q), ihi = fmax(ihi, q), icnt++;
    }
  }
  printf("nodes: axis window %d nodes (%d lattice), h_a/h_band in [%.4f, %.4f]; "
         "inner %d nodes in [%.4f, %.4f]\n",
         cnt, lat, lo, hi, icnt, ilo, ihi);
  assert_true(cnt > 100 && icnt > 100);
  /* inner window: exact hex lattice in the band, up to the 1D grading's global rescale
   * (< 1%) and the ~1% rise of h one spacing off the axis at the window's outer corner */
  assert_true(ilo >= 0.97 && ihi <= 1.03);
  /* whole window: its first and last rows (|Z -+ 1| ~ 4 eps) have half their Delaunay edges
   * outside the band where h = h_band + 0.15 (|d| - 4 eps) is up to 15% larger one spacing
   * out, so h_a/h_band up to ~1.08 is the sizing itself, plus a few % of lattice shear and of
   * the Lloyd nodes where the strip narrows (measured [0.961, 1.108]) */
  assert_true(lo >= 0.93 && hi <= 1.12);

  /* determinism: the same seed gives the same set, for 1, 2 and 3 threads (the Lloyd
   * cells run on the OpenMP threads) */
#ifdef _OPENMP
  const int nthr0 = omp_get_max_threads();
#endif
  for (int nt = 1; nt <= 3; nt++) {
#ifdef _OPENMP
    omp_set_num_threads(nt);
#endif
    ves_nodes *nd2 = NULL;
    assert_int_equal(ves_nodes_generate(&par, &nd2), VES_OK);
    assert_int_equal(nd2->n, n);
    assert_memory_equal(nd2->x, nd->x, sizeof(double) * 2 * (size_t)n);
    ves_nodes_destroy(&nd2);
  }
#ifdef _OPENMP
  omp_set_num_threads(nthr0);
#endif

  free(seen), free(xe), free(w), free(ratio);
  ves_nodes_destroy(&nd);
  assert_null(nd);
  ves_nodes_destroy(&nd);
  ves_nodes_destroy(NULL);
}

static double bad_h(const double X[2], void *ctx) {
  (void)ctx;
  return X[1] > 0.5 ? -1.0 : 0.3; /* negative in part of the box */
}

static double flat_h(const double X[2], void *ctx) {
  (void)X;
  return *(const double *)ctx;
}

/* Error paths of the generator, and a small uniform set (constant h, no free region check). */
static void test_nodes_errors(void **state) {
  (void)state;
  double h0 = 0.1;
  ves_nodes_params par;
  ves_nodes_params_default(&par);
  assert_true(par.axis_spacings >= 8 && par.lloyd_iter > 0);
  par.LR = 1, par.LZ = 1, par.h = flat_h, par.h_ctx = &h0;
  ves_nodes *nd = NULL;
  par.LR = 0;
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_ERR_ARG);
  par.LR = -1;
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_ERR_ARG);
  par.LR = 1, par.LZ = 0;
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_ERR_ARG);
  par.LZ = 1, par.h = NULL;
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_ERR_ARG);
  par.h = bad_h;
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_ERR_ARG);
  h0 = 0.0;
  par.h = flat_h;
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_ERR_ARG);
  h0 = NAN;
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_ERR_ARG);
  assert_null(nd);
  assert_int_equal(ves_nodes_generate(NULL, &nd), VES_ERR_ARG);
  assert_int_equal(ves_nodes_generate(&par, NULL), VES_ERR_ARG);
  /* a constant h on a box wider than the strip: spacing near h everywhere inside */
  h0 = 0.05, par.LR = 1.5;
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_OK);
  int interior = 0, good = 0;
  for (int a = 0; a < nd->n; a++) {
    double R = nd->x[2 * a], Z = nd->x[2 * a + 1];
    if (R < par.LR - 2 * h0 && fabs(Z) < par.LZ - 2 * h0) {
      interior++;
      good += fabs(nd->h[a] / h0 - 1) < 0.15;
    }
  }
  printf("uniform: n %d, %d of %d interior nodes with |h_a/h - 1| < 0.15\n", nd->n, good, interior);
  assert_true(good >= 0.95 * interior); /* CVT of a constant density is near hex: few defects */
  ves_nodes_destroy(&nd);
}

/* Region |X - (0.5, 0)| < 0.3 reserved for the caller's nodes. */
static int reserved_disc(const double X[2], void *ctx) {
  (void)ctx;
  return hypot(X[0] - 0.5, X[1]) < 0.3;
}

static double uniform_h(const double X[2], void *ctx) {
  (void)X;
  return *(const double *)ctx;
}

/* Caller-supplied fixed nodes and a reserved region: the fixed nodes are kept
 * exactly (flagged BAND), no strip or CVT node enters the region, and fixed
 * nodes outside the box are refused. */
static void test_nodes_fixed_reserved(void **state) {
  (void)state;
  double hh = 0.05, xf[2 * 40];
  int ff[40];
  for (int k = 0; k < 40; k++) { /* a ring of radius 0.2 around (0.5, 0) */
    xf[2 * k] = 0.5 + 0.2 * cos(2 * M_PI * k / 40);
    xf[2 * k + 1] = 0.2 * sin(2 * M_PI * k / 40);
    ff[k] = 0;
  }
  ves_nodes_params par;
  ves_nodes_params_default(&par);
  par.LR = 1.0, par.LZ = 1.0, par.h = uniform_h, par.h_ctx = &hh;
  par.nfixed = 40, par.xfixed = xf, par.fixed_flag = ff;
  par.reserved = reserved_disc;
  ves_nodes *nd = NULL;
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_OK);
  int band = 0;
  for (int a = 0; a < nd->n; a++) {
    const double *X = nd->x + 2 * a;
    if (nd->flag[a] & VES_NODE_BAND) {
      /* copied exactly, in the order given */
      assert_true(X[0] == xf[2 * band] && X[1] == xf[2 * band + 1]);
      band++;
    } else {
      assert_false(reserved_disc(X, NULL));
    }
  }
  assert_int_equal(band, 40);
  ves_nodes_destroy(&nd);
  xf[0] = 1.5; /* outside the box */
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_ERR_ARG);
  par.xfixed = NULL;
  assert_int_equal(ves_nodes_generate(&par, &nd), VES_ERR_ARG);
  assert_null(nd);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_nodes_fixed_reserved),
      cmocka_unit_test(test_delaunay_random), cmocka_unit_test(test_delaunay_errors),
      cmocka_unit_test(test_spacing_hex),     cmocka_unit_test(test_search),
      cmocka_unit_test(test_nodes_sphere),    cmocka_unit_test(test_nodes_errors),
  };
  // clang-format on
  return cmocka_run_group_tests(tests, NULL, NULL);
}
