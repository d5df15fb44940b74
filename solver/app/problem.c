/* vesica — the problem file's parameters as the library's parameter structs
 * (problem.h). */
#include "app/problem.h"

#include <string.h>

/* The integrator's parameters: every field from the problem's keys. */
static void integrate_params(const ves_config *c, ves_integrate_params *ip) {
  ves_integrate_params_default(ip); /* fields without a key (check_energy) */
  ip->t_end = c->t_end, ip->dt_initial = c->dt_initial, ip->dt_max = c->dt_max;
  ip->dt_min = c->dt_min, ip->adaptive = c->adaptive, ip->dE_target = c->dE_target;
  ip->growth_max = c->growth_max, ip->iter_target = c->iter_target;
  ip->factor_target = c->factor_target;
  ip->factor_shrink = c->factor_shrink;
  ip->predictor = c->predictor;
  ip->retry_memory = c->retry_memory, ip->retry_cap = c->retry_cap;
  ip->hold_area = c->area, ip->hold_volume = c->volume;
  ip->volume_rate = c->volume_rate, ip->volume_final = c->volume_final;
  ip->c0_time = c->c0_time, ip->c0_after = c->c0_after, ip->c0_until = c->c0_until;
  ip->c0_ramp_start = c->c0_ramp_start, ip->c0_ramp_end = c->c0_ramp_end;
  ip->c0_ramp_to = c->c0_ramp_to;
  ip->reconnect_every = c->reconnect_every, ip->reconnect_cond_max = c->reconnect_cond_max;
  ip->reconnect_det_min = c->reconnect_det_min;
  ip->reconnect_nodes =
      strcmp(c->reconnect_nodes, "motion") ? VES_RESET_NODES_COEF : VES_RESET_NODES_MOTION;
}

void ves_problem_params_from_config(const ves_config *c, ves_problem_params *p) {
  if (!c || !p) return;
  memset(p, 0, sizeof *p);
  p->backend = ves_backend_find(c->backend);
  ves_backend_options_default(&p->bopt);
  ves_backend_options_from_config(c, &p->bopt);
  integrate_params(c, &p->ip);
  p->remesh = c->remesh_every > 0 || c->remesh_cond_max > 0 || c->remesh_det_min > 0 ||
              c->remesh_on_failed_reset;
  p->remesh_policy = (ves_remesh_policy){.every = c->remesh_every,
                                         .cond_max = c->remesh_cond_max,
                                         .det_min = c->remesh_det_min,
                                         .on_failed_reset = c->remesh_on_failed_reset};
  p->resets =
      c->reconnect_every > 0 || c->reconnect_cond_max > 0 || c->reconnect_det_min > 0 || p->remesh;
}
