/* vesica — tests of the ldl module: the MUMPS LDL^T / Cholesky solver
 * (against dense LAPACK) and its GMRES-refined single-precision solves. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ves/ldl.h"
#include "numeric_impl.h"

/* Lower triplets of the dense symmetric A[n*n] (entries with |A_ij| > 0, j <= i).
 * Returns the count; arrays sized n(n+1)/2 by the caller. */
static int dense_to_lower(int n, const double *A, int *ir, int *jc, double *v) {
  int nnz = 0;
  for (int i = 0; i < n; i++)
    for (int j = 0; j <= i; j++)
      if (A[i * n + j] != 0.0) ir[nnz] = i, jc[nnz] = j, v[nnz++] = A[i * n + j];
  return nnz;
}

/* Split the triplet (i, j) in two: f of its value and the rest (the
 * factorizations sum duplicates). Returns the new count (room for one more
 * triplet given by the caller). */
static int split_entry(int nnz, int *ir, int *jc, double *v, int i, int j, double f) {
  for (int k = 0; k < nnz; k++)
    if (ir[k] == i && jc[k] == j) {
      const double rest = v[k] - f * v[k];
      v[k] *= f;
      ir[nnz] = i, jc[nnz] = j, v[nnz] = rest;
      return nnz + 1;
    }
  return nnz;
}

/* A sparse SPD matrix, Gershgorin-bounded: symmetric random off-diagonal
 * entries in [-1, 1] on ~ 40% of the pairs, diagonal = row sum of |offdiag| +
 * 1 + U[0, 1]. Eigenvalues lie in [min(d_i - R_i), max(d_i + R_i)] with
 * R_i the off-diagonal row sum: returns that bound on cond_2(A). */
static double make_spd(int n, double *A, uint64_t *seed) {
  memset(A, 0, (size_t)n * n * sizeof *A);
  for (int i = 0; i < n; i++)
    for (int j = 0; j < i; j++)
      if (urand(seed) < 0.4) A[i * n + j] = A[j * n + i] = 2.0 * urand(seed) - 1.0;
  double lo = INFINITY, hi = 0.0;
  for (int i = 0; i < n; i++) {
    double R = 0.0;
    for (int j = 0; j < n; j++)
      if (j != i) R += fabs(A[i * n + j]);
    A[i * n + i] = R + 1.0 + urand(seed);
    lo = fmin(lo, A[i * n + i] - R);
    hi = fmax(hi, A[i * n + i] + R);
  }
  return hi / lo;
}

/* ---- ves_ldl ---- */

/* SPD: MUMPS Cholesky against LAPACK dpotrf/dpotrs, with one entry split
 * into two triplets (MUMPS sums duplicates). */
static void test_ldl_spd_vs_lapack(void **state) {
  (void)state;
  enum { N = 12 };
  uint64_t seed = 2024;
  double A[N * N], L[N * N], x[N], xl[N];
  double cond = make_spd(N, A, &seed);
  int ir[N * (N + 1) / 2 + 1], jc[N * (N + 1) / 2 + 1];
  double v[N * (N + 1) / 2 + 1];
  int nnz = dense_to_lower(N, A, ir, jc, v);
  nnz = split_entry(nnz, ir, jc, v, 3, 3, 0.5); /* the diagonal entry (3, 3) in two halves */
  for (int i = 0; i < N; i++) xl[i] = x[i] = sin(1.0 + i);
  ves_ldl *f = NULL;
  assert_int_equal(ves_ldl_create(N, nnz, ir, jc, 1, &f), VES_OK);
  assert_int_equal(ves_ldl_size(f), N);
  assert_int_equal(ves_ldl_factor(f, v), VES_OK);
  assert_int_equal(ves_ldl_solve(f, x), VES_OK);
  ves_ldl_info info;
  ves_ldl_get_info(f, &info);
  assert_int_equal(info.infog1, 0);
  assert_int_equal(info.neg_pivots, 0);
  assert_true(info.factor_entries >= N);
  memcpy(L, A, sizeof A);
  assert_int_equal(LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'L', N, L, N), 0);
  assert_int_equal(LAPACKE_dpotrs(LAPACK_ROW_MAJOR, 'L', N, 1, L, N, xl, 1), 0);
  double d[N];
  for (int i = 0; i < N; i++) d[i] = x[i] - xl[i];
  double err = norm2(N, d) / norm2(N, xl);
  printf("# spd: cond bound %.2f, |x_mumps - x_lapack|/|x| = %.2e\n", cond, err);
  /* both are backward stable: each solution is within ~ n u cond of the
   * exact one (forward error bound of Cholesky), so they differ by at most
   * twice that; cond is the Gershgorin bound computed above */
  assert_true(err <= 2.0 * N * U * cond);
  ves_ldl_destroy(&f);
  assert_null(f);
}

/* The bordered KKT-like matrix [K a; a^T 0] (N = NK + 1, row-major) of the
 * SPD K[NK*NK], a_i = 1 + 0.1 i (the constraint gradient). */
static void kkt_dense(int NK, const double *K, double *A) {
  const int N = NK + 1;
  memset(A, 0, (size_t)N * N * sizeof *A);
  for (int i = 0; i < NK; i++) {
    for (int j = 0; j < NK; j++) A[i * N + j] = K[i * NK + j];
    A[NK * N + i] = A[i * N + NK] = 1.0 + 0.1 * i;
  }
}

/* x against LAPACK's dsysv (Bunch-Kaufman) on the dense A x = b: *err =
 * |x - x_lapack| / |x_lapack|, *res = |A x - b| / |b|. */
static void against_dsysv(int N, const double *A, const double *b, const double *x, double *err,
                          double *res) {
  double *Ad = malloc((size_t)N * N * sizeof *Ad), *xl = malloc((size_t)N * sizeof *xl);
  double *d = malloc((size_t)N * sizeof *d), *r = malloc((size_t)N * sizeof *r);
  lapack_int *ipiv = malloc((size_t)N * sizeof *ipiv);
  assert_true(Ad && xl && d && r && ipiv);
  memcpy(Ad, A, (size_t)N * N * sizeof *Ad);
  memcpy(xl, b, (size_t)N * sizeof *xl);
  assert_int_equal(LAPACKE_dsysv(LAPACK_ROW_MAJOR, 'L', N, 1, Ad, N, ipiv, xl, 1), 0);
  for (int i = 0; i < N; i++) {
    d[i] = x[i] - xl[i];
    r[i] = -b[i];
    for (int j = 0; j < N; j++) r[i] += A[i * N + j] * x[j];
  }
  *err = norm2(N, d) / norm2(N, xl), *res = norm2(N, r) / norm2(N, b);
  free(Ad), free(xl), free(d), free(r), free(ipiv);
}

/* KKT-like [K a; a^T 0], K SPD: inertia (N, 1, 0), so one negative pivot;
 * the solution against LAPACK's dsysv (Bunch-Kaufman). */
static void test_ldl_kkt(void **state) {
  (void)state;
  enum { NK = 8, N = NK + 1 };
  uint64_t seed = 7;
  double K[NK * NK], A[N * N], b[N], x[N];
  make_spd(NK, K, &seed);
  kkt_dense(NK, K, A);
  int ir[N * N], jc[N * N];
  double v[N * N];
  int nnz = dense_to_lower(N, A, ir, jc, v);
  for (int i = 0; i < N; i++) b[i] = x[i] = cos(0.5 * i);
  ves_ldl *f = NULL;
  assert_int_equal(ves_ldl_create(N, nnz, ir, jc, 0, &f), VES_OK);
  assert_int_equal(ves_ldl_factor(f, v), VES_OK);
  assert_int_equal(ves_ldl_solve(f, x), VES_OK);
  ves_ldl_info info;
  ves_ldl_get_info(f, &info);
  assert_int_equal(info.neg_pivots, 1); /* Sylvester: one negative eigenvalue */
  double err, res;
  against_dsysv(N, A, b, x, &err, &res);
  printf("# kkt: |x - x_lapack|/|x| = %.2e, |Ax - b|/|b| = %.2e\n", err, res);
  /* O(1) entries, N = 9, and a KKT matrix of moderate conditioning (K's
   * Gershgorin bound is ~ 10, a has norm ~ 3): backward-stable residual ~ N u,
   * forward error ~ N u cond with cond << 1e3 */
  assert_true(res <= 1e-14);
  assert_true(err <= 1e-12);
  ves_ldl_destroy(&f);
}

enum { SK_NK = 40, SK_N = SK_NK + 1 };

/* The KKT system of test_ldl_kkt (K from seed 11) scaled by D = diag(10^(2
 * i / N)), cond(A) ~ 1e4 cond(K), into A (SK_N x SK_N dense), factored in
 * single precision (ves_ldl_create_prec); *cond the bound make_spd gives for
 * cond(K). The single precision solve alone leaves |b - A x0| ~ 1e-6 |b|
 * (measured 1.05e-6 for b_i = cos(i/2)), just above VES_LDL_REFINE_TOL, so
 * a solve to it needs the refinement. */
static ves_ldl *scaled_kkt_single(double *A, double *cond) {
  uint64_t seed = 11;
  static double K[SK_NK * SK_NK], v[SK_N * SK_N];
  static int ir[SK_N * SK_N], jc[SK_N * SK_N];
  *cond = make_spd(SK_NK, K, &seed);
  kkt_dense(SK_NK, K, A);
  for (int i = 0; i < SK_N; i++)
    for (int j = 0; j < SK_N; j++) A[i * SK_N + j] *= pow(10.0, 2.0 * (i + j) / SK_N);
  int nnz = dense_to_lower(SK_N, A, ir, jc, v);
  ves_ldl *f = NULL;
  assert_int_equal(ves_ldl_create_prec(SK_N, nnz, ir, jc, 0, 1, &f), VES_OK);
  assert_int_equal(ves_ldl_factor(f, v), VES_OK);
  return f;
}

/* Single precision factors (ves_ldl_create_prec): the same KKT system as
 * test_ldl_kkt, scaled, factored in single precision and refined in
 * double. */
static void test_ldl_single_kkt(void **state) {
  (void)state;
  enum { N = SK_N };
  static double A[N * N];
  double b[N], x[N], cond;
  ves_ldl *f = scaled_kkt_single(A, &cond);
  for (int i = 0; i < N; i++) b[i] = x[i] = cos(0.5 * i);
  assert_int_equal(ves_ldl_solve(f, x), VES_OK);
  ves_ldl_info info;
  ves_ldl_get_info(f, &info);
  assert_int_equal(info.neg_pivots, 1);
  assert_int_equal(info.fallbacks, 0);
  assert_true(info.refinements >= 1 && info.refinements <= 4); /* GMRES iterations */
  double err, res;
  against_dsysv(N, A, b, x, &err, &res);
  printf("# single kkt: %d corrections, |x - x_lapack|/|x| = %.2e, |Ax - b|/|b| = %.2e "
         "(cond(K) <= %.0f)\n",
         info.refinements, err, res, cond);
  /* the refinement stops at |r| <= 1e-6 |b| (ldl.c); the forward error is
   * then at most cond(A) |r|/|b| (cond(A) < 1e5 here: 1e4 from D, < 10 from
   * K and the border) */
  assert_true(res <= 1e-6);
  assert_true(err <= 1e5 * res);
  ves_ldl_destroy(&f);
}

/* ves_ldl_solve_tol: the refinement stops at the tolerance asked (the
 * system of scaled_kkt_single). */
static void test_ldl_single_solve_tol(void **state) {
  (void)state;
  enum { N = SK_N };
  static double A[N * N];
  double b[N], x[N], err, res[3], cond;
  const double tols[3] = {1e-3, 1e-5, VES_LDL_REFINE_TOL};
  int refine[3];
  ves_ldl *f = scaled_kkt_single(A, &cond);
  for (int t = 0; t < 3; t++) {
    for (int i = 0; i < N; i++) b[i] = x[i] = cos(0.5 * i);
    assert_int_equal(ves_ldl_solve_tol(f, x, tols[t]), VES_OK);
    ves_ldl_info info;
    ves_ldl_get_info(f, &info);
    assert_int_equal(info.fallbacks, 0);
    refine[t] = info.refinements;
    against_dsysv(N, A, b, x, &err, &res[t]);
    printf("# solve_tol %.0e: %d GMRES iterations, |Ax - b|/|b| = %.2e\n", tols[t], refine[t],
           res[t]);
    /* the stopping test is on the GMRES recurrence's residual, which
     * differs from b - A x by the rounding of A's products (~1e-16 |A||x|,
     * |A||x|/|b| <= cond(A) < 1e5 here): a margin of 2 covers it */
    assert_true(res[t] <= 2 * tols[t]);
  }
  /* 1e-3 and 1e-5 are met by the single precision solve alone, 1e-6 is
   * not: the looser targets skip the refinement, the tighter one runs it */
  assert_int_equal(refine[0], 0);
  assert_int_equal(refine[1], 0);
  assert_true(refine[2] >= 1);
  assert_true(res[0] > VES_LDL_REFINE_TOL); /* the loose solve did stop early */
  assert_int_equal(ves_ldl_solve_tol(f, x, 0.0), VES_ERR_ARG);
  assert_int_equal(ves_ldl_solve_tol(f, x, 1.0), VES_ERR_ARG);
  ves_ldl_destroy(&f);
}

/* A matrix single precision represents badly: [1 c; c 1], c = 1 - 1e-7,
 * eigenvalues 2 and 1e-7; rounded to float, c becomes 1 - 1.19e-7, the small
 * eigenvalue 19% off, so plain iterative refinement gains only a factor
 * ~0.2 a correction (it needed more than 4 and fell back to double). The
 * refinement's GMRES minimizes over the Krylov space, whose dimension is 2
 * here: it converges in at most 2 iterations without a fallback. */
static void test_ldl_single_gmres(void **state) {
  (void)state;
  const double c = 1.0 - 1e-7;
  int ir[3] = {0, 1, 1}, jc[3] = {0, 0, 1};
  double v[3] = {1.0, c, 1.0}, x[2] = {1.0, -1.0};
  ves_ldl *f = NULL;
  assert_int_equal(ves_ldl_create_prec(2, 3, ir, jc, 0, 1, &f), VES_OK);
  assert_int_equal(ves_ldl_factor(f, v), VES_OK);
  assert_int_equal(ves_ldl_solve(f, x), VES_OK);
  ves_ldl_info info;
  ves_ldl_get_info(f, &info);
  printf("# single [1 c; c 1]: %d GMRES iterations, %d fallbacks\n", info.refinements,
         info.fallbacks);
  assert_int_equal(info.fallbacks, 0);
  assert_true(info.refinements >= 1 && info.refinements <= 2);
  /* exact: x = (1, -1) / (1 - c) = (1e7, -1e7); the refinement stops at
   * |r| <= 1e-6 |b|, and the error along the small eigenvector is |r| / 1e-7
   * at most: relative to |x| = 1e7 sqrt 2, 1e-6 |b| / 1e-7 / 1e7 = 1e-6 */
  const double xe = 1.0 / (1.0 - c);
  assert_true(fabs(x[0] - xe) <= 2e-6 * xe && fabs(x[1] + xe) <= 2e-6 * xe);
  ves_ldl_destroy(&f);
}

/* Single precision LDL^T runs without numerical pivoting (ldl.c,
 * LDL_SINGLE_PIVOT): [0 1; 1 0] meets a zero pivot in any order, so the
 * single factorization fails and is redone in double precision, which
 * pivots (a 2 x 2 pivot): one fallback, one negative pivot (the
 * eigenvalues are +-1), and x = (3, 2) for b = (2, 3), exact in double. */
static void test_ldl_single_zero_pivot(void **state) {
  (void)state;
  int ir[3] = {0, 1, 1}, jc[3] = {0, 0, 1};
  double v[3] = {0.0, 1.0, 0.0}, x[2] = {2.0, 3.0};
  ves_ldl *f = NULL;
  assert_int_equal(ves_ldl_create_prec(2, 3, ir, jc, 0, 1, &f), VES_OK);
  assert_int_equal(ves_ldl_factor(f, v), VES_OK);
  ves_ldl_info info;
  ves_ldl_get_info(f, &info);
  printf("# single [0 1; 1 0]: %d fallbacks, %d negative pivots\n", info.fallbacks,
         info.neg_pivots);
  assert_int_equal(info.fallbacks, 1);
  assert_int_equal(info.neg_pivots, 1);
  assert_int_equal(ves_ldl_solve(f, x), VES_OK);
  assert_true(fabs(x[0] - 3.0) <= 1e-15 && fabs(x[1] - 2.0) <= 1e-15);
  ves_ldl_destroy(&f);
}

/* A = Q diag(lam) Q^T (Q a product of 4 random Householder reflections),
 * N = 80, whose first nsmall eigenvalues are +-[1e-8, 1e-7] and the others
 * in [1, 2]: rounding A's O(1) entries to float moves the small ones by
 * ~6e-8, so single precision factors are a poor preconditioner in ~nsmall
 * directions. Solves A x = b with single precision factors; *res = |Ax -
 * b| / |b| against LAPACK's dsysv. */
static void scrambled_solve(int nsmall, ves_ldl_info *info, double *res) {
  enum { N = 80 };
  static double A[N * N], Q[N * N], v[N * N];
  static int ir[N * N], jc[N * N];
  double b[N], x[N], u[N], lam[N], err;
  uint64_t seed = 5;
  for (int i = 0; i < N; i++) {
    lam[i] = i < nsmall ? (i % 2 ? -1 : 1) * (1e-8 + 9e-8 * urand(&seed)) : 1.0 + urand(&seed);
    for (int j = 0; j < N; j++) Q[i * N + j] = i == j;
  }
  for (int h = 0; h < 4; h++) { /* Q <- Q (I - 2 u u^T) */
    double un = 0;
    for (int i = 0; i < N; i++) u[i] = 2.0 * urand(&seed) - 1.0, un += u[i] * u[i];
    for (int i = 0; i < N; i++) u[i] /= sqrt(un);
    for (int i = 0; i < N; i++) {
      double d = 0;
      for (int j = 0; j < N; j++) d += Q[i * N + j] * u[j];
      for (int j = 0; j < N; j++) Q[i * N + j] -= 2.0 * d * u[j];
    }
  }
  for (int i = 0; i < N; i++)
    for (int j = i; j < N; j++) {
      double sum = 0;
      for (int l = 0; l < N; l++) sum += Q[i * N + l] * lam[l] * Q[j * N + l];
      A[i * N + j] = A[j * N + i] = sum;
    }
  const int nnz = dense_to_lower(N, A, ir, jc, v);
  for (int i = 0; i < N; i++) b[i] = x[i] = cos(0.3 * i);
  ves_ldl *f = NULL;
  assert_int_equal(ves_ldl_create_prec(N, nnz, ir, jc, 0, 1, &f), VES_OK);
  assert_int_equal(ves_ldl_factor(f, v), VES_OK);
  assert_int_equal(ves_ldl_solve(f, x), VES_OK);
  ves_ldl_get_info(f, info);
  against_dsysv(N, A, b, x, &err, res);
  printf("# single, %d scrambled eigenvalues: %d GMRES iterations, %d fallbacks, |Ax - b|/|b| = "
         "%.2e\n",
         nsmall, info->refinements, info->fallbacks, *res);
  ves_ldl_destroy(&f);
}

/* 14 scrambled directions: the refinement's GMRES needs about as many
 * iterations (measured 28 with OpenBLAS's SkylakeX and Haswell kernels, one
 * restart of LDL_GMRES_M = 20; 18 with its Prescott kernels) and reaches
 * |r| <= 1e-6 |b| without the double fallback (plain iterative refinement,
 * contracting by |I - A M^-1| >= 1 in those directions, could not). */
static void test_ldl_single_restart(void **state) {
  (void)state;
  ves_ldl_info info;
  double res;
  scrambled_solve(14, &info, &res);
  assert_int_equal(info.fallbacks, 0);
  assert_true(info.refinements >= 10);
  /* the recurrence's residual met 1e-6 |b|; the true one differs by the
   * rounding of the double products, ~1e-16 |A| |x| ~ 1e-16 * 2 * 1e8 */
  assert_true(res <= 2e-6);
}

/* 40 scrambled directions: restarted GMRES (20 vectors a cycle) cannot
 * resolve them in its 60 iterations (measured with all three kernels above),
 * so the solve redoes the factorization in double precision: a backward
 * stable answer, |Ax - b| ~ u |A| |x| ~ 1e-16 * 2 * 1e8. */
static void test_ldl_single_solve_fallback(void **state) {
  (void)state;
  ves_ldl_info info;
  double res;
  scrambled_solve(40, &info, &res);
  assert_int_equal(info.fallbacks, 1);
  assert_int_equal(info.single, 0);
  assert_true(res <= 1e-7);
}

/* Values float cannot hold: 1e39 overflows to inf. The factorization is
 * done in double precision (info.fallbacks 1) and the answer is double's;
 * the next factorization of representable values is single again (its
 * solve refined, no new fallback). */
static void test_ldl_single_fallback(void **state) {
  (void)state;
  int ir[3] = {0, 1, 1}, jc[3] = {0, 0, 1};
  double v[3] = {1e39, 1.0, 2.0}, x[2] = {1e39, 1.0};
  ves_ldl *f = NULL;
  assert_int_equal(ves_ldl_create_prec(2, 3, ir, jc, 0, 1, &f), VES_OK);
  assert_int_equal(ves_ldl_factor(f, v), VES_OK);
  assert_int_equal(ves_ldl_solve(f, x), VES_OK);
  ves_ldl_info info;
  ves_ldl_get_info(f, &info);
  assert_int_equal(info.fallbacks, 1);
  assert_int_equal(info.single, 0);
  /* [1e39 1; 1 2] x = (1e39, 1): x = (1 - 5e-40, 5e-40), i.e. (1, 0) to
   * rounding: double precision's LDL^T pivots on 1e39 and solves exactly up
   * to u = 1.1e-16 */
  assert_true(fabs(x[0] - 1.0) <= 1e-15);
  assert_true(fabs(x[1]) <= 1e-15);
  double w[3] = {4.0, 1.0, 3.0}, y[2] = {5.0, 4.0}; /* [4 1; 1 3] y = (5, 4): y = (1, 1) */
  assert_int_equal(ves_ldl_factor(f, w), VES_OK);
  assert_int_equal(ves_ldl_solve(f, y), VES_OK);
  ves_ldl_get_info(f, &info);
  assert_int_equal(info.fallbacks, 1);
  assert_int_equal(info.single, 1);
  /* single precision factors of a matrix of condition 2.6: the float solve
   * is within ~1e-7 and one refinement iteration at most brings it to 1e-6
   * |b| (ldl.c) */
  assert_true(info.refinements <= 1);
  assert_true(fabs(y[0] - 1.0) <= 1e-6 && fabs(y[1] - 1.0) <= 1e-6);
  ves_ldl_destroy(&f);
}

/* New values on the same pattern: the second factorization must not see the
 * first (A2 = 3 A1 + diag shift changes the solution non-trivially). */
static void test_ldl_refactor(void **state) {
  (void)state;
  enum { N = 10 };
  uint64_t seed = 99;
  double A[N * N], x[N], b[N];
  make_spd(N, A, &seed);
  int ir[N * N], jc[N * N];
  double v[N * N], v2[N * N];
  int nnz = dense_to_lower(N, A, ir, jc, v);
  ves_ldl *f = NULL;
  assert_int_equal(ves_ldl_create(N, nnz, ir, jc, 1, &f), VES_OK);
  for (int rep = 0; rep < 3; rep++) {
    double scale = 1.0 + rep, shift = 0.5 * rep;
    for (int k = 0; k < nnz; k++) v2[k] = scale * v[k] + (ir[k] == jc[k] ? shift : 0.0);
    assert_int_equal(ves_ldl_factor(f, v2), VES_OK);
    for (int i = 0; i < N; i++) b[i] = x[i] = 1.0 / (1.0 + i);
    assert_int_equal(ves_ldl_solve(f, x), VES_OK);
    double r[N];
    for (int i = 0; i < N; i++) {
      r[i] = -b[i];
      for (int j = 0; j < N; j++) r[i] += (scale * A[i * N + j] + (i == j ? shift : 0.0)) * x[j];
    }
    /* backward stable, well conditioned (Gershgorin bound < 10): ~ N u */
    assert_true(norm2(N, r) <= 1e-14 * norm2(N, b));
    /* a second solve with the same factors gives the same answer */
    double y[N];
    memcpy(y, b, sizeof y);
    assert_int_equal(ves_ldl_solve(f, y), VES_OK);
    assert_memory_equal(x, y, sizeof y);
  }
  ves_ldl_destroy(&f);
}

/* Singular matrices are VES_ERR_SINGULAR with the MUMPS code kept; a failed
 * factorization leaves the analysis usable; solve without factors is refused. */
static void test_ldl_singular(void **state) {
  (void)state;
  /* [1 1; 1 1] (+ a regular third row): a zero pivot after one step */
  int ir[4] = {0, 1, 1, 2}, jc[4] = {0, 0, 1, 2};
  double sing[4] = {1, 1, 1, 1}, good[4] = {2, 1, 2, 1}, x[3] = {1, 1, 1};
  for (int spd = 1; spd >= 0; spd--) {
    ves_ldl *f = NULL;
    assert_int_equal(ves_ldl_create(3, 4, ir, jc, spd, &f), VES_OK);
    assert_int_equal(ves_ldl_solve(f, x), VES_ERR_ARG); /* not factored yet */
    assert_int_equal(ves_ldl_factor(f, sing), VES_ERR_SINGULAR);
    ves_ldl_info info;
    ves_ldl_get_info(f, &info);
    printf("# singular (spd = %d): INFOG(1) = %d, INFOG(2) = %d\n", spd, info.infog1, info.infog2);
    assert_true(info.infog1 == -10 || info.infog1 == -6);
    assert_int_equal(ves_ldl_solve(f, x), VES_ERR_ARG); /* the failed factors are not used */
    assert_int_equal(ves_ldl_factor(f, good), VES_OK);
    ves_ldl_get_info(f, &info);
    assert_int_equal(info.infog1, 0);
    assert_int_equal(ves_ldl_solve(f, x), VES_OK);
    /* [2 1; 1 2] x = 1 -> 1/3; 1 x = 1 -> 1: two or three roundings of O(1)
     * numbers, so a few 1e-16 */
    assert_true(fabs(x[0] - 1.0 / 3) < 1e-15 && fabs(x[1] - 1.0 / 3) < 1e-15);
    assert_true(fabs(x[2] - 1) < 1e-15);
    x[0] = x[1] = x[2] = 1.0;
    ves_ldl_destroy(&f);
  }
  /* spd requested but indefinite: [1 2; 2 1] has eigenvalues 3, -1 */
  int ir2[3] = {0, 1, 1}, jc2[3] = {0, 0, 1};
  double indef[3] = {1, 2, 1};
  ves_ldl *f = NULL;
  assert_int_equal(ves_ldl_create(2, 3, ir2, jc2, 1, &f), VES_OK);
  ves_status s = ves_ldl_factor(f, indef);
  ves_ldl_info info;
  ves_ldl_get_info(f, &info);
  printf("# indefinite as spd: %s, INFOG(1) = %d, INFOG(12) = %d\n", ves_status_str(s), info.infog1,
         info.neg_pivots);
  assert_int_equal(s, VES_ERR_SINGULAR);
  ves_ldl_destroy(&f);
  /* the same matrix as symmetric indefinite: fine, one negative pivot */
  assert_int_equal(ves_ldl_create(2, 3, ir2, jc2, 0, &f), VES_OK);
  assert_int_equal(ves_ldl_factor(f, indef), VES_OK);
  ves_ldl_get_info(f, &info);
  assert_int_equal(info.neg_pivots, 1);
  ves_ldl_destroy(&f);
}

static void test_ldl_errors(void **state) {
  (void)state;
  int ir[2] = {0, 1}, jc[2] = {0, 0}, up[2] = {0, 0};
  double v[2] = {1, 0};
  ves_ldl *f = (ves_ldl *)&f; /* a non-NULL value that must be overwritten */
  assert_int_equal(ves_ldl_create(0, 2, ir, jc, 1, &f), VES_ERR_ARG);
  assert_null(f);
  assert_int_equal(ves_ldl_create(2, 0, ir, jc, 1, &f), VES_ERR_ARG);
  assert_int_equal(ves_ldl_create(2, 2, NULL, jc, 1, &f), VES_ERR_ARG);
  assert_int_equal(ves_ldl_create(2, 2, ir, NULL, 1, &f), VES_ERR_ARG);
  assert_int_equal(ves_ldl_create(2, 2, ir, jc, 1, NULL), VES_ERR_ARG);
  assert_int_equal(ves_ldl_create(2, 2, up, ir, 1, &f), VES_ERR_ARG); /* (0, 1): upper */
  int out_of_range[2] = {0, 2};
  assert_int_equal(ves_ldl_create(2, 2, out_of_range, jc, 1, &f), VES_ERR_ARG);
  int negative[2] = {0, -1};
  assert_int_equal(ves_ldl_create(2, 2, ir, negative, 1, &f), VES_ERR_ARG);
  assert_null(f);
  assert_int_equal(ves_ldl_factor(NULL, v), VES_ERR_ARG);
  assert_int_equal(ves_ldl_solve(NULL, v), VES_ERR_ARG);
  assert_int_equal(ves_ldl_create(2, 2, ir, jc, 1, &f), VES_OK);
  assert_int_equal(ves_ldl_factor(f, NULL), VES_ERR_ARG);
  assert_int_equal(ves_ldl_solve(f, NULL), VES_ERR_ARG);
  assert_int_equal(ves_ldl_size(NULL), 0);
  ves_ldl_destroy(&f);
  assert_null(f);
  ves_ldl_destroy(&f);
  ves_ldl_destroy(NULL);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_ldl_spd_vs_lapack), cmocka_unit_test(test_ldl_kkt),
      cmocka_unit_test(test_ldl_single_kkt), cmocka_unit_test(test_ldl_single_solve_tol),
      cmocka_unit_test(test_ldl_single_gmres), cmocka_unit_test(test_ldl_single_zero_pivot),
      cmocka_unit_test(test_ldl_single_restart),
      cmocka_unit_test(test_ldl_single_solve_fallback),
      cmocka_unit_test(test_ldl_single_fallback),
      cmocka_unit_test(test_ldl_refactor),      cmocka_unit_test(test_ldl_singular),
      cmocka_unit_test(test_ldl_errors),
  };
  // clang-format on
  return cmocka_run_group_tests(tests, NULL, NULL);
}
