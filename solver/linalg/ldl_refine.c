/* vesica — the solves of the direct solver: with double precision factors
 * one MUMPS solve; with single precision factors M, x0 = M^-1 b refined
 * against the double values by flexible GMRES right-preconditioned by M,
 *   x = x0 + Z_k y,  z_i = M^-1 v_i,  y = argmin |beta e_1 - H_k y|,
 * to |b - A x| <= tol |b| (docs/design.md, "Numerical choices and why"). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "linalg/ldl_impl.h"

/* y <- A x for the symmetric A of the lower triplets (double values): the
 * triplets in LDL_MATVEC_CHUNKS fixed chunks, each summed into its own
 * vector (the chunks shared out over the OpenMP threads), then the chunks
 * added in order: the same result for any thread count. */
static void matvec(ves_ldl *f, const double *x, double *y) {
  const int n = f->n, nnz = f->nnz;
  double *yc = f->yc;
#pragma omp parallel for schedule(static)
  for (int c = 0; c < LDL_MATVEC_CHUNKS; c++) {
    double *u = yc + (size_t)c * n;
    memset(u, 0, (size_t)n * sizeof *u);
    const int k0 = (int)((long long)nnz * c / LDL_MATVEC_CHUNKS),
              k1 = (int)((long long)nnz * (c + 1) / LDL_MATVEC_CHUNKS);
    for (int k = k0; k < k1; k++) {
      const int i = f->irn[k] - 1, j = f->jcn[k] - 1;
      u[i] += f->a[k] * x[j];
      if (i != j) u[j] += f->a[k] * x[i];
    }
  }
  for (int i = 0; i < n; i++) {
    double v = yc[i];
    for (int c = 1; c < LDL_MATVEC_CHUNKS; c++) v += yc[(size_t)c * n + i];
    y[i] = v;
  }
}

/* x . y, summed in index order. */
static double dot(int n, const double *x, const double *y) {
  double s = 0;
  for (int i = 0; i < n; i++) s += x[i] * y[i];
  return s;
}

/* x += correction of A x = b, right-preconditioned by the single precision
 * factors M (flexible GMRES: FGMRES(LDL_GMRES_M) keeping z_k = M^-1 v_k),
 * until |b - A x| <= tol |b| or LDL_GMRES_MAX iterations. On
 * entry f->r holds r0 = b - A x, |r0| = beta. The residual is the GMRES
 * recurrence's, r = V_{k+1} Q^T (0, .., 0, g_k), of norm |g_k| (V
 * orthonormal: classical Gram-Schmidt twice); it differs from b - A x by
 * the rounding of A's products in double precision (~1e-16 |A| |x|), far
 * below the tolerance. Returns VES_OK with *done = 1 when it was reached.
 * Classical iterative refinement (x += M^-1 r) is the first iteration's
 * direction; it contracts by |I - A M^-1| per correction, ~0.1 on the KKT
 * matrices at large dt (eps 0.01, dt* 0.1-0.8: 5 corrections from 3e-2),
 * where GMRES, minimizing over the
 * Krylov space, needs a few. */
static ves_status gmres(ves_ldl *f, double *x, double beta, double bn, double tol, int *done) {
  const int n = f->n, m = LDL_GMRES_M;
  double H[(LDL_GMRES_M + 1) * LDL_GMRES_M], cs[LDL_GMRES_M], sn[LDL_GMRES_M], g[LDL_GMRES_M + 1],
      y[LDL_GMRES_M + 1];
  *done = 0;
  if (!f->V) {
    f->V = malloc((size_t)(m + 1) * n * sizeof *f->V);
    f->Z = malloc((size_t)m * n * sizeof *f->Z);
    if (!f->V || !f->Z) return VES_ERR_ALLOC;
  }
  while (f->info_.refinements < LDL_GMRES_MAX) {
    for (int i = 0; i < n; i++) f->V[i] = f->r[i] / beta;
    g[0] = beta;
    int k = 0, breakdown = 0;
    while (k < m && f->info_.refinements < LDL_GMRES_MAX) {
      double *z = f->Z + (size_t)k * n, *w = f->V + (size_t)(k + 1) * n;
      memcpy(z, f->V + (size_t)k * n, (size_t)n * sizeof *z);
      VES_CALL(ldl_mumps_solve(f, z));
      matvec(f, z, w);
      f->info_.refinements++;
      for (int pass = 0; pass < 2; pass++) /* classical Gram-Schmidt, twice */
        for (int i = 0; i <= k; i++) {
          const double *v = f->V + (size_t)i * n, h = dot(n, w, v);
          H[i * m + k] = pass ? H[i * m + k] + h : h;
          for (int j = 0; j < n; j++) w[j] -= h * v[j];
        }
      const double hn = sqrt(dot(n, w, w));
      breakdown = !(hn > 0); /* the Krylov space is invariant: the solution is in it */
      if (!breakdown)
        for (int j = 0; j < n; j++) w[j] /= hn;
      for (int i = 0; i < k; i++) { /* the earlier rotations on column k */
        const double a = H[i * m + k], c = H[(i + 1) * m + k];
        H[i * m + k] = cs[i] * a + sn[i] * c, H[(i + 1) * m + k] = -sn[i] * a + cs[i] * c;
      }
      const double a = H[k * m + k], rho = hypot(a, hn);
      cs[k] = rho > 0 ? a / rho : 1, sn[k] = rho > 0 ? hn / rho : 0;
      H[k * m + k] = rho;
      g[k + 1] = -sn[k] * g[k], g[k] *= cs[k];
      k++;
      if (fabs(g[k]) <= tol * bn || breakdown) break;
    }
    for (int i = k - 1; i >= 0; i--) { /* R y = g, upper triangular k x k */
      double d = g[i];
      for (int j = i + 1; j < k; j++) d -= H[i * m + j] * y[j];
      y[i] = H[i * m + i] != 0 ? d / H[i * m + i] : 0;
    }
    for (int i = 0; i < k; i++) {
      const double *z = f->Z + (size_t)i * n;
      for (int j = 0; j < n; j++) x[j] += y[i] * z[j];
    }
    beta = fabs(g[k]);
    if (!isfinite(beta)) return VES_OK;
    if (beta <= tol * bn) {
      *done = 1;
      return VES_OK;
    }
    if (breakdown) return VES_OK; /* a breakdown short of the tolerance: rounding */
    /* restart from r = V_{k+1} Q^T (0, .., 0, g_k) */
    for (int i = 0; i < k; i++) y[i] = 0;
    y[k] = g[k];
    for (int i = k - 1; i >= 0; i--) { /* the rotations transposed, last first */
      const double a = y[i], c = y[i + 1];
      y[i] = cs[i] * a - sn[i] * c, y[i + 1] = sn[i] * a + cs[i] * c;
    }
    memset(f->r, 0, (size_t)n * sizeof *f->r);
    for (int i = 0; i <= k; i++) {
      const double *v = f->V + (size_t)i * n;
      for (int j = 0; j < n; j++) f->r[j] += y[i] * v[j];
    }
  }
  return VES_OK;
}

/* rhs <- A^-1 rhs. With single precision factors: x0 = M^-1 b, then, when
 * |b - A x0| > tol |b| (it is 1e-5..2e-4 on the KKT matrices), FGMRES
 * preconditioned by M (gmres) to that tolerance, usually in one iteration;
 * a solve that cannot get there redoes the factorization in double
 * precision (ldl_to_double) and solves with it. */
ves_status ves_ldl_solve_tol(ves_ldl *f, double *rhs, double tol) {
  VES_CHECK(f && rhs && f->factored, VES_ERR_ARG);
  VES_CHECK(tol > 0 && tol < 1, VES_ERR_ARG);
  f->info_.refinements = 0;
  if (!f->single) return ldl_mumps_solve(f, rhs);
  const int n = f->n;
  memcpy(f->b, rhs, (size_t)n * sizeof *f->b);
  VES_CALL(ldl_mumps_solve(f, rhs));
  const double bn = sqrt(dot(n, f->b, f->b));
  matvec(f, rhs, f->r);
  for (int j = 0; j < n; j++) f->r[j] = f->b[j] - f->r[j];
  const double rn = sqrt(dot(n, f->r, f->r));
  if (rn <= tol * bn) return VES_OK; /* also b = 0 */
  int done = 0;
  if (isfinite(rn)) VES_CALL(gmres(f, rhs, rn, bn, tol, &done));
  if (done) return VES_OK;
  memcpy(rhs, f->b, (size_t)n * sizeof *rhs);
  VES_CALL(ldl_to_double(f));
  return ldl_mumps_solve(f, rhs);
}

ves_status ves_ldl_solve(ves_ldl *f, double *rhs) {
  return ves_ldl_solve_tol(f, rhs, VES_LDL_REFINE_TOL);
}
