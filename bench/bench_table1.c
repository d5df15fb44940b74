/* vesica — the paper's Table 1 (Sec. 4): variational time integration (VTI)
 * with constant steps against explicit forward Euler (FE) on a portion
 * [t1, t2] of the relaxation of the out-of-equilibrium oblate vesicle
 * (problems/oblate.ini, v = 0.9).
 *
 * All methods start from the same state at t1 = 1e-3, reached by a VTI run
 * (newton) with constant dt = t1 / 10 from t = 0, and run to t2 = 1.1e-2 with
 * constant steps (no halving: dt_min = dt, so a failed step ends the row).
 * For FE the candidate steps are tried from the largest down; a run is
 * stable when it reaches t2 with E* never rising by more than 1e-9 relative
 * in a step (the exact dynamics dissipates: a rise is the explicit scheme's
 * instability, which grows from there) and the first stable dt is reported
 * as FE's largest stable step (the rows of the unstable ones are printed
 * too, marked; the integrator rejects an energy-raising step, so an unstable
 * run usually ends as "step failed" at dt_min). With --fe-watch N (which
 * turns the integrator's energy check off for FE) an FE run does not stop at the first rise
 * but goes on for at most N steps, printing E* at every step, to tell a
 * growing instability from a rounding-level rise. With --fe-limit N the
 * stiffness of the state at t1 is computed first (ves_spectrum_stiffness, N
 * Lanczos steps): FE's linear stability limit 2 / mu_max, printed before the
 * table; --limit-only stops there.
 *
 * Columns: method, backend, dt*, E*(t1), E*(t2), steps, gradient and
 * Hessian evaluations (a Hessian = one assembly of the Hessian of E or of
 * the Lagrangian; FE assembles K every step, counted apart), backend
 * iterations, wall seconds, max |A/A0 - 1| and max |V/V0 - 1| over the run.
 *
 * Usage: bench_table1 [CONFIG] [--set section.key=value]... [--t1 T]
 *        [--t2 T] [--vti dt,dt,...] [--fe dt,dt,...] [--backends b,b,...]
 *        [--fe-watch N] [--fe-limit N [--limit-only]]
 * Default: problems/oblate.ini at eps = 0.02, h_band = 0.5 (docs/results.md,
 * "The paper's figures and tables", gives the command of the eps = 0.01 table). Threads:
 * OMP_NUM_THREADS. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ves/backend.h"
#include "app/config.h"
#include "app/problem.h"
#include "ves/integrate.h"
#include "ves/setup.h"
#include "ves/spectrum.h"
#include "ves/step.h"
#include "bench_common.h"
#include "app/blas_core_impl.h"
#include "core/clock_impl.h"

#define MAX_LIST 16
#define MAX_SET 32

/* One row of the table. */
typedef struct {
  const char *method, *backend;
  double dt, E1, E2;
  long steps, grad, hess, iters;
  double seconds, dA, dV;
  int stable; /* 1 reached t2 with E never rising; 0 otherwise */
  char why[96];
} row;

/* Run `backend` with constant dt from state (st0, y0) to t2. */
static ves_status run_row(ves_setup *s, const ves_config *cfg, const char *backend, double dt,
                          double t2, const ves_sim_state *st0, const double *y0, long watch,
                          row *r) {
  ves_integrate_params ip;
  ves_backend_options bo;
  bench_constant_params(cfg, dt, t2, &ip);
  bench_backend_options(cfg, &bo);
  if (watch) ip.check_energy = 0; /* follow the rise instead of rejecting it */
  ves_sim *sim = NULL;
  ves_status st = ves_sim_create(s->model, ves_backend_find(backend), &bo, &ip, &sim);
  if (st != VES_OK) return st;
  ves_sim_state ss = *st0;
  ss.dt = dt;
  ss.dt_prev = 0; /* every row starts from y0 alone (no predictor from the run before) */
  if ((st = ves_sim_set_state(sim, &ss, y0, NULL)) != VES_OK) {
    ves_sim_destroy(&sim);
    return st;
  }
  memset(r, 0, sizeof *r);
  r->backend = backend, r->dt = dt, r->E1 = st0->E / cfg->k, r->stable = 1;
  double Eprev = r->E1, t0 = ves_wall_seconds();
  ves_step_report rep;
  while ((st = ves_sim_step(sim, &rep)) == VES_OK) {
    r->steps++;
    r->grad += rep.stats.g_evals, r->hess += rep.stats.h_evals;
    r->iters += rep.stats.iterations;
    r->dA = fmax(r->dA, fabs(rep.A / st0->A0 - 1)), r->dV = fmax(r->dV, fabs(rep.V / st0->V0 - 1));
    if (watch)
      printf("# %s dt %g step %ld t* %.6g E* %.12f\n", backend, dt, r->steps, rep.t, rep.E);
    if (!(rep.E <= Eprev + 1e-9 * fabs(Eprev)) && r->stable) {
      r->stable = 0;
      snprintf(r->why, sizeof r->why, "E* rose at step %ld (t* = %.4g)", r->steps, rep.t);
      if (!watch) {
        Eprev = rep.E;
        break;
      }
    }
    Eprev = rep.E;
    if (watch && r->steps >= watch) break;
  }
  if (st < 0) {
    r->stable = 0;
    snprintf(r->why, sizeof r->why, "step %ld failed: %s", r->steps + 1, ves_status_str(st));
  }
  r->E2 = Eprev;
  r->seconds = ves_wall_seconds() - t0;
  ves_sim_destroy(&sim);
  return VES_OK;
}

static void print_row(const row *r) {
  printf("| %s | %s | %.1e | %.6f | %.6f | %ld | %ld | %ld | %ld | %.1f | %.1e | %.1e | %s |\n",
         r->method, r->backend, r->dt, r->E1, r->E2, r->steps, r->grad, r->hess, r->iters,
         r->seconds, r->dA, r->dV, r->stable ? "stable" : r->why);
  fflush(stdout);
}

/* Kept whole (147 lines): the option parsing, the runs and the table they print, in order. */
int main(int argc, char **argv) {
  ves_blas_core_fix(argv); /* OpenBLAS's kernels (blas_core_impl.h) */
  setvbuf(stdout, NULL, _IOLBF, 0);
  const char *path = "problems/oblate.ini", *set[MAX_SET];
  int nset = 0;
  set[nset++] = "geometry.epsilon=0.02";
  double t1 = 1e-3, t2 = 1.1e-2, vti[MAX_LIST] = {1e-2, 1e-3, 1e-4},
         fe[MAX_LIST] = {1e-4, 5e-5, 2e-5, 1e-5, 5e-6, 2e-6, 1e-6};
  int nvti = 3, nfe = 7, nb = 1;
  long watch = 0;
  int lanczos = 0, limit_only = 0;
  char blist[256] = "newton";
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--set") && v && nset < MAX_SET)
      set[nset++] = v, i++;
    else if (!strcmp(a, "--t1") && v)
      t1 = atof(v), i++;
    else if (!strcmp(a, "--t2") && v)
      t2 = atof(v), i++;
    else if (!strcmp(a, "--vti") && v)
      nvti = bench_parse_list(v, vti, MAX_LIST), i++;
    else if (!strcmp(a, "--fe") && v)
      nfe = bench_parse_list(v, fe, MAX_LIST), i++;
    else if (!strcmp(a, "--fe-watch") && v)
      watch = atol(v), i++;
    else if (!strcmp(a, "--fe-limit") && v)
      lanczos = atoi(v), i++;
    else if (!strcmp(a, "--limit-only"))
      limit_only = 1;
    else if (!strcmp(a, "--backends") && v)
      snprintf(blist, sizeof blist, "%s", v), i++;
    else if (a[0] != '-')
      path = a;
    else {
      fprintf(stderr, "bench_table1: bad argument '%s' (see the header of bench/bench_table1.c)\n",
              a);
      return 2;
    }
  }
  if (nvti < 0 || nfe < 0 || !(t1 > 0 && t2 > t1)) {
    fprintf(stderr, "bench_table1: bad --vti/--fe list or times\n");
    return 2;
  }
  const char *backends[8];
  nb = 0;
  for (char *tok = strtok(blist, ","); tok && nb < 8; tok = strtok(NULL, ",")) {
    if (!ves_backend_find(tok) || !strcmp(tok, "euler")) {
      fprintf(stderr, "bench_table1: --backends: '%s' is not a VTI backend\n", tok);
      return 2;
    }
    backends[nb++] = tok;
  }
  ves_config cfg;
  char err[1024] = "";
  if (ves_config_load(path, nset, set, &cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "bench_table1: %s\n", err);
    return 2;
  }
  ves_setup *s = NULL;
  double ts = ves_wall_seconds();
  if (ves_problem_setup_create(&cfg, VES_PHI0_L2, &s, err, sizeof err) != VES_OK) {
    fprintf(stderr, "bench_table1: %s: %s\n", path, err);
    return 3;
  }
  printf("# %s eps %g h_band %g band %g: %d nodes, %d quadrature points, setup %.1f s\n", path,
         cfg.epsilon, cfg.h_band, cfg.band, s->nodes->n, s->quad->nq, ves_wall_seconds() - ts);

  /* the common start: VTI (newton), constant dt = t1/10, from 0 to t1 */
  ves_integrate_params ip;
  ves_backend_options bo;
  bench_constant_params(&cfg, t1 / 10, t1, &ip);
  ip.dt_min = 1e-12;
  bench_backend_options(&cfg, &bo);
  ves_sim *sim = NULL;
  ves_status st = ves_sim_create(s->model, &ves_backend_newton, &bo, &ip, &sim);
  double E0 = 0, *y1 = malloc(2 * (size_t)s->nodes->n * sizeof *y1);
  if (st != VES_OK || !y1) {
    fprintf(stderr, "bench_table1: start: %s\n", ves_status_str(st));
    return 3;
  }
  ves_sim_initial(sim, &E0, NULL, NULL);
  ves_step_report rep;
  double t0 = ves_wall_seconds();
  while ((st = ves_sim_step(sim, &rep)) == VES_OK) continue;
  if (st < 0) {
    fprintf(stderr, "bench_table1: start run failed: %s\n", ves_status_str(st));
    return 3;
  }
  ves_sim_state st1;
  ves_sim_get_state(sim, &st1, y1);
  ves_sim_destroy(&sim);
  printf("# start: E*(0) = %.6f, E*(t1 = %g) = %.6f (newton, dt %g, %.1f s)\n", E0, t1,
         st1.E / cfg.k, t1 / 10, ves_wall_seconds() - t0);
  if (lanczos > 0) {
    /* K^-1 Hess L at y(t1), the constraint forces of the last step per unit time */
    ves_step *sp = NULL;
    ves_step_params par = {.dt = st1.dt,
                           .hold_area = cfg.area,
                           .A0 = st1.A0,
                           .hold_volume = cfg.volume,
                           .V_target = st1.V0};
    double sigma[2] = {st1.lambda[0] / st1.dt, st1.lambda[1] / st1.dt}, mu = 0, res = 0;
    t0 = ves_wall_seconds();
    st = ves_step_create(s->model, &sp);
    if (st == VES_OK) st = ves_step_set(sp, y1, &par);
    if (st == VES_OK) st = ves_spectrum_stiffness(sp, sigma, lanczos, &mu, &res);
    ves_step_destroy(&sp);
    if (st != VES_OK) {
      fprintf(stderr, "bench_table1: --fe-limit: %s\n", ves_status_str(st));
      return 3;
    }
    printf("# FE stability at t1: mu_max = %.6e 1/t* (%d Lanczos steps, Ritz residual %.1e, "
           "%.1f s): FE stable for dt* <= 2/mu_max = %.4e\n",
           mu, lanczos, res, ves_wall_seconds() - t0, 2 / mu);
    if (limit_only) {
      free(y1);
      ves_setup_destroy(&s);
      return 0;
    }
  }
  printf("| method | backend | dt* | E*(t1) | E*(t2) | steps | grad | hess | iterations | "
         "seconds | max dA/A0 | max dV/V0 | status |\n|---|---|---|---|---|---|---|---|---|---|"
         "---|---|---|\n");
  row r;
  for (int b = 0; b < nb; b++)
    for (int i = 0; i < nvti; i++) {
      if ((st = run_row(s, &cfg, backends[b], vti[i], t2, &st1, y1, 0, &r)) != VES_OK) {
        fprintf(stderr, "bench_table1: %s: %s\n", backends[b], ves_status_str(st));
        return 3;
      }
      r.method = "VTI";
      print_row(&r);
    }
  for (int i = 0; i < nfe; i++) {
    if ((st = run_row(s, &cfg, "euler", fe[i], t2, &st1, y1, watch, &r)) != VES_OK) {
      fprintf(stderr, "bench_table1: euler: %s\n", ves_status_str(st));
      return 3;
    }
    r.method = "FE";
    print_row(&r);
    if (r.stable) break; /* the largest stable step */
  }
  free(y1);
  ves_setup_destroy(&s);
  return 0;
}
