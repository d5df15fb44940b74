/* vesica — the linearized flow at a state (spectrum.h): the gradient flow
 * K ydot = -grad E - J^T sigma, J ydot = 0; Lanczos for A v = mu K v (A =
 * Hess E + sum_i sigma_i Hess c_i) in the K inner product on the held
 * constraints' tangent space (stiffness, shift-and-invert modes); the
 * functionals' curvatures; and the analysis of a simulation's state that
 * `vesica spectrum` prints. Every KKT matrix [M J^T; J D] is a step
 * problem's (kkt.h: two constraint rows always, D = -1 on an unused one).
 * docs/design.md, "Analysis". */
#include "ves/spectrum.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ves/kkt.h"

/* The pieces of a step problem set at y^n that the analysis reads. */
typedef struct {
  ves_step *s;                /* borrowed */
  ves_model *m;               /* the step's model (borrowed) */
  const ves_pattern *pat;     /* its pattern (borrowed) */
  const double *K;            /* K(y^n), free-dof triplets (borrowed) */
  const ves_step_params *par; /* the step's parameters (borrowed) */
  int nv;                     /* free dofs */
  int nc;                     /* held constraints */
  double *x0;                 /* nv free dofs of y^n */
  double *yn;                 /* 2n y^n */
  double *blk;                /* 4 ptr[n] block values of a Hessian assembly */
} flow;

static void flow_close(flow *f) {
  free(f->x0), free(f->yn), free(f->blk);
  memset(f, 0, sizeof *f);
}

/* The step's pieces and workspaces; VES_ERR_ARG when s is not set. */
static ves_status flow_open(ves_step *s, flow *f) {
  memset(f, 0, sizeof *f);
  VES_CHECK(s && ves_step_get_params(s), VES_ERR_ARG);
  f->s = s, f->m = ves_step_model(s), f->pat = ves_model_pattern(f->m);
  f->K = ves_step_K(s), f->par = ves_step_get_params(s); /* K assembled here (lazy) */
  VES_CHECK(f->K, VES_ERR_DOMAIN);
  f->nv = ves_step_nvar(s), f->nc = ves_step_ncon(s);
  const size_t n = (size_t)f->pat->n;
  f->x0 = malloc((size_t)f->nv * sizeof *f->x0);
  f->yn = malloc(2 * n * sizeof *f->yn);
  f->blk = malloc((4 * (size_t)f->pat->ptr[n] + 1) * sizeof *f->blk);
  if (!f->x0 || !f->yn || !f->blk) {
    flow_close(f);
    return VES_ERR_ALLOC;
  }
  ves_step_x0(s, f->x0);
  ves_step_expand(s, f->x0, f->yn); /* y^n: free dofs from x0, fixed ones kept */
  return VES_OK;
}

/* u^T K v with K given by its lower triplets (the step pattern). */
static double k_dot(const ves_pattern *p, const double *K, const double *u, const double *v,
                    double *w) {
  ves_pattern_symv(p, K, v, w); /* w = K v */
  double s = 0;
  for (int i = 0; i < p->nfree; i++) s += u[i] * w[i];
  return s;
}

/* A = Hess E + sigma_A Hess A + sigma_V Hess V at y^n (lower triplets, the
 * step pattern) and the constraint Jacobian J there. */
static ves_status flow_matrices(flow *f, const double *sigma, double *A, double *J) {
  double sA = 0, sV = 0;
  int q = 0;
  if (f->par->hold_area) sA = sigma[q++];
  if (f->par->hold_volume) sV = sigma[q++];
  VES_CALL(ves_model_hessian(f->m, f->yn, 1.0, sA, sV, f->blk));
  ves_pattern_extract(f->pat, f->blk, A);
  return ves_step_eval_jac(f->s, f->x0, J);
}

/* Create and factorize the KKT matrix [M J^T; J D] into *k (the caller
 * destroys it): M in the step pattern's lower triplets, J row-major
 * ncon x nvar. k->neg counts M's negative eigenvalues on {v : J v = 0}
 * plus VES_KKT_NROWS (one per held row with J of full rank, one per unused
 * row's -1). */
static ves_status kkt_of(const flow *f, const double *M, const double *J, ves_kkt *k) {
  VES_CALL(ves_kkt_create(f->s, 0, k));
  ves_kkt_fill(k, M, 0.0, NULL, J, f->nc);
  return ves_kkt_factor(k);
}

/* Ritz pairs of a K-symmetric operator on {v : J v = 0}. */
typedef struct {
  int k;       /* Ritz values computed (<= the Lanczos steps asked for) */
  double *th;  /* th[k]: Ritz values, ascending */
  double *res; /* res[k]: their Ritz residuals |(Op - th) V s| in the K norm */
  int neg;     /* negative pivots of the factorized KKT matrix of M */
} ritz;

/* Lanczos in the K inner product for Op v = w, [M J^T; J 0] [w; m] =
 * [B v; 0], M and B symmetric in the step pattern (lower triplets), one of
 * them K: then Op is K-symmetric on the null space of J (M = K: P K^-1 B;
 * B = K: P M^-1 K with M restricted to that space). Start vector:
 * [M J^T; J 0]^-1 [K r; 0] for a fixed pseudo-random r, which lies in the
 * null space of J. Full reorthogonalization (twice), at most kmax steps;
 * eigenpairs of the tridiagonal by LAPACK dstev. out->th and out->res hold
 * kmax entries. vec (NULL when nvec = 0) receives the Ritz vectors V z of
 * the nvec largest Ritz values, largest first, nv entries each,
 * K-normalized (NAN beyond the k computed). */
static ves_status lanczos(const flow *f, const double *M, const double *B, const double *J,
                          int kmax, int nvec, double *vec, ritz *out) {
  const ves_pattern *p = f->pat;
  const int nv = f->nv, nk = nv + VES_KKT_NROWS;
  ves_status st = VES_ERR_ALLOC;
  ves_kkt kkt;
  memset(&kkt, 0, sizeof kkt);
  double *rhs = malloc((size_t)nk * sizeof *rhs);
  double *V = malloc((size_t)(kmax + 1) * nv * sizeof *V), *w = malloc((size_t)nv * sizeof *w);
  double *tmp = malloc((size_t)nv * sizeof *tmp);
  double *al = malloc((size_t)kmax * sizeof *al), *be = malloc((size_t)kmax * sizeof *be);
  double *e = malloc((size_t)kmax * sizeof *e), *Z = malloc((size_t)kmax * kmax * sizeof *Z);
  if (!rhs || !V || !w || !tmp || !al || !be || !e || !Z) goto done;
  if ((st = kkt_of(f, M, J, &kkt)) != VES_OK) goto done;
  out->neg = kkt.neg;
  /* v_0 from a fixed pseudo-random vector */
  unsigned long long r = 88172645463325252ULL;
  for (int i = 0; i < nv; i++) {
    r ^= r << 13, r ^= r >> 7, r ^= r << 17; /* xorshift64 */
    tmp[i] = (double)(r >> 11) / 9007199254740992.0 - 0.5;
  }
  ves_pattern_symv(p, f->K, tmp, rhs); /* [K r; 0] */
  for (int i = nv; i < nk; i++) rhs[i] = 0.0;
  if ((st = ves_kkt_solve(&kkt, rhs)) != VES_OK) goto done;
  double nrm = sqrt(fmax(k_dot(p, f->K, rhs, rhs, tmp), 0.0));
  st = VES_ERR_NOCONV;
  if (!(nrm > 0)) goto done;
  for (int i = 0; i < nv; i++) V[i] = rhs[i] / nrm;
  int k = 0;
  for (; k < kmax; k++) {
    double *vk = V + (size_t)k * nv;
    ves_pattern_symv(p, B, vk, rhs); /* [B v; 0] */
    for (int i = nv; i < nk; i++) rhs[i] = 0.0;
    if ((st = ves_kkt_solve(&kkt, rhs)) != VES_OK) goto done;
    memcpy(w, rhs, (size_t)nv * sizeof *w); /* w = Op v_k */
    for (int pass = 0; pass < 2; pass++) {
      ves_pattern_symv(p, f->K, w, tmp); /* K w */
      for (int j = 0; j <= k; j++) {
        const double *vj = V + (size_t)j * nv;
        double c = 0;
        for (int i = 0; i < nv; i++) c += vj[i] * tmp[i];
        if (pass == 0 && j == k) al[k] = c;
        for (int i = 0; i < nv; i++) w[i] -= c * vj[i];
      }
    }
    be[k] = sqrt(fmax(k_dot(p, f->K, w, w, tmp), 0.0));
    if (k + 1 == kmax || !(be[k] > 1e-14 * fabs(al[k]))) {
      k++;
      break; /* the Krylov space is exhausted or the budget spent */
    }
    double *vn = V + (size_t)(k + 1) * nv;
    for (int i = 0; i < nv; i++) vn[i] = w[i] / be[k];
  }
  /* eigenpairs of the k x k tridiagonal (al, be), ascending */
  memcpy(out->th, al, (size_t)k * sizeof *al);
  if (k > 1) memcpy(e, be, (size_t)(k - 1) * sizeof *e);
  st = LAPACKE_dstev(LAPACK_COL_MAJOR, 'V', k, out->th, e, Z, k) == 0 ? VES_OK : VES_ERR_NOCONV;
  if (st == VES_OK) {
    out->k = k;
    /* |(Op - th_j) V s_j| = be_k |last entry of s_j| */
    for (int j = 0; j < k; j++) out->res[j] = be[k - 1] * fabs(Z[(size_t)j * k + (k - 1)]);
    for (int j = 0; j < nvec; j++) { /* x_j = V z_{k-1-j} */
      double *x = vec + (size_t)j * nv;
      if (j >= k) {
        for (int i = 0; i < nv; i++) x[i] = NAN;
        continue;
      }
      const double *z = Z + (size_t)(k - 1 - j) * k;
      memset(x, 0, (size_t)nv * sizeof *x);
      for (int l = 0; l < k; l++)
        for (int i = 0; i < nv; i++) x[i] += z[l] * V[(size_t)l * nv + i];
    }
  }
done:
  ves_kkt_destroy(&kkt);
  free(rhs), free(V), free(w), free(tmp);
  free(al), free(be), free(e), free(Z);
  return st;
}

/* The work of a spectrum: A, J and the Ritz arrays for kmax steps. */
typedef struct {
  double *A; /* nnz */
  double *J; /* ncon * nvar */
  ritz rz;
} spectrum_work;

static void work_free(spectrum_work *w) {
  free(w->A), free(w->J), free(w->rz.th), free(w->rz.res);
  memset(w, 0, sizeof *w);
}

static ves_status work_alloc(const flow *f, int kmax, spectrum_work *w) {
  memset(w, 0, sizeof *w);
  w->A = malloc((size_t)f->pat->nnz * sizeof *w->A);
  w->J = malloc(((size_t)f->nc * f->nv + 1) * sizeof *w->J);
  w->rz.th = malloc((size_t)kmax * sizeof *w->rz.th);
  w->rz.res = malloc((size_t)kmax * sizeof *w->rz.res);
  if (w->A && w->J && w->rz.th && w->rz.res) return VES_OK;
  work_free(w);
  return VES_ERR_ALLOC;
}

/* mu_max of K^-1 A on {v : J v = 0} (spectrum.h): Lanczos on P K^-1 A, P the
 * K-orthogonal projection onto the null space of J. */
ves_status ves_spectrum_stiffness(ves_step *s, const double *sigma, int iters, double *mu_max,
                                  double *resid) {
  VES_CHECK(s && ves_step_get_params(s) && mu_max && iters >= 2, VES_ERR_ARG);
  VES_CHECK(sigma || ves_step_ncon(s) == 0, VES_ERR_ARG);
  const int nt = ves_step_nvar(s) - ves_step_ncon(s); /* tangent dimension */
  const int kmax = iters < nt ? iters : nt;
  VES_CHECK(kmax >= 2, VES_ERR_ARG);
  flow f;
  spectrum_work w;
  VES_CALL(flow_open(s, &f));
  ves_status st = work_alloc(&f, kmax, &w);
  if (st == VES_OK && (st = flow_matrices(&f, sigma, w.A, w.J)) == VES_OK &&
      (st = lanczos(&f, f.K, w.A, w.J, kmax, 0, NULL, &w.rz)) == VES_OK) {
    *mu_max = w.rz.th[w.rz.k - 1];
    if (resid) *resid = w.rz.res[w.rz.k - 1] / fabs(w.rz.th[w.rz.k - 1]);
  }
  work_free(&w);
  flow_close(&f);
  return st;
}

/* The lowest eigenvalues above mu_lo (spectrum.h): shift and invert, Lanczos
 * on Op = P (A - mu_lo K)^-1 K, whose eigenvalues are th = 1 / (mu - mu_lo):
 * the largest th are the mu nearest above mu_lo; the KKT matrix of A - mu_lo
 * K has the negative eigenvalues of A - mu_lo K on the null space of J plus
 * VES_KKT_NROWS (kkt_of). */
ves_status ves_spectrum_modes(ves_step *s, const double *sigma, double mu_lo, int iters, int nwant,
                              double *mu, double *err, double *vec, int *nbelow) {
  VES_CHECK(s && ves_step_get_params(s) && mu && iters >= 2 && nwant >= 1 && nwant <= iters,
            VES_ERR_ARG);
  VES_CHECK((sigma || ves_step_ncon(s) == 0) && isfinite(mu_lo), VES_ERR_ARG);
  const int nt = ves_step_nvar(s) - ves_step_ncon(s);
  const int kmax = iters < nt ? iters : nt;
  VES_CHECK(kmax >= 2 && nwant <= kmax, VES_ERR_ARG);
  flow f;
  spectrum_work w;
  VES_CALL(flow_open(s, &f));
  ves_status st = work_alloc(&f, kmax, &w);
  if (st != VES_OK || (st = flow_matrices(&f, sigma, w.A, w.J)) != VES_OK) goto done;
  for (int i = 0; i < f.pat->nnz; i++) w.A[i] -= mu_lo * f.K[i]; /* A - mu_lo K */
  if ((st = lanczos(&f, w.A, f.K, w.J, kmax, vec ? nwant : 0, vec, &w.rz)) != VES_OK) goto done;
  if (nbelow) *nbelow = w.rz.neg - VES_KKT_NROWS;
  for (int j = 0; j < nwant; j++) {
    const int i = w.rz.k - 1 - j; /* the j-th largest th */
    const int ok = i >= 0 && w.rz.th[i] > 0;
    mu[j] = ok ? mu_lo + 1 / w.rz.th[i] : NAN;
    /* |d mu| = |d th| / th^2 */
    if (err) err[j] = ok ? w.rz.res[i] / (w.rz.th[i] * w.rz.th[i]) : NAN;
  }
done:
  work_free(&w);
  flow_close(&f);
  return st;
}

/* v^T Hess F v for F = E, A, V at y^n (spectrum.h): three assemblies. */
ves_status ves_spectrum_curvatures(ves_step *s, const double *v, double curv[3]) {
  VES_CHECK(s && ves_step_get_params(s) && v && curv, VES_ERR_ARG);
  flow f;
  VES_CALL(flow_open(s, &f));
  const ves_pattern *p = f.pat;
  double *H = malloc((size_t)p->nnz * sizeof *H), *w = malloc((size_t)f.nv * sizeof *w);
  ves_status st = H && w ? VES_OK : VES_ERR_ALLOC;
  for (int k = 0; k < 3 && st == VES_OK; k++) {
    if ((st = ves_model_hessian(f.m, f.yn, k == 0, k == 1, k == 2, f.blk)) != VES_OK) break;
    ves_pattern_extract(p, f.blk, H);
    curv[k] = k_dot(p, H, v, v, w); /* v^T H v */
  }
  free(H), free(w);
  flow_close(&f);
  return st;
}

/* The gradient flow at y^n (spectrum.h): [K J^T; J 0] [ydot; sigma] = [-grad E; 0]. */
ves_status ves_spectrum_flow(ves_step *s, double *ydot, double *sigma) {
  VES_CHECK(s && ves_step_get_params(s) && (sigma || ves_step_ncon(s) == 0), VES_ERR_ARG);
  flow f;
  VES_CALL(flow_open(s, &f));
  const int nv = f.nv, nc = f.nc;
  ves_status st = VES_ERR_ALLOC;
  ves_kkt kkt;
  memset(&kkt, 0, sizeof kkt);
  double *J = malloc(((size_t)nc * nv + 1) * sizeof *J),
         *rhs = malloc((size_t)(nv + VES_KKT_NROWS) * sizeof *rhs);
  if (!J || !rhs) goto done;
  if ((st = ves_step_eval_jac(s, f.x0, J)) != VES_OK ||
      (st = ves_step_eval_energy_grad(s, f.x0, NULL, rhs)) != VES_OK ||
      (st = kkt_of(&f, f.K, J, &kkt)) != VES_OK)
    goto done;
  for (int i = 0; i < nv; i++) rhs[i] /= -f.par->dt; /* -grad E (the step's is dt grad E) */
  for (int i = nv; i < nv + VES_KKT_NROWS; i++) rhs[i] = 0.0;
  if ((st = ves_kkt_solve(&kkt, rhs)) != VES_OK) goto done;
  if (ydot) memcpy(ydot, rhs, (size_t)nv * sizeof *ydot);
  for (int i = 0; i < nc; i++) sigma[i] = rhs[nv + i];
done:
  ves_kkt_destroy(&kkt);
  free(J), free(rhs);
  flow_close(&f);
  return st;
}

/* ---- the analysis of a simulation's state --------------------------------- */

void ves_spectrum_destroy(ves_spectrum **s) {
  if (!s || !*s) return;
  ves_spectrum *p = *s;
  free(p->mu), free(p->mu_err), free(p->mode), free(p->vec);
  free(p->x), free(p->phi), free(p->u), free(p->du);
  free(p);
  *s = NULL;
}

static ves_status spectrum_alloc(int n, int nv, int nm, ves_spectrum **out) {
  ves_spectrum *r = calloc(1, sizeof *r);
  if (!r) return VES_ERR_ALLOC;
  r->n = n, r->nvar = nv, r->nmodes = nm;
  r->mu = malloc((size_t)nm * sizeof *r->mu);
  r->mu_err = malloc((size_t)nm * sizeof *r->mu_err);
  r->mode = calloc((size_t)nm, sizeof *r->mode);
  r->vec = malloc((size_t)nm * nv * sizeof *r->vec);
  r->x = malloc(2 * (size_t)n * sizeof *r->x);
  r->phi = malloc((size_t)n * sizeof *r->phi);
  r->u = malloc(2 * (size_t)n * nm * sizeof *r->u);
  r->du = malloc(2 * (size_t)n * nm * sizeof *r->du);
  *out = r;
  if (r->mu && r->mu_err && r->mode && r->vec && r->x && r->phi && r->u && r->du) return VES_OK;
  ves_spectrum_destroy(out);
  return VES_ERR_ALLOC;
}

/* The flow's dissipation ydot^T K ydot and largest nodal speed (work[nv]). */
static void flow_size(const ves_pattern *pat, const double *K, const double *yd, double *work,
                      ves_spectrum *r) {
  ves_pattern_symv(pat, K, yd, work);
  double diss = 0, vmax = 0;
  for (int i = 0; i < r->nvar; i++) diss += yd[i] * work[i];
  for (int a = 0; a < pat->n; a++) { /* |ydot| of node a over its free components */
    double v2 = 0;
    for (int c = 0; c < 2; c++)
      if (pat->dof[2 * a + c] >= 0) v2 += yd[pat->dof[2 * a + c]] * yd[pat->dof[2 * a + c]];
    vmax = fmax(vmax, sqrt(v2));
  }
  r->dissipation = diss, r->ydot_max = vmax;
}

/* The coefficients' drift from the motion, d = y^a - y(X_a) over the free
 * dofs (x: the material at the nodes), and its K-cosine with each
 * K-normalized mode (d[nv], Kd[nv] work). */
static void drift_cosines(const ves_pattern *pat, const double *K, const double *y, const double *x,
                          double *d, double *Kd, ves_spectrum *r) {
  const int nv = r->nvar;
  for (int i = 0; i < 2 * pat->n; i++)
    if (pat->dof[i] >= 0) d[pat->dof[i]] = y[i] - x[i];
  ves_pattern_symv(pat, K, d, Kd);
  double dKd = 0, share = 0;
  for (int i = 0; i < nv; i++) dKd += d[i] * Kd[i];
  for (int j = 0; j < r->nmodes; j++) {
    double c = 0;
    for (int i = 0; i < nv; i++) c += r->vec[(size_t)j * nv + i] * Kd[i];
    r->mode[j].drift = dKd > 0 ? c / sqrt(dKd) : 0.0;
    if (isfinite(r->mode[j].drift)) share += r->mode[j].drift * r->mode[j].drift;
  }
  r->drift_K_norm = sqrt(dKd), r->drift_in_modes = share;
}

/* Where each mode lives (ves_spectrum_mode): its coefficients per node u,
 * the motion du they give at the nodes, and the shares over the band, the
 * axis and the material; r->x and r->phi hold the material at the nodes. */
static ves_status mode_places(ves_sim *sim, const ves_pattern *pat, const ves_nodes *nd,
                              ves_spectrum *r) {
  const int n = r->n, nv = r->nvar;
  for (int j = 0; j < r->nmodes; j++) {
    const double *v = r->vec + (size_t)j * nv;
    double *uj = r->u + 2 * (size_t)n * j, *dj = r->du + 2 * (size_t)n * j;
    for (int i = 0; i < 2 * n; i++) uj[i] = pat->dof[i] >= 0 ? v[pat->dof[i]] : 0.0;
    VES_CALL(ves_sim_motion_at_nodes(sim, uj, dj));
    double tot = 0, band = 0, axis = 0, mat = 0, big = -1;
    ves_spectrum_mode *q = r->mode + j;
    for (int a = 0; a < n; a++) {
      const double u2 = uj[2 * a] * uj[2 * a] + uj[2 * a + 1] * uj[2 * a + 1];
      tot += u2, mat += dj[2 * a] * dj[2 * a] + dj[2 * a + 1] * dj[2 * a + 1];
      if (fabs(r->phi[a]) < 0.9) band += u2;
      if (r->x[2 * a] < 2 * nd->h[a]) axis += u2;
      if (u2 > big)
        big = u2, q->peak[0] = r->x[2 * a], q->peak[1] = r->x[2 * a + 1], q->peak_phi = r->phi[a];
    }
    q->band = band / tot, q->axis = axis / tot, q->material = sqrt(mat / tot);
  }
  return VES_OK;
}

/* The spectra and the mode shares on a step problem set at the state. */
static ves_status analyse(ves_sim *sim, ves_step *sp, const ves_spectrum_params *p, double *yd,
                          double *Kyd, ves_spectrum *r) {
  const ves_pattern *pat = ves_model_pattern(ves_step_model(sp));
  const ves_step_params *par = ves_step_get_params(sp);
  VES_CALL(ves_spectrum_flow(sp, yd, r->sigma));
  if (!par->hold_area) r->sigma[1] = r->sigma[0], r->sigma[0] = 0.0; /* (sigma_A, sigma_V) */
  if (!par->hold_volume) r->sigma[1] = 0.0;
  flow_size(pat, ves_step_K(sp), yd, Kyd, r);
  const double *sg = par->hold_area ? r->sigma : r->sigma + 1; /* the held ones, area first */
  VES_CALL(ves_spectrum_stiffness(sp, sg, p->lanczos, &r->mu_max, &r->mu_max_resid));
  VES_CALL(ves_spectrum_modes(sp, sg, p->above, p->lanczos, p->modes, r->mu, r->mu_err, r->vec,
                              &r->below));
  VES_CALL(ves_sim_node_material(sim, r->x, NULL));
  drift_cosines(pat, ves_step_K(sp), ves_sim_y(sim), r->x, yd, Kyd, r);
  for (int j = 0; j < p->modes; j++) { /* mu = E'' + sigma_A A'' + sigma_V V'' */
    double cv[3] = {NAN, NAN, NAN};
    if (isfinite(r->mu[j])) VES_CALL(ves_spectrum_curvatures(sp, r->vec + (size_t)j * r->nvar, cv));
    r->mode[j].from[0] = cv[0];
    r->mode[j].from[1] = par->hold_area ? r->sigma[0] * cv[1] : 0.0;
    r->mode[j].from[2] = par->hold_volume ? r->sigma[1] * cv[2] : 0.0;
  }
  return VES_OK;
}

ves_status ves_spectrum_create(ves_sim *sim, const ves_spectrum_params *p, ves_spectrum **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL;
  VES_CHECK(sim && p && p->lanczos >= 2 && p->modes >= 1 && p->modes <= p->lanczos, VES_ERR_ARG);
  VES_CHECK(isfinite(p->above), VES_ERR_ARG);
  ves_model *m = ves_sim_model(sim);
  const ves_nodes *nd = ves_model_nodes(m);
  ves_sim_state ss;
  ves_sim_get_state(sim, &ss, NULL);
  const ves_step_params par = {.dt = ss.dt,
                               .hold_area = p->hold_area != 0,
                               .A0 = ss.A0,
                               .hold_volume = p->hold_volume != 0,
                               .V_target = ss.V};
  ves_step *sp = NULL;
  ves_spectrum *r = NULL;
  double *yd = NULL, *Kyd = NULL;
  ves_status st = ves_step_create(m, &sp);
  if (st == VES_OK) st = ves_step_set(sp, ves_sim_y(sim), &par);
  if (st == VES_OK) st = spectrum_alloc(nd->n, ves_step_nvar(sp), p->modes, &r);
  if (st == VES_OK) {
    yd = malloc((size_t)r->nvar * sizeof *yd), Kyd = malloc((size_t)r->nvar * sizeof *Kyd);
    st = yd && Kyd ? analyse(sim, sp, p, yd, Kyd, r) : VES_ERR_ALLOC;
  }
  ves_step_destroy(&sp);
  if (st == VES_OK && (st = ves_sim_node_material(sim, r->x, r->phi)) == VES_OK)
    st = mode_places(sim, ves_model_pattern(m), nd, r);
  free(yd), free(Kyd);
  if (st != VES_OK) ves_spectrum_destroy(&r);
  *out = r;
  return st;
}
