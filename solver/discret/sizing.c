/* vesica — the node sizing field: h = h_band within band eps of the
 * interface, growing with `slope` to h_far, from |d| (ves_shape_distance)
 * tabulated on a grid and interpolated bilinearly (O(1) an evaluation;
 * docs/design.md, "Discretization"). */
#include "ves/sizing.h"

#include <math.h>
#include <stdlib.h>

struct ves_sizing {
  ves_sizing_params par;
  double LR, LZ, g; /* box and grid spacing */
  int nr, nz;       /* grid points along R and Z */
  double *ad;       /* nr * nz values of |d| */
};

ves_status ves_sizing_create(const ves_shape *s, const ves_sizing_params *par, double LR, double LZ,
                             ves_sizing **out) {
  VES_CHECK(s && par && out && LR > 0 && LZ > 0, VES_ERR_ARG);
  VES_CHECK(par->eps > 0 && par->h_band > 0 && par->band >= 0 && par->slope > 0 &&
                par->h_far >= par->h_band && par->reserve >= 0,
            VES_ERR_ARG);
  *out = NULL;
  ves_sizing *z = calloc(1, sizeof *z);
  if (!z) return VES_ERR_ALLOC;
  z->par = *par;
  z->LR = LR, z->LZ = LZ;
  /* grid spacing: 2 h_band (bilinear error ~ g^2 kappa / 8, far below h), at
   * most 4000 cells a side */
  z->g = fmax(2 * par->h_band, fmax(LR, 2 * LZ) / 4000);
  z->nr = (int)ceil(LR / z->g) + 1;
  z->nz = (int)ceil(2 * LZ / z->g) + 1;
  z->ad = malloc((size_t)z->nr * z->nz * sizeof *z->ad);
  if (!z->ad) {
    free(z);
    return VES_ERR_ALLOC;
  }
  /* independent evaluations of a read-only shape, on the OpenMP threads */
#pragma omp parallel for schedule(dynamic, 8)
  for (int j = 0; j < z->nz; j++)
    for (int i = 0; i < z->nr; i++) {
      double X[2] = {i * z->g, -LZ + j * z->g};
      z->ad[(size_t)j * z->nr + i] = fabs(ves_shape_distance(s, X));
    }
  *out = z;
  return VES_OK;
}

void ves_sizing_destroy(ves_sizing **z) {
  if (!z || !*z) return;
  free((*z)->ad);
  free(*z);
  *z = NULL;
}

/* |d(X)| interpolated bilinearly on the grid (extrapolated slightly outside). */
static double grid_abs_d(const ves_sizing *z, const double X[2]) {
  double u = X[0] / z->g, w = (X[1] + z->LZ) / z->g;
  int i = (int)floor(u), j = (int)floor(w);
  if (i < 0) i = 0;
  if (j < 0) j = 0;
  if (i > z->nr - 2) i = z->nr - 2;
  if (j > z->nz - 2) j = z->nz - 2;
  double fu = u - i, fw = w - j;
  const double *a = z->ad + (size_t)j * z->nr + i;
  return (1 - fu) * (1 - fw) * a[0] + fu * (1 - fw) * a[1] + (1 - fu) * fw * a[z->nr] +
         fu * fw * a[z->nr + 1];
}

/* h(X) = min(h_far, h_band + slope max(0, |d(X)| - band eps)). */
double ves_sizing_eval(const double X[2], void *ctx) {
  const ves_sizing *z = ctx;
  double d = grid_abs_d(z, X);
  double h = z->par.h_band + z->par.slope * fmax(0.0, d - z->par.band * z->par.eps);
  return h < z->par.h_far ? h : z->par.h_far;
}

/* 1 where |d(X)| < reserve: the band left to the caller's layered nodes. */
int ves_sizing_reserved(const double X[2], void *ctx) {
  const ves_sizing *z = ctx;
  return z->par.reserve > 0 && grid_abs_d(z, X) < z->par.reserve;
}
