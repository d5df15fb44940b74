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

/* The zero set {phi_h = 0} as curves: the segments ves_level_set_eval
 * integrates (one per triangle the zero line crosses, its ends where edges
 * change sign, exactly at a node where phi is 0 there), joined at shared
 * edges and nodes into connected pieces. A crossing point is computed once
 * per edge (from its lower-indexed node), so adjacent triangles share it.
 *
 * Every piece has the region it encloses on its right (r to the right, z up):
 * an open piece (ends on the mesh boundary: the axis r = 0 or the box) runs
 * from its end of larger z to the other (at equal z, from the end of smaller
 * r): from pole to pole, north to south, for a vesicle closed by the axis; a
 * closed loop runs clockwise from its point of largest z (at equal z, of
 * smallest r), first point repeated at the end. Hence for a piece,
 *   V = pi sum_seg (r_a^2 + r_a r_b + r_b^2)(z_a - z_b) / 3,
 *   A = 2 pi sum_seg (r_a + r_b)/2 |b - a|,
 * and for a vesicle closed by the axis (phi > 0 inside, away from the box)
 * the sums over all pieces are ves_level_set_eval's volume and area up to
 * rounding. Pieces are sorted by their largest z, descending (at equal
 * largest z, by the r of their first point, ascending). A point equal to
 * the previous one is dropped, so a degenerate zero segment (phi = 0 at a
 * node) leaves no duplicate; a node where phi = 0 joins the pieces through
 * it. Where the zero set branches (phi = 0 at a saddle node) the branches
 * are joined in the order of the segments' triangles.
 *
 * Arguments and errors as ves_level_set_eval; VES_ERR_ALLOC when memory
 * runs out. out is overwritten (free it with ves_level_set_curves_free). */
typedef struct {
  int npieces; /* connected pieces */
  int *start;  /* npieces + 1 offsets into the points: piece i is points
                  start[i] .. start[i+1]-1 */
  double *rz;  /* 2 per point: r, z (R0) */
  int *closed; /* per piece: 1 a closed loop (first point repeated at the
                  end), 0 open */
} ves_level_set_curves;

ves_status ves_level_set_curves_eval(int n, int ntri, const int *tri, const double *x,
                                     const double *phi, ves_level_set_curves *out);
/* Free the arrays of c and zero it (NULL is a no-op). */
void ves_level_set_curves_free(ves_level_set_curves *c);

#endif
