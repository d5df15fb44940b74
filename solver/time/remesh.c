/* vesica — full remeshing with field projection (remesh.h): the interface
 * of the current state as a sharp curve, nodes adapted to it as the setup
 * adapts them, new quadrature and tables, the L2 projection of phi onto the
 * new basis over the old points moved with the material, and a minimal
 * correction of the positions restoring the area (and volume). */
#include "ves/remesh.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ves/reconnect.h"
#include "ves/setup.h"
#include "ves/project.h"

#include "core/clock_impl.h"

struct ves_remesh {
  ves_shape *shape;     /* the interface curve it was adapted to (NULL after a restore) */
  ves_nodes *nodes;     /* new nodes (owned) */
  ves_quad *quad;       /* new points, weights and tables (owned) */
  double *phi0c;        /* n projected phi0 coefficients */
  ves_model *model;     /* the model on them (owned; borrows nodes, quad) */
  double *y;            /* 2n corrected positions */
  double *yprev;        /* 2n the carried y_prev (NULL: none) */
  ves_remesh_info info; /* what the remeshing changed */
};

void ves_remesh_params_default(ves_remesh_params *par) {
  memset(par, 0, sizeof *par);
  par->ctol = 1e-14; /* A and V are sums over ~1e5 points: rounding ~1e-15 relative */
  par->max_iter = 10;
  par->curve_spacing = 1.0;
}

void ves_remesh_destroy(ves_remesh **r) {
  if (!r || !*r) return;
  ves_model_destroy(&(*r)->model); /* first: it borrows nodes and quad */
  ves_quad_destroy(&(*r)->quad);
  ves_nodes_destroy(&(*r)->nodes);
  ves_shape_destroy(&(*r)->shape);
  free((*r)->phi0c);
  free((*r)->y);
  free((*r)->yprev);
  free(*r);
  *r = NULL;
}

ves_model *ves_remesh_model(ves_remesh *r) { return r->model; }
const ves_model *ves_remesh_model_const(const ves_remesh *r) { return r->model; }
const ves_nodes *ves_remesh_nodes(const ves_remesh *r) { return r->nodes; }
const ves_quad *ves_remesh_quad(const ves_remesh *r) { return r->quad; }
const double *ves_remesh_phi0c(const ves_remesh *r) { return r->phi0c; }
const double *ves_remesh_y(const ves_remesh *r) { return r->y; }
const double *ves_remesh_y_prev(const ves_remesh *r) { return r->yprev; }
void ves_remesh_get_info(const ves_remesh *r, ves_remesh_info *info) { *info = r->info; }

/* ------------------------------------------------------------------------ */
/* The interface                                                             */
/* ------------------------------------------------------------------------ */

/* The L2 fit c[n] of the model's point values of phi0 onto its basis (the
 * setup's tolerance; the best iterate when it is not met: the point values
 * came from a field of this basis, or from one close to it). */
static ves_status old_coefficients(const ves_model *m, double *c) {
  const ves_quad *q = ves_model_quad(m);
  double *pd = malloc(6 * (size_t)q->nq * sizeof *pd);
  if (!pd) return VES_ERR_ALLOC;
  ves_model_point_data(m, pd);
  for (int al = 0; al < q->nq; al++) pd[al] = pd[6 * (size_t)al]; /* phi0 row, in place */
  ves_status st = ves_project_l2(q, ves_model_nodes(m)->n, pd, c, 1e-12, 3, NULL, NULL);
  free(pd);
  return st == VES_MAXITER ? VES_OK : st;
}

/* The material at the real nodes, xm[2n] = y(X_a), and phi there, phi[n]:
 * the field of phi0c, or (phi0c NULL) of old_coefficients. */
static ves_status node_state(const ves_model *m, const double *y, const double *phi0c, double *xm,
                             double *phi) {
  const ves_nodes *nd = ves_model_nodes(m);
  const ves_quad *q = ves_model_quad(m);
  const int n = nd->n;
  ves_quad *pq = NULL;
  double *c = NULL, *fld = malloc(6 * (size_t)n * sizeof *fld);
  ves_status st = fld ? ves_quad_create_at_nodes(nd, &pq) : VES_ERR_ALLOC;
  if (st == VES_OK) st = ves_quad_tables(pq, nd, &q->lme, NULL);
  if (st == VES_OK) ves_reconnect_motion_at_nodes(nd, pq, y, xm, NULL);
  if (st == VES_OK && !phi0c) {
    c = malloc((size_t)n * sizeof *c);
    st = c ? old_coefficients(m, c) : VES_ERR_ALLOC;
    phi0c = c;
  }
  if (st == VES_OK) {
    ves_quad_field(pq, phi0c, 0, fld);
    for (int a = 0; a < n; a++) phi[a] = fld[6 * (size_t)a];
  }
  ves_quad_destroy(&pq);
  free(c), free(fld);
  return st;
}

/* atanh(phi) clamped short of +-1: the profile's distance coordinate up to
 * the factor sqrt2 eps (the factor cancels in the crossing fraction). */
static double dist_of(double phi) {
  const double lim = 1.0 - 1e-12;
  return atanh(fmax(-lim, fmin(lim, phi)));
}

/* One end of a crossing segment: the edge (a < b) it lies on. */
typedef struct {
  long key; /* a * n + b */
  int seg;  /* segment index */
  int end;  /* 0 or 1 */
} seg_end;

static int cmp_end(const void *p, const void *q) {
  const seg_end *u = p, *v = q;
  if (u->key != v->key) return u->key < v->key ? -1 : 1;
  return u->seg != v->seg ? (u->seg < v->seg ? -1 : 1) : u->end - v->end;
}

/* The other end sharing e's edge, or -1 (a boundary edge). ends sorted. */
static long partner(const seg_end *ends, long nends, long i) {
  if (i > 0 && ends[i - 1].key == ends[i].key) return i - 1;
  if (i + 1 < nends && ends[i + 1].key == ends[i].key) return i + 1;
  return -1;
}

/* The zero segments of phi on the triangles moved to xm: segment s's ends
 * (r, z) at sp[4 s ..], each keyed by its edge (the lower node first, so
 * both triangles of an edge agree) in ends[2 s + j]. Returns their count. */
static int zero_segments(int n, int ntri, const int *tri, const double *xm, const double *phi,
                         double *sp, seg_end *ends) {
  int nseg = 0;
  for (int t = 0; t < ntri; t++) {
    const int *v = tri + 3 * t;
    int k = 0;
    for (int j = 0; j < 3 && k < 2; j++) {
      int a = v[j], b = v[(j + 1) % 3];
      if ((phi[a] > 0) == (phi[b] > 0)) continue;
      if (a > b) {
        int tmp = a;
        a = b, b = tmp;
      } /* canonical: both triangles agree */
      const double da = dist_of(phi[a]), db = dist_of(phi[b]), s = da / (da - db);
      sp[4 * nseg + 2 * k] = xm[2 * a] + s * (xm[2 * b] - xm[2 * a]);
      sp[4 * nseg + 2 * k + 1] = xm[2 * a + 1] + s * (xm[2 * b + 1] - xm[2 * a + 1]);
      ends[2 * nseg + k] = (seg_end){.key = (long)a * n + b, .seg = nseg, .end = k};
      k++;
    }
    if (k == 2) nseg++;
  }
  return nseg;
}

/* The pieces of the zero line besides the chained one: the connected sets
 * of the segments not seen yet (marked seen here), flooded through shared
 * edges. */
static int other_pieces(int nseg, const seg_end *ends, long nends, const long *where,
                        unsigned char *seen) {
  int others = 0;
  for (int s = 0; s < nseg; s++) {
    if (seen[s]) continue;
    others++;
    /* flood the piece through shared edges */
    int cur = s;
    seen[cur] = 1;
    for (int j = 0; j < 2; j++) {
      long e = where[2 * cur + j];
      for (;;) {
        long nx = partner(ends, nends, e);
        if (nx < 0 || seen[ends[nx].seg]) break;
        int s2 = ends[nx].seg;
        seen[s2] = 1;
        e = where[2 * s2 + 1 - ends[nx].end];
      }
    }
  }
  return others;
}

/* The zero line of phi on the triangles moved to xm, chained. */
static ves_status chain(int n, int ntri, const int *tri, const double *xm, const double *phi,
                        int *npts, double **pts, int *pieces) {
  ves_status st = VES_ERR_ALLOC;
  int nseg = 0;
  double *sp = malloc(4 * (size_t)ntri * sizeof *sp); /* segment ends (r, z) x 2 */
  seg_end *ends = malloc(2 * (size_t)ntri * sizeof *ends);
  long *where = NULL; /* position in ends of segment s's end j: where[2 s + j] */
  unsigned char *seen = NULL;
  double *out = NULL;
  if (!sp || !ends) goto done;
  nseg = zero_segments(n, ntri, tri, xm, phi, sp, ends);
  const long nends = 2 * (long)nseg;
  qsort(ends, (size_t)nends, sizeof *ends, cmp_end);
  where = malloc((size_t)(nends ? nends : 1) * sizeof *where);
  seen = calloc((size_t)(nseg ? nseg : 1), 1);
  out = malloc(2 * ((size_t)nseg + 1) * sizeof *out);
  if (!where || !seen || !out) goto done;
  for (long i = 0; i < nends; i++) where[2 * (long)ends[i].seg + ends[i].end] = i;
  /* the start: the northernmost end on the axis (r = 0 exactly: both nodes of
   * its edge are axis nodes) without a partner */
  long start = -1;
  for (long i = 0; i < nends; i++) {
    const double *p = sp + 4 * ends[i].seg + 2 * ends[i].end;
    if (partner(ends, nends, i) < 0 && p[0] == 0.0 &&
        (start < 0 || p[1] > sp[4 * ends[start].seg + 2 * ends[start].end + 1]))
      start = i;
  }
  st = VES_ERR_GEOM;
  if (start < 0) goto done;
  int np = 0;
  long i = start;
  for (;;) {
    const int s = ends[i].seg, j = ends[i].end;
    if (seen[s]) goto done; /* a loop: cannot happen from a boundary end */
    seen[s] = 1;
    memcpy(out + 2 * np++, sp + 4 * s + 2 * j, 2 * sizeof *out);
    const long o = where[2 * s + 1 - j]; /* the segment's other end */
    const long nx = partner(ends, nends, o);
    if (nx < 0) { /* a boundary edge: the curve ends */
      const double *p = sp + 4 * s + 2 * (1 - j);
      memcpy(out + 2 * np++, p, 2 * sizeof *out);
      if (p[0] != 0.0) goto done; /* it ends on the wall, not on the axis */
      break;
    }
    i = nx;
  }
  const int others = other_pieces(nseg, ends, nends, where, seen);
  for (int k = 0; k < np; k++) out[2 * k] = fmax(0.0, out[2 * k]);
  if (out[1] <= out[2 * np - 1]) goto done; /* not north to south */
  *npts = np, *pts = out, out = NULL;
  if (pieces) *pieces = 1 + others;
  st = VES_OK;
done:
  free(sp), free(ends), free(where), free(seen), free(out);
  return st;
}

ves_status ves_remesh_interface(const ves_model *m, const double *y, const double *phi0c, int *npts,
                                double **pts, int *pieces) {
  VES_CHECK(m && y && npts && pts, VES_ERR_ARG);
  const ves_nodes *nd = ves_model_nodes(m);
  const ves_quad *q = ves_model_quad(m);
  const int n = nd->n;
  for (int i = 0; i < 2 * n; i++) VES_CHECK(isfinite(y[i]), VES_ERR_ARG);
  VES_CHECK(q->ntri > 0 && q->tri, VES_ERR_ARG);
  double *xm = malloc(2 * (size_t)n * sizeof *xm), *phi = malloc((size_t)n * sizeof *phi);
  ves_status st = xm && phi ? node_state(m, y, phi0c, xm, phi) : VES_ERR_ALLOC;
  if (st == VES_OK) st = chain(n, q->ntri, q->tri, xm, phi, npts, pts, pieces);
  free(xm), free(phi);
  return st;
}

/* The polyline resampled at equal arclength, spacing about ds: *out (2 (*m))
 * taken by the caller; ends kept exactly. */
static ves_status resample(int np, const double *p, double ds, int *m, double **out,
                           double *length) {
  double *cum = malloc((size_t)np * sizeof *cum);
  if (!cum) return VES_ERR_ALLOC;
  cum[0] = 0;
  for (int k = 1; k < np; k++)
    cum[k] = cum[k - 1] + hypot(p[2 * k] - p[2 * k - 2], p[2 * k + 1] - p[2 * k - 1]);
  const double L = cum[np - 1];
  int N = (int)ceil(L / ds);
  if (N < 8) N = 8; /* the spline needs a few knots even on a tiny curve */
  double *o = malloc(2 * ((size_t)N + 1) * sizeof *o);
  if (!o) {
    free(cum);
    return VES_ERR_ALLOC;
  }
  int k = 0;
  for (int i = 0; i <= N; i++) {
    const double s = L * i / N;
    while (k < np - 2 && cum[k + 1] < s) k++;
    const double seg = cum[k + 1] - cum[k], f = seg > 0 ? fmin(1.0, (s - cum[k]) / seg) : 0.0;
    o[2 * i] = p[2 * k] + f * (p[2 * k + 2] - p[2 * k]);
    o[2 * i + 1] = p[2 * k + 1] + f * (p[2 * k + 3] - p[2 * k + 1]);
  }
  o[0] = 0.0, o[1] = p[1]; /* the poles exactly */
  o[2 * N] = 0.0, o[2 * N + 1] = p[2 * np - 1];
  free(cum);
  *m = N + 1, *out = o, *length = L;
  return VES_OK;
}

/* ------------------------------------------------------------------------ */
/* The new discretization                                                    */
/* ------------------------------------------------------------------------ */

/* A node set from positions, spacings and flags (copied): a ghost (-r_a,
 * z_a) for every node with r_a > 0, in node order. The same function
 * builds the nodes of a remesh and of its restore (bit-exact restarts). */
static ves_status make_nodes(double LR, double LZ, int n, const double *x, const double *h,
                             const int *flag, ves_nodes **out) {
  ves_nodes *nd = calloc(1, sizeof *nd); /* malloc'd parts: ves_nodes_destroy frees them */
  if (!nd) return VES_ERR_ALLOC;
  nd->LR = LR, nd->LZ = LZ, nd->n = n;
  nd->x = malloc(2 * (size_t)n * sizeof *nd->x);
  nd->h = malloc((size_t)n * sizeof *nd->h);
  nd->flag = malloc((size_t)n * sizeof *nd->flag);
  nd->ghost_of = malloc((size_t)n * sizeof *nd->ghost_of);
  if (!nd->x || !nd->h || !nd->flag || !nd->ghost_of) {
    ves_nodes_destroy(&nd);
    return VES_ERR_ALLOC;
  }
  memcpy(nd->x, x, 2 * (size_t)n * sizeof *nd->x);
  memcpy(nd->h, h, (size_t)n * sizeof *nd->h);
  memcpy(nd->flag, flag, (size_t)n * sizeof *nd->flag);
  for (int a = 0; a < n; a++)
    if (x[2 * a] > 0) nd->ghost_of[nd->ng++] = a;
  *out = nd;
  return VES_OK;
}

/* The Delaunay quadrature (the old one's rule; the default for a point set
 * that does not know it) and the LME tables on r->nodes. */
static ves_status build(ves_remesh *r, const ves_quad *old) {
  const ves_lme_params *lme = &old->lme;
  const ves_quad_rulespec d4 = {4, 1};
  VES_CALL(ves_quad_create_rule(r->nodes, ves_quad_rule_npt(old->rule) ? old->rule : d4, &r->quad));
  VES_CALL(ves_quad_tables(r->quad, r->nodes, lme, &r->info.qinfo));
  return VES_OK;
}

/* The points of q moved with the material: xq[2 nq] = y(Xh), wq[nq] = w
 * det F. A point is in the domain when det F > 0 and r > 0 there. With ok
 * NULL any point outside fails the call (VES_ERR_DOMAIN: the model's own
 * points, which every accepted step has checked); else ok[al] says which
 * are in, *nout counts the others, and the call succeeds. */
static ves_status moved_points(const ves_quad *q, const double *y, double *xq, double *wq,
                               unsigned char *ok, int *nout) {
  int bad = 0;
#pragma omp parallel for schedule(static) reduction(+ : bad)
  for (int al = 0; al < q->nq; al++) {
    double mo[12];
    ves_quad_motion(q, y, al, 1, mo);
    const double J = mo[1] * mo[8] - mo[2] * mo[7];
    const int in = J > 0 && mo[0] > 0;
    bad += !in;
    if (ok) ok[al] = (unsigned char)in;
    xq[2 * al] = mo[0], xq[2 * al + 1] = mo[6];
    wq[al] = q->w[al] * J;
  }
  if (nout) *nout = bad;
  return bad && !ok ? VES_ERR_DOMAIN : VES_OK;
}

/* The displacement dy (2n coefficients, y - y_prev) at q's points, moved
 * to xq (2 nq, moved_points' output), as two fields even in r: dv[al] =
 * d_r / r (d_r is odd in r), dv[ld + al] = d_z; at the points in the
 * domain (ok[al], NULL: all, where r > 0), 0 elsewhere. */
static void moved_displacement(const ves_quad *q, const double *xq, const unsigned char *ok,
                               const double *dy, double *dv, size_t ld) {
#pragma omp parallel for schedule(static)
  for (int al = 0; al < q->nq; al++) {
    double md[12];
    if (ok && !ok[al]) {
      dv[al] = dv[ld + al] = 0;
      continue;
    }
    ves_quad_motion(q, dy, al, 0, md);
    dv[al] = md[0] / xq[2 * (size_t)al], dv[ld + al] = md[6];
  }
}

/* Points per h^2 of the new sizing that the projection's points must have:
 * the setup's own density is ~14 (12 points a node, two triangles of 6, on
 * a hex lattice of spacing h, whose node cell is (sqrt3/2) h^2). A cell
 * below half of it is refined to the full density. */
#define CROSS_DENSITY 14.0
#define CROSS_THIN 7.0

/* Signed area of the reference triangle v of nodes nd. */
static double tri_area(const ves_nodes *nd, const int v[3]) {
  const double *A = nd->x + 2 * v[0], *B = nd->x + 2 * v[1], *C = nd->x + 2 * v[2];
  return 0.5 * ((B[0] - A[0]) * (C[1] - A[1]) - (C[0] - A[0]) * (B[1] - A[1]));
}

/* The split each of the ncell cells (npc moved points xq, wq each) needs:
 * split[t] = 0 (dense enough, or no triangle), 2 or 4 (the rule {4, s});
 * counts in->proj_cells_refined and proj_cells_capped; returns the refined
 * points' count. */
static int cell_splits(const ves_nodes *od, const int *cells, int ncell, int npc, const double *xq,
                       const double *wq, ves_sizing *sz, int *split, ves_remesh_info *in) {
  int nr = 0;
  for (int t = 0; t < ncell; t++) {
    double am = 0, xc[2] = {0, 0};
    for (int k = t * npc; k < (t + 1) * npc; k++)
      am += wq[k], xc[0] += wq[k] * xq[2 * k], xc[1] += wq[k] * xq[2 * k + 1];
    xc[0] /= am, xc[1] /= am;
    const double h = ves_sizing_eval(xc, sz), need = CROSS_DENSITY * am / (h * h);
    if (npc >= CROSS_THIN * am / (h * h)) continue;   /* dense enough */
    if (!(tri_area(od, cells + 3 * t) > 0)) continue; /* no triangle to split */
    split[t] = 6 * 4 >= need ? 2 : 4;
    in->proj_cells_refined++;
    if (6 * 16 < need) in->proj_cells_capped++;
    nr += 6 * split[t] * split[t];
  }
  return nr;
}

/* The points xr and weights wr (measure dR dZ) of the refined cells in the
 * reference: the rule bary[0], wb[0] ({4, 2}) or bary[1], wb[1] ({4, 4}) on
 * each cell t with split[t] = 2 or 4, in cell order. */
static void refined_points(const ves_nodes *od, const int *cells, int ncell, const int *split,
                           double bary[2][3 * VES_QUAD_NPT_MAX], double wb[2][VES_QUAD_NPT_MAX],
                           double *xr, double *wr) {
  for (int t = 0, p = 0; t < ncell; t++) {
    if (!split[t]) continue;
    const int *v = cells + 3 * t, r = split[t] == 2 ? 0 : 1, npt = 6 * split[t] * split[t];
    const double *A = od->x + 2 * v[0], *B = od->x + 2 * v[1], *C = od->x + 2 * v[2];
    const double area = tri_area(od, v);
    for (int k = 0; k < npt; k++, p++) {
      const double *b = bary[r] + 3 * k;
      xr[2 * p] = b[0] * A[0] + b[1] * B[0] + b[2] * C[0];
      xr[2 * p + 1] = b[0] * A[1] + b[1] * B[1] + b[2] * C[1];
      wr[p] = wb[r][k] * area;
    }
  }
}

/* The projection's points xo[2 np], weights wo[np] (w det F: the current
 * measure) and phi values fo[np]: the old points moved with the material,
 * except in the old cells the motion has spread too thin for the new basis
 * (fewer than CROSS_THIN / h^2 points per area at the cell, h the new
 * sizing there: the stretched core of a thinning neck, where the new nodes
 * are finer than the old ones and the normal equations of the fit become
 * singular in all but name). Such a cell's points are replaced by the rule
 * {4, s} (s = 2 or 4: 24 or 96 points) on its reference triangle, the old
 * field (coefficients c, old_coefficients) and motion evaluated there.
 * in->proj_cells_refined, proj_cells_capped (still too thin at s = 4),
 * proj_points_dropped (refined points the motion puts outside the domain),
 * proj_points report it; no cell refined: the old points exactly. Kept
 * whole (~100 lines) around one cleanup exit for the dozen buffers that
 * change hands; the per-cell parts are cell_splits and refined_points. */
static ves_status cross_points(const ves_model *m, const double *y, const double *c, ves_sizing *sz,
                               const double *dy, int *npo, double **xo, double **wo, double **fo,
                               double **dvo, ves_remesh_info *in) {
  const ves_quad *oq = ves_model_quad(m);
  const ves_nodes *od = ves_model_nodes(m);
  const int nq = oq->nq;
  int ncell = 0, *cells = NULL, *split = NULL, np = 0, nr = 0;
  double *xq = malloc(2 * (size_t)nq * sizeof *xq), *wq = malloc((size_t)nq * sizeof *wq);
  double *f = malloc(6 * (size_t)nq * sizeof *f), *xr = NULL, *wr = NULL, *fr = NULL;
  double *dv = dy ? malloc(2 * (size_t)nq * sizeof *dv) : NULL;
  ves_quad *pq = NULL;
  ves_status st = xq && wq && f && (dv || !dy) ? VES_OK : VES_ERR_ALLOC;
  if (st == VES_OK) st = moved_points(oq, y, xq, wq, NULL, NULL);
  if (st != VES_OK) goto done;
  if (dy) moved_displacement(oq, xq, NULL, dy, dv, (size_t)nq);
  ves_model_point_data(m, f);
  for (int al = 0; al < nq; al++) f[al] = f[6 * (size_t)al]; /* phi0 row, in place */
  in->proj_cells_refined = in->proj_cells_capped = in->proj_points_dropped = 0;
  in->proj_points = nq;
  if (oq->ntri == 0) goto done; /* a point set without cells: nothing to refine */
  if ((st = ves_quad_cells(oq, &ncell, &cells)) != VES_OK) goto done;
  const int npc = nq / ncell; /* points a cell */
  if (npc * ncell != nq) goto done;
  if (!(split = calloc((size_t)ncell, sizeof *split))) {
    st = VES_ERR_ALLOC;
    goto done;
  }
  nr = cell_splits(od, cells, ncell, npc, xq, wq, sz, split, in);
  if (!in->proj_cells_refined) goto done;

  /* the refined cells' points in the reference, then the old field there */
  double bary[2][3 * VES_QUAD_NPT_MAX], wb[2][VES_QUAD_NPT_MAX];
  if ((st = ves_quad_rule_composite((ves_quad_rulespec){4, 2}, bary[0], wb[0])) != VES_OK ||
      (st = ves_quad_rule_composite((ves_quad_rulespec){4, 4}, bary[1], wb[1])) != VES_OK)
    goto done;
  xr = malloc(2 * (size_t)nr * sizeof *xr), wr = malloc((size_t)nr * sizeof *wr);
  fr = malloc(6 * (size_t)nr * sizeof *fr);
  if (!xr || !wr || !fr) {
    st = VES_ERR_ALLOC;
    goto done;
  }
  refined_points(od, cells, ncell, split, bary, wb, xr, wr);
  if ((st = ves_quad_create_points(nr, xr, wr, 0, NULL, &pq)) != VES_OK ||
      (st = ves_quad_tables(pq, od, &oq->lme, NULL)) != VES_OK)
    goto done;
  ves_quad_field(pq, c, 0, fr);
  /* the refined points moved (pq's weights are wr). Unlike the model's own
   * points, nothing has checked the motion between them: where a cell
   * touches the axis and the motion stretches it along a tether, points
   * within a few 1e-3 of the axis can come out at r < 0 or det F <= 0 (a
   * few dozen of ~5e4 in a tether at eps 0.01: docs/results.md, "Resets and
   * remeshing"). They have no current measure and are left out of the fit
   * (proj_points_dropped); more than a tenth of them fails the remeshing. */
  double *xm = malloc(2 * (size_t)nr * sizeof *xm), *wm = malloc((size_t)nr * sizeof *wm);
  double *dm = dy ? malloc(2 * (size_t)nr * sizeof *dm) : NULL;
  unsigned char *okm = malloc((size_t)nr);
  double *x2 = malloc(2 * (size_t)(nq + nr) * sizeof *x2),
         *w2 = malloc((size_t)(nq + nr) * sizeof *w2);
  double *f2 = malloc((size_t)(nq + nr) * sizeof *f2);
  double *d2 = dy ? malloc(2 * (size_t)(nq + nr) * sizeof *d2) : NULL;
  int nout = 0;
  if (!xm || !wm || (dy && !dm) || !okm || !x2 || !w2 || !f2 || (dy && !d2)) st = VES_ERR_ALLOC;
  if (st == VES_OK) st = moved_points(pq, y, xm, wm, okm, &nout);
  if (st == VES_OK && nout > nr / 10) st = VES_ERR_DOMAIN;
  if (st != VES_OK) {
    free(xm), free(wm), free(dm), free(okm), free(x2), free(w2), free(f2), free(d2);
    goto done;
  }
  if (dy) moved_displacement(pq, xm, okm, dy, dm, (size_t)nr);
  in->proj_points_dropped = nout;
  /* the points' count once the cells are replaced: the layout of the fields */
  const size_t ld = (size_t)(nq - npc * in->proj_cells_refined + nr - nout);
  for (int t = 0; t < ncell; t++) { /* the cells kept, then the refined ones */
    if (split[t]) continue;
    for (int k = t * npc; k < (t + 1) * npc; k++, np++) {
      x2[2 * np] = xq[2 * k], x2[2 * np + 1] = xq[2 * k + 1], w2[np] = wq[k], f2[np] = f[k];
      if (dy) d2[np] = dv[k], d2[ld + np] = dv[nq + k];
    }
  }
  for (int p = 0; p < nr; p++) {
    if (!okm[p]) continue;
    x2[2 * np] = xm[2 * p], x2[2 * np + 1] = xm[2 * p + 1], w2[np] = wm[p];
    f2[np] = fr[6 * (size_t)p];
    if (dy) d2[np] = dm[p], d2[ld + np] = dm[nr + p];
    np++;
  }
  free(xm), free(wm), free(dm), free(okm);
  free(xq), free(wq), free(f), free(dv);
  xq = x2, wq = w2, f = f2, dv = d2;
  in->proj_points = np;
done:
  ves_quad_destroy(&pq);
  free(cells), free(split), free(xr), free(wr), free(fr);
  if (st != VES_OK) {
    free(xq), free(wq), free(f), free(dv);
    return st;
  }
  *npo = in->proj_points, *xo = xq, *wo = wq, *fo = f, *dvo = dv;
  return VES_OK;
}

/* Free dofs: wall nodes fixed, axis nodes' r fixed (as the model fixes them). */
static int is_free(const ves_nodes *nd, int i) {
  const int f = nd->flag[i / 2];
  if (f & VES_NODE_WALL) return 0;
  if ((f & VES_NODE_AXIS) && i % 2 == 0) return 0;
  return 1;
}

/* The minimal correction: y += delta, delta = -G^T (G G^T)^-1 c over the free
 * dofs, G = (grad A; grad V) of the held constraints, c their residuals,
 * until both are within ctol (relative). */
static ves_status correct(ves_remesh *r, const ves_remesh_params *par, double *gA, double *gV) {
  ves_model *m = r->model;
  const ves_nodes *nd = r->nodes;
  const int n2 = 2 * nd->n;
  ves_remesh_info *in = &r->info;
  double E, A, V;
  ves_status st = VES_OK;
  for (int it = 0;; it++) {
    VES_CALL(ves_model_eval(m, r->y, VES_F_E | VES_F_A | VES_F_V, &E, &A, &V, NULL, gA, gV));
    const double cA = par->hold_area ? A - par->A_target : 0.0;
    const double cV = par->hold_volume ? V - par->V_target : 0.0;
    in->res_A = par->hold_area ? fabs(cA) / par->A_target : 0.0;
    in->res_V = par->hold_volume ? fabs(cV) / par->V_target : 0.0;
    in->E = E / ves_model_get_k(m), in->A = A, in->V = V;
    in->corr_iter = it;
    if (in->res_A <= par->ctol && in->res_V <= par->ctol) break;
    if (it == par->max_iter) {
      st = VES_MAXITER;
      break;
    }
    double aa = 0, av = 0, vv = 0; /* G G^T over the free dofs */
    for (int i = 0; i < n2; i++) {
      if (!is_free(nd, i)) continue;
      const double a = par->hold_area ? gA[i] : 0.0, v = par->hold_volume ? gV[i] : 0.0;
      aa += a * a, av += a * v, vv += v * v;
    }
    double mA = 0, mV = 0; /* (G G^T) mu = c */
    if (par->hold_area && par->hold_volume) {
      const double det = aa * vv - av * av;
      if (!(det > 0)) return VES_ERR_SINGULAR;
      mA = (vv * cA - av * cV) / det, mV = (aa * cV - av * cA) / det;
    } else if (par->hold_area) {
      if (!(aa > 0)) return VES_ERR_SINGULAR;
      mA = cA / aa;
    } else {
      if (!(vv > 0)) return VES_ERR_SINGULAR;
      mV = cV / vv;
    }
    for (int i = 0; i < n2; i++)
      if (is_free(nd, i))
        r->y[i] -= (par->hold_area ? mA * gA[i] : 0.0) + (par->hold_volume ? mV * gV[i] : 0.0);
  }
  double cmax = 0, c2 = 0;
  for (int a = 0; a < nd->n; a++) {
    const double dr = r->y[2 * a] - nd->x[2 * a], dz = r->y[2 * a + 1] - nd->x[2 * a + 1];
    cmax = fmax(cmax, hypot(dr, dz) / nd->h[a]);
    c2 += dr * dr + dz * dz;
  }
  in->corr_max = cmax, in->corr_norm = sqrt(c2);
  return st;
}

#define FAIL(code, ...)                                                                            \
  do {                                                                                             \
    st = (code);                                                                                   \
    snprintf(err, errlen, __VA_ARGS__);                                                            \
    goto fail;                                                                                     \
  } while (0)

/* Longer than most functions, on purpose: one pipeline (interface, new
 * nodes, quadrature and tables, projection, correction) with one cleanup
 * exit that frees what a failure half-way made, as ves_setup_create. */
ves_status ves_remesh_create(const ves_discret_params *dp, ves_model *m, const double *y,
                             const ves_remesh_params *par, ves_remesh **out, char *err,
                             size_t errlen) {
  VES_CHECK(dp && m && y && par && out && err && errlen, VES_ERR_ARG);
  *out = NULL;
  ves_error_clear(); /* err names the record of this remeshing's failure (status.h) */
  const double t0 = ves_wall_seconds();
  const ves_nodes *od = ves_model_nodes(m);
  const ves_quad *oq = ves_model_quad(m);
  ves_status st = VES_OK;
  double *poly = NULL, *knots = NULL, *xq = NULL, *wq = NULL, *f = NULL, *gA = NULL, *gV = NULL;
  double *cold = NULL, *dy = NULL, *dv = NULL, *cd = NULL;
  ves_sizing *sizing = NULL;
  ves_nodes *gen = NULL;
  ves_quad *cross = NULL;
  ves_remesh *r = calloc(1, sizeof *r);
  if (!r) return VES_ERR_ALLOC;
  ves_remesh_info *in = &r->info;
  in->n_old = od->n, in->nq_old = oq->nq;
  if (dp->box_r != od->LR || dp->box_z != od->LZ)
    FAIL(VES_ERR_ARG, "remesh: the box %g x %g is not the model's %g x %g", dp->box_r, dp->box_z,
         od->LR, od->LZ);
  for (int i = 0; i < 2 * od->n; i++)
    if (!isfinite(y[i])) FAIL(VES_ERR_ARG, "remesh: a non-finite position");
  const double k = ves_model_get_k(m);
  ves_model_params mp;
  ves_model_get_params(m, &mp);
  {
    double E, A, V;
    if ((st = ves_model_eval(m, y, VES_F_E | VES_F_A | VES_F_V, &E, &A, &V, NULL, NULL, NULL)) !=
        VES_OK)
      FAIL(st, "remesh: the state: %s", ves_error_text(st));
    in->E_old = E / k, in->A_old = A, in->V_old = V;
  }

  /* 1. the interface curve */
  double t = ves_wall_seconds();
  int np = 0, nk = 0, pieces = 0;
  if (!(cold = malloc((size_t)od->n * sizeof *cold))) FAIL(VES_ERR_ALLOC, "remesh: out of memory");
  if ((st = old_coefficients(m, cold)) != VES_OK)
    FAIL(st, "remesh: the old field's coefficients: %s", ves_error_text(st));
  if ((st = ves_remesh_interface(m, y, cold, &np, &poly, &pieces)) != VES_OK)
    FAIL(st, "remesh: interface: %s (no zero line of phi from pole to pole)", ves_error_text(st));
  if (pieces != 1)
    FAIL(VES_ERR_GEOM, "remesh: the interface has %d pieces (one vesicle only)", pieces);
  if ((st = resample(np, poly, par->curve_spacing * dp->eps, &nk, &knots, &in->curve_length)) !=
      VES_OK)
    FAIL(st, "remesh: %s", ves_error_text(st));
  in->curve_points = nk;
  ves_shape_params sp;
  ves_shape_params_default(&sp);
  sp.kind = VES_SHAPE_CURVE, sp.npts = nk, sp.pts = knots, sp.keep_scale = 1;
  if ((st = ves_shape_create(&sp, &r->shape)) != VES_OK)
    FAIL(st, "remesh: interface curve: %s", ves_error_text(st));
  in->seconds_interface = ves_wall_seconds() - t;

  /* 2. nodes, quadrature, tables */
  t = ves_wall_seconds();
  /* the band layers are offset curves of the interface: where it bends more
   * tightly than band*eps (a neck, a thin tube, a small pearl) they fold, and
   * the band is then filled as the setup fills it without layers (CVT with the
   * same sizing) rather than refusing the remeshing */
  in->band_layers = dp->band_layers;
  st = ves_setup_nodes(dp, r->shape, &sizing, &gen, err, errlen);
  if (st == VES_ERR_CONFIG && dp->band_layers) {
    ves_discret_params c = *dp;
    c.band_layers = 0, in->band_layers = 0;
    st = ves_setup_nodes(&c, r->shape, &sizing, &gen, err, errlen);
  }
  if (st != VES_OK) goto fail;
  if ((st = make_nodes(gen->LR, gen->LZ, gen->n, gen->x, gen->h, gen->flag, &r->nodes)) != VES_OK)
    FAIL(st, "remesh: %s", ves_error_text(st));
  ves_nodes_destroy(&gen);
  in->seconds_nodes = ves_wall_seconds() - t;
  t = ves_wall_seconds();
  if ((st = build(r, oq)) != VES_OK)
    FAIL(st, "remesh: quadrature or LME tables: %s", ves_error_text(st));
  in->n_new = r->nodes->n, in->nq_new = r->quad->nq;
  in->seconds_tables = ves_wall_seconds() - t;

  /* 3. phi projected over the old points moved with the material (the thin
   * cells' refined) */
  t = ves_wall_seconds();
  const int n = r->nodes->n;
  int ncross = 0;
  r->phi0c = malloc((size_t)n * sizeof *r->phi0c);
  if (!r->phi0c) FAIL(VES_ERR_ALLOC, "remesh: out of memory");
  if (par->y_prev) { /* the displacement to carry (ves_remesh_params.y_prev) */
    if (!(dy = malloc(2 * (size_t)od->n * sizeof *dy)))
      FAIL(VES_ERR_ALLOC, "remesh: out of memory");
    for (int i = 0; i < 2 * od->n; i++) dy[i] = y[i] - par->y_prev[i];
  }
  if ((st = cross_points(m, y, cold, sizing, dy, &ncross, &xq, &wq, &f, &dv, in)) != VES_OK)
    FAIL(st, "remesh: the state: %s", ves_error_text(st));
  ves_sizing_destroy(&sizing);
  if ((st = ves_quad_create_points(ncross, xq, wq, 0, NULL, &cross)) != VES_OK ||
      (st = ves_quad_tables(cross, r->nodes, &oq->lme, NULL)) != VES_OK)
    FAIL(st, "remesh: the moved points on the new basis: %s", ves_error_text(st));
  /* the setup's tolerance: the fit error far below the discretization's;
   * the displacement's fields (if any) with the same factorization, their
   * tolerance not required (a predictor's start) */
  if (dv) {
    double *f3 = malloc(3 * (size_t)ncross * sizeof *f3), res[3] = {0, 0, 0};
    int ref[3] = {0, 0, 0};
    cd = malloc(3 * (size_t)n * sizeof *cd);
    if (!f3 || !cd) {
      free(f3);
      FAIL(VES_ERR_ALLOC, "remesh: out of memory");
    }
    memcpy(f3, f, (size_t)ncross * sizeof *f3);
    memcpy(f3 + ncross, dv, 2 * (size_t)ncross * sizeof *f3);
    st = ves_project_l2_fields(cross, n, 3, f3, cd, 1e-12, 3, ref, res);
    free(f3);
    memcpy(r->phi0c, cd, (size_t)n * sizeof *cd);
    in->proj_refinements = ref[0], in->proj_residual = res[0];
    if (st == VES_MAXITER && res[0] <= 1e-12) st = VES_OK; /* only the displacement missed */
  } else
    st = ves_project_l2(cross, n, f, r->phi0c, 1e-12, 3, &in->proj_refinements, &in->proj_residual);
  if (st != VES_OK)
    FAIL(st < 0 ? st : VES_ERR_NOCONV, "remesh: phi projection: %s (relative residual %.2e)",
         ves_error_text(st), in->proj_residual);
  ves_quad_destroy(&cross);
  in->seconds_project = ves_wall_seconds() - t;

  /* 4. the model at the identity, then the correction */
  t = ves_wall_seconds();
  if ((st = ves_model_create(r->nodes, r->quad, r->phi0c, &mp, &r->model)) != VES_OK)
    FAIL(st, "remesh: model: %s", ves_error_text(st));
  r->y = malloc(2 * (size_t)n * sizeof *r->y);
  gA = malloc(2 * (size_t)n * sizeof *gA);
  gV = malloc(2 * (size_t)n * sizeof *gV);
  if (!r->y || !gA || !gV) FAIL(VES_ERR_ALLOC, "remesh: out of memory");
  ves_model_reference(r->model, r->y);
  {
    double E, A, V;
    if ((st = ves_model_eval(r->model, r->y, VES_F_E | VES_F_A | VES_F_V, &E, &A, &V, NULL, NULL,
                             NULL)) != VES_OK)
      FAIL(st, "remesh: the projected state: %s", ves_error_text(st));
    in->E_proj = E / k, in->A_proj = A, in->V_proj = V;
    in->dE = in->E_proj - in->E_old;
    in->dA = A / in->A_old - 1, in->dV = V / in->V_old - 1;
  }
  ves_status cst = correct(r, par, gA, gV);
  if (cst < 0) FAIL(cst, "remesh: correction: %s", ves_error_text(cst));
  if (cd) { /* y_prev' = y' - d, d = (r c_{d_r / r}, c_{d_z}) at the free dofs */
    if (!(r->yprev = malloc(2 * (size_t)n * sizeof *r->yprev)))
      FAIL(VES_ERR_ALLOC, "remesh: out of memory");
    for (int i = 0; i < 2 * n; i++) {
      const int a = i / 2;
      const double d = i % 2 ? cd[2 * (size_t)n + a] : r->nodes->x[2 * a] * cd[(size_t)n + a];
      r->yprev[i] = r->y[i] - (is_free(r->nodes, i) ? d : 0.0);
    }
  }
  in->seconds_correct = ves_wall_seconds() - t;

  /* 5. the interface's displacement: the new state's zero line against the
   * old curve */
  free(poly);
  poly = NULL;
  if ((st = ves_remesh_interface(r->model, r->y, r->phi0c, &np, &poly, NULL)) != VES_OK)
    FAIL(st, "remesh: the new interface: %s", ves_error_text(st));
  double dmax = 0, dsum = 0;
  for (int i = 0; i < np; i++) {
    const double d = fabs(ves_shape_distance(r->shape, poly + 2 * i));
    dmax = fmax(dmax, d), dsum += d;
  }
  in->disp_max = dmax, in->disp_mean = dsum / np;
  in->seconds = ves_wall_seconds() - t0;
  free(poly), free(knots), free(xq), free(wq), free(f), free(gA), free(gV), free(cold);
  free(dy), free(dv), free(cd);
  *out = r;
  return cst; /* VES_OK, or VES_MAXITER from the correction */
fail:
  free(poly), free(knots), free(xq), free(wq), free(f), free(gA), free(gV), free(cold);
  free(dy), free(dv), free(cd);
  ves_quad_destroy(&cross);
  ves_nodes_destroy(&gen);
  ves_sizing_destroy(&sizing);
  ves_remesh_destroy(&r);
  return st;
}

ves_status ves_remesh_restore(const ves_model *m, int n, const double *x, const double *h,
                              const int *flag, const double *phi0c, ves_remesh **out) {
  VES_CHECK(m && x && h && flag && phi0c && out && n >= 3, VES_ERR_ARG);
  *out = NULL;
  for (int a = 0; a < n; a++)
    VES_CHECK(isfinite(x[2 * a]) && isfinite(x[2 * a + 1]) && x[2 * a] >= 0 && h[a] > 0 &&
                  isfinite(h[a]) && isfinite(phi0c[a]),
              VES_ERR_ARG);
  const ves_nodes *od = ves_model_nodes(m);
  ves_model_params mp;
  ves_model_get_params(m, &mp);
  ves_remesh *r = calloc(1, sizeof *r);
  if (!r) return VES_ERR_ALLOC;
  ves_status st = make_nodes(od->LR, od->LZ, n, x, h, flag, &r->nodes);
  if (st == VES_OK) st = build(r, ves_model_quad(m));
  if (st == VES_OK) {
    r->phi0c = malloc((size_t)n * sizeof *r->phi0c);
    r->y = malloc(2 * (size_t)n * sizeof *r->y);
    st = r->phi0c && r->y ? VES_OK : VES_ERR_ALLOC;
  }
  if (st == VES_OK) {
    memcpy(r->phi0c, phi0c, (size_t)n * sizeof *phi0c);
    memcpy(r->y, x, 2 * (size_t)n * sizeof *x);
    st = ves_model_create(r->nodes, r->quad, r->phi0c, &mp, &r->model);
  }
  if (st != VES_OK) {
    ves_remesh_destroy(&r);
    return st;
  }
  r->info.n_new = n, r->info.nq_new = r->quad->nq;
  *out = r;
  return VES_OK;
}
