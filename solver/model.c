/* vesica — the discrete model: E, A, V, their gradients and Hessians, and the
 * dissipation matrix K, through ONE per-point assembly over the local
 * kinematic variables (DESIGN.md §2):
 *   q_alpha = B_alpha y,  F = 2 pi sum_alpha w_alpha c e(q_alpha),
 *   grad F = 2 pi sum w c B^T de/dq,  Hess F = 2 pi sum w c B^T (d2e/dq2) B,
 * with c = f_E = 3k/(16 sqrt2 eps) for E, f_A = 3/(2 sqrt2) for A, 1 for V.
 * B_alpha comes from the table of the point folded onto its real nodes: a
 * ghost entry adds its column to its real node with sign -1 for r (odd) and
 * +1 for z (even). r-dofs feed q through the table rows (p, p_R, p_Z, p_RR,
 * p_RZ, p_ZZ) -> (r, F_rR, F_rZ, G_rRR, G_rRZ, G_rZZ); z-dofs through
 * (p_R, p_Z, p_RR, p_RZ, p_ZZ) -> (F_zR, F_zZ, G_zRR, G_zRZ, G_zZZ).
 * The velocity variables of K use the first rows only.
 *
 * Assembly of the Hessians and K, per triangle: its 6 points share nearly
 * all their nodes, so the products c B^T H B of all 6 are summed into one
 * block matrix over the union of their node lists, formed by the BLAS as
 * three dense products X^T diag_p(c H_p) X (the rr, rz and zz parts; X the
 * points' B stacked, K = 36 / 30 deep; one BLAS thread per triangle, the
 * triangles in parallel), and each lower block is added to the pattern
 * once, not once per point (~6x fewer scattered updates). Triangles
 * are visited along a Morton curve so the pattern rows they touch stay in
 * cache. Threads (OpenMP, the count fixed at create from
 * omp_get_max_threads(), i.e. OMP_NUM_THREADS or all cores): the nodes are
 * split into slabs in Z of equal work, each thread writes only the rows of
 * its slab and visits the triangles whose unions meet it (those straddling
 * two slabs are computed by both, ~a few %). Every block and gradient entry
 * thus receives its contributions in the same order for any thread count:
 * results are bitwise the same for 1, 2, ... threads (for one BLAS kernel:
 * OpenBLAS picks it from the CPU). E, A, V are summed in point order and
 * their gradients in point order; the Hessian and K differ from a per-point
 * assembly by rounding only (sums regrouped per triangle).
 *
 * Drift damping (not in the paper; ves_model_params.drift, off by default):
 * LME smooths, so coefficient patterns at the grid scale barely move the
 * material (~1% on a sphere) and K, which sees only the motion at the
 * points, hardly resists them; the discrete E has directions of negative
 * curvature among them (relabeling modes, bench/RESULTS.md), and the
 * coefficients drift from the material by up to 1e6 h over long runs. A
 * constant S (drift_build) added to K penalizes the rate of y^a - y(X_a):
 * zero on affine motions, O((h/L)^2) of K on smooth ones. Measured effect
 * in bench/RESULTS.md, "Drift damping".
 *
 * Coefficient-mode stabilization (ves_model_params.stab, off by default):
 * the same defect in E instead of K, E_s = (1/2) sum_a c_a |y^a - y(X_a)|^2
 * (stab_build, stab_eval), zero on affine maps (so at the reference), O(h^2)
 * on smooth motions, and of the size of the coefficients on the grid-scale
 * patterns along which the discrete E has negative curvature: it turns the
 * relaxed sphere from a saddle into a minimum (bench/RESULTS.md, issue 22). */
#include "ves/model.h"
#include "ves/project.h"

#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "omp_impl.h"

#include <cblas.h>

#include "model_impl.h"

/* Which q entries an r-dof (resp. z-dof) feeds, and from which table row. */
typedef struct {
  int nr, nz;       /* entries fed by r and by z */
  int qr[6], rr[6]; /* q index and table row, r-dof */
  int qz[5], rz[5]; /* q index and table row, z-dof */
  int nl;           /* size of the local variable vector */
} local_map;

static const local_map MAP_Q = {
    6, 5, {0, 1, 2, 5, 6, 7}, {0, 1, 2, 3, 4, 5}, {3, 4, 8, 9, 10}, {1, 2, 3, 4, 5}, VES_NQ};
static const local_map MAP_QD = {3, 2, {0, 1, 2}, {0, 1, 2}, {3, 4}, {1, 2}, VES_NQD};

#define NPT VES_QUAD_NPT /* points per triangle: the unit of assembly */
#define NB 11            /* largest nr + nz (MAP_Q) */

/* Per-thread workspace (allocated at create; cap = NPT mmax bounds the
 * union of a triangle's node lists, numax is the largest union). */
typedef struct {
  int *un;         /* NPT x mmax: folded node lists of a triangle's points */
  double *Tr, *Tz; /* NPT x 6 mmax: folded tables */
  int *stamp;      /* n: fold_point's duplicate marks, -1 when free */
  int *slot;       /* n: position of a node in a point's list, then in the union */
  int *U, *Utmp;   /* cap: the triangle's union node list (ascending), merge buffer */
  double *X;       /* NPT NB x numax: the stacked B of a triangle (triangle_xy) */
  double *Y;       /* NPT (NB + 6) x numax: its products with the local Hessians */
  double *M;       /* 3 numax^2: the triangle's Mrr, Mrz, Mzz (triangle_blocks) */
  double *yl;      /* 4 mmax: a point's gathered y, then its gradient rows */
} model_ws;

/* One folded point of a triangle (pointers into the table or the workspace). */
typedef struct {
  int mu;                /* unique real nodes */
  const double *Tr, *Tz; /* folded tables, 6 x mu */
  const int *un;         /* its nodes, ascending */
} folded;

struct ves_model {
  const ves_nodes *nodes; /* borrowed */
  const ves_quad *q;      /* borrowed */
  ves_model_params par;   /* copied */
  ves_model_local_par lp; /* parameters for the local densities */
  ves_model_point *pt;    /* nq point data (phi0 and derivatives) */
  unsigned char *fixed;   /* 2n fixed-dof flags */
  ves_pattern *pat;       /* block pattern */
  double *yref;           /* 2n reference positions */
  int mmax;               /* largest neighbour count of a point */
  int cap;                /* NPT mmax: capacity of a triangle's union */
  int numax;              /* the largest union of a triangle (make_slabs) */
  /* Threads: the nodes are split into nthr slabs in Z of about equal
   * assembly work; slab k owns the rows (nodes) in it, and every triangle
   * whose union meets slab k is visited by the thread of slab k, which writes
   * only owned rows. Every block (and gradient entry) thus receives its
   * contributions in triangle order whatever the thread count. */
  int nthr;       /* slabs = threads (omp_get_max_threads() at create) */
  int *owner;     /* n: slab of a node */
  int *tlo, *thi; /* ntri: slab range of a triangle's union */
  int *torder;    /* ntri: the order of assembly, along a Morton curve of
                     the centroids, so that consecutive triangles share
                     most nodes and their pattern rows stay in cache */
  model_ws *ws;   /* nthr workspaces */
  double *ev;     /* 4 nq: per-point w e of E, A, V and the step's dissipation
                     (summed in point order) */
  /* Drift damping (par.drift > 0, else NULL): the points at the nodes with
   * their tables, and the block values of the constant matrix S added to K
   * (drift_build). */
  ves_quad *qn; /* n points at the nodes (ves_quad_create_at_nodes) */
  double *dblk; /* 4 ptr[n] block values of S in the pattern */
  /* Coefficient-mode stabilization of E (par.stab > 0, else NULL; stab_build):
   * E_s = (1/2) sum_a c_a |y^a - y(X_a)|^2 from the defect rows
   * d_a = sum_j (sdr_j y_r, sdz_j y_z)(snb_j), j in [sptr[a], sptr[a+1]). */
  int *sptr;    /* n + 1 offsets (wall nodes: empty rows) */
  int *snb;     /* sptr[n] nodes of the rows */
  double *sdr;  /* sptr[n] weights of y_r (ghosts folded with -1) */
  double *sdz;  /* sptr[n] weights of y_z */
  double *sc;   /* n: c_a = stab k 2 pi M_a / h_a^2 (0 on the wall) */
  double *sblk; /* 4 ptr[n] block values of Hess E_s (constant) */
};

const ves_pattern *ves_model_pattern(const ves_model *m) { return m->pat; }

void ves_model_reference(const ves_model *m, double *y) {
  memcpy(y, m->yref, 2 * (size_t)m->nodes->n * sizeof *y);
}

static void ws_free(model_ws *w) {
  free(w->un), free(w->Tr), free(w->Tz), free(w->stamp), free(w->slot);
  free(w->U), free(w->Utmp), free(w->X), free(w->Y), free(w->M), free(w->yl);
}

/* The workspace of the folding and the unions (the products' arrays follow
 * in ws_alloc_products, once the largest union is known). */
static ves_status ws_alloc(model_ws *w, int n, int mmax, int cap) {
  w->un = malloc((size_t)NPT * mmax * sizeof *w->un);
  w->Tr = malloc((size_t)NPT * 6 * mmax * sizeof *w->Tr);
  w->Tz = malloc((size_t)NPT * 6 * mmax * sizeof *w->Tz);
  w->stamp = malloc((size_t)n * sizeof *w->stamp);
  w->slot = malloc((size_t)n * sizeof *w->slot);
  w->U = malloc((size_t)cap * sizeof *w->U);
  w->Utmp = malloc((size_t)cap * sizeof *w->Utmp);
  w->yl = malloc(4 * (size_t)mmax * sizeof *w->yl);
  if (!w->un || !w->Tr || !w->Tz || !w->stamp || !w->slot || !w->U || !w->Utmp || !w->yl)
    return VES_ERR_ALLOC;
  for (int a = 0; a < n; a++) w->stamp[a] = -1;
  return VES_OK;
}

static ves_status ws_alloc_products(model_ws *w, int numax) {
  w->X = malloc((size_t)NPT * NB * numax * sizeof *w->X);
  w->Y = malloc((size_t)NPT * (NB + 6) * numax * sizeof *w->Y);
  w->M = malloc(3 * (size_t)numax * numax * sizeof *w->M);
  return w->X && w->Y && w->M ? VES_OK : VES_ERR_ALLOC;
}

void ves_model_destroy(ves_model **m) {
  if (!m || !*m) return;
  ves_model *p = *m;
  free(p->pt);
  free(p->fixed);
  ves_pattern_destroy(&p->pat);
  free(p->yref);
  free(p->owner);
  free(p->tlo);
  free(p->thi);
  free(p->torder);
  if (p->ws)
    for (int k = 0; k < p->nthr; k++) ws_free(p->ws + k);
  free(p->ws);
  free(p->ev);
  ves_quad_destroy(&p->qn);
  free(p->dblk);
  free(p->sptr), free(p->snb), free(p->sdr), free(p->sdz), free(p->sc), free(p->sblk);
  free(p);
  *m = NULL;
}

/* Fold point al's table onto its unique real nodes: *Tr (6 x mu, ghost
 * columns added with sign -1) and *Tz (ghost columns added with +1), node
 * list *un, ascending, into slot p (0..NPT-1) of the workspace. Points that
 * see no ghost and list their nodes in ascending order (the tables do) use
 * the table in place. Returns mu. */
static int fold_point(const ves_quad *q, int mmax, model_ws *w, int al, int p, folded *f) {
  int m0 = q->ptr[al + 1] - q->ptr[al];
  const int *nb = q->nbr + q->ptr[al];
  const unsigned char *mir = q->mirror + q->ptr[al];
  const double *t = q->tab + 6 * (size_t)q->ptr[al];
  int ghosts = 0, sorted = 1;
  for (int k = 0; k < m0; k++) ghosts |= mir[k];
  for (int k = 1; k < m0; k++) sorted &= nb[k] > nb[k - 1];
  if (!ghosts && sorted) {
    f->Tr = f->Tz = t, f->un = nb, f->mu = m0;
    return m0;
  }
  int *un = w->un + (size_t)p * mmax;
  double *Tr = w->Tr + (size_t)p * 6 * mmax, *Tz = w->Tz + (size_t)p * 6 * mmax;
  /* first pass: unique nodes, sorted ascending (the assembly relies on it) */
  int mu = 0;
  for (int k = 0; k < m0; k++) {
    int a = nb[k];
    if (w->stamp[a] != al) w->stamp[a] = al, un[mu++] = a;
  }
  for (int i = 1; i < mu; i++) { /* insertion sort: mu ~ 100 */
    int v = un[i], j = i - 1;
    while (j >= 0 && un[j] > v) un[j + 1] = un[j], j--;
    un[j + 1] = v;
  }
  for (int u = 0; u < mu; u++) w->slot[un[u]] = u;
  for (int j = 0; j < 6; j++)
    for (int u = 0; u < mu; u++) Tr[j * mu + u] = Tz[j * mu + u] = 0.0;
  for (int k = 0; k < m0; k++) {
    int u = w->slot[nb[k]];
    double sg = mir[k] ? -1.0 : 1.0;
    for (int j = 0; j < 6; j++) {
      Tr[j * mu + u] += sg * t[j * m0 + k];
      Tz[j * mu + u] += t[j * m0 + k];
    }
  }
  /* release the stamps: they must not survive into the next call, where the
   * same point index would find them set and skip its nodes */
  for (int u = 0; u < mu; u++) w->stamp[un[u]] = -1;
  f->Tr = Tr, f->Tz = Tz, f->un = un, f->mu = mu;
  return mu;
}

/* out = a union b (both ascending, without repeats); returns its length. */
static int merge_sorted(const int *a, int na, const int *b, int nb, int *out) {
  int i = 0, j = 0, k = 0;
  while (i < na && j < nb) {
    int x = a[i] <= b[j] ? a[i] : b[j];
    i += a[i] == x, j += b[j] == x;
    out[k++] = x;
  }
  while (i < na) out[k++] = a[i++];
  while (j < nb) out[k++] = b[j++];
  return k;
}

/* Fold the NPT points of triangle t into f[] and build the union of their
 * node lists (ascending) in *U, with slot[U[i]] = i. Returns its size. */
static int triangle_union(const ves_model *m, model_ws *w, int t, folded f[NPT], const int **U) {
  for (int p = 0; p < NPT; p++) fold_point(m->q, m->mmax, w, NPT * t + p, p, f + p);
  int *cur = w->U, *nxt = w->Utmp, nu = f[0].mu;
  memcpy(cur, f[0].un, (size_t)nu * sizeof *cur);
  for (int p = 1; p < NPT; p++) {
    int *tmp;
    nu = merge_sorted(cur, nu, f[p].un, f[p].mu, nxt);
    tmp = cur, cur = nxt, nxt = tmp;
  }
  for (int i = 0; i < nu; i++) w->slot[cur[i]] = i;
  *U = cur;
  return nu;
}

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
static ves_status order_triangles(ves_model *m) {
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
static ves_status make_slabs(ves_model *m) {
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
    int nu = triangle_union(m, w, t, f, &U);
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

/* M_a = sum_alpha w_alpha R_alpha P_a(X_alpha) into M[n] (zeroed here). */
static void node_measure(const ves_quad *q, int n, double *M) {
  memset(M, 0, (size_t)n * sizeof *M);
  for (int al = 0; al < q->nq; al++) /* M_a = sum w R P_a */
    for (int k = q->ptr[al]; k < q->ptr[al + 1]; k++)
      M[q->nbr[k]] +=
          q->w[al] * q->x[2 * (size_t)al] * q->tab[6 * (size_t)q->ptr[al] + (k - q->ptr[al])];
}

/* Node a's defect row: y^a - y(X_a) = sum_j (dr_j y_r, dz_j y_z)(nb_j) over
 * the returned count of distinct nodes (ghosts folded). */
static int defect_row(const ves_quad *qn, int a, int *nb, double *dr, double *dz) {
  const int k0 = qn->ptr[a], mk = qn->ptr[a + 1] - k0;
  const double *p = qn->tab + 6 * (size_t)k0; /* value row */
  int cnt = 0;
  for (int k = 0; k < mk; k++) { /* fold: d_b = delta_ab - sum of the entries of b */
    int b = qn->nbr[k0 + k], j = 0;
    while (j < cnt && nb[j] != b) j++;
    if (j == cnt) nb[cnt] = b, dr[cnt] = dz[cnt] = 0, cnt++;
    dr[j] -= qn->mirror[k0 + k] ? -p[k] : p[k];
    dz[j] -= p[k];
  }
  int j = 0;
  while (j < cnt && nb[j] != a) j++;
  if (j == cnt) nb[cnt] = a, dr[cnt] = dz[cnt] = 0, cnt++;
  dr[j] += 1, dz[j] += 1;
  return cnt;
}

/* blk += c (dr dr^T (rr), dz dz^T (zz)) on the pattern. */
static void defect_blocks(const ves_pattern *pat, int cnt, const int *nb, const double *dr,
                          const double *dz, double c, double *blk) {
  for (int i = 0; i < cnt; i++)
    for (int k = 0; k < cnt; k++) {
      if (nb[k] > nb[i]) continue;
      long t = ves_pattern_find(pat, nb[i], nb[k]);
      assert(t >= 0); /* the pattern holds the couplings of the points at the nodes */
      blk[4 * t] += c * dr[i] * dr[k];
      blk[4 * t + 3] += c * dz[i] * dz[k];
    }
}

/* The drift-damping matrix S (model.h, ves_model_params.drift):
 *   u^T S u = sum_a c_a |u^a - u(X_a)|^2,  c_a = drift mu 2 pi M_a / h_a^2,
 *   M_a = sum_alpha w_alpha R_alpha P_a(X_alpha)  (P_a: p_a plus its ghost's),
 * with u(X_a) = sum_b N_ab u^b from the tables at the nodes (a ghost entry
 * carries -u_r, +u_z). Per component i, S_i = sum_a c_a d_ia d_ia^T with
 * d_ia = e_a - N_i(a, .): r and z decouple, so only the rr and zz entries of
 * the blocks are set. M_a is node a's share of the r-weighted reference
 * measure (the lumped mass of the basis; > 0 on the axis too). Wall nodes
 * (fixed, no drift) have no term: their points at the nodes lie 1e-3 h_a
 * inside the hull, where an affine motion differs from its nodal value. */
static ves_status drift_build(ves_model *m) {
  const ves_quad *q = m->q, *qn = m->qn;
  const int n = m->nodes->n;
  const ves_pattern *pat = m->pat;
  double *M = calloc((size_t)n, sizeof *M);
  int *nb = malloc(((size_t)qn->ptr[n] + 1) * sizeof *nb);
  double *dr = malloc(((size_t)qn->ptr[n] + 1) * sizeof *dr);
  double *dz = malloc(((size_t)qn->ptr[n] + 1) * sizeof *dz);
  m->dblk = calloc(4 * (size_t)pat->ptr[n] + 1, sizeof *m->dblk);
  ves_status s = VES_ERR_ALLOC;
  if (!M || !nb || !dr || !dz || !m->dblk) goto done;
  node_measure(q, n, M);
  for (int a = 0; a < n; a++) {
    if (m->nodes->flag[a] & VES_NODE_WALL) /* fixed, u = 0 there; and its point sits */
      continue;                            /* off the hull, so no exact reproduction */
    const int cnt = defect_row(qn, a, nb, dr, dz);
    const double h = m->nodes->h[a];
    const double c = m->par.drift * m->par.mu * 2 * M_PI * M[a] / (h * h);
    defect_blocks(pat, cnt, nb, dr, dz, c, m->dblk);
  }
  s = VES_OK;
done:
  free(M), free(nb), free(dr), free(dz);
  return s;
}

/* The stabilization of E (model.h, ves_model_params.stab): the defect rows
 * of the nodes off the wall, c_a = stab k 2 pi M_a / h_a^2, and the constant
 * Hessian sum_a c_a d_a d_a^T (per component) in the pattern. */
static ves_status stab_build(ves_model *m) {
  const ves_quad *qn = m->qn;
  const int n = m->nodes->n;
  const size_t cap = (size_t)qn->ptr[n] + n + 1; /* a row: its list, and a itself */
  m->sptr = malloc(((size_t)n + 1) * sizeof *m->sptr);
  m->snb = malloc(cap * sizeof *m->snb);
  m->sdr = malloc(cap * sizeof *m->sdr);
  m->sdz = malloc(cap * sizeof *m->sdz);
  m->sc = calloc((size_t)n, sizeof *m->sc);
  m->sblk = calloc(4 * (size_t)m->pat->ptr[n] + 1, sizeof *m->sblk);
  if (!m->sptr || !m->snb || !m->sdr || !m->sdz || !m->sc || !m->sblk) return VES_ERR_ALLOC;
  node_measure(m->q, n, m->sc);
  m->sptr[0] = 0;
  for (int a = 0; a < n; a++) {
    const int k0 = m->sptr[a];
    if (m->nodes->flag[a] & VES_NODE_WALL) { /* fixed: no term (as the drift damping) */
      m->sc[a] = 0, m->sptr[a + 1] = k0;
      continue;
    }
    const int cnt = defect_row(qn, a, m->snb + k0, m->sdr + k0, m->sdz + k0);
    const double h = m->nodes->h[a];
    m->sc[a] = m->par.stab * m->par.k * 2 * M_PI * m->sc[a] / (h * h);
    defect_blocks(m->pat, cnt, m->snb + k0, m->sdr + k0, m->sdz + k0, m->sc[a], m->sblk);
    m->sptr[a + 1] = k0 + cnt;
  }
  return VES_OK;
}

/* E_s = (1/2) sum_a c_a |d_a|^2 and (g != NULL) g += grad E_s. */
static long double stab_eval(const ves_model *m, const double *y, double *g, double gs) {
  long double E = 0;
  for (int a = 0; a < m->nodes->n; a++) {
    double d[2] = {0, 0};
    for (int j = m->sptr[a]; j < m->sptr[a + 1]; j++)
      d[0] += m->sdr[j] * y[2 * m->snb[j]], d[1] += m->sdz[j] * y[2 * m->snb[j] + 1];
    E += 0.5 * m->sc[a] * (d[0] * d[0] + d[1] * d[1]);
    if (g)
      for (int j = m->sptr[a]; j < m->sptr[a + 1]; j++)
        g[2 * m->snb[j]] += gs * m->sc[a] * d[0] * m->sdr[j],
            g[2 * m->snb[j] + 1] += gs * m->sc[a] * d[1] * m->sdz[j];
  }
  return E;
}

/* The model from checked arguments and point data pd[6 nq] (copied): the
 * common part of ves_model_create and ves_model_create_points. */
static ves_status model_build(const ves_nodes *nodes, const ves_quad *q, const double *pd,
                              const ves_model_params *par, ves_model **out) {
  int n = nodes->n;
  ves_status s = VES_ERR_ALLOC;
  ves_model *m = calloc(1, sizeof *m);
  if (!m) return VES_ERR_ALLOC;
  m->nodes = nodes, m->q = q, m->par = *par;
  m->lp.eps = par->eps, m->lp.C0 = par->c0, m->lp.mu = par->mu, m->lp.lambda = par->lambda;
  m->mmax = 0;
  for (int al = 0; al < q->nq; al++)
    if (q->ptr[al + 1] - q->ptr[al] > m->mmax) m->mmax = q->ptr[al + 1] - q->ptr[al];
  m->cap = NPT * m->mmax;
  m->nthr = ves_omp_threads();
  if (m->nthr > 64) /* zcut[] in make_slabs; beyond 2 cores untested anyway */
    m->nthr = 64;
  if (m->nthr < 1) m->nthr = 1;
  m->pt = malloc((size_t)q->nq * sizeof *m->pt);
  m->fixed = malloc(2 * (size_t)n);
  m->yref = malloc(2 * (size_t)n * sizeof *m->yref);
  m->ws = calloc((size_t)m->nthr, sizeof *m->ws);
  m->ev = malloc(4 * (size_t)q->nq * sizeof *m->ev);
  if (!m->pt || !m->fixed || !m->yref || !m->ws || !m->ev) goto fail;
  for (int k = 0; k < m->nthr; k++)
    if ((s = ws_alloc(m->ws + k, n, m->mmax, m->cap)) != VES_OK) goto fail;
  for (int a = 0; a < n; a++) {
    m->fixed[2 * a] = (nodes->flag[a] & (VES_NODE_WALL | VES_NODE_AXIS)) != 0; /* r */
    m->fixed[2 * a + 1] = (nodes->flag[a] & VES_NODE_WALL) != 0;               /* z */
  }
  memcpy(m->yref, nodes->x, 2 * (size_t)n * sizeof *m->yref);
  for (int al = 0; al < q->nq; al++) {
    const double *f = pd + 6 * (size_t)al;
    m->pt[al].phi0 = f[0];
    m->pt[al].dphi0[0] = f[1], m->pt[al].dphi0[1] = f[2];
    m->pt[al].ddphi0[0] = f[3], m->pt[al].ddphi0[1] = f[4], m->pt[al].ddphi0[2] = f[5];
  }
  if ((s = make_slabs(m)) != VES_OK || (s = order_triangles(m)) != VES_OK) goto fail;
  for (int k = 0; k < m->nthr; k++)
    if ((s = ws_alloc_products(m->ws + k, m->numax)) != VES_OK) goto fail;
  if (par->drift > 0 || par->stab > 0) { /* the points at the nodes, same LME parameters */
    if ((s = ves_quad_create_at_nodes(nodes, &m->qn)) != VES_OK ||
        (s = ves_quad_tables(m->qn, nodes, &q->lme, NULL)) != VES_OK)
      goto fail;
  }
  s = ves_pattern_create(q, m->qn, n, m->fixed, &m->pat);
  if (s != VES_OK) goto fail;
  if (par->drift > 0 && (s = drift_build(m)) != VES_OK) goto fail;
  if (par->stab > 0 && (s = stab_build(m)) != VES_OK) goto fail;
  *out = m;
  return VES_OK;
fail:
  ves_model_destroy(&m);
  return s;
}

ves_status ves_model_create_points(const ves_nodes *nodes, const ves_quad *q, const double *pd,
                                   const ves_model_params *par, ves_model **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL; /* on every error path */
  VES_CHECK(nodes && q && q->tab && pd && par, VES_ERR_ARG);
  VES_CHECK(par->eps > 0 && par->k > 0 && par->mu >= 0 && par->drift >= 0 && isfinite(par->drift),
            VES_ERR_ARG);
  VES_CHECK(par->stab >= 0 && isfinite(par->stab), VES_ERR_ARG);
  VES_CHECK(q->nq == NPT * q->ntri, VES_ERR_ARG);
  for (size_t i = 0; i < 6 * (size_t)q->nq; i++) VES_CHECK(isfinite(pd[i]), VES_ERR_ARG);
  return model_build(nodes, q, pd, par, out);
}

/* The point data of phi0 from its nodal coefficients (ves_quad_field), then
 * the common build. */
ves_status ves_model_create(const ves_nodes *nodes, const ves_quad *q, const double *phi0c,
                            const ves_model_params *par, ves_model **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL; /* on every error path */
  VES_CHECK(nodes && q && q->tab && phi0c && par, VES_ERR_ARG);
  VES_CHECK(par->eps > 0 && par->k > 0 && par->mu >= 0 && par->drift >= 0 && isfinite(par->drift),
            VES_ERR_ARG);
  VES_CHECK(par->stab >= 0 && isfinite(par->stab), VES_ERR_ARG);
  VES_CHECK(q->nq == NPT * q->ntri, VES_ERR_ARG);
  double *fld = malloc(6 * (size_t)q->nq * sizeof *fld);
  if (!fld) return VES_ERR_ALLOC;
  ves_quad_field(q, phi0c, 2, fld);
  ves_status s = model_build(nodes, q, fld, par, out);
  free(fld);
  return s;
}

void ves_model_point_data(const ves_model *m, double *pd) {
  for (int al = 0; al < m->q->nq; al++) {
    const ves_model_point *p = m->pt + al;
    double *f = pd + 6 * (size_t)al;
    f[0] = p->phi0, f[1] = p->dphi0[0], f[2] = p->dphi0[1];
    f[3] = p->ddphi0[0], f[4] = p->ddphi0[1], f[5] = p->ddphi0[2];
  }
}

void ves_model_get_params(const ves_model *m, ves_model_params *par) { *par = m->par; }

const ves_nodes *ves_model_nodes(const ves_model *m) { return m->nodes; }

const ves_quad *ves_model_quad(const ves_model *m) { return m->q; }

/* The inner loops over a point's nodes are written as contiguous
 * reductions (the table rows are contiguous; y is gathered first) and asked
 * to vectorize with OpenMP simd: the same binary sums in the same order on
 * every thread, so results stay bitwise independent of the thread count. */
#ifdef _OPENMP
#define OMP_SIMD_SUM _Pragma("omp simd reduction(+ : s)")
#define OMP_SIMD _Pragma("omp simd")
#else
#define OMP_SIMD_SUM
#define OMP_SIMD
#endif

/* q = B y at the point (the 11 local kinematic variables), with yl (2 mu
 * scratch) the gathered y_r, y_z of its nodes. */
static void kinematics(const folded *f, const double *y, double *yl, double q[VES_NQ]) {
  const int mu = f->mu;
  const double *Tr = f->Tr, *Tz = f->Tz;
  const int *un = f->un;
  double *yr = yl, *yz = yl + mu;
  for (int u = 0; u < mu; u++) yr[u] = y[2 * un[u]], yz[u] = y[2 * un[u] + 1];
  for (int j = 0; j < 6; j++) {
    const double *row = Tr + j * mu;
    double s = 0.0;
    OMP_SIMD_SUM /* over s */
        for (int u = 0; u < mu; u++) s += row[u] * yr[u];
    q[MAP_Q.qr[j]] = s;
  }
  for (int j = 0; j < 5; j++) {
    const double *row = Tz + MAP_Q.rz[j] * mu;
    double s = 0.0;
    OMP_SIMD_SUM /* over s */
        for (int u = 0; u < mu; u++) s += row[u] * yz[u];
    q[MAP_Q.qz[j]] = s;
  }
}

/* g += c B^T ge on the entries of the nodes of slab k: per node u,
 * (B^T ge)_r(u) = sum_j ge[qr_j] Tr[rr_j][u], (B^T ge)_z(u) likewise, formed
 * row by row over the nodes (sl: 2 mu scratch), then added. */
static void scatter_grad(const folded *f, const int *owner, int k, double c, const double *ge,
                         double *sl, double *g) {
  const int mu = f->mu;
  double *sr = sl, *sz = sl + mu;
  for (int u = 0; u < mu; u++) sr[u] = sz[u] = 0.0;
  for (int j = 0; j < 6; j++) {
    const double a = c * ge[MAP_Q.qr[j]], *row = f->Tr + MAP_Q.rr[j] * mu;
    OMP_SIMD
    for (int u = 0; u < mu; u++) sr[u] += a * row[u];
  }
  for (int j = 0; j < 5; j++) {
    const double a = c * ge[MAP_Q.qz[j]], *row = f->Tz + MAP_Q.rz[j] * mu;
    OMP_SIMD
    for (int u = 0; u < mu; u++) sz[u] += a * row[u];
  }
  for (int u = 0; u < mu; u++) {
    const int a = f->un[u];
    if (owner[a] == k) g[2 * a] += sr[u], g[2 * a + 1] += sz[u];
  }
}

/* The triangle's matrices B over its union, stacked point by point, and
 * their products with the local Hessians (workspace X, Y; nu x K
 * column-major: one contiguous column per row (p, k) of B, over the union
 * nodes j):
 *   Xr[(p nr + k) nu + j] = b_r(p, k; j),  Xz[(p nz + k) nu + j] = b_z(p, k; j)
 * (the folded table rows of map mp; zero where point p does not see node j),
 * Kr = NPT nr, Kz = NPT nz columns, and with cH_p = c_p d2e/dq2 at point p
 * split by the map into its rr, rz and zz parts,
 *   Yrr = Xr diag_p(cH_rr),  Yrz = Xz diag_p(cH_zr),  Yzz = Xz diag_p(cH_zz)
 * (axpys over the union, vectorized).
 * Hs holds the NPT local matrices (nl x nl each, c included). */
#if defined(__GNUC__)
__attribute__((always_inline))
#endif
static inline void
triangle_xy_n(const local_map *mp, const int nr, const int nz, const folded f[NPT], const int *slot,
              int nu, const double *Hs, double *X, double *Y) {
  const int nl = mp->nl, Kr = NPT * nr, Kz = NPT * nz;
  double *Xr = X, *Xz = X + (size_t)Kr * nu;
  double *Yrr = Y, *Yrz = Y + (size_t)Kr * nu, *Yzz = Y + 2 * (size_t)Kr * nu;
  memset(X, 0, (size_t)(Kr + Kz) * nu * sizeof *X);
  for (int p = 0; p < NPT; p++) {
    const folded *fp = f + p;
    const int mu = fp->mu;
    for (int v = 0; v < mu; v++) {
      const int j = slot[fp->un[v]];
      for (int k = 0; k < nr; k++) Xr[(size_t)(p * nr + k) * nu + j] = fp->Tr[mp->rr[k] * mu + v];
      for (int k = 0; k < nz; k++) Xz[(size_t)(p * nz + k) * nu + j] = fp->Tz[mp->rz[k] * mu + v];
    }
  }
  for (int p = 0; p < NPT; p++) {
    const double *H = Hs + (size_t)p * nl * nl;
    const double *xr = Xr + (size_t)p * nr * nu, *xz = Xz + (size_t)p * nz * nu;
    for (int k = 0; k < nr; k++) { /* row (p, k) of Yrr and Yrz: axpys over the union */
      double *yrr = Yrr + (size_t)(p * nr + k) * nu, *yrz = Yrz + (size_t)(p * nr + k) * nu;
      for (int j = 0; j < nu; j++) yrr[j] = yrz[j] = 0.0;
      for (int l = 0; l < nr; l++) {
        const double h = H[mp->qr[k] * nl + mp->qr[l]], *x = xr + (size_t)l * nu;
        OMP_SIMD
        for (int j = 0; j < nu; j++) yrr[j] += h * x[j];
      }
      for (int l = 0; l < nz; l++) {
        const double h = H[mp->qr[k] * nl + mp->qz[l]], *x = xz + (size_t)l * nu;
        OMP_SIMD
        for (int j = 0; j < nu; j++) yrz[j] += h * x[j];
      }
    }
    for (int k = 0; k < nz; k++) {
      double *yzz = Yzz + (size_t)(p * nz + k) * nu;
      for (int j = 0; j < nu; j++) yzz[j] = 0.0;
      for (int l = 0; l < nz; l++) {
        const double h = H[mp->qz[k] * nl + mp->qz[l]], *x = xz + (size_t)l * nu;
        OMP_SIMD
        for (int j = 0; j < nu; j++) yzz[j] += h * x[j];
      }
    }
  }
}

/* triangle_xy_n with the map's sizes as constants (the small products
 * unrolled). */
static void triangle_xy(const local_map *mp, const folded f[NPT], const int *slot, int nu,
                        const double *Hs, double *X, double *Y) {
  if (mp->nr == 6 && mp->nz == 5)
    triangle_xy_n(mp, 6, 5, f, slot, nu, Hs, X, Y);
  else if (mp->nr == 3 && mp->nz == 2)
    triangle_xy_n(mp, 3, 2, f, slot, nu, Hs, X, Y);
  else
    triangle_xy_n(mp, mp->nr, mp->nz, f, slot, nu, Hs, X, Y);
}

/* Add the owned rows of the triangle's block matrix to the pattern: block
 * (U[i], U[j]), j <= i, with entries (rr, rz, zr, zz) =
 * (Mrr[j + i nu], Mrz[i + j nu], Mrz[j + i nu], Mzz[j + i nu]) (Mrr and Mzz
 * are symmetric: column i is read), by one forward walk along the pattern
 * row of U[i] (ascending, as U is). Pairs of the union that share no point
 * are not in the pattern; their sums are exactly zero (X is zero where a
 * point does not see the node) and are skipped. */
static void triangle_scatter(const ves_model *m, const int *U, int nu, int k, const double *M,
                             double *blk) {
  const ves_pattern *pat = m->pat;
  const double *Mrr = M, *Mrz = M + (size_t)nu * nu, *Mzz = M + 2 * (size_t)nu * nu;
  for (int i = 0; i < nu; i++) {
    const int a = U[i];
    if (m->owner[a] != k) continue;
    const double *crr = Mrr + (size_t)i * nu, *czr = Mrz + (size_t)i * nu,
                 *czz = Mzz + (size_t)i * nu;
    int lo = pat->ptr[a], hi = pat->ptr[a + 1] - 1;
    while (lo < hi) { /* first column >= U[0] in row a */
      int mid = (lo + hi) / 2;
      if (pat->col[mid] < U[0])
        lo = mid + 1;
      else
        hi = mid;
    }
    for (int j = 0, t = lo; j <= i; j++) {
      const int b = U[j];
      while (pat->col[t] < b) t++; /* the diagonal (a, a) ends the walk */
      const double rz = Mrz[i + (size_t)j * nu];
      if (pat->col[t] != b) {
        assert(crr[j] == 0 && rz == 0 && czr[j] == 0 && czz[j] == 0);
        continue;
      }
      double *dst = blk + 4 * (size_t)t;
      dst[0] += crr[j], dst[1] += rz, dst[2] += czr[j], dst[3] += czz[j];
    }
  }
}

/* The step's dissipation at its start y^n (ves_model_dissipation_ref): the
 * velocity variables qn (VES_NQD a point) of y^n, and the coefficient cK of
 * K(y^n) in what is assembled or evaluated. */
typedef struct {
  const double *qn;
  double cK;
} step_ref;

/* D = d2 diss / dqdot2 at point al of y^n (without 2 pi w). */
static ves_status step_ref_dissip(const ves_model *m, const step_ref *sr, int al, double *D) {
  double qa[VES_NQ] = {0};
  memcpy(qa, sr->qn + VES_NQD * (size_t)al, VES_NQD * sizeof *qa);
  return ves_model_local_dissip(&m->lp, qa, D);
}

/* What a triangle pass assembles. */
typedef enum { ASM_HESS, ASM_DISS } asm_kind;

/* Triangle t's contribution to the rows of slab k: the local matrices of its
 * points (fac[3] = f_E cE, f_A cA, f_V cV for ASM_HESS), then its block
 * matrix sum_p B_p^T cH_p B_p over its union as three products
 *   Mrr = Xr Yrr^T,  Mrz = Xr Yrz^T,  Mzz = Xz Yzz^T   (triangle_xy)
 * by the BLAS (one thread: the caller runs the triangles in parallel), and
 * its owned rows into blk. */
static ves_status triangle_blocks(const ves_model *m, model_ws *w, asm_kind kind,
                                  const double fac[3], const step_ref *sr, int t, int k,
                                  const double *y, double *blk) {
  const local_map *mp = kind == ASM_HESS ? &MAP_Q : &MAP_QD;
  const int nl = mp->nl;
  folded f[NPT];
  const int *U;
  const int nu = triangle_union(m, w, t, f, &U);
  double Hs[NPT * VES_NQ * VES_NQ];
  for (int p = 0; p < NPT; p++) {
    const int al = NPT * t + p;
    double q[VES_NQ], e, H[VES_NQ * VES_NQ], *Hp = Hs + (size_t)p * nl * nl, c;
    kinematics(f + p, y, w->yl, q);
    for (int i = 0; i < nl * nl; i++) Hp[i] = 0.0;
    if (kind == ASM_HESS) {
      if (fac[0] != 0) {
        VES_CALL(ves_model_local_energy(&m->lp, &m->pt[al], q, &e, NULL, H));
        for (int i = 0; i < VES_NQ * VES_NQ; i++) Hp[i] += fac[0] * H[i];
      }
      if (fac[1] != 0) {
        VES_CALL(ves_model_local_area(&m->lp, &m->pt[al], q, &e, NULL, H));
        for (int i = 0; i < VES_NQ * VES_NQ; i++) Hp[i] += fac[1] * H[i];
      }
      if (fac[2] != 0) {
        VES_CALL(ves_model_local_volume(&m->lp, &m->pt[al], q, &e, NULL, H));
        for (int i = 0; i < VES_NQ * VES_NQ; i++) Hp[i] += fac[2] * H[i];
      }
      if (sr && sr->cK != 0) { /* + cK K(y^n): the velocity block (q 0..4) */
        double D[VES_NQD * VES_NQD];
        VES_CALL(step_ref_dissip(m, sr, al, D));
        for (int i = 0; i < VES_NQD; i++)
          for (int j = 0; j < VES_NQD; j++) Hp[i * VES_NQ + j] += 2 * M_PI * sr->cK * D[i * VES_NQD + j];
      }
      c = m->q->w[al];
    } else {
      VES_CALL(ves_model_local_dissip(&m->lp, q, Hp));
      c = 2 * M_PI * m->q->w[al];
    }
    for (int i = 0; i < nl * nl; i++) Hp[i] *= c;
  }
  triangle_xy(mp, f, w->slot, nu, Hs, w->X, w->Y);
  const int Kr = NPT * mp->nr, Kz = NPT * mp->nz;
  const double *Xr = w->X, *Xz = w->X + (size_t)Kr * nu;
  const double *Yrr = w->Y, *Yrz = w->Y + (size_t)Kr * nu, *Yzz = w->Y + 2 * (size_t)Kr * nu;
  double *M = w->M;
  cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, nu, nu, Kr, 1.0, Xr, nu, Yrr, nu, 0.0, M,
              nu); /* Mrr = Xr Yrr^T */
  cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, nu, nu, Kr, 1.0, Xr, nu, Yrz, nu, 0.0,
              M + (size_t)nu * nu, nu); /* Mrz = Xr Yrz^T */
  cblas_dgemm(CblasColMajor, CblasNoTrans, CblasTrans, nu, nu, Kz, 1.0, Xz, nu, Yzz, nu, 0.0,
              M + 2 * (size_t)nu * nu, nu); /* Mzz = Xz Yzz^T */
  triangle_scatter(m, U, nu, k, M, blk);
  return VES_OK;
}

/* blk = sum over the triangles of their block matrices (kind, fac as in
 * triangle_blocks), the slabs shared out over the threads. */
static ves_status assemble(ves_model *m, asm_kind kind, const double fac[3], const step_ref *sr,
                           const double *y, double *blk) {
  const ves_pattern *pat = m->pat;
  ves_status st[64];
  memset(blk, 0, 4 * (size_t)pat->ptr[pat->n] * sizeof *blk);
  for (int k = 0; k < m->nthr; k++) st[k] = VES_OK;
  /* the triangles' products run on one BLAS thread each, in parallel */
  const int blas_threads = openblas_get_num_threads();
  if (blas_threads != 1) openblas_set_num_threads(1);
#pragma omp parallel num_threads(m->nthr)
  {
    const int tid = ves_omp_tid(), nt = ves_omp_nteam();
    model_ws *w = m->ws + tid;
    for (int k = tid; k < m->nthr; k += nt)
      for (int it = 0; it < m->q->ntri && st[k] == VES_OK; it++) {
        const int t = m->torder[it];
        if (m->tlo[t] <= k && k <= m->thi[t])
          st[k] = triangle_blocks(m, w, kind, fac, sr, t, k, y, blk);
      }
  }
  if (blas_threads != 1) openblas_set_num_threads(blas_threads);
  for (int k = 0; k < m->nthr; k++)
    if (st[k] != VES_OK) return st[k];
  return VES_OK;
}

/* The prefactors of the integrands of E, A and V: 2 pi (the axisymmetric
 * measure) times f_E = 3k/(16 sqrt2 eps), f_A = 3/(2 sqrt2), f_V = 1
 * (DESIGN.md §1), each times its coefficient c[i]. */
static void functional_factors(const ves_model *m, double cE, double cA, double cV,
                               double fac[3]) {
  fac[0] = 2 * M_PI * 3 * m->par.k / (16 * M_SQRT2 * m->par.eps) * cE;
  fac[1] = 2 * M_PI * 3 / (2 * M_SQRT2) * cA;
  fac[2] = 2 * M_PI * cV;
}

/* The values and gradients of triangle t's points for slab k: w e of the
 * selected functionals into m->ev (by the triangle's first slab only), and
 * the gradient entries of the slab's nodes. With a step reference sr (E
 * selected): g[0] receives cE grad E + K(y^n)(y - y^n), one scatter a point,
 * and ev's fourth slot the point's (1/2) dq^T (2 pi w D) dq, dq = q - q(y^n)
 * (the velocity variables; K = sum 2 pi w B^T D B). */
static ves_status triangle_eval(ves_model *m, model_ws *w, int which, const step_ref *sr, double cE,
                                int t, int k, const double *y, double *const g[3]) {
  double fac[3];
  functional_factors(m, 1.0, 1.0, 1.0, fac);
  static ves_model_local_fn *const fn[3] = {ves_model_local_energy, ves_model_local_area,
                                            ves_model_local_volume};
  for (int p = 0; p < NPT; p++) {
    const int al = NPT * t + p;
    folded f;
    double q[VES_NQ], e, ge[VES_NQ], wa = m->q->w[al], gk[VES_NQD];
    fold_point(m->q, m->mmax, w, al, 0, &f);
    kinematics(&f, y, w->yl, q);
    if (sr) { /* the step's dissipation: gk = 2 pi w D dq */
      double D[VES_NQD * VES_NQD], dq[VES_NQD], dv = 0;
      VES_CALL(step_ref_dissip(m, sr, al, D));
      for (int i = 0; i < VES_NQD; i++) dq[i] = q[i] - sr->qn[VES_NQD * (size_t)al + i];
      for (int i = 0; i < VES_NQD; i++) {
        double s = 0;
        for (int j = 0; j < VES_NQD; j++) s += D[i * VES_NQD + j] * dq[j];
        gk[i] = 2 * M_PI * wa * s;
        dv += dq[i] * gk[i];
      }
      if (k == m->tlo[t]) m->ev[4 * (size_t)al + 3] = 0.5 * dv;
    }
    for (int i = 0; i < 3; i++) {
      if (!(which & (1 << i))) continue;
      VES_CALL(fn[i](&m->lp, &m->pt[al], q, &e, g[i] ? ge : NULL, NULL));
      if (k == m->tlo[t]) m->ev[4 * (size_t)al + i] = wa * e;
      if (!g[i]) continue;
      if (i == 0 && sr) { /* cE grad E + K d in one scatter */
        const double c = cE * fac[0] * wa;
        for (int j = 0; j < VES_NQ; j++) ge[j] *= c;
        for (int j = 0; j < VES_NQD; j++) ge[j] += gk[j];
        scatter_grad(&f, m->owner, k, 1.0, ge, w->yl + 2 * f.mu, g[i]);
      } else
        scatter_grad(&f, m->owner, k, fac[i] * wa, ge, w->yl + 2 * f.mu, g[i]);
    }
  }
  return VES_OK;
}

/* ves_model_eval and ves_model_eval_step. */
static ves_status eval_points(ves_model *m, const double *y, int which, const step_ref *sr,
                              double cE, double *E, double *A, double *V, double *Dv, double *gE,
                              double *gA, double *gV) {
  VES_CHECK(m && y, VES_ERR_ARG);
  int n = m->nodes->n;
  double fac[3];
  functional_factors(m, 1.0, 1.0, 1.0, fac);
  const double fE = fac[0], fA = fac[1], fV = fac[2];
  double *const g[3] = {(which & VES_F_E) ? gE : NULL, (which & VES_F_A) ? gA : NULL,
                        (which & VES_F_V) ? gV : NULL};
  ves_status st[64];
  which &= VES_F_E | VES_F_A | VES_F_V;
  for (int i = 0; i < 3; i++)
    if (g[i]) memset(g[i], 0, 2 * (size_t)n * sizeof *g[i]);
  for (int k = 0; k < m->nthr; k++) st[k] = VES_OK;
#pragma omp parallel num_threads(m->nthr)
  {
    const int tid = ves_omp_tid(), nt = ves_omp_nteam();
    model_ws *w = m->ws + tid;
    for (int k = tid; k < m->nthr; k += nt)
      for (int t = 0; t < m->q->ntri && st[k] == VES_OK; t++) /* point order: the */
        if (m->tlo[t] <= k && k <= m->thi[t]) /* gradient sums as before, bit for bit */
          st[k] = triangle_eval(m, w, which, sr, cE, t, k, y, g);
  }
  for (int k = 0; k < m->nthr; k++)
    if (st[k] != VES_OK) return st[k];
  /* The totals are accumulated in extended precision, in point order: the
   * sums run over ~1e4..1e6 points, and the optimizers (line searches,
   * finite-difference checks) compare values that differ by far less than
   * the double rounding of such a sum (~1e-16 sqrt(nq) relative); each
   * point's contribution stays in double. */
  long double s[4] = {0, 0, 0, 0};
  const int nsum = sr ? 4 : 3;
  for (int al = 0; al < m->q->nq; al++)
    for (int i = 0; i < nsum; i++)
      if (i == 3 || (which & (1 << i))) s[i] += m->ev[4 * (size_t)al + i];
  long double Es = 0; /* the stabilization, E_s and its gradient (weight cE in a step's) */
  if ((which & VES_F_E) && m->sc) Es = stab_eval(m, y, g[0], sr ? cE : 1.0);
  if ((which & VES_F_E) && E) *E = m->sc ? (double)(fE * s[0] + Es) : (double)(fE * s[0]);
  if ((which & VES_F_A) && A) *A = (double)(fA * s[1]);
  if ((which & VES_F_V) && V) *V = (double)(fV * s[2]);
  if (sr && Dv) *Dv = (double)s[3];
  return VES_OK;
}

ves_status ves_model_eval(ves_model *m, const double *y, int which, double *E, double *A, double *V,
                          double *gE, double *gA, double *gV) {
  return eval_points(m, y, which, NULL, 1.0, E, A, V, NULL, gE, gA, gV);
}

ves_status ves_model_eval_step(ves_model *m, const double *y, int which, const double *qn, double cE,
                               double *E, double *A, double *V, double *Dv, double *gF, double *gA,
                               double *gV) {
  VES_CHECK(qn && (which & VES_F_E) && isfinite(cE), VES_ERR_ARG);
  const step_ref sr = {qn, 1.0};
  return eval_points(m, y, which, &sr, cE, E, A, V, Dv, gF, gA, gV);
}

size_t ves_model_dissipation_ref_size(const ves_model *m) {
  return m ? VES_NQD * (size_t)m->q->nq : 0;
}

/* Call fn(m, al, q, ctx) once for every point al with its kinematics q at y,
 * the triangles shared out over the threads (each by its first slab). */
typedef ves_status point_fn(const ves_model *m, int al, const double q[VES_NQ], void *ctx);
static ves_status each_point(ves_model *m, const double *y, point_fn *fn, void *ctx) {
  ves_status st[64];
  for (int k = 0; k < m->nthr; k++) st[k] = VES_OK;
#pragma omp parallel num_threads(m->nthr)
  {
    const int tid = ves_omp_tid(), nt = ves_omp_nteam();
    model_ws *w = m->ws + tid;
    for (int k = tid; k < m->nthr; k += nt)
      for (int t = 0; t < m->q->ntri && st[k] == VES_OK; t++) {
        if (m->tlo[t] != k) /* each triangle once */
          continue;
        for (int p = 0; p < NPT && st[k] == VES_OK; p++) {
          const int al = NPT * t + p;
          folded f;
          double q[VES_NQ];
          fold_point(m->q, m->mmax, w, al, 0, &f);
          kinematics(&f, y, w->yl, q);
          st[k] = fn(m, al, q, ctx);
        }
      }
  }
  for (int k = 0; k < m->nthr; k++)
    if (st[k] != VES_OK) return st[k];
  return VES_OK;
}

/* ves_model_dissipation_ref's point: its velocity variables, and D there
 * (y must be admissible). */
static ves_status ref_point(const ves_model *m, int al, const double q[VES_NQ], void *ctx) {
  double D[VES_NQD * VES_NQD];
  memcpy((double *)ctx + VES_NQD * (size_t)al, q, VES_NQD * sizeof *q);
  return ves_model_local_dissip(&m->lp, q, D);
}

ves_status ves_model_dissipation_ref(ves_model *m, const double *y, double *qn) {
  VES_CHECK(m && y && qn, VES_ERR_ARG);
  return each_point(m, y, ref_point, qn);
}

ves_status ves_model_hessian(ves_model *m, const double *y, double cE, double cA, double cV,
                             double *blk) {
  VES_CHECK(m && y && blk, VES_ERR_ARG);
  double fac[3];
  functional_factors(m, cE, cA, cV, fac);
  VES_CALL(assemble(m, ASM_HESS, fac, NULL, y, blk));
  if (m->sblk && cE != 0) /* + cE Hess E_s, constant */
    for (size_t i = 0; i < 4 * (size_t)m->pat->ptr[m->nodes->n]; i++) blk[i] += cE * m->sblk[i];
  return VES_OK;
}

ves_status ves_model_hessian_step(ves_model *m, const double *y, const double *qn, double cE,
                                  double cA, double cV, double cK, double *blk) {
  VES_CHECK(m && y && qn && blk && isfinite(cK), VES_ERR_ARG);
  double fac[3];
  functional_factors(m, cE, cA, cV, fac);
  const step_ref sr = {qn, cK};
  VES_CALL(assemble(m, ASM_HESS, fac, &sr, y, blk));
  if (m->sblk && cE != 0) /* + cE Hess E_s, constant */
    for (size_t i = 0; i < 4 * (size_t)m->pat->ptr[m->nodes->n]; i++) blk[i] += cE * m->sblk[i];
  if (m->dblk && cK != 0) /* + cK S: the drift damping */
    for (size_t i = 0; i < 4 * (size_t)m->pat->ptr[m->nodes->n]; i++) blk[i] += cK * m->dblk[i];
  return VES_OK;
}

const double *ves_model_drift_blocks(const ves_model *m) { return m ? m->dblk : NULL; }

ves_status ves_model_dissipation(ves_model *m, const double *y, double *blk) {
  VES_CHECK(m && y && blk, VES_ERR_ARG);
  const double fac[3] = {0, 0, 0};
  VES_CALL(assemble(m, ASM_DISS, fac, NULL, y, blk));
  if (m->dblk) /* K + S: the drift damping */
    for (size_t i = 0; i < 4 * (size_t)m->pat->ptr[m->nodes->n]; i++) blk[i] += m->dblk[i];
  return VES_OK;
}

/* ves_model_pointwise_W's point. */
static ves_status w_point(const ves_model *m, int al, const double q[VES_NQ], void *ctx) {
  double e;
  return ves_model_local_energy_ex(&m->lp, &m->pt[al], q, &e, NULL, NULL, (double *)ctx + al, NULL);
}

ves_status ves_model_pointwise_W(ves_model *m, const double *y, double *W) {
  VES_CHECK(m && y && W, VES_ERR_ARG);
  return each_point(m, y, w_point, W);
}

ves_status ves_model_set_c0(ves_model *m, double c0) {
  VES_CHECK(m && isfinite(c0), VES_ERR_ARG);
  m->par.c0 = c0;
  m->lp.C0 = c0;
  return VES_OK;
}

double ves_model_get_c0(const ves_model *m) { return m->par.c0; }

double ves_model_get_k(const ves_model *m) { return m->par.k; }
