/* vesica — initial vesicle shapes: axisymmetric generating curves with an exact
 * signed distance d(R, Z) (> 0 inside), their sharp area and volume, the
 * phase-field phi0 = tanh(d / (sqrt2 eps)) (the node sizing field: sizing.h;
 * docs/design.md, "Discretization"). */
#ifndef VES_SHAPE_H
#define VES_SHAPE_H

#include "ves/status.h"

typedef enum {
  VES_SHAPE_SPHERE = 0,    /* circle of radius `radius` */
  VES_SHAPE_SPHEROID = 1,  /* ellipse with reduced volume v, area 4 pi */
  VES_SHAPE_DISCOCYTE = 2, /* Evans-Fung biconcave disc, area 4 pi */
  VES_SHAPE_CURVE = 3      /* points (R, Z) from the north pole to the south pole,
                              periodic cubic spline (with the mirror image) by
                              chord length, scaled to area 4 pi */
} ves_shape_kind;

/* What the user gives. Lengths in units of R0 = sqrt(A0 / 4 pi). */
typedef struct {
  ves_shape_kind kind;
  double radius;     /* sphere radius (default 1) */
  double v;          /* spheroid: reduced volume in (0, 1] (default 0.9) */
  int prolate;       /* spheroid: 1 long axis along Z (prolate), 0 oblate */
  int mode;          /* perturbation: the curve is scaled radially by
                        1 + delta P_mode(cos t), t the polar parameter; 0 = none */
  double delta;      /* perturbation amplitude (|delta| < 0.5) */
  int npts;          /* curve: number of points (>= 4), first and last on the axis */
  const double *pts; /* curve: 2 npts coordinates (R >= 0, Z), copied */
  int keep_scale;    /* curve: 1 keeps the points' own scale (an interface
                        extracted from a state, remesh.h), 0 (default) scales
                        the curve to area 4 pi */
} ves_shape_params;

typedef struct ves_shape ves_shape;

/* Defaults: unit sphere, no perturbation. */
void ves_shape_params_default(ves_shape_params *par);

/* Build the shape (for spheroids and discocytes: solve for the semi-axes /
 * scale with area 4 pi). par is copied. A curve scaled to area 4 pi whose
 * spline leaves R > 0 between the poles or encloses no area or volume (it
 * can, through a valid polygon: a long segment after short ones) is
 * VES_ERR_GEOM. */
ves_status ves_shape_create(const ves_shape_params *par, ves_shape **out);
void ves_shape_destroy(ves_shape **s);

/* Signed distance to the generating curve, > 0 inside, exact to rounding
 * (closest point by safeguarded Newton on the curve parameter). NaN for a
 * non-finite X (both functions below). */
double ves_shape_distance(const ves_shape *s, const double X[2]);

/* The same distance by the plain coarse search (|P(t_i) - X| at every
 * sample), which ves_shape_distance prunes by bounds on blocks of samples:
 * the two agree bit for bit (tests/test_shape.c); ~3.5x slower. */
double ves_shape_distance_reference(const ves_shape *s, const double X[2]);

/* Sharp area and enclosed volume of the surface of revolution. */
void ves_shape_sharp(const ves_shape *s, double *area, double *volume);

/* Sharp Helfrich energy (1/2) int (H - C0)^2 dA / k of the surface of
 * revolution, H = (k1 + k2)/2 (k1 meridional, k2 parallel curvature; 1/R for
 * a sphere of radius R, so a sphere gives 2 pi (1 - C0 R)^2). */
double ves_shape_sharp_energy(const ves_shape *s, double c0);

/* Largest R and |Z| on the generating curve (from its samples). */
void ves_shape_extent(const ves_shape *s, double *rmax, double *zmax);

/* Length of the generating curve from pole to pole (the meridian; pi R for a
 * sphere), from its samples (relative error ~1e-6). */
double ves_shape_length(const ves_shape *s);

/* Semi-axes (equatorial along R, polar along Z) of the unperturbed curve. */
void ves_shape_axes(const ves_shape *s, double *a, double *c);

/* phi0(X) = tanh(d(X) / (sqrt2 eps)). */
double ves_shape_phi0(const ves_shape *s, double eps, const double X[2]);

/* Interface-aligned band nodes: layers at signed distance d_j = j (sqrt3/2) h,
 * |d_j| <= halfwidth, each the offset curve P(t) + d_j n_in(t) with nodes at
 * equal arclength h_j ~ h from the north pole, odd layers shifted by h_j / 2:
 * a hexagonal lattice bent along the interface, and at each pole an axis node
 * (even layers) or a mirrored pair at +-h_j/2 (odd layers), i.e. regular
 * through the axis. Nodes whose exact distance is not their layer's (offset
 * layers of two branches overlapping, as in a thin discocyte centre) are
 * dropped. *x (2 *n) and *flag (*n, VES_NODE_AXIS on R = 0) are taken by the
 * caller. VES_ERR_GEOM when a layer folds (halfwidth beyond a curvature
 * radius). */
ves_status ves_shape_band_nodes(const ves_shape *s, double h, double halfwidth, int *n, double **x,
                                int **flag);

#endif
