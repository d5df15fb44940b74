/* vesica — the model's constant matrices of the motion of the coefficients
 * relative to the material (model.c holds the API).
 *
 * Drift damping (not in the paper; ves_model_params.drift, off by default):
 * LME smooths, so coefficient patterns at the grid scale barely move the
 * material (~1% on a sphere) and K, which sees only the motion at the
 * points, hardly resists them; the discrete E has directions of negative
 * curvature among them (relabeling modes, bench/RESULTS.md), and the
 * coefficients drift from the material by up to 1e6 h over long runs. A
 * constant S (model_drift_build) added to K penalizes the rate of y^a - y(X_a):
 * zero on affine motions, O((h/L)^2) of K on smooth ones. Measured effect
 * in bench/RESULTS.md, "Drift damping".
 *
 * Coefficient-mode stabilization (ves_model_params.stab, off by default):
 * the same defect in E instead of K, E_s = (1/2) sum_a c_a |y^a - y(X_a)|^2
 * (model_stab_build, model_stab_eval), zero on affine maps (so at the reference), O(h^2)
 * on smooth motions, and of the size of the coefficients on the grid-scale
 * patterns along which the discrete E has negative curvature: it turns the
 * relaxed sphere from a saddle into a minimum (bench/RESULTS.md, issue 22). */
#include "model_core_impl.h"

#include <assert.h>
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
ves_status model_drift_build(ves_model *m) {
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
ves_status model_stab_build(ves_model *m) {
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
