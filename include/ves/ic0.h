/* vesica — the incomplete Cholesky factor IC(0) of a symmetric matrix given
 * by its lower triplets (0-based), the nlopt backend's change of variables:
 * L L^T ~= M + alpha diag(M) with L restricted to the lower pattern of M
 * (row-wise, no fill), and the half solves v -> L^{-1} v, v -> L^{-T} v.
 * Knows only status codes (docs/design.md, "Backends"). */
#ifndef VES_IC0_H
#define VES_IC0_H

#include "ves/status.h"

/* Plain data: the factor in compressed rows, open so a caller can read M's
 * diagonal before factoring. */
typedef struct {
  int n;     /* order */
  int nnz;   /* triplets the pattern is built from */
  int *ptr;  /* n + 1 row offsets */
  int *col;  /* ptr[n] columns, ascending in each row, the diagonal last */
  double *a; /* ptr[n] values of M (the triplets summed, ves_ldl_ic_set) */
  double *l; /* ptr[n] values of L (ves_ldl_ic_factor) */
  int *map;  /* nnz: the slot in col of triplet k */
} ves_ldl_ic;

/* The pattern of the lower triplets irow[nnz] >= jcol[nnz] (copied; the
 * diagonal added where missing, duplicates merged). *out taken by the caller.
 * Returns VES_OK, VES_ERR_ARG (n < 1, nnz < 0, an index out of range or above
 * the diagonal), VES_ERR_ALLOC. */
ves_status ves_ldl_ic_create(int n, int nnz, const int *irow, const int *jcol, ves_ldl_ic **out);

/* M = the triplet values val[nnz] (in the order given to create) summed into
 * the pattern: L->a. */
void ves_ldl_ic_set(ves_ldl_ic *L, const double *val);

/* L L^T = M + alpha diag(M) on the pattern of M (M from ves_ldl_ic_set):
 *   L_ij = (M_ij - sum_{k<j} L_ik L_jk) / L_jj,
 *   L_ii = sqrt(M_ii (1 + alpha) - sum_{k<i} L_ik^2).
 * Returns VES_OK, VES_ERR_SINGULAR (a breakdown: a pivot <= 0 or not finite). */
ves_status ves_ldl_ic_factor(ves_ldl_ic *L, double alpha);

/* v = L^{-1} v (forward substitution, in place). */
void ves_ldl_ic_lsolve(const ves_ldl_ic *L, double *v);

/* v = L^{-T} v (backward substitution, in place). */
void ves_ldl_ic_ltsolve(const ves_ldl_ic *L, double *v);

/* Free; accepts NULL and sets *L to NULL. */
void ves_ldl_ic_destroy(ves_ldl_ic **L);

#endif
