/* vesica — resetting the reference configuration (paper Sec. 3.3, Fig. 2):
 * the current positions become the reference, the quadrature points move
 * with the material, and the LME basis, neighbour lists and sparse pattern
 * are rebuilt, with no field projection and no new quadrature. From nodes
 * X_a, points Xh_alpha, weights w_alpha, point data of phi0 and positions
 * y^a (motion y(X) = sum_a p_a(X) y^a, F = Dy, G = D2y):
 *   nodes    X'_a = y^a (VES_RESET_NODES_COEF, the paper) or y(X_a)
 *            (VES_RESET_NODES_MOTION); h'_a from the new node set,
 *            beta'_a = gamma / h'_a^2; ghosts regenerated, flags kept
 *   points   Xh'_alpha = y(Xh_alpha), weights w'_alpha = w_alpha det F
 *   phi0     phi0' = phi0, grad' phi0 = grad phi0 F^-1            (Eq. 2)
 *            Hess' phi0 = F^-T (Hess phi0 - g_n G_n) F^-1         (Eq. 3)
 * The new motion is the identity (LME reproduces affine maps), so E, A, V
 * are unchanged up to rounding; the discrete space of motions changes at
 * the level of the discretization error (tests/test_reconnect.c). A node
 * whose r coefficient crossed the axis is mirrored (X'_a = (-r_a, z_a): the
 * same motion), so after a reset continue from ves_reconnect_nodes(r)->x.
 * Wall nodes keep y^a, axis nodes r = 0 (docs/design.md, "The time loop";
 * the two node choices compared: docs/results.md, "Resets and remeshing"). */
#ifndef VES_RECONNECT_H
#define VES_RECONNECT_H

#include "ves/geom.h"
#include "ves/lme.h"
#include "ves/model.h"
#include "ves/quad.h"
#include "ves/status.h"

/* A reference configuration made by a reset: it owns its nodes, its
 * quadrature (points, weights, tables) and the model built on them (the
 * model borrows the other two, so all three live and die together). It
 * borrows nothing from the model it was made from: that model (and the
 * setup or reconnect object owning it) may be destroyed once the caller has
 * switched over. */
typedef struct ves_reconnect ves_reconnect;

/* Statistics of one reset. */
typedef struct {
  double cond_max;     /* distortion of y relative to the old reference:
                          max over the points of cond_2 F (>= 1) */
  double det_min;      /* min over the points of det F */
  double h_min, h_max; /* range of the new spacings h'_a (units R0) */
  int mirrored;        /* nodes with r_a < 0 in y, mirrored into r > 0 */
  double shift_max;    /* max over the non-wall nodes of |y^a - y(X_a)| / h_a (old h_a) */
  ves_quad_info qinfo; /* the table build of the new reference */
  double seconds;      /* wall time of the whole reset */
} ves_reconnect_info;

/* Where the new reference nodes go (header comment). */
typedef enum {
  VES_RESET_NODES_COEF = 0,  /* X'_a = y^a, the nodal coefficients (paper Sec. 3.3) */
  VES_RESET_NODES_MOTION = 1 /* X'_a = y(X_a), the motion at the old nodes */
} ves_reset_nodes;

/* Reset the reference configuration of model m to the positions y.
 *   m     the current model (borrowed; read only); its nodes, quadrature
 *         (with tables), point data and parameters (c0 as in force) are used;
 *         the new tables are built with the LME parameters of m's tables
 *         (ves_model_quad(m)->lme: the discretization does not change)
 *   y     2n current positions (r_a, z_a) of the real nodes (borrowed); axis
 *         nodes must have r_a = 0 exactly, every other node r_a != 0 (it gets
 *         a ghost; r_a < 0 is mirrored, above); wall nodes keep their flag
 *         and stay fixed at y^a
 *   where the new node positions: y^a or y(X_a) (above)
 *   out   the new reference, taken by the caller (ves_reconnect_destroy)
 * The new model's reference positions (ves_model_reference) are the new
 * nodes, mirrored ones with r negated (= ves_reconnect_nodes(out)->x), its
 * fixed dofs those of the old one, its parameters copied from m.
 * Allocates (a once-per-reset operation: ~ the cost of the setup's tables).
 * Returns VES_OK; VES_ERR_ARG (NULL, non-finite y, an axis node with
 * r != 0, m's quadrature without tables); VES_ERR_DOMAIN (det F <= 0 or r <= 0 at a point, or
 * a non-axis node with r = 0, on its own ghost: y is not admissible); VES_ERR_GEOM (two nodes
 * at the same position); VES_ERR_NOCONV / VES_ERR_ARG from the LME tables
 * (a point outside the hull of its new neighbours); VES_ERR_ALLOC. */
ves_status ves_reconnect_create(const ves_model *m, const double *y, ves_reset_nodes where,
                                ves_reconnect **out);

/* A second state z of m's reference (2n coefficients; the integrator's
 * y^{n-1}, its predictor's start) as coefficients zn (2n) on the reference
 * that ves_reconnect_create(m, y, where, .) makes: zn = z for
 * VES_RESET_NODES_COEF (the new nodes are y's coefficients), zn_a = z(X_a)
 * for VES_RESET_NODES_MOTION (they are y(X_a)); r negated at the nodes the
 * reset mirrors, axis nodes r = 0, wall nodes z^a (as the reset treats y).
 * Carrying y itself gives the new nodes. The new basis reproduces affine
 * fields, so a motion z = y + affine map is carried exactly; otherwise zn is
 * a quasi-interpolant (within O(h^2) of the motion; enough for a predictor).
 * Returns VES_OK; VES_ERR_ARG (NULL, non-finite); from the node tables
 * (MOTION: ~n / nq of a table build) VES_ERR_NOCONV, VES_ERR_ALLOC. */
ves_status ves_reconnect_carry(const ves_model *m, const double *y, ves_reset_nodes where,
                               const double *z, double *zn);

/* Rebuild a reference made by a reset from what defines it (a restart:
 * io.h stores these at every reset), without the motion that made it:
 *   m       a model on the same node set (flags, box, triangles; its
 *           parameters are copied, c0 as in force; its tables' LME
 *           parameters are used), e.g. the creation model
 *   x, h    2n node positions (r >= 0: mirrored ones already mirrored) and
 *           n spacings h_a (taken as given, not measured again)
 *   nq, xq, wq, pd   the points (2 nq), weights (nq) and point data of phi0
 *           (6 nq, the layout of ves_model_create_points)
 * With the values of ves_reconnect_nodes/quad and ves_model_point_data of a
 * reset, the nodes, tables and model are those of that reset, bit for bit
 * (the same code builds them). info: the node count and spacings only (no
 * cond F, det F or shift: no motion). Errors as ves_reconnect_create, and
 * VES_ERR_ARG for nq not that of m's quadrature, h <= 0 or r < 0. */
ves_status ves_reconnect_restore(const ves_model *m, const double *x, const double *h, int nq,
                                 const double *xq, const double *wq, const double *pd,
                                 ves_reconnect **out);

/* Free the model, quadrature and nodes; accepts NULL and sets *r to NULL.
 * The model must no longer be in use (step problems and backends on it
 * destroyed first). */
void ves_reconnect_destroy(ves_reconnect **r);

/* The new model (owned by r; the step problem may modify its c0). */
ves_model *ves_reconnect_model(ves_reconnect *r);
const ves_model *ves_reconnect_model_const(const ves_reconnect *r); /* the same, read only */
/* The new nodes and quadrature (owned by r). */
const ves_nodes *ves_reconnect_nodes(const ves_reconnect *r);
const ves_quad *ves_reconnect_quad(const ves_reconnect *r);
/* Statistics of the reset. */
void ves_reconnect_get_info(const ves_reconnect *r, ves_reconnect_info *info);

/* The motion at the real nodes of a reference, xm[2n] = y(X_a) (the current
 * position of the material at node a), from a point set at the nodes with
 * tables on that reference (ves_quad_create_at_nodes + ves_quad_tables) and
 * the positions y[2n]. Wall nodes keep y^a (fixed dofs: their points sit
 * just off the hull only so the point set is valid), axis nodes get r = 0
 * exactly (the motion is odd in R: rounding otherwise). shift_max (may be
 * NULL) receives max over the non-wall nodes of |y^a - y(X_a)| / h_a.
 * No allocation. */
void ves_reconnect_motion_at_nodes(const ves_nodes *nodes, const ves_quad *pq, const double *y,
                                   double *xm, double *shift_max);

/* The distortion of the motion y relative to the model's reference
 * configuration, over the quadrature points:
 *   *cond_max = max_alpha cond_2 F(Xh_alpha) = sigma_max / sigma_min of the
 *               2 x 2 meridian deformation gradient F-tilde (1 for rigid
 *               motions and uniform dilatations; rotation invariant, like
 *               the LME basis itself); +inf if det F <= 0 somewhere
 *   *det_min  = min_alpha det F(Xh_alpha) (compression; <= 0: folded)
 * The hoop stretch r/R is not included: it does not distort the meridian
 * node layout the basis lives on. Either output may be NULL. No allocation
 * (callable every step); OpenMP threads over the points (a max and a min:
 * the same result for any thread count).
 * VES_ERR_ARG for NULL m or y or a non-finite y. */
ves_status ves_reconnect_distortion(const ves_model *m, const double *y, double *cond_max,
                                    double *det_min);

/* The same per point: cond[nq] and det[nq] (either may be NULL); cond is
 * +inf where det <= 0. */
ves_status ves_reconnect_distortion_points(const ves_model *m, const double *y, double *cond,
                                           double *det);

/* The push-forward of the point data of phi0 at one point (Eqs. 2-3):
 *   F[4]   (F_rR, F_rZ, F_zR, F_zZ), F_iI = dy_i/dX_I
 *   G[6]   (r_RR, r_RZ, r_ZZ, z_RR, z_RZ, z_ZZ), second derivatives of y
 *   pd[6]  (phi0, phi0_R, phi0_Z, phi0_RR, phi0_RZ, phi0_ZZ) in X
 *   out[6] (phi0, phi_r, phi_z, phi_rr, phi_rz, phi_zz): the derivatives of
 *          phi = phi0 o y^-1 with respect to the current coordinates at y(X):
 *          g_i = phi0_I H_Ii, phi_ij = H_Ii (phi0_IJ - g_n G_nIJ) H_Jj,
 *          H = F^-1 (from phi0(X) = phi(y(X)) differentiated twice).
 * Returns VES_OK or VES_ERR_DOMAIN (det F <= 0; out not written). */
ves_status ves_reconnect_push_forward(const double F[4], const double G[6], const double pd[6],
                                      double out[6]);

/* When to reset (the integrator's policy; a reset is due when any enabled
 * criterion holds). */
typedef struct {
  int every;       /* accepted steps between resets (0: off; paper Fig. 5: 20) */
  double cond_max; /* reset when max cond_2 F exceeds this (> 1; 0: off) */
  double det_min;  /* reset when min det F drops below this (in (0, 1); 0: off) */
} ves_reconnect_params;

/* Defaults: the problem file's [reconnect] every, cond_max, det_min (all
 * off; the implementation says which thresholds are worth enabling). */
void ves_reconnect_params_default(ves_reconnect_params *par);

/* *due = 1 when a reset is due at y after `steps` accepted steps since the
 * last reset (or the start), else 0; *cond and *det (may be NULL) receive
 * the distortion measured (only when a threshold is enabled; else 1 and 1).
 * VES_ERR_ARG for invalid arguments or parameters. */
ves_status ves_reconnect_due(const ves_reconnect_params *par, const ves_model *m, const double *y,
                             long steps, int *due, double *cond, double *det);

#endif
