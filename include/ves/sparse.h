/* vesica — sparse storage (CSparse-like, 0-based, int indices).
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
 * point has both in its (ghost-folded) neighbour list. fixed[2n] flags the
 * fixed dofs (borrowed). *out taken by the caller. */
ves_status ves_pattern_create(const ves_quad *q, int n, const unsigned char *fixed,
                              ves_pattern **out);
void ves_pattern_destroy(ves_pattern **p);

/* Position of the block (a, b), b <= a, in the pattern, or -1. */
long ves_pattern_find(const ves_pattern *p, int a, int b);

/* Triplet values v[nnz] from block values blk[4 ptr[n]]. */
void ves_pattern_extract(const ves_pattern *p, const double *blk, double *v);

/* y = A x over the free dofs, A symmetric given by its lower triplets v. */
void ves_pattern_symv(const ves_pattern *p, const double *v, const double *x, double *y);

#endif
