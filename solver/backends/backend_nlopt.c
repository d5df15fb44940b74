/* vesica — the "nlopt" backend: the step problem (step.h) solved by NLopt's
 * augmented Lagrangian (NLOPT_AUGLAG) around L-BFGS (NLOPT_LD_LBFGS), in
 * preconditioned variables u (docs/design.md, "Backends"):
 *
 *   x = x_start + root L^{-T} u,   F(u) = (f(x) + lambda0^T c(x)) / root^2,
 *   r_i(u) = c_i(x) / sigma_i,     sigma_i = root |L^{-1} grad c_i| / NLB_CSCALE,
 *
 * L L^T = M the Hessian of the Lagrangian at x_start (K when M has a
 * non-positive diagonal entry) by sparse Cholesky (chol.h), shifted by
 * alpha diag(M) until positive definite; an indefinite M with constraints
 * first tries the dense metric M + J^T S J (nlb_dense_metric). The Hessian
 * of F at the start is then the identity. root = tol max|L^{-1} grad f| /
 * LBFGS_GTOL turns L-BFGS's fixed absolute gradient test into the relative
 * one; lambda0 are the multipliers of the quadratic model's step (AUGLAG
 * starts its own at zero). A solve runs two phases, to NLB_TOL1 in the
 * metric of the start and to tol in that of the first phase's end, or one
 * when the step is near-quadratic (max_i |M_ii - K_ii| / K_ii <=
 * NLB_ONE_PHASE_R). A direct solve that leaves the domain (det F <= 0: the
 * objective returns HUGE_VAL, NLB_DOMAIN_MAX in a row stop it) is solved
 * again by continuation in dt (nlb_continue). lambda out: least squares of
 * grad f + J^T lambda = 0 at the answer. Statistics: iterations = AUGLAG's
 * outer iterations, h_evals = Hessians factored. Measurements:
 * docs/results.md, "The backends compared" and "Robustness at large Δt". */
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <nlopt.h>

#include "ves/backend.h"
#include "ves/chol.h"
#include "core/clock_impl.h"

#define NLB_EVALS_PER_ITER 100 /* maxeval = this * max_iter */
#define NLB_KKT_SLACK 1e6      /* the final first-order check: tol times this (nlb_solve) */
#define NLB_DOMAIN_MAX 30      /* consecutive domain errors before giving up */
#define LBFGS_GTOL 1e-8        /* Luksan's fixed gradient tolerance (NLopt plis.c) */
#define NLB_SHIFTS 8           /* diagonal shifts alpha = 0, 1e-3, ..., 1e3 tried */
#define NLB_TOL1 1e-3          /* first phase's relative gradient tolerance (0: one phase) */
#define NLB_ONE_PHASE_R 1.0    /* one phase when max |diag(M - K)| / diag(K) is below this */
#define NLB_CONT_R 1e4       /* r = max|M_ii - K_ii| / K_ii above this: straight to nlb_continue */
#define NLB_CTOL1 1e-6       /* first phase's relative constraint tolerance */
#define NLB_LAMBDA_RTOL 1e-2 /* rebuild the Hessian at the model multipliers beyond this */
#define NLB_DENSE_N 6000     /* the dense constraint metric up to this many unknowns */
#define NLB_JT_TAU0 1e-2     /* ... its first tau (nlb_precondition) */
#define NLB_JT_TAU_MAX 10    /* ... and its last */
#define NLB_CSCALE                                                                                 \
  10.0 /* |grad_u r_i| at the start: AUGLAG's penalty (rho0 10) 100 rho F's curvature */
#define NLB_CONT_FACTOR 10.0       /* continuation in dt: first factor between stages up */
#define NLB_CONT_DOWN_FACTOR 100.0 /* ... the factor of the search down from dt */
#define NLB_CONT_DOWN 3            /* ... down from dt at most this many factors */
#define NLB_CONT_MIN 1.2           /* ... a stage factor shrunk below this: give up */

/* The typed context of the callbacks. */
typedef struct {
  ves_step *s;          /* the step problem (borrowed) */
  nlopt_opt opt;        /* the outer optimizer (for nlopt_force_stop) */
  int n, m;             /* nvar, ncon */
  ves_chol *C;          /* the factor L of the change of variables (borrowed) */
  const double *xs;     /* n the start x_start */
  double root;          /* x = x_start + root L^{-T} u */
  double f_scale;       /* root^2 */
  double *x;            /* n scratch: x(u) */
  double *g;            /* n scratch: grad f at x */
  double *J;            /* 2 n scratch Jacobian */
  double *B;            /* 3 n scratch: the columns of one batched half solve */
  double *uc;           /* n: the u of the constraints cached by the objective */
  double rc[2];         /* ... their values r_i(uc) */
  int cached;           /* 0 none, 1 the values, 2 also their gradients (in B + n) */
  double tgt[2];        /* constraint scales sigma_i (the banner) */
  double lam0[2];       /* multipliers folded into the objective (warm start) */
  int f_evals, g_evals; /* objective evaluations, with gradient */
  int h_evals;          /* Hessians assembled for the factor */
  int outer;            /* objective calls without gradient (AUGLAG's own) */
  int phases;           /* AUGLAG solves started (nlb_phase) */
  int domain_run;       /* consecutive domain errors */
  int gate;             /* the next phase is a step's direct solve: NLB_CONT_R applies */
  int need_pd;          /* the next phase starts only where M is positive definite */
  int one_phase;        /* NLB_ONE_PHASE_R may make a first phase the last */
  int promoted;         /* ... and did, in this solve */
  ves_status reason;    /* why the solve was forced to stop (VES_OK: not) */
} nlb_ctx;

typedef struct {
  ves_backend_options opt;           /* copied options */
  int n, nnz;                        /* sizes the arrays are for */
  double *x, *g, *J, *u, *xs, *hval; /* scratch, u, start, Hessian values */
  double *B, *uc;                    /* 3 n, n: the callbacks' cache (nlb_ctx) */
  int *hi, *hj;                      /* Hessian structure (lower triplets) */
  ves_chol *C;                       /* the factor L: sparse Cholesky on the Hessian pattern */
  double shift;                      /* the diagonal shift alpha of the last factorization */
  double tau;                        /* ... or the weight of its dense J^T S J term (0: none) */
  int dense_fail;                    /* the last factorization tried that term in vain */
  double rdiag;                      /* max_i |M_ii - K_ii| / K_ii of the last Hessian M */
  double *dg;                        /* 2 n scratch: diagonals */
  int pass;                          /* 0: M is the Hessian of the Lagrangian; 1: K */
  double kkt, jtl, noise;            /* max |grad f + J^T lambda|, max |J^T lambda|, its
                                        rounding floor (nlb_finish) */
  nlb_ctx ctx;
} nlb_state;

/* v = L^{-1} v; fails only on arguments it is never given. */
static void nlb_lsolve(ves_chol *C, double *v) { (void)ves_chol_lsolve(C, v); }

/* v = L^{-T} v. */
static void nlb_ltsolve(ves_chol *C, double *v) { (void)ves_chol_ltsolve(C, v); }

/* ---- callbacks ---------------------------------------------------------- */

/* Stop the solve for reason st (kept in the context). */
static void nlb_stop(nlb_ctx *c, ves_status st) {
  if (c->reason == VES_OK) c->reason = st;
  nlopt_force_stop(c->opt);
}

/* c->x = x_start + root L^{-T} u */
static void nlb_x_of_u(nlb_ctx *c, const double *u) {
  for (int i = 0; i < c->n; i++) c->x[i] = c->root * u[i];
  nlb_ltsolve(c->C, c->x);
  for (int i = 0; i < c->n; i++) c->x[i] += c->xs[i];
}

/* The constraints' values r_i = c_i / sigma_i at x = x(u) into c->rc, and
 * with J (the Jacobian in x, 2 n) their gradients in u, root L^{-1} grad c_i
 * / sigma_i, already in c->B + n (nlb_objective's batched solve): kept for
 * nlb_constraints at the same u. */
static void nlb_cache(nlb_ctx *c, const double *u, const double *cv, int with_grad) {
  const size_t n = (size_t)c->n;
  memcpy(c->uc, u, n * sizeof *u);
  for (int i = 0; i < c->m; i++) {
    c->rc[i] = cv[i] / c->tgt[i];
    if (with_grad)
      for (size_t j = 0; j < n; j++) c->B[(size_t)(i + 1) * n + j] *= c->root / c->tgt[i];
  }
  c->cached = with_grad ? 2 : 1;
}

/* F(u) = f(x(u)) / root^2 and grad_u F = L^{-1} grad f / root. With
 * constraints, their values and gradients at the same point are computed
 * here too and kept for nlb_constraints, which AUGLAG calls next at the same
 * u: x(u) is then solved for once, and the gradient and the constraints'
 * gradients go through one batched half solve (the factor read once instead
 * of three times; docs/results.md, "Robustness at large Δt"). */
static double nlb_objective(unsigned n, const double *u, double *grad, void *data) {
  nlb_ctx *c = data;
  c->cached = 0;
  nlb_x_of_u(c, u);
  double f = 0.0, cv[2] = {0.0, 0.0};
  ves_status st = ves_step_eval_f(c->s, c->x, &f);
  c->f_evals++;
  if (grad) {
    c->g_evals++;
    if (st == VES_OK) st = ves_step_eval_grad(c->s, c->x, grad);
  } else {
    c->outer++;
  }
  if (st == VES_OK && c->m > 0) {
    st = ves_step_eval_c(c->s, c->x, cv);
    if (st == VES_OK && grad) st = ves_step_eval_jac(c->s, c->x, c->J);
    /* f + lam0^T c (same minimizer on c = 0) */
    for (int i = 0; i < c->m && st == VES_OK; i++) {
      f += c->lam0[i] * cv[i];
      if (grad)
        for (unsigned j = 0; j < n; j++) grad[j] += c->lam0[i] * c->J[(size_t)i * n + j];
    }
  }
  if (st == VES_ERR_DOMAIN) {
    /* outside: an infinite value makes the line search back off */
    if (++c->domain_run >= NLB_DOMAIN_MAX || c->f_evals == 1) nlb_stop(c, st);
    if (grad) memset(grad, 0, n * sizeof *grad);
    return HUGE_VAL;
  }
  if (st != VES_OK) {
    nlb_stop(c, st);
    if (grad) memset(grad, 0, n * sizeof *grad);
    return HUGE_VAL;
  }
  c->domain_run = 0;
  if (grad && c->m > 0) { /* [grad, J^T] in one solve */
    memcpy(c->B, grad, n * sizeof *grad);
    memcpy(c->B + n, c->J, (size_t)c->m * n * sizeof *grad);
    if (ves_chol_lsolve_cols(c->C, 1 + c->m, c->B) == VES_OK) {
      for (unsigned i = 0; i < n; i++) grad[i] = c->B[i] / c->root;
      nlb_cache(c, u, cv, 1);
      return f / c->f_scale;
    }
  }
  if (grad) {
    nlb_lsolve(c->C, grad);
    for (unsigned i = 0; i < n; i++) grad[i] /= c->root;
  }
  if (c->m > 0) nlb_cache(c, u, cv, 0);
  return f / c->f_scale;
}

/* r_i(u) = c_i(x(u)) / sigma_i, grad[i n + .] = L^{-1} grad c_i root / sigma_i;
 * from the objective's cache at the same u when it holds what is asked. */
static void nlb_constraints(unsigned m, double *r, unsigned n, const double *u, double *grad,
                            void *data) {
  nlb_ctx *c = data;
  if (c->cached >= (grad ? 2 : 1) && memcmp(u, c->uc, n * sizeof *u) == 0) {
    for (unsigned i = 0; i < m; i++) r[i] = c->rc[i];
    if (grad) memcpy(grad, c->B + n, (size_t)m * n * sizeof *grad);
    return;
  }
  nlb_x_of_u(c, u);
  ves_status st = ves_step_eval_c(c->s, c->x, r);
  if (st == VES_OK && grad) st = ves_step_eval_jac(c->s, c->x, grad);
  if (st != VES_OK) {
    /* AUGLAG asks for the constraints at every point it evaluated, also one
     * the objective refused as outside the domain, so a domain error stops
     * the solve here at its first refusal: tolerated, L-BFGS does not
     * converge at dt* 1e3 and 1e4 and a hopeless step costs maxeval
     * gradients before the integrator may halve dt (docs/results.md,
     * "Approaches measured and not adopted"). */
    for (unsigned i = 0; i < m; i++) r[i] = HUGE_VAL;
    nlb_stop(c, st);
    return;
  }
  for (unsigned i = 0; i < m; i++) {
    r[i] /= c->tgt[i];
    if (grad) {
      nlb_lsolve(c->C, grad + (size_t)i * n);
      for (unsigned j = 0; j < n; j++) grad[i * n + j] *= c->root / c->tgt[i];
    }
  }
}

/* ---- the backend -------------------------------------------------------- */

static void nlb_free_arrays(nlb_state *st) {
  free(st->x), free(st->g), free(st->J), free(st->u), free(st->xs), free(st->hval);
  free(st->hi), free(st->hj), free(st->dg), free(st->B), free(st->uc);
  ves_chol_destroy(&st->C);
  st->x = st->g = st->J = st->u = st->xs = st->hval = NULL;
  st->hi = st->hj = NULL, st->dg = st->B = st->uc = NULL;
  st->n = 0, st->nnz = 0;
}

/* Workspaces and the preconditioner's pattern for the sizes of s. */
static ves_status nlb_alloc(nlb_state *st, ves_step *s) {
  int n = ves_step_nvar(s), nnz = ves_step_hess_nnz(s);
  VES_CHECK(n > 0 && nnz >= 0, VES_ERR_ARG);
  if (st->n == n && st->nnz == nnz) return VES_OK;
  nlb_free_arrays(st);
  size_t N = (size_t)n, Z = (size_t)(nnz > 0 ? nnz : 1);
  st->x = malloc(N * sizeof(double)), st->g = malloc(N * sizeof(double));
  st->J = malloc(2 * N * sizeof(double)), st->u = malloc(N * sizeof(double));
  st->xs = malloc(N * sizeof(double)), st->hval = malloc(Z * sizeof(double));
  st->hi = malloc(Z * sizeof(int)), st->hj = malloc(Z * sizeof(int));
  st->dg = malloc(2 * N * sizeof(double));
  st->B = malloc(3 * N * sizeof(double)), st->uc = malloc(N * sizeof(double));
  if (!st->x || !st->g || !st->J || !st->u || !st->xs || !st->hval || !st->hi || !st->hj ||
      !st->dg || !st->B || !st->uc) {
    nlb_free_arrays(st);
    return VES_ERR_ALLOC;
  }
  ves_step_hess_structure(s, st->hi, st->hj);
  ves_status rc = ves_chol_create(n, nnz, st->hi, st->hj, &st->C);
  if (rc != VES_OK) {
    nlb_free_arrays(st);
    return rc;
  }
  st->n = n, st->nnz = nnz;
  return VES_OK;
}

static void nlb_destroy(void **state) {
  if (!state || !*state) return;
  nlb_state *st = *state;
  nlb_free_arrays(st);
  free(st);
  *state = NULL;
}

static ves_status nlb_create(const ves_backend_options *opt, ves_step *s, void **state) {
  VES_CHECK(opt && s && state, VES_ERR_ARG);
  VES_CHECK(opt->tol > 0 && opt->ctol > 0 && opt->max_iter > 0, VES_ERR_ARG);
  nlb_state *st = calloc(1, sizeof *st);
  VES_CHECK(st, VES_ERR_ALLOC);
  st->opt = *opt;
  ves_status rc = nlb_alloc(st, s);
  if (rc != VES_OK) {
    void *p = st;
    nlb_destroy(&p);
    return rc;
  }
  *state = st;
  return VES_OK;
}

/* max_i |M_ii - K_ii| / K_ii of the Hessian in st->hval against K (the
 * triplets' diagonal entries summed; HUGE_VAL where K_ii <= 0): how far the
 * step is from quadratic (nlb_phase, the banner). The diagonals
 * stay in st->dg (M's, then K's) for nlb_precondition. */
static double nlb_rdiag(nlb_state *st, const double *K) {
  double *dh = st->dg, *dk = st->dg + st->n, r = 0.0;
  memset(st->dg, 0, 2 * (size_t)st->n * sizeof *st->dg);
  for (int k = 0; k < st->nnz; k++)
    if (st->hi[k] == st->hj[k]) dh[st->hi[k]] += st->hval[k], dk[st->hi[k]] += K[k];
  for (int i = 0; i < st->n; i++) r = fmax(r, dk[i] > 0.0 ? fabs(dh[i] - dk[i]) / dk[i] : HUGE_VAL);
  return r;
}

/* G G^T = M + sum_i s_i J_i J_i^T, s_i = tau mean(diag M) / |J_i|^2, for tau
 * = NLB_JT_TAU0, 10 NLB_JT_TAU0, ... NLB_JT_TAU_MAX: the least tau that
 * makes it positive definite, densely (ves_chol_factor_dense). Stops early
 * when a larger tau leaves the failing pivot where it was: the negative
 * curvature is then not along J (the reduced Hessian itself is indefinite),
 * and no tau will do. */
static ves_status nlb_dense_metric(nlb_state *st, int m, const double *J) {
  double dm = 0.0, sc[2] = {0.0, 0.0};
  for (int k = 0; k < st->nnz; k++)
    if (st->hi[k] == st->hj[k]) dm += st->hval[k];
  dm /= st->n;
  for (int i = 0; i < m; i++) {
    double nn = 0.0;
    for (int j = 0; j < st->n; j++) nn += J[(size_t)i * st->n + j] * J[(size_t)i * st->n + j];
    if (!(nn > 0.0 && dm > 0.0)) return VES_ERR_SINGULAR;
    sc[i] = dm / nn;
  }
  int last = -1;
  for (double tau = NLB_JT_TAU0; tau <= NLB_JT_TAU_MAX; tau *= 10.0) {
    const double sw[2] = {tau * sc[0], tau * sc[1]};
    int fail = 0;
    ves_status rc = ves_chol_factor_dense(st->C, st->hval, m, J, sw, &fail);
    if (rc == VES_OK) {
      st->tau = tau;
      return VES_OK;
    }
    if (rc != VES_ERR_SINGULAR || fail == last) return rc;
    last = fail;
  }
  return VES_ERR_SINGULAR;
}

/* Factor the preconditioner at x (the banner): M = Hessian of the
 * Lagrangian, or K if that has a non-positive diagonal entry, by sparse
 * Cholesky with diagonal shifts. With constraints
 * (J: their m gradients at x) and an indefinite M, first the dense metric
 * M + J^T S J (nlb_dense_metric; up to NLB_DENSE_N unknowns, and not when
 * dense is 0), then the diagonal shifts. */
static ves_status nlb_precondition(nlb_state *st, ves_step *s, const double *x,
                                   const double *lambda, int m, const double *J, int dense) {
  const double *K = ves_step_K(s);
  VES_CHECK(K != NULL, VES_ERR_ARG);
  VES_CALL(ves_step_eval_hess(s, x, 1.0, lambda, st->hval));
  st->rdiag = nlb_rdiag(st, K);
  /* a step's direct solve that goes to the continuation needs no factor */
  if (st->ctx.gate && st->rdiag > NLB_CONT_R) return VES_ERR_DOMAIN;
  if (st->ctx.need_pd) { /* a stage of the search down: M itself or nothing */
    st->ctx.need_pd = 0;
    if (ves_chol_factor(st->C, st->hval, 0.0) != VES_OK) return VES_ERR_DOMAIN;
    st->shift = 0.0, st->tau = 0.0, st->pass = 0, st->dense_fail = 0;
    return VES_OK;
  }
  for (int pass = 0; pass < 2; pass++) {
    const double *v = pass == 0 ? st->hval : K;
    const double *dv = st->dg + (size_t)pass * st->n; /* its diagonal (nlb_rdiag) */
    int posdiag = 1;
    for (int i = 0; i < st->n; i++) posdiag &= dv[i] > 0.0;
    if (!posdiag) continue;
    double alpha = 0.0;
    st->tau = 0.0, st->dense_fail = 0;
    for (int t = 0; t < NLB_SHIFTS; t++, alpha = alpha == 0.0 ? 1e-3 : 10.0 * alpha) {
      if (ves_chol_factor(st->C, v, alpha) == VES_OK) {
        st->shift = alpha, st->pass = pass;
        return VES_OK;
      }
      if (t == 0 && pass == 0 && dense && m > 0 && st->n <= NLB_DENSE_N) {
        ves_status rc = nlb_dense_metric(st, m, J);
        if (rc == VES_OK) {
          st->shift = 0.0, st->pass = pass;
          return VES_OK;
        }
        if (rc != VES_ERR_SINGULAR) return rc;
        st->dense_fail = 1;
      }
    }
  }
  return VES_ERR_SINGULAR;
}

/* (J J^T) lambda = r - J g, m <= 2, r[m] (NULL: 0): with r = 0 the
 * least-squares multipliers of grad f + J^T lambda = 0; with J and g in the
 * variables of an exact factor of M (L^{-1} grad c_i, L^{-1} grad f) and r =
 * c, those of the quadratic model's step [M J^T; J 0] (dx, lambda) = -(g, c). */
static void nlb_multipliers(int n, int m, const double *J, const double *g, const double *r,
                            double *lambda) {
  double a[2][2] = {{0, 0}, {0, 0}}, b[2] = {r && m > 0 ? r[0] : 0, r && m > 1 ? r[1] : 0};
  for (int i = 0; i < m; i++) {
    for (int k = 0; k < m; k++)
      for (int j = 0; j < n; j++) a[i][k] += J[i * n + j] * J[k * n + j];
    for (int j = 0; j < n; j++) b[i] -= J[i * n + j] * g[j];
  }
  if (m == 1) {
    lambda[0] = a[0][0] > 0 ? b[0] / a[0][0] : 0.0;
  } else if (m == 2) {
    double det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
    lambda[0] = det != 0.0 ? (b[0] * a[1][1] - a[0][1] * b[1]) / det : 0.0;
    lambda[1] = det != 0.0 ? (a[0][0] * b[1] - a[1][0] * b[0]) / det : 0.0;
  }
}

/* Multipliers and violation at x: least-squares lambda of grad f + J^T
 * lambda = 0, max |c_i| / target_i into *viol. */
static ves_status nlb_finish(nlb_state *st, ves_step *s, const double *x, int m, const double *tgt,
                             double *lambda, double *viol) {
  double cv[2] = {0.0, 0.0};
  ves_status e = m > 0 ? ves_step_eval_c(s, x, cv) : VES_OK;
  if (e == VES_OK) e = ves_step_eval_grad(s, x, st->g);
  if (e == VES_OK && m > 0) e = ves_step_eval_jac(s, x, st->J);
  if (e != VES_OK) return e;
  *viol = 0.0;
  for (int i = 0; i < m; i++) *viol = fmax(*viol, fabs(cv[i]) / tgt[i]);
  if (m > 0) nlb_multipliers(st->n, m, st->J, st->g, NULL, lambda);
  /* the residual of the first-order conditions, the size of J^T lambda and
   * the rounding floor eps_mach (|H| |x|)_inf of the residual (newton's: x
   * holds absolute positions to eps_mach; H the last Hessian assembled) */
  double *acc = st->u; /* scratch: u is not needed after the solve */
  memset(acc, 0, (size_t)st->n * sizeof *acc);
  for (int k = 0; k < st->nnz; k++) {
    const int i = st->hi[k], j = st->hj[k];
    acc[i] += fabs(st->hval[k] * x[j]);
    if (i != j) acc[j] += fabs(st->hval[k] * x[i]);
  }
  st->noise = 0.0;
  for (int j = 0; j < st->n; j++) st->noise = fmax(st->noise, DBL_EPSILON * acc[j]);
  st->kkt = 0.0, st->jtl = 0.0;
  for (int j = 0; j < st->n; j++) {
    double t = 0.0;
    for (int i = 0; i < m; i++) t += lambda[i] * st->J[(size_t)i * st->n + j];
    st->kkt = fmax(st->kkt, fabs(st->g[j] + t)), st->jtl = fmax(st->jtl, fabs(t));
  }
  return VES_OK;
}

/* The start of nlb_phase at x: the gradient g and the constraints' Jacobian
 * J in the variables of the factor (nlb_precondition), and with an exact
 * factor and constraints the multipliers lam_qp of the quadratic model's
 * step (*have_qp). */
static ves_status nlb_start(nlb_state *st, ves_step *s, const double *x, const double *lambda,
                            double lam_qp[2], int *have_qp) {
  nlb_ctx *c = &st->ctx;
  const int n = st->n, m = c->m;
  /* Its gradient and the preconditioner; with an exact factor and
   * constraints, the multipliers of the quadratic model's step, and when they
   * differ from the ones the Hessian was built with by more than
   * NLB_LAMBDA_RTOL, once more with the Hessian at those. */
  double lam_m[2] = {m > 0 ? lambda[0] : 0.0, m > 1 ? lambda[1] : 0.0};
  double c0[2] = {0.0, 0.0};
  *have_qp = 0;
  ves_status rc = m > 0 ? ves_step_eval_c(s, x, c0) : VES_OK;
  for (int pass = 0; pass < 2 && rc == VES_OK; pass++) {
    rc = ves_step_eval_grad(s, x, st->g);
    if (rc == VES_OK && m > 0) rc = ves_step_eval_jac(s, x, st->J);
    if (rc == VES_OK) {
      const int probe = c->gate || c->need_pd; /* may stop at the Hessian */
      /* at the same x with other multipliers: no second try of a dense
       * metric that failed (its reduced Hessian is indefinite) */
      rc = nlb_precondition(st, s, x, m > 0 ? lam_m : NULL, m, st->J, pass == 0 || !st->dense_fail);
      if (rc == VES_OK || (rc == VES_ERR_DOMAIN && probe)) c->g_evals++, c->h_evals++;
    }
    if (rc != VES_OK) break;
    nlb_lsolve(st->C, st->g); /* the gradient in u at root = 1 */
    for (int i = 0; i < m; i++) nlb_lsolve(st->C, st->J + (size_t)i * n);
    *have_qp = m > 0; /* an estimate, also from a shifted factor */
    if (!*have_qp) break;
    nlb_multipliers(n, m, st->J, st->g, c0, lam_qp);
    double dl = 0.0, lm = 0.0;
    for (int i = 0; i < m; i++)
      dl = fmax(dl, fabs(lam_qp[i] - lam_m[i])), lm = fmax(lm, fabs(lam_qp[i]));
    if (dl <= NLB_LAMBDA_RTOL * lm) break;
    lam_m[0] = lam_qp[0], lam_m[1] = lam_qp[1];
  }
  return rc;
}

/* The scales of nlb_phase from the start's gradient and Jacobian: the root
 * of u (c->root, c->f_scale), the constraint scales c->tgt with their
 * tolerances ctol[] (relative ctol_rel on c_i), the multipliers to start
 * AUGLAG from (c->lam0); x is kept as st->xs. */
static void nlb_scales(nlb_state *st, const double *x, const double *lambda, const double *tgt,
                       double tol, double ctol_rel, const double lam_qp[2], int have_qp,
                       double ctol[2]) {
  nlb_ctx *c = &st->ctx;
  const int n = st->n, m = c->m;
  memcpy(st->xs, x, (size_t)n * sizeof(double));
  double gmax = 0.0;
  for (int i = 0; i < n; i++) gmax = fmax(gmax, fabs(st->g[i]));
  c->root = gmax > 0.0 ? tol * gmax / LBFGS_GTOL : 1.0;
  c->f_scale = c->root * c->root;
  /* Constraint scales: |grad_u r_i| = NLB_CSCALE at the start, so AUGLAG's
   * penalty rho |r|^2 / 2 (rho starts at 10) is NLB_CSCALE^2 rho times F's
   * unit Hessian in those directions; the tolerance of r_i is ctol
   * target_i / sigma_i (relative ctol on c_i). */
  ctol[0] = ctol[1] = ctol_rel;
  for (int i = 0; i < m; i++) {
    double *Ji = st->J + (size_t)i * n, nrm = 0.0;
    for (int j = 0; j < n; j++) nrm += Ji[j] * Ji[j];
    c->tgt[i] = nrm > 0.0 ? c->root * sqrt(nrm) / NLB_CSCALE : tgt[i];
    ctol[i] = ctol_rel * tgt[i] / c->tgt[i];
    c->lam0[i] = have_qp ? lam_qp[i] : lambda[i];
  }
}

/* NLopt's verdict as a status: the stops at a point (tolerances, a
 * stalled line search) VES_OK, the evaluation or time limit VES_MAXITER. */
static ves_status nlb_status(nlopt_result r) {
  switch (r) {
  case NLOPT_SUCCESS:
  case NLOPT_STOPVAL_REACHED:
  case NLOPT_FTOL_REACHED:
  case NLOPT_XTOL_REACHED:
  case NLOPT_FAILURE: /* LBFGS's line search stalled on roundoff: judged by nlb_finish */
  case NLOPT_ROUNDOFF_LIMITED:
    return VES_OK;
  case NLOPT_MAXEVAL_REACHED:
  case NLOPT_MAXTIME_REACHED:
    return VES_MAXITER;
  case NLOPT_OUT_OF_MEMORY:
    return VES_ERR_ALLOC;
  default: /* invalid arguments, a forced stop without a reason */
    return VES_ERR_SOLVER;
  }
}

/* One AUGLAG solve from x (in/out) to relative tolerances tol (gradient in
 * the metric of the factor) and ctol (constraints), in the variables of the
 * factor of the Hessian at x with multipliers lambda (in; out: least-squares
 * ones at the result). *last (in/out): 0 for a first phase, to NLB_TOL1 and
 * NLB_CTOL1, unless the Hessian at x is near K (max_i |M_ii - K_ii| / K_ii
 * <= NLB_ONE_PHASE_R: a near-quadratic step, whose metric does not change
 * along it), which makes it the last phase, to tol and ctol (*last = 1).
 * *r: NLopt's verdict. */
static ves_status nlb_phase(nlb_state *st, ves_step *s, double *x, double *lambda,
                            const double *tgt, double tol, double ctol_rel, int *last,
                            nlopt_result *r, double *viol) {
  nlb_ctx *c = &st->ctx;
  const int n = st->n, m = c->m;
  c->phases++;
  *r = NLOPT_FAILURE;
  *viol = HUGE_VAL;
  c->domain_run = 0;
  double lam_qp[2] = {0.0, 0.0};
  int have_qp = 0;
  ves_status rc = nlb_start(st, s, x, lambda, lam_qp, &have_qp);
  if (rc != VES_OK) return rc;
  if (c->gate && st->rdiag > NLB_CONT_R) return VES_ERR_DOMAIN; /* to the continuation */
  c->gate = 0;
  if (!*last && c->one_phase && st->rdiag <= NLB_ONE_PHASE_R) *last = 1, c->promoted = 1;
  if (!*last) tol = NLB_TOL1, ctol_rel = NLB_CTOL1;
  double ctol[2];
  nlb_scales(st, x, lambda, tgt, tol, ctol_rel, lam_qp, have_qp, ctol);
  memset(st->u, 0, (size_t)n * sizeof(double)); /* u = 0 is x_start */

  nlopt_opt opt = nlopt_create(NLOPT_AUGLAG, (unsigned)n);
  nlopt_opt local = nlopt_create(NLOPT_LD_LBFGS, (unsigned)n);
  ves_status out = VES_ERR_SOLVER;
  double F = 0.0;
  int maxeval = st->opt.max_iter > INT_MAX / NLB_EVALS_PER_ITER
                    ? INT_MAX
                    : NLB_EVALS_PER_ITER * st->opt.max_iter;
  maxeval = maxeval > c->f_evals ? maxeval - c->f_evals : 1;
  if (!opt || !local) {
    out = VES_ERR_ALLOC;
    goto done;
  }
  c->opt = opt;
  c->cached = 0; /* a new factor, root and scales */
  if (nlopt_set_ftol_rel(local, 0.0) < 0 || nlopt_set_xtol_rel(local, tol) < 0 ||
      nlopt_set_local_optimizer(opt, local) < 0 ||
      nlopt_set_min_objective(opt, nlb_objective, c) < 0 || nlopt_set_ftol_rel(opt, 0.0) < 0 ||
      nlopt_set_xtol_rel(opt, sqrt(tol)) < 0 || nlopt_set_maxeval(opt, maxeval) < 0)
    goto done;
  /* NLopt may accept an algorithm and reject its constraints (LD_MMA with
   * equalities, then optimizing unconstrained): check the return. */
  if (m > 0 && nlopt_add_equality_mconstraint(opt, (unsigned)m, nlb_constraints, c, ctol) < 0)
    goto done;

  ves_step_eager_gradients(s, 1); /* every point NLopt evaluates gets its gradient */
  *r = nlopt_optimize(opt, st->u, &F);
  ves_step_eager_gradients(s, 0);
  nlb_x_of_u(c, st->u);
  memcpy(x, c->x, (size_t)n * sizeof(double));
  if (c->reason != VES_OK) {
    out = c->reason;
    goto done;
  }
  out = nlb_status(*r);
done:
  if (out == VES_OK || out == VES_MAXITER) {
    /* AUGLAG's verdict is not enough: check feasibility here, and return
     * least-squares multipliers. */
    ves_status e = nlb_finish(st, s, x, m, tgt, lambda, viol);
    if (e != VES_OK)
      out = e;
    else if (out == VES_OK && !(*viol <= ctol_rel))
      out = VES_ERR_NOCONV;
  }
  nlopt_destroy(local);
  nlopt_destroy(opt);
  return out;
}

/* The phases of one solve from x (in/out) at the step's current dt, with
 * multipliers lam (in/out), to tolerances tol and ctol: a first phase to
 * the loose NLB_TOL1 in the metric of the start, then the last one in the
 * metric of the Hessian where the first ended (the banner); with check,
 * the first-order test against gS (below). *r, *viol: the last phase's. */
static ves_status nlb_direct(nlb_state *st, ves_step *s, double *x, double lam[2],
                             const double *tgt, double tol, double ctol, int check, double gS,
                             nlopt_result *r, double *viol) {
  ves_status out = VES_OK;
  const int phases = NLB_TOL1 > tol ? 2 : 1;
  st->ctx.reason = VES_OK; /* a domain stop of an earlier solve is that solve's */
  for (int ph = 0, last = 0; ph < phases && out == VES_OK && !last; ph++) {
    last = ph == phases - 1;
    out = nlb_phase(st, s, x, lam, tgt, tol, ctol, &last, r, viol);
    if (!last && (out == VES_ERR_NOCONV || out == VES_MAXITER)) out = VES_OK; /* go on */
  }
  /* AUGLAG reports success also when L-BFGS could not move (every trial
   * point refused as outside the domain): the first-order conditions are
   * checked here, as newton's (max |grad f + J^T lambda| <= max(tol S, N),
   * S = max of |grad f(x_start)| and |J^T lambda|, N the rounding floor),
   * NLB_KKT_SLACK times looser: a test against a step that did not move
   * (residual ~ S), not of accuracy, which is L-BFGS's test in the metric of
   * the factor (2.9e-6 S at dt* 1e-4, 1.3e-8 S at 1, 0.8 S for the start
   * point of a dt* 1e4 step; docs/results.md, "Robustness at large Δt"). */
  if (check && out == VES_OK &&
      !(st->kkt <= NLB_KKT_SLACK * fmax(tol * fmax(gS, st->jtl), st->noise)))
    out = VES_ERR_NOCONV;
  return out;
}

/* The continuation in dt after the direct solve at dt failed: x (in:
 * x_start; out: the answer) and lam (in: the multipliers handed in). The
 * objective's dt is lowered (ves_step_set_dt: y^n, K and the targets stay)
 * by NLB_CONT_DOWN_FACTOR from x_start until a solve converges (at most
 * NLB_CONT_DOWN factors; a stage before the last is skipped where M at
 * x_start is not positive definite, since no metric is exact there), then
 * raised by NLB_CONT_FACTOR from each converged answer towards dt, the
 * multipliers scaled with dt (a tension times dt), the factor shrunk to its
 * square root after a failed stage; the last stage is the step itself at
 * the requested tolerances. The answer is the step's own KKT point: only
 * the path to it changes. The step's dt is set back before returning
 * (docs/results.md, "Robustness at large Δt"). */
static ves_status nlb_continue(nlb_state *st, ves_step *s, double *x, double lam[2],
                               const double *tgt, double dt, double gS, nlopt_result *r,
                               double *viol) {
  const int n = st->n;
  double *xs = malloc((size_t)n * sizeof *xs), *xk = malloc((size_t)n * sizeof *xk);
  ves_status out = xs && xk ? VES_OK : VES_ERR_ALLOC;
  double dk = dt, lam_in[2] = {lam[0], lam[1]}, lk[2] = {lam[0], lam[1]};
  if (out == VES_OK) memcpy(xs, x, (size_t)n * sizeof *xs);
  /* down: the largest dt / NLB_CONT_DOWN_FACTOR^j from x_start that converges */
  int ok = 0;
  for (int j = 1; j <= NLB_CONT_DOWN && out == VES_OK && !ok; j++) {
    dk = dt / pow(NLB_CONT_DOWN_FACTOR, j);
    memcpy(xk, xs, (size_t)n * sizeof *xk);
    lk[0] = lam_in[0] * dk / dt, lk[1] = lam_in[1] * dk / dt; /* lambda ~ dt (tension) */
    if ((out = ves_step_set_dt(s, dk)) != VES_OK) break;
    st->ctx.need_pd = j < NLB_CONT_DOWN; /* the last one: whatever M is */
    ves_status e = nlb_direct(st, s, xk, lk, tgt, NLB_TOL1, NLB_CTOL1, 0, gS, r, viol);
    st->ctx.need_pd = 0;
    if (e == VES_OK)
      ok = 1;
    else if (e != VES_ERR_DOMAIN && e != VES_ERR_NOCONV && e != VES_MAXITER)
      out = e;
  }
  if (out == VES_OK && !ok) out = VES_ERR_DOMAIN;
  /* up: from the last converged (dk, xk) towards dt by factors f, f shrunk
   * to its square root after a failure (down to NLB_CONT_MIN) */
  double f = NLB_CONT_FACTOR;
  while (out == VES_OK && dk < dt) {
    const double dn = fmin(dt, dk * f), ln[2] = {lk[0] * dn / dk, lk[1] * dn / dk};
    const int last = dn == dt;
    double xn_lam[2] = {ln[0], ln[1]};
    memcpy(x, xk, (size_t)n * sizeof *x);
    if ((out = ves_step_set_dt(s, dn)) != VES_OK) break;
    ves_status e =
        last ? nlb_direct(st, s, x, xn_lam, tgt, st->opt.tol, st->opt.ctol, 1, gS, r, viol)
             : nlb_direct(st, s, x, xn_lam, tgt, NLB_TOL1, NLB_CTOL1, 0, gS, r, viol);
    if (e == VES_OK) {
      memcpy(xk, x, (size_t)n * sizeof *xk);
      dk = dn, lk[0] = xn_lam[0], lk[1] = xn_lam[1];
    } else if (e == VES_ERR_DOMAIN || e == VES_ERR_NOCONV || e == VES_MAXITER) {
      f = sqrt(f);
      if (f < NLB_CONT_MIN) out = e;
    } else
      out = e;
  }
  const ves_status back = ves_step_set_dt(s, dt);
  if (out == VES_OK) out = back;
  if (out == VES_OK) lam[0] = lk[0], lam[1] = lk[1];
  free(xs), free(xk);
  return out;
}

/* One step: the direct solve from x_start, again in two phases when a
 * promoted single phase stalled, and the continuation in dt when the direct
 * solve left the domain or its start is beyond NLB_CONT_R (the robustness
 * problem's direct solve fails at r = 4e4 and converges at 4e3;
 * docs/results.md, "Robustness at large Δt"). */
static ves_status nlb_solve(void *state, ves_step *s, double *x, double *lambda,
                            ves_backend_stats *stats) {
  VES_CHECK(state && s && x, VES_ERR_ARG);
  nlb_state *st = state;
  double t0 = ves_wall_seconds();
  ves_backend_stats zero = {0};
  if (stats) *stats = zero;
  VES_CALL(nlb_alloc(st, s));
  int n = st->n, m = ves_step_ncon(s);
  VES_CHECK(m >= 0 && m <= 2 && (m == 0 || lambda), VES_ERR_ARG);
  const ves_step_params *par = ves_step_get_params(s);
  VES_CHECK(par != NULL, VES_ERR_ARG);
  const double dt = par->dt;
  nlb_ctx *c = &st->ctx;
  *c = (nlb_ctx){.s = s,
                 .n = n,
                 .m = m,
                 .C = st->C,
                 .xs = st->xs,
                 .x = st->x,
                 .g = st->g,
                 .J = st->J,
                 .B = st->B,
                 .uc = st->uc,
                 .reason = VES_OK};
  double tgt[2];
  VES_CHECK(ves_step_get_targets(s, tgt) == m, VES_ERR_INTERNAL);

  /* S of the first-order test: the largest force at x_start at the step's dt */
  double f0, gS = 0.0;
  ves_status out = ves_step_eval_f(s, x, &f0);
  if (out == VES_OK) out = ves_step_eval_grad(s, x, st->g);
  for (int j = 0; j < n && out == VES_OK; j++) gS = fmax(gS, fabs(st->g[j]));
  nlopt_result r = NLOPT_FAILURE;
  double viol = HUGE_VAL, lam[2] = {m > 0 ? lambda[0] : 0.0, m > 1 ? lambda[1] : 0.0};
  double *xs = out == VES_OK ? malloc((size_t)n * sizeof *xs) : NULL;
  if (out == VES_OK && !xs) out = VES_ERR_ALLOC;
  const int admissible = out == VES_OK; /* x_start itself (else nothing to continue from) */
  if (out == VES_OK) {
    memcpy(xs, x, (size_t)n * sizeof *xs);
    c->gate = 1, c->one_phase = 1;
    out = nlb_direct(st, s, x, lam, tgt, st->opt.tol, st->opt.ctol, 1, gS, &r, &viol);
    c->gate = 0;
  }
  /* A near-quadratic step that one phase did not solve (L-BFGS stalls on
   * the rounding of f from some warm starts: 2 steps of the default
   * relaxation): again from x_start in two phases. */
  if (c->promoted && (out == VES_ERR_NOCONV || out == VES_MAXITER)) {
    memcpy(x, xs, (size_t)n * sizeof *x);
    lam[0] = m > 0 ? lambda[0] : 0.0, lam[1] = m > 1 ? lambda[1] : 0.0;
    c->one_phase = 0, c->reason = VES_OK;
    out = nlb_direct(st, s, x, lam, tgt, st->opt.tol, st->opt.ctol, 1, gS, &r, &viol);
  }
  c->one_phase = 0;
  /* A step too long for L-BFGS from x_start (its line search left the
   * domain): the continuation in dt, from x_start again. Other failures (a
   * stall, the evaluation limit) go back to the integrator, which halves dt. */
  if (admissible && out == VES_ERR_DOMAIN) {
    memcpy(x, xs, (size_t)n * sizeof *x);
    lam[0] = m > 0 ? lambda[0] : 0.0, lam[1] = m > 1 ? lambda[1] : 0.0;
    c->reason = VES_OK;
    out = nlb_continue(st, s, x, lam, tgt, dt, gS, &r, &viol);
  }
  free(xs);
  if (out == VES_OK || out == VES_MAXITER)
    for (int i = 0; i < m; i++) lambda[i] = lam[i];
  if (stats) {
    stats->iterations = c->outer > c->phases * (m > 0) ? c->outer - c->phases * (m > 0) : 0;
    stats->f_evals = c->f_evals + 1;
    stats->g_evals = c->g_evals;
    stats->h_evals = c->h_evals;
    stats->violation = viol;
    stats->seconds = ves_wall_seconds() - t0;
    stats->solver_status = (int)r;
    stats->limit = out == VES_MAXITER ? VES_LIMIT_ITER : VES_LIMIT_NONE; /* its budget */
  }
  return out;
}

const ves_backend_type ves_backend_nlopt = {"nlopt", nlb_create, nlb_solve, nlb_destroy, 0, 1};
