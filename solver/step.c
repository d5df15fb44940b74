/* vesica — one time step as a constrained NLP over the free dofs (paper Eq. 11,
 * DESIGN.md §3): f(x) = (1/2) d^T K(y^n) d + dt E(y), d = x - x0,
 * c = (A(y) - A0, V(y) - V_target) for the held constraints.
 *
 * The model is evaluated once per point x: the last x, its status, E, A, V and
 * (when asked for) their gradients are cached, so f, grad f, c and the
 * Jacobian at the same x cost one model pass. The key is the content of x
 * (a copy is kept), not the pointer, so a caller that changes x in place is
 * never served stale values. */
#include "ves/step.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct ves_step {
  ves_model *m;           /* borrowed */
  const ves_pattern *pat; /* the model's pattern (borrowed) */
  int n;                  /* real nodes */
  int nvar;               /* free dofs */
  int ncon;               /* held constraints (0..2) */
  int which;              /* functionals the model evaluates: E | held A | held V */
  int is_set;             /* 1 after a successful ves_step_set */
  ves_step_params par;    /* copied at set */
  double *yn;             /* 2n positions y^n */
  double *x0;             /* nvar free dofs of y^n */
  double *K;              /* nnz triplet values of K(y^n) */
  double *blk;            /* 4 ptr[n] block values (K and Hessian assembly) */
  double *y;              /* 2n work: y from x */
  double *d;              /* nvar work: x - x0 */
  double *Kd;             /* nvar K d at the cached x */
  double *gfull;          /* 3 x 2n gradients of E, A, V over all dofs at the cached x */
  /* cache of the last model evaluation */
  double *xc;     /* nvar the cached point */
  int cache;      /* 0 nothing, 1 values, 2 values and gradients */
  int eager;      /* 1: values always with their gradients (ves_step_eager_gradients) */
  ves_status cst; /* status of the cached evaluation (VES_OK or an error) */
  double E, A, V; /* values at xc */
  double dKd;     /* d^T K d at xc */
};

void ves_step_destroy(ves_step **s) {
  if (!s || !*s) return;
  ves_step *p = *s;
  free(p->yn), free(p->x0), free(p->K), free(p->blk), free(p->y), free(p->d), free(p->Kd);
  free(p->gfull), free(p->xc);
  free(p);
  *s = NULL;
}

ves_status ves_step_create(ves_model *m, ves_step **out) {
  VES_CHECK(out, VES_ERR_ARG);
  *out = NULL;
  VES_CHECK(m, VES_ERR_ARG);
  const ves_pattern *pat = ves_model_pattern(m);
  VES_CHECK(pat && pat->nfree > 0, VES_ERR_ARG);
  ves_step *s = calloc(1, sizeof *s);
  if (!s) return VES_ERR_ALLOC;
  s->m = m, s->pat = pat, s->n = pat->n, s->nvar = pat->nfree;
  const size_t n2 = 2 * (size_t)s->n, nv = (size_t)s->nvar;
  s->yn = malloc(n2 * sizeof *s->yn);
  s->x0 = malloc(nv * sizeof *s->x0);
  s->K = malloc(((size_t)pat->nnz + 1) * sizeof *s->K);
  s->blk = malloc((4 * (size_t)pat->ptr[pat->n] + 1) * sizeof *s->blk);
  s->y = malloc(n2 * sizeof *s->y);
  s->d = malloc(nv * sizeof *s->d);
  s->Kd = malloc(nv * sizeof *s->Kd);
  s->gfull = malloc(3 * n2 * sizeof *s->gfull);
  s->xc = malloc(nv * sizeof *s->xc);
  if (!s->yn || !s->x0 || !s->K || !s->blk || !s->y || !s->d || !s->Kd || !s->gfull || !s->xc) {
    ves_step_destroy(&s);
    return VES_ERR_ALLOC;
  }
  *out = s;
  return VES_OK;
}

/* Targets and K(y^n). */
ves_status ves_step_set(ves_step *s, const double *yn, const ves_step_params *par) {
  VES_CHECK(s && yn && par, VES_ERR_ARG);
  VES_CHECK(isfinite(par->dt) && par->dt > 0, VES_ERR_ARG);
  VES_CHECK(!par->hold_area || (isfinite(par->A0) && par->A0 > 0), VES_ERR_ARG);
  VES_CHECK(!par->hold_volume || (isfinite(par->V_target) && par->V_target > 0), VES_ERR_ARG);
  s->is_set = 0;
  s->cache = 0;
  s->par = *par;
  s->ncon = (par->hold_area != 0) + (par->hold_volume != 0);
  s->which = VES_F_E | (par->hold_area ? VES_F_A : 0) | (par->hold_volume ? VES_F_V : 0);
  memcpy(s->yn, yn, 2 * (size_t)s->n * sizeof *yn);
  for (int i = 0; i < 2 * s->n; i++)
    if (s->pat->dof[i] >= 0) s->x0[s->pat->dof[i]] = yn[i];
  VES_CALL(ves_model_dissipation(s->m, yn, s->blk)); /* K(y^n), blocks */
  ves_pattern_extract(s->pat, s->blk, s->K);         /* -> free-dof triplets */
  s->is_set = 1;
  return VES_OK;
}

int ves_step_nvar(const ves_step *s) { return s ? s->nvar : 0; }
int ves_step_ncon(const ves_step *s) { return s && s->is_set ? s->ncon : 0; }

void ves_step_x0(const ves_step *s, double *x) {
  if (s && x) memcpy(x, s->x0, (size_t)s->nvar * sizeof *x);
}

void ves_step_expand(const ves_step *s, const double *x, double *y) {
  if (!s || !x || !y) return;
  for (int i = 0; i < 2 * s->n; i++) {
    int k = s->pat->dof[i];
    y[i] = k >= 0 ? x[k] : s->yn[i]; /* free: from x; fixed: y^n */
  }
}

/* Make the cache hold x with at least `level` (1 values, 2 gradients). */
static ves_status ensure(ves_step *s, const double *x, int level) {
  const size_t nv = (size_t)s->nvar;
  if (s->cache && memcmp(x, s->xc, nv * sizeof *x) == 0) {
    if (s->cst != VES_OK) return s->cst; /* the same inadmissible point */
    if (s->cache >= level) return VES_OK;
  } else {
    s->cache = 0;
    memcpy(s->xc, x, nv * sizeof *x);
    for (size_t i = 0; i < nv; i++) s->d[i] = x[i] - s->x0[i]; /* d = x - x0 */
    ves_pattern_symv(s->pat, s->K, s->d, s->Kd);               /* K d */
    double q = 0;
    for (size_t i = 0; i < nv; i++) q += s->d[i] * s->Kd[i];
    s->dKd = q; /* d^T K d */
  }
  if (s->eager) level = 2;
  ves_step_expand(s, x, s->y);
  const size_t n2 = 2 * (size_t)s->n;
  double *gE = level >= 2 ? s->gfull : NULL;
  double *gA = level >= 2 ? s->gfull + n2 : NULL;
  double *gV = level >= 2 ? s->gfull + 2 * n2 : NULL;
  ves_status st = ves_model_eval(s->m, s->y, s->which, &s->E, &s->A, &s->V, gE, gA, gV);
  s->cst = st;
  s->cache = st == VES_OK ? level : 1; /* an error is remembered for this x */
  return st;
}

void ves_step_eager_gradients(ves_step *s, int on) {
  if (s) s->eager = on != 0;
}

#define STEP_READY(s, x) VES_CHECK((s) && (x) && (s)->is_set, VES_ERR_ARG)

/* f = (1/2) d^T K d + dt E(y). */
ves_status ves_step_eval_f(ves_step *s, const double *x, double *f) {
  STEP_READY(s, x);
  VES_CHECK(f, VES_ERR_ARG);
  VES_CALL(ensure(s, x, 1));
  *f = 0.5 * s->dKd + s->par.dt * s->E;
  return VES_OK;
}

/* Restrict a full gradient (2n) to the free dofs, scaled: out = a g_free (+ out if add). */
static void restrict_grad(const ves_step *s, const double *gfull, double a, int add, double *out) {
  for (int i = 0; i < 2 * s->n; i++) {
    int k = s->pat->dof[i];
    if (k >= 0) out[k] = (add ? out[k] : 0.0) + a * gfull[i];
  }
}

/* grad f = K d + dt grad E (free dofs). */
ves_status ves_step_eval_grad(ves_step *s, const double *x, double *g) {
  STEP_READY(s, x);
  VES_CHECK(g, VES_ERR_ARG);
  VES_CALL(ensure(s, x, 2));
  memcpy(g, s->Kd, (size_t)s->nvar * sizeof *g);
  restrict_grad(s, s->gfull, s->par.dt, 1, g);
  return VES_OK;
}

/* c = (A - A0, V - V_target) for the held ones, area first. */
ves_status ves_step_eval_c(ves_step *s, const double *x, double *c) {
  STEP_READY(s, x);
  VES_CHECK(c || s->ncon == 0, VES_ERR_ARG);
  VES_CALL(ensure(s, x, 1));
  int k = 0;
  if (s->par.hold_area) c[k++] = s->A - s->par.A0;
  if (s->par.hold_volume) c[k++] = s->V - s->par.V_target;
  return VES_OK;
}

/* Rows grad A, grad V (free dofs), row-major. */
ves_status ves_step_eval_jac(ves_step *s, const double *x, double *J) {
  STEP_READY(s, x);
  VES_CHECK(J || s->ncon == 0, VES_ERR_ARG);
  VES_CALL(ensure(s, x, 2));
  const size_t n2 = 2 * (size_t)s->n, nv = (size_t)s->nvar;
  int k = 0;
  if (s->par.hold_area) restrict_grad(s, s->gfull + n2, 1.0, 0, J + nv * k++);
  if (s->par.hold_volume) restrict_grad(s, s->gfull + 2 * n2, 1.0, 0, J + nv * k++);
  return VES_OK;
}

ves_status ves_step_eval_energy_grad(ves_step *s, const double *x, double *E, double *gE) {
  STEP_READY(s, x);
  VES_CALL(ensure(s, x, gE ? 2 : 1));
  if (E) *E = s->par.dt * s->E;                         /* dt E(y) */
  if (gE) restrict_grad(s, s->gfull, s->par.dt, 0, gE); /* dt grad E */
  return VES_OK;
}

int ves_step_hess_nnz(const ves_step *s) { return s ? s->pat->nnz : 0; }

void ves_step_hess_structure(const ves_step *s, int *irow, int *jcol) {
  if (!s) return;
  if (irow) memcpy(irow, s->pat->irow, (size_t)s->pat->nnz * sizeof *irow);
  if (jcol) memcpy(jcol, s->pat->jcol, (size_t)s->pat->nnz * sizeof *jcol);
}

/* val = sigma_f (K + dt Hess E) + lambda_A Hess A + lambda_V Hess V. */
ves_status ves_step_eval_hess(ves_step *s, const double *x, double sigma_f, const double *lambda,
                              double *val) {
  STEP_READY(s, x);
  VES_CHECK(val && (lambda || s->ncon == 0), VES_ERR_ARG);
  double lA = 0, lV = 0;
  int k = 0;
  if (s->par.hold_area) lA = lambda[k++];
  if (s->par.hold_volume) lV = lambda[k++];
  ves_step_expand(s, x, s->y);
  VES_CALL(ves_model_hessian(s->m, s->y, sigma_f * s->par.dt, lA, lV, s->blk));
  ves_pattern_extract(s->pat, s->blk, val);
  if (sigma_f != 0)
    for (int t = 0; t < s->pat->nnz; t++) val[t] += sigma_f * s->K[t]; /* + sigma_f K(y^n) */
  return VES_OK;
}

const double *ves_step_K(const ves_step *s) { return s && s->is_set ? s->K : NULL; }

ves_model *ves_step_model(ves_step *s) { return s ? s->m : NULL; }

const ves_step_params *ves_step_get_params(const ves_step *s) {
  return s && s->is_set ? &s->par : NULL;
}

/* ---- the spectrum of the linearized flow ---------------------------------- */

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
static ves_status flow_matrices(ves_step *s, const double *sigma, double *A, double *J) {
  double sA = 0, sV = 0;
  int q = 0;
  if (s->par.hold_area) sA = sigma[q++];
  if (s->par.hold_volume) sV = sigma[q++];
  VES_CALL(ves_model_hessian(s->m, s->yn, 1.0, sA, sV, s->blk));
  ves_pattern_extract(s->pat, s->blk, A);
  return ves_step_eval_jac(s, s->x0, J);
}

/* Ritz pairs of a K-symmetric operator on {v : J v = 0}. */
typedef struct {
  int k;       /* Ritz values computed (<= the Lanczos steps asked for) */
  double *th;  /* th[k]: Ritz values, ascending */
  double *res; /* res[k]: their Ritz residuals |(Op - th) V s| in the K norm */
  int neg;     /* negative pivots of the factorized [M J^T; J 0] */
} ritz;

/* Factorize [M J^T; J 0] (M in the step pattern's lower triplets, J
 * row-major ncon x nvar) into *out (taken by the caller); spd: M is positive
 * definite (Cholesky when ncon = 0). */
static ves_status kkt_factor(const ves_step *s, const double *M, int spd, const double *J,
                             ves_ldl **out) {
  const ves_pattern *p = s->pat;
  const int nv = s->nvar, nc = s->ncon, nnz = p->nnz + nc * (nv + 1);
  int *ir = malloc((size_t)nnz * sizeof *ir), *jc = malloc((size_t)nnz * sizeof *jc);
  double *val = malloc((size_t)nnz * sizeof *val);
  ves_status st = VES_ERR_ALLOC;
  if (ir && jc && val) {
    memcpy(ir, p->irow, (size_t)p->nnz * sizeof *ir);
    memcpy(jc, p->jcol, (size_t)p->nnz * sizeof *jc);
    memcpy(val, M, (size_t)p->nnz * sizeof *val);
    int t = p->nnz; /* then the rows of J and their zero diagonal */
    for (int i = 0; i < nc; i++) {
      for (int j = 0; j < nv; j++) ir[t] = nv + i, jc[t] = j, val[t++] = J[(size_t)i * nv + j];
      ir[t] = nv + i, jc[t] = nv + i, val[t++] = 0.0;
    }
    st = ves_ldl_create(nv + nc, nnz, ir, jc, spd && nc == 0, out);
    if (st == VES_OK && (st = ves_ldl_factor(*out, val)) != VES_OK) ves_ldl_destroy(out);
  }
  free(ir), free(jc), free(val);
  return st;
}

/* Lanczos in the K inner product for Op v = w, [M J^T; J 0] [w; m] =
 * [B v; 0], M and B symmetric in the step pattern (lower triplets), one of
 * them K: then Op is K-symmetric on the null space of J (M = K: P K^-1 B;
 * B = K: P M^-1 K with M restricted to that space). Start vector:
 * [M J^T; J 0]^-1 [K r; 0] for a fixed pseudo-random r, which lies in the
 * null space of J. Full reorthogonalization (twice), at most kmax steps;
 * eigenpairs of the tridiagonal by LAPACK dstev. out->th and out->res hold
 * kmax entries; spd as for kkt_factor. vec (NULL when nvec = 0) receives
 * the Ritz vectors V z of the nvec largest Ritz values, largest first, nv
 * entries each, K-normalized (NAN beyond the k computed). */
static ves_status lanczos(ves_step *s, const double *M, int spd, const double *B, const double *J,
                          int kmax, int nvec, double *vec, ritz *out) {
  const ves_pattern *p = s->pat;
  const int nv = s->nvar, nc = s->ncon, nk = nv + nc;
  ves_status st = VES_ERR_ALLOC;
  ves_ldl *f = NULL;
  double *rhs = malloc((size_t)nk * sizeof *rhs);
  double *V = malloc((size_t)(kmax + 1) * nv * sizeof *V), *w = malloc((size_t)nv * sizeof *w);
  double *tmp = malloc((size_t)nv * sizeof *tmp);
  double *al = malloc((size_t)kmax * sizeof *al), *be = malloc((size_t)kmax * sizeof *be);
  double *e = malloc((size_t)kmax * sizeof *e), *Z = malloc((size_t)kmax * kmax * sizeof *Z);
  if (!rhs || !V || !w || !tmp || !al || !be || !e || !Z) goto done;
  if ((st = kkt_factor(s, M, spd, J, &f)) != VES_OK) goto done;
  ves_ldl_info li;
  ves_ldl_get_info(f, &li);
  out->neg = li.neg_pivots;
  /* v_0 from a fixed pseudo-random vector */
  unsigned long long r = 88172645463325252ULL;
  for (int i = 0; i < nv; i++) {
    r ^= r << 13, r ^= r >> 7, r ^= r << 17; /* xorshift64 */
    tmp[i] = (double)(r >> 11) / 9007199254740992.0 - 0.5;
  }
  ves_pattern_symv(p, s->K, tmp, rhs); /* [K r; 0] */
  for (int i = 0; i < nc; i++) rhs[nv + i] = 0.0;
  if ((st = ves_ldl_solve(f, rhs)) != VES_OK) goto done;
  double nrm = sqrt(fmax(k_dot(p, s->K, rhs, rhs, tmp), 0.0));
  st = VES_ERR_NOCONV;
  if (!(nrm > 0)) goto done;
  for (int i = 0; i < nv; i++) V[i] = rhs[i] / nrm;
  int k = 0;
  for (; k < kmax; k++) {
    double *vk = V + (size_t)k * nv;
    ves_pattern_symv(p, B, vk, rhs); /* [B v; 0] */
    for (int i = 0; i < nc; i++) rhs[nv + i] = 0.0;
    if ((st = ves_ldl_solve(f, rhs)) != VES_OK) goto done;
    memcpy(w, rhs, (size_t)nv * sizeof *w); /* w = Op v_k */
    for (int pass = 0; pass < 2; pass++) {
      ves_pattern_symv(p, s->K, w, tmp); /* K w */
      for (int j = 0; j <= k; j++) {
        const double *vj = V + (size_t)j * nv;
        double c = 0;
        for (int i = 0; i < nv; i++) c += vj[i] * tmp[i];
        if (pass == 0 && j == k) al[k] = c;
        for (int i = 0; i < nv; i++) w[i] -= c * vj[i];
      }
    }
    be[k] = sqrt(fmax(k_dot(p, s->K, w, w, tmp), 0.0));
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
  ves_ldl_destroy(&f);
  free(rhs), free(V), free(w), free(tmp);
  free(al), free(be), free(e), free(Z);
  return st;
}

/* mu_max of K^-1 A on {v : J v = 0} (step.h): Lanczos on P K^-1 A, P the
 * K-orthogonal projection onto the null space of J. */
ves_status ves_step_stiffness(ves_step *s, const double *sigma, int iters, double *mu_max,
                              double *resid) {
  VES_CHECK(s && s->is_set && mu_max && iters >= 2 && (sigma || s->ncon == 0), VES_ERR_ARG);
  const int nv = s->nvar, nc = s->ncon, nnz = s->pat->nnz;
  const int kmax = iters < nv - nc ? iters : nv - nc;
  VES_CHECK(kmax >= 2, VES_ERR_ARG);
  ves_status st = VES_ERR_ALLOC;
  double *A = malloc((size_t)nnz * sizeof *A), *J = malloc(((size_t)nc * nv + 1) * sizeof *J);
  ritz rz = {.th = malloc((size_t)kmax * sizeof(double)),
             .res = malloc((size_t)kmax * sizeof(double))};
  if (A && J && rz.th && rz.res && (st = flow_matrices(s, sigma, A, J)) == VES_OK &&
      (st = lanczos(s, s->K, 1, A, J, kmax, 0, NULL, &rz)) == VES_OK) {
    *mu_max = rz.th[rz.k - 1];
    if (resid) *resid = rz.res[rz.k - 1] / fabs(rz.th[rz.k - 1]);
  }
  free(A), free(J), free(rz.th), free(rz.res);
  return st;
}

/* The lowest eigenvalues above mu_lo (step.h): shift and invert, Lanczos on
 * Op = P (A - mu_lo K)^-1 K, whose eigenvalues are th = 1 / (mu - mu_lo):
 * the largest th are the mu nearest above mu_lo; the inertia of [A - mu_lo
 * K, J^T; J 0] is that of A - mu_lo K on the null space of J, plus ncon
 * positive and ncon negative. */
ves_status ves_step_modes(ves_step *s, const double *sigma, double mu_lo, int iters, int nwant,
                          double *mu, double *err, double *vec, int *nbelow) {
  VES_CHECK(s && s->is_set && mu && iters >= 2 && nwant >= 1 && nwant <= iters &&
                (sigma || s->ncon == 0) && isfinite(mu_lo),
            VES_ERR_ARG);
  const int nv = s->nvar, nc = s->ncon, nnz = s->pat->nnz;
  const int kmax = iters < nv - nc ? iters : nv - nc;
  VES_CHECK(kmax >= 2 && nwant <= kmax, VES_ERR_ARG);
  ves_status st = VES_ERR_ALLOC;
  double *A = malloc((size_t)nnz * sizeof *A), *J = malloc(((size_t)nc * nv + 1) * sizeof *J);
  ritz rz = {.th = malloc((size_t)kmax * sizeof(double)),
             .res = malloc((size_t)kmax * sizeof(double))};
  if (!A || !J || !rz.th || !rz.res || (st = flow_matrices(s, sigma, A, J)) != VES_OK) goto done;
  for (int i = 0; i < nnz; i++) A[i] -= mu_lo * s->K[i]; /* A - mu_lo K */
  if ((st = lanczos(s, A, 0, s->K, J, kmax, vec ? nwant : 0, vec, &rz)) != VES_OK) goto done;
  if (nbelow) *nbelow = rz.neg - nc;
  for (int j = 0; j < nwant; j++) {
    const int i = rz.k - 1 - j; /* the j-th largest th */
    const int ok = i >= 0 && rz.th[i] > 0;
    mu[j] = ok ? mu_lo + 1 / rz.th[i] : NAN;
    /* |d mu| = |d th| / th^2 */
    if (err) err[j] = ok ? rz.res[i] / (rz.th[i] * rz.th[i]) : NAN;
  }
done:
  free(A), free(J), free(rz.th), free(rz.res);
  return st;
}

/* v^T Hess F v for F = E, A, V at y^n (step.h): three assemblies. */
ves_status ves_step_curvatures(ves_step *s, const double *v, double curv[3]) {
  VES_CHECK(s && s->is_set && v && curv, VES_ERR_ARG);
  const ves_pattern *p = s->pat;
  double *H = malloc((size_t)p->nnz * sizeof *H), *w = malloc((size_t)s->nvar * sizeof *w);
  ves_status st = H && w ? VES_OK : VES_ERR_ALLOC;
  for (int f = 0; f < 3 && st == VES_OK; f++) {
    if ((st = ves_model_hessian(s->m, s->yn, f == 0, f == 1, f == 2, s->blk)) != VES_OK) break;
    ves_pattern_extract(p, s->blk, H);
    curv[f] = k_dot(p, H, v, v, w); /* v^T H v */
  }
  free(H), free(w);
  return st;
}

/* The gradient flow at y^n (step.h): [K J^T; J 0] [ydot; sigma] = [-grad E; 0]. */
ves_status ves_step_flow(ves_step *s, double *ydot, double *sigma) {
  VES_CHECK(s && s->is_set && (sigma || s->ncon == 0), VES_ERR_ARG);
  const int nv = s->nvar, nc = s->ncon;
  ves_status st = VES_ERR_ALLOC;
  ves_ldl *f = NULL;
  double *J = malloc(((size_t)nc * nv + 1) * sizeof *J),
         *rhs = malloc((size_t)(nv + nc) * sizeof *rhs);
  if (!J || !rhs) goto done;
  if ((st = ves_step_eval_jac(s, s->x0, J)) != VES_OK ||
      (st = ves_step_eval_energy_grad(s, s->x0, NULL, rhs)) != VES_OK ||
      (st = kkt_factor(s, s->K, 1, J, &f)) != VES_OK)
    goto done;
  for (int i = 0; i < nv; i++) rhs[i] /= -s->par.dt; /* -grad E (the step's is dt grad E) */
  for (int i = 0; i < nc; i++) rhs[nv + i] = 0.0;
  if ((st = ves_ldl_solve(f, rhs)) != VES_OK) goto done;
  if (ydot) memcpy(ydot, rhs, (size_t)nv * sizeof *ydot);
  for (int i = 0; i < nc; i++) sigma[i] = rhs[nv + i];
done:
  ves_ldl_destroy(&f);
  free(J), free(rhs);
  return st;
}
