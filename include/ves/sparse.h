/* vesica — the node-level block pattern of the model's matrices (CSparse-like
 * storage, 0-based, int indices): plain data and the operations that need no
 * quadrature. It is built from a quadrature by ves_pattern_create (project.h,
 * the layer above quadrature and this one); the factorization is in ldl.h.
 *
 * Matrices over the nodal unknowns are assembled into a node-level block
 * pattern: for every pair of real nodes (a, b), b <= a, that share a
 * quadrature point, one dense 2x2 block (r, z) x (r, z), row-major. The
 * pattern is computed once per reference configuration. For the solvers it is
 * mapped to triplets over the FREE degrees of freedom only (fixed ones
 * eliminated), lower triangle, in a fixed order (Ipopt and MUMPS both take it;
 * docs/design.md, "Discretization"). */
#ifndef VES_SPARSE_H
#define VES_SPARSE_H

#include "ves/status.h"

/* Node-level lower block pattern and its free-dof triplet map. */
typedef struct {
  int n;     /* real nodes */
  int *ptr;  /* n + 1 row offsets */
  int *col;  /* ptr[n] column nodes, ascending in each row, col <= row */
  int nfree; /* free degrees of freedom */
  int *dof;  /* 2n: free index of (node a, component i) at 2a + i, or -1 */
  int nnz;   /* triplets over free dofs, lower triangle (row >= col) */
  int *irow; /* nnz triplet rows (free indices) */
  int *jcol; /* nnz triplet columns */
  long *src; /* nnz positions in the block values (4 ptr[n] doubles) */
} ves_pattern;

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

#endif
