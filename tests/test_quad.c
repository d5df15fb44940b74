/* vesica — tests of the quadrature rule and the discretization tables. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "ves/quad.h"

#include <omp.h>
#include <string.h>

/* Deterministic uniform numbers in [0, 1) (xorshift64*). */
static double urand(uint64_t *s) {
  *s ^= *s >> 12;
  *s ^= *s << 25;
  *s ^= *s >> 27;
  return (double)((*s * 2685821657736338717ULL) >> 11) * 0x1.0p-53;
}

/* Exact integral of x^i y^j over triangle v by Green's theorem,
 * int_T x^i y^j dA = sum_edges int x^(i+1) y^j / (i+1) dy, each edge integral
 * (a polynomial of degree <= 6 in the edge parameter) done with 4-point
 * Gauss-Legendre, exact to degree 7: independent of the rule under test. */
static double exact_monomial(const double v[6], int i, int j) {
  static const double gx[4] = {-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                               0.8611363115940526};
  static const double gw[4] = {0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                               0.3478548451374538};
  double sum = 0.0;
  for (int e = 0; e < 3; e++) {
    const double *a = v + 2 * e, *b = v + 2 * ((e + 1) % 3);
    for (int g = 0; g < 4; g++) {
      double t = 0.5 * (gx[g] + 1.0);
      double x = a[0] + t * (b[0] - a[0]), y = a[1] + t * (b[1] - a[1]);
      sum += 0.5 * gw[g] * pow(x, i + 1) / (i + 1) * pow(y, j) * (b[1] - a[1]);
    }
  }
  return sum;
}

/* The rule integrates every monomial x^i y^j, i + j <= 4, exactly on
 * arbitrary triangles. */
static void test_rule_exact_degree4(void **state) {
  (void)state;
  double bary[18], w[6], wsum = 0.0;
  ves_quad_rule(bary, w);
  for (int k = 0; k < 6; k++) {
    wsum += w[k];
    assert_true(bary[3 * k] > 0 && bary[3 * k + 1] > 0 && bary[3 * k + 2] > 0); /* interior */
  }
  /* weights sum to one: 6 terms of O(0.2) in double -> a few ulp */
  assert_true(fabs(wsum - 1.0) < 4e-16);
  uint64_t seed = 12345;
  double worst = 0.0;
  for (int trial = 0; trial < 200; trial++) {
    double v[6];
    for (int c = 0; c < 6; c++) v[c] = 4.0 * urand(&seed) - 2.0;
    double area = 0.5 * ((v[2] - v[0]) * (v[5] - v[1]) - (v[3] - v[1]) * (v[4] - v[0]));
    if (fabs(area) < 1e-3) continue; /* skip slivers: the reference sum cancels badly */
    for (int i = 0; i <= 4; i++)
      for (int j = 0; i + j <= 4; j++) {
        double q = 0.0;
        for (int k = 0; k < 6; k++) {
          const double *b = bary + 3 * k;
          double x = b[0] * v[0] + b[1] * v[2] + b[2] * v[4];
          double y = b[0] * v[1] + b[1] * v[3] + b[2] * v[5];
          q += w[k] * fabs(area) * pow(x, i) * pow(y, j);
        }
        double ex = exact_monomial(v, i, j) * (area > 0 ? 1.0 : -1.0);
        /* error relative to the integral of |x|^i|y|^j's scale |T| * 2^(i+j):
         * both sides are sums of O(10) terms of that size */
        double err = fabs(q - ex) / (fabs(area) * pow(2.0, i + j));
        if (err > worst) worst = err;
      }
  }
  printf("# degree-4 rule: worst scaled error over 200 triangles %.2e\n", worst);
  assert_true(worst <= 1e-13);
}

/* Degree 5 is NOT exact: the test above can fail. */
static void test_rule_not_degree5(void **state) {
  (void)state;
  double bary[18], w[6], v[6] = {0, 0, 1, 0, 0, 1};
  ves_quad_rule(bary, w);
  double q = 0.0;
  for (int k = 0; k < 6; k++) q += w[k] * 0.5 * pow(bary[3 * k + 1], 5);
  assert_true(fabs(q - exact_monomial(v, 5, 0)) > 1e-6);
}

/* Every composite rule: weights summing to 1, interior points, exact on the
 * monomials of its base degree on random triangles; {4, 1} is ves_quad_rule
 * bit for bit; the degree-6 rule is not exact at degree 7; names parse. */
static void test_rule_composite(void **state) {
  (void)state;
  static const char *names[] = {"d4", "d6", "d4x4", "d6x4", "d4x16", "d6x16"};
  double bary[3 * VES_QUAD_NPT_MAX], w[VES_QUAD_NPT_MAX];
  uint64_t seed = 777;
  for (int r = 0; r < 6; r++) {
    ves_quad_rulespec rs;
    assert_int_equal(ves_quad_rule_parse(names[r], &rs), VES_OK);
    const int npt = ves_quad_rule_npt(rs);
    assert_int_equal(npt, (rs.degree == 4 ? 6 : 12) * rs.split * rs.split);
    assert_int_equal(npt % VES_QUAD_NPT, 0);
    assert_int_equal(ves_quad_rule_composite(rs, bary, w), VES_OK);
    double wsum = 0.0;
    for (int k = 0; k < npt; k++) {
      wsum += w[k];
      assert_true(w[k] > 0);
      assert_true(bary[3 * k] > 0 && bary[3 * k + 1] > 0 && bary[3 * k + 2] > 0);
    }
    /* up to 192 terms of size <= 0.2: a few ulp */
    assert_true(fabs(wsum - 1.0) < 1e-14);
    double worst = 0.0;
    for (int trial = 0; trial < 50; trial++) {
      double v[6];
      for (int c = 0; c < 6; c++) v[c] = 4.0 * urand(&seed) - 2.0;
      double area = 0.5 * ((v[2] - v[0]) * (v[5] - v[1]) - (v[3] - v[1]) * (v[4] - v[0]));
      if (fabs(area) < 1e-3) continue; /* skip slivers, as above */
      for (int i = 0; i <= rs.degree; i++)
        for (int j = 0; i + j <= rs.degree; j++) {
          double q = 0.0;
          for (int k = 0; k < npt; k++) {
            const double *b = bary + 3 * k;
            double x = b[0] * v[0] + b[1] * v[2] + b[2] * v[4];
            double y = b[0] * v[1] + b[1] * v[3] + b[2] * v[5];
            q += w[k] * fabs(area) * pow(x, i) * pow(y, j);
          }
          double ex = exact_monomial(v, i, j) * (area > 0 ? 1.0 : -1.0);
          double err = fabs(q - ex) / (fabs(area) * pow(2.0, i + j)); /* scaled as above */
          if (err > worst) worst = err;
        }
    }
    printf("# rule %s (%d points): worst scaled error to degree %d: %.2e\n", names[r], npt,
           rs.degree, worst);
    /* rounding only: the rules' double values are exact to 4e-17 on every
     * moment in exact rational arithmetic (checked offline); evaluating x^i y^j
     * at up to 192 points of a triangle in [-2, 2]^2 loses 2e-13 at degree 6
     * (measured). A wrong point or weight shows as >= 1e-6. */
    assert_true(worst <= 2e-12);
  }
  double b6[18], w6[6];
  ves_quad_rule(b6, w6);
  ves_quad_rulespec d4 = {4, 1}, d6 = {6, 1}, bad = {5, 1};
  assert_int_equal(ves_quad_rule_composite(d4, bary, w), VES_OK);
  assert_memory_equal(bary, b6, sizeof b6);
  assert_memory_equal(w, w6, sizeof w6);
  /* degree 7 on the unit triangle: int x^7 = 7! 0! / 9! = 1/72 */
  assert_int_equal(ves_quad_rule_composite(d6, bary, w), VES_OK);
  double q7 = 0.0;
  for (int k = 0; k < 12; k++) q7 += w[k] * 0.5 * pow(bary[3 * k + 1], 7);
  assert_true(fabs(q7 - 1.0 / 72.0) > 1e-6);
  ves_quad_rulespec rs;
  assert_int_equal(ves_quad_rule_parse("D6X4", &rs), VES_OK); /* case as the config's */
  assert_true(rs.degree == 6 && rs.split == 2);
  assert_int_equal(ves_quad_rule_parse("d8", &rs), VES_ERR_ARG);
  assert_int_equal(ves_quad_rule_npt(bad), 0);
  assert_int_equal(ves_quad_rule_composite(bad, bary, w), VES_ERR_ARG);
}

/* The weights of a whole triangulation sum to the domain's area. */
static void test_triangulation_area(void **state) {
  (void)state;
  const double LR = 1.5, LZ = 2.0;
  int nb = 10, ni = 300, n = 4 * nb + ni;
  ves_nodes nodes = {0};
  nodes.n = n;
  nodes.LR = LR;
  nodes.LZ = LZ;
  nodes.x = malloc(2 * (size_t)n * sizeof(double));
  uint64_t seed = 99;
  int k = 0;
  for (int e = 0; e < nb; e++) { /* boundary points, corners included */
    double t = (double)e / nb;
    double *p = nodes.x + 2 * k;
    p[0] = t * LR, p[1] = -LZ, p[2] = LR, p[3] = -LZ + 2 * LZ * t;
    p[4] = LR - t * LR, p[5] = LZ, p[6] = 0.0, p[7] = LZ - 2 * LZ * t;
    k += 4;
  }
  for (; k < n; k++) {
    nodes.x[2 * k] = (0.01 + 0.98 * urand(&seed)) * LR;
    nodes.x[2 * k + 1] = (0.98 * urand(&seed) - 0.49) * 2 * LZ;
  }
  ves_quad *q = NULL;
  assert_int_equal(ves_quad_create(&nodes, &q), VES_OK);
  assert_int_equal(q->nq, 6 * q->ntri);
  double sum = 0.0, mom = 0.0;
  for (int p = 0; p < q->nq; p++) {
    assert_true(q->w[p] > 0.0);
    sum += q->w[p];
    mom += q->w[p] * q->x[2 * p] * q->x[2 * p] * q->x[2 * p + 1] * q->x[2 * p + 1];
  }
  /* ~4000 positive terms: relative rounding well below 1e-13 */
  assert_true(fabs(sum - 2 * LR * LZ) <= 1e-13 * 2 * LR * LZ);
  /* int R^2 Z^2 over the box = LR^3/3 * 2 LZ^3/3: degree 4, exact */
  double ex = LR * LR * LR / 3.0 * 2.0 * LZ * LZ * LZ / 3.0;
  assert_true(fabs(mom - ex) <= 1e-12 * ex);
  /* a composite rule on the same triangles: the same cells, sub groups each */
  ves_quad *q2 = NULL;
  const ves_quad_rulespec rs = {6, 2};
  assert_int_equal(ves_quad_create_rule(&nodes, rs, &q2), VES_OK);
  assert_int_equal(q2->sub, 8);
  assert_int_equal(q2->ntri, 8 * q->ntri);
  assert_int_equal(q2->nq, 48 * q->ntri);
  int nc = 0, *cells = NULL;
  assert_int_equal(ves_quad_cells(q2, &nc, &cells), VES_OK);
  assert_int_equal(nc, q->ntri);
  assert_memory_equal(cells, q->tri, 3 * (size_t)nc * sizeof *cells);
  free(cells);
  double sum2 = 0.0, mom2 = 0.0;
  for (int p = 0; p < q2->nq; p++) {
    sum2 += q2->w[p];
    mom2 += q2->w[p] * q2->x[2 * p] * q2->x[2 * p] * q2->x[2 * p + 1] * q2->x[2 * p + 1];
  }
  /* as above, with 8x the terms */
  assert_true(fabs(sum2 - 2 * LR * LZ) <= 1e-13 * 2 * LR * LZ);
  assert_true(fabs(mom2 - ex) <= 1e-12 * ex);
  ves_quad_destroy(&q2);
  ves_quad_destroy(&q);
  assert_null(q);
  ves_quad_destroy(NULL);
  free(nodes.x);
}

static void test_errors(void **state) {
  (void)state;
  ves_quad *q = NULL;
  assert_int_equal(ves_quad_create(NULL, &q), VES_ERR_ARG);
  ves_nodes nodes = {0};
  assert_int_equal(ves_quad_create(&nodes, &q), VES_ERR_ARG);
  assert_null(q);
}

/* Sizing for a sphere of radius 1: h_band in |d| < 4 eps, then slope 0.15. */
static double sphere_h(const double X[2], void *ctx) {
  double eps = *(double *)ctx, hb = 0.5 * eps;
  double d = fabs(1.0 - hypot(X[0], X[1])) - 4 * eps;
  double h = hb + (d > 0 ? 0.15 * d : 0.0);
  return h < 0.2 ? h : 0.2;
}

/* Tables on an adapted node set: partition of unity and affine reproduction
 * with the ghosts folded (r-coefficient -R_a for a ghost), and the exact
 * integral of R over the box. */
static void test_tables(void **state) {
  (void)state;
  double eps = 0.1;
  ves_nodes_params np;
  ves_nodes_params_default(&np);
  np.LR = 1.5;
  np.LZ = 1.5;
  np.h = sphere_h;
  np.h_ctx = &eps;
  ves_nodes *nodes = NULL;
  assert_int_equal(ves_nodes_generate(&np, &nodes), VES_OK);
  ves_quad *q = NULL;
  assert_int_equal(ves_quad_create(nodes, &q), VES_OK);
  ves_lme_params lp;
  ves_lme_params_default(&lp);
  lp.gamma = 0.8; /* the paper's, the value this test's bounds are set for */
  ves_quad_info info;
  assert_int_equal(ves_quad_tables(q, nodes, &lp, &info), VES_OK);
  printf("# tables: %d nodes, %d ghosts, %d points, m mean %.1f max %d, Newton mean %.2f max %d, "
         "%.3f s\n",
         nodes->n, nodes->ng, q->nq, info.m_mean, info.m_max, info.iter_mean, info.iter_max,
         info.seconds);
  double worst = 0.0, intR = 0.0;
  int near_axis_with_ghost = 0;
  for (int p = 0; p < q->nq; p++) {
    int m = q->ptr[p + 1] - q->ptr[p];
    const double *t = q->tab + 6 * (size_t)q->ptr[p];
    double sum[6] = {0}, rr[6] = {0}, zz[6] = {0};
    int has_ghost = 0;
    for (int k = 0; k < m; k++) {
      int a = q->nbr[q->ptr[p] + k];
      double sg = q->mirror[q->ptr[p] + k] ? -1.0 : 1.0;
      has_ghost |= q->mirror[q->ptr[p] + k];
      for (int d = 0; d < 6; d++) {
        sum[d] += t[d * m + k];
        rr[d] += t[d * m + k] * sg * nodes->x[2 * a];
        zz[d] += t[d * m + k] * nodes->x[2 * a + 1];
      }
    }
    near_axis_with_ghost += has_ghost;
    const double *X = q->x + 2 * p;
    double want_s[6] = {1, 0, 0, 0, 0, 0}, want_r[6] = {X[0], 1, 0, 0, 0, 0},
           want_z[6] = {X[1], 0, 1, 0, 0, 0};
    for (int d = 0; d < 6; d++) {
      double e =
          fmax(fabs(sum[d] - want_s[d]), fmax(fabs(rr[d] - want_r[d]), fabs(zz[d] - want_z[d])));
      /* second-derivative rows are O(1/h^2) per entry: scale their error by h^2 */
      double h2 = d >= 3 ? 0.05 * 0.05 : 1.0;
      if (e * h2 > worst) worst = e * h2;
    }
    intR += q->w[p] * rr[0];
  }
  printf("# tables: worst reproduction error %.2e, points seeing ghosts %d\n", worst,
         near_axis_with_ghost);
  /* LME reproduces affine fields to the Newton tolerance (1e-14 h) times the
   * conditioning of the table rows: 1e-10 leaves a wide margin */
  assert_true(worst <= 1e-10);
  assert_true(near_axis_with_ghost > 0);
  /* int R dR dZ = LR^2/2 * 2 LZ, exact: affine reproduction + exact rule */
  double ex = 0.5 * np.LR * np.LR * 2 * np.LZ;
  assert_true(fabs(intR - ex) <= 1e-11 * ex);
  ves_quad_destroy(&q);
  ves_nodes_destroy(&nodes);
}

/* ves_quad_tables with the thread count at k. */
static ves_status tables_on(int k, ves_quad *q, const ves_nodes *nodes, const ves_lme_params *lp,
                            ves_quad_info *info) {
  const int was = omp_get_max_threads();
  omp_set_num_threads(k);
  ves_status s = ves_quad_tables(q, nodes, lp, info);
  omp_set_num_threads(was);
  return s;
}

/* The tables are those of the straightforward construction, bit for bit, for
 * 1, 2 and 3 threads: at every point a query of its own, neighbours in
 * increasing extended index, ghosts folded, and ves_lme_eval with lambda
 * passed from point to point of a triangle, 0 at its first (for points
 * without triangles, 0 at every point). A point outside the nodes' hull
 * fails with the same status for any thread count, leaving no tables.
 * ves_quad_field gives the same values with 1 and 2 threads.
 * Kept whole (100 lines): one scenario whose checks build on each other. */
static void test_tables_threads(void **state) {
  (void)state;
  double eps = 0.1;
  ves_nodes_params np;
  ves_nodes_params_default(&np);
  np.LR = 1.5;
  np.LZ = 1.5;
  np.h = sphere_h;
  np.h_ctx = &eps;
  ves_nodes *nodes = NULL;
  assert_int_equal(ves_nodes_generate(&np, &nodes), VES_OK);
  ves_lme_params lp;
  ves_lme_params_default(&lp);
  lp.gamma = 0.8; /* the paper's, the value this test's bounds are set for */
  const int n = nodes->n, ne = n + nodes->ng;
  double *xe = malloc(2 * (size_t)ne * sizeof *xe), *rad = malloc((size_t)ne * sizeof *rad);
  double *beta_e = malloc((size_t)ne * sizeof *beta_e);
  int *idx = malloc((size_t)ne * sizeof *idx);
  assert_true(xe && rad && beta_e && idx);
  ves_nodes_extended(nodes, xe);
  for (int a = 0; a < ne; a++) {
    const double h = nodes->h[a < n ? a : nodes->ghost_of[a - n]];
    rad[a] = ves_lme_radius(&lp, h), beta_e[a] = lp.gamma / (h * h);
  }
  ves_geom_search *sr = NULL;
  assert_int_equal(ves_geom_search_create(ne, xe, rad, &sr), VES_OK);
  for (int set = 0; set < 2; set++) { /* triangles, then the points at the nodes */
    ves_quad *q[3] = {NULL, NULL, NULL};
    for (int k = 0; k < 3; k++) {
      assert_int_equal(set ? ves_quad_create_at_nodes(nodes, q + k) : ves_quad_create(nodes, q + k),
                       VES_OK);
      ves_quad_info info;
      assert_int_equal(tables_on(k + 1, q[k], nodes, &lp, &info), VES_OK);
      if (k == 0)
        printf("# tables (%s): %d points, m mean %.1f, Newton mean %.2f\n",
               set ? "at the nodes" : "triangles", q[0]->nq, info.m_mean, info.iter_mean);
    }
    const ves_quad *q0 = q[0];
    const size_t nnz = (size_t)q0->ptr[q0->nq];
    for (int k = 1; k < 3; k++) {
      assert_memory_equal(q[k]->ptr, q0->ptr, ((size_t)q0->nq + 1) * sizeof *q0->ptr);
      assert_memory_equal(q[k]->nbr, q0->nbr, nnz * sizeof *q0->nbr);
      assert_memory_equal(q[k]->mirror, q0->mirror, nnz);
      assert_memory_equal(q[k]->tab, q0->tab, 6 * nnz * sizeof *q0->tab);
    }
    /* ves_quad_field: the same values with 1 and 2 threads */
    double *cf = malloc((size_t)n * sizeof *cf), *fld[2];
    fld[0] = malloc(6 * (size_t)q0->nq * sizeof *fld[0]);
    fld[1] = malloc(6 * (size_t)q0->nq * sizeof *fld[1]);
    assert_true(cf && fld[0] && fld[1]);
    for (int a = 0; a < n; a++) cf[a] = sin(3.0 * nodes->x[2 * a]) * nodes->x[2 * a + 1];
    for (int k = 0; k < 2; k++) {
      const int was = omp_get_max_threads();
      omp_set_num_threads(k + 1);
      ves_quad_field(q0, cf, 2, fld[k]);
      omp_set_num_threads(was);
    }
    assert_memory_equal(fld[0], fld[1], 6 * (size_t)q0->nq * sizeof *fld[0]);
    free(cf), free(fld[0]), free(fld[1]);
    /* the reference construction */
    double *xa = malloc(2 * (size_t)ne * sizeof *xa), *beta = malloc((size_t)ne * sizeof *beta);
    double *work = malloc((size_t)ves_lme_work_size(ne) * sizeof *work);
    double *tab = malloc(6 * (size_t)ne * sizeof *tab);
    assert_true(xa && beta && work && tab);
    double lambda[2] = {0.0, 0.0};
    for (int p = 0; p < q0->nq; p++) {
      int c = -1;
      assert_int_equal(ves_geom_search_query(sr, q0->x + 2 * p, ne, idx, &c), VES_OK);
      assert_int_equal(c, q0->ptr[p + 1] - q0->ptr[p]);
      for (int j = 0; j < c; j++) {
        const int a = idx[j];
        assert_int_equal(q0->nbr[q0->ptr[p] + j], a < n ? a : nodes->ghost_of[a - n]);
        assert_int_equal(q0->mirror[q0->ptr[p] + j], a >= n);
        xa[2 * j] = xe[2 * a], xa[2 * j + 1] = xe[2 * a + 1], beta[j] = beta_e[a];
      }
      if (set || p % VES_QUAD_NPT == 0) lambda[0] = lambda[1] = 0.0;
      assert_int_equal(ves_lme_eval(&lp, q0->x + 2 * p, c, xa, beta, lambda, 2, tab, work, NULL),
                       VES_OK);
      assert_memory_equal(tab, q0->tab + 6 * (size_t)q0->ptr[p], 6 * (size_t)c * sizeof *tab);
    }
    free(xa), free(beta), free(work), free(tab);
    for (int k = 0; k < 3; k++) ves_quad_destroy(q + k);
  }
  /* a point far outside the hull: the same failure with 1 and 2 threads */
  ves_status st[2];
  for (int k = 0; k < 2; k++) {
    ves_quad *qb = NULL;
    double x[8] = {0.5, 0.0, 0.7, 0.3, 5.0, 5.0, 0.9, -0.2}, w[4] = {1, 1, 1, 1};
    assert_int_equal(ves_quad_create_points(4, x, w, 0, NULL, &qb), VES_OK);
    st[k] = tables_on(k + 1, qb, nodes, &lp, NULL);
    assert_true(st[k] < 0);
    assert_null(qb->ptr);
    assert_null(qb->tab);
    ves_quad_destroy(&qb);
  }
  assert_int_equal(st[0], st[1]);
  ves_geom_search_destroy(&sr);
  free(xe), free(rad), free(beta_e), free(idx);
  ves_nodes_destroy(&nodes);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_rule_exact_degree4),
      cmocka_unit_test(test_rule_not_degree5),
      cmocka_unit_test(test_rule_composite),
      cmocka_unit_test(test_triangulation_area),
      cmocka_unit_test(test_errors),
      cmocka_unit_test(test_tables),
      cmocka_unit_test(test_tables_threads),
  };
  // clang-format on
  return cmocka_run_group_tests_name("quad", tests, NULL, NULL);
}
