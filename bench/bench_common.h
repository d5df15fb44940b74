/* vesica — what the benchmark programs share: run parameters from a problem
 * file for constant-step runs, and comma-separated lists of numbers. Private
 * to bench/ (static functions, one copy per program). */
#ifndef VES_BENCH_COMMON_H
#define VES_BENCH_COMMON_H

#include <stdlib.h>

#include "ves/backend.h"
#include "app/config.h"
#include "app/problem.h"
#include "ves/integrate.h"

/* Integrator parameters of a run with constant dt to t_end, the constraints
 * as in cfg, and no halving (dt_min just below dt: a failed step ends it). */
static inline void bench_constant_params(const ves_config *cfg, double dt, double t_end,
                                         ves_integrate_params *ip) {
  ves_integrate_params_default(ip);
  ip->t_end = t_end, ip->dt_initial = dt, ip->dt_max = dt, ip->dt_min = dt * (1 - 1e-12);
  ip->adaptive = 0;
  ip->hold_area = cfg->area, ip->hold_volume = cfg->volume;
}

/* Backend options from the [solver] section of cfg. */
static inline void bench_backend_options(const ves_config *cfg, ves_backend_options *bo) {
  ves_problem_backend_options(cfg, bo);
}

/* Parse "a,b,c" into v[max]; returns the count, -1 on a malformed entry. */
static inline int bench_parse_list(const char *s, double *v, int max) {
  int n = 0;
  char *end;
  while (*s && n < max) {
    v[n++] = strtod(s, &end);
    if (end == s) return -1;
    s = *end == ',' ? end + 1 : end;
  }
  return n;
}

#endif
