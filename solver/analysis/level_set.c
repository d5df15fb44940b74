/* vesica — the sharp interface {phi = 0} of a nodal field on a
 * triangulation: the volume inside and the area of the zero line, in the
 * axisymmetric measure, exact for the piecewise-linear interpolant
 * (post-processing: what the nodes show, against the phase field's A, V;
 * docs/design.md, "Analysis"). */
#include "ves/level_set.h"

#include <math.h>

/* int r dA over a polygon (r, z) of k vertices, signed by orientation:
 * (1/6) sum (r_i + r_j)(r_i z_j - r_j z_i). */
static double poly_r_moment(int k, const double *p) {
  double s = 0;
  for (int i = 0; i < k; i++) {
    const double *a = p + 2 * i, *b = p + 2 * ((i + 1) % k);
    s += (a[0] + b[0]) * (a[0] * b[1] - b[0] * a[1]);
  }
  return s / 6;
}

/* Per triangle, the linear interpolant's zero segment and the part with
 * phi > 0: V += 2 pi int r dA over that part, A += 2 pi int r ds along the
 * segment (exact for piecewise-linear phi). */
ves_status ves_level_set_eval(int n, int ntri, const int *tri, const double *x, const double *phi,
                              ves_level_set *out) {
  VES_CHECK(tri && x && phi && out && ntri >= 1 && n >= 3, VES_ERR_ARG);
  double vol = 0, area = 0;
  int inv = 0;
  for (int t = 0; t < ntri; t++) {
    const int *v = tri + 3 * t;
    for (int j = 0; j < 3; j++) {
      VES_CHECK(v[j] >= 0 && v[j] < n, VES_ERR_ARG);
      VES_CHECK(isfinite(x[2 * v[j]]) && isfinite(x[2 * v[j] + 1]) && isfinite(phi[v[j]]),
                VES_ERR_ARG);
    }
    double P[6], f[3];
    for (int j = 0; j < 3; j++)
      P[2 * j] = x[2 * v[j]], P[2 * j + 1] = x[2 * v[j] + 1], f[j] = phi[v[j]];
    if ((P[2] - P[0]) * (P[5] - P[1]) - (P[4] - P[0]) * (P[3] - P[1]) <= 0) inv++;
    /* clip by phi > 0 (Sutherland-Hodgman, one line): at most 4 vertices;
     * the crossing points of the edges are the zero segment */
    double C[8], Z[4];
    int k = 0, nz = 0;
    for (int j = 0; j < 3; j++) {
      const int i2 = (j + 1) % 3;
      const double *a = P + 2 * j, *b = P + 2 * i2;
      const double fa = f[j], fb = f[i2];
      if (fa > 0) C[2 * k] = a[0], C[2 * k + 1] = a[1], k++;
      if ((fa > 0) != (fb > 0)) { /* the edge crosses phi = 0 at s */
        const double s = fa / (fa - fb);
        const double q0 = a[0] + s * (b[0] - a[0]), q1 = a[1] + s * (b[1] - a[1]);
        C[2 * k] = q0, C[2 * k + 1] = q1, k++;
        if (nz < 2) Z[2 * nz] = q0, Z[2 * nz + 1] = q1, nz++;
      }
    }
    if (k >= 3) vol += poly_r_moment(k, C);
    if (nz == 2) area += 0.5 * (Z[0] + Z[2]) * hypot(Z[2] - Z[0], Z[3] - Z[1]);
  }
  out->volume = 2 * M_PI * vol;
  out->area = 2 * M_PI * area;
  out->inverted = inv;
  return VES_OK;
}
