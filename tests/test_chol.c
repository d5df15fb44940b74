/* vesica — tests of the chol module: the exact sparse Cholesky factor
 * G G^T = M (CHOLMOD) and its half solves, against the matrix itself. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ves/chol.h"
#include "numeric_impl.h"

/* y = M x, M by its lower triplets (duplicates summed), scaled by 1 + alpha
 * on the diagonal. */
static void lower_matvec(int n, int nnz, const int *ir, const int *jc, const double *v,
                         double alpha, const double *x, double *y) {
  memset(y, 0, (size_t)n * sizeof *y);
  for (int k = 0; k < nnz; k++) {
    const int i = ir[k], j = jc[k];
    if (i == j) {
      y[i] += (1.0 + alpha) * v[k] * x[i];
    } else {
      y[i] += v[k] * x[j];
      y[j] += v[k] * x[i];
    }
  }
}

/* The checks of a factor of M + alpha diag(M) on random vectors a, b:
 * M G^{-T} G^{-1} a = a (relative to |a|, bounded by cond eps), and
 * <G^{-1} a, b> = <a, G^{-T} b> (the two half solves are transposes). */
static void check_factor(ves_chol *F, int n, int nnz, const int *ir, const int *jc, const double *v,
                         double alpha, double cond, uint64_t *seed) {
  double *a = malloc((size_t)n * sizeof *a), *b = malloc((size_t)n * sizeof *b);
  double *y = malloc((size_t)n * sizeof *y), *z = malloc((size_t)n * sizeof *z);
  double *ga = malloc((size_t)n * sizeof *ga), *gb = malloc((size_t)n * sizeof *gb);
  assert_non_null(a), assert_non_null(b), assert_non_null(y), assert_non_null(z);
  assert_non_null(ga), assert_non_null(gb);
  for (int i = 0; i < n; i++) a[i] = 2 * urand(seed) - 1, b[i] = 2 * urand(seed) - 1;
  memcpy(y, a, (size_t)n * sizeof *y);
  assert_int_equal(ves_chol_lsolve(F, y), VES_OK);
  memcpy(ga, y, (size_t)n * sizeof *y);
  assert_int_equal(ves_chol_ltsolve(F, y), VES_OK);
  lower_matvec(n, nnz, ir, jc, v, alpha, y, z);
  double res = 0.0;
  for (int i = 0; i < n; i++) res = fmax(res, fabs(z[i] - a[i]));
  memcpy(gb, b, (size_t)n * sizeof *gb);
  assert_int_equal(ves_chol_ltsolve(F, gb), VES_OK);
  double s1 = 0.0, s2 = 0.0, m1 = 0.0, m2 = 0.0;
  for (int i = 0; i < n; i++) {
    s1 += ga[i] * b[i], s2 += a[i] * gb[i];
    m1 += fabs(ga[i] * b[i]), m2 += fabs(a[i] * gb[i]);
  }
  printf("# n %d: |M G^-T G^-1 a - a| = %.2e (cond <= %.1f), <G^-1 a, b> - <a, G^-T b> = %.2e"
         " of %.2e, L entries %zu\n",
         n, res, cond, fabs(s1 - s2), fmax(m1, m2), ves_chol_factor_entries(F));
  /* backward stable Cholesky: residual <= c n u |M| |y| ~ cond u |a|, with
   * the constant 100 for n up to a few thousand (measured: below 1e-14) */
  assert_true(res <= 100 * cond * U);
  /* two triangular solves, each backward stable: both sums to n u their
   * absolute sums */
  assert_true(fabs(s1 - s2) <= 4 * n * U * fmax(m1, m2));
  free(a), free(b), free(y), free(z), free(ga), free(gb);
}

/* A random sparse SPD matrix of order n by its lower triplets
 * (Gershgorin-bounded: off-diagonal entries in [-1, 1] on ~ density of the
 * pairs, then the diagonal, entry nnz - n + i, = row sum of |offdiag| + 1 +
 * U[0, 1]); R[n] (zeroed here) gets the row sums of |offdiag|. Returns nnz. */
static int random_gershgorin(int n, double density, uint64_t *seed, int *ir, int *jc, double *v,
                             double *R) {
  int nnz = 0;
  memset(R, 0, (size_t)n * sizeof *R);
  for (int i = 0; i < n; i++)
    for (int j = 0; j < i; j++)
      if (urand(seed) < density) {
        ir[nnz] = i, jc[nnz] = j, v[nnz] = 2 * urand(seed) - 1;
        R[i] += fabs(v[nnz]), R[j] += fabs(v[nnz]);
        nnz++;
      }
  for (int i = 0; i < n; i++) ir[nnz] = jc[nnz] = i, v[nnz++] = R[i] + 1.0 + urand(seed);
  return nnz;
}

/* random_gershgorin at density 0.3, one entry split in two: the factor's
 * checks, then the shifted factor's. */
static void test_chol_random(void **state) {
  (void)state;
  enum { N = 80, MAXNZ = N * (N + 1) / 2 + 1 };
  uint64_t seed = 7;
  static int ir[MAXNZ], jc[MAXNZ];
  static double v[MAXNZ], R[N];
  int nnz = random_gershgorin(N, 0.3, &seed, ir, jc, v, R);
  double lo = INFINITY, hi = 0.0;
  for (int i = 0; i < N; i++) {
    const double d = v[nnz - N + i];
    lo = fmin(lo, d - R[i]), hi = fmax(hi, d + R[i]);
  }
  /* split an off-diagonal entry in two triplets: duplicates are summed */
  ir[nnz] = ir[0], jc[nnz] = jc[0], v[nnz] = 0.25 * v[0], v[0] *= 0.75, nnz++;
  ves_chol *F = NULL;
  assert_int_equal(ves_chol_create(N, nnz, ir, jc, &F), VES_OK);
  assert_int_equal(ves_chol_factor_entries(F), 0);
  assert_int_equal(ves_chol_factor(F, v, 0.0), VES_OK);
  assert_true(ves_chol_factor_entries(F) >= (size_t)N);
  check_factor(F, N, nnz, ir, jc, v, 0.0, hi / lo, &seed);
  /* M + diag(M): still Gershgorin-bounded, by a smaller ratio */
  assert_int_equal(ves_chol_factor(F, v, 1.0), VES_OK);
  check_factor(F, N, nnz, ir, jc, v, 1.0, hi / lo, &seed);
  ves_chol_destroy(&F);
  assert_null(F);
}

/* The 5-point Laplacian of a G x G grid plus 0.1 I (supernodal at this size
 * in CHOLMOD's choice; cond <= 8.1 / 0.1), the triplets in a scrambled
 * order. */
static void test_chol_grid(void **state) {
  (void)state;
  enum { G = 48, N = G * G, NZ = N + 2 * G * (G - 1) };
  static int ir[NZ], jc[NZ];
  static double v[NZ];
  int nnz = 0;
  for (int i = N - 1; i >= 0; i--) {
    ir[nnz] = jc[nnz] = i, v[nnz++] = 4.1;
    if (i % G > 0) ir[nnz] = i, jc[nnz] = i - 1, v[nnz++] = -1.0;
    if (i >= G) ir[nnz] = i, jc[nnz] = i - G, v[nnz++] = -1.0;
  }
  assert_int_equal(nnz, NZ);
  uint64_t seed = 11;
  ves_chol *F = NULL;
  assert_int_equal(ves_chol_create(N, nnz, ir, jc, &F), VES_OK);
  assert_int_equal(ves_chol_factor(F, v, 0.0), VES_OK);
  /* fill: more than the pattern's, far less than dense */
  assert_true(ves_chol_factor_entries(F) > (size_t)NZ);
  assert_true(ves_chol_factor_entries(F) < (size_t)N * N / 8);
  check_factor(F, N, nnz, ir, jc, v, 0.0, 8.1 / 0.1, &seed);
  /* a second factorization of new values on the same pattern */
  for (int k = 0; k < nnz; k++) v[k] *= 2.0;
  assert_int_equal(ves_chol_factor(F, v, 0.0), VES_OK);
  check_factor(F, N, nnz, ir, jc, v, 0.0, 8.1 / 0.1, &seed);
  ves_chol_destroy(&F);
}

/* Not positive definite: VES_ERR_SINGULAR, no solves until a good factor;
 * a shift or new values cure it; the diagonal is forced into the pattern. */
static void test_chol_singular(void **state) {
  (void)state;
  int ir[3] = {0, 1, 1}, jc[3] = {0, 0, 1};
  double v[3] = {1.0, 2.0, 1.0}; /* [1 2; 2 1]: eigenvalues 3, -1 */
  double x[2] = {1.0, 1.0};
  ves_chol *F = NULL;
  assert_int_equal(ves_chol_create(2, 3, ir, jc, &F), VES_OK);
  assert_int_equal(ves_chol_factor(F, v, 0.0), VES_ERR_SINGULAR);
  assert_int_equal(ves_chol_lsolve(F, x), VES_ERR_ARG);
  assert_int_equal(ves_chol_ltsolve(F, x), VES_ERR_ARG);
  assert_int_equal(ves_chol_factor_entries(F), 0);
  /* alpha = 10: [11 2; 2 11], positive definite */
  assert_int_equal(ves_chol_factor(F, v, 10.0), VES_OK);
  assert_int_equal(ves_chol_lsolve(F, x), VES_OK);
  assert_int_equal(ves_chol_ltsolve(F, x), VES_OK);
  /* y = [11 2; 2 11]^{-1} (1, 1) = (1/13, 1/13) */
  assert_true(fabs(x[0] - 1.0 / 13) <= 8 * U && fabs(x[1] - 1.0 / 13) <= 8 * U);
  double nan_v[3] = {NAN, 0.0, 1.0};
  assert_int_equal(ves_chol_factor(F, nan_v, 0.0), VES_ERR_SINGULAR);
  assert_int_equal(ves_chol_factor(F, v, -1.0), VES_ERR_ARG);
  assert_int_equal(ves_chol_factor(F, NULL, 0.0), VES_ERR_ARG);
  ves_chol_destroy(&F);
  /* no (0, 0) triplet: the diagonal slot exists, with value 0 */
  int ir2[2] = {1, 1}, jc2[2] = {0, 1};
  double v2[2] = {2.0, 1.0};
  assert_int_equal(ves_chol_create(2, 2, ir2, jc2, &F), VES_OK);
  assert_int_equal(ves_chol_factor(F, v2, 0.0), VES_ERR_SINGULAR);
  ves_chol_destroy(&F);
}

/* y = (M + sum_i s_i w_i w_i^T) x, M by its lower triplets. */
static void rank_matvec(int n, int nnz, const int *ir, const int *jc, const double *v, int m,
                        const double *w, const double *sw, const double *x, double *y) {
  lower_matvec(n, nnz, ir, jc, v, 0.0, x, y);
  for (int i = 0; i < m; i++) {
    double d = 0.0;
    for (int j = 0; j < n; j++) d += w[(size_t)i * n + j] * x[j];
    for (int j = 0; j < n; j++) y[j] += sw[i] * d * w[(size_t)i * n + j];
  }
}

/* The dense variant: a random Gershgorin-bounded SPD matrix A
 * (random_gershgorin at density 0.2) with two diagonal entries lowered by
 * beta, so M has (by interlacing) at most two negative eigenvalues, which
 * the rank-2 term s (w_1 w_1^T + w_2 w_2^T), w_i = e_{k_i} + 0.01 (random),
 * removes (with noise eps the negative curvature left orthogonal to w_i is
 * ~ beta eps^2 N / 18 against A's ~ 1: 0.03 here, 3 at eps 0.1). The factor
 * of M + S is checked as the sparse ones are; its half solves then serve
 * until a sparse factorization replaces it. */
static void test_chol_dense(void **state) {
  (void)state;
  enum { N = 60, MAXNZ = N * (N + 1) / 2 };
  uint64_t seed = 13;
  static int ir[MAXNZ], jc[MAXNZ];
  static double v[MAXNZ], R[N], w[2 * N];
  const int nnz = random_gershgorin(N, 0.2, &seed, ir, jc, v, R);
  const int k1 = 7, k2 = 41, d1 = nnz - N + k1, d2 = nnz - N + k2; /* their diagonal slots */
  const double beta = 100.0;
  v[d1] -= beta, v[d2] -= beta; /* M = A - beta (e_k1 e_k1^T + e_k2 e_k2^T) */
  for (int j = 0; j < 2 * N; j++) w[j] = 0.01 * (2 * urand(&seed) - 1);
  w[k1] += 1.0, w[N + k2] += 1.0;
  ves_chol *F = NULL;
  assert_int_equal(ves_chol_create(N, nnz, ir, jc, &F), VES_OK);
  /* the sparse factor of M fails, and so does the dense one without S */
  assert_int_equal(ves_chol_factor(F, v, 0.0), VES_ERR_SINGULAR);
  const double s0[2] = {0.0, 0.0}, s1[2] = {10 * beta, 10 * beta};
  int fail = 0;
  assert_int_equal(ves_chol_factor_dense(F, v, 2, w, s0, &fail), VES_ERR_SINGULAR);
  assert_true(fail >= 1 && fail <= N);
  double x[N];
  for (int i = 0; i < N; i++) x[i] = 1.0;
  assert_int_equal(ves_chol_lsolve(F, x), VES_ERR_ARG);
  assert_int_equal(ves_chol_factor_entries(F), 0);
  /* one term cures one of the two negative directions only */
  assert_int_equal(ves_chol_factor_dense(F, v, 1, w, s1, &fail), VES_ERR_SINGULAR);
  assert_int_equal(ves_chol_factor_dense(F, v, 2, w, s1, &fail), VES_OK);
  assert_int_equal(fail, 0);
  assert_int_equal(ves_chol_factor_entries(F), (size_t)N * (N + 1) / 2);
  /* the checks of check_factor on M + S: y = G^{-T} G^{-1} a solves
   * (M + S) y = a backward stably, |(M + S) y - a| <= c N u |M + S| |y| (c
   * = 4; the row sums of |M| and |S| bound |M + S|), and the two half solves
   * are transposes */
  double a[N], y[N], z[N], ga[N], b[N], gb[N];
  for (int i = 0; i < N; i++) a[i] = 2 * urand(&seed) - 1, b[i] = 2 * urand(&seed) - 1;
  memcpy(y, a, sizeof y);
  assert_int_equal(ves_chol_lsolve(F, y), VES_OK);
  memcpy(ga, y, sizeof y);
  assert_int_equal(ves_chol_ltsolve(F, y), VES_OK);
  rank_matvec(N, nnz, ir, jc, v, 2, w, s1, y, z);
  double res = 0.0, s1d = 0.0, s2d = 0.0, m1 = 0.0, m2 = 0.0;
  double ymax = 0.0, nrm = 0.0, rs[N] = {0}, wsum[2] = {0.0, 0.0};
  for (int i = 0; i < N; i++) res = fmax(res, fabs(z[i] - a[i])), ymax = fmax(ymax, fabs(y[i]));
  for (int k = 0; k < nnz; k++) {
    rs[ir[k]] += fabs(v[k]);
    if (ir[k] != jc[k]) rs[jc[k]] += fabs(v[k]);
  }
  for (int t = 0; t < 2; t++)
    for (int j = 0; j < N; j++) wsum[t] += fabs(w[t * N + j]);
  for (int i = 0; i < N; i++)
    nrm = fmax(nrm, rs[i] + s1[0] * fabs(w[i]) * wsum[0] + s1[1] * fabs(w[N + i]) * wsum[1]);
  memcpy(gb, b, sizeof gb);
  assert_int_equal(ves_chol_ltsolve(F, gb), VES_OK);
  for (int i = 0; i < N; i++) {
    s1d += ga[i] * b[i], s2d += a[i] * gb[i];
    m1 += fabs(ga[i] * b[i]), m2 += fabs(a[i] * gb[i]);
  }
  printf("# dense n %d: |(M + S) G^-T G^-1 a - a| = %.2e of |M + S| |y| = %.2e,"
         " <G^-1 a, b> - <a, G^-T b> = %.2e\n",
         N, res, nrm * ymax, fabs(s1d - s2d));
  assert_true(res <= 4 * N * U * nrm * ymax);
  assert_true(fabs(s1d - s2d) <= 4 * N * U * fmax(m1, m2));
  /* a sparse factorization replaces the dense one (of A itself: cond <=
   * 1e3 is loose for a Gershgorin-bounded A with diagonal excess >= 1) */
  v[d1] += beta, v[d2] += beta;
  assert_int_equal(ves_chol_factor(F, v, 0.0), VES_OK);
  check_factor(F, N, nnz, ir, jc, v, 0.0, 1e3, &seed);
  ves_chol_destroy(&F);
}

/* lsolve_cols: k columns at once equal k single solves (to rounding: the
 * batched kernels sum in another order), for a sparse and a dense factor;
 * the fill of the grid's factor is far from dense, the random one's is not
 * above 1. */
static void test_chol_cols(void **state) {
  (void)state;
  enum { G = 24, N = G * G, NZ = N + 2 * G * (G - 1), K = 3 };
  static int ir[NZ], jc[NZ];
  static double v[NZ], V[K * N], X[K * N], w[N];
  int nnz = 0;
  for (int i = 0; i < N; i++) {
    ir[nnz] = jc[nnz] = i, v[nnz++] = 4.1;
    if (i % G > 0) ir[nnz] = i, jc[nnz] = i - 1, v[nnz++] = -1.0;
    if (i >= G) ir[nnz] = i, jc[nnz] = i - G, v[nnz++] = -1.0;
  }
  uint64_t seed = 17;
  for (int j = 0; j < K * N; j++) V[j] = 2 * urand(&seed) - 1;
  for (int j = 0; j < N; j++) w[j] = urand(&seed);
  ves_chol *F = NULL;
  assert_int_equal(ves_chol_create(N, nnz, ir, jc, &F), VES_OK);
  const double fill = ves_chol_fill(F);
  printf("# grid %d: fill %.3f\n", N, fill);
  assert_true(fill > 0.0 && fill < 0.25);
  assert_true(ves_chol_fill(NULL) == 0.0);
  const double sw = 1.0;
  for (int dense = 0; dense < 2; dense++) {
    if (dense)
      assert_int_equal(ves_chol_factor_dense(F, v, 1, w, &sw, NULL), VES_OK);
    else
      assert_int_equal(ves_chol_factor(F, v, 0.0), VES_OK);
    memcpy(X, V, sizeof X);
    assert_int_equal(ves_chol_lsolve_cols(F, K, X), VES_OK);
    double d = 0.0, mx = 0.0;
    for (int c = 0; c < K; c++) {
      double y[N];
      memcpy(y, V + c * N, sizeof y);
      assert_int_equal(ves_chol_lsolve(F, y), VES_OK);
      for (int i = 0; i < N; i++) d = fmax(d, fabs(y[i] - X[c * N + i])), mx = fmax(mx, fabs(y[i]));
    }
    printf("# %s: k columns against k solves: %.2e of %.2e\n", dense ? "dense" : "sparse", d, mx);
    /* two backward stable solves of the same system: their difference is
     * within the condition number (<= 8.1 / 0.1 + N for the dense w w^T)
     * times u of the answer */
    assert_true(d <= 4 * (81.0 + N) * U * mx);
  }
  assert_int_equal(ves_chol_lsolve_cols(F, 0, X), VES_ERR_ARG);
  assert_int_equal(ves_chol_lsolve_cols(NULL, 1, X), VES_ERR_ARG);
  ves_chol_destroy(&F);
}

static void test_chol_errors(void **state) {
  (void)state;
  int ir[2] = {0, 1}, jc[2] = {0, 0}, up[2] = {0, 1}, big[2] = {0, 2}, neg[2] = {0, -1};
  ves_chol *F = (ves_chol *)&F; /* a non-NULL value that must be overwritten */
  assert_int_equal(ves_chol_create(0, 2, ir, jc, &F), VES_ERR_ARG);
  assert_null(F);
  assert_int_equal(ves_chol_create(2, -1, ir, jc, &F), VES_ERR_ARG);
  assert_int_equal(ves_chol_create(2, 2, NULL, jc, &F), VES_ERR_ARG);
  assert_int_equal(ves_chol_create(2, 2, ir, NULL, &F), VES_ERR_ARG);
  assert_int_equal(ves_chol_create(2, 2, ir, jc, NULL), VES_ERR_ARG);
  assert_int_equal(ves_chol_create(2, 2, jc, up, &F), VES_ERR_ARG); /* (0, 1): upper */
  assert_int_equal(ves_chol_create(2, 2, big, jc, &F), VES_ERR_ARG);
  assert_int_equal(ves_chol_create(2, 2, ir, neg, &F), VES_ERR_ARG);
  assert_null(F);
  assert_int_equal(ves_chol_factor(NULL, NULL, 0.0), VES_ERR_ARG);
  assert_int_equal(ves_chol_lsolve(NULL, NULL), VES_ERR_ARG);
  assert_int_equal(ves_chol_ltsolve(NULL, NULL), VES_ERR_ARG);
  assert_int_equal(ves_chol_factor_entries(NULL), 0);
  {
    double val[2] = {1.0, 0.0}, ww[2] = {1.0, 0.0}, sneg = -1.0, snan = NAN, sok = 1.0;
    assert_int_equal(ves_chol_create(2, 2, ir, jc, &F), VES_OK);
    assert_int_equal(ves_chol_factor_dense(NULL, val, 1, ww, &sok, NULL), VES_ERR_ARG);
    assert_int_equal(ves_chol_factor_dense(F, NULL, 1, ww, &sok, NULL), VES_ERR_ARG);
    assert_int_equal(ves_chol_factor_dense(F, val, -1, ww, &sok, NULL), VES_ERR_ARG);
    assert_int_equal(ves_chol_factor_dense(F, val, 1, NULL, &sok, NULL), VES_ERR_ARG);
    assert_int_equal(ves_chol_factor_dense(F, val, 1, ww, NULL, NULL), VES_ERR_ARG);
    assert_int_equal(ves_chol_factor_dense(F, val, 1, ww, &sneg, NULL), VES_ERR_ARG);
    assert_int_equal(ves_chol_factor_dense(F, val, 1, ww, &snan, NULL), VES_ERR_ARG);
    /* [1 0; 0 0] + 0: the second pivot fails */
    int fail = 0;
    assert_int_equal(ves_chol_factor_dense(F, val, 0, NULL, NULL, &fail), VES_ERR_SINGULAR);
    assert_int_equal(fail, 2);
    ves_chol_destroy(&F);
  }
  /* the diagonal alone: M = 0 is not positive definite */
  assert_int_equal(ves_chol_create(2, 0, NULL, NULL, &F), VES_OK);
  assert_int_equal(ves_chol_factor(F, NULL, 0.0), VES_ERR_SINGULAR);
  ves_chol_destroy(&F);
  assert_null(F);
  ves_chol_destroy(&F);
  ves_chol_destroy(NULL);
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_chol_random),   cmocka_unit_test(test_chol_grid),
      cmocka_unit_test(test_chol_singular), cmocka_unit_test(test_chol_dense),
      cmocka_unit_test(test_chol_cols),     cmocka_unit_test(test_chol_errors),
  };
  return cmocka_run_group_tests(tests, NULL, NULL);
}
