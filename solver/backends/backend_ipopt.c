/* vesica — the "ipopt" backend: the step problem (step.h) solved by Ipopt
 * 3.11 (C interface, MUMPS inside) with the exact sparse Hessian of the
 * Lagrangian sigma_f f + lambda^T c and warm-started multipliers
 * (docs/design.md, "Backends"). Scaling: f by 1 / max_i |df/dx_i(x_start)|,
 * so "tol" is relative to the initial force, c_i by 1 / target_i;
 * "constr_viol_tol" = ctol min(A0, V_target) (Ipopt's acceptable default
 * 1e-2 would accept visibly wrong areas) and the final max |c_i| / target_i
 * is checked again here. A solve is also converged when the scaled dual
 * infeasibility is within the rounding floor eps_mach (|H| |x|)_inf of the
 * last Hessian and the constraints within ctol (newton's test; the
 * intermediate callback stops Ipopt there). Every point's values come with
 * their gradients in one model pass (ves_step_eager_gradients: Ipopt's
 * trial points are nearly always accepted), the constraint Jacobian goes
 * as dense rows (exact; a sparse pattern guessed from x0 could miss
 * entries later), and create keeps the heap (ves_mem_keep_heap) so that
 * the MUMPS workspace Ipopt allocates at every factorization is reused
 * (docs/results.md, "Performance and its scaling"). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <coin/IpStdCInterface.h>

#include "ves/backend.h"
#include "core/clock_impl.h"
#include "core/mem_impl.h"

/* Ipopt's representation of an infinite bound ("nlp_lower_bound_inf"). */
#define IPOPT_INF 2e19

/* What the callbacks share during one IpoptSolve (the typed context). */
typedef struct {
  ves_step *s;          /* the step problem (borrowed) */
  int n, m;             /* nvar, ncon */
  int f_evals, g_evals; /* objective / gradient evaluations */
  int c_evals, j_evals; /* constraint / Jacobian evaluations */
  int h_evals;          /* Hessian assemblies */
  int iterations;       /* last iter_count seen by the intermediate callback */
  int domain_errors;    /* evaluations refused as outside the domain */
  double noise;         /* eps_mach (|H| |x|)_inf of the last Hessian (0: none yet) */
  double viol;          /* max |c_i| / target_i at the last constraint evaluation */
  double tgt[2];        /* the constraints' targets */
  double ctol;          /* ves_backend_options.ctol */
  int floor_stop;       /* 1: stopped by the intermediate callback at the rounding floor */
  double *acc;          /* n scratch for |H| |x| */
  int first_domain;     /* 1 when the very first evaluation was refused */
  int n_calls;          /* evaluations so far (to recognise the first) */
  ves_status error;     /* first non-domain error met in a callback */
} ipopt_ctx;

/* Backend state: one IpoptProblem per step-problem size. */
typedef struct {
  IpoptProblem prob;       /* NULL until built */
  int n, m, nnz_h;         /* the sizes prob was built for */
  ves_backend_options opt; /* copied options */
  double *mult_x_L;        /* n zeros: Ipopt needs them even without bounds */
  double *mult_x_U;        /* n zeros */
  double *grad;            /* n scratch (initial gradient, for the objective scale) */
  double *acc;             /* n scratch (|H| |x|, the rounding floor) */
  double g[2];             /* final constraint values */
  ipopt_ctx ctx;           /* the callback context */
} ipopt_state;

/* Record a callback's status: Ipopt only sees TRUE/FALSE. A domain error
 * (det F <= 0) makes Ipopt cut its line-search step back; any other error is
 * kept to be reported after the solve. */
static Bool ipopt_map(ipopt_ctx *c, ves_status st) {
  c->n_calls++;
  if (st == VES_OK) return TRUE;
  if (st == VES_ERR_DOMAIN) {
    c->domain_errors++;
    if (c->n_calls == 1) c->first_domain = 1;
  } else if (c->error == VES_OK) {
    c->error = st;
  }
  return FALSE;
}

/* f(x) */
static Bool ipopt_eval_f(Index n, Number *x, Bool new_x, Number *f, UserDataPtr ud) {
  ipopt_ctx *c = ud;
  (void)n, (void)new_x;
  c->f_evals++;
  return ipopt_map(c, ves_step_eval_f(c->s, x, f));
}

/* grad f(x) */
static Bool ipopt_eval_grad_f(Index n, Number *x, Bool new_x, Number *g, UserDataPtr ud) {
  ipopt_ctx *c = ud;
  (void)n, (void)new_x;
  c->g_evals++;
  return ipopt_map(c, ves_step_eval_grad(c->s, x, g));
}

/* c(x) = (A - A0, V - V_target) */
static Bool ipopt_eval_g(Index n, Number *x, Bool new_x, Index m, Number *g, UserDataPtr ud) {
  ipopt_ctx *c = ud;
  (void)n, (void)new_x;
  if (m == 0) return TRUE;
  c->c_evals++;
  ves_status st = ves_step_eval_c(c->s, x, g);
  if (st == VES_OK) {
    c->viol = 0.0;
    for (Index i = 0; i < m; i++) c->viol = fmax(c->viol, fabs(g[i]) / c->tgt[i]);
  }
  return ipopt_map(c, st);
}

/* Jacobian of c: dense rows, entry k = i n + j is dc_i/dx_j (row-major, the
 * layout of ves_step_eval_jac). */
static Bool ipopt_eval_jac_g(Index n, Number *x, Bool new_x, Index m, Index nele, Index *irow,
                             Index *jcol, Number *val, UserDataPtr ud) {
  ipopt_ctx *c = ud;
  (void)new_x, (void)nele;
  if (m == 0) return TRUE;
  if (val == NULL) {
    for (Index i = 0; i < m; i++)
      for (Index j = 0; j < n; j++) irow[i * n + j] = i, jcol[i * n + j] = j;
    return TRUE;
  }
  c->j_evals++;
  return ipopt_map(c, ves_step_eval_jac(c->s, x, val));
}

/* Lower triangle of obj_factor (K + dt Hess E) + sum lambda_i Hess c_i. */
static Bool ipopt_eval_h(Index n, Number *x, Bool new_x, Number obj_factor, Index m, Number *lambda,
                         Bool new_lambda, Index nele, Index *irow, Index *jcol, Number *val,
                         UserDataPtr ud) {
  ipopt_ctx *c = ud;
  (void)n, (void)new_x, (void)new_lambda, (void)nele;
  if (val == NULL) {
    ves_step_hess_structure(c->s, irow, jcol);
    return TRUE;
  }
  c->h_evals++;
  ves_status st = ves_step_eval_hess(c->s, x, obj_factor, m > 0 ? lambda : NULL, val);
  if (st == VES_OK) c->noise = ves_step_hess_floor(c->s, x, val, c->acc); /* the banner */
  return ipopt_map(c, st);
}

/* Once per iteration, before Ipopt's convergence test: remember the count
 * (Ipopt 3.11's C interface has no other access to it), and stop at the
 * rounding floor (the banner). inf_du is the scaled dual infeasibility
 * |obj_scale grad f + J^T lambda|_inf. */
static Bool ipopt_intermediate(Index alg_mod, Index iter, Number obj, Number inf_pr, Number inf_du,
                               Number mu, Number d_norm, Number reg, Number alpha_du,
                               Number alpha_pr, Index ls_trials, UserDataPtr ud) {
  ipopt_ctx *c = ud;
  (void)obj, (void)inf_pr, (void)mu, (void)d_norm, (void)reg;
  (void)alpha_du, (void)alpha_pr, (void)ls_trials;
  c->iterations = iter;
  /* regular mode only: in the restoration phase (alg_mod 1) inf_du is the
   * restoration problem's */
  if (alg_mod == 0 && iter > 0 && c->noise > 0 && inf_du <= c->noise && c->viol <= c->ctol) {
    c->floor_stop = 1;
    return FALSE;
  }
  return TRUE;
}

/* (Re)build the IpoptProblem for the current sizes of s and set the options
 * that do not depend on the step (tolerances depending on the targets and on
 * the start are set in solve). */
static ves_status ipopt_build(ipopt_state *st, ves_step *s) {
  int n = ves_step_nvar(s), m = ves_step_ncon(s), nnz = ves_step_hess_nnz(s);
  VES_CHECK(n > 0 && m >= 0 && m <= 2 && nnz >= 0, VES_ERR_ARG);
  if (st->prob && st->n == n && st->m == m && st->nnz_h == nnz) return VES_OK;
  if (st->prob) FreeIpoptProblem(st->prob), st->prob = NULL;
  if (st->n != n) {
    free(st->mult_x_L), free(st->mult_x_U), free(st->grad), free(st->acc);
    st->mult_x_L = calloc((size_t)n, sizeof(double));
    st->mult_x_U = calloc((size_t)n, sizeof(double));
    st->grad = malloc((size_t)n * sizeof(double));
    st->acc = malloc((size_t)n * sizeof(double));
    st->n = 0;
    VES_CHECK(st->mult_x_L && st->mult_x_U && st->grad && st->acc, VES_ERR_ALLOC);
  }
  double *xl = malloc((size_t)n * sizeof(double)), *xu = malloc((size_t)n * sizeof(double));
  double gl[2] = {0.0, 0.0}, gu[2] = {0.0, 0.0}; /* equality constraints c = 0 */
  if (!xl || !xu) {
    free(xl), free(xu);
    return VES_ERR_ALLOC;
  }
  for (int i = 0; i < n; i++) xl[i] = -IPOPT_INF, xu[i] = IPOPT_INF; /* no bounds */
  st->prob = CreateIpoptProblem(n, xl, xu, m, gl, gu, m * n, nnz, 0, ipopt_eval_f, ipopt_eval_g,
                                ipopt_eval_grad_f, ipopt_eval_jac_g, ipopt_eval_h);
  free(xl), free(xu);
  VES_CHECK(st->prob != NULL, VES_ERR_SOLVER);
  st->n = n, st->m = m, st->nnz_h = nnz;

  const ves_backend_options *o = &st->opt;
  int ok = 1;
  ok &= AddIpoptStrOption(st->prob, (char *)"option_file_name", (char *)"");
  if (o->verbose <= 0) {
    ok &= AddIpoptIntOption(st->prob, (char *)"print_level", 0);
    ok &= AddIpoptStrOption(st->prob, (char *)"sb", (char *)"yes");
  } else {
    ok &= AddIpoptIntOption(st->prob, (char *)"print_level",
                            o->verbose + 4 < 12 ? o->verbose + 4 : 12);
  }
  ok &= AddIpoptNumOption(st->prob, (char *)"tol", o->tol);
  ok &= AddIpoptNumOption(st->prob, (char *)"acceptable_tol", 100.0 * o->tol);
  ok &= AddIpoptIntOption(st->prob, (char *)"max_iter", o->max_iter);
  ok &= AddIpoptStrOption(st->prob, (char *)"hessian_approximation", (char *)"exact");
  ok &= AddIpoptStrOption(st->prob, (char *)"mu_strategy", (char *)"adaptive");
  ok &= AddIpoptStrOption(st->prob, (char *)"nlp_scaling_method", (char *)"user-scaling");
  ok &= SetIntermediateCallback(st->prob, ipopt_intermediate);
  VES_CHECK(ok, VES_ERR_SOLVER);
  return VES_OK;
}

static void ipopt_destroy(void **state) {
  if (!state || !*state) return;
  ipopt_state *st = *state;
  if (st->prob) FreeIpoptProblem(st->prob);
  free(st->mult_x_L), free(st->mult_x_U), free(st->grad), free(st->acc);
  free(st);
  *state = NULL;
}

static ves_status ipopt_create(const ves_backend_options *opt, ves_step *s, void **state) {
  VES_CHECK(opt && s && state, VES_ERR_ARG);
  VES_CHECK(opt->tol > 0 && opt->ctol > 0 && opt->max_iter >= 0, VES_ERR_ARG);
  ves_mem_keep_heap(); /* the banner */
  ipopt_state *st = calloc(1, sizeof *st);
  VES_CHECK(st, VES_ERR_ALLOC);
  st->opt = *opt;
  ves_status rc = ipopt_build(st, s);
  if (rc != VES_OK) {
    void *p = st;
    ipopt_destroy(&p);
    return rc;
  }
  *state = st;
  return VES_OK;
}

/* Ipopt's verdict as a status: a solve is VES_OK only with the violation we
 * measured (viol) within ctol; the stops without a solution VES_ERR_NOCONV,
 * a broken problem or option VES_ERR_SOLVER. */
static ves_status ipopt_status(enum ApplicationReturnStatus ars, double viol, double ctol) {
  switch (ars) {
  case Solve_Succeeded:
  case Solved_To_Acceptable_Level:
    return viol <= ctol ? VES_OK : VES_ERR_NOCONV;
  case Maximum_Iterations_Exceeded:
    return VES_MAXITER;
  case Infeasible_Problem_Detected:
  case Search_Direction_Becomes_Too_Small:
  case Diverging_Iterates:
  case User_Requested_Stop:
  case Feasible_Point_Found:
  case Restoration_Failed:
  case Error_In_Step_Computation:
  case Maximum_CpuTime_Exceeded:
  case Invalid_Number_Detected:
    return VES_ERR_NOCONV;
  default: /* Not_Enough_Degrees_Of_Freedom, Invalid_Problem_Definition,
            * Invalid_Option, exceptions, memory, internal errors */
    return VES_ERR_SOLVER;
  }
}

/* The solve's scales and options: the objective by its initial force
 * (1 / max |st->grad|), the constraints by their targets tgt, so tol and
 * ctol act as relative tolerances (the banner); a warm start only with
 * multipliers to start from (all zero means none). */
static ves_status ipopt_scale(ipopt_state *st, const double *lambda, const double tgt[2]) {
  const int n = st->n, m = st->m;
  double gmax = 0.0;
  for (int i = 0; i < n; i++) gmax = fmax(gmax, fabs(st->grad[i]));
  double obj_scale = gmax > 0.0 ? 1.0 / gmax : 1.0;
  double g_scale[2] = {1.0 / fmax(tgt[0], 1e-300), 1.0 / fmax(tgt[1], 1e-300)};
  double tmin = m == 2 ? fmin(tgt[0], tgt[1]) : tgt[0];
  int ok = SetIpoptProblemScaling(st->prob, obj_scale, NULL, m > 0 ? g_scale : NULL);
  ok &= AddIpoptNumOption(st->prob, (char *)"constr_viol_tol", st->opt.ctol * tmin);
  ok &= AddIpoptNumOption(st->prob, (char *)"acceptable_constr_viol_tol", st->opt.ctol * tmin);
  /* Warm start only with multipliers to start from (all zero means none). */
  int warm = 0;
  for (int i = 0; i < m; i++) warm |= lambda[i] != 0.0;
  ok &= AddIpoptStrOption(st->prob, (char *)"warm_start_init_point", (char *)(warm ? "yes" : "no"));
  VES_CHECK(ok, VES_ERR_SOLVER);
  return VES_OK;
}

static ves_status ipopt_solve(void *state, ves_step *s, double *x, double *lambda,
                              ves_backend_stats *stats) {
  VES_CHECK(state && s && x, VES_ERR_ARG);
  ipopt_state *st = state;
  double t0 = ves_wall_seconds();
  VES_CALL(ipopt_build(st, s)); /* a no-op unless the sizes changed */
  int n = st->n, m = st->m;
  VES_CHECK(m == 0 || lambda != NULL, VES_ERR_ARG);
  double tgt[2] = {1.0, 1.0};
  VES_CHECK(ves_step_get_targets(s, tgt) == m, VES_ERR_INTERNAL);
  ves_backend_stats zero = {0};
  if (stats) *stats = zero;

  ipopt_ctx *c = &st->ctx;
  *c = (ipopt_ctx){.s = s,
                   .n = n,
                   .m = m,
                   .error = VES_OK,
                   .tgt = {tgt[0], tgt[1]},
                   .ctol = st->opt.ctol,
                   .viol = HUGE_VAL,
                   .acc = st->acc};

  /* the initial force, the objective's scale */
  ves_status rc = ves_step_eval_grad(s, x, st->grad);
  c->g_evals++;
  if (rc != VES_OK) {
    if (stats) stats->g_evals = 1, stats->seconds = ves_wall_seconds() - t0;
    return rc;
  }
  VES_CALL(ipopt_scale(st, lambda, tgt));

  double mult_g[2] = {0.0, 0.0}, obj = 0.0;
  for (int i = 0; i < m; i++) mult_g[i] = lambda[i];
  memset(st->mult_x_L, 0, (size_t)n * sizeof(double));
  memset(st->mult_x_U, 0, (size_t)n * sizeof(double));
  ves_step_eager_gradients(s, 1); /* the banner */
  enum ApplicationReturnStatus ars =
      IpoptSolve(st->prob, x, st->g, &obj, mult_g, st->mult_x_L, st->mult_x_U, c);
  ves_step_eager_gradients(s, 0);

  /* Final violation, measured by us at the returned x. */
  double viol = HUGE_VAL;
  if (m == 0) {
    viol = 0.0;
  } else if (ves_step_eval_c(s, x, st->g) == VES_OK) {
    viol = 0.0;
    for (int i = 0; i < m; i++) viol = fmax(viol, fabs(st->g[i]) / tgt[i]);
  }

  if (ars == User_Requested_Stop && c->floor_stop) ars = Solve_Succeeded; /* at the floor */
  ves_status out = ipopt_status(ars, viol, st->opt.ctol);
  /* A failure rooted in our callbacks is reported as such: an error raised
   * there, or a start outside the domain. */
  if (out < 0 && c->error != VES_OK)
    out = c->error;
  else if (out < 0 && c->first_domain)
    out = VES_ERR_DOMAIN;
  if (out == VES_OK || out == VES_MAXITER)
    for (int i = 0; i < m; i++) lambda[i] = mult_g[i];

  if (stats) {
    stats->iterations = c->iterations;
    stats->f_evals = c->f_evals;
    stats->g_evals = c->g_evals;
    stats->h_evals = c->h_evals;
    stats->violation = viol;
    stats->seconds = ves_wall_seconds() - t0;
    stats->solver_status = (int)ars;
    stats->limit = out == VES_MAXITER ? VES_LIMIT_ITER : VES_LIMIT_NONE;
  }
  return out;
}

const ves_backend_type ves_backend_ipopt = {"ipopt", ipopt_create, ipopt_solve, ipopt_destroy, 0,
                                            0};
