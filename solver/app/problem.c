/* vesica — the problem file's parameters as the library's parameter structs
 * (problem.h): each field from its key, names parsed into the library's
 * enums and rules, lambda = lambda_ratio mu the one product
 * (docs/design.md, "The program"). */
#include "app/problem.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* The integrator's parameters: every field from the problem's keys. */
static void integrate_params(const ves_config *c, ves_integrate_params *ip) {
  ves_integrate_params_default(ip); /* fields without a key (check_energy) */
  ip->t_end = c->t_end, ip->dt_initial = c->dt_initial, ip->dt_max = c->dt_max;
  ip->dt_min = c->dt_min, ip->adaptive = c->adaptive, ip->dE_target = c->dE_target;
  ip->growth_max = c->growth_max, ip->iter_target = c->iter_target;
  ip->factor_target = c->factor_target;
  ip->factor_shrink = c->factor_shrink;
  ip->predictor = c->predictor;
  ip->order = c->order;
  ip->retry_memory = c->retry_memory, ip->retry_cap = c->retry_cap;
  ip->event_cut = c->event_cut;
  ip->hold_area = c->area, ip->hold_volume = c->volume;
  ip->volume_rate = c->volume_rate, ip->volume_final = c->volume_final;
  ip->c0_time = c->c0_time, ip->c0_after = c->c0_after, ip->c0_until = c->c0_until;
  ip->c0_ramp_start = c->c0_ramp_start, ip->c0_ramp_end = c->c0_ramp_end;
  ip->c0_ramp_to = c->c0_ramp_to;
  ip->reconnect_every = c->reconnect_every, ip->reconnect_cond_max = c->reconnect_cond_max;
  ip->profile_every = c->profile_every;
  ip->reconnect_det_min = c->reconnect_det_min;
  ip->reconnect_nodes =
      strcmp(c->reconnect_nodes, "motion") ? VES_RESET_NODES_COEF : VES_RESET_NODES_MOTION;
}

void ves_problem_backend_options(const ves_config *c, ves_backend_options *opt) {
  if (!c || !opt) return;
  opt->tol = c->tol;
  opt->ctol = c->ctol;
  opt->max_iter = c->max_iter;
  opt->max_builds = c->max_builds;
  opt->max_correction = c->max_correction;
  opt->freeze_hessian = c->freeze_hessian;
  opt->factor_single = strcmp(c->factor_precision, "double") != 0;
  opt->verbose = 0;
}

/* The discretization with the rule parsed ({0, 0} when it names none). */
static int discret_params(const ves_config *c, ves_discret_params *d) {
  *d = (ves_discret_params){.eps = c->epsilon,
                            .box_r = c->box_r,
                            .box_z = c->box_z,
                            .h_band = c->h_band,
                            .band = c->band,
                            .slope = c->slope,
                            .h_far = c->h_far,
                            .gamma = c->gamma,
                            .support_tol = c->support_tol,
                            .axis_spacings = c->axis_spacings,
                            .lloyd_iterations = c->lloyd_iterations,
                            .band_layers = c->band_layers,
                            .seed = c->seed};
  if (ves_quad_rule_parse(c->quadrature, &d->rule) == VES_OK) return 1;
  d->rule = (ves_quad_rulespec){0};
  return 0;
}

ves_status ves_problem_discret(const ves_config *c, ves_discret_params *d, char *err,
                               size_t errlen) {
  VES_CHECK(c && d, VES_ERR_ARG);
  if (discret_params(c, d)) return VES_OK;
  ves_error_say(err, errlen, "[geometry] quadrature = %s: not a rule", c->quadrature);
  return VES_ERR_CONFIG;
}

void ves_problem_model_params(const ves_config *c, ves_model_params *mp) {
  if (!c || !mp) return;
  *mp = (ves_model_params){.eps = c->epsilon,
                           .c0 = c->c0,
                           .k = c->k,
                           .mu = c->mu,
                           .lambda = c->lambda_ratio * c->mu,
                           .drift = c->drift_damping,
                           .stab = c->stabilization};
}

ves_status ves_problem_shape(const ves_config *c, ves_shape **shape, char *err, size_t errlen) {
  VES_CHECK(c && shape && err && errlen, VES_ERR_ARG);
  *shape = NULL;
  ves_status st;
  double *cpts = NULL;
  ves_shape_params sp;
  ves_shape_params_default(&sp);
  if (!strcasecmp(c->shape_type, "sphere"))
    sp.kind = VES_SHAPE_SPHERE;
  else if (!strcasecmp(c->shape_type, "spheroid"))
    sp.kind = VES_SHAPE_SPHEROID;
  else if (!strcasecmp(c->shape_type, "curve"))
    sp.kind = VES_SHAPE_CURVE;
  else
    sp.kind = VES_SHAPE_DISCOCYTE;
  if (sp.kind == VES_SHAPE_CURVE) {
    if ((st = ves_config_read_points(c, &sp.npts, &cpts, err, errlen)) != VES_OK) return st;
    sp.pts = cpts;
  }
  sp.radius = c->radius;
  sp.v = c->reduced_volume;
  sp.prolate = !strcasecmp(c->orientation, "prolate");
  sp.mode = c->mode;
  sp.delta = c->delta;
  st = ves_shape_create(&sp, shape);
  free(cpts);
  if (st == VES_ERR_GEOM && sp.kind == VES_SHAPE_CURVE) { /* bad input: exit code 2 */
    snprintf(err, errlen,
             "[shape] points = %s: the spline through the points crosses the axis (R < 0 between "
             "the poles) or encloses no volume; add points along its longest segments",
             c->points);
    return VES_ERR_CONFIG;
  }
  if (st != VES_OK) snprintf(err, errlen, "shape: %s", ves_error_text(st));
  return st;
}

ves_status ves_problem_setup_create(const ves_config *c, ves_phi0_method method, ves_setup **out,
                                    char *err, size_t errlen) {
  VES_CHECK(c && out && err && errlen, VES_ERR_ARG);
  *out = NULL;
  ves_error_clear(); /* err names the record of this setup's failure (status.h) */
  ves_shape *shape = NULL;
  ves_discret_params d;
  ves_model_params mp;
  ves_status st = ves_problem_shape(c, &shape, err, errlen);
  if (st != VES_OK) return st;
  if ((st = ves_problem_discret(c, &d, err, errlen)) != VES_OK) {
    ves_shape_destroy(&shape);
    return st;
  }
  ves_problem_model_params(c, &mp);
  return ves_setup_create(&d, shape, &mp, method, out, err, errlen); /* shape taken */
}

void ves_problem_params_from_config(const ves_config *c, ves_problem_params *p) {
  if (!c || !p) return;
  memset(p, 0, sizeof *p);
  p->backend = ves_backend_find(c->backend);
  ves_backend_options_default(&p->bopt);
  ves_problem_backend_options(c, &p->bopt);
  integrate_params(c, &p->ip);
  discret_params(c, &p->discret);
  p->remesh = c->remesh_every > 0 || c->remesh_cond_max > 0 || c->remesh_det_min > 0 ||
              c->remesh_on_failed_reset;
  p->remesh_policy = (ves_remesh_policy){.every = c->remesh_every,
                                         .cond_max = c->remesh_cond_max,
                                         .det_min = c->remesh_det_min,
                                         .on_failed_reset = c->remesh_on_failed_reset};
  p->resets =
      c->reconnect_every > 0 || c->reconnect_cond_max > 0 || c->reconnect_det_min > 0 || p->remesh;
}
