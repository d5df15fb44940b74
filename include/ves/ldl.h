/* vesica — the sparse symmetric direct solver of a matrix given by its lower
 * triplets (0-based): A = L D L^T or A = L L^T on sequential MUMPS, for the
 * KKT systems and the L2 projection (docs/design.md, "Numerical choices and
 * why"). Knows only status codes: no quadrature, no model. */
#ifndef VES_LDL_H
#define VES_LDL_H

#include "ves/status.h"

/* ---- Sparse symmetric direct solver (MUMPS, sequential) ----
 *
 * A = L D L^T of a symmetric n x n matrix given by its lower-triangle
 * triplets (0-based; duplicates are summed). The pattern is analysed once at
 * create; factor may be called again with new values on the same pattern. The
 * object is opaque: it owns a MUMPS instance and 1-based copies of the
 * indices, and borrows the values of the last factorization (ves_ldl_factor).
 * MUMPS prints nothing; ordering: approximate minimum fill (ICNTL(7) = 2,
 * faster than SCOTCH/AMD/QAMD/PORD on these matrices: docs/results.md,
 * "Performance and its scaling"). */
typedef struct ves_ldl ves_ldl;

/* Diagnostics of the last MUMPS call (create, factor or solve). */
typedef struct {
  int infog1;            /* MUMPS INFOG(1): 0 ok, < 0 error, > 0 warning */
  int infog2;            /* MUMPS INFOG(2): detail of INFOG(1) (see the MUMPS guide) */
  int neg_pivots;        /* INFOG(12) of the last factorization: negative pivots, i.e.
                            negative eigenvalues of A (the inertia the KKT path checks) */
  double factor_entries; /* entries in the factors (INFOG(29)), 0 before a factorization */
  int icntl14;           /* ICNTL(14) in use: workspace relaxation, percent */
  int retries;           /* workspace retries (INFOG(1) = -8/-9) in the last factorization */
  int single;            /* 1: the factorization in use is single precision */
  int refinements;       /* single precision: refinement (FGMRES) iterations of the last
                            solve, 0 when the single precision solve is enough */
  int fallbacks;         /* single precision: factorizations redone in double precision so
                            far (values that float cannot factor, or a solve that could not
                            be refined); each lasts until the next ves_ldl_factor */
} ves_ldl_info;

/* Analyse the pattern (MUMPS JOB = 1). irow[nnz], jcol[nnz]: 0-based lower
 * triplets, irow[k] >= jcol[k] (copied). spd != 0: A is symmetric positive
 * definite (Cholesky, MUMPS SYM = 1); spd == 0: symmetric indefinite (LDL^T with
 * 2x2 pivots, SYM = 2). *out taken by the caller.
 * Returns VES_OK, VES_ERR_ARG (n < 1, nnz < 1, an index out of range or above
 * the diagonal), VES_ERR_ALLOC, VES_ERR_SINGULAR (structurally singular),
 * VES_ERR_SOLVER (another MUMPS error; no object is returned, so its codes
 * are not available: for valid input this does not happen). */
ves_status ves_ldl_create(int n, int nnz, const int *irow, const int *jcol, int spd, ves_ldl **out);

/* As ves_ldl_create; single != 0 factors in single precision (SMUMPS: half
 * the factors' memory and bandwidth, ~1.7x faster on the KKT matrix at eps
 * 0.01: docs/results.md, "Performance and its scaling") and refines each
 * solve with the double precision values to |b - A x| <= 1e-6 |b|: flexible
 * GMRES preconditioned by the single precision factors (one iteration on
 * most KKT matrices: 5e-5 -> 5e-8; a few where plain iterative refinement
 * contracts by only ~0.1 per correction), at most 60 iterations. A
 * factorization whose float values fail (singular, overflow), or whose
 * solve cannot be refined, is redone in double precision (a new analysis;
 * info.fallbacks), and the next ves_ldl_factor is single precision again. The inertia is that of
 * the factorization in use. */
ves_status ves_ldl_create_prec(int n, int nnz, const int *irow, const int *jcol, int spd,
                               int single, ves_ldl **out);

/* Numeric factorization (JOB = 2) reusing the analysis; val[nnz] in the order
 * of the triplets given to create, borrowed, not copied: val must stay valid
 * and unchanged until the next ves_ldl_factor or ves_ldl_destroy (the
 * single precision solves' refinement and a double fallback read it; at
 * eps 0.01 a copy would take ~0.3 GB). Retries with twice the workspace
 * relaxation ICNTL(14) when MUMPS runs out of workspace (up to
 * VES_LDL_MAX_RETRIES times; the larger value is kept for later calls).
 * Returns VES_OK, VES_ERR_ARG, VES_ERR_SINGULAR (a zero pivot: INFOG(1) = -10
 * or -6; for spd also a negative pivot, INFOG(12) > 0 with INFOG(1) = 0, since
 * MUMPS's SYM = 1 is an unpivoted LDL^T that accepts an indefinite matrix),
 * VES_ERR_ALLOC, VES_ERR_SOLVER
 * (other MUMPS errors; codes in ves_ldl_get_info). After a failure the
 * analysis is still valid and factor may be called again. */
ves_status ves_ldl_factor(ves_ldl *f, const double *val);

/* Solve A x = rhs in place (JOB = 3): rhs[n] in, x out. Requires a successful
 * factor. With single precision factors the solve is refined to
 * |b - A x| <= VES_LDL_REFINE_TOL |b|. Returns VES_OK, VES_ERR_ARG (no valid
 * factorization), VES_ERR_SOLVER. */
ves_status ves_ldl_solve(ves_ldl *f, double *rhs);
#define VES_LDL_REFINE_TOL 1e-6 /* ves_ldl_solve's refinement target, relative */
/* As ves_ldl_solve, the single precision refinement stopping at
 * |b - A x| <= tol |b|, 0 < tol < 1 (VES_ERR_ARG otherwise): an iteration
 * that needs only an approximate direction (a chord or inexact Newton step,
 * whose own residual is recomputed exactly) skips the refinement when the
 * single precision solve is within tol (one MUMPS solve and one product
 * instead of two of each). Double precision factors solve exactly. */
ves_status ves_ldl_solve_tol(ves_ldl *f, double *rhs, double tol);

/* Order of the matrix. */
int ves_ldl_size(const ves_ldl *f);

/* Copy the diagnostics of the last call into *info. */
void ves_ldl_get_info(const ves_ldl *f, ves_ldl_info *info);

/* Free (JOB = -2); accepts NULL and sets *f to NULL. */
void ves_ldl_destroy(ves_ldl **f);

#define VES_LDL_MAX_RETRIES 3 /* workspace retries in ves_ldl_factor */

#endif
