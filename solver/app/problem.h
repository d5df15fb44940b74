/* vesica — the problem file's parameters (ves_config) as the library's
 * parameter structs: the shape, the discretization, the model, the backend
 * and its options, the integrator's time stepping and protocols, the
 * remeshing policy. The one mapping from a problem file to the library,
 * shared by vesica run, its restart, vesica check and vesica spectrum, the
 * tests and the benchmarks (docs/design.md, "The program"). */
#ifndef VES_PROBLEM_H
#define VES_PROBLEM_H

#include <stddef.h>

#include "app/config.h"
#include "ves/backend.h"
#include "ves/integrate.h"
#include "ves/model.h"
#include "ves/reconnect.h"
#include "ves/remesh.h"
#include "ves/setup.h"
#include "ves/shape.h"

/* Everything a simulation of a problem takes besides its model. */
typedef struct {
  const ves_backend_type *backend; /* [solver] backend (NULL: not a known name) */
  ves_backend_options bopt;        /* [solver] tol, ctol, max_iter, freeze_hessian, ... */
  ves_integrate_params ip;         /* [time], [constraints], [protocol], [material], [reconnect] */
  ves_discret_params discret;      /* [geometry] (the rule {0, 0} when quadrature names none) */
  int remesh;                      /* 1: [remesh] asks for remeshings */
  ves_remesh_policy remesh_policy; /* [remesh] every, cond_max, det_min, on_failed_reset */
  int resets;                      /* 1: the reference may change in a run (resets or remeshings) */
} ves_problem_params;

/* p from the configuration c (borrowed for the call). */
void ves_problem_params_from_config(const ves_config *c, ves_problem_params *p);

/* The [solver] keys of c (tol, ctol, max_iter, max_builds, max_correction,
 * freeze_hessian, factor_precision) as backend options, verbose 0. */
void ves_problem_backend_options(const ves_config *c, ves_backend_options *opt);

/* The [geometry] keys of c as the discretization. VES_ERR_CONFIG when
 * [geometry] quadrature names no rule (one line in err; d->rule {0, 0}). */
ves_status ves_problem_discret(const ves_config *c, ves_discret_params *d, char *err,
                               size_t errlen);

/* The model's parameters: eps from [geometry] epsilon, c0, k, mu and
 * lambda = lambda_ratio mu from [material], drift from [solver]
 * drift_damping, stab from [geometry] stabilization. */
void ves_problem_model_params(const ves_config *c, ves_model_params *mp);

/* The initial shape of c ([shape]; a curve's points file is read,
 * ves_config_read_points): *shape taken by the caller. VES_ERR_CONFIG for a
 * points file whose spline the shape refuses; errors of the points file
 * and of ves_shape_create. One line in err on error. */
ves_status ves_problem_shape(const ves_config *c, ves_shape **shape, char *err, size_t errlen);

/* The setup of c: ves_setup_create of its shape, discretization and model
 * parameters; *out taken by the caller. Errors as those three functions and
 * ves_setup_create, one line in err. */
ves_status ves_problem_setup_create(const ves_config *c, ves_phi0_method method, ves_setup **out,
                                    char *err, size_t errlen);

#endif
