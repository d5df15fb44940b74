/* vesica — the table of step backends and their common options (docs/design.md, "Backends"). */
#include "ves/backend.h"

#include <string.h>

/* Defaults: the problem file's [solver] keys (vesica keys lists them;
 * test_config checks that the two agree): KKT residual 1e-9 relative,
 * constraints 1e-10 of their targets, 40 iterations a step, no build or
 * correction limit, newton's Hessian frozen within a step, the KKT matrix
 * factorized in single precision; quiet. */
void ves_backend_options_default(ves_backend_options *opt) {
  if (!opt) return;
  *opt = (ves_backend_options){.tol = 1e-9,
                               .ctol = 1e-10,
                               .max_iter = 40,
                               .max_builds = 0,
                               .max_correction = 0.0,
                               .freeze_hessian = 1,
                               .factor_single = 1,
                               .verbose = 0};
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
