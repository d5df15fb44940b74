/* vesica — the KKT matrix of a step problem (kkt.h): its triplet structure,
 * values and MUMPS factorization. docs/design.md, "Backends". */
#include "ves/kkt.h"

#include <stdlib.h>
#include <string.h>

void ves_kkt_destroy(ves_kkt *k) {
  free(k->irow), free(k->jcol), free(k->val);
  ves_ldl_destroy(&k->ldl);
  memset(k, 0, sizeof *k);
}

/* Structure: H triplets first, then for each constraint row q = nvar + i the
 * entries (q, 0..nvar-1) and (q, q). Analysis (symmetric indefinite) once;
 * single: the factors in single precision, the solves refined (ldl.h). */
ves_status ves_kkt_create(const ves_step *s, int single, ves_kkt *k) {
  memset(k, 0, sizeof *k);
  const int nv = ves_step_nvar(s), nh = ves_step_hess_nnz(s);
  if (nv < 1 || nh < 1) return VES_ERR_ARG;
  k->nvar = nv, k->nh = nh, k->nnz = nh + VES_KKT_NROWS * (nv + 1);
  k->irow = malloc((size_t)k->nnz * sizeof *k->irow);
  k->jcol = malloc((size_t)k->nnz * sizeof *k->jcol);
  k->val = calloc((size_t)k->nnz, sizeof *k->val);
  if (!k->irow || !k->jcol || !k->val) {
    ves_kkt_destroy(k);
    return VES_ERR_ALLOC;
  }
  ves_step_hess_structure(s, k->irow, k->jcol);
  int t = nh;
  for (int i = 0; i < VES_KKT_NROWS; i++) {
    for (int j = 0; j < nv; j++) k->irow[t] = nv + i, k->jcol[t++] = j; /* row of J */
    k->irow[t] = nv + i, k->jcol[t++] = nv + i;                         /* D */
  }
  ves_status st =
      ves_ldl_create_prec(nv + VES_KKT_NROWS, k->nnz, k->irow, k->jcol, 0, single, &k->ldl);
  if (st != VES_OK) ves_kkt_destroy(k);
  return st;
}

/* The constraint rows' values: J[ncon x nvar] row-major for the held
 * constraints, D as above; the (1,1) block untouched. */
void ves_kkt_fill_rows(ves_kkt *k, const double *J, int ncon) {
  const int nv = k->nvar;
  int t = k->nh;
  for (int i = 0; i < VES_KKT_NROWS; i++) {
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
void ves_kkt_fill(ves_kkt *k, const double *H, double delta, const double *K, const double *J,
                  int ncon) {
  for (int t = 0; t < k->nh; t++) k->val[t] = H[t] + (delta != 0 ? delta * K[t] : 0.0);
  ves_kkt_fill_rows(k, J, ncon);
}

/* Factorize; VES_OK with k->neg the negative pivots, or the ves_ldl error. */
ves_status ves_kkt_factor(ves_kkt *k) {
  ves_status st = ves_ldl_factor(k->ldl, k->val);
  ves_ldl_info info;
  ves_ldl_get_info(k->ldl, &info);
  k->neg = st == VES_OK ? info.neg_pivots : -1;
  return st;
}

/* Solve in place: rhs[nvar + VES_KKT_NROWS]. */
ves_status ves_kkt_solve(ves_kkt *k, double *rhs) { return ves_ldl_solve(k->ldl, rhs); }

/* As kkt_solve, single precision factors refined only to |b - A x| <= tol |b|
 * (ves_ldl_solve_tol). */
ves_status ves_kkt_solve_tol(ves_kkt *k, double *rhs, double tol) {
  return ves_ldl_solve_tol(k->ldl, rhs, tol);
}
