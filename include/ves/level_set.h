/* vesica — the sharp interface a nodal field carries on a triangulation
 * (post-processing, paper Sec. 4: the area and volume the nodes show;
 * docs/design.md, "Analysis"). */
#ifndef VES_LEVEL_SET_H
#define VES_LEVEL_SET_H

#include "ves/status.h"

/* The sharp interface that a nodal field carries on a triangulation, in
 * the axisymmetric measure (post-processing: a check of the discrete
 * functionals against the geometry the nodes show). */
typedef struct {
  double volume; /* 2 pi int r dA over {phi_h > 0} (units R0^3), phi_h the
                    piecewise-linear interpolant of the nodal phi on the
                    triangles mapped to the positions x; signed: a mapped
                    triangle of negative area counts negatively, so the
                    volumes of {phi_h > 0} and {phi_h <= 0} add up to the
                    image's signed volume */
  double area;   /* 2 pi int r ds along {phi_h = 0} (units R0^2) */
  int inverted;  /* triangles whose image has area <= 0 (the map folds at
                    the scale of the nodes) */
} ves_level_set;

/* The level set {phi = 0} of node values phi[n] on the triangles tri[3 ntri]
 * (counter-clockwise in the reference) placed at positions x[2n] (r, z):
 * exact for the piecewise-linear interpolant (a triangle is clipped by the
 * zero line of its linear phi). VES_ERR_ARG for a NULL array, ntri < 1, an
 * index outside [0, n), or a non-finite x or phi on a triangle. */
ves_status ves_level_set_eval(int n, int ntri, const int *tri, const double *x, const double *phi,
                              ves_level_set *out);

#endif
