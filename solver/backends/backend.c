/* vesica — the table of step backends and their common options (DESIGN.md §3). */
#include "ves/backend.h"

#include <string.h>

void ves_backend_options_from_config(const ves_config *cfg, ves_backend_options *opt) {
  if (!cfg || !opt) return;
  opt->tol = cfg->tol;
  opt->ctol = cfg->ctol;
  opt->max_iter = cfg->max_iter;
  opt->max_builds = cfg->max_builds;
  opt->max_correction = cfg->max_correction;
  opt->freeze_hessian = cfg->freeze_hessian;
  opt->factor_single = strcmp(cfg->factor_precision, "double") != 0;
  opt->verbose = 0;
}

/* Defaults: the problem file's, from config.c's table of keys (KKT residual
 * 1e-9 relative, constraints 1e-10 of their targets, 40 iterations, newton's
 * Hessian frozen within a step; quiet). */
void ves_backend_options_default(ves_backend_options *opt) {
  if (!opt) return;
  ves_config cfg;
  ves_config_default(&cfg);
  ves_backend_options_from_config(&cfg, opt);
}

const char *ves_backend_limit_key(int limit) {
  switch (limit) {
  case VES_LIMIT_ITER:
    return "solver.max_iter";
  case VES_LIMIT_BUILDS:
    return "solver.max_builds";
  case VES_LIMIT_CORRECTION:
    return "solver.max_correction";
  default:
    return "";
  }
}

static const ves_backend_type *const TABLE[] = {&ves_backend_ipopt, &ves_backend_nlopt,
                                                &ves_backend_newton, &ves_backend_euler};

const ves_backend_type *ves_backend_find(const char *name) {
  if (!name) return NULL;
  for (size_t i = 0; i < sizeof TABLE / sizeof TABLE[0]; i++)
    if (!strcmp(TABLE[i]->name, name)) return TABLE[i];
  return NULL;
}
