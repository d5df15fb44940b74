/* vesica — the "nlopt" backend: one step problem (step.h) solved by NLopt 2.7's
 * augmented Lagrangian (NLOPT_AUGLAG) around limited-memory BFGS
 * (NLOPT_LD_LBFGS) (DESIGN.md §3). SLSQP is dense (useless at 1e4 variables)
 * and LD_MMA refuses equality constraints, so LBFGS is the sub-solver.
 *
 * Preconditioning by a change of variables (the part that decides whether it
 * converges at all). NLopt's LBFGS takes no preconditioner, so the problem is
 * handed to it in variables u with
 *     x = x_start + root L^{-T} u,      F(u) = f(x) / root^2,
 * where L L^T ~ M is an incomplete Cholesky factorization, IC(0) on the
 * Hessian pattern, of M = the Hessian of the Lagrangian at the start
 * (K + dt Hess E + lambda Hess c; K alone if that has a non-positive
 * diagonal), with a diagonal shift M + alpha diag(M), alpha = 0, 1e-3, 1e-2,
 * ... until it does not break down. The Hessian of F in u is then close to
 * the identity, and LBFGS's unit first step is close to a Newton step.
 * Measured on the 3.4k-dof test step (tests/test_backend.c, dt = 0.05):
 * with the variables scaled by the diagonal only (L = diag(M)^{1/2}) LBFGS
 * needed 3604 gradients (500 s) and still missed Ipopt's point by 7% of the
 * displacement (compile with -DNLB_DIAGONAL_ONLY to repeat); with no scaling
 * the gradient test fired at 4e-5 of the initial force (f_scale 1) and the
 * result was 47% off. With IC(0) (and the constraint scaling below):
 * 964 gradients, 17 outer iterations, 164 s, 1.2% of the displacement
 * (3e-6 of max |y|), multipliers to 1e-6. Ipopt: 3 iterations, 5 s, exact.
 * root: LBFGS (Luksan's code) stops on a fixed absolute test
 * max |dF/du_i| <= LBFGS_GTOL = 1e-8. The gradient in u is
 * root^-1 L^{-1} grad f, so root = tol * gmax / LBFGS_GTOL, gmax = the largest
 * component of L^{-1} grad f(x_start), turns it into the relative test
 * max |L^{-1} grad L| <= tol gmax, without changing the Hessian of F in u.
 *
 * Constraints: c_i(x) / target_i (A / A0 - 1, V / V_target - 1), each with
 * tolerance ctol, so AUGLAG's feasibility test is exactly the relative test of
 * ves_backend_options.
 * Stopping: no f tolerance (ftol_rel = 0: f contains dt E, whose roundoff
 * swamps the small decrease of one step); xtol_rel = tol on u for the LBFGS
 * sub-solves (their gradient test is the one that acts) and sqrt(tol) for
 * AUGLAG's outer iterates (with tol the outer loop ran 29 sub-solves without
 * gaining accuracy: the sub-solves' own noise); AUGLAG stops once feasible and
 * the outer iterate has settled, or when LBFGS fails (its line search limited
 * by roundoff near the solution). maxeval = NLB_EVALS_PER_ITER * max_iter
 * objective evaluations in all (a gradient method needs many more than a
 * Newton method). AUGLAG's verdict is not trusted: after the solve the
 * constraint violation is checked against ctol (VES_ERR_NOCONV if not met).
 * Domain errors (det F <= 0): NLopt has no "cut the step"; the objective
 * returns HUGE_VAL (and a zero gradient) so the line search backs off; after
 * NLB_DOMAIN_MAX consecutive refusals, or at the start, the solve is stopped
 * with nlopt_force_stop and VES_ERR_DOMAIN is returned.
 * Multipliers: AUGLAG restarts its own from zero at every call (lambda in is
 * used only for the Hessian of the preconditioner); lambda out is the
 * least-squares solution of grad f + J^T lambda = 0 at the solution.
 * Statistics: iterations = AUGLAG outer iterations (its objective calls
 * without a gradient, one per outer iteration after the first at the start);
 * f_evals, g_evals count objective and gradient evaluations; h_evals = 1 (the
 * Hessian for the preconditioner). */
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <nlopt.h>

#include "ves/backend.h"
#include "clock_impl.h"

#define NLB_EVALS_PER_ITER 100 /* maxeval = this * max_iter */
#define NLB_DOMAIN_MAX 30      /* consecutive domain errors before giving up */
#define LBFGS_GTOL 1e-8        /* Luksan's fixed gradient tolerance (NLopt plis.c) */
#define NLB_IC_SHIFTS 8        /* shifts alpha = 0, 1e-3, ..., 1e3 tried */

/* Lower-triangular factor in compressed rows, the diagonal last in each row. */
typedef struct {
  int n;
  int *ptr;   /* n + 1 */
  int *col;   /* ptr[n], ascending in each row */
  double *a;  /* ptr[n] values of M (summed duplicates) */
  double *l;  /* ptr[n] values of L */
  int *map;   /* nnz: triplet k -> position in col (or -1 above the diagonal) */
} nlb_ic;

/* The typed context of the callbacks. */
typedef struct {
  ves_step *s;          /* the step problem (borrowed) */
  nlopt_opt opt;        /* the outer optimizer (for nlopt_force_stop) */
  int n, m;             /* nvar, ncon */
  const nlb_ic *L;      /* the factor of the change of variables */
  const double *xs;     /* n the start x_start */
  double root;          /* x = x_start + root L^{-T} u */
  double f_scale;       /* root^2 */
  double *x;            /* n scratch: x(u) */
  double *g;            /* n scratch: grad f at x */
  double *J;            /* 2 n scratch Jacobian */
  double tgt[2];        /* constraint scales sigma_i (header comment) */
  double lam0[2];       /* multipliers folded into the objective (warm start) */
  int f_evals, g_evals; /* objective evaluations, with gradient */
  int outer;            /* objective calls without gradient (AUGLAG's own) */
  int domain_run;       /* consecutive domain errors */
  ves_status reason;    /* why the solve was forced to stop (VES_OK: not) */
} nlb_ctx;

typedef struct {
  ves_backend_options opt; /* copied options */
  int n, nnz;              /* sizes the arrays are for */
  double *x, *g, *J, *u, *xs, *hval; /* scratch, u, start, Hessian values */
  int *hi, *hj;            /* Hessian structure (lower triplets) */
  nlb_ic L;                /* preconditioner */
  nlb_ctx ctx;
} nlb_state;

/* ---- IC(0) ------------------------------------------------------------- */

static void nlb_ic_free(nlb_ic *L) {
  free(L->ptr), free(L->col), free(L->a), free(L->l), free(L->map);
  memset(L, 0, sizeof *L);
}

/* Pattern of the lower triplets (irow >= jcol) in compressed rows, columns
 * ascending, duplicates merged; map[k] the slot of triplet k. */
static ves_status nlb_ic_pattern(nlb_ic *L, int n, int nnz, const int *hi, const int *hj) {
  L->n = n;
  L->ptr = calloc((size_t)n + 1, sizeof(int));
  L->map = malloc((size_t)(nnz > 0 ? nnz : 1) * sizeof(int));
  int *cnt = calloc((size_t)n + 1, sizeof(int));
  int *tmp = malloc((size_t)(nnz + n + 1) * sizeof(int));
  ves_status rc = VES_ERR_ALLOC;
  if (!L->ptr || !L->map || !cnt || !tmp) goto out;
  /* rows with the diagonal forced in: count, fill, sort, merge */
  for (int k = 0; k < nnz; k++) {
    if (hi[k] < 0 || hi[k] >= n || hj[k] < 0 || hj[k] > hi[k]) {
      rc = VES_ERR_ARG;
      goto out;
    }
    cnt[hi[k] + 1]++;
  }
  for (int i = 0; i < n; i++) cnt[i + 1] += cnt[i] + 1; /* + 1: the diagonal */
  int *pos = L->ptr;                                     /* fill positions */
  for (int i = 0; i < n; i++) pos[i] = cnt[i], tmp[pos[i]++] = i;
  for (int k = 0; k < nnz; k++) tmp[pos[hi[k]]++] = hj[k];
  int w = 0;
  for (int i = 0; i < n; i++) {
    int b = cnt[i], e = cnt[i + 1];
    for (int p = b + 1; p < e; p++) /* insertion sort (rows are short) */
      for (int q = p; q > b && tmp[q - 1] > tmp[q]; q--) {
        int t = tmp[q];
        tmp[q] = tmp[q - 1], tmp[q - 1] = t;
      }
    L->ptr[i] = w;
    for (int p = b; p < e; p++)
      if (p == b || tmp[p] != tmp[p - 1]) tmp[w++] = tmp[p];
  }
  L->ptr[n] = w;
  L->col = malloc((size_t)w * sizeof(int));
  L->a = malloc((size_t)w * sizeof(double));
  L->l = malloc((size_t)w * sizeof(double));
  if (!L->col || !L->a || !L->l) goto out;
  memcpy(L->col, tmp, (size_t)w * sizeof(int));
  for (int k = 0; k < nnz; k++) { /* binary search of the slot */
    int lo = L->ptr[hi[k]], hi_ = L->ptr[hi[k] + 1] - 1;
    while (lo < hi_) {
      int mid = (lo + hi_) / 2;
      if (L->col[mid] < hj[k]) lo = mid + 1;
      else hi_ = mid;
    }
    L->map[k] = lo;
  }
  rc = VES_OK;
out:
  free(cnt), free(tmp);
  if (rc != VES_OK) nlb_ic_free(L);
  return rc;
}

/* L L^T = M + alpha diag(M) on the pattern of M (row-wise IC(0)):
 * L_ij = (M_ij - sum_{k<j} L_ik L_jk) / L_jj,  L_ii = sqrt(M_ii(1 + alpha) - sum L_ik^2).
 * Returns 0 on success, -1 on a breakdown (a pivot <= 0). */
static int nlb_ic_factor(nlb_ic *L, double alpha) {
  const int *ptr = L->ptr, *col = L->col;
  for (int i = 0; i < L->n; i++) {
    int bi = ptr[i], ei = ptr[i + 1] - 1; /* ei: the diagonal */
    for (int p = bi; p <= ei; p++) {
      int j = col[p];
      double sum = L->a[p] * (j == i ? 1.0 + alpha : 1.0);
      /* sparse dot of rows i and j over columns < j */
      int q = bi, r = ptr[j], er = ptr[j + 1] - 1;
      while (q < p && r < er) {
        if (col[q] == col[r]) sum -= L->l[q++] * L->l[r++];
        else if (col[q] < col[r]) q++;
        else r++;
      }
      if (j < i) {
        L->l[p] = sum / L->l[er];
      } else {
        if (!(sum > 0.0) || !isfinite(sum)) return -1;
        L->l[p] = sqrt(sum);
      }
    }
  }
  return 0;
}

/* w = L^{-1} v (forward substitution, in place). */
static void nlb_ic_lsolve(const nlb_ic *L, double *v) {
  for (int i = 0; i < L->n; i++) {
    int e = L->ptr[i + 1] - 1;
    double s = v[i];
    for (int p = L->ptr[i]; p < e; p++) s -= L->l[p] * v[L->col[p]];
    v[i] = s / L->l[e];
  }
}

/* w = L^{-T} v (backward substitution, in place). */
static void nlb_ic_ltsolve(const nlb_ic *L, double *v) {
  for (int i = L->n - 1; i >= 0; i--) {
    int e = L->ptr[i + 1] - 1;
    v[i] /= L->l[e];
    for (int p = L->ptr[i]; p < e; p++) v[L->col[p]] -= L->l[p] * v[i];
  }
}

/* ---- callbacks ---------------------------------------------------------- */

/* Stop the solve for reason st (kept in the context). */
static void nlb_stop(nlb_ctx *c, ves_status st) {
  if (c->reason == VES_OK) c->reason = st;
  nlopt_force_stop(c->opt);
}

/* c->x = x_start + root L^{-T} u */
static void nlb_x_of_u(nlb_ctx *c, const double *u) {
  for (int i = 0; i < c->n; i++) c->x[i] = c->root * u[i];
  nlb_ic_ltsolve(c->L, c->x);
  for (int i = 0; i < c->n; i++) c->x[i] += c->xs[i];
}

/* F(u) = f(x(u)) / root^2 and grad_u F = L^{-1} grad f / root. */
static double nlb_objective(unsigned n, const double *u, double *grad, void *data) {
  nlb_ctx *c = data;
  nlb_x_of_u(c, u);
  double f = 0.0;
  ves_status st = ves_step_eval_f(c->s, c->x, &f);
  c->f_evals++;
  if (grad) {
    c->g_evals++;
    if (st == VES_OK) st = ves_step_eval_grad(c->s, c->x, grad);
  } else {
    c->outer++;
  }
  if (st == VES_OK && c->m > 0 && (c->lam0[0] != 0.0 || c->lam0[1] != 0.0)) {
    /* f + lam0^T c (same minimizer on c = 0) */
    double cv[2] = {0.0, 0.0};
    st = ves_step_eval_c(c->s, c->x, cv);
    if (st == VES_OK && grad) st = ves_step_eval_jac(c->s, c->x, c->J);
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
  if (grad) {
    nlb_ic_lsolve(c->L, grad);
    for (unsigned i = 0; i < n; i++) grad[i] /= c->root;
  }
  return f / c->f_scale;
}

/* r_i(u) = c_i(x(u)) / sigma_i, grad[i n + .] = L^{-1} grad c_i root / sigma_i. */
static void nlb_constraints(unsigned m, double *r, unsigned n, const double *u, double *grad,
                            void *data) {
  nlb_ctx *c = data;
  nlb_x_of_u(c, u);
  ves_status st = ves_step_eval_c(c->s, c->x, r);
  if (st == VES_OK && grad) st = ves_step_eval_jac(c->s, c->x, grad);
  if (st != VES_OK) {
    /* The objective accepted this point just before; stop rather than guess. */
    for (unsigned i = 0; i < m; i++) r[i] = HUGE_VAL;
    nlb_stop(c, st);
    return;
  }
  for (unsigned i = 0; i < m; i++) {
    r[i] /= c->tgt[i];
    if (grad) {
      nlb_ic_lsolve(c->L, grad + (size_t)i * n);
      for (unsigned j = 0; j < n; j++) grad[i * n + j] *= c->root / c->tgt[i];
    }
  }
}

/* ---- the backend -------------------------------------------------------- */

static void nlb_free_arrays(nlb_state *st) {
  free(st->x), free(st->g), free(st->J), free(st->u), free(st->xs), free(st->hval);
  free(st->hi), free(st->hj);
  st->x = st->g = st->J = st->u = st->xs = st->hval = NULL;
  st->hi = st->hj = NULL;
  nlb_ic_free(&st->L);
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
  if (!st->x || !st->g || !st->J || !st->u || !st->xs || !st->hval || !st->hi || !st->hj) {
    nlb_free_arrays(st);
    return VES_ERR_ALLOC;
  }
  ves_step_hess_structure(s, st->hi, st->hj);
  ves_status rc = nlb_ic_pattern(&st->L, n, nnz, st->hi, st->hj);
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

/* Factor the preconditioner at x (header comment): M = Hessian of the
 * Lagrangian, or K if that has a non-positive diagonal entry. */
static ves_status nlb_precondition(nlb_state *st, ves_step *s, const double *x,
                                   const double *lambda) {
  nlb_ic *L = &st->L;
  const double *K = ves_step_K(s);
  VES_CHECK(K != NULL, VES_ERR_ARG);
  VES_CALL(ves_step_eval_hess(s, x, 1.0, lambda, st->hval));
  for (int pass = 0; pass < 2; pass++) {
    const double *v = pass == 0 ? st->hval : K;
    memset(L->a, 0, (size_t)L->ptr[L->n] * sizeof(double));
    for (int k = 0; k < st->nnz; k++) L->a[L->map[k]] += v[k];
    int posdiag = 1;
    for (int i = 0; i < L->n; i++) posdiag &= L->a[L->ptr[i + 1] - 1] > 0.0;
#ifdef NLB_DIAGONAL_ONLY /* measurement: the diagonal scaling alone */
    for (int i = 0; i < L->n; i++)
      for (int p = L->ptr[i]; p < L->ptr[i + 1] - 1; p++) L->a[p] = 0.0;
#endif
    if (!posdiag) continue;
    double alpha = 0.0;
    for (int t = 0; t < NLB_IC_SHIFTS; t++, alpha = alpha == 0.0 ? 1e-3 : 10.0 * alpha)
      if (nlb_ic_factor(L, alpha) == 0) return VES_OK;
  }
  return VES_ERR_SINGULAR;
}

/* Least-squares multipliers: (J J^T) lambda = -J g, m <= 2. */
static void nlb_multipliers(int n, int m, const double *J, const double *g, double *lambda) {
  double a[2][2] = {{0, 0}, {0, 0}}, b[2] = {0, 0};
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
  nlb_ctx *c = &st->ctx;
  *c = (nlb_ctx){.s = s, .n = n, .m = m, .L = &st->L, .xs = st->xs, .x = st->x, .g = st->g,
                 .J = st->J, .reason = VES_OK};
  double tgt[2] = {1.0, 1.0};
  int k = 0;
  if (par->hold_area) tgt[k++] = fabs(par->A0);
  if (par->hold_volume) tgt[k++] = fabs(par->V_target);
  VES_CHECK(k == m, VES_ERR_INTERNAL);

  /* Start: its gradient and the preconditioner. */
  double f0;
  ves_status rc = ves_step_eval_f(s, x, &f0);
  if (rc == VES_OK) rc = ves_step_eval_grad(s, x, st->g);
  if (rc == VES_OK) rc = nlb_precondition(st, s, x, m > 0 ? lambda : NULL);
  if (rc != VES_OK) {
    if (stats) stats->f_evals = stats->g_evals = 1, stats->seconds = ves_wall_seconds() - t0;
    return rc;
  }
  memcpy(st->xs, x, (size_t)n * sizeof(double));
  nlb_ic_lsolve(&st->L, st->g); /* the gradient in u at root = 1 */
  double gmax = 0.0;
  for (int i = 0; i < n; i++) gmax = fmax(gmax, fabs(st->g[i]));
  c->root = gmax > 0.0 ? st->opt.tol * gmax / LBFGS_GTOL : 1.0;
  c->f_scale = c->root * c->root;
  /* Constraint scales: |grad_u r_i| = 1 at the start, so AUGLAG's penalty
   * rho |r|^2 / 2 (rho starts at 10) is on the scale of F's unit Hessian;
   * the tolerance of r_i is ctol target_i / sigma_i (relative ctol on c_i). */
  double ctol[2] = {st->opt.ctol, st->opt.ctol};
  if (m > 0) {
    rc = ves_step_eval_jac(s, x, st->J);
    if (rc != VES_OK) return rc;
  }
  for (int i = 0; i < m; i++) {
    double *Ji = st->J + (size_t)i * n, nrm = 0.0;
    nlb_ic_lsolve(&st->L, Ji);
    for (int j = 0; j < n; j++) nrm += Ji[j] * Ji[j];
    c->tgt[i] = nrm > 0.0 ? c->root * sqrt(nrm) : tgt[i];
    ctol[i] = st->opt.ctol * tgt[i] / c->tgt[i];
    c->lam0[i] = lambda[i];
  }
  memset(st->u, 0, (size_t)n * sizeof(double)); /* u = 0 is x_start */

  nlopt_opt opt = nlopt_create(NLOPT_AUGLAG, (unsigned)n);
  nlopt_opt local = nlopt_create(NLOPT_LD_LBFGS, (unsigned)n);
  nlopt_result r = NLOPT_FAILURE;
  ves_status out = VES_ERR_SOLVER;
  double F = 0.0;
  int maxeval = st->opt.max_iter > INT_MAX / NLB_EVALS_PER_ITER
                    ? INT_MAX
                    : NLB_EVALS_PER_ITER * st->opt.max_iter;
  if (!opt || !local) {
    out = VES_ERR_ALLOC;
    goto done;
  }
  c->opt = opt;
  if (nlopt_set_ftol_rel(local, 0.0) < 0 || nlopt_set_xtol_rel(local, st->opt.tol) < 0 ||
      nlopt_set_local_optimizer(opt, local) < 0 ||
      nlopt_set_min_objective(opt, nlb_objective, c) < 0 || nlopt_set_ftol_rel(opt, 0.0) < 0 ||
      nlopt_set_xtol_rel(opt, sqrt(st->opt.tol)) < 0 || nlopt_set_maxeval(opt, maxeval) < 0)
    goto done;
  /* NLopt may accept an algorithm and reject its constraints (LD_MMA with
   * equalities, then optimizing unconstrained): check the return. */
  if (m > 0 && nlopt_add_equality_mconstraint(opt, (unsigned)m, nlb_constraints, c, ctol) < 0)
    goto done;

  r = nlopt_optimize(opt, st->u, &F);
  nlb_x_of_u(c, st->u);
  memcpy(x, c->x, (size_t)n * sizeof(double));
  if (c->reason != VES_OK) {
    out = c->reason;
    goto done;
  }
  switch (r) {
  case NLOPT_SUCCESS:
  case NLOPT_STOPVAL_REACHED:
  case NLOPT_FTOL_REACHED:
  case NLOPT_XTOL_REACHED:
  case NLOPT_FAILURE: /* LBFGS's line search stalled on roundoff: judged below */
  case NLOPT_ROUNDOFF_LIMITED:
    out = VES_OK;
    break;
  case NLOPT_MAXEVAL_REACHED:
  case NLOPT_MAXTIME_REACHED:
    out = VES_MAXITER;
    break;
  case NLOPT_OUT_OF_MEMORY:
    out = VES_ERR_ALLOC;
    break;
  default: /* invalid arguments, a forced stop without a reason */
    out = VES_ERR_SOLVER;
    break;
  }

done:;
  double viol = HUGE_VAL;
  if (out == VES_OK || out == VES_MAXITER) {
    /* AUGLAG's verdict is not enough: check feasibility here, and return
     * least-squares multipliers. */
    double cv[2] = {0.0, 0.0};
    ves_status e = m > 0 ? ves_step_eval_c(s, x, cv) : VES_OK;
    if (e == VES_OK) e = ves_step_eval_grad(s, x, st->g);
    if (e == VES_OK && m > 0) e = ves_step_eval_jac(s, x, st->J);
    if (e != VES_OK) {
      out = e;
    } else {
      viol = 0.0;
      for (int i = 0; i < m; i++) viol = fmax(viol, fabs(cv[i]) / tgt[i]);
      if (m > 0) nlb_multipliers(n, m, st->J, st->g, lambda);
      if (out == VES_OK && !(viol <= st->opt.ctol)) out = VES_ERR_NOCONV;
    }
  }
  nlopt_destroy(local);
  nlopt_destroy(opt);
  if (stats) {
    stats->iterations = c->outer > 0 ? c->outer - (m > 0) : 0;
    stats->f_evals = c->f_evals + 1;
    stats->g_evals = c->g_evals + 1;
    stats->h_evals = 1;
    stats->violation = viol;
    stats->seconds = ves_wall_seconds() - t0;
    stats->solver_status = (int)r;
  }
  return out;
}

const ves_backend_type ves_backend_nlopt = {"nlopt", nlb_create, nlb_solve, nlb_destroy};
