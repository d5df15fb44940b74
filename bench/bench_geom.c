/* vesica — benchmark of geom: adapted node sets for a sphere, quadrature size and LME neighbours.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "ves/geom.h"

/* Sizing of the sphere R0 = 1: h_band in |d| < 4 eps, slope s beyond, capped at h_far. */
typedef struct {
  double eps, h_band, s, h_far;
} sphere_sizing;

static double sphere_h(const double X[2], void *ctx) {
  const sphere_sizing *c = ctx;
  double d = 1.0 - hypot(X[0], X[1]); /* signed distance, > 0 inside */
  return fmin(c->h_band + c->s * fmax(0.0, fabs(d) - 4 * c->eps), c->h_far);
}

static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

/* One row of the table; returns 0 on success. */
static int run(double eps) {
  const double gamma = 0.8, tol0 = 1e-6;
  /* Dunavant degree-4 rule: barycentric (a, a, 1-2a) and permutations */
  const double da[2] = {0.445948490915965, 0.091576213509771};
  sphere_sizing sz = {eps, 0.5 * eps, 0.15, 0.2};
  ves_nodes_params par;
  ves_nodes_params_default(&par);
  par.LR = 2, par.LZ = 2, par.h = sphere_h, par.h_ctx = &sz;
  ves_nodes *nd = NULL;
  double t0 = now();
  ves_status st = ves_nodes_generate(&par, &nd);
  double tgen = now() - t0;
  if (st != VES_OK) {
    fprintf(stderr, "bench_geom: ves_nodes_generate: %s\n", ves_status_str(st));
    return 1;
  }
  int n = nd->n, ne = n + nd->ng, ntri = 0, *tri = NULL, *idx = NULL;
  double *xe = malloc(sizeof(double) * 2 * (size_t)ne), *rad = malloc(sizeof(double) * (size_t)ne);
  ves_geom_search *s = NULL;
  int rc = 1;
  if (!xe || !rad) goto done;
  ves_nodes_extended(nd, xe);
  for (int a = 0; a < ne; a++) /* support radius: beta_a r^2 = -ln tol0, beta_a = gamma/h_a^2 */
    rad[a] = nd->h[a < n ? a : nd->ghost_of[a - n]] * sqrt(-log(tol0) / gamma);
  t0 = now();
  if (ves_geom_delaunay(n, nd->x, &ntri, &tri) != VES_OK) goto done;
  if (ves_geom_search_create(ne, xe, rad, &s) != VES_OK) goto done;
  int cap = ne;
  idx = malloc(sizeof(int) * (size_t)cap);
  if (!idx) goto done;
  long hits = 0;
  for (int t = 0; t < ntri; t++)
    for (int q = 0; q < 6; q++) {
      double a = da[q / 3], b[3] = {a, a, a};
      b[q % 3] = 1 - 2 * a;
      double X[2] = {0, 0};
      for (int k = 0; k < 3; k++)
        X[0] += b[k] * nd->x[2 * tri[3 * t + k]], X[1] += b[k] * nd->x[2 * tri[3 * t + k] + 1];
      int c = 0;
      if (ves_geom_search_query(s, X, cap, idx, &c) != VES_OK) goto done;
      hits += c;
    }
  double tsearch = now() - t0;
  printf("%6.3f %7d %7d %8d %9d %8.2f %7.1f %9.2f %9.2f\n", eps, n, nd->ng, ntri, 6 * ntri,
         6.0 * ntri / n, (double)hits / (6.0 * ntri), tgen, tsearch);
  rc = 0;
done:
  if (rc) fprintf(stderr, "bench_geom: failed at eps = %g\n", eps);
  ves_geom_search_destroy(&s);
  ves_nodes_destroy(&nd);
  free(xe), free(rad), free(tri), free(idx);
  return rc;
}

int main(void) {
  printf("sphere R0 = 1 in [0,2]x[-2,2]; h_band = 0.5 eps, slope 0.15, h_far = 0.2;\n"
         "m = mean neighbours (real + ghost nodes) at the 6 Dunavant points of every\n"
         "Delaunay triangle of the real nodes, gamma = 0.8, tol0 = 1e-6\n");
  printf("%6s %7s %7s %8s %9s %8s %7s %9s %9s\n", "eps", "nodes", "ghosts", "tri", "qpoints",
         "qp/node", "m", "gen[s]", "tri+m[s]");
  const double eps[3] = {0.04, 0.02, 0.01};
  for (int i = 0; i < 3; i++)
    if (run(eps[i])) return 1;
  return 0;
}
