/* vesica — the KKT system shared by the newton and euler backends (private):
 *
 *   [ H + delta K   J^T ] [ dx ]   [ r1 ]
 *   [ J             D   ] [ dl ] = [ r2 ]
 *
 * over nvar + 2 unknowns, H in the step Hessian pattern (lower triplets), two
 * dense constraint rows always present, D = 0 on a held constraint's row and
 * D = -1 (with a zero J row) on an unused one, so the structure does not
 * depend on which constraints a step holds and the MUMPS analysis is done once.
 * The inertia of a good KKT matrix is then always (nvar, 2 negative, 0):
 * a held row contributes one negative eigenvalue (J of full row rank, H
 * positive definite on its null space), an unused row its -1. */
#ifndef VES_BACKEND_KKT_IMPL_H
#define VES_BACKEND_KKT_IMPL_H

#include <stdlib.h>
#include <string.h>

#include "ves/ldl.h"
#include "ves/step.h"

#define KKT_NROWS 2 /* constraint rows in the structure (area, volume) */

typedef struct {
  int nvar;     /* free dofs */
  int nh;       /* triplets of the (1,1) block (the step Hessian pattern) */
  int nnz;      /* all triplets: nh + KKT_NROWS (nvar + 1) */
  int *irow;    /* nnz triplet rows (lower triangle) */
  int *jcol;    /* nnz triplet columns */
  double *val;  /* nnz values of the current matrix */
  ves_ldl *ldl; /* MUMPS LDL^T, analysed at create */
  int neg;      /* negative pivots of the last factorization */
} kkt_system;

static inline void kkt_destroy(kkt_system *k) {
  free(k->irow), free(k->jcol), free(k->val);
  ves_ldl_destroy(&k->ldl);
  memset(k, 0, sizeof *k);
}

/* Structure: H triplets first, then for each constraint row q = nvar + i the
 * entries (q, 0..nvar-1) and (q, q). Analysis (symmetric indefinite) once;
 * single: the factors in single precision, the solves refined (ldl.h). */
static inline ves_status kkt_create(const ves_step *s, int single, kkt_system *k) {
  memset(k, 0, sizeof *k);
  const int nv = ves_step_nvar(s), nh = ves_step_hess_nnz(s);
  if (nv < 1 || nh < 1) return VES_ERR_ARG;
  k->nvar = nv, k->nh = nh, k->nnz = nh + KKT_NROWS * (nv + 1);
  k->irow = malloc((size_t)k->nnz * sizeof *k->irow);
  k->jcol = malloc((size_t)k->nnz * sizeof *k->jcol);
  k->val = calloc((size_t)k->nnz, sizeof *k->val);
  if (!k->irow || !k->jcol || !k->val) {
    kkt_destroy(k);
    return VES_ERR_ALLOC;
  }
  ves_step_hess_structure(s, k->irow, k->jcol);
  int t = nh;
  for (int i = 0; i < KKT_NROWS; i++) {
    for (int j = 0; j < nv; j++) k->irow[t] = nv + i, k->jcol[t++] = j; /* row of J */
    k->irow[t] = nv + i, k->jcol[t++] = nv + i;                         /* D */
  }
  ves_status st = ves_ldl_create_prec(nv + KKT_NROWS, k->nnz, k->irow, k->jcol, 0, single, &k->ldl);
  if (st != VES_OK) kkt_destroy(k);
  return st;
}

/* The constraint rows' values: J[ncon x nvar] row-major for the held
 * constraints, D as above; the (1,1) block untouched. */
static inline void kkt_fill_rows(kkt_system *k, const double *J, int ncon) {
  const int nv = k->nvar;
  int t = k->nh;
  for (int i = 0; i < KKT_NROWS; i++) {
    if (i < ncon)
      memcpy(k->val + t, J + (size_t)i * nv, (size_t)nv * sizeof *J);
    else
      memset(k->val + t, 0, (size_t)nv * sizeof *k->val);
    t += nv;
    k->val[t++] = i < ncon ? 0.0 : -1.0;
  }
}

/* Values: (1,1) = H + delta K (K may be NULL when delta = 0), the rows as
 * kkt_fill_rows. */
static inline void kkt_fill(kkt_system *k, const double *H, double delta, const double *K,
                            const double *J, int ncon) {
  for (int t = 0; t < k->nh; t++) k->val[t] = H[t] + (delta != 0 ? delta * K[t] : 0.0);
  kkt_fill_rows(k, J, ncon);
}

/* Factorize; VES_OK with k->neg the negative pivots, or the ves_ldl error. */
static inline ves_status kkt_factor(kkt_system *k) {
  ves_status st = ves_ldl_factor(k->ldl, k->val);
  ves_ldl_info info;
  ves_ldl_get_info(k->ldl, &info);
  k->neg = st == VES_OK ? info.neg_pivots : -1;
  return st;
}

/* Solve in place: rhs[nvar + KKT_NROWS]. */
static inline ves_status kkt_solve(kkt_system *k, double *rhs) {
  return ves_ldl_solve(k->ldl, rhs);
}

/* As kkt_solve, single precision factors refined only to |b - A x| <= tol |b|
 * (ves_ldl_solve_tol). */
static inline ves_status kkt_solve_tol(kkt_system *k, double *rhs, double tol) {
  return ves_ldl_solve_tol(k->ldl, rhs, tol);
}

#endif
