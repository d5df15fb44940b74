/* vesica — reset of the reference configuration (reconnect.h; paper Sec.
 * 3.3, Fig. 2). E, A, V are preserved term by term: each is
 * 2 pi sum_alpha w_alpha f(phi data, F, G, r) det F r, f depends on (F, G)
 * only through the spatial derivatives of phi = phi0 o y^-1 (Eqs. 2-4), and
 * after the reset y' = identity (F' = I, G' = 0, r' = r) with w' = w det F
 * and the pushed-forward data those spatial derivatives; the residual is the
 * LME reproduction error (~1e-14 h) plus rounding (tests/test_reconnect.c).
 * The assembly unit (the points of one initial triangle) is kept: they stay
 * neighbours under a continuous motion; the model's slab partition and
 * Morton order are recomputed at create (docs/design.md, "The time loop"). */
#include "ves/reconnect.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/clock_impl.h"

struct ves_reconnect {
  ves_nodes *nodes;        /* the new reference nodes (owned) */
  ves_quad *quad;          /* moved points, new weights and tables (owned) */
  ves_model *model;        /* the model on them (owned; borrows nodes, quad) */
  ves_reconnect_info info; /* statistics of the reset */
};

void ves_reconnect_destroy(ves_reconnect **r) {
  if (!r || !*r) return;
  ves_model_destroy(&(*r)->model); /* first: it borrows the other two */
  ves_quad_destroy(&(*r)->quad);
  ves_nodes_destroy(&(*r)->nodes);
  free(*r);
  *r = NULL;
}

ves_model *ves_reconnect_model(ves_reconnect *r) { return r->model; }

const ves_model *ves_reconnect_model_const(const ves_reconnect *r) { return r->model; }
const ves_nodes *ves_reconnect_nodes(const ves_reconnect *r) { return r->nodes; }
const ves_quad *ves_reconnect_quad(const ves_reconnect *r) { return r->quad; }
void ves_reconnect_get_info(const ves_reconnect *r, ves_reconnect_info *info) { *info = r->info; }

/* cond_2 of F = [a b; c d] with det > 0: with P = |(a + d, b - c)| =
 * sigma_1 + sigma_2 and Q = |(a - d, b + c)| = sigma_1 - sigma_2,
 * P^2 - Q^2 = 4 det, so sigma_1 / sigma_2 = (P + Q) / (P - Q) = (P + Q)^2 / (4 det)
 * (no cancellation). +inf when det <= 0. */
static double cond2(const double F[4], double det) {
  if (!(det > 0)) return INFINITY;
  double P = hypot(F[0] + F[3], F[1] - F[2]), Q = hypot(F[0] - F[3], F[1] + F[2]);
  return (P + Q) * (P + Q) / (4.0 * det);
}

/* F at point al: (F_rR, F_rZ, F_zR, F_zZ) from the rows of ves_quad_motion. */
static void point_F(const ves_quad *q, const double *y, int al, double F[4]) {
  double mo[12];
  ves_quad_motion(q, y, al, 1, mo);
  F[0] = mo[1], F[1] = mo[2], F[2] = mo[7], F[3] = mo[8];
}

static int finite_vec(size_t n, const double *v) {
  for (size_t i = 0; i < n; i++)
    if (!isfinite(v[i])) return 0;
  return 1;
}

ves_status ves_reconnect_distortion_points(const ves_model *m, const double *y, double *cond,
                                           double *det) {
  VES_CHECK(m && y, VES_ERR_ARG);
  const ves_quad *q = ves_model_quad(m);
  VES_CHECK(finite_vec(2 * (size_t)ves_model_nodes(m)->n, y), VES_ERR_ARG);
#pragma omp parallel for schedule(static)
  for (int al = 0; al < q->nq; al++) {
    double F[4];
    point_F(q, y, al, F);
    const double J = F[0] * F[3] - F[1] * F[2];
    if (cond) cond[al] = cond2(F, J);
    if (det) det[al] = J;
  }
  return VES_OK;
}

ves_status ves_reconnect_distortion(const ves_model *m, const double *y, double *cond_max,
                                    double *det_min) {
  VES_CHECK(m && y, VES_ERR_ARG);
  const ves_quad *q = ves_model_quad(m);
  VES_CHECK(finite_vec(2 * (size_t)ves_model_nodes(m)->n, y), VES_ERR_ARG);
  double cmax = 1.0, dmin = INFINITY; /* max and min are exact: any thread count, same result */
#pragma omp parallel for schedule(static) reduction(max : cmax) reduction(min : dmin)
  for (int al = 0; al < q->nq; al++) {
    double F[4];
    point_F(q, y, al, F);
    const double J = F[0] * F[3] - F[1] * F[2];
    cmax = fmax(cmax, cond2(F, J));
    dmin = fmin(dmin, J);
  }
  if (cond_max) *cond_max = cmax;
  if (det_min) *det_min = dmin;
  return VES_OK;
}

/* phi0(X) = phi(y(X)) differentiated once and twice:
 *   phi0_I = phi_i F_iI                      => g = grad phi0 F^-1   (Eq. 2)
 *   phi0_IJ = phi_ij F_iI F_jJ + phi_n G_nIJ => phi_ij = H_Ii (phi0_IJ - g_n G_nIJ) H_Jj
 * with H = F^-1 (Eq. 3 with d_j F^-1_Ii = -F^-1_In F^-1_Ji F^-1_Kj G_nJK). */
ves_status ves_reconnect_push_forward(const double F[4], const double G[6], const double pd[6],
                                      double out[6]) {
  const double J = F[0] * F[3] - F[1] * F[2];
  if (!(J > 0)) return VES_ERR_DOMAIN;
  const double H[2][2] = {{F[3] / J, -F[1] / J}, {-F[2] / J, F[0] / J}}; /* H[I][i] = F^-1_Ii */
  const double g[2] = {pd[1] * H[0][0] + pd[2] * H[1][0],                /* g_r = phi0_I H_Ir */
                       pd[1] * H[0][1] + pd[2] * H[1][1]};               /* g_z = phi0_I H_Iz */
  const double T[3] = {pd[3] - g[0] * G[0] - g[1] * G[3], /* T = Hess phi0 - g_n G_n */
                       pd[4] - g[0] * G[1] - g[1] * G[4], pd[5] - g[0] * G[2] - g[1] * G[5]};
  const double Tm[2][2] = {{T[0], T[1]}, {T[1], T[2]}};
  double S[2][2]; /* S_ij = H_Ii T_IJ H_Jj */
  for (int i = 0; i < 2; i++)
    for (int j = 0; j < 2; j++) {
      double s = 0.0;
      for (int I = 0; I < 2; I++)
        for (int K = 0; K < 2; K++) s += H[I][i] * Tm[I][K] * H[K][j];
      S[i][j] = s;
    }
  out[0] = pd[0], out[1] = g[0], out[2] = g[1];
  out[3] = S[0][0], out[4] = 0.5 * (S[0][1] + S[1][0]), out[5] = S[1][1];
  return VES_OK;
}

void ves_reconnect_motion_at_nodes(const ves_nodes *nodes, const ves_quad *pq, const double *y,
                                   double *xm, double *shift_max) {
  double smax = 0.0;
  for (int a = 0; a < nodes->n; a++) {
    double mo[12];
    ves_quad_motion(pq, y, a, 0, mo);
    if (nodes->flag[a] & VES_NODE_AXIS) mo[0] = 0.0;
    if (nodes->flag[a] & VES_NODE_WALL) mo[0] = y[2 * a], mo[6] = y[2 * a + 1];
    smax = fmax(smax, hypot(mo[0] - y[2 * a], mo[6] - y[2 * a + 1]) / nodes->h[a]);
    xm[2 * a] = mo[0], xm[2 * a + 1] = mo[6];
  }
  if (shift_max) *shift_max = smax;
}

/* The motion at the real nodes, y(X_a) (into xm[2n]), and max_a |y^a -
 * y(X_a)| / h_a, on a point set at the nodes with its own tables on the old
 * basis (the cost of ~n/nq of a table build). */
static ves_status node_motion(const ves_nodes *nodes, const double *y, const ves_lme_params *lme,
                              double *xm, double *shift_max) {
  ves_quad *pq = NULL;
  ves_status s = ves_quad_create_at_nodes(nodes, &pq);
  if (s == VES_OK) s = ves_quad_tables(pq, nodes, lme, NULL);
  if (s == VES_OK) ves_reconnect_motion_at_nodes(nodes, pq, y, xm, shift_max);
  ves_quad_destroy(&pq);
  return s;
}

/* The new node set: X'_a = y[a] (y^a or y(X_a)), flags and box copied, a ghost (-r_a, z_a)
 * for every non-axis node (a node with r_a < 0 is mirrored: X'_a = (|r_a|,
 * z_a), the same point set; see the header), h'_a measured on real and ghost
 * nodes together (as ves_nodes_generate does). The struct is allocated with
 * malloc like geom.cpp's, so ves_nodes_destroy frees it. */
static ves_status new_nodes(const ves_nodes *old, const double *y, const double *h, ves_nodes **out,
                            int *mirrored) {
  const int n = old->n;
  ves_status s = VES_ERR_ALLOC;
  double *xe = NULL, *he = NULL;
  ves_nodes *nd = calloc(1, sizeof *nd);
  if (!nd) return VES_ERR_ALLOC;
  nd->LR = old->LR, nd->LZ = old->LZ, nd->n = n;
  nd->x = malloc(2 * (size_t)n * sizeof *nd->x);
  nd->h = malloc((size_t)n * sizeof *nd->h);
  nd->flag = malloc((size_t)n * sizeof *nd->flag);
  nd->ghost_of = malloc((size_t)n * sizeof *nd->ghost_of);
  xe = malloc(4 * (size_t)n * sizeof *xe);
  he = malloc(2 * (size_t)n * sizeof *he);
  if (!nd->x || !nd->h || !nd->flag || !nd->ghost_of || !xe || !he) goto fail;
  memcpy(nd->x, y, 2 * (size_t)n * sizeof *nd->x);
  memcpy(nd->flag, old->flag, (size_t)n * sizeof *nd->flag);
  for (int a = 0; a < n; a++) {
    const double r = y[2 * a];
    if ((old->flag[a] & VES_NODE_AXIS) && r != 0.0) {
      s = VES_ERR_ARG; /* an axis node must keep r = 0 (its r is a fixed dof) */
      goto fail;
    }
    if (!(old->flag[a] & VES_NODE_AXIS) && !(r != 0.0)) {
      s = VES_ERR_DOMAIN; /* a node on its own ghost */
      goto fail;
    }
    if (r < 0.0) nd->x[2 * a] = -r, ++*mirrored;
    if (r != 0.0) nd->ghost_of[nd->ng++] = a;
  }
  memcpy(xe, nd->x, 2 * (size_t)n * sizeof *xe);
  for (int k = 0; k < nd->ng; k++) {
    const int a = nd->ghost_of[k];
    xe[2 * (n + k)] = -nd->x[2 * a], xe[2 * (n + k) + 1] = nd->x[2 * a + 1];
  }
  if (h) { /* given (a restored reference): no measurement */
    memcpy(nd->h, h, (size_t)n * sizeof *nd->h);
  } else {
    if ((s = ves_geom_spacing(n + nd->ng, xe, he)) != VES_OK) goto fail;
    memcpy(nd->h, he, (size_t)n * sizeof *nd->h);
  }
  free(xe), free(he);
  *out = nd;
  return VES_OK;
fail:
  free(xe), free(he);
  ves_nodes_destroy(&nd);
  return s;
}

ves_status ves_reconnect_create(const ves_model *m, const double *y, ves_reset_nodes where,
                                ves_reconnect **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL;
  VES_CHECK(m && y, VES_ERR_ARG);
  VES_CHECK(where == VES_RESET_NODES_COEF || where == VES_RESET_NODES_MOTION, VES_ERR_ARG);
  const double t0 = ves_wall_seconds();
  const ves_nodes *nodes = ves_model_nodes(m);
  const ves_quad *q = ves_model_quad(m);
  VES_CHECK(q->tab, VES_ERR_ARG); /* the LME parameters are those of m's tables */
  const ves_lme_params *lme = &q->lme;
  const int n = nodes->n, nq = q->nq;
  VES_CHECK(finite_vec(2 * (size_t)n, y), VES_ERR_ARG);
  ves_status s = VES_ERR_ALLOC;
  double *pd = malloc(6 * (size_t)nq * sizeof *pd), *xq = malloc(2 * (size_t)nq * sizeof *xq);
  double *wq = malloc((size_t)nq * sizeof *wq), *xn = malloc(2 * (size_t)n * sizeof *xn);
  ves_reconnect *r = calloc(1, sizeof *r);
  if (!pd || !xq || !wq || !xn || !r) goto fail;
  r->info.cond_max = 1.0, r->info.det_min = INFINITY;

  /* the moved points, their weights and pushed-forward data (Eqs. 2-3) */
  ves_model_point_data(m, pd);
  for (int al = 0; al < nq; al++) {
    double mo[12], F[4], G[6], pf[6];
    ves_quad_motion(q, y, al, 2, mo);
    F[0] = mo[1], F[1] = mo[2], F[2] = mo[7], F[3] = mo[8];
    G[0] = mo[3], G[1] = mo[4], G[2] = mo[5], G[3] = mo[9], G[4] = mo[10], G[5] = mo[11];
    const double J = F[0] * F[3] - F[1] * F[2];
    s = VES_ERR_DOMAIN;
    if (!(J > 0.0) || !(mo[0] > 0.0)) goto fail;
    r->info.cond_max = fmax(r->info.cond_max, cond2(F, J));
    r->info.det_min = fmin(r->info.det_min, J);
    if ((s = ves_reconnect_push_forward(F, G, pd + 6 * (size_t)al, pf)) != VES_OK) goto fail;
    memcpy(pd + 6 * (size_t)al, pf, sizeof pf);
    xq[2 * al] = mo[0], xq[2 * al + 1] = mo[6]; /* Xh' = y(Xh) */
    wq[al] = q->w[al] * J;                      /* w' = w det F */
  }

  /* the motion at the nodes: the new nodes, or only the measured shift */
  if ((s = node_motion(nodes, y, lme, xn, &r->info.shift_max)) != VES_OK) goto fail;
  if (where == VES_RESET_NODES_COEF) memcpy(xn, y, 2 * (size_t)n * sizeof *xn);
  if ((s = new_nodes(nodes, xn, NULL, &r->nodes, &r->info.mirrored)) != VES_OK) goto fail;
  if ((s = ves_quad_create_points(nq, xq, wq, q->ntri, q->tri, &r->quad)) != VES_OK) goto fail;
  r->quad->sub = q->sub, r->quad->rule = q->rule; /* the same triangles and groups */
  if ((s = ves_quad_tables(r->quad, r->nodes, lme, &r->info.qinfo)) != VES_OK) goto fail;
  ves_model_params par;
  ves_model_get_params(m, &par);
  if ((s = ves_model_create_points(r->nodes, r->quad, pd, &par, &r->model)) != VES_OK) goto fail;
  r->info.h_min = INFINITY, r->info.h_max = 0.0;
  for (int a = 0; a < n; a++)
    r->info.h_min = fmin(r->info.h_min, r->nodes->h[a]),
    r->info.h_max = fmax(r->info.h_max, r->nodes->h[a]);
  r->info.seconds = ves_wall_seconds() - t0;
  free(pd), free(xq), free(wq), free(xn);
  *out = r;
  return VES_OK;
fail:
  free(pd), free(xq), free(wq), free(xn);
  ves_reconnect_destroy(&r);
  return s;
}

ves_status ves_reconnect_carry(const ves_model *m, const double *y, ves_reset_nodes where,
                               const double *z, double *zn) {
  VES_CHECK(m && y && z && zn, VES_ERR_ARG);
  VES_CHECK(where == VES_RESET_NODES_COEF || where == VES_RESET_NODES_MOTION, VES_ERR_ARG);
  const ves_nodes *nodes = ves_model_nodes(m);
  const int n = nodes->n;
  VES_CHECK(finite_vec(2 * (size_t)n, y) && finite_vec(2 * (size_t)n, z), VES_ERR_ARG);
  if (where == VES_RESET_NODES_COEF) {
    for (int a = 0; a < n; a++) /* a node mirrored by the reset (y^a_r < 0): z's r too */
      zn[2 * a] = y[2 * a] < 0.0 ? -z[2 * a] : z[2 * a], zn[2 * a + 1] = z[2 * a + 1];
    return VES_OK;
  }
  ves_quad *pq = NULL;
  double *ym = malloc(2 * (size_t)n * sizeof *ym);
  ves_status s = ym ? ves_quad_create_at_nodes(nodes, &pq) : VES_ERR_ALLOC;
  if (s == VES_OK) s = ves_quad_tables(pq, nodes, &ves_model_quad(m)->lme, NULL);
  if (s == VES_OK) {
    ves_reconnect_motion_at_nodes(nodes, pq, y, ym, NULL);
    ves_reconnect_motion_at_nodes(nodes, pq, z, zn, NULL);
    for (int a = 0; a < n; a++)
      if (ym[2 * a] < 0.0) zn[2 * a] = -zn[2 * a]; /* mirrored by the reset */
  }
  ves_quad_destroy(&pq);
  free(ym);
  return s;
}

ves_status ves_reconnect_restore(const ves_model *m, const double *x, const double *h, int nq,
                                 const double *xq, const double *wq, const double *pd,
                                 ves_reconnect **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL;
  VES_CHECK(m && x && h && xq && wq && pd, VES_ERR_ARG);
  const double t0 = ves_wall_seconds();
  const ves_nodes *nodes = ves_model_nodes(m);
  const ves_quad *q = ves_model_quad(m);
  VES_CHECK(q->tab, VES_ERR_ARG); /* the LME parameters are those of m's tables */
  const ves_lme_params *lme = &q->lme;
  const int n = nodes->n;
  VES_CHECK(nq == q->nq, VES_ERR_ARG);
  VES_CHECK(finite_vec(2 * (size_t)n, x) && finite_vec((size_t)n, h), VES_ERR_ARG);
  for (int a = 0; a < n; a++) VES_CHECK(h[a] > 0 && x[2 * a] >= 0, VES_ERR_ARG);
  ves_reconnect *r = calloc(1, sizeof *r);
  if (!r) return VES_ERR_ALLOC;
  r->info.cond_max = 1.0, r->info.det_min = 1.0; /* no motion measured */
  ves_status s = new_nodes(nodes, x, h, &r->nodes, &r->info.mirrored);
  if (s == VES_OK) s = ves_quad_create_points(nq, xq, wq, q->ntri, q->tri, &r->quad);
  if (s == VES_OK) r->quad->sub = q->sub, r->quad->rule = q->rule;
  if (s == VES_OK) s = ves_quad_tables(r->quad, r->nodes, lme, &r->info.qinfo);
  ves_model_params par;
  ves_model_get_params(m, &par);
  if (s == VES_OK) s = ves_model_create_points(r->nodes, r->quad, pd, &par, &r->model);
  if (s != VES_OK) {
    ves_reconnect_destroy(&r);
    return s;
  }
  r->info.h_min = INFINITY, r->info.h_max = 0.0;
  for (int a = 0; a < n; a++)
    r->info.h_min = fmin(r->info.h_min, h[a]), r->info.h_max = fmax(r->info.h_max, h[a]);
  r->info.seconds = ves_wall_seconds() - t0;
  *out = r;
  return VES_OK;
}

/* Defaults: every criterion off, as the problem file's [reconnect] keys
 * have them (test_config checks that the two agree). Thresholds worth
 * enabling: a motion with singular values sigma_1 >= sigma_2 seen from the
 * current configuration turns the basis functions p_a o y^-1 into ellipses,
 * beta_a |F^-1 (x - x_a)|^2 acting as an aspect ratio gamma / sigma^2 along
 * each principal direction; gamma 0.6-0.8 is good for second derivatives and
 * 1.8 useless (docs/design.md, "Numerical choices and why"), so cond_max = 2
 * and det_min = 0.5 keep sigma_2 >~ 1/sqrt2 and an effective gamma /
 * sigma_2^2 <~ 1.6 at gamma = 0.8. These bounds are reasoned, not tuned on
 * runs (the paper's Fig. 5 run resets every 20 steps). */
void ves_reconnect_params_default(ves_reconnect_params *par) {
  if (!par) return;
  par->every = 0;
  par->cond_max = 0.0;
  par->det_min = 0.0;
}

ves_status ves_reconnect_due(const ves_reconnect_params *par, const ves_model *m, const double *y,
                             long steps, int *due, double *cond, double *det) {
  VES_CHECK(par && m && y && due && steps >= 0, VES_ERR_ARG);
  VES_CHECK(par->every >= 0, VES_ERR_ARG);
  VES_CHECK(par->cond_max == 0 || par->cond_max > 1, VES_ERR_ARG);
  VES_CHECK(par->det_min >= 0 && par->det_min < 1, VES_ERR_ARG);
  double c = 1.0, d = 1.0;
  if (par->cond_max > 0 || par->det_min > 0) VES_CALL(ves_reconnect_distortion(m, y, &c, &d));
  *due = (par->every > 0 && steps >= par->every) || (par->cond_max > 0 && c > par->cond_max) ||
         (par->det_min > 0 && d < par->det_min);
  if (cond) *cond = c;
  if (det) *det = d;
  return VES_OK;
}
