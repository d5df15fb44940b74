/* vesica — explicit forward Euler backend (the paper's comparison, Table 1):
 * one step of size dt of the gradient flow with constraints, mobility K(y^n),
 *
 *   [ K  J^T ] [ u ]   [ -dt grad E(y^n) ]
 *   [ J  0   ] [ m ] = [  0              ],   x = x0 + u,  u = dt ydot,
 *
 * i.e. K ydot = -grad E + J^T sigma, J ydot = 0 with sigma = -m / dt. The
 * multipliers returned are m = -dt sigma: the convention of the other
 * backends (Lagrangian f + lambda^T c), since the Euler step is the
 * linearization of the VTI step at x0 (K d + dt grad E + J^T lambda = 0,
 * J d = 0), so they agree with Newton's to O(dt). The constraints are held
 * only to first order: the drift |c(x)| = O(dt^2) is reported as the violation.
 * K is SPD on the free dofs, so the KKT matrix has exactly 2 negative pivots
 * (kkt.h); no inertia correction is made. The input x is
 * ignored (the step starts from y^n); iterations = 1, g_evals = 1 (grad E and
 * J at y^n), f_evals = 1 (values at the new state, for the violation),
 * h_evals = 0. docs/design.md, "Backends". */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ves/kkt.h"
#include "ves/backend.h"
#include "core/clock_impl.h"

typedef struct {
  ves_kkt kkt; /* KKT structure and factorization */
  int nvar;    /* free dofs */
  double *J;   /* VES_KKT_NROWS nvar constraint Jacobian at x0 */
  double *sol; /* nvar + VES_KKT_NROWS right-hand side / solution */
} euler_state;

static void euler_destroy(void **state) {
  if (!state || !*state) return;
  euler_state *w = *state;
  ves_kkt_destroy(&w->kkt);
  free(w->J), free(w->sol);
  free(w);
  *state = NULL;
}

static ves_status euler_create(const ves_backend_options *opt, ves_step *s, void **state) {
  VES_CHECK(state, VES_ERR_ARG);
  *state = NULL;
  VES_CHECK(opt && s, VES_ERR_ARG);
  euler_state *w = calloc(1, sizeof *w);
  if (!w) return VES_ERR_ALLOC;
  w->nvar = ves_step_nvar(s);
  ves_status st = ves_kkt_create(s, opt->factor_single, &w->kkt);
  if (st != VES_OK) {
    free(w);
    return st;
  }
  w->J = calloc(VES_KKT_NROWS * (size_t)w->nvar, sizeof *w->J);
  w->sol = malloc(((size_t)w->nvar + VES_KKT_NROWS) * sizeof *w->sol);
  *state = w;
  if (!w->J || !w->sol) {
    euler_destroy(state);
    return VES_ERR_ALLOC;
  }
  return VES_OK;
}

/* x = x0 + u with [K J^T; J 0][u; m] = [-dt grad E(x0); 0]. */
static ves_status euler_solve(void *state, ves_step *s, double *x, double *lambda,
                              ves_backend_stats *stt) {
  VES_CHECK(state && s && x && stt, VES_ERR_ARG);
  memset(stt, 0, sizeof *stt);
  const double t0 = ves_wall_seconds();
  euler_state *w = state;
  const ves_step_params *par = ves_step_get_params(s);
  const double *K = ves_step_K(s);
  VES_CHECK(par && K, VES_ERR_ARG); /* ves_step_set not called */
  const int nv = w->nvar, ncon = ves_step_ncon(s);
  VES_CHECK(nv == ves_step_nvar(s), VES_ERR_ARG);
  VES_CHECK(ncon == 0 || lambda, VES_ERR_ARG);
  ves_step_x0(s, x);
  stt->g_evals = 1;
  VES_CALL(ves_step_eval_energy_grad(s, x, NULL, w->sol)); /* dt grad E(y^n) */
  VES_CALL(ves_step_eval_jac(s, x, w->J));
  ves_kkt_fill(&w->kkt, K, 0.0, NULL, w->J, ncon);
  ves_status st = ves_kkt_factor(&w->kkt);
  stt->factorizations = 1;
  if (st != VES_OK || w->kkt.neg != VES_KKT_NROWS) {
    stt->solver_status = st != VES_OK ? (int)st : w->kkt.neg;
    stt->seconds = ves_wall_seconds() - t0;
    return VES_ERR_SOLVER; /* K not SPD or J rank deficient: no Euler step */
  }
  for (int j = 0; j < nv; j++) w->sol[j] = -w->sol[j];
  for (int i = 0; i < VES_KKT_NROWS; i++) w->sol[nv + i] = 0.0;
  if ((st = ves_kkt_solve(&w->kkt, w->sol)) != VES_OK) return VES_ERR_SOLVER;
  for (int j = 0; j < nv; j++) x[j] += w->sol[j]; /* x = x0 + dt ydot */
  for (int i = 0; i < ncon; i++) lambda[i] = w->sol[nv + i];
  stt->iterations = 1;
  /* constraint drift at the new state */
  double c[VES_KKT_NROWS] = {0, 0}, tgt[VES_KKT_NROWS] = {1, 1};
  ves_step_get_targets(s, tgt);
  stt->f_evals = 1;
  st = ves_step_eval_c(s, x, c);
  if (st != VES_OK) {
    stt->seconds = ves_wall_seconds() - t0;
    return st; /* the explicit step left the admissible set */
  }
  for (int i = 0; i < ncon; i++) stt->violation = fmax(stt->violation, fabs(c[i]) / tgt[i]);
  stt->solver_status = 0;
  stt->seconds = ves_wall_seconds() - t0;
  return VES_OK;
}

const ves_backend_type ves_backend_euler = {"euler", euler_create, euler_solve, euler_destroy, 1,
                                            0};
