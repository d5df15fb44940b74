/* vesica — the table of step backends and their common options (DESIGN.md §3). */
#include "ves/backend.h"

#include <string.h>

/* Defaults: KKT residual 1e-9 relative, constraints 1e-10 of their targets
 * (A0 ~ 4 pi, so |A - A0| <~ 1e-9), 100 iterations, fresh Hessian each
 * iteration, quiet. */
void ves_backend_options_default(ves_backend_options *opt) {
  if (!opt) return;
  opt->tol = 1e-9;
  opt->ctol = 1e-10;
  opt->max_iter = 100;
  opt->freeze_hessian = 0;
  opt->verbose = 0;
}

static const ves_backend_type *const TABLE[] = {&ves_backend_ipopt, &ves_backend_nlopt,
                                                &ves_backend_newton, &ves_backend_euler};

const ves_backend_type *ves_backend_find(const char *name) {
  if (!name) return NULL;
  for (size_t i = 0; i < sizeof TABLE / sizeof TABLE[0]; i++)
    if (!strcmp(TABLE[i]->name, name)) return TABLE[i];
  return NULL;
}
