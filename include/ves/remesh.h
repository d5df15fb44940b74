/* vesica — full remeshing with field projection (paper Secs. 1 and 3.3):
 * from a model (nodes X_a, points Xh_alpha, weights w_alpha, phi0 data) and
 * positions y,
 *   1. the interface: the zero line of phi on the old triangles moved to
 *      y(X_a) (crossings interpolated in d = sqrt2 eps atanh(phi)), from pole
 *      to pole, resampled at equal arclength: a sharp curve (shape.h);
 *   2. nodes adapted to it as the setup adapts them (ves_setup_nodes; where
 *      the band layers fold, the band without layers), the quadrature and
 *      LME tables with the old tables' parameters;
 *   3. phi0' = the L2 projection of the current phi onto the new basis over
 *      the old points moved with the material:
 *        c = argmin sum_alpha w_alpha det F (sum_a p'_a(y(Xh_alpha)) c_a - phi0(Xh_alpha))^2,
 *      cells the motion spread thinner than the new basis needs refined
 *      (info.proj_cells_refined);
 *   4. the correction y' + delta, delta = -G^T (G G^T)^-1 c (Newton on the
 *      constraints, G their gradients) restoring A = A_target (and V);
 *   5. the report: E, A, V before and after, the interface's displacement.
 * One vesicle: an interface of more than one piece is refused (VES_ERR_GEOM).
 * Design: docs/design.md, "The time loop"; measured: docs/results.md,
 * "Resets and remeshing". */
#ifndef VES_REMESH_H
#define VES_REMESH_H

#include <stddef.h>

#include "ves/geom.h"
#include "ves/model.h"
#include "ves/quad.h"
#include "ves/setup.h"
#include "ves/shape.h"
#include "ves/status.h"

/* What a remeshing restores and how. */
typedef struct {
  int hold_area;        /* 1: restore A = A_target */
  double A_target;      /* area target (units R0^2) */
  int hold_volume;      /* 1: restore V = V_target */
  double V_target;      /* volume target (units R0^3) */
  double ctol;          /* relative tolerance of the correction (default 1e-14) */
  int max_iter;         /* Newton iterations of the correction (default 10) */
  double curve_spacing; /* resampling spacing of the interface curve, units eps
                           (default 1: a spline knot every eps) */
  const double *y_prev; /* NULL (default), or a second state of the old reference (2n;
                           the integrator's y^{n-1}) to carry: its displacement
                           d = y - y_prev at the projection's points, projected
                           with phi (d_z, and d_r / r: both even in r, so one
                           factorization serves all three), gives
                           ves_remesh_y_prev = y' - d on the new nodes (borrowed) */
} ves_remesh_params;

/* Defaults: no constraint held, ctol 1e-14, max_iter 10, curve_spacing 1. */
void ves_remesh_params_default(ves_remesh_params *par);

/* What a remeshing changed. E in units of k (E*). */
typedef struct {
  int n_old, n_new;              /* real nodes before and after */
  int nq_old, nq_new;            /* quadrature points before and after */
  int curve_points;              /* knots of the interface curve */
  int band_layers;               /* 1: the band on interface-aligned layers ([geometry]
                                    band_layers = 1); 0: CVT in the band (band_layers = 0,
                                    or the layers folded on the curve: step 2) */
  double curve_length;           /* its length (units R0) */
  double E_old, A_old, V_old;    /* the old model at y */
  double E_proj, A_proj, V_proj; /* the new model at the identity, before the correction */
  double E, A, V;                /* the new model at the corrected positions */
  double dE, dA, dV;             /* E_proj - E_old, A_proj / A_old - 1, V_proj / V_old - 1 */
  double corr_max;               /* max_a |delta_a| / h_a, the correction at the nodes */
  double corr_norm;              /* |delta| (units R0, all dofs) */
  int corr_iter;                 /* Newton iterations of the correction */
  double res_A, res_V;           /* |A / A_target - 1|, |V / V_target - 1| after it (0 when
                                    not held) */
  double disp_max, disp_mean;    /* distance of the new interface's points from the old
                                    interface curve: max and mean (units R0) */
  ves_quad_info qinfo;           /* the new tables */
  int proj_points;               /* points of the projection: the old ones moved, with
                                   the thin cells' replaced (proj_cells_refined) */
  int proj_cells_refined;        /* old cells the motion had spread thinner than the new
                                    basis needs (CROSS_DENSITY in remesh.c: 14 points per
                                    h^2 of the new sizing), their points replaced by a
                                    rule of 24 or 96 points on the reference triangle */
  int proj_cells_capped;         /* of those, the ones still thinner at 96 points */
  int proj_points_dropped;       /* of their points, the ones the motion puts outside the
                                    domain (det F <= 0 or r <= 0: near the axis), left out
                                    of the fit (more than a tenth: VES_ERR_DOMAIN) */
  int proj_refinements;          /* refinement steps of the projection */
  double proj_residual;          /* its relative residual */
  double seconds_interface, seconds_nodes, seconds_tables, seconds_project, seconds_correct,
      seconds; /* wall times: the steps and the whole */
} ves_remesh_info;

/* A remeshed reference: it owns its nodes, quadrature (with tables), phi0
 * coefficients, model (which borrows the others) and the corrected
 * positions. It borrows nothing from the model it was made from. */
typedef struct ves_remesh ves_remesh;

/* Remesh the state y of model m (both borrowed; m is evaluated, not changed).
 *   dp    the discretization (borrowed for the call); its box must be m's
 *   par   targets and tolerances (copied)
 *   out   taken by the caller (ves_remesh_destroy)
 * The new model's parameters are m's (c0 as in force); its tables use m's
 * LME parameters. Allocates (~ the cost of a setup and a half).
 * Returns VES_OK; VES_MAXITER when the correction did not reach ctol in
 * max_iter iterations (out is made; res_A, res_V say how far);
 * VES_ERR_ARG (NULL, non-finite y, a box not m's); VES_ERR_DOMAIN (det F
 * <= 0 or r <= 0 at an old point); VES_ERR_GEOM (no interface from pole to
 * pole, or one of more than one piece); VES_ERR_CONFIG (the band does not
 * fit in the box; a fold of the band layers is not one: the band is then
 * made without them, info.band_layers = 0); errors of the node
 * generation, tables and projection. On error a line in err. */
ves_status ves_remesh_create(const ves_discret_params *dp, ves_model *m, const double *y,
                             const ves_remesh_params *par, ves_remesh **out, char *err,
                             size_t errlen);

/* Rebuild a remeshed reference from what defines it (a restart): a model m
 * on the same box and discretization (its parameters and LME parameters are
 * used), n nodes x[2n] (r >= 0), spacings h[n], flags flag[n] and phi0
 * coefficients phi0c[n] (ves_remesh_nodes and ves_remesh_phi0c of a remesh):
 * the nodes, tables and model are then those of that remesh, bit for bit
 * (the same code builds them). The positions (ves_remesh_y) are the nodes
 * (no correction) and the info holds the node and point counts only.
 * VES_ERR_ARG for invalid arrays; errors as ves_remesh_create. */
ves_status ves_remesh_restore(const ves_model *m, int n, const double *x, const double *h,
                              const int *flag, const double *phi0c, ves_remesh **out);

/* Free everything; accepts NULL and sets *r to NULL. The model must no
 * longer be in use. */
void ves_remesh_destroy(ves_remesh **r);

ves_model *ves_remesh_model(ves_remesh *r); /* owned by r */
const ves_model *ves_remesh_model_const(const ves_remesh *r);
const ves_nodes *ves_remesh_nodes(const ves_remesh *r); /* owned by r */
const ves_quad *ves_remesh_quad(const ves_remesh *r);   /* owned by r */
const double *ves_remesh_phi0c(const ves_remesh *r);    /* n phi0 coefficients */
const double *ves_remesh_y(const ves_remesh *r);        /* 2n corrected positions */
/* 2n: the carried y_prev (ves_remesh_params), NULL when none was given or
 * after a restore; wall nodes and the axis nodes' r at y' (no displacement). */
const double *ves_remesh_y_prev(const ves_remesh *r);
void ves_remesh_get_info(const ves_remesh *r, ves_remesh_info *info);

/* The interface of the state y of model m as a polyline from the north
 * pole to the south pole (step 1 above, before resampling): *pts (2 *npts,
 * (r, z), first and last with r = 0 exactly) taken by the caller;
 * *pieces (may be NULL) receives the number of pieces the zero line has
 * (1 for a single vesicle; the polyline is the pole-to-pole one).
 * phi0c (may be NULL): nodal coefficients of phi0 on m's basis when known
 * (the fit is then skipped). VES_ERR_GEOM when no piece runs from the axis
 * to the axis. */
ves_status ves_remesh_interface(const ves_model *m, const double *y, const double *phi0c, int *npts,
                                double **pts, int *pieces);

/* When to remesh (the integrator's policy; due when any enabled criterion
 * holds). */
typedef struct {
  int every;           /* accepted steps between remeshings (0: off) */
  double cond_max;     /* remesh when max cond_2 F exceeds this (> 1; 0: off) */
  double det_min;      /* remesh when min det F drops below this (in (0, 1); 0: off) */
  int on_failed_reset; /* 1: remesh when a reset of the reference was due and failed */
} ves_remesh_policy;

#endif
