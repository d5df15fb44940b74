/* vesica — the model's constant matrices of the motion of the coefficients
 * relative to the material (model.c holds the API), both over the nodes a
 * off the wall with M_a = sum_alpha w_alpha R_alpha P_a(X_alpha) the node's
 * r-weighted reference measure:
 *
 * Drift damping (ves_model_params.drift = alpha, off by default): a constant S
 * added to K, ydot^T S ydot = sum_a alpha mu 2 pi M_a / h_a^2 |ydot^a - ydot(X_a)|^2
 * (model_drift_build): zero on affine motions, O((h/L)^2) of K on smooth
 * ones, stiff on the grid-scale coefficient patterns that K hardly resists
 * and along which the coefficients drift from the material over long runs
 * (docs/results.md, "Resets and remeshing").
 *
 * Coefficient-mode stabilization (ves_model_params.stab = kappa; the problem
 * file's [geometry] stabilization, 0.1 by default): the same defect in E,
 * E_s = (1/2) sum_a kappa k 2 pi M_a / h_a^2 |y^a - y(X_a)|^2 (model_stab_build,
 * model_stab_eval): zero on affine maps (so at the reference), O(h^2) on
 * smooth motions, of the size of the coefficients on the grid-scale patterns
 * along which the discrete E has negative curvature, which it removes (the
 * relaxed sphere at eps 0.1 is a minimum; the oblate at eps 0.01 relaxes to
 * the sharp equilibrium's E* within 1.2e-5). With kappa = 0.1 the sphere at
 * rest at eps 0.04 has mu_1 = -6.5e-4 / -1.6e-4 / -1.1e-5 per t* at h_band
 * 0.35 / 0.5 / 0.7 eps (-2.5e-3 / -1.4e-3 / -6.0e-4 with 1e-2), and the
 * sphere's E, the l = 2 rate and the oblate's E* move by less than their
 * discretization errors (docs/results.md, "Accuracy against the
 * sharp-interface references"). E_s is measured from the reference: a reset
 * or a remeshing drops it to 0 (docs/design.md, "Discretization"). */
#include "model/model_core_impl.h"
#include "core/omp_impl.h"

#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

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

/* A row's scratch: its entries sorted by weight and the pattern positions
 * of their pairs (cut_row). */
typedef struct {
  int b;
  double r, z;
} row_entry;

typedef struct {
  long *where; /* n: position of (row, col) in the scattered pattern row, or -1 */
  long *pos;   /* cap^2: pos[i cap + k] = position of the pair (i, k), or -1 */
  row_entry *e;
  int cap;
} row_scratch;

static int by_weight(const void *x, const void *y) {
  const row_entry *p = x, *q = y;
  const double a = fabs(p->z), b = fabs(q->z);
  return a > b ? -1 : a < b ? 1 : (p->b > q->b) - (p->b < q->b); /* falling; ties by node */
}

/* Cut a defect row to the quadrature's couplings: its entries by falling
 * weight, each kept when it is coupled to every one kept before (the
 * pattern of the points, which a node's row exceeds only at the edge of its
 * support: weights ~1e-6..1e-4 of the row's). Returns the kept count. */
static int cut_row(const ves_pattern *pat, row_scratch *w, int cnt, int *nb, double *dr,
                   double *dz) {
  for (int i = 0; i < cnt; i++) w->e[i] = (row_entry){nb[i], dr[i], dz[i]};
  qsort(w->e, (size_t)cnt, sizeof *w->e, by_weight);
  const int cap = w->cap;
  for (int i = 0; i < cnt; i++) { /* the pairs (i, k), k <= i, from row max(b_i, b_k) */
    const int bi = w->e[i].b;
    for (int t = pat->ptr[bi]; t < pat->ptr[bi + 1]; t++) w->where[pat->col[t]] = t;
    for (int k = 0; k < cnt; k++)
      if (w->e[k].b <= bi)
        w->pos[(size_t)i * cap + k] = w->pos[(size_t)k * cap + i] = w->where[w->e[k].b];
    for (int t = pat->ptr[bi]; t < pat->ptr[bi + 1]; t++) w->where[pat->col[t]] = -1;
  }
  int kept = 0, *keep = nb; /* the kept entries' old indices, then the row */
  for (int i = 0; i < cnt; i++) {
    int ok = 1;
    for (int k = 0; k < kept && ok; k++) ok = w->pos[(size_t)i * cap + keep[k]] >= 0;
    if (ok) keep[kept++] = i;
  }
  for (int i = kept - 1; i >= 0; i--) { /* keep[i] >= i: back to front is safe */
    const row_entry en = w->e[keep[i]];
    nb[i] = en.b, dr[i] = en.r, dz[i] = en.z;
  }
  return kept;
}

/* Restore what the cut took from a row: the uncut rows vanish on the fields
 * the folded LME tables reproduce (y_z = c + b z, y_r = b r: translations
 * along the axis and the linear maps), the cut ones only up to the cut
 * weights. The smallest change of the weights, each in proportion to its
 * size (w_j += |w_j| (B^T mu)_j), that makes sum_j dz_j (1, Z_j - Z_a) = 0
 * and sum_j dr_j R_j = 0 (dr carries the ghosts' sign) again, so E_s is zero
 * at the reference and unchanged by translations to rounding. */
static void refit_row(const double *X, int a, int cnt, const int *nb, double *dr, double *dz) {
  double m00 = 0, m01 = 0, m11 = 0, e0 = 0, e1 = 0, mr = 0, er = 0;
  for (int j = 0; j < cnt; j++) {
    const double wz = fabs(dz[j]), wr = fabs(dr[j]), Z = X[2 * nb[j] + 1] - X[2 * a + 1];
    const double R = X[2 * nb[j]];
    m00 += wz, m01 += wz * Z, m11 += wz * Z * Z, e0 += dz[j], e1 += dz[j] * Z;
    mr += wr * R * R, er += dr[j] * R;
  }
  const double det = m00 * m11 - m01 * m01; /* > 0: the row spans several heights */
  const double mu0 = det > 0 ? (-e0 * m11 + e1 * m01) / det : -e0 / m00;
  const double mu1 = det > 0 ? (e0 * m01 - e1 * m00) / det : 0;
  const double nur = mr > 0 ? -er / mr : 0; /* mr = 0: a node on the axis alone */
  for (int j = 0; j < cnt; j++) {
    const double Z = X[2 * nb[j] + 1] - X[2 * a + 1];
    dz[j] += fabs(dz[j]) * (mu0 + mu1 * Z);
    dr[j] += fabs(dr[j]) * nur * X[2 * nb[j]];
  }
}

/* blk += c (dr dr^T, dz dz^T) over the pairs (i, k) of a cut row whose
 * pattern row nb[i] (>= nb[k]) lies in [lo, hi): the rr entry of block t at
 * blk[stride t], the zz entry at blk[stride t + zz] (r and z decouple: S's
 * 4-value blocks, or Hess E_s's rr and zz alone). where[n] is -1 and left so. */
static void row_blocks(const ves_pattern *pat, long *where, int lo, int hi, int cnt, const int *nb,
                       const double *dr, const double *dz, double c, int stride, int zz,
                       double *blk) {
  for (int i = 0; i < cnt; i++) {
    const int bi = nb[i];
    if (bi < lo || bi >= hi) continue;
    for (int t = pat->ptr[bi]; t < pat->ptr[bi + 1]; t++) where[pat->col[t]] = t;
    for (int k = 0; k < cnt; k++) {
      if (nb[k] > bi) continue;
      const long t = where[nb[k]]; /* >= 0: the cut kept coupled pairs only */
      blk[stride * t] += c * dr[i] * dr[k];
      blk[stride * t + zz] += c * dz[i] * dz[k];
    }
    for (int t = pat->ptr[bi]; t < pat->ptr[bi + 1]; t++) where[pat->col[t]] = -1;
  }
}

/* The scratch for the rows of the points at the nodes qn (n nodes). */
static ves_status row_scratch_open(const ves_quad *qn, int n, row_scratch *w) {
  int rmax = 1;
  for (int a = 0; a < n; a++)
    if (qn->ptr[a + 1] - qn->ptr[a] + 1 > rmax) rmax = qn->ptr[a + 1] - qn->ptr[a] + 1;
  *w = (row_scratch){.where = malloc((size_t)n * sizeof *w->where),
                     .pos = malloc((size_t)rmax * rmax * sizeof *w->pos),
                     .e = malloc((size_t)rmax * sizeof *w->e),
                     .cap = rmax};
  if (!w->where || !w->pos || !w->e) return VES_ERR_ALLOC;
  for (int a = 0; a < n; a++) w->where[a] = -1;
  return VES_OK;
}

static void row_scratch_close(row_scratch *w) { free(w->where), free(w->pos), free(w->e); }

/* Node a's defect row, cut to the pattern and refit, into nb, dr, dz (the
 * positions of its pairs in w); returns its count. */
static int node_row(const ves_model *m, row_scratch *w, int a, int *nb, double *dr, double *dz) {
  const int cnt = cut_row(m->pat, w, defect_row(m->qn, a, nb, dr, dz), nb, dr, dz);
  refit_row(m->yref, a, cnt, nb, dr, dz);
  return cnt;
}

/* The cut and refit defect rows of the nodes off the wall (wall nodes: empty
 * rows) into ptr[n + 1], nb, dr, dz (capacity qn->ptr[n] + n + 1, rows a
 * node's points' list and the node itself), and sum_a c[a] (dr dr^T, dz
 * dz^T) of them into blk (stride, zz: row_blocks). Threaded twice over: the
 * rows by node, each thread with its scratch, written at their largest
 * offsets and then packed; the blocks by ranges of pattern rows, every
 * thread walking all rows in node order, so each entry sums its terms in
 * the order of the serial loop: the same bits for any thread count. */
static ves_status defect_rows(const ves_model *m, const double *c, int stride, int zz, int *ptr,
                              int *nb, double *dr, double *dz, double *blk) {
  const ves_quad *qn = m->qn;
  const int n = m->nodes->n;
  int *cnt = malloc((size_t)n * sizeof *cnt);
  if (!cnt) return VES_ERR_ALLOC;
  ves_status st = VES_OK;
#pragma omp parallel if (n > 1000)
  {
    row_scratch w = {0};
    const ves_status mine = row_scratch_open(qn, n, &w);
#pragma omp for schedule(dynamic, 64)
    for (int a = 0; a < n; a++) {
      const size_t k0 = (size_t)qn->ptr[a] + a;
      cnt[a] = mine != VES_OK || (m->nodes->flag[a] & VES_NODE_WALL)
                   ? 0
                   : node_row(m, &w, a, nb + k0, dr + k0, dz + k0);
    }
#pragma omp critical(ves_defect_rows)
    if (mine != VES_OK) st = mine;
    row_scratch_close(&w);
  }
  if (st != VES_OK) goto done;
  ptr[0] = 0;
  for (int a = 0; a < n; a++) { /* pack: a row moves only towards the front */
    const size_t k0 = (size_t)qn->ptr[a] + a;
    ptr[a + 1] = ptr[a] + cnt[a];
    memmove(nb + ptr[a], nb + k0, (size_t)cnt[a] * sizeof *nb);
    memmove(dr + ptr[a], dr + k0, (size_t)cnt[a] * sizeof *dr);
    memmove(dz + ptr[a], dz + k0, (size_t)cnt[a] * sizeof *dz);
  }
#pragma omp parallel if (n > 1000)
  {
    const int nt = ves_omp_nteam(), me = ves_omp_tid();
    const int lo = (int)((long)n * me / nt), hi = (int)((long)n * (me + 1) / nt);
    long *where = malloc((size_t)n * sizeof *where);
    if (where) {
      for (int b = 0; b < n; b++) where[b] = -1;
      for (int a = 0; a < n; a++)
        row_blocks(m->pat, where, lo, hi, ptr[a + 1] - ptr[a], nb + ptr[a], dr + ptr[a],
                   dz + ptr[a], c[a], stride, zz, blk);
    }
#pragma omp critical(ves_defect_rows)
    if (!where) st = VES_ERR_ALLOC;
    free(where);
  }
done:
  free(cnt);
  return st;
}

/* The drift-damping matrix S (model.h, ves_model_params.drift):
 *   u^T S u = sum_a c_a |u^a - u(X_a)|^2,  c_a = drift mu 2 pi M_a / h_a^2,
 *   M_a = sum_alpha w_alpha R_alpha P_a(X_alpha)  (P_a: p_a plus its ghost's),
 * with u(X_a) = sum_b N_ab u^b from the tables at the nodes (a ghost entry
 * carries -u_r, +u_z). Per component i, S_i = sum_a c_a d_ia d_ia^T with
 * d_ia = e_a - N_i(a, .): r and z decouple, so only the rr and zz entries of
 * the blocks are set. The rows are cut to the quadrature's couplings and
 * refit, as the stabilization's (node_row): uncut, they would couple every
 * pair of a node's neighbours beyond the points' pattern (+0.07% blocks on
 * test_model's problem). M_a is node a's share of the r-weighted reference
 * measure (the lumped mass of the basis; > 0 on the axis too). Wall nodes
 * (fixed, no drift) have no term: their points at the nodes lie 1e-3 h_a
 * inside the hull, where an affine motion differs from its nodal value. */
ves_status model_drift_build(ves_model *m) {
  const ves_quad *qn = m->qn;
  const int n = m->nodes->n;
  const size_t cap = (size_t)qn->ptr[n] + n + 1;
  double *c = calloc((size_t)n, sizeof *c);
  int *ptr = malloc(((size_t)n + 1) * sizeof *ptr), *nb = malloc(cap * sizeof *nb);
  double *dr = malloc(cap * sizeof *dr), *dz = malloc(cap * sizeof *dz);
  m->dblk = calloc(4 * (size_t)m->pat->ptr[n] + 1, sizeof *m->dblk);
  ves_status s = VES_ERR_ALLOC;
  if (c && ptr && nb && dr && dz && m->dblk) {
    node_measure(m->q, n, c);   /* M_a, then c_a; wall nodes: no term (fixed, u = 0 */
    for (int a = 0; a < n; a++) /* there, and their points sit off the hull) */
      c[a] = m->par.drift * m->par.mu * 2 * M_PI * c[a] / (m->nodes->h[a] * m->nodes->h[a]);
    s = defect_rows(m, c, 4, 3, ptr, nb, dr, dz, m->dblk);
  }
  free(c), free(ptr), free(nb), free(dr), free(dz);
  return s;
}

/* The stabilization of E (model.h, ves_model_params.stab): the defect rows
 * of the nodes off the wall, cut to the quadrature's pattern (so E_s adds
 * no fill to the step matrix: the uncut rows grow the KKT factorization by
 * 21% at eps 0.01) and refit (refit_row), c_a = stab k 2 pi M_a / h_a^2, and the constant
 * Hessian sum_a c_a d_a d_a^T (per component) in the pattern. */
ves_status model_stab_build(ves_model *m) {
  const ves_quad *qn = m->qn;
  const int n = m->nodes->n;
  const size_t cap = (size_t)qn->ptr[n] + n + 1; /* a row: its list, and a itself */
  m->sptr = malloc(((size_t)n + 1) * sizeof *m->sptr);
  m->snb = malloc(cap * sizeof *m->snb);
  m->sdr = malloc(cap * sizeof *m->sdr);
  m->sdz = malloc(cap * sizeof *m->sdz);
  m->sc = calloc((size_t)n, sizeof *m->sc);
  m->sblk = calloc(2 * (size_t)m->pat->ptr[n] + 1, sizeof *m->sblk);
  if (!m->sptr || !m->snb || !m->sdr || !m->sdz || !m->sc || !m->sblk) return VES_ERR_ALLOC;
  node_measure(m->q, n, m->sc);
  for (int a = 0; a < n; a++) /* wall nodes: fixed, no term (as the drift damping) */
    m->sc[a] = m->nodes->flag[a] & VES_NODE_WALL ? 0
                                                 : m->par.stab * m->par.k * 2 * M_PI * m->sc[a] /
                                                       (m->nodes->h[a] * m->nodes->h[a]);
  return defect_rows(m, m->sc, 2, 1, m->sptr, m->snb, m->sdr, m->sdz, m->sblk);
}

/* E_s = (1/2) sum_a c_a |d_a|^2 and (g != NULL) g += grad E_s. */
long double model_stab_eval(const ves_model *m, const double *y, double *g, double gs) {
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
