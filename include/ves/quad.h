/* vesica — quadrature on the Delaunay triangles of the reference nodes, and the
 * discretization tables: for every quadrature point its neighbour list and the
 * 6 x m table [p; dp/dR; dp/dZ; d2p/dR2; d2p/dRdZ; d2p/dZ2] of the LME basis
 * (docs/design.md, "Discretization"). */
#ifndef VES_QUAD_H
#define VES_QUAD_H

#include "ves/geom.h"
#include "ves/lme.h"
#include "ves/status.h"

#define VES_QUAD_NPT 6 /* points per triangle (degree-4 rule) */

/* Points and weights of the 6-point degree-4 rule on a triangle: bary[3k+j]
 * is the j-th barycentric coordinate of point k, w[k] its weight; the weights
 * sum to 1 (multiply by the triangle's area). */
void ves_quad_rule(double bary[3 * VES_QUAD_NPT], double w[VES_QUAD_NPT]);

/* A composite rule on a triangle: a base rule (degree 4, 6 points: the
 * default; or degree 6, 12 points, Dunavant 1985) on each of the split^2
 * congruent sub-triangles of a uniform split (split 1, 2 or 4). Points per
 * triangle npt = (6 or 12) split^2, always a multiple of VES_QUAD_NPT, so the
 * points of a triangle form npt / VES_QUAD_NPT groups of VES_QUAD_NPT, the unit
 * of assembly of the model (see ves_quad.ntri). Named in problem files as
 * "d4", "d6", "d4x4", "d6x4", "d4x16", "d6x16" (degree, then sub-triangles). */
typedef struct {
  int degree; /* 4 or 6: the base rule */
  int split;  /* 1, 2 or 4: each triangle cut into split^2 */
} ves_quad_rulespec;

#define VES_QUAD_NPT_MAX (12 * 16) /* points per triangle of the richest rule */

/* The rule named s ("d4", "d6", "d4x4", ...; see above): VES_ERR_ARG for
 * another name. */
ves_status ves_quad_rule_parse(const char *s, ves_quad_rulespec *out);

/* Points per triangle of a rule (0 for an invalid one). */
int ves_quad_rule_npt(ves_quad_rulespec r);

/* Points and weights of a composite rule in the triangle's barycentric
 * coordinates: bary[3k+j], w[k] for k < ves_quad_rule_npt(r); the weights sum
 * to 1. For {4, 1} exactly ves_quad_rule's. VES_ERR_ARG for an invalid rule. */
ves_status ves_quad_rule_composite(ves_quad_rulespec r, double bary[3 * VES_QUAD_NPT_MAX],
                                   double w[VES_QUAD_NPT_MAX]);

/* Quadrature points and their tables (plain data; sizes in the comments). */
typedef struct {
  int ntri;               /* groups of VES_QUAD_NPT points, the unit of assembly:
                             with the default rule the triangles of the reference
                             Delaunay triangulation; with a richer rule each
                             triangle gives sub consecutive groups */
  int *tri;               /* 3 ntri node indices, counter-clockwise: a group's
                             triangle (repeated sub times per triangle) */
  int sub;                /* groups per triangle (ves_quad_rule_npt / VES_QUAD_NPT;
                             1 for the default rule; 0 for a point set made by
                             ves_quad_create_points, which does not know it) */
  ves_quad_rulespec rule; /* the rule of ves_quad_create_rule ({0, 0} for
                           ves_quad_create_points: a reset sets sub and rule
                           to those of the quadrature it moves) */
  int nq;                 /* quadrature points, VES_QUAD_NPT * ntri */
  double *x;              /* 2 nq reference positions (R, Z), units of R0 */
  double *w;              /* nq weights of the measure dR dZ (units R0^2); the
                             axisymmetric factor 2 pi r det F belongs to the model */
  /* Tables (NULL until ves_quad_tables): CSR over the points. */
  int *ptr;              /* nq + 1 offsets into nbr, mirror; m_a = ptr[a+1]-ptr[a] */
  int *nbr;              /* ptr[nq] real node indices */
  unsigned char *mirror; /* ptr[nq] flags: 1 when the entry is the ghost (-R, Z)
                            of node nbr[k] (r-coefficient -1, z and phi0 +1) */
  double *tab;           /* 6 ptr[nq]: point a's table starts at tab + 6 ptr[a],
                            row-major 6 x m_a, rows p, p_R, p_Z, p_RR, p_RZ, p_ZZ */
  ves_lme_params lme;    /* the LME parameters the tables were built with (a copy,
                            set by ves_quad_tables): tables built later for the
                            same discretization (a reset, points at the nodes)
                            take them from here */
} ves_quad;

/* Statistics of a table build. */
typedef struct {
  double m_mean;    /* mean neighbours per point (ghost entries included) */
  int m_max;        /* largest neighbour count */
  double iter_mean; /* mean Newton iterations of the LME dual */
  int iter_max;     /* largest Newton iteration count */
  double seconds;   /* wall time of the build */
} ves_quad_info;

/* Triangulate the real nodes (Delaunay) and place VES_QUAD_NPT points per
 * triangle. nodes is borrowed; *out is taken by the caller. */
ves_status ves_quad_create(const ves_nodes *nodes, ves_quad **out);

/* The same with a composite rule r (ves_quad_create is {4, 1}): sub =
 * ves_quad_rule_npt(r) / VES_QUAD_NPT groups per triangle, group g of
 * triangle t holding the rule's points VES_QUAD_NPT g .. + VES_QUAD_NPT - 1. */
ves_status ves_quad_create_rule(const ves_nodes *nodes, ves_quad_rulespec r, ves_quad **out);

/* The Delaunay triangles under the groups: *ncell = ntri / sub and a fresh
 * copy *cells[3 *ncell] (taken by the caller) of every sub-th triple (all of
 * them when sub <= 1). */
ves_status ves_quad_cells(const ves_quad *q, int *ncell, int **cells);

/* A point set given by the caller: nq points x[2 nq] (R, Z) and weights
 * w[nq] (units R0^2), all copied, no tables. When ntri > 0 the points are
 * grouped VES_QUAD_NPT per triangle of tri[3 ntri] (copied; nq must be
 * VES_QUAD_NPT ntri), the unit of assembly of the model; ntri = 0 (tri NULL)
 * gives a point set for evaluation only (ves_quad_tables, ves_quad_field,
 * ves_quad_motion), which ves_model_create refuses. Used by the reset of the
 * reference configuration (reconnect.h): the current triangles with the moved
 * points and weights. *out is taken by the caller. VES_ERR_ARG for nq < 1, a
 * non-finite coordinate, a weight <= 0 or non-finite, or a triangle index < 0. */
ves_status ves_quad_create_points(int nq, const double *x, const double *w, int ntri,
                                  const int *tri, ves_quad **out);

/* A point set at the real nodes, for evaluating fields and motions there
 * (ves_quad_tables, then ves_quad_field or ves_quad_motion): point a at X_a,
 * weight 1, no triangles. Wall nodes lie on the hull, where LME is not
 * evaluated: their points are moved 1e-3 h_a inwards. nodes borrowed; *out
 * taken by the caller. */
ves_status ves_quad_create_at_nodes(const ves_nodes *nodes, ves_quad **out);

/* Build the tables for the current points against the current nodes (real +
 * ghost), with support radii ves_lme_radius(lme, h_a) and beta_a = gamma/h_a^2.
 * Replaces previous tables; lme is copied into q->lme. info may be NULL. */
ves_status ves_quad_tables(ves_quad *q, const ves_nodes *nodes, const ves_lme_params *lme,
                           ves_quad_info *info);

/* The least-squares (L2) projection of a field onto these tables is
 * ves_project_l2 (project.h): it needs the direct solver. */

/* Evaluate an even field from coefficients: out[6 nq] rows (value, d/dR,
 * d/dZ, d2/dR2, d2/dRdZ, d2/dZ2) at every point, point-major: out[6 alpha + j].
 * nder as in ves_lme_eval (rows beyond are not written). */
void ves_quad_field(const ves_quad *q, const double *c, int nder, double *out);

/* The motion y(X) = sum_a p_a(X) y^a and its derivatives at point al, from
 * the point's table and the nodal positions y[2n] (r_a, z_a) of the real
 * nodes (a ghost entry carries (-r_a, z_a): r is odd in R, z even):
 *   out[0..5]  = r, dr/dR, dr/dZ, d2r/dR2, d2r/dRdZ, d2r/dZ2
 *   out[6..11] = z, dz/dR, dz/dZ, d2z/dR2, d2z/dRdZ, d2z/dZ2
 * i.e. F_iI = out[6 i + 1 + I], G_iJK = out[6 i + 3 + (J + K)]. nder as in
 * ves_lme_eval: rows beyond it are not written. Requires the tables. */
void ves_quad_motion(const ves_quad *q, const double *y, int al, int nder, double out[12]);

/* Free; accepts NULL and sets *q to NULL. */
void ves_quad_destroy(ves_quad **q);

#endif
