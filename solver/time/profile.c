/* vesica — restoration of the phase field's profile (profile.h): phi0 at
 * every point replaced by tanh(d / (sqrt 2 eps)) of the signed distance of
 * the point's current position to the current zero set, then fitted onto
 * the basis (L2 projection). The zero set: the crossing points of the
 * Delaunay cells' edges by the linear interpolant of phi at the nodes'
 * material positions, chained into a polyline; the distance to the
 * polyline plus the sag of the circular arc through consecutive crossing
 * points (docs/results.md, "Shape-mode rates against the Stokes
 * reference"). */
#include "ves/profile.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "ves/project.h"
#include "ves/quad.h"

struct ves_profile {
  const ves_model *model; /* the model the tables and coefficients belong to */
  ves_quad *at_nodes;     /* points at its nodes, with tables */
  ves_projector *proj;    /* the L2 projection on its points, factorized */
  int n;                  /* its real nodes */
  double *c;              /* n: nodal coefficients of its phi0 */
  int have_c;             /* c holds them */
};

/* One segment of the zero set in one cell: ends P, Q (current r, z), the
 * cell's phi gradient g (points inside), the edge keys of its ends, the
 * neighbour across each end (-1: none) and the signed curvature at each
 * end (> 0: centre inside). */
typedef struct {
  double p[4], g[2], kap[2];
  uint64_t key[2];
  int nb[2];
} segment;

typedef struct {
  uint64_t key;
  int seg, end;
} end_ref;

ves_status ves_profile_create(ves_profile **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = calloc(1, sizeof **out);
  return *out ? VES_OK : VES_ERR_ALLOC;
}

void ves_profile_forget(ves_profile *p) {
  if (!p) return;
  ves_quad_destroy(&p->at_nodes);
  ves_projector_destroy(&p->proj);
  free(p->c);
  p->c = NULL, p->have_c = 0, p->model = NULL, p->n = 0;
}

void ves_profile_destroy(ves_profile **p) {
  if (!p || !*p) return;
  ves_profile_forget(*p);
  free(*p);
  *p = NULL;
}

const double *ves_profile_coefficients(const ves_profile *p) {
  return p && p->have_c ? p->c : NULL;
}

/* The tables at the nodes of m and the coefficients of its phi0 (the L2 fit
 * of its point values: the field lies in the basis' span to the fit's
 * tolerance). */
static ves_status bind(ves_profile *p, const ves_model *m) {
  if (p->model == m && p->have_c) return VES_OK;
  ves_profile_forget(p);
  const ves_nodes *nd = ves_model_nodes(m);
  const ves_quad *q = ves_model_quad(m);
  p->n = nd->n;
  p->c = malloc((size_t)p->n * sizeof *p->c);
  double *pd = malloc(6 * (size_t)q->nq * sizeof *pd);
  ves_status st = p->c && pd ? VES_OK : VES_ERR_ALLOC;
  if (st == VES_OK) st = ves_quad_create_at_nodes(nd, &p->at_nodes);
  if (st == VES_OK) st = ves_quad_tables(p->at_nodes, nd, &q->lme, NULL);
  if (st == VES_OK) st = ves_projector_create(q, p->n, &p->proj);
  if (st == VES_OK) {
    ves_model_point_data(m, pd);
    for (int al = 0; al < q->nq; al++) pd[al] = pd[6 * (size_t)al];
    st = ves_projector_apply(p->proj, pd, p->c, 1e-12, 3);
    if (st == VES_MAXITER) st = VES_OK; /* the best iterate: far below the band's resolution */
  }
  free(pd);
  if (st != VES_OK) {
    ves_profile_forget(p);
    return st;
  }
  p->model = m, p->have_c = 1;
  return VES_OK;
}

static int cmp_end(const void *a, const void *b) {
  const end_ref *x = a, *y = b;
  if (x->key != y->key) return x->key < y->key ? -1 : 1;
  return x->seg - y->seg;
}

/* The crossing point of edge (a, b), a < b, computed in that order so that
 * the two cells sharing the edge get the same point bit for bit. */
static void crossing(const double *xy, const double *f, int a, int b, double out[2]) {
  const double s = f[a] / (f[a] - f[b]);
  out[0] = xy[2 * a] + s * (xy[2 * b] - xy[2 * a]);
  out[1] = xy[2 * a + 1] + s * (xy[2 * b + 1] - xy[2 * a + 1]);
}

/* The segments of the zero set on the cells: *out (taken), *nseg. */
static ves_status zero_segments(int n, int ncell, const int *cells, const double *xy,
                                const double *f, segment **out, int *nseg) {
  segment *sg = malloc(((size_t)ncell + 1) * sizeof *sg);
  if (!sg) return VES_ERR_ALLOC;
  int ns = 0;
  for (int t = 0; t < ncell; t++) {
    const int *v = cells + 3 * t;
    if (v[0] >= n || v[1] >= n || v[2] >= n) continue;
    double P[4];
    uint64_t key[2];
    int k = 0;
    for (int j = 0; j < 3; j++) {
      int a = v[j], b = v[(j + 1) % 3];
      if ((f[a] > 0) == (f[b] > 0)) continue;
      if (a > b) {
        const int tmp = a;
        a = b, b = tmp;
      }
      if (k < 2) crossing(xy, f, a, b, P + 2 * k), key[k] = (uint64_t)a * (uint64_t)n + (uint64_t)b;
      k++;
    }
    if (k != 2) continue;
    /* the linear interpolant's gradient on the cell */
    const double *A = xy + 2 * v[0], *B = xy + 2 * v[1], *C = xy + 2 * v[2];
    const double e1r = B[0] - A[0], e1z = B[1] - A[1], e2r = C[0] - A[0], e2z = C[1] - A[1];
    const double det = e1r * e2z - e2r * e1z, df1 = f[v[1]] - f[v[0]], df2 = f[v[2]] - f[v[0]];
    if (det == 0) continue;
    segment *s = sg + ns++;
    memcpy(s->p, P, sizeof P);
    s->g[0] = (df1 * e2z - df2 * e1z) / det;
    s->g[1] = (-df1 * e2r + df2 * e1r) / det;
    s->key[0] = key[0], s->key[1] = key[1];
    s->nb[0] = s->nb[1] = -1;
    s->kap[0] = s->kap[1] = 0;
  }
  *out = sg, *nseg = ns;
  return VES_OK;
}

/* The neighbour of each segment across each end (the shared edge key). */
static ves_status link_ends(segment *sg, int ns) {
  end_ref *e = malloc(2 * ((size_t)ns + 1) * sizeof *e);
  if (!e) return VES_ERR_ALLOC;
  for (int i = 0; i < ns; i++)
    for (int j = 0; j < 2; j++) e[2 * i + j] = (end_ref){sg[i].key[j], i, j};
  qsort(e, 2 * (size_t)ns, sizeof *e, cmp_end);
  for (int i = 0; i + 1 < 2 * ns; i++)
    if (e[i].key == e[i + 1].key) {
      sg[e[i].seg].nb[e[i].end] = e[i + 1].seg;
      sg[e[i + 1].seg].nb[e[i + 1].end] = e[i].seg;
      i++;
    }
  free(e);
  return VES_OK;
}

/* The vertices of the chain through segment s0 entered at its end e0, into
 * v[2 *nv] (room for ns + 1); seen[] marks the segments walked; *closed 1
 * when the walk came back to s0. *orient
 * +1 when the inside lies left of the chain's direction. */
static void walk(const segment *sg, int s0, int e0, char *seen, double *v, int *nv, int *closed,
                 double *orient) {
  int cur = s0, e = e0, k = 0;
  v[0] = sg[s0].p[2 * e0], v[1] = sg[s0].p[2 * e0 + 1], k = 1;
  const double tr = sg[s0].p[2 * (1 - e0)] - v[0], tz = sg[s0].p[2 * (1 - e0) + 1] - v[1];
  *orient = -tz * sg[s0].g[0] + tr * sg[s0].g[1] >= 0 ? 1.0 : -1.0;
  *closed = 0;
  for (;;) {
    seen[cur] = 1;
    const int far = 1 - e;
    v[2 * k] = sg[cur].p[2 * far], v[2 * k + 1] = sg[cur].p[2 * far + 1], k++;
    const int nx = sg[cur].nb[far];
    if (nx < 0) break;
    if (nx == s0) {
      *closed = 1, k--; /* the last vertex is the first */
      break;
    }
    if (seen[nx]) break;
    e = sg[nx].key[0] == sg[cur].key[far] ? 0 : 1;
    cur = nx;
  }
  *nv = k;
}

/* The chain's vertex i smoothed by a weighted quadratic least-squares fit
 * of r(s), z(s) over the arc length |s| <= w (weights (1 - (s/w)^2)^2), with
 * the chain continued by its mirror image across the axis at an end on it,
 * or periodically when closed: out (r, z) and the signed curvature kap
 * (> 0 towards the left of the chain's direction). The fit removes the
 * grid-scale scatter of the crossing points (the L2 fit of phi oscillates
 * by ~1e-3 at the node scale) and keeps every wavelength >> w. */
static void smooth_vertex(const double *v, int nv, int closed, int i, double w, double out[2],
                          double *kap) {
  double M[3][3] = {{0}}, br[3] = {0}, bz[3] = {0};
  for (int d0 = -1; d0 <= 1; d0 += 2) {
    int j = i, dir = d0, mirror = 0;
    double sacc = 0, px = v[2 * i], pz = v[2 * i + 1];
    for (int step = 0; step < 2 * nv + 4; step++) {
      if (step > 0 || d0 > 0) { /* the vertex itself once, then its neighbours */
        int jn = j + dir;
        if (closed)
          jn = (jn + nv) % nv;
        else if (jn < 0 || jn >= nv) {
          /* j is an end: on the axis the chain goes on as its mirror image */
          if (mirror || fabs(v[2 * j]) > 1e-12) break;
          mirror = 1, dir = -dir, jn = j + dir;
          if (jn < 0 || jn >= nv) break;
        }
        j = jn;
        const double qr = mirror ? -v[2 * j] : v[2 * j], qz = v[2 * j + 1];
        sacc += hypot(qr - px, qz - pz);
        px = qr, pz = qz;
        if (sacc >= w) break;
      }
      const double sg = d0 * sacc, t = sacc / w, wt = (1 - t * t) * (1 - t * t);
      const double ph[3] = {1, sg, sg * sg};
      for (int a = 0; a < 3; a++) {
        for (int b = 0; b < 3; b++) M[a][b] += wt * ph[a] * ph[b];
        br[a] += wt * ph[a] * px, bz[a] += wt * ph[a] * pz;
      }
    }
  }
  /* solve M c = b by Cramer's rule (3 x 3, well conditioned for >= 3 points) */
  const double det = M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1]) -
                     M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) +
                     M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0]);
  if (!(fabs(det) > 0)) {
    out[0] = v[2 * i], out[1] = v[2 * i + 1], *kap = 0;
    return;
  }
  double cr[3], cz[3];
  for (int k = 0; k < 3; k++) {
    double A[3][3];
    memcpy(A, M, sizeof A);
    for (int a = 0; a < 3; a++) A[a][k] = br[a];
    cr[k] = (A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) -
             A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
             A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0])) /
            det;
    memcpy(A, M, sizeof A);
    for (int a = 0; a < 3; a++) A[a][k] = bz[a];
    cz[k] = (A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) -
             A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
             A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0])) /
            det;
  }
  out[0] = cr[0], out[1] = cz[0];
  const double r1 = cr[1], z1 = cz[1], r2 = 2 * cr[2], z2 = 2 * cz[2];
  const double sp = hypot(r1, z1);
  *kap = sp > 0 ? (r1 * z2 - z1 * r2) / (sp * sp * sp) : 0;
}

/* The zero set as smoothed chains: the segments between consecutive
 * smoothed vertices, each end's curvature signed > 0 when the centre lies
 * inside. *out (taken), *nout. */
static ves_status smooth_chains(segment *sg, int ns, double w, segment **out, int *nout) {
  char *seen = calloc((size_t)ns + 1, 1);
  double *v = malloc(2 * ((size_t)ns + 2) * sizeof *v),
         *sv = malloc(3 * ((size_t)ns + 2) * sizeof *sv);
  segment *o = malloc(((size_t)ns + 1) * sizeof *o);
  if (!seen || !v || !sv || !o) {
    free(seen), free(v), free(sv), free(o);
    return VES_ERR_ALLOC;
  }
  int no = 0;
  for (int pass = 0; pass < 2; pass++) /* open chains from their free ends first */
    for (int s0 = 0; s0 < ns; s0++) {
      if (seen[s0]) continue;
      int e0 = -1;
      if (pass == 0) {
        if (sg[s0].nb[0] < 0)
          e0 = 0;
        else if (sg[s0].nb[1] < 0)
          e0 = 1;
        else
          continue;
      } else
        e0 = 0;
      int nv, closed;
      double orient;
      walk(sg, s0, e0, seen, v, &nv, &closed, &orient);
      for (int i = 0; i < nv; i++) {
        smooth_vertex(v, nv, closed, i, w, sv + 3 * i, sv + 3 * i + 2);
        sv[3 * i + 2] *= orient;
      }
      const int nsegs = closed ? nv : nv - 1;
      for (int i = 0; i < nsegs; i++) {
        const int a = i, b = (i + 1) % nv;
        segment *t = o + no++;
        t->p[0] = sv[3 * a], t->p[1] = sv[3 * a + 1], t->p[2] = sv[3 * b], t->p[3] = sv[3 * b + 1];
        t->kap[0] = sv[3 * a + 2], t->kap[1] = sv[3 * b + 2];
      }
    }
  free(seen), free(v), free(sv);
  *out = o, *nout = no;
  return VES_OK;
}

/* Signed distance of x to the zero set (sign: sgn, the side of phi). */
static double signed_distance(const segment *sg, int ns, const double x[2], double sgn) {
  double best = INFINITY, corr = 0;
  for (int i = 0; i < ns; i++) {
    const double *P = sg[i].p;
    const double er = P[2] - P[0], ez = P[3] - P[1], L2 = er * er + ez * ez;
    double s = L2 > 0 ? ((x[0] - P[0]) * er + (x[1] - P[1]) * ez) / L2 : 0;
    s = s < 0 ? 0 : (s > 1 ? 1 : s);
    const double dr = x[0] - P[0] - s * er, dz = x[1] - P[1] - s * ez;
    const double d2 = dr * dr + dz * dz;
    if (d2 < best) {
      best = d2;
      const double kap = (1 - s) * sg[i].kap[0] + s * sg[i].kap[1];
      corr = 0.5 * kap * L2 * s * (1 - s); /* the arc's sag beyond the chord */
    }
  }
  return sgn * sqrt(best) + corr;
}

ves_status ves_profile_restore(ves_profile *p, ves_model *m, const double *y,
                               ves_profile_info *info) {
  VES_CHECK(p && m && y, VES_ERR_ARG);
  VES_CALL(bind(p, m));
  const ves_quad *q = ves_model_quad(m);
  ves_model_params par;
  ves_model_get_params(m, &par);
  const int n = p->n, nq = q->nq;
  const double w = sqrt(2.0) * par.eps;
  double *fn = malloc(6 * (size_t)n * sizeof *fn), *xy = malloc(2 * (size_t)n * sizeof *xy);
  double *pd = malloc(6 * (size_t)nq * sizeof *pd), *f = malloc((size_t)nq * sizeof *f);
  int ncell = 0, *cells = NULL, ns = 0;
  segment *sg = NULL;
  ves_status st = fn && xy && pd && f ? VES_OK : VES_ERR_ALLOC;
  if (st == VES_OK) st = ves_quad_cells(q, &ncell, &cells);
  if (st == VES_OK) {
    /* phi and the material position at the nodes */
    ves_quad_field(p->at_nodes, p->c, 0, fn);
    for (int a = 0; a < n; a++) {
      double mo[12];
      ves_quad_motion(p->at_nodes, y, a, 0, mo);
      xy[2 * a] = mo[0], xy[2 * a + 1] = mo[6];
      /* atanh(phi) = d / (sqrt2 eps) is linear across a tanh profile: its
       * linear interpolant puts the crossing points on the interface, where
       * phi's own would miss it by O(h^3 / eps^2) in a grid-scale pattern */
      const double v = fmax(-1 + 1e-15, fmin(1 - 1e-15, fn[6 * (size_t)a]));
      fn[a] = atanh(v);
    }
    st = zero_segments(n, ncell, cells, xy, fn, &sg, &ns);
  }
  if (st == VES_OK && ns == 0) st = VES_ERR_GEOM;
  if (st == VES_OK) st = link_ends(sg, ns);
  segment *sm = NULL;
  int nsm = 0;
  /* smoothing half-width 2 eps: ~20 crossing points at h_band 0.5 */
  if (st == VES_OK) st = smooth_chains(sg, ns, 2 * par.eps, &sm, &nsm);
  if (st == VES_OK) free(sg), sg = sm, ns = nsm;
  double max_dphi = 0, max_shift = 0;
  if (st == VES_OK) {
    ves_model_point_data(m, pd);
#pragma omp parallel for schedule(static) reduction(max : max_dphi, max_shift)
    for (int al = 0; al < nq; al++) {
      double mo[12];
      ves_quad_motion(q, y, al, 0, mo);
      const double x[2] = {mo[0], mo[6]}, old = pd[6 * (size_t)al];
      const double d = signed_distance(sg, ns, x, old >= 0 ? 1.0 : -1.0);
      f[al] = tanh(d / w);
      max_dphi = fmax(max_dphi, fabs(f[al] - old));
      if (fabs(old) < 0.9) max_shift = fmax(max_shift, fabs(d - w * atanh(old)));
    }
    st = ves_projector_apply(p->proj, f, p->c, 1e-12, 3);
    if (st == VES_MAXITER) st = VES_OK;
  }
  if (st == VES_OK) {
    ves_quad_field(q, p->c, 2, pd);
    st = ves_model_set_points(m, pd);
  }
  if (st != VES_OK) p->have_c = 0; /* c may be half-written: refit at the next call */
  if (st == VES_OK && info)
    info->segments = ns, info->max_dphi = max_dphi, info->max_shift = max_shift;
  free(fn), free(xy), free(pd), free(f), free(cells), free(sg);
  return st;
}
