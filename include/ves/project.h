/* vesica — the sparse structures that need a quadrature, the layer above both
 * quadrature (quad.h) and factorization (ldl.h): the node-level block pattern
 * of the model's matrices built from the quadrature tables (its type and the
 * operations that need no quadrature are in sparse.h), and the L2 projection
 * of a field onto the LME space (docs/design.md, "Discretization"). */
#ifndef VES_PROJECT_H
#define VES_PROJECT_H

#include "ves/quad.h"
#include "ves/sparse.h"
#include "ves/status.h"

/* Build the pattern from the quadrature tables: a and b are coupled when some
 * point has both in its (ghost-folded) neighbour list. q2 (may be NULL): a
 * second point set with tables against the same n nodes whose couplings are
 * added (the union; the model passes NULL: its defect rows are cut to the
 * points' own pattern, model_drift.c).
 * fixed[2n] flags the fixed dofs (borrowed). *out taken by the caller.
 * Named for its type: the constructor of sparse.h's ves_pattern, the pair
 * of ves_pattern_destroy there (GSL's _alloc/_free by type); it stands here
 * because it reads a quadrature, which sparse (a layer below quad) cannot
 * see. */
ves_status ves_pattern_create(const ves_quad *q, const ves_quad *q2, int n,
                              const unsigned char *fixed, ves_pattern **out);

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
ves_status ves_project_l2(const ves_quad *q, int n, const double *f, double *c, double rtol,
                          int maxref, int *refinements, double *relres);

/* ves_project_l2 of nf fields at once (one M, one factorization): f[nf nq]
 * field k at f + k nq, c[nf n] its coefficients at c + k n, refinements[nf]
 * and relres[nf] (may be NULL) per field. Field 0 gets exactly the
 * coefficients ves_project_l2 gives it (that function is this one with
 * nf = 1); the others' right-hand sides are summed in the same order.
 * VES_MAXITER when some field misses rtol (each has its best iterate). */
ves_status ves_project_l2_fields(const ves_quad *q, int n, int nf, const double *f, double *c,
                                 double rtol, int maxref, int *refinements, double *relres);

/* ves_project_l2 with M assembled and factorized once, for repeated fields
 * on the same points (q, n borrowed and unchanged while it lives): create
 * builds and factorizes M; apply gives the coefficients c[n] of f[nq] as
 * ves_project_l2 does (same M, same refinement, VES_MAXITER when rtol is
 * missed, c then the best iterate). *out taken by the caller. */
typedef struct ves_projector ves_projector;
ves_status ves_projector_create(const ves_quad *q, int n, ves_projector **out);
ves_status ves_projector_apply(ves_projector *p, const double *f, double *c, double rtol,
                               int maxref);
void ves_projector_destroy(ves_projector **p);

#endif
