/* vesica — the model's thread scheduling (model_assemble.c runs the loops):
 * triangles are visited along a Morton curve so the pattern rows they touch
 * stay in cache. Threads (OpenMP, the count fixed at create from
 * omp_get_max_threads(), i.e. OMP_NUM_THREADS or all cores): the nodes are
 * split into slabs in Z of equal work, each thread writes only the rows of
 * its slab and visits the triangles whose unions meet it (those straddling
 * two slabs are computed by both, ~a few %). Every block and gradient entry
 * thus receives its contributions in the same order for any thread count
 * (docs/design.md, "Numerical choices and why"). */
#include "model/model_core_impl.h"

#include <stdlib.h>

/* Morton (Z-order) key of a point of the unit square: the bits of
 * 16-bit coordinates interleaved. */
static unsigned long morton_key(double x, double z) {
  unsigned long key = 0, ix = (unsigned long)(x * 65535.0), iz = (unsigned long)(z * 65535.0);
  for (int b = 0; b < 16; b++)
    key |= ((ix >> b) & 1UL) << (2 * b) | ((iz >> b) & 1UL) << (2 * b + 1);
  return key;
}

typedef struct {
  unsigned long key;
  int t;
} key_index;

static int cmp_key(const void *a, const void *b) {
  const key_index *x = a, *y = b;
  if (x->key != y->key) return x->key < y->key ? -1 : 1;
  return (x->t > y->t) - (x->t < y->t);
}

/* m->torder: the triangles sorted by the Morton key of their centroids in
 * the bounding box of the nodes. */
ves_status model_order_triangles(ves_model *m) {
  const ves_quad *q = m->q;
  const double *x = m->nodes->x;
  const int n = m->nodes->n;
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  key_index *ki = malloc((size_t)q->ntri * sizeof *ki);
  m->torder = malloc((size_t)q->ntri * sizeof *m->torder);
  if (!ki || !m->torder) {
    free(ki);
    return VES_ERR_ALLOC;
  }
  for (int a = 0; a < n; a++)
    for (int d = 0; d < 2; d++)
      lo[d] = fmin(lo[d], x[2 * a + d]), hi[d] = fmax(hi[d], x[2 * a + d]);
  for (int t = 0; t < q->ntri; t++) {
    double c[2];
    for (int d = 0; d < 2; d++) {
      c[d] =
          (x[2 * q->tri[3 * t] + d] + x[2 * q->tri[3 * t + 1] + d] + x[2 * q->tri[3 * t + 2] + d]) /
          3;
      c[d] = hi[d] > lo[d] ? (c[d] - lo[d]) / (hi[d] - lo[d]) : 0.0;
      c[d] = fmin(fmax(c[d], 0.0), 1.0);
    }
    ki[t].key = morton_key(c[0], c[1]), ki[t].t = t;
  }
  qsort(ki, (size_t)q->ntri, sizeof *ki, cmp_key);
  for (int t = 0; t < q->ntri; t++) m->torder[t] = ki[t].t;
  free(ki);
  return VES_OK;
}

/* Slab of a node at height z: the number of thresholds at or below z. */
static int slab_of(const double *zcut, int nthr, double z) {
  int k = 0;
  while (k < nthr - 1 && zcut[k] <= z) k++;
  return k;
}

typedef struct {
  double z, w;
} zw_pair;

static int cmp_z(const void *a, const void *b) {
  double za = ((const zw_pair *)a)->z, zb = ((const zw_pair *)b)->z;
  return (za > zb) - (za < zb);
}

/* Split the nodes into m->nthr slabs in Z of about equal assembly work (a
 * node's work: over the triangles whose union holds it at position i, i + 1
 * pairs per point that sees it) and give every triangle the slab range of
 * its union. One serial pass over the triangles (setup cost). */
ves_status model_make_slabs(ves_model *m) {
  const ves_quad *q = m->q;
  const int n = m->nodes->n, ntri = q->ntri, T = m->nthr;
  model_ws *w = m->ws;
  double *work = calloc((size_t)n, sizeof *work), *zlo = NULL, *zhi = NULL, zcut[64];
  zw_pair *zs = NULL;
  ves_status s = VES_ERR_ALLOC;
  m->owner = malloc((size_t)n * sizeof *m->owner);
  m->tlo = malloc((size_t)ntri * sizeof *m->tlo);
  m->thi = malloc((size_t)ntri * sizeof *m->thi);
  zlo = malloc((size_t)ntri * sizeof *zlo);
  zhi = malloc((size_t)ntri * sizeof *zhi);
  zs = malloc((size_t)n * sizeof *zs);
  if (!work || !m->owner || !m->tlo || !m->thi || !zlo || !zhi || !zs) goto done;
  for (int t = 0; t < ntri; t++) {
    folded f[NPT];
    const int *U;
    int nu = model_triangle_union(m, w, t, f, &U);
    if (nu > m->numax) m->numax = nu;
    zlo[t] = INFINITY, zhi[t] = -INFINITY;
    for (int i = 0; i < nu; i++) {
      double z = m->nodes->x[2 * U[i] + 1];
      zlo[t] = fmin(zlo[t], z), zhi[t] = fmax(zhi[t], z);
    }
    for (int p = 0; p < NPT; p++)
      for (int u = 0; u < f[p].mu; u++) work[f[p].un[u]] += w->slot[f[p].un[u]] + 1;
  }
  double total = 0;
  for (int a = 0; a < n; a++) {
    zs[a].z = m->nodes->x[2 * a + 1], zs[a].w = work[a];
    total += work[a];
  }
  qsort(zs, (size_t)n, sizeof *zs, cmp_z);
  for (int k = 0; k < T - 1; k++) { /* zcut[k]: the lowest z of slab k + 1 */
    double acc = 0, target = total * (k + 1) / T;
    int a = 0;
    while (a < n && acc < target) acc += zs[a++].w;
    zcut[k] = a < n ? zs[a].z : INFINITY;
  }
  for (int a = 0; a < n; a++) m->owner[a] = slab_of(zcut, T, m->nodes->x[2 * a + 1]);
  for (int t = 0; t < ntri; t++)
    m->tlo[t] = slab_of(zcut, T, zlo[t]), m->thi[t] = slab_of(zcut, T, zhi[t]);
  s = VES_OK;
done:
  free(work), free(zlo), free(zhi), free(zs);
  return s;
}
