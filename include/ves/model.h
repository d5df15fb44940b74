/* vesica — the discrete Lagrangian phase-field model: energy E, area A and
 * volume V (docs/design.md, "The model") as functions of the nodal positions
 * y, with gradients and exact sparse Hessians, and the dissipation matrix
 * K(y), all from one per-point assembly over the local kinematic variables
 * q_alpha = B_alpha y (docs/design.md, "Discretization").
 *
 * y has 2n entries (r_a, z_a) for the real nodes; ghosts carry (-r_a, z_a).
 * Every integral is 2 pi sum_alpha w_alpha (density at alpha). */
#ifndef VES_MODEL_H
#define VES_MODEL_H

#include <stddef.h>

#include "ves/geom.h"
#include "ves/quad.h"
#include "ves/sparse.h"
#include "ves/status.h"

/* Physical parameters. Lengths in R0; k and mu in any one system of units,
 * in which times come out (the reduced time is t* = t k / (mu R0^3), so t
 * is t* for k = mu = 1, as the program sets them). */
typedef struct {
  double eps;    /* interface width eps / R0 */
  double c0;     /* spontaneous curvature C0 R0 */
  double k;      /* bending stiffness (1 in reduced units) */
  double mu;     /* shear viscosity (1 in reduced units) */
  double lambda; /* penalty viscosity lambda (lambda/mu >= 10) */
  double drift;  /* drift damping alpha >= 0 (dimensionless; 0: off): K gets
                    the constant S with ydot^T S ydot =
                    sum_a alpha mu 2 pi M_a / h_a^2 |ydot^a - ydot(X_a)|^2
                    (a over the nodes off the wall),
                    M_a = sum_alpha w_alpha R_alpha p_a(X_alpha) the node's
                    r-weighted reference measure: a viscous penalty on the
                    rate of the coefficients' departure from the motion at
                    their nodes. Zero on affine motions (LME reproduces
                    them), O((h/L)^2) of the dissipation on smooth ones,
                    stiff on grid-scale coefficient patterns (docs/results.md,
                    "Resets and remeshing") */
  double stab;   /* coefficient-mode stabilization kappa >= 0 (0: off): E gets
                    E_s = (1/2) sum_a kappa k 2 pi M_a / h_a^2 |y^a - y(X_a)|^2
                    over the nodes off the wall (M_a as for drift): zero on
                    affine maps, so at the reference; O(kappa (h/L)^2) on
                    smooth motions; positive curvature along the grid-scale
                    coefficient patterns on which the discrete E has negative
                    curvature (docs/results.md, "Accuracy against the
                    sharp-interface references"). Its Hessian is
                    constant, added to Hess E */
} ves_model_params;

typedef struct ves_model ves_model;

/* Which functionals to evaluate. */
enum { VES_F_E = 1, VES_F_A = 2, VES_F_V = 4 };

/* Build the model for nodes and quadrature tables (both borrowed: they must
 * outlive the model) and the phase-field coefficients phi0c[n] (copied into
 * point values phi0, grad phi0, Hess phi0 at every quadrature point).
 * Fixed dofs: wall nodes (r and z) and the r of axis nodes.
 * The evaluations below run on omp_get_max_threads() threads as of create
 * (OMP_NUM_THREADS, default all cores) with workspace per thread; their
 * results are bitwise the same for any thread count. One model must not be
 * evaluated from two threads at once. */
ves_status ves_model_create(const ves_nodes *nodes, const ves_quad *q, const double *phi0c,
                            const ves_model_params *par, ves_model **out);
void ves_model_destroy(ves_model **m);

/* As ves_model_create, from the point data of phi0 instead of nodal
 * coefficients: pd[6 nq], point-major, pd[6 alpha + j] = phi0, d phi0/dR,
 * d phi0/dZ, d2 phi0/dR2, d2 phi0/dRdZ, d2 phi0/dZ2 at point alpha with
 * respect to the reference coordinates of nodes and q (units 1, 1/R0,
 * 1/R0^2; the layout of ves_quad_field), copied. nodes and q borrowed (they
 * must outlive the model). ves_model_create is this function applied to
 * ves_quad_field(q, phi0c). Used after a reset of the reference
 * configuration (reconnect.h), where phi0 has no nodal coefficients.
 * VES_ERR_ARG also for a non-finite entry of pd. */
ves_status ves_model_create_points(const ves_nodes *nodes, const ves_quad *q, const double *pd,
                                   const ves_model_params *par, ves_model **out);

/* The model's point data pd[6 nq] (layout of ves_model_create_points). */
void ves_model_point_data(const ves_model *m, double *pd);

/* Replace the model's phi0 point data by pd[6 nq] (layout of
 * ves_model_create_points, copied): a restoration of the profile (profile.h).
 * The nodes, tables and pattern stay. VES_ERR_ARG for a non-finite entry
 * (then nothing is changed). */
ves_status ves_model_set_points(ves_model *m, const double *pd);

/* The parameters in force (c0 as last set by ves_model_set_c0). */
void ves_model_get_params(const ves_model *m, ves_model_params *par);

/* The nodes and the quadrature the model was built on (borrowed by the
 * model, so by the caller too). */
const ves_nodes *ves_model_nodes(const ves_model *m);
const ves_quad *ves_model_quad(const ves_model *m);

/* The sparse pattern shared by the Hessians and K (owned by the model). */
const ves_pattern *ves_model_pattern(const ves_model *m);

/* Values (and gradients over all 2n dofs when g* != NULL) of the functionals
 * selected in `which`; outputs of unselected ones are not touched.
 * VES_ERR_DOMAIN when det F <= 0 or r <= 0 at some point. */
ves_status ves_model_eval(ves_model *m, const double *y, int which, double *E, double *A, double *V,
                          double *gE, double *gA, double *gV);

/* Block values (4 ptr[n] doubles, see ves_pattern) of
 * cE Hess E + cA Hess A + cV Hess V at y. */
ves_status ves_model_hessian(ves_model *m, const double *y, double cE, double cA, double cV,
                             double *blk);

/* Block values of the dissipation matrix K(y): Diss = (1/2) ydot^T K ydot,
 * K including the drift damping S (ves_model_params.drift). */
ves_status ves_model_dissipation(ves_model *m, const double *y, double *blk);

/* The step's dissipation K(y^n) without assembling it (a step's objective
 * (1/2) d^T K(y^n) d + dt E(y), d = y - y^n, paper Eq. 11):
 * ves_model_dissipation_ref stores the velocity variables of y^n, VES_NQD = 5
 * doubles a quadrature point (qn[5 nq]; VES_ERR_DOMAIN if y^n is not
 * admissible). ves_model_eval_step is ves_model_eval (E selected) with
 *   gF = cE grad E + K(y^n) (y - y^a),  *Dv = (1/2) (y - y^a)^T K(y^n) (y - y^a)
 * in place of gE (each point's K term added before the scatter: no matrix),
 * where qa holds the velocity variables of the anchor y^a, as
 * ves_model_dissipation_ref gives them (a BDF2 step's combination of y^n and
 * y^{n-1}: step.h), or is NULL for y^a = y^n; the matrix is K at the
 * configuration whose variables are qn, which need not be y^n (a BDF2 step
 * takes it at the extrapolated state). Those variables are linear in y, so
 * a combination of two states' qn is the combined state's. K here is
 * without the drift damping S (ves_model_drift_blocks; constant).
 * ves_model_hessian_step is ves_model_hessian + cK K(y^n) (with S), the two
 * summed per point before the one assembly. Agree with the assembled
 * ves_model_dissipation to rounding. single != 0: each triangle's block
 * matrix is formed in single precision (its products by sgemm; the points'
 * local matrices and the sums over the triangles stay double), for a matrix
 * that is factored in single precision anyway: entries to ~1e-6 of the
 * terms summed into them (float rounding of the 36-42 term products), ~1.5x
 * faster (docs/results.md, "Performance and its scaling"). */
ves_status ves_model_dissipation_ref(ves_model *m, const double *y, double *qn);
size_t ves_model_dissipation_ref_size(const ves_model *m); /* doubles in qn: 5 nq */
ves_status ves_model_eval_step(ves_model *m, const double *y, int which, const double *qn,
                               const double *qa, double cE, double *E, double *A, double *V,
                               double *Dv, double *gF, double *gA, double *gV);
ves_status ves_model_hessian_step(ves_model *m, const double *y, const double *qn, double cE,
                                  double cA, double cV, double cK, int single, double *blk);

/* The block values (4 ptr[n]) of the drift damping S in the pattern, or NULL
 * when it is off (ves_model_params.drift = 0). Owned by the model. */
const double *ves_model_drift_blocks(const ves_model *m);

/* Pointwise W (units 1/R0) at every quadrature point, W[nq]. */
ves_status ves_model_pointwise_W(ves_model *m, const double *y, double *W);

/* Spontaneous curvature C0 R0 in force (protocols change it in time), and
 * the bending stiffness k. */
ves_status ves_model_set_c0(ves_model *m, double c0);
double ves_model_get_c0(const ves_model *m);
double ves_model_get_k(const ves_model *m);

/* Reference nodal positions (y at rest), 2n, for convenience. */
void ves_model_reference(const ves_model *m, double *y);

#endif
