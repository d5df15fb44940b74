/* vesica — the problem file's parameters (ves_config) as the library's
 * parameter structs: the backend, its options, the integrator's time
 * stepping and protocols, the remeshing policy. The one mapping shared by
 * vesica run, its restart and vesica spectrum (DESIGN.md §3, §6). */
#ifndef VES_PROBLEM_H
#define VES_PROBLEM_H

#include "ves/backend.h"
#include "app/config.h"
#include "ves/integrate.h"
#include "ves/reconnect.h"
#include "ves/remesh.h"

/* Everything a simulation of a problem takes besides its model. */
typedef struct {
  const ves_backend_type *backend; /* [solver] backend (NULL: not a known name) */
  ves_backend_options bopt;        /* [solver] tol, ctol, max_iter, freeze_hessian */
  ves_integrate_params ip;         /* [time], [constraints], [protocol], [material], [reconnect] */
  int remesh;                      /* 1: [remesh] asks for remeshings */
  ves_remesh_policy remesh_policy; /* [remesh] every, cond_max, det_min, on_failed_reset */
  int resets;                      /* 1: the reference may change in a run (resets or remeshings) */
} ves_problem_params;

/* p from the configuration c (borrowed for the call). */
void ves_problem_params_from_config(const ves_config *c, ves_problem_params *p);

#endif
