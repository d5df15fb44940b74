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
 * The velocity variables of K use the first rows only. */
#include "ves/model.h"

#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "model_impl.h"

/* Which q entries an r-dof (resp. z-dof) feeds, and from which table row. */
typedef struct {
  int nr, nz;       /* entries fed by r and by z */
  int qr[6], rr[6]; /* q index and table row, r-dof */
  int qz[5], rz[5]; /* q index and table row, z-dof */
  int nl;           /* size of the local variable vector */
} local_map;

static const local_map MAP_Q = {6,
                                5,
                                {0, 1, 2, 5, 6, 7},
                                {0, 1, 2, 3, 4, 5},
                                {3, 4, 8, 9, 10},
                                {1, 2, 3, 4, 5},
                                VES_NQ};
static const local_map MAP_QD = {3,      2,      {0, 1, 2}, {0, 1, 2},
                                 {3, 4}, {1, 2}, VES_NQD};

struct ves_model {
  const ves_nodes *nodes; /* borrowed */
  const ves_quad *q;      /* borrowed */
  ves_model_params par;   /* copied */
  ves_model_local_par lp; /* parameters for the local densities */
  ves_model_point *pt;    /* nq point data (phi0 and derivatives) */
  unsigned char *fixed;   /* 2n fixed-dof flags */
  ves_pattern *pat;       /* block pattern */
  double *yref;           /* 2n reference positions */
  /* workspace (sized for the largest point) */
  int mmax;
  int *un;         /* unique real nodes of a point */
  double *Tr, *Tz; /* folded tables, 6 x mu each */
  int *slot;       /* n: slot of a node in un (valid when stamp matches) */
  int *stamp;      /* n */
  double *Av;      /* per-node products with the local Hessian, 22 mu */
};

const ves_pattern *ves_model_pattern(const ves_model *m) { return m->pat; }

void ves_model_reference(const ves_model *m, double *y) {
  memcpy(y, m->yref, 2 * (size_t)m->nodes->n * sizeof *y);
}

void ves_model_destroy(ves_model **m) {
  if (!m || !*m)
    return;
  ves_model *p = *m;
  free(p->pt);
  free(p->fixed);
  ves_pattern_destroy(&p->pat);
  free(p->yref);
  free(p->un);
  free(p->Tr);
  free(p->Tz);
  free(p->slot);
  free(p->stamp);
  free(p->Av);
  free(p);
  *m = NULL;
}

ves_status ves_model_create(const ves_nodes *nodes, const ves_quad *q,
                            const double *phi0c, const ves_model_params *par,
                            ves_model **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL; /* on every error path */
  VES_CHECK(nodes && q && q->tab && phi0c && par, VES_ERR_ARG);
  VES_CHECK(par->eps > 0 && par->k > 0 && par->mu >= 0, VES_ERR_ARG);
  int n = nodes->n;
  ves_status s = VES_ERR_ALLOC;
  ves_model *m = calloc(1, sizeof *m);
  double *fld = NULL;
  if (!m)
    return VES_ERR_ALLOC;
  m->nodes = nodes, m->q = q, m->par = *par;
  m->lp.eps = par->eps, m->lp.C0 = par->c0, m->lp.mu = par->mu,
  m->lp.lambda = par->lambda;
  m->mmax = 0;
  for (int al = 0; al < q->nq; al++)
    if (q->ptr[al + 1] - q->ptr[al] > m->mmax)
      m->mmax = q->ptr[al + 1] - q->ptr[al];
  m->pt = malloc((size_t)q->nq * sizeof *m->pt);
  m->fixed = malloc(2 * (size_t)n);
  m->yref = malloc(2 * (size_t)n * sizeof *m->yref);
  m->un = malloc((size_t)m->mmax * sizeof *m->un);
  m->Tr = malloc(6 * (size_t)m->mmax * sizeof *m->Tr);
  m->Tz = malloc(6 * (size_t)m->mmax * sizeof *m->Tz);
  m->slot = malloc((size_t)n * sizeof *m->slot);
  m->stamp = malloc((size_t)n * sizeof *m->stamp);
  m->Av = malloc(22 * (size_t)m->mmax * sizeof *m->Av);
  fld = malloc(6 * (size_t)q->nq * sizeof *fld);
  if (!m->pt || !m->fixed || !m->yref || !m->un || !m->Tr || !m->Tz ||
      !m->slot || !m->stamp || !m->Av || !fld)
    goto fail;
  for (int a = 0; a < n; a++) {
    m->stamp[a] = -1;
    m->fixed[2 * a] =
        (nodes->flag[a] & (VES_NODE_WALL | VES_NODE_AXIS)) != 0; /* r */
    m->fixed[2 * a + 1] = (nodes->flag[a] & VES_NODE_WALL) != 0; /* z */
  }
  memcpy(m->yref, nodes->x, 2 * (size_t)n * sizeof *m->yref);
  ves_quad_field(q, phi0c, 2, fld);
  for (int al = 0; al < q->nq; al++) {
    const double *f = fld + 6 * (size_t)al;
    m->pt[al].phi0 = f[0];
    m->pt[al].dphi0[0] = f[1], m->pt[al].dphi0[1] = f[2];
    m->pt[al].ddphi0[0] = f[3], m->pt[al].ddphi0[1] = f[4],
    m->pt[al].ddphi0[2] = f[5];
  }
  s = ves_pattern_create(q, n, m->fixed, &m->pat);
  if (s != VES_OK)
    goto fail;
  free(fld);
  *out = m;
  return VES_OK;
fail:
  free(fld);
  ves_model_destroy(&m);
  return s;
}

/* Fold point al's table onto its unique real nodes: *Tr (6 x mu, ghost
 * columns added with sign -1) and *Tz (ghost columns added with +1), node
 * list *un, ascending. Points that see no ghost and list their nodes in
 * ascending order (the tables do) use the table in place. Returns mu. */
static int fold_point(ves_model *m, int al, const double **Tr,
                      const double **Tz, const int **un) {
  const ves_quad *q = m->q;
  int m0 = q->ptr[al + 1] - q->ptr[al];
  const int *nb = q->nbr + q->ptr[al];
  const unsigned char *mir = q->mirror + q->ptr[al];
  const double *t = q->tab + 6 * (size_t)q->ptr[al];
  int ghosts = 0, sorted = 1;
  for (int k = 0; k < m0; k++)
    ghosts |= mir[k];
  for (int k = 1; k < m0; k++)
    sorted &= nb[k] > nb[k - 1];
  if (!ghosts && sorted) {
    *Tr = *Tz = t, *un = nb;
    return m0;
  }
  /* first pass: unique nodes, sorted ascending (scatter_hess relies on it) */
  int mu = 0;
  for (int k = 0; k < m0; k++) {
    int a = nb[k];
    if (m->stamp[a] != al)
      m->stamp[a] = al, m->un[mu++] = a;
  }
  for (int i = 1; i < mu; i++) { /* insertion sort: mu ~ 70 */
    int v = m->un[i], j = i - 1;
    while (j >= 0 && m->un[j] > v)
      m->un[j + 1] = m->un[j], j--;
    m->un[j + 1] = v;
  }
  for (int u = 0; u < mu; u++)
    m->slot[m->un[u]] = u;
  for (int j = 0; j < 6; j++)
    for (int u = 0; u < mu; u++)
      m->Tr[j * mu + u] = m->Tz[j * mu + u] = 0.0;
  for (int k = 0; k < m0; k++) {
    int u = m->slot[nb[k]];
    double sg = mir[k] ? -1.0 : 1.0;
    for (int j = 0; j < 6; j++) {
      m->Tr[j * mu + u] += sg * t[j * m0 + k];
      m->Tz[j * mu + u] += t[j * m0 + k];
    }
  }
  /* release the stamps: they must not survive into the next call, where the
   * same point index would find them set and skip its nodes */
  for (int u = 0; u < mu; u++)
    m->stamp[m->un[u]] = -1;
  *Tr = m->Tr, *Tz = m->Tz, *un = m->un;
  return mu;
}

/* q = B y at the point (the 11 local kinematic variables). */
static void kinematics(int mu, const double *Tr, const double *Tz,
                       const int *un, const double *y, double q[VES_NQ]) {
  for (int i = 0; i < VES_NQ; i++)
    q[i] = 0.0;
  for (int j = 0; j < 6; j++) {
    double s = 0.0;
    for (int u = 0; u < mu; u++)
      s += Tr[j * mu + u] * y[2 * un[u]];
    q[MAP_Q.qr[j]] = s;
  }
  for (int j = 0; j < 5; j++) {
    const double *row = Tz + MAP_Q.rz[j] * mu;
    double s = 0.0;
    for (int u = 0; u < mu; u++)
      s += row[u] * y[2 * un[u] + 1];
    q[MAP_Q.qz[j]] = s;
  }
}

/* g += c B^T ge (ge over the local variables of map mp). */
static void scatter_grad(const local_map *mp, int mu, const double *Tr,
                         const double *Tz, const int *un, double c,
                         const double *ge, double *g) {
  for (int u = 0; u < mu; u++) {
    double sr = 0.0, sz = 0.0;
    for (int j = 0; j < mp->nr; j++)
      sr += ge[mp->qr[j]] * Tr[mp->rr[j] * mu + u];
    for (int j = 0; j < mp->nz; j++)
      sz += ge[mp->qz[j]] * Tz[mp->rz[j] * mu + u];
    g[2 * un[u]] += c * sr;
    g[2 * un[u] + 1] += c * sz;
  }
}

/* blk += c B^T H B on the lower block pattern (H over the local variables of
 * map mp, row-major nl x nl). For each column node v: A_v = H_rr b_r(v),
 * B_v = H_rz b_z(v), C_v = H_zr b_r(v), D_v = H_zz b_z(v); then block
 * (u, v) = [b_r(u).A_v, b_r(u).B_v; b_z(u).C_v, b_z(u).D_v]. */
static void scatter_hess(ves_model *m, const local_map *mp, int mu,
                         const double *Tr, const double *Tz, const int *un,
                         double c, const double *H, double *blk) {
  const ves_pattern *pat = m->pat;
  int nr = mp->nr, nz = mp->nz, nl = mp->nl, stride = 2 * (nr + nz);
  for (int v = 0; v < mu; v++) {
    double br[6], bz[5], *o = m->Av + (size_t)stride * v;
    for (int j = 0; j < nr; j++)
      br[j] = Tr[mp->rr[j] * mu + v];
    for (int j = 0; j < nz; j++)
      bz[j] = Tz[mp->rz[j] * mu + v];
    for (int i = 0; i < nr; i++) { /* A_v and B_v */
      double sa = 0.0, sb = 0.0;
      for (int j = 0; j < nr; j++)
        sa += H[mp->qr[i] * nl + mp->qr[j]] * br[j];
      for (int j = 0; j < nz; j++)
        sb += H[mp->qr[i] * nl + mp->qz[j]] * bz[j];
      o[i] = c * sa, o[nr + i] = c * sb;
    }
    for (int i = 0; i < nz; i++) { /* C_v and D_v */
      double sc = 0.0, sd = 0.0;
      for (int j = 0; j < nr; j++)
        sc += H[mp->qz[i] * nl + mp->qr[j]] * br[j];
      for (int j = 0; j < nz; j++)
        sd += H[mp->qz[i] * nl + mp->qz[j]] * bz[j];
      o[2 * nr + i] = c * sc, o[2 * nr + nz + i] = c * sd;
    }
  }
  /* un is ascending, so the lower blocks of row u are v = 0..u, and their
   * positions are found by one forward walk along the (ascending) pattern
   * row of a: every (a, b) pair of the point is in the pattern */
  for (int u = 0; u < mu; u++) {
    int a = un[u], t = pat->ptr[a];
    double br[6], bz[5];
    for (int j = 0; j < nr; j++)
      br[j] = Tr[mp->rr[j] * mu + u];
    for (int j = 0; j < nz; j++)
      bz[j] = Tz[mp->rz[j] * mu + u];
    for (int v = 0; v <= u; v++) {
      int b = un[v];
      while (pat->col[t] < b)
        t++; /* position of block (a, b) */
      assert(t < pat->ptr[a + 1] && pat->col[t] == b);
      const double *o = m->Av + (size_t)stride * v;
      double h00 = 0, h01 = 0, h10 = 0, h11 = 0;
      for (int j = 0; j < nr; j++)
        h00 += br[j] * o[j], h01 += br[j] * o[nr + j];
      for (int j = 0; j < nz; j++)
        h10 += bz[j] * o[2 * nr + j], h11 += bz[j] * o[2 * nr + nz + j];
      double *dst = blk + 4 * (size_t)t;
      dst[0] += h00, dst[1] += h01, dst[2] += h10, dst[3] += h11;
    }
  }
}

ves_status ves_model_eval(ves_model *m, const double *y, int which, double *E,
                          double *A, double *V, double *gE, double *gA,
                          double *gV) {
  VES_CHECK(m && y, VES_ERR_ARG);
  int n = m->nodes->n;
  const double fE = 2 * M_PI * 3 * m->par.k / (16 * M_SQRT2 * m->par.eps),
               fA = 2 * M_PI * 3 / (2 * M_SQRT2), fV = 2 * M_PI;
  /* The totals are accumulated in extended precision: the sums run over
   * ~1e4..1e6 points, and the optimizers (line searches, finite-difference
   * checks) compare values that differ by far less than the double rounding
   * of such a sum (~1e-16 sqrt(nq) relative); each point's contribution
   * stays in double. */
  long double sE = 0, sA = 0, sV = 0;
  if ((which & VES_F_E) && gE)
    memset(gE, 0, 2 * (size_t)n * sizeof *gE);
  if ((which & VES_F_A) && gA)
    memset(gA, 0, 2 * (size_t)n * sizeof *gA);
  if ((which & VES_F_V) && gV)
    memset(gV, 0, 2 * (size_t)n * sizeof *gV);
  for (int al = 0; al < m->q->nq; al++) {
    const double *Tr, *Tz;
    const int *un;
    int mu = fold_point(m, al, &Tr, &Tz, &un);
    double q[VES_NQ], e, ge[VES_NQ], w = m->q->w[al];
    kinematics(mu, Tr, Tz, un, y, q);
    if (which & VES_F_E) {
      VES_CALL(ves_model_local_energy(&m->lp, &m->pt[al], q, &e, gE ? ge : NULL,
                                      NULL));
      sE += w * e;
      if (gE)
        scatter_grad(&MAP_Q, mu, Tr, Tz, un, fE * w, ge, gE);
    }
    if (which & VES_F_A) {
      VES_CALL(ves_model_local_area(&m->lp, &m->pt[al], q, &e, gA ? ge : NULL,
                                    NULL));
      sA += w * e;
      if (gA)
        scatter_grad(&MAP_Q, mu, Tr, Tz, un, fA * w, ge, gA);
    }
    if (which & VES_F_V) {
      VES_CALL(ves_model_local_volume(&m->lp, &m->pt[al], q, &e, gV ? ge : NULL,
                                      NULL));
      sV += w * e;
      if (gV)
        scatter_grad(&MAP_Q, mu, Tr, Tz, un, fV * w, ge, gV);
    }
  }
  if ((which & VES_F_E) && E)
    *E = (double)(fE * sE);
  if ((which & VES_F_A) && A)
    *A = (double)(fA * sA);
  if ((which & VES_F_V) && V)
    *V = (double)(fV * sV);
  return VES_OK;
}

ves_status ves_model_hessian(ves_model *m, const double *y, double cE,
                             double cA, double cV, double *blk) {
  VES_CHECK(m && y && blk, VES_ERR_ARG);
  const ves_pattern *pat = m->pat;
  const double fE = 2 * M_PI * 3 * m->par.k / (16 * M_SQRT2 * m->par.eps) * cE,
               fA = 2 * M_PI * 3 / (2 * M_SQRT2) * cA, fV = 2 * M_PI * cV;
  memset(blk, 0, 4 * (size_t)pat->ptr[pat->n] * sizeof *blk);
  for (int al = 0; al < m->q->nq; al++) {
    const double *Tr, *Tz;
    const int *un;
    int mu = fold_point(m, al, &Tr, &Tz, &un);
    double q[VES_NQ], e, H[VES_NQ * VES_NQ], Hs[VES_NQ * VES_NQ] = {0};
    kinematics(mu, Tr, Tz, un, y, q);
    if (fE != 0) {
      VES_CALL(ves_model_local_energy(&m->lp, &m->pt[al], q, &e, NULL, H));
      for (int i = 0; i < VES_NQ * VES_NQ; i++)
        Hs[i] += fE * H[i];
    }
    if (fA != 0) {
      VES_CALL(ves_model_local_area(&m->lp, &m->pt[al], q, &e, NULL, H));
      for (int i = 0; i < VES_NQ * VES_NQ; i++)
        Hs[i] += fA * H[i];
    }
    if (fV != 0) {
      VES_CALL(ves_model_local_volume(&m->lp, &m->pt[al], q, &e, NULL, H));
      for (int i = 0; i < VES_NQ * VES_NQ; i++)
        Hs[i] += fV * H[i];
    }
    scatter_hess(m, &MAP_Q, mu, Tr, Tz, un, m->q->w[al], Hs, blk);
  }
  return VES_OK;
}

ves_status ves_model_dissipation(ves_model *m, const double *y, double *blk) {
  VES_CHECK(m && y && blk, VES_ERR_ARG);
  const ves_pattern *pat = m->pat;
  memset(blk, 0, 4 * (size_t)pat->ptr[pat->n] * sizeof *blk);
  for (int al = 0; al < m->q->nq; al++) {
    const double *Tr, *Tz;
    const int *un;
    int mu = fold_point(m, al, &Tr, &Tz, &un);
    double q[VES_NQ], D[VES_NQD * VES_NQD];
    kinematics(mu, Tr, Tz, un, y, q);
    VES_CALL(ves_model_local_dissip(&m->lp, q, D));
    scatter_hess(m, &MAP_QD, mu, Tr, Tz, un, 2 * M_PI * m->q->w[al], D, blk);
  }
  return VES_OK;
}

ves_status ves_model_pointwise_W(ves_model *m, const double *y, double *W) {
  VES_CHECK(m && y && W, VES_ERR_ARG);
  for (int al = 0; al < m->q->nq; al++) {
    const double *Tr, *Tz;
    const int *un;
    int mu = fold_point(m, al, &Tr, &Tz, &un);
    double q[VES_NQ], e;
    kinematics(mu, Tr, Tz, un, y, q);
    VES_CALL(ves_model_local_energy_ex(&m->lp, &m->pt[al], q, &e, NULL, NULL,
                                       W + al, NULL));
  }
  return VES_OK;
}
