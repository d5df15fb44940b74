/* vesica — the setup stage: from a discretization, a shape and the model's
 * parameters to the initial discrete state (adapted nodes, quadrature and
 * LME tables, least-squares phi0 coefficients, model):
 *   nodes   spacing h(X) = h_band eps in the band |d| < band eps, growing
 *           with `slope` to h_far (sizing.h)
 *   phi0    c = argmin sum_alpha w_alpha (sum_a c_a p_a(X_alpha) - phi0(X_alpha))^2,
 *           phi0 = tanh(d / (sqrt2 eps)), d the shape's signed distance (project.h)
 * (docs/design.md, "Discretization"). */
#ifndef VES_SETUP_H
#define VES_SETUP_H

#include <stddef.h>

#include "ves/model.h"
#include "ves/quad.h"
#include "ves/shape.h"
#include "ves/sizing.h"

/* The discretization (the problem file's [geometry] keys but the model's
 * stabilization). Lengths in units of R0 = sqrt(A0 / 4 pi). Plain data:
 * every function here copies what it needs. */
typedef struct {
  double eps;             /* interface width eps (units R0) */
  double box_r, box_z;    /* the meridian box [0, box_r] x [-box_z, box_z] (units R0) */
  double h_band;          /* node spacing in the band (units eps) */
  double band;            /* half-width of the refined band |d| < band eps (units eps) */
  double slope;           /* growth of the spacing away from the band (dh / dd, 1) */
  double h_far;           /* largest node spacing (units R0) */
  double gamma;           /* LME aspect ratio, beta_a = gamma / h_a^2 (1) */
  double support_tol;     /* LME support truncation tol0 (1) */
  double axis_spacings;   /* width of the regular lattice strip along the axis (spacings) */
  int lloyd_iterations;   /* Lloyd (CVT) smoothing iterations of the node set */
  int band_layers;        /* 1: nodes in the band on interface-aligned layers; 0: CVT */
  int seed;               /* seed of the deterministic node sampling (>= 0) */
  ves_quad_rulespec rule; /* quadrature rule per Delaunay triangle (ves_quad_rule_parse) */
} ves_discret_params;

/* How the nodal coefficients of phi0 are obtained. */
typedef enum {
  VES_PHI0_L2 = 0,     /* least-squares projection (the only correct choice) */
  VES_PHI0_SAMPLED = 1 /* phi0(X_a): kept only to measure why not
                          (docs/design.md, "Numerical choices and why") */
} ves_phi0_method;

typedef struct {
  ves_shape *shape;     /* initial shape */
  ves_sizing *sizing;   /* node sizing field */
  ves_nodes *nodes;     /* adapted nodes with ghosts */
  ves_quad *quad;       /* points, weights, tables */
  double *phi0c;        /* n nodal coefficients of phi0 */
  ves_model *model;     /* E, A, V, K */
  double area_sharp;    /* sharp area of the initial shape (units R0^2) */
  double volume_sharp;  /* sharp volume (units R0^3) */
  ves_quad_info qinfo;  /* table statistics */
  int proj_refinements; /* iterative-refinement steps of the projection (direct solve) */
  double proj_residual; /* final relative residual |Mc - b| / |b| of the projection */
  double seconds_nodes, seconds_tables, seconds_project, seconds_total; /* wall times */
} ves_setup;

/* Build everything for the discretization d (copied) of the shape (taken:
 * it belongs to the setup, and is freed on failure too) with the model's
 * parameters mp (copied; mp->eps must be d->eps). On error returns the
 * status and writes a one-line message to err: VES_ERR_ARG for NULL
 * pointers, an invalid rule or mp->eps != d->eps; VES_ERR_CONFIG as
 * ves_setup_nodes; errors of the tables, the projection and the model. */
ves_status ves_setup_create(const ves_discret_params *d, ves_shape *shape,
                            const ves_model_params *mp, ves_phi0_method method, ves_setup **out,
                            char *err, size_t errlen);
void ves_setup_destroy(ves_setup **s);

/* The node set of the discretization d (borrowed for the call: eps, h_band,
 * band, slope, h_far, box, band_layers, axis_spacings, lloyd_iterations,
 * seed) adapted to a shape (borrowed), exactly as the setup builds it:
 * *sizing and *nodes are taken by the caller (the nodes do not borrow the
 * sizing). VES_ERR_CONFIG when the shape with its band does not fit the box
 * or the band layers fold; errors of node generation. One line in err on
 * error. */
ves_status ves_setup_nodes(const ves_discret_params *d, const ves_shape *shape, ves_sizing **sizing,
                           ves_nodes **nodes, char *err, size_t errlen);

/* The checks of ves_setup_nodes that need no node, with its messages: the
 * shape with its band of (band + 1) eps inside the box, and with band_layers
 * the band's offset curves within the shape's radii of curvature (d and
 * shape borrowed). VES_ERR_CONFIG and one line in err when one fails (bad
 * input although every key is in range); VES_OK otherwise, also when the
 * offset curves fail for another reason (the setup reports that). Costs
 * milliseconds: a study checks its cells with it before running any. */
ves_status ves_setup_check_geometry(const ves_discret_params *d, const ves_shape *shape, char *err,
                                    size_t errlen);

#endif
