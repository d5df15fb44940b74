/* vesica — the exact sparse Cholesky factor of a symmetric positive definite
 * matrix given by its lower triplets (0-based), with the half solves a
 * change of variables needs (the nlopt backend's): G G^T = M, v -> G^{-1} v
 * and v -> G^{-T} v. On CHOLMOD (SuiteSparse 5.12): P M P^T = L L^T with a
 * fill-reducing permutation P chosen once at create, and G = P^T L; or
 * densely (LAPACK) for M plus a rank-m term that a sparse factor cannot
 * hold. MUMPS (ldl.h) offers full solves M^{-1} v only. Knows only status
 * codes: no quadrature, no model (docs/design.md, "Backends"). */
#ifndef VES_CHOL_H
#define VES_CHOL_H

#include <stddef.h>

#include "ves/status.h"

typedef struct ves_chol ves_chol;

/* Analyse the pattern: irow[nnz] >= jcol[nnz] (duplicates are summed, the
 * diagonal is forced in), ordering and symbolic factorization once.
 * Returns VES_OK, VES_ERR_ARG (n < 1, nnz < 0, an index out of range or
 * above the diagonal), VES_ERR_ALLOC, VES_ERR_SOLVER (CHOLMOD's analysis
 * failed). */
ves_status ves_chol_create(int n, int nnz, const int *irow, const int *jcol, ves_chol **out);

/* G G^T = M + alpha diag(M), M the triplet values val[nnz] (in the order
 * given to create) summed, alpha >= 0. Returns VES_OK, VES_ERR_ARG,
 * VES_ERR_SINGULAR (not positive definite: a pivot <= 0, not finite; the
 * factor is then unusable until the next successful call), VES_ERR_ALLOC,
 * VES_ERR_SOLVER. */
ves_status ves_chol_factor(ves_chol *f, const double *val, double alpha);

/* The dense variant: G G^T = M + sum_i s_i w_i w_i^T, M as above (alpha 0),
 * w the m rows w_i (m n doubles), s_i >= 0, factored by LAPACK on an n x n
 * array (allocated at the first call, 8 n^2 bytes, kept): for a rank-m term
 * that a sparse factor cannot hold. The half solves below then use it, until
 * the next ves_chol_factor. Returns as ves_chol_factor; on VES_ERR_SINGULAR
 * *fail (may be NULL) is the 1-based column whose pivot failed (0 for a
 * non-finite diagonal). */
ves_status ves_chol_factor_dense(ves_chol *f, const double *val, int m, const double *w,
                                 const double *s, int *fail);

/* v = G^{-1} v and v = G^{-T} v, in place (n entries), with the factor of
 * the last successful ves_chol_factor or ves_chol_factor_dense. Return
 * VES_OK or VES_ERR_ARG (no factor), VES_ERR_SOLVER. */
ves_status ves_chol_lsolve(ves_chol *f, double *v);
ves_status ves_chol_ltsolve(ves_chol *f, double *v);

/* v = G^{-1} v for the k >= 1 columns of v (n k doubles, column-major), the
 * factor read once for all of them (the solves of one vector are bound by
 * reading the factor). VES_ERR_ALLOC besides the codes above. */
ves_status ves_chol_lsolve_cols(ves_chol *f, int k, double *v);

/* Entries of L (the last factorization's; 0 before one). */
size_t ves_chol_factor_entries(const ves_chol *f);

/* The sparse factor's entries from the analysis over n (n + 1) / 2: how
 * nearly dense it is (0 for NULL). */
double ves_chol_fill(const ves_chol *f);

/* Free; accepts NULL and sets *f to NULL. */
void ves_chol_destroy(ves_chol **f);

#endif
