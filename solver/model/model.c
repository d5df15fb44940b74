/* vesica — the discrete model: E, A, V, their gradients and Hessians, and the
 * dissipation matrix K, through ONE per-point assembly over the local
 * kinematic variables (docs/design.md, "Discretization"):
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
 * The model is four files on one private header (model_core_impl.h, the
 * object): this one, the API and the physics (create, the evaluation entry
 * points, the prefactors and parameters); model_assemble.c, the assembly
 * kernel; model_threads.c, the thread scheduling (Morton order, slabs);
 * model_drift.c, the drift damping and the stabilization. */
#include "model/model_core_impl.h"

#include <stdlib.h>
#include <string.h>
#include "core/mem_impl.h"
#include "core/omp_impl.h"

const ves_pattern *ves_model_pattern(const ves_model *m) { return m->pat; }

void ves_model_reference(const ves_model *m, double *y) {
  memcpy(y, m->yref, 2 * (size_t)m->nodes->n * sizeof *y);
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
    for (int k = 0; k < p->nthr; k++) model_ws_free(p->ws + k);
  free(p->ws);
  free(p->ev), free(p->qrec), free(p->yrec);
  ves_quad_destroy(&p->qn);
  free(p->dblk);
  free(p->sptr), free(p->snb), free(p->sdr), free(p->sdz), free(p->sc), free(p->sblk);
  free(p);
  *m = NULL;
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
  if (m->nthr > 64) /* zcut[] in model_make_slabs; beyond 2 cores untested anyway */
    m->nthr = 64;
  if (m->nthr < 1) m->nthr = 1;
  m->pt = ves_big_alloc((size_t)q->nq * sizeof *m->pt);
  m->fixed = malloc(2 * (size_t)n);
  m->yref = malloc(2 * (size_t)n * sizeof *m->yref);
  m->ws = calloc((size_t)m->nthr, sizeof *m->ws);
  m->ev = ves_big_alloc(4 * (size_t)q->nq * sizeof *m->ev);
  m->qrec = ves_big_alloc(VES_NQD * (size_t)q->nq * sizeof *m->qrec);
  m->yrec = malloc(2 * (size_t)n * sizeof *m->yrec);
  if (!m->pt || !m->fixed || !m->yref || !m->ws || !m->ev || !m->qrec || !m->yrec) goto fail;
  for (int k = 0; k < m->nthr; k++)
    if ((s = model_ws_alloc(m->ws + k, n, m->mmax, m->cap)) != VES_OK) goto fail;
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
  if ((s = model_make_slabs(m)) != VES_OK || (s = model_order_triangles(m)) != VES_OK) goto fail;
  for (int k = 0; k < m->nthr; k++)
    if ((s = model_ws_alloc_products(m->ws + k, m->numax)) != VES_OK) goto fail;
  if (par->drift > 0 || par->stab > 0) { /* the points at the nodes, same LME parameters */
    if ((s = ves_quad_create_at_nodes(nodes, &m->qn)) != VES_OK ||
        (s = ves_quad_tables(m->qn, nodes, &q->lme, NULL)) != VES_OK)
      goto fail;
  }
  /* the pattern of the points: the defect rows are cut to it (model_drift.c) */
  s = ves_pattern_create(q, NULL, n, m->fixed, &m->pat);
  if (s != VES_OK) goto fail;
  if (par->drift > 0 && (s = model_drift_build(m)) != VES_OK) goto fail;
  if (par->stab > 0 && (s = model_stab_build(m)) != VES_OK) goto fail;
  ves_quad_destroy(&m->qn); /* the rows are copied: the tables are done with */
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

ves_status ves_model_set_points(ves_model *m, const double *pd) {
  VES_CHECK(m && pd, VES_ERR_ARG);
  for (size_t i = 0; i < 6 * (size_t)m->q->nq; i++) VES_CHECK(isfinite(pd[i]), VES_ERR_ARG);
  for (int al = 0; al < m->q->nq; al++) {
    const double *f = pd + 6 * (size_t)al;
    m->pt[al].phi0 = f[0];
    m->pt[al].dphi0[0] = f[1], m->pt[al].dphi0[1] = f[2];
    m->pt[al].ddphi0[0] = f[3], m->pt[al].ddphi0[1] = f[4], m->pt[al].ddphi0[2] = f[5];
  }
  return VES_OK;
}

void ves_model_get_params(const ves_model *m, ves_model_params *par) { *par = m->par; }

const ves_nodes *ves_model_nodes(const ves_model *m) { return m->nodes; }

const ves_quad *ves_model_quad(const ves_model *m) { return m->q; }

/* F = 2 pi sum_alpha w_alpha c e(q_alpha), grad F = 2 pi sum w c B^T de/dq
 * for the selected F in {E, A, V} (model_eval_points). */
ves_status ves_model_eval(ves_model *m, const double *y, int which, double *E, double *A, double *V,
                          double *gE, double *gA, double *gV) {
  return model_eval_points(m, y, which, NULL, 1.0, E, A, V, NULL, gE, gA, gV);
}

ves_status ves_model_eval_step(ves_model *m, const double *y, int which, const double *qn,
                               const double *qa, double cE, double *E, double *A, double *V,
                               double *Dv, double *gF, double *gA, double *gV) {
  VES_CHECK(qn && (which & VES_F_E) && isfinite(cE), VES_ERR_ARG);
  const step_ref sr = {qn, 1.0, qa};
  return model_eval_points(m, y, which, &sr, cE, E, A, V, Dv, gF, gA, gV);
}

size_t ves_model_dissipation_ref_size(const ves_model *m) {
  return m ? VES_NQD * (size_t)m->q->nq : 0;
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
  if (m->qrec_ok && memcmp(y, m->yrec, 2 * (size_t)m->nodes->n * sizeof *y) == 0) {
    memcpy(qn, m->qrec, VES_NQD * (size_t)m->q->nq * sizeof *qn); /* the last pass's, bit for bit */
    return VES_OK;
  }
  return model_each_point(m, y, ref_point, qn);
}

/* blk += c M for a constant matrix of the defect rows (model_drift.c: S, or
 * Hess E_s), whose blocks have only rr and zz entries: block t's at src[stride
 * t] and src[stride t + stride - 1] (S keeps 4 values a block, the layout
 * ves_model_drift_blocks hands out; Hess E_s only the 2). */
static void add_rz(const ves_model *m, double c, const double *src, int stride, double *blk) {
  const size_t nb = (size_t)m->pat->ptr[m->nodes->n];
  for (size_t t = 0; t < nb; t++)
    blk[4 * t] += c * src[stride * t], blk[4 * t + 3] += c * src[stride * t + stride - 1];
}

/* sum_F c_F 2 pi sum_alpha w_alpha f_F B^T (d2e_F/dq2) B, plus cE Hess E_s. */
ves_status ves_model_hessian(ves_model *m, const double *y, double cE, double cA, double cV,
                             double *blk) {
  VES_CHECK(m && y && blk, VES_ERR_ARG);
  double fac[3];
  model_functional_factors(m, cE, cA, cV, fac);
  VES_CALL(model_assemble(m, ASM_HESS, fac, NULL, 0, y, blk));
  if (m->sblk && cE != 0) add_rz(m, cE, m->sblk, 2, blk); /* + cE Hess E_s */
  return VES_OK;
}

ves_status ves_model_hessian_step(ves_model *m, const double *y, const double *qn, double cE,
                                  double cA, double cV, double cK, int single, double *blk) {
  VES_CHECK(m && y && qn && blk && isfinite(cK), VES_ERR_ARG);
  double fac[3];
  model_functional_factors(m, cE, cA, cV, fac);
  const step_ref sr = {qn, cK, NULL};
  VES_CALL(model_assemble(m, ASM_HESS, fac, &sr, single, y, blk));
  if (m->sblk && cE != 0) add_rz(m, cE, m->sblk, 2, blk); /* + cE Hess E_s */
  if (m->dblk && cK != 0) add_rz(m, cK, m->dblk, 4, blk); /* + cK S: the drift damping */
  return VES_OK;
}

const double *ves_model_drift_blocks(const ves_model *m) { return m ? m->dblk : NULL; }

/* K = 2 pi sum_alpha w_alpha B_v^T D(q_alpha) B_v over the velocity
 * variables, plus the drift damping S. */
ves_status ves_model_dissipation(ves_model *m, const double *y, double *blk) {
  VES_CHECK(m && y && blk, VES_ERR_ARG);
  const double fac[3] = {0, 0, 0};
  VES_CALL(model_assemble(m, ASM_DISS, fac, NULL, 0, y, blk));
  if (m->dblk) add_rz(m, 1.0, m->dblk, 4, blk); /* K + S: the drift damping */
  return VES_OK;
}

/* ves_model_pointwise_W's point. */
static ves_status w_point(const ves_model *m, int al, const double q[VES_NQ], void *ctx) {
  double e;
  return ves_model_local_energy_ex(&m->lp, &m->pt[al], q, &e, NULL, NULL, (double *)ctx + al, NULL);
}

/* W = eps Lap phi + (phi0/eps + sqrt2 C0)(1 - phi0^2) at every point. */
ves_status ves_model_pointwise_W(ves_model *m, const double *y, double *W) {
  VES_CHECK(m && y && W, VES_ERR_ARG);
  return model_each_point(m, y, w_point, W);
}

ves_status ves_model_set_c0(ves_model *m, double c0) {
  VES_CHECK(m && isfinite(c0), VES_ERR_ARG);
  m->par.c0 = c0;
  m->lp.C0 = c0;
  return VES_OK;
}

double ves_model_get_c0(const ves_model *m) { return m->par.c0; }

double ves_model_get_k(const ves_model *m) { return m->par.k; }
