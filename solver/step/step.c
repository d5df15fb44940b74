/* vesica — one time step as a constrained NLP over the free dofs (paper Eq. 11;
 * docs/design.md, "The time step"): f(x) = (1/2) d^T K(y^n) d + dt E(y), d = x - x0,
 * c = (A(y) - A0, V(y) - V_target) for the held constraints. A BDF2 step
 * (ves_step_set_history) has the same form with another anchor, matrix
 * configuration and weight of E.
 *
 * The model is evaluated once per point x: the last x, its status, E, A, V and
 * (when asked for) their gradients are cached, so f, grad f, c and the
 * Jacobian at the same x cost one model pass. The key is the content of x
 * (a copy is kept), not the pointer, so a caller that changes x in place is
 * never served stale values. */
#include "ves/step.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/mem_impl.h"

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
  double *xa;             /* nvar anchor of d = x - xa: x0, or a BDF2 step's combination */
  const double *yk;       /* 2n configuration of K: yn, or yb in a BDF2 step */
  double *yb;             /* 2n BDF2 extrapolation storage */
  double *qa;             /* the anchor's velocity variables (BDF2), else NULL: qn's */
  double *qp;             /* velocity variables of y^{n-1} (BDF2 scratch), else NULL */
  double *xb;             /* nvar BDF2 anchor storage */
  double dt;              /* the step's dt (par.dt is dt / alpha in a BDF2 step) */
  double *K;              /* nnz triplet values of K(y^n), assembled on demand (K_ok) */
  int K_ok;               /* 1 when K holds K(yk) */
  int bdf2;               /* 1 after ves_step_set_history */
  double *qn;             /* the model's reference of K(y^n) (ves_model_dissipation_ref) */
  double *S;              /* nnz triplets of the drift damping S, or NULL (off) */
  double *blk;            /* 4 ptr[n] block values (K and Hessian assembly) */
  double *y;              /* 2n work: y from x */
  double *d;              /* nvar work: x - x0 */
  double *Sd;             /* nvar S d at the cached x (drift damping on) */
  double *gfull;          /* 3 x 2n gradients of E, A, V over all dofs at the cached x */
  /* cache of the last model evaluation */
  double *xc;     /* nvar the cached point */
  int cache;      /* 0 nothing, 1 values, 2 values and gradients */
  int eager;      /* 1: values always with their gradients (ves_step_eager_gradients) */
  ves_status cst; /* status of the cached evaluation (VES_OK or an error) */
  double E, A, V; /* values at xc */
  double dSd;     /* d^T S d at xc (drift damping) */
  double Dv;      /* (1/2) d^T K(y^n) d at xc (the model's) */
};

void ves_step_destroy(ves_step **s) {
  if (!s || !*s) return;
  ves_step *p = *s;
  free(p->yn), free(p->x0), free(p->K), free(p->blk), free(p->y), free(p->d), free(p->Sd);
  free(p->gfull), free(p->xc), free(p->qn), free(p->S), free(p->xb), free(p->yb);
  free(p->qa), free(p->qp);
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
  s->K = ves_big_alloc(((size_t)pat->nnz + 1) * sizeof *s->K);
  s->blk = ves_big_alloc((4 * (size_t)pat->ptr[pat->n] + 1) * sizeof *s->blk);
  s->y = malloc(n2 * sizeof *s->y);
  s->d = malloc(nv * sizeof *s->d);
  s->Sd = malloc(nv * sizeof *s->Sd);
  s->gfull = malloc(3 * n2 * sizeof *s->gfull);
  s->xc = malloc(nv * sizeof *s->xc);
  s->xb = malloc(nv * sizeof *s->xb);
  s->yb = malloc(n2 * sizeof *s->yb);
  const size_t nqd = ves_model_dissipation_ref_size(m) + 1;
  s->qn = malloc(nqd * sizeof *s->qn);
  s->qa = s->qp = NULL; /* allocated at the first BDF2 step (5 doubles a point each) */
  const double *S = ves_model_drift_blocks(m);
  if (S && (s->S = ves_big_alloc(((size_t)pat->nnz + 1) * sizeof *s->S)))
    ves_pattern_extract(pat, S, s->S);
  if (!s->yn || !s->x0 || !s->K || !s->blk || !s->y || !s->d || !s->Sd || !s->gfull || !s->xc ||
      !s->qn || !s->xb || !s->yb || (S && !s->S)) {
    ves_step_destroy(&s);
    return VES_ERR_ALLOC;
  }
  *out = s;
  return VES_OK;
}

/* Targets and the reference of K(y^n) (the matrix itself only on demand:
 * ves_step_K). */
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
  s->xa = s->x0, s->yk = s->yn, s->bdf2 = 0, s->dt = par->dt;
  s->K_ok = 0;
  VES_CALL(ves_model_dissipation_ref(s->m, yn, s->qn));
  s->is_set = 1;
  return VES_OK;
}

/* BDF2 on K(y) ydot = -grad E - J^T lambda with the step ratio w = dt /
 * dt_prev: ydot^{n+1} ~ (alpha / dt) (y - y^a), alpha = (1 + 2w)/(1 + w),
 * y^a = c y^n + (1 - c) y^{n-1}, c = (1 + w)^2 / (1 + 2w), so the step is
 * the minimization of (1/2)(y - y^a)^T K (y - y^a) + (dt / alpha) E(y), K
 * taken at the linear extrapolation y~ = (1 + w) y^n - w y^{n-1}: an O(dt^2)
 * approximation of y^{n+1}, which keeps the scheme second order where K(y^n)
 * would leave an O(dt) error in the force balance (docs/design.md, "The
 * incremental potential"). */
ves_status ves_step_set_history(ves_step *s, const double *yprev, double w) {
  VES_CHECK(s && s->is_set && !s->bdf2 && yprev, VES_ERR_ARG); /* once after each set */
  VES_CHECK(isfinite(w) && w > 0 && w <= VES_BDF2_RATIO_MAX, VES_ERR_ARG);
  const size_t n2 = 2 * (size_t)s->n, nqd = ves_model_dissipation_ref_size(s->m);
  if (!s->qa && !(s->qa = malloc((nqd + 1) * sizeof *s->qa))) return VES_ERR_ALLOC;
  if (!s->qp && !(s->qp = malloc((nqd + 1) * sizeof *s->qp))) return VES_ERR_ALLOC;
  const double alpha = (1 + 2 * w) / (1 + w), c = (1 + w) * (1 + w) / (1 + 2 * w);
  for (size_t i = 0; i < n2; i++) s->yb[i] = (1 + w) * s->yn[i] - w * yprev[i];
  /* y~ must be admissible (det F > 0, r > 0) for K to exist there */
  ves_status st = ves_model_dissipation_ref(s->m, yprev, s->qp);
  if (st == VES_OK) st = ves_model_dissipation_ref(s->m, s->yb, s->qa);
  if (st != VES_OK) return st; /* the step stays BDF1 */
  /* qa holds y~'s variables, qn y^n's: anchor into qa, y~ into qn */
  for (size_t i = 0; i < nqd; i++) {
    const double qk = s->qa[i];
    s->qa[i] = c * s->qn[i] + (1 - c) * s->qp[i];
    s->qn[i] = qk;
  }
  for (int i = 0; i < 2 * s->n; i++) {
    const int k = s->pat->dof[i];
    if (k >= 0) s->xb[k] = c * s->x0[k] + (1 - c) * yprev[i];
  }
  s->xa = s->xb, s->yk = s->yb, s->bdf2 = 1;
  s->par.dt = s->dt / alpha;
  s->K_ok = 0, s->cache = 0;
  return VES_OK;
}

int ves_step_is_bdf2(const ves_step *s) { return s && s->is_set && s->bdf2; }

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

/* 1 when the cache holds an evaluation at x (admissible or not). */
static int holds(const ves_step *s, const double *x) {
  return s->cache && memcmp(x, s->xc, (size_t)s->nvar * sizeof *x) == 0;
}

/* Make the cache hold x with at least `level` (1 values, 2 gradients). */
static ves_status ensure(ves_step *s, const double *x, int level) {
  const size_t nv = (size_t)s->nvar;
  if (holds(s, x)) {
    if (s->cst != VES_OK) return s->cst; /* the same inadmissible point */
    if (s->cache >= level) return VES_OK;
  } else {
    s->cache = 0;
    memcpy(s->xc, x, nv * sizeof *x);
    for (size_t i = 0; i < nv; i++) s->d[i] = x[i] - s->xa[i]; /* d = x - xa */
    double q = 0;
    if (s->S) { /* S d, d^T S d: the drift damping */
      ves_pattern_symv(s->pat, s->S, s->d, s->Sd);
      for (size_t i = 0; i < nv; i++) q += s->d[i] * s->Sd[i];
    }
    s->dSd = q;
  }
  if (s->eager) level = 2;
  ves_step_expand(s, x, s->y);
  const size_t n2 = 2 * (size_t)s->n;
  double *gE = level >= 2 ? s->gfull : NULL;
  double *gA = level >= 2 ? s->gfull + n2 : NULL;
  double *gV = level >= 2 ? s->gfull + 2 * n2 : NULL;
  /* gE: dt grad E + K d */
  ves_status st = ves_model_eval_step(s->m, s->y, s->which, s->qn, s->bdf2 ? s->qa : NULL,
                                      s->par.dt, &s->E, &s->A, &s->V, &s->Dv, gE, gA, gV);
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
  *f = s->Dv + 0.5 * s->dSd + s->par.dt * s->E;
  return VES_OK;
}

ves_status ves_step_eval_f_start(ves_step *s, double *f) {
  STEP_READY(s, s->x0);
  return ves_step_eval_f(s, s->x0, f);
}

ves_status ves_step_values(ves_step *s, const double *x, double *E, double *A, double *V) {
  STEP_READY(s, x);
  VES_CHECK(E && A && V, VES_ERR_ARG);
  const int all = VES_F_E | VES_F_A | VES_F_V;
  if (holds(s, x) && s->cst == VES_OK && (s->which & all) == all) {
    *E = s->E, *A = s->A, *V = s->V;
    return VES_OK;
  }
  ves_step_expand(s, x, s->y);
  return ves_model_eval(s->m, s->y, all, E, A, V, NULL, NULL, NULL);
}

/* Restrict a full gradient (2n) to the free dofs, scaled: out = a g_free (+ out if add). */
static void restrict_grad(const ves_step *s, const double *gfull, double a, int add, double *out) {
  for (int i = 0; i < 2 * s->n; i++) {
    int k = s->pat->dof[i];
    if (k >= 0) out[k] = (add ? out[k] : 0.0) + a * gfull[i];
  }
}

/* grad f = K d + dt grad E (+ S d) (free dofs); the model's first gradient
 * is K d + dt grad E (ensure). */
ves_status ves_step_eval_grad(ves_step *s, const double *x, double *g) {
  STEP_READY(s, x);
  VES_CHECK(g, VES_ERR_ARG);
  VES_CALL(ensure(s, x, 2));
  if (s->S) memcpy(g, s->Sd, (size_t)s->nvar * sizeof *g);
  restrict_grad(s, s->gfull, 1.0, s->S != NULL, g);
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

/* dt E and dt grad E alone: the cache holds K d + dt grad E, so the gradient
 * is a model pass of its own (the Euler backend's, once a step). */
ves_status ves_step_eval_energy_grad(ves_step *s, const double *x, double *E, double *gE) {
  STEP_READY(s, x);
  VES_CALL(ensure(s, x, 1));
  if (E) *E = s->par.dt * s->E; /* dt E(y) */
  if (!gE) return VES_OK;
  double *g = malloc(2 * (size_t)s->n * sizeof *g), e;
  if (!g) return VES_ERR_ALLOC;
  ves_step_expand(s, x, s->y);
  ves_status st = ves_model_eval(s->m, s->y, VES_F_E, &e, NULL, NULL, g, NULL, NULL);
  if (st == VES_OK) restrict_grad(s, g, s->par.dt, 0, gE); /* dt grad E */
  free(g);
  return st;
}

int ves_step_hess_nnz(const ves_step *s) { return s ? s->pat->nnz : 0; }

void ves_step_hess_structure(const ves_step *s, int *irow, int *jcol) {
  if (!s) return;
  if (irow) memcpy(irow, s->pat->irow, (size_t)s->pat->nnz * sizeof *irow);
  if (jcol) memcpy(jcol, s->pat->jcol, (size_t)s->pat->nnz * sizeof *jcol);
}

/* val = sigma_f (K + dt Hess E) + lambda_A Hess A + lambda_V Hess V, the
 * triangles' products in single precision when single is set. */
static ves_status eval_hess(ves_step *s, const double *x, double sigma_f, const double *lambda,
                            int single, double *val) {
  STEP_READY(s, x);
  VES_CHECK(val && (lambda || s->ncon == 0), VES_ERR_ARG);
  double lA = 0, lV = 0;
  int k = 0;
  if (s->par.hold_area) lA = lambda[k++];
  if (s->par.hold_volume) lV = lambda[k++];
  ves_step_expand(s, x, s->y);
  /* sigma_f K(y^n) summed per point into the one assembly */
  VES_CALL(ves_model_hessian_step(s->m, s->y, s->qn, sigma_f * s->par.dt, lA, lV, sigma_f, single,
                                  s->blk));
  ves_pattern_extract(s->pat, s->blk, val);
  return VES_OK;
}

ves_status ves_step_eval_hess(ves_step *s, const double *x, double sigma_f, const double *lambda,
                              double *val) {
  return eval_hess(s, x, sigma_f, lambda, 0, val);
}

ves_status ves_step_eval_hess_single(ves_step *s, const double *x, double sigma_f,
                                     const double *lambda, double *val) {
  return eval_hess(s, x, sigma_f, lambda, 1, val);
}

double ves_step_hess_floor(const ves_step *s, const double *x, const double *val, double *acc) {
  const int *irow = s->pat->irow, *jcol = s->pat->jcol;
  memset(acc, 0, (size_t)s->nvar * sizeof *acc);
  for (int t = 0; t < s->pat->nnz; t++) {
    const int i = irow[t], j = jcol[t];
    acc[i] += fabs(val[t] * x[j]);
    if (i != j) acc[j] += fabs(val[t] * x[i]); /* the mirrored upper entry */
  }
  double amax = 0.0;
  for (int i = 0; i < s->nvar; i++) amax = fmax(amax, acc[i]);
  return DBL_EPSILON * amax;
}

/* s->K = K(yk) + S, assembled at the first request of the step. */
static ves_status step_K(ves_step *s) {
  if (!s->K_ok) {
    VES_CALL(ves_model_dissipation(s->m, s->yk, s->blk));
    ves_pattern_extract(s->pat, s->blk, s->K);
    s->K_ok = 1;
  }
  return VES_OK;
}

const double *ves_step_K(ves_step *s) {
  return s && s->is_set && step_K(s) == VES_OK ? s->K : NULL;
}

ves_model *ves_step_model(ves_step *s) { return s ? s->m : NULL; }

ves_status ves_step_set_dt(ves_step *s, double dt) {
  VES_CHECK(s && s->is_set && dt > 0 && isfinite(dt), VES_ERR_ARG);
  if (dt != s->par.dt) s->par.dt = dt, s->cache = 0; /* f and grad f weigh E by dt */
  return VES_OK;
}

const ves_step_params *ves_step_get_params(const ves_step *s) {
  return s && s->is_set ? &s->par : NULL;
}

int ves_step_get_targets(const ves_step *s, double tgt[2]) {
  int k = 0;
  tgt[0] = tgt[1] = 1.0;
  if (!s || !s->is_set) return 0;
  if (s->par.hold_area) tgt[k++] = s->par.A0;
  if (s->par.hold_volume) tgt[k++] = s->par.V_target;
  return k;
}
