/* vesica — the sharp interface {phi = 0} of a nodal field on a
 * triangulation: the volume inside and the area of the zero line, in the
 * axisymmetric measure, exact for the piecewise-linear interpolant
 * (post-processing: what the nodes show, against the phase field's A, V;
 * docs/design.md, "Analysis"). */
#include "ves/level_set.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

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

/* ---- the zero set as curves ---- */

/* A point of the zero set: on the edge (lo, hi), lo < hi, key lo n + hi; at
 * the node a where phi is 0, key a n + a (distinct from every edge key). */
static int64_t pt_key(int a, int b, int n) {
  const int lo = a < b ? a : b, hi = a < b ? b : a;
  return (int64_t)lo * n + hi;
}

static int cmp_i64(const void *pa, const void *pb) {
  const int64_t a = *(const int64_t *)pa, b = *(const int64_t *)pb;
  return (a > b) - (a < b);
}

static int find_key(const int64_t *keys, int nk, int64_t k) {
  int lo = 0, hi = nk - 1;
  while (lo < hi) {
    const int mid = lo + (hi - lo) / 2;
    if (keys[mid] < k)
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo;
}

/* Piece order: largest z descending, then first r ascending, first z
 * descending, more points first, then the order found (a total order). */
typedef struct {
  double zmax, r0, z0;
  int np, idx;      /* points, order found */
  int base, closed; /* first point in the work array; 1 a loop */
} piece_key;

static int cmp_piece(const void *pa, const void *pb) {
  const piece_key *a = pa, *b = pb;
  if (a->zmax != b->zmax) return a->zmax > b->zmax ? -1 : 1;
  if (a->r0 != b->r0) return a->r0 < b->r0 ? -1 : 1;
  if (a->z0 != b->z0) return a->z0 > b->z0 ? -1 : 1;
  if (a->np != b->np) return a->np > b->np ? -1 : 1;
  return (a->idx > b->idx) - (a->idx < b->idx);
}

void ves_level_set_curves_free(ves_level_set_curves *c) {
  if (!c) return;
  free(c->start), free(c->rz), free(c->closed);
  c->start = c->closed = NULL, c->rz = NULL, c->npieces = 0;
}

/* Reverse the points p[2m] in place. */
static void reverse_pts(double *p, int m) {
  for (int i = 0, j = m - 1; i < j; i++, j--)
    for (int d = 0; d < 2; d++) {
      const double t = p[2 * i + d];
      p[2 * i + d] = p[2 * j + d], p[2 * j + d] = t;
    }
}

/* Orient and rotate one piece of m points in p (see the header): returns the
 * number of points kept (0: the piece is a single point and is dropped). */
static int orient_piece(double *p, int m, int closed, double *tmp) {
  if (m < 2) return 0;
  if (!closed) {
    const double *a = p, *b = p + 2 * (m - 1);
    if (b[1] > a[1] || (b[1] == a[1] && b[0] < a[0])) reverse_pts(p, m);
    return m;
  }
  const int k = m - 1; /* distinct vertices of the loop */
  if (k < 2) return 0;
  int top = 0;
  for (int i = 1; i < k; i++)
    if (p[2 * i + 1] > p[2 * top + 1] || (p[2 * i + 1] == p[2 * top + 1] && p[2 * i] < p[2 * top]))
      top = i;
  for (int i = 0; i < k; i++)
    tmp[2 * i] = p[2 * ((top + i) % k)], tmp[2 * i + 1] = p[2 * ((top + i) % k) + 1];
  double s = 0; /* twice the signed area (counter-clockwise > 0) */
  for (int i = 0; i < k; i++) {
    const double *a = tmp + 2 * i, *b = tmp + 2 * ((i + 1) % k);
    s += a[0] * b[1] - b[0] * a[1];
  }
  if (s > 0) reverse_pts(tmp + 2, k - 1); /* keep the start, run clockwise */
  memcpy(p, tmp, 2 * (size_t)k * sizeof *p);
  p[2 * k] = p[0], p[2 * k + 1] = p[1];
  return m;
}

/* The segments as a directed graph (exit crossing -> entry crossing of the
 * triangle's boundary walk: phi > 0 on the left in a counter-clockwise
 * triangle, so a crossing point is entered as often as it is left except on
 * the mesh boundary), walked into paths (from points left more often than
 * entered) and then loops; each piece oriented and the pieces sorted. */
ves_status ves_level_set_curves_eval(int n, int ntri, const int *tri, const double *x,
                                     const double *phi, ves_level_set_curves *out) {
  VES_CHECK(tri && x && phi && out && ntri >= 1 && n >= 3, VES_ERR_ARG);
  out->npieces = 0, out->start = out->closed = NULL, out->rz = NULL;
  for (int t = 0; t < ntri; t++)
    for (int j = 0; j < 3; j++) {
      const int a = tri[3 * t + j];
      VES_CHECK(a >= 0 && a < n, VES_ERR_ARG);
      VES_CHECK(isfinite(x[2 * a]) && isfinite(x[2 * a + 1]) && isfinite(phi[a]), VES_ERR_ARG);
    }
  ves_status st = VES_ERR_ALLOC;
  int64_t *seg = malloc(2 * (size_t)ntri * sizeof *seg), *keys = NULL;
  int *src = NULL, *dst = NULL, *outp = NULL, *ptr = NULL, *indeg = NULL, *outl = NULL;
  int *seq = NULL, *pstart = NULL, *pclosed = NULL;
  double *pts = NULL, *tmp = NULL;
  piece_key *order = NULL;
  if (!seg) goto done;
  int nseg = 0;
  for (int t = 0; t < ntri; t++) {
    const int *v = tri + 3 * t;
    int64_t ex = -1, en = -1;
    for (int j = 0; j < 3; j++) {
      const int a = v[j], b = v[(j + 1) % 3];
      const int pa = phi[a] > 0, pb = phi[b] > 0;
      if (pa == pb) continue;
      /* the crossing at s = fa / (fa - fb): at the node whose phi is 0 */
      const int64_t k = phi[a] == 0   ? pt_key(a, a, n)
                        : phi[b] == 0 ? pt_key(b, b, n)
                                      : pt_key(a, b, n);
      if (pa)
        ex = k;
      else
        en = k;
    }
    if (ex >= 0 && en >= 0 && ex != en) seg[2 * nseg] = ex, seg[2 * nseg + 1] = en, nseg++;
  }
  /* the points: the distinct keys */
  keys = malloc((2 * (size_t)nseg + 1) * sizeof *keys);
  if (!keys) goto done;
  memcpy(keys, seg, 2 * (size_t)nseg * sizeof *keys);
  qsort(keys, 2 * (size_t)nseg, sizeof *keys, cmp_i64);
  int np = 0;
  for (int i = 0; i < 2 * nseg; i++)
    if (np == 0 || keys[i] != keys[np - 1]) keys[np++] = keys[i];
  src = malloc(((size_t)nseg + 1) * sizeof *src);
  dst = malloc(((size_t)nseg + 1) * sizeof *dst);
  outp = calloc((size_t)np + 1, sizeof *outp);
  ptr = calloc((size_t)np + 1, sizeof *ptr);
  indeg = calloc((size_t)np + 1, sizeof *indeg);
  outl = malloc(((size_t)nseg + 1) * sizeof *outl);
  seq = malloc((2 * (size_t)nseg + 1) * sizeof *seq);
  pstart = malloc(((size_t)nseg + 2) * sizeof *pstart);
  pclosed = malloc(((size_t)nseg + 1) * sizeof *pclosed);
  if (!src || !dst || !outp || !ptr || !indeg || !outl || !seq || !pstart || !pclosed) goto done;
  for (int s = 0; s < nseg; s++) {
    src[s] = find_key(keys, np, seg[2 * s]), dst[s] = find_key(keys, np, seg[2 * s + 1]);
    outp[src[s] + 1]++, indeg[dst[s]]++;
  }
  for (int p = 0; p < np; p++) outp[p + 1] += outp[p];
  for (int p = 0; p < np; p++) ptr[p] = outp[p];
  for (int s = 0; s < nseg; s++) outl[ptr[src[s]]++] = s; /* in triangle order */
  for (int p = 0; p < np; p++) ptr[p] = outp[p];
  /* walk: paths from the points left more often than entered, then loops */
  int npc = 0, ns = 0;
  pstart[0] = 0;
  for (int p = 0; p < np; p++)
    for (int w = (outp[p + 1] - outp[p]) - indeg[p]; w > 0; w--) {
      int cur = p;
      seq[ns++] = cur;
      while (ptr[cur] < outp[cur + 1]) cur = dst[outl[ptr[cur]++]], seq[ns++] = cur;
      pclosed[npc] = 0, pstart[++npc] = ns;
    }
  for (int p = 0; p < np; p++)
    while (ptr[p] < outp[p + 1]) { /* every point left is balanced: back at p */
      int cur = p;
      seq[ns++] = cur;
      while (ptr[cur] < outp[cur + 1]) cur = dst[outl[ptr[cur]++]], seq[ns++] = cur;
      pclosed[npc] = cur == p, pstart[++npc] = ns;
    }
  /* coordinates, a point equal to the previous one dropped */
  pts = malloc((2 * (size_t)ns + 2) * sizeof *pts);
  tmp = malloc((2 * (size_t)ns + 2) * sizeof *tmp);
  order = malloc(((size_t)npc + 1) * sizeof *order);
  if (!pts || !tmp || !order) goto done;
  int total = 0, nkept = 0;
  for (int c = 0; c < npc; c++) {
    int m = 0;
    for (int i = pstart[c]; i < pstart[c + 1]; i++) {
      const int64_t k = keys[seq[i]];
      const int lo = (int)(k / n), hi = (int)(k % n);
      double q[2];
      if (lo == hi)
        q[0] = x[2 * lo], q[1] = x[2 * lo + 1];
      else {
        const double s = phi[lo] / (phi[lo] - phi[hi]);
        q[0] = x[2 * lo] + s * (x[2 * hi] - x[2 * lo]);
        q[1] = x[2 * lo + 1] + s * (x[2 * hi + 1] - x[2 * lo + 1]);
      }
      double *d = pts + 2 * (total + m);
      if (m > 0 && d[-2] == q[0] && d[-1] == q[1]) continue;
      d[0] = q[0], d[1] = q[1], m++;
    }
    double *P = pts + 2 * total;
    m = orient_piece(P, m, pclosed[c], tmp);
    if (m == 0) continue;
    double zmax = P[1];
    for (int i = 1; i < m; i++)
      if (P[2 * i + 1] > zmax) zmax = P[2 * i + 1];
    order[nkept] = (piece_key){zmax, P[0], P[1], m, nkept, total, pclosed[c]};
    nkept++, total += m;
  }
  qsort(order, (size_t)nkept, sizeof *order, cmp_piece);
  out->start = malloc(((size_t)nkept + 1) * sizeof *out->start);
  out->closed = malloc(((size_t)nkept + 1) * sizeof *out->closed);
  out->rz = malloc((2 * (size_t)total + 1) * sizeof *out->rz);
  if (!out->start || !out->closed || !out->rz) {
    ves_level_set_curves_free(out);
    goto done;
  }
  out->start[0] = 0;
  for (int i = 0; i < nkept; i++) {
    const piece_key *o = order + i;
    memcpy(out->rz + 2 * out->start[i], pts + 2 * o->base, 2 * (size_t)o->np * sizeof *pts);
    out->closed[i] = o->closed;
    out->start[i + 1] = out->start[i] + o->np;
  }
  out->npieces = nkept;
  st = VES_OK;
done:
  free(seg), free(keys), free(src), free(dst), free(outp), free(ptr), free(indeg), free(outl);
  free(seq), free(pstart), free(pclosed), free(pts), free(tmp), free(order);
  if (st != VES_OK) VES_FAIL(st, "out of memory in ves_level_set_curves_eval");
  return VES_OK;
}
