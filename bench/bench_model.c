/* vesica — benchmark of the model assembly (solver/model/model.c): setup time, one
 * E+A+V value+gradient evaluation (the fastest of EVAL_REPEAT, as in a run's
 * warm loop), one Hessian (cE = cA = cV = 1) and one K assembly (each the
 * fastest of MAT_REPEAT), with the sizes that drive them, for a sphere in a
 * 2 x 2 box at eps = 0.04 (quick row) and eps = 0.01 (the paper's scale),
 * h_band = 0.5 eps.
 * Wall times, and the process CPU time of the Hessian and K (all threads:
 * on a shared machine the CPU time of a one-thread run is the steadier
 * measure). Threads: OMP_NUM_THREADS (default: all cores).
 * Usage: bench_model [eps ...]  (default: 0.04 0.01). */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "ves/model.h"
#include "ves/setup.h"
#include "app/problem.h"
#include "app/blas_core_impl.h"

#define EVAL_REPEAT 5 /* E+A+V+g passes timed (a run makes hundreds) */
#define MAT_REPEAT                                                                                 \
  3 /* Hessian and K assemblies timed (the first pays the block array's                            \
       first touch; single timings vary by ~15% on a shared machine) */

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static double cpu(void) {
  struct timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* One row: sizes and timings (seconds) at interface width eps. */
typedef struct {
  double eps;
  int n, nfree, nq;
  double m_mean;
  long nnz_blocks, nnz_free;
  double mem_tab, mem_blk; /* MB */
  double t_setup, t_eval, t_hess, t_diss;
  double c_hess, c_diss; /* CPU seconds, all threads */
} row;

/* The fastest of MAT_REPEAT assemblies at y into blk, the Hessian (hess,
 * cE = cA = cV = 1) or K: *t its wall time, *c its CPU time. */
static ves_status fastest_assembly(ves_model *m, const double *y, int hess, double *blk, double *t,
                                   double *c) {
  *t = 1e300;
  for (int k = 0; k < MAT_REPEAT; k++) {
    const double c0 = cpu(), t0 = now();
    ves_status st = hess ? ves_model_hessian(m, y, 1, 1, 1, blk) : ves_model_dissipation(m, y, blk);
    if (st != VES_OK) return st;
    const double dt = now() - t0;
    if (dt < *t) *t = dt, *c = cpu() - c0;
  }
  return VES_OK;
}

static int run(double eps, row *r) {
  ves_config cfg;
  ves_config_default(&cfg);
  cfg.epsilon = eps, cfg.h_band = 0.5, cfg.box_r = 2.0, cfg.box_z = 2.0;
  char err[256] = "";
  ves_setup *s = NULL;
  double t = now();
  ves_status st = ves_problem_setup_create(&cfg, VES_PHI0_L2, &s, err, sizeof err);
  r->t_setup = now() - t;
  if (st != VES_OK) {
    fprintf(stderr, "bench_model: setup at eps = %g: %s\n", eps, err);
    return 1;
  }
  const ves_pattern *pat = ves_model_pattern(s->model);
  const int n = s->nodes->n;
  r->eps = eps, r->n = n, r->nfree = pat->nfree, r->nq = s->quad->nq, r->m_mean = s->qinfo.m_mean;
  r->nnz_blocks = pat->ptr[n], r->nnz_free = pat->nnz;
  r->mem_tab = 6.0 * 8 * s->quad->ptr[s->quad->nq] / 1e6;
  r->mem_blk = 4.0 * 8 * pat->ptr[n] / 1e6;
  double *y = malloc(2 * (size_t)n * sizeof *y), *g = malloc(6 * (size_t)n * sizeof *g);
  double *blk = malloc(4 * (size_t)pat->ptr[n] * sizeof *blk);
  if (!y || !g || !blk) return 1;
  ves_model_reference(s->model, y);
  double E, A, V;
  r->t_eval = 1e300; /* the fastest of EVAL_REPEAT: the first pass also pays the cold caches */
  for (int k = 0; k < EVAL_REPEAT; k++) {
    t = now();
    st = ves_model_eval(s->model, y, VES_F_E | VES_F_A | VES_F_V, &E, &A, &V, g, g + 2 * n,
                        g + 4 * n);
    const double dt = now() - t;
    if (dt < r->t_eval) r->t_eval = dt;
  }
  if (st == VES_OK) st = fastest_assembly(s->model, y, 1, blk, &r->t_hess, &r->c_hess);
  if (st == VES_OK) st = fastest_assembly(s->model, y, 0, blk, &r->t_diss, &r->c_diss);
  if (st != VES_OK)
    fprintf(stderr, "bench_model: model at eps = %g: %s\n", eps, ves_status_str(st));
  printf("# eps = %g: E* = %.6f (sphere: 2 pi = 6.283185), A/4pi - 1 = %.2e, "
         "setup: nodes %.1f s, "
         "tables %.1f s, projection %.1f s\n",
         eps, E, A / (4 * 3.141592653589793) - 1, s->seconds_nodes, s->seconds_tables,
         s->seconds_project);
  free(y), free(g), free(blk);
  ves_setup_destroy(&s);
  return st != VES_OK;
}

int main(int argc, char **argv) {
  ves_blas_core_fix(argv); /* OpenBLAS's kernels (blas_core_impl.h) */
  double def[2] = {0.04, 0.01};
  int nrow = argc > 1 ? argc - 1 : 2;
  row rows[16];
  if (nrow > 16) nrow = 16;
  const char *thr = getenv("OPENBLAS_NUM_THREADS");
#ifdef _OPENMP
  const int nthr = omp_get_max_threads();
#else
  const int nthr = 1;
#endif
  printf("# bench_model: sphere R = 1, box 2 x 2, h_band = 0.5 eps, other keys at their "
         "defaults (vesica keys), phi0 L2; "
         "OPENBLAS_NUM_THREADS = %s; model threads (OpenMP) = %d\n",
         thr ? thr : "(unset)", nthr);
  for (int i = 0; i < nrow; i++)
    if (run(argc > 1 ? atof(argv[i + 1]) : def[i], rows + i)) return 1;
  printf("%6s %7s %7s %8s %5s %9s %10s %8s %8s %8s %9s %9s %9s %9s %9s\n", "eps", "nodes", "free",
         "points", "m", "blocks", "nnz(free)", "tab MB", "blk MB", "setup s", "E+A+V+g s", "Hess s",
         "K s", "Hess cpu", "K cpu");
  for (int i = 0; i < nrow; i++) {
    const row *r = rows + i;
    printf("%6.3f %7d %7d %8d %5.1f %9ld %10ld %8.1f %8.1f %8.2f %9.3f %9.3f "
           "%9.3f %9.3f %9.3f\n",
           r->eps, r->n, r->nfree, r->nq, r->m_mean, r->nnz_blocks, r->nnz_free, r->mem_tab,
           r->mem_blk, r->t_setup, r->t_eval, r->t_hess, r->t_diss, r->c_hess, r->c_diss);
  }
  return 0;
}
