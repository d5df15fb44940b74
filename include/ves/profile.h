/* vesica — restoration of the phase field's profile: the model's phi0 is
 * replaced by tanh(d / (sqrt 2 eps)) of the signed distance d (positive
 * inside) of each quadrature point's current position to the current zero
 * set of phi, the positions kept. phi is material, so a flow with normal
 * strain across the band widens or narrows the tanh profile; the
 * restoration removes that stretch and keeps the interface where it is
 * (docs/results.md, "Shape-mode rates against the Stokes reference";
 * [solver] profile_every, docs/manual.md).
 *
 * The zero set is that of the piecewise-linear interpolant of atanh(phi)
 * at the nodes' material positions on the Delaunay cells (atanh(phi) =
 * d / (sqrt2 eps) is linear across a tanh profile, so the crossing points
 * lie on the interface up to the profile's curvature); the distance to the polyline is corrected by
 * the sag of the circular arc through consecutive crossing points, kappa L^2 s (1 - s) / 2, so that
 * the restored zero set does not shrink to the chords. The restored values at the points are fitted
 * onto the basis by the L2 projection of the setup (project.h). */
#ifndef VES_PROFILE_H
#define VES_PROFILE_H

#include "ves/model.h"
#include "ves/status.h"

typedef struct ves_profile ves_profile;

/* What one restoration did. */
typedef struct {
  int segments;     /* segments of the zero set found */
  double max_dphi;  /* max over the points of |phi0 new - phi0 old| */
  double max_shift; /* max |d_new - d_old| over the points with |phi| < 0.9, where
                       d_old = sqrt2 eps atanh(phi0 old): the profile's stretch (units R0) */
} ves_profile_info;

/* An empty restorer (the tables at the nodes are built at the first use on
 * a model). *out taken by the caller. */
ves_status ves_profile_create(ves_profile **out);
void ves_profile_destroy(ves_profile **p);

/* Forget the model it last worked on (its coefficients and tables): call
 * when the model's reference changes (a reset, a remeshing). */
void ves_profile_forget(ves_profile *p);

/* Restore the profile of model m at positions y[2n] (the model's phi0
 * point data replaced, ves_model_set_points). info may be NULL. The nodal
 * coefficients of the restored phi0 are then ves_profile_coefficients.
 * VES_ERR_GEOM when phi has no zero set; VES_ERR_ARG, VES_ERR_ALLOC, and
 * the projection's errors (project.h). */
ves_status ves_profile_restore(ves_profile *p, ves_model *m, const double *y,
                               ves_profile_info *info);

/* The nodal coefficients (n) of the last restored phi0 (NULL before one). */
const double *ves_profile_coefficients(const ves_profile *p);

#endif
