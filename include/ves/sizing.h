/* vesica — the node sizing field of an initial shape: the target spacing
 * h(X) of the adapted node set, from the shape's signed distance
 * (docs/design.md, "Discretization"). */
#ifndef VES_SIZING_H
#define VES_SIZING_H

#include "ves/shape.h"
#include "ves/status.h"

/* Node sizing: h = h_band for |d| < band*eps, then growing linearly with
 * `slope` to h_far. d is tabulated on a grid (spacing <= h_band) and
 * interpolated bilinearly, so an evaluation is O(1). */
typedef struct {
  double eps;     /* interface width eps (units R0) */
  double h_band;  /* spacing in the band (default 0.5 eps) */
  double band;    /* half-width of the band in units of eps (default 4) */
  double slope;   /* growth rate of h away from the band (default 0.15, < 0.2) */
  double h_far;   /* largest spacing (default 0.2) */
  double reserve; /* ves_sizing_reserved is true where |d| < reserve (0: never) */
} ves_sizing_params;

typedef struct ves_sizing ves_sizing;

/* The field of shape s (read during the call only: |d| is tabulated) in the
 * box [0, LR] x [-LZ, LZ]; *out is taken by the caller. VES_ERR_ARG for a
 * NULL pointer, a box or parameter out of range (h_far < h_band, slope <= 0). */
ves_status ves_sizing_create(const ves_shape *s, const ves_sizing_params *par, double LR, double LZ,
                             ves_sizing **out);
/* Free; accepts NULL and sets *z to NULL. */
void ves_sizing_destroy(ves_sizing **z);
/* ves_sizing_fn-compatible: ctx is a ves_sizing *. */
double ves_sizing_eval(const double X[2], void *ctx);
/* ves_region_fn-compatible: 1 where |d(X)| < reserve (the band layers' own
 * region, kept free of strip and CVT nodes), else 0. ctx is a ves_sizing *. */
int ves_sizing_reserved(const double X[2], void *ctx);

#endif
