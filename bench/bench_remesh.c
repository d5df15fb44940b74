/* vesica — remeshing benchmark: a problem run twice
 * with the same integrator, once without remeshing and once remeshed every
 * N accepted steps (remesh.h), printing each remeshing (nodes before and
 * after, dE*, dA/A, dV/V before the correction, the correction, the
 * interface's displacement, seconds) and the two energy trajectories at the
 * same times (the runs take the same steps only while dt is the same; the
 * comparison is at the unremeshed run's times, the remeshed run's E*
 * interpolated linearly in t).
 *
 *   bench_remesh [PROBLEM.ini] [--every N] [--steps M] [--set section.key=value]...
 * ([remesh] every overrides --every; [remesh] cond_max and det_min apply too.)
 *
 * Output: one '#' line per remeshing, then a table t, E*(plain), E*(remeshed),
 * difference, |A/A0 - 1|, |V/V0 - 1| of the remeshed run, and a summary. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_common.h"
#include "app/problem.h"
#include "ves/setup.h"

#define MAXS 100000

typedef struct {
  int n;
  double t[MAXS], E[MAXS], A[MAXS], V[MAXS];
  double seconds;
  int remeshings;
} traj;

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static int run(const ves_config *cfg, int every, long max_steps, traj *tr) {
  char err[512];
  ves_setup *su = NULL;
  if (ves_problem_setup_create(cfg, VES_PHI0_L2, &su, err, sizeof err) != VES_OK) {
    fprintf(stderr, "setup: %s\n", err);
    return 1;
  }
  ves_problem_params pp; /* as vesica run maps the problem file */
  ves_problem_params_from_config(cfg, &pp);
  ves_sim *sim = NULL;
  if (ves_sim_create(su->model, pp.backend, &pp.bopt, &pp.ip, &sim) != VES_OK) {
    fprintf(stderr, "sim_create failed\n");
    return 1;
  }
  ves_remesh_policy pol = pp.remesh_policy;
  pol.every = every;
  if (every > 0 || pol.cond_max > 0 || pol.det_min > 0) ves_sim_set_remesh(sim, &pp.discret, &pol);
  double A0, V0;
  ves_sim_initial(sim, &tr->E[0], &A0, &V0);
  tr->t[0] = 0, tr->A[0] = A0, tr->V[0] = V0, tr->n = 1;
  const double t0 = now();
  ves_step_report rep;
  ves_status st;
  while (tr->n < MAXS && tr->n <= max_steps && (st = ves_sim_step(sim, &rep)) == VES_OK) {
    tr->t[tr->n] = rep.t, tr->E[tr->n] = rep.E, tr->A[tr->n] = rep.A, tr->V[tr->n] = rep.V;
    if (rep.remeshed) {
      const ves_remesh_info *in = &rep.remesh;
      printf("# step %ld t* %.4g remesh: nodes %d -> %d, points %d -> %d, E* %.7f -> %.7f "
             "(dE* %+.2e), dA/A %+.2e, dV/V %+.2e; correction max|d|/h %.2e in %d it, "
             "residuals A %.1e V %.1e; E* after %.7f; interface moved max %.2e mean %.2e; "
             "%.2f s\n",
             rep.step, rep.t, in->n_old, in->n_new, in->nq_old, in->nq_new, in->E_old, in->E_proj,
             in->dE, in->dA, in->dV, in->corr_max, in->corr_iter, in->res_A, in->res_V, in->E,
             in->disp_max, in->disp_mean, in->seconds);
      tr->E[tr->n] = in->E; /* the state the run continues from */
    } else if (rep.remesh_status != VES_OK) {
      printf("# step %ld: remeshing failed: %s\n", rep.step, ves_status_str(rep.remesh_status));
    }
    tr->n++;
  }
  tr->seconds = now() - t0;
  tr->remeshings = ves_sim_remeshings(sim);
  ves_sim_destroy(&sim);
  ves_setup_destroy(&su);
  return 0;
}

static double interp(const traj *tr, double t) {
  int k = 1;
  while (k < tr->n - 1 && tr->t[k] < t) k++;
  const double f = (t - tr->t[k - 1]) / (tr->t[k] - tr->t[k - 1]);
  return tr->E[k - 1] + fmin(1.0, fmax(0.0, f)) * (tr->E[k] - tr->E[k - 1]);
}

int main(int argc, char **argv) {
  /* without arguments (make bench): the oblate relaxation at eps 0.1 (band 3:
   * 4 eps would exceed the rim's radius of curvature, 0.35) */
  const char *problem = argc > 1 && argv[1][0] != '-' ? argv[1] : "problems/oblate.ini";
  int every = 10;
  long steps = MAXS;
  const char *set[64];
  int nset = 0;
  if (argc < 2) set[nset++] = "geometry.epsilon=0.1", set[nset++] = "geometry.band=3";
  for (int i = argc > 1 && argv[1][0] != '-' ? 2 : 1; i < argc; i++) {
    if (!strcmp(argv[i], "--every") && i + 1 < argc)
      every = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--steps") && i + 1 < argc)
      steps = atol(argv[++i]);
    else if (!strcmp(argv[i], "--set") && i + 1 < argc && nset < 64)
      set[nset++] = argv[++i];
    else {
      fprintf(stderr, "bench_remesh: unknown argument %s\n", argv[i]);
      return 2;
    }
  }
  ves_config cfg;
  char err[512];
  if (ves_config_load(problem, nset, set, &cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "%s\n", err);
    return 2;
  }
  if (cfg.remesh_every > 0) every = cfg.remesh_every;
  static traj plain, re;
  ves_config cfg0 = cfg; /* the plain run: no remeshing at all */
  cfg0.remesh_cond_max = 0, cfg0.remesh_det_min = 0;
  if (run(&cfg0, 0, steps, &plain) || run(&cfg, every, steps, &re)) return 1;
  printf("# t*  E*(plain)  E*(remeshed every %d)  difference  |A/A0-1|  |V/V0-1| (remeshed)\n",
         every);
  double dmax = 0, amax = 0, vmax = 0;
  for (int k = 0; k < re.n; k++) {
    amax = fmax(amax, fabs(re.A[k] / re.A[0] - 1)), vmax = fmax(vmax, fabs(re.V[k] / re.V[0] - 1));
  }
  for (int k = 0; k < plain.n; k++) {
    if (plain.t[k] > re.t[re.n - 1]) break;
    const double e = interp(&re, plain.t[k]), d = e - plain.E[k];
    dmax = fmax(dmax, fabs(d));
    printf("%.6g %.8f %.8f %+.3e\n", plain.t[k], plain.E[k], e, d);
  }
  printf("# plain: %d steps, %.1f s; remeshed: %d steps, %d remeshings, %.1f s\n", plain.n - 1,
         plain.seconds, re.n - 1, re.remeshings, re.seconds);
  printf("# max |E*(remeshed) - E*(plain)| = %.3e (relative %.3e); remeshed run: max |A/A0 - 1| = "
         "%.2e, max |V/V0 - 1| = %.2e\n",
         dmax, dmax / plain.E[plain.n - 1], amax, vmax);
  return 0;
}
