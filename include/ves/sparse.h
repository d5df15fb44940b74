/* vesica — sparse storage (CSparse-like, 0-based, int indices), the sparse
 * symmetric direct solver (MUMPS) and the L2 projection built on both.
 *
 * Matrices over the nodal unknowns are assembled into a node-level block
 * pattern: for every pair of real nodes (a, b), b <= a, that share a
 * quadrature point, one dense 2x2 block (r, z) x (r, z), row-major. The
 * pattern is computed once per reference configuration. For the solvers it is
 * mapped to triplets over the FREE degrees of freedom only (fixed ones
 * eliminated), lower triangle, in a fixed order (Ipopt and MUMPS both take it). */
#ifndef VES_SPARSE_H
#define VES_SPARSE_H

#include "ves/quad.h"
#include "ves/status.h"

/* Node-level lower block pattern and its free-dof triplet map. */
typedef struct {
  int n;          /* real nodes */
  int *ptr;       /* n + 1 row offsets */
  int *col;       /* ptr[n] column nodes, ascending in each row, col <= row */
  int nfree;      /* free degrees of freedom */
  int *dof;       /* 2n: free index of (node a, component i) at 2a + i, or -1 */
  int nnz;        /* triplets over free dofs, lower triangle (row >= col) */
  int *irow;      /* nnz triplet rows (free indices) */
  int *jcol;      /* nnz triplet columns */
  long *src;      /* nnz positions in the block values (4 ptr[n] doubles) */
} ves_pattern;

/* Build the pattern from the quadrature tables: a and b are coupled when some
 * point has both in its (ghost-folded) neighbour list. q2 (may be NULL): a
 * second point set with tables against the same n nodes whose couplings are
 * added (the union; the model's drift damping uses the points at the nodes).
 * fixed[2n] flags the fixed dofs (borrowed). *out taken by the caller. */
ves_status ves_pattern_create(const ves_quad *q, const ves_quad *q2, int n,
                              const unsigned char *fixed, ves_pattern **out);
void ves_pattern_destroy(ves_pattern **p);

/* Position of the block (a, b), b <= a, in the pattern, or -1. */
long ves_pattern_find(const ves_pattern *p, int a, int b);

/* Triplet values v[nnz] from block values blk[4 ptr[n]]. */
void ves_pattern_extract(const ves_pattern *p, const double *blk, double *v);

/* y = A x over the free dofs, A symmetric given by its lower triplets v. */
void ves_pattern_symv(const ves_pattern *p, const double *v, const double *x, double *y);

/* The full symmetric matrix given by its lower triplets v, in compressed rows
 * over the free dofs (both triangles, columns ascending in each row):
 * *ptr (nfree + 1), *col and *val (ptr[nfree]) are taken by the caller. */
ves_status ves_pattern_csr(const ves_pattern *p, const double *v, int **ptr, int **col,
                           double **val);

/* ---- Sparse symmetric direct solver (MUMPS, sequential) ----
 *
 * A = L D L^T of a symmetric n x n matrix given by its lower-triangle
 * triplets (0-based; duplicates are summed). The pattern is analysed once at
 * create; factor may be called again with new values on the same pattern. The
 * object is opaque: it owns a MUMPS instance and 1-based copies of the indices
 * and of the values. MUMPS prints nothing; ordering: approximate minimum fill
 * (ICNTL(7) = 2, measured faster than SCOTCH/AMD/QAMD/PORD on our matrices). */
typedef struct ves_ldl ves_ldl;

/* Diagnostics of the last MUMPS call (create, factor or solve). */
typedef struct {
  int infog1;          /* MUMPS INFOG(1): 0 ok, < 0 error, > 0 warning */
  int infog2;          /* MUMPS INFOG(2): detail of INFOG(1) (see the MUMPS guide) */
  int neg_pivots;      /* INFOG(12) of the last factorization: negative pivots, i.e.
                          negative eigenvalues of A (the inertia the KKT path checks) */
  double factor_entries; /* entries in the factors (INFOG(29)), 0 before a factorization */
  int icntl14;         /* ICNTL(14) in use: workspace relaxation, percent */
  int retries;         /* workspace retries (INFOG(1) = -8/-9) in the last factorization */
} ves_ldl_info;

/* Analyse the pattern (MUMPS JOB = 1). irow[nnz], jcol[nnz]: 0-based lower
 * triplets, irow[k] >= jcol[k] (copied). spd != 0: A is symmetric positive
 * definite (Cholesky, MUMPS SYM = 1); spd == 0: symmetric indefinite (LDL^T with
 * 2x2 pivots, SYM = 2). *out taken by the caller.
 * Returns VES_OK, VES_ERR_ARG (n < 1, nnz < 1, an index out of range or above
 * the diagonal), VES_ERR_ALLOC, VES_ERR_SINGULAR (structurally singular),
 * VES_ERR_SOLVER (another MUMPS error; no object is returned, so its codes
 * are not available: for valid input this does not happen). */
ves_status ves_ldl_create(int n, int nnz, const int *irow, const int *jcol, int spd,
                          ves_ldl **out);

/* Numeric factorization (JOB = 2) reusing the analysis; val[nnz] in the order
 * of the triplets given to create (copied). Retries with twice the workspace
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
 * factor. Returns VES_OK, VES_ERR_ARG (no valid factorization), VES_ERR_SOLVER. */
ves_status ves_ldl_solve(ves_ldl *f, double *rhs);

/* Order of the matrix. */
int ves_ldl_size(const ves_ldl *f);

/* Copy the diagnostics of the last call into *info. */
void ves_ldl_get_info(const ves_ldl *f, ves_ldl_info *info);

/* Free (JOB = -2); accepts NULL and sets *f to NULL. */
void ves_ldl_destroy(ves_ldl **f);

#define VES_LDL_MAX_RETRIES 3 /* workspace retries in ves_ldl_factor */

/* ---- L2 projection onto the LME space ---- */

/* Least-squares (L2) coefficients of a field that is even in R (a ghost
 * carries its real node's coefficient): c minimizes
 *   sum_alpha w_alpha (sum_a P_alpha,a c_a - f_alpha)^2,
 * P_alpha,a = p_a(X_alpha) + p_ghost(a)(X_alpha) (the table's value row folded
 * over ghosts), i.e. solves the normal equations M c = b,
 *   M_ab = sum_alpha w_alpha P_alpha,a P_alpha,b,  b_a = sum_alpha w_alpha P_alpha,a f_alpha,
 * by a sparse Cholesky factorization of M on the node-level pattern (the one
 * of ves_pattern, nodes coupled through a common point), followed by
 * iterative refinement c += M^-1 (b - M c) until |M c - b| <= rtol |b|, at
 * most maxref steps, or until the residual stops decreasing.
 *   q       points with tables (borrowed)
 *   n       real nodes
 *   f[nq]   the field at the points (borrowed)
 *   c[n]    out: the coefficients (the best iterate if rtol is not met)
 *   refinements, relres  out, may be NULL: refinement steps taken, final
 *           relative residual |M c - b| / |b| (0 when b = 0)
 * Returns VES_OK, VES_MAXITER (rtol not met), VES_ERR_ARG, VES_ERR_ALLOC,
 * VES_ERR_SINGULAR (M singular: a node that no point sees, or a numerically
 * dependent basis), VES_ERR_SOLVER. Allocates and frees its workspace (a
 * once-per-configuration operation). */
ves_status ves_sparse_project_l2(const ves_quad *q, int n, const double *f, double *c,
                                 double rtol, int maxref, int *refinements, double *relres);

#endif
