/* vesica — the setup stage: from a configuration to the initial discrete
 * state (shape, adapted nodes, quadrature and LME tables, least-squares phi0
 * coefficients, model). Data flows one way: config -> setup -> time loop. */
#ifndef VES_SETUP_H
#define VES_SETUP_H

#include <stddef.h>

#include "app/config.h"
#include "ves/model.h"
#include "ves/quad.h"
#include "ves/shape.h"
#include "ves/sizing.h"

/* How the nodal coefficients of phi0 are obtained. */
typedef enum {
  VES_PHI0_L2 = 0,     /* least-squares projection (the only correct choice) */
  VES_PHI0_SAMPLED = 1 /* phi0(X_a): kept only to measure why not (DESIGN.md §2) */
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

/* Build everything for cfg. On error returns the status and writes a one-line
 * message to err. */
ves_status ves_setup_create(const ves_config *cfg, ves_phi0_method method, ves_setup **out,
                            char *err, size_t errlen);
void ves_setup_destroy(ves_setup **s);

/* The initial shape of cfg ([shape]; a points file is read), as the setup
 * builds it: *shape is taken by the caller. VES_ERR_CONFIG for a points
 * file the setup refuses (one line in err). */
ves_status ves_setup_shape(const ves_config *cfg, ves_shape **shape, char *err, size_t errlen);

/* The node set of cfg's discretization ([geometry]: epsilon, h_band, band,
 * slope, h_far, box, band_layers, axis_spacings, lloyd_iterations, seed)
 * adapted to a shape (borrowed), exactly as the setup builds it: *sizing
 * and *nodes are taken by the caller (the nodes do not borrow the sizing).
 * VES_ERR_CONFIG when the shape with its band does not fit the box or the
 * band layers fold; errors of node generation. One line in err on error. */
ves_status ves_setup_nodes(const ves_config *cfg, const ves_shape *shape, ves_sizing **sizing,
                           ves_nodes **nodes, char *err, size_t errlen);

#endif
