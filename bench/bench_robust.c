/* vesica — robustness of the step solvers: for every backend, one
 * step of constant dt from the initial out-of-equilibrium oblate vesicle
 * (problems/oblate.ini) for dt* = 1e-4 ... 1e2, without halving (dt_min =
 * dt). A step counts as converged when the backend reports convergence and
 * the integrator accepts it (energy not raised, constraints within ctol).
 * Prints one row per (backend, dt): status, iterations, gradient and Hessian
 * evaluations, wall seconds, E* after the step; then per backend the largest
 * dt that converged.
 *
 * Usage: bench_robust [CONFIG] [--set section.key=value]... [--backends b,...]
 *        [--dts dt,dt,...]
 * Default: problems/oblate.ini at eps = 0.1, band 3 (1,483 nodes), solver.max_iter
 * 100 (the config default, 40, is a time loop's budget per attempt), all four
 * backends. Threads: OMP_NUM_THREADS. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ves/backend.h"
#include "app/config.h"
#include "app/problem.h"
#include "ves/integrate.h"
#include "ves/setup.h"
#include "bench_common.h"
#include "app/blas_core_impl.h"
#include "core/clock_impl.h"

#define MAX_LIST 32
#define MAX_SET 32

/* CPU seconds of this process (all threads): the measure that a shared
 * machine does not inflate. */
static double cpu_seconds(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Kept whole (86 lines): the option parsing, the runs and the table they print, in order. */
int main(int argc, char **argv) {
  ves_blas_core_fix(argv); /* OpenBLAS's kernels (blas_core_impl.h) */
  setvbuf(stdout, NULL, _IOLBF, 0);
  const char *path = "problems/oblate.ini", *set[MAX_SET];
  int nset = 0;
  set[nset++] = "geometry.epsilon=0.1";
  set[nset++] = "geometry.band=3";
  set[nset++] = "solver.max_iter=100"; /* one step's reach, not a time loop's budget */
  set[nset++] = "solver.max_builds=0"; /* (newton: dt* 100 needs 30 builds) */
  double dts[MAX_LIST] = {1e-4, 1e-3, 1e-2, 1e-1, 1, 10, 100};
  int ndt = 7;
  char blist[256] = "newton,ipopt,nlopt,euler";
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
    if (!strcmp(a, "--set") && v && nset < MAX_SET)
      set[nset++] = v, i++;
    else if (!strcmp(a, "--backends") && v)
      snprintf(blist, sizeof blist, "%s", v), i++;
    else if (!strcmp(a, "--dts") && v) {
      if ((ndt = bench_parse_list(v, dts, MAX_LIST)) < 0) return 2;
      i++;
    } else if (a[0] != '-')
      path = a;
    else {
      fprintf(stderr, "bench_robust: bad argument '%s' (see bench/bench_robust.c)\n", a);
      return 2;
    }
  }
  ves_config cfg;
  char err[1024] = "";
  if (ves_config_load(path, nset, set, &cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "bench_robust: %s\n", err);
    return 2;
  }
  ves_setup *s = NULL;
  if (ves_problem_setup_create(&cfg, VES_PHI0_L2, &s, err, sizeof err) != VES_OK) {
    fprintf(stderr, "bench_robust: %s: %s\n", path, err);
    return 3;
  }
  printf("# %s eps %g band %g: %d nodes, %d quadrature points; tol %g ctol %g max_iter %d\n", path,
         cfg.epsilon, cfg.band, s->nodes->n, s->quad->nq, cfg.tol, cfg.ctol, cfg.max_iter);
  printf("| backend | dt* | status | iterations | grad | hess | seconds | CPU s | E* after |\n"
         "|---|---|---|---|---|---|---|---|---|\n");
  char summary[1024] = "";
  for (char *b = strtok(blist, ","); b; b = strtok(NULL, ",")) {
    const ves_backend_type *bk = ves_backend_find(b);
    if (!bk) {
      fprintf(stderr, "bench_robust: unknown backend '%s'\n", b);
      return 2;
    }
    double largest = 0;
    for (int i = 0; i < ndt; i++) {
      ves_integrate_params ip;
      bench_constant_params(&cfg, dts[i], dts[i], &ip);
      ves_backend_options bo;
      bench_backend_options(&cfg, &bo);
      ves_sim *sim = NULL;
      ves_status st = ves_sim_create(s->model, bk, &bo, &ip, &sim);
      if (st != VES_OK) {
        fprintf(stderr, "bench_robust: %s: %s\n", b, ves_status_str(st));
        return 3;
      }
      ves_step_report rep;
      double E0, t0 = ves_wall_seconds(), c0 = cpu_seconds();
      ves_sim_initial(sim, &E0, NULL, NULL);
      st = ves_sim_step(sim, &rep);
      double sec = ves_wall_seconds() - t0, cpu = cpu_seconds() - c0;
      /* explicit Euler is not checked by the integrator: a step that raises
       * E* is its instability, not a solution */
      const int ok = st == VES_OK && rep.E <= E0;
      printf("| %s | %.0e | %s | %d | %d | %d | %.2f | %.2f | %.9f |\n", b, dts[i],
             ok             ? "converged"
             : st == VES_OK ? "E* rose"
                            : ves_status_str(rep.solve_status),
             rep.stats.iterations, rep.stats.g_evals, rep.stats.h_evals, sec, cpu,
             st == VES_OK ? rep.E : NAN);
      if (ok) largest = dts[i];
      ves_sim_destroy(&sim);
    }
    size_t len = strlen(summary);
    snprintf(summary + len, sizeof summary - len, "# %s: largest converged dt* %g\n", b, largest);
  }
  fputs(summary, stdout);
  ves_setup_destroy(&s);
  return 0;
}
