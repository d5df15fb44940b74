/* vesica — how the cost of a run scales with the interface width: for one
 * problem file at geometry.epsilon = EPS, in one process, the sizes (nodes,
 * quadrature points, mean LME neighbours), the setup's wall time and its
 * parts, one model evaluation (E, A, V and their gradients), one Hessian, one
 * K assembly, the step's matrix (stepH: K(y^n) + dt Hess E + ... in one
 * assembly, what a Newton step builds), the MUMPS analysis and one numeric factorization of the
 * Newton KKT matrix, the mean wall time of the first NSTEPS accepted steps of the newton backend
 * with the problem's own time-stepping parameters (as `vesica run` builds them), and at the end the
 * process CPU time and peak resident memory. The single evaluations are the median of 3.
 *
 * Usage: bench_scale PROBLEM.ini EPS [NSTEPS]   (NSTEPS default 3)
 * Prints one tab-separated row on stdout; with BENCH_HEADER=1 a header line
 * starting with '#' first. Without arguments (as `make bench` runs every
 * bench_*): problems/oblate.ini at eps 0.04, header included.
 * Threads: OMP_NUM_THREADS (model assembly) and OPENBLAS_NUM_THREADS (MUMPS's
 * dense kernels), both reported in the row, with OpenBLAS's kernel family.
 * One row per process, so that peak_MB belongs to that row: bench/scale.sh
 * runs the table (make bench BENCH_ONLY=scale). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "ves/backend.h"
#include "app/config.h"
#include "ves/integrate.h"
#include "ves/model.h"
#include "app/problem.h"
#include "ves/setup.h"
#include "ves/step.h"
#include "ves/kkt.h"
#include "app/blas_core_impl.h"

#define NREP 3 /* repeats of each single evaluation (the median is reported) */

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* Median of NREP values (sorted in place). */
static double median(double *t) {
  for (int i = 1; i < NREP; i++)
    for (int j = i; j > 0 && t[j] < t[j - 1]; j--) {
      double s = t[j];
      t[j] = t[j - 1], t[j - 1] = s;
    }
  return t[NREP / 2];
}

/* Report a failed call and give the exit code. */
static int fail(const char *what, ves_status st) {
  fprintf(stderr, "bench_scale: %s: %s\n", what, ves_status_str(st));
  return 1;
}

/* What one row holds (seconds unless said). */
typedef struct {
  int nodes, points;
  double m_mean;                                          /* mean LME neighbours per point */
  double setup, nodes_s, tables_s, project_s;             /* ves_setup_create and its parts */
  double eval, hess, diss, stepH, analysis, factor, step; /* single operations; step: mean */
  double solve;                                           /* one KKT solve (with its refinement) */
  long kkt_nnz;                                           /* triplets of the KKT matrix */
  double iters, hessians;                                 /* per accepted step, retries included */
  int retries;                                            /* halvings over the NSTEPS steps */
} row;

/* Everything after the setup: the model, the KKT factorization and the steps.
 * Kept whole (168 lines): one computation over shared buffers with one exit. */
static int measure(const ves_config *cfg, ves_setup *s, int nsteps, row *r) {
  ves_model *m = s->model;
  const ves_pattern *pat = ves_model_pattern(m);
  const int n = s->nodes->n;
  const double dt = cfg->dt_initial;
  double t[NREP], E = 0, A = 0, V = 0;
  int rc = 1;
  ves_status st = VES_OK;
  ves_step *step = NULL;
  ves_sim *sim = NULL;
  ves_kkt k;
  memset(&k, 0, sizeof k);
  double *H = NULL, *J = NULL, *x0 = NULL;
  double *y = malloc(2 * (size_t)n * sizeof *y), *g = malloc(6 * (size_t)n * sizeof *g);
  double *blk = malloc(4 * (size_t)pat->ptr[n] * sizeof *blk);
  if (!y || !g || !blk) {
    fprintf(stderr, "bench_scale: out of memory (model buffers, n = %d)\n", n);
    goto done;
  }
  ves_model_reference(m, y);

  /* the model at the reference y */
  for (int i = 0; i < NREP; i++) {
    double t0 = now();
    st = ves_model_eval(m, y, VES_F_E | VES_F_A | VES_F_V, &E, &A, &V, g, g + 2 * n, g + 4 * n);
    t[i] = now() - t0;
    if (st != VES_OK) {
      rc = fail("ves_model_eval", st);
      goto done;
    }
  }
  r->eval = median(t);
  for (int i = 0; i < NREP; i++) {
    double t0 = now();
    st = ves_model_hessian(m, y, dt, 1, 1, blk); /* dt Hess E + Hess A + Hess V */
    t[i] = now() - t0;
    if (st != VES_OK) {
      rc = fail("ves_model_hessian", st);
      goto done;
    }
  }
  r->hess = median(t);
  for (int i = 0; i < NREP; i++) {
    double t0 = now();
    st = ves_model_dissipation(m, y, blk);
    t[i] = now() - t0;
    if (st != VES_OK) {
      rc = fail("ves_model_dissipation", st);
      goto done;
    }
  }
  r->diss = median(t);
  free(blk), blk = NULL;

  /* the Newton KKT matrix at x0: H = K + dt Hess E (sigma_f = 1, lambda = 0),
   * J the held constraints' rows */
  const ves_step_params sp = {
      .dt = dt, .hold_area = cfg->area, .A0 = A, .hold_volume = cfg->volume, .V_target = V};
  if ((st = ves_step_create(m, &step)) != VES_OK) {
    rc = fail("ves_step_create", st);
    goto done;
  }
  if ((st = ves_step_set(step, y, &sp)) != VES_OK) {
    rc = fail("ves_step_set", st);
    goto done;
  }
  const int nvar = ves_step_nvar(step), ncon = ves_step_ncon(step);
  const double lambda[2] = {0, 0};
  H = malloc((size_t)ves_step_hess_nnz(step) * sizeof *H);
  J = malloc((size_t)(ncon > 0 ? ncon : 1) * nvar * sizeof *J);
  x0 = malloc((size_t)nvar * sizeof *x0);
  if (!H || !J || !x0) {
    fprintf(stderr, "bench_scale: out of memory (KKT values, nvar = %d)\n", nvar);
    goto done;
  }
  ves_step_x0(step, x0);
  ves_problem_params pp; /* as vesica run maps the problem file (the backend: newton) */
  ves_problem_params_from_config(cfg, &pp);
  for (int i = 0; i < NREP; i++) { /* the step's matrix: K(y^n) + dt Hess E + ..., one assembly,
                                      in the precision newton forms it in (step.h) */
    double t0 = now();
    st = pp.bopt.factor_single ? ves_step_eval_hess_single(step, x0, 1.0, lambda, H)
                               : ves_step_eval_hess(step, x0, 1.0, lambda, H);
    t[i] = now() - t0;
    if (st != VES_OK) {
      rc = fail("ves_step_eval_hess", st);
      goto done;
    }
  }
  r->stepH = median(t);
  if (ncon > 0 && (st = ves_step_eval_jac(step, x0, J)) != VES_OK) {
    rc = fail("ves_step_eval_jac", st);
    goto done;
  }
  double t0 = now();
  st = ves_kkt_create(step, pp.bopt.factor_single, &k); /* structure and the MUMPS analysis */
  r->analysis = now() - t0;
  if (st != VES_OK) {
    rc = fail("ves_kkt_create (MUMPS analysis)", st);
    goto done;
  }
  for (int i = 0; i < NREP; i++) {
    ves_kkt_fill(&k, H, 0, NULL, J, ncon); /* the values, outside the timing */
    t0 = now();
    st = ves_kkt_factor(&k);
    t[i] = now() - t0;
    if (st != VES_OK) {
      rc = fail("ves_kkt_factor", st);
      goto done;
    }
  }
  r->factor = median(t);
  r->kkt_nnz = k.nnz;
  for (int i = 0; i < NREP; i++) { /* a solve, x0 as the right-hand side */
    for (int j = 0; j < nvar + VES_KKT_NROWS; j++) g[j] = j < nvar ? x0[j] : 0.0;
    t0 = now();
    st = ves_kkt_solve(&k, g);
    t[i] = now() - t0;
    if (st != VES_OK) {
      rc = fail("ves_kkt_solve", st);
      goto done;
    }
  }
  r->solve = median(t);
  /* the steps below build their own step problem and KKT system: free these
   * first, so that the peak memory is a run's, not a run's plus this copy */
  ves_kkt_destroy(&k);
  ves_step_destroy(&step);
  free(H), free(J), free(x0), free(g), free(y);
  H = J = x0 = g = y = NULL;

  /* NSTEPS accepted steps of the newton backend from the reference state */
  if ((st = ves_sim_create(m, &ves_backend_newton, &pp.bopt, &pp.ip, &sim)) != VES_OK) {
    rc = fail("ves_sim_create (newton)", st);
    goto done;
  }
  double wall = 0;
  long iters = 0, hessians = 0;
  r->retries = 0;
  for (int i = 0; i < nsteps; i++) {
    ves_step_report rep;
    t0 = now();
    st = ves_sim_step(sim, &rep);
    wall += now() - t0;
    if (st == VES_DONE) {
      fprintf(stderr, "bench_scale: t_end reached after %d of %d steps\n", i, nsteps);
      goto done;
    }
    if (st != VES_OK) {
      char what[64];
      snprintf(what, sizeof what, "ves_sim_step (step %d)", i + 1);
      rc = fail(what, st);
      goto done;
    }
    iters += rep.stats.iterations + rep.rejected.iterations;
    hessians += rep.stats.h_evals + rep.rejected.h_evals;
    r->retries += rep.retries;
  }
  r->step = wall / nsteps;
  r->iters = (double)iters / nsteps, r->hessians = (double)hessians / nsteps;
  rc = 0;
done:
  ves_sim_destroy(&sim);
  ves_kkt_destroy(&k);
  ves_step_destroy(&step);
  free(H), free(J), free(x0), free(g), free(y), free(blk);
  return rc;
}

/* Kept whole (81 lines): the option parsing, the runs and the table they print, in order. */
int main(int argc, char **argv) {
  ves_blas_core_fix(argv); /* OpenBLAS's kernels (blas_core_impl.h) */
  const char *hdr = getenv("BENCH_HEADER");
  int header = hdr && !strcmp(hdr, "1");
  static char *quick[] = {"bench_scale", "problems/oblate.ini", "0.04", NULL};
  if (argc == 1) /* the quick row, from the repository's top folder */
    argc = 3, argv = quick, header = 1;
  if (argc < 3 || argc > 4) {
    fprintf(stderr, "usage: bench_scale [PROBLEM.ini EPS [NSTEPS]]\n");
    return 1;
  }
  char *end;
  const double eps = strtod(argv[2], &end);
  if (*end || end == argv[2] || !(eps > 0)) {
    fprintf(stderr, "bench_scale: EPS '%s': not a positive number\n", argv[2]);
    return 1;
  }
  long nsteps = 3;
  if (argc == 4) {
    nsteps = strtol(argv[3], &end, 10);
    if (*end || end == argv[3] || nsteps < 1 || nsteps > 100000) {
      fprintf(stderr, "bench_scale: NSTEPS '%s': not a positive integer\n", argv[3]);
      return 1;
    }
  }
  char setbuf_eps[128], err[1024] = "";
  snprintf(setbuf_eps, sizeof setbuf_eps, "geometry.epsilon=%s", argv[2]);
  const char *set[1] = {setbuf_eps};
  ves_config cfg;
  ves_status st = ves_config_load(argv[1], 1, set, &cfg, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr, "bench_scale: %s\n", err);
    return 1;
  }
  const char *blas = getenv("OPENBLAS_NUM_THREADS");
  const char *core = openblas_get_corename();
#ifdef _OPENMP
  const int nthr = omp_get_max_threads();
#else
  const int nthr = 1;
#endif

  row r;
  memset(&r, 0, sizeof r);
  ves_setup *s = NULL;
  double t0 = now();
  st = ves_problem_setup_create(&cfg, VES_PHI0_L2, &s, err, sizeof err);
  r.setup = now() - t0;
  if (st != VES_OK) {
    fprintf(stderr, "bench_scale: setup of %s at eps %s: %s (%s)\n", argv[1], argv[2], err,
            ves_status_str(st));
    return 1;
  }
  r.nodes = s->nodes->n, r.points = s->quad->nq, r.m_mean = s->qinfo.m_mean;
  r.nodes_s = s->seconds_nodes, r.tables_s = s->seconds_tables, r.project_s = s->seconds_project;
  int rc = measure(&cfg, s, (int)nsteps, &r);
  ves_setup_destroy(&s);
  if (rc) return rc;

  struct rusage ru;
  if (getrusage(RUSAGE_SELF, &ru) != 0) {
    perror("bench_scale: getrusage");
    return 1;
  }
  const double cpu_s = ru.ru_utime.tv_sec + 1e-6 * ru.ru_utime.tv_usec + ru.ru_stime.tv_sec +
                       1e-6 * ru.ru_stime.tv_usec;
  const double peak_mb = ru.ru_maxrss / 1024.0; /* ru_maxrss in kB on Linux */
  if (header)
    printf(
        "# eps\tthreads\tblas_threads\tnodes\tpoints\tneighbours_mean\tsetup_s\tnodes_s\t"
        "tables_s\tproject_s\tmodel_s\teval_s\thess_s\tK_s\tstepH_s\tanalysis_s\tfactor_s\tstep_s\t"
        "iters_per_step\thess_per_step\tretries\tcpu_s\tpeak_MB\tblas_core\tsolve_s\tkkt_nnz\n");
  printf(
      "%g\t%d\t%s\t%d\t%d\t%.1f\t%.3f\t%.3f\t%.3f\t%.3f\t%.3f\t%.4f\t%.4f\t%.4f\t%.4f\t%.3f\t%.3f\t"
      "%.3f\t%.2f\t%.2f\t%d\t%.2f\t%.1f\t%s\t%.3f\t%ld\n",
      eps, nthr, blas ? blas : "unset", r.nodes, r.points, r.m_mean, r.setup, r.nodes_s, r.tables_s,
      r.project_s, r.setup - r.nodes_s - r.tables_s - r.project_s, r.eval, r.hess, r.diss, r.stepH,
      r.analysis, r.factor, r.step, r.iters, r.hessians, r.retries, cpu_s, peak_mb,
      core ? core : "unknown", r.solve, r.kkt_nnz);
  return 0;
}
