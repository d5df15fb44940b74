/* vesica — the model's assembly kernel (model.c holds the API; the object
 * in model_core_impl.h): the folding of a point's table onto its real nodes,
 * the kinematics q = B y, the gradient scatter, and per triangle the Hessian
 * and K blocks
 *   sum_p c_p B_p^T H_p B_p = X^T diag_p(c H_p) X   (p the triangle's points),
 * over the union of the points' node lists (X their B stacked, K = 36 / 30
 * deep), formed by the BLAS as the rr, rz and zz parts (one BLAS thread per
 * triangle, the triangles in parallel) and added to the pattern once per
 * triangle, not once per point (~6x fewer scattered updates). The products
 * run in double, or in single precision for a matrix factored in single
 * precision (ves_step_eval_hess_single; model_asm_prec_impl.h holds both);
 * the points' local matrices and the pattern's sums stay double. The
 * triangles are visited in the order and by the slabs of model_threads.c, so
 * every entry receives its contributions in the same order and results are
 * bitwise the same for any thread count (for one BLAS kernel). E, A, V and
 * their gradients are summed in point order; the Hessian and K differ from a
 * per-point assembly by rounding only (docs/design.md, "Numerical choices
 * and why"). */
#include "model/model_core_impl.h"

#include <assert.h>
#include <stdlib.h>
#include <string.h>
#include "core/omp_impl.h"

#include <cblas.h>

#define ASM_PANELS 4 /* column panels of the symmetric block products (upper_product) */

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

void model_ws_free(model_ws *w) {
  free(w->un), free(w->Tr), free(w->Tz), free(w->stamp), free(w->slot);
  free(w->U), free(w->Utmp), free(w->X), free(w->Y), free(w->M), free(w->yl);
}

/* The workspace of the folding and the unions (the products' arrays follow
 * in model_ws_alloc_products, once the largest union is known). */
ves_status model_ws_alloc(model_ws *w, int n, int mmax, int cap) {
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

ves_status model_ws_alloc_products(model_ws *w, int numax) {
  w->X = malloc((size_t)NPT * NB * numax * sizeof *w->X);
  w->Y = malloc((size_t)NPT * (NB + 6) * numax * sizeof *w->Y);
  w->M = malloc(3 * (size_t)numax * numax * sizeof *w->M);
  return w->X && w->Y && w->M ? VES_OK : VES_ERR_ALLOC;
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
int model_triangle_union(const ves_model *m, model_ws *w, int t, folded f[NPT], const int **U) {
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

/* The inner loops over a point's nodes are written as contiguous
 * reductions (the table rows are contiguous; y is gathered first) and asked
 * to vectorize with OpenMP simd: the same binary sums in the same order on
 * every thread, so results stay bitwise independent of the thread count. */
#ifdef _OPENMP
#define OMP_SIMD _Pragma("omp simd")
#define OMP_PRAGMA(x) _Pragma(#x)
#define OMP_SIMD_SUMS(...) OMP_PRAGMA(omp simd reduction(+ : __VA_ARGS__))
#else
#define OMP_SIMD_SUMS(...)
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
  /* the 6 r sums in one pass and the 5 z sums in another: each is a
   * reduction over u as its own loop would be (one vector accumulator a
   * sum), the node's y loaded once for all of them */
  const double *r0 = Tr, *r1 = Tr + mu, *r2 = Tr + 2 * mu, *r3 = Tr + 3 * mu, *r4 = Tr + 4 * mu,
               *r5 = Tr + 5 * mu;
  double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0, s4 = 0.0, s5 = 0.0;
  OMP_SIMD_SUMS(s0, s1, s2, s3, s4, s5)
  for (int u = 0; u < mu; u++) {
    const double v = yr[u];
    s0 += r0[u] * v, s1 += r1[u] * v, s2 += r2[u] * v;
    s3 += r3[u] * v, s4 += r4[u] * v, s5 += r5[u] * v;
  }
  q[MAP_Q.qr[0]] = s0, q[MAP_Q.qr[1]] = s1, q[MAP_Q.qr[2]] = s2;
  q[MAP_Q.qr[3]] = s3, q[MAP_Q.qr[4]] = s4, q[MAP_Q.qr[5]] = s5;
  const double *z1 = Tz + mu, *z2 = Tz + 2 * mu, *z3 = Tz + 3 * mu, *z4 = Tz + 4 * mu,
               *z5 = Tz + 5 * mu; /* MAP_Q.rz = 1..5 */
  double t1 = 0.0, t2 = 0.0, t3 = 0.0, t4 = 0.0, t5 = 0.0;
  OMP_SIMD_SUMS(t1, t2, t3, t4, t5)
  for (int u = 0; u < mu; u++) {
    const double v = yz[u];
    t1 += z1[u] * v, t2 += z2[u] * v, t3 += z3[u] * v, t4 += z4[u] * v, t5 += z5[u] * v;
  }
  q[MAP_Q.qz[0]] = t1, q[MAP_Q.qz[1]] = t2, q[MAP_Q.qz[2]] = t3;
  q[MAP_Q.qz[3]] = t4, q[MAP_Q.qz[4]] = t5;
}

/* out[u] = sum_j c_j T[row_j][u] over the nodes, summed in j order from 0
 * (the order of the axpys it replaces: bitwise the same), one pass over u
 * with the sum in a register: 5 or 6 rows, their loads shared by nothing
 * else, vectorized over u. */
static void rows6(int mu, const double *T, const double c[6], double *out) {
  const double *t0 = T, *t1 = T + mu, *t2 = T + 2 * mu, *t3 = T + 3 * mu, *t4 = T + 4 * mu,
               *t5 = T + 5 * mu;
  OMP_SIMD
  for (int u = 0; u < mu; u++) {
    double s = 0.0;
    s += c[0] * t0[u], s += c[1] * t1[u], s += c[2] * t2[u];
    s += c[3] * t3[u], s += c[4] * t4[u], s += c[5] * t5[u];
    out[u] = s;
  }
}

static void rows5(int mu, const double *T, const double c[5], double *out) {
  const double *t1 = T + mu, *t2 = T + 2 * mu, *t3 = T + 3 * mu, *t4 = T + 4 * mu, *t5 = T + 5 * mu;
  OMP_SIMD
  for (int u = 0; u < mu; u++) {
    double s = 0.0;
    s += c[0] * t1[u], s += c[1] * t2[u], s += c[2] * t3[u];
    s += c[3] * t4[u], s += c[4] * t5[u];
    out[u] = s;
  }
}

/* g += c B^T ge on the entries of the nodes of slab k: per node u,
 * (B^T ge)_r(u) = sum_j c ge[qr_j] Tr[rr_j][u] (rows 0-5 of Tr), (B^T
 * ge)_z(u) = sum_j c ge[qz_j] Tz[rz_j][u] (rows 1-5 of Tz), formed over the
 * nodes (sl: 2 mu scratch), then added. */
static void scatter_grad(const folded *f, const int *owner, int k, double c, const double *ge,
                         double *sl, double *g) {
  const int mu = f->mu;
  double *sr = sl, *sz = sl + mu, cr[6], cz[5];
  for (int j = 0; j < 6; j++) cr[j] = c * ge[MAP_Q.qr[j]]; /* MAP_Q.rr = 0..5 */
  for (int j = 0; j < 5; j++) cz[j] = c * ge[MAP_Q.qz[j]]; /* MAP_Q.rz = 1..5 */
  rows6(mu, f->Tr, cr, sr);
  rows5(mu, f->Tz, cz, sz);
  for (int u = 0; u < mu; u++) {
    const int a = f->un[u];
    if (owner[a] == k) g[2 * a] += sr[u], g[2 * a + 1] += sz[u];
  }
}

#define ASM_REAL double
#define ASM_SFX(name) name##_d
#define ASM_GEMM cblas_dgemm
#include "model/model_asm_prec_impl.h"
#undef ASM_REAL
#undef ASM_SFX
#undef ASM_GEMM
#define ASM_REAL float
#define ASM_SFX(name) name##_s
#define ASM_GEMM cblas_sgemm
#include "model/model_asm_prec_impl.h"
#undef ASM_REAL
#undef ASM_SFX
#undef ASM_GEMM
/* D = d2 diss / dqdot2 at point al of y^n (without 2 pi w). */
static ves_status step_ref_dissip(const ves_model *m, const step_ref *sr, int al, double *D) {
  double qa[VES_NQ] = {0};
  memcpy(qa, sr->qn + VES_NQD * (size_t)al, VES_NQD * sizeof *qa);
  return ves_model_local_dissip(&m->lp, qa, D);
}

/* Triangle t's contribution to the rows of slab k: the local matrices of its
 * points (fac[3] = f_E cE, f_A cA, f_V cV for ASM_HESS), then its block
 * matrix sum_p B_p^T cH_p B_p over its union as three products
 *   Mrr = Xr Yrr^T,  Mrz = Xr Yrz^T,  Mzz = Xz Yzz^T   (triangle_xy)
 * by the BLAS (one thread: the caller runs the triangles in parallel; of
 * the symmetric Mrr and Mzz only the triangle the scatter reads), in single
 * precision when single is set (model_asm_prec_impl.h), and its owned rows
 * into blk. */
static ves_status triangle_blocks(const ves_model *m, model_ws *w, asm_kind kind,
                                  const double fac[3], const step_ref *sr, int single, int t, int k,
                                  const double *y, double *blk) {
  const local_map *mp = kind == ASM_HESS ? &MAP_Q : &MAP_QD;
  const int nl = mp->nl;
  folded f[NPT];
  const int *U;
  const int nu = model_triangle_union(m, w, t, f, &U);
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
          for (int j = 0; j < VES_NQD; j++)
            Hp[i * VES_NQ + j] += 2 * M_PI * sr->cK * D[i * VES_NQD + j];
      }
      c = m->q->w[al];
    } else {
      VES_CALL(ves_model_local_dissip(&m->lp, q, Hp));
      c = 2 * M_PI * m->q->w[al];
    }
    for (int i = 0; i < nl * nl; i++) Hp[i] *= c;
  }
  if (single)
    triangle_products_s(m, w, mp, f, U, nu, Hs, k, blk);
  else
    triangle_products_d(m, w, mp, f, U, nu, Hs, k, blk);
  return VES_OK;
}

/* blk = sum over the triangles of their block matrices (kind, fac as in
 * triangle_blocks), the slabs shared out over the threads. */
ves_status model_assemble(ves_model *m, asm_kind kind, const double fac[3], const step_ref *sr,
                          int single, const double *y, double *blk) {
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
          st[k] = triangle_blocks(m, w, kind, fac, sr, single, t, k, y, blk);
      }
  }
  if (blas_threads != 1) openblas_set_num_threads(blas_threads);
  for (int k = 0; k < m->nthr; k++)
    if (st[k] != VES_OK) return st[k];
  return VES_OK;
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
  model_functional_factors(m, 1.0, 1.0, 1.0, fac);
  static ves_model_local_fn *const fn[3] = {ves_model_local_energy, ves_model_local_area,
                                            ves_model_local_volume};
  for (int p = 0; p < NPT; p++) {
    const int al = NPT * t + p;
    folded f;
    double q[VES_NQ], e, ge[VES_NQ], wa = m->q->w[al], gk[VES_NQD];
    fold_point(m->q, m->mmax, w, al, 0, &f);
    kinematics(&f, y, w->yl, q);
    if (k == m->tlo[t]) memcpy(m->qrec + VES_NQD * (size_t)al, q, VES_NQD * sizeof *q);
    if (sr) { /* the step's dissipation: gk = 2 pi w D dq */
      double D[VES_NQD * VES_NQD], dq[VES_NQD], dv = 0;
      VES_CALL(step_ref_dissip(m, sr, al, D));
      const double *qa = (sr->qa ? sr->qa : sr->qn) + VES_NQD * (size_t)al;
      for (int i = 0; i < VES_NQD; i++) dq[i] = q[i] - qa[i];
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
ves_status model_eval_points(ves_model *m, const double *y, int which, const step_ref *sr,
                             double cE, double *E, double *A, double *V, double *Dv, double *gE,
                             double *gA, double *gV) {
  VES_CHECK(m && y, VES_ERR_ARG);
  int n = m->nodes->n;
  double fac[3];
  model_functional_factors(m, 1.0, 1.0, 1.0, fac);
  const double fE = fac[0], fA = fac[1], fV = fac[2];
  double *const g[3] = {(which & VES_F_E) ? gE : NULL, (which & VES_F_A) ? gA : NULL,
                        (which & VES_F_V) ? gV : NULL};
  ves_status st[64];
  which &= VES_F_E | VES_F_A | VES_F_V;
  for (int i = 0; i < 3; i++)
    if (g[i]) memset(g[i], 0, 2 * (size_t)n * sizeof *g[i]);
  for (int k = 0; k < m->nthr; k++) st[k] = VES_OK;
  m->qrec_ok = 0; /* overwritten from here on */
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
  if (which) { /* every point's kinematics passed the domain check: q is a reference */
    memcpy(m->yrec, y, 2 * (size_t)n * sizeof *y);
    m->qrec_ok = 1;
  }
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
  if ((which & VES_F_E) && m->sc) Es = model_stab_eval(m, y, g[0], sr ? cE : 1.0);
  if ((which & VES_F_E) && E) *E = m->sc ? (double)(fE * s[0] + Es) : (double)(fE * s[0]);
  if ((which & VES_F_A) && A) *A = (double)(fA * s[1]);
  if ((which & VES_F_V) && V) *V = (double)(fV * s[2]);
  if (sr && Dv) *Dv = (double)s[3];
  return VES_OK;
}

/* Call fn(m, al, q, ctx) once for every point al with its kinematics q at y,
 * the triangles shared out over the threads (each by its first slab). */
ves_status model_each_point(ves_model *m, const double *y, point_fn *fn, void *ctx) {
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
