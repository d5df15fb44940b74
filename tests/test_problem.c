/* vesica — tests of the problem file's parameters as the library's structs
 * (problem.h): the defaults give the library's defaults, every key lands in
 * its field (the discretization's and the model's too), and the switches
 * (remeshing, resets) follow the keys. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <stdio.h>
#include <string.h>

#include "app/problem.h"

static void load(int nset, const char *const *set, ves_config *c) {
  char err[512] = "";
  if (ves_config_load(NULL, nset, set, c, err, sizeof err) != VES_OK) fail_msg("config: %s", err);
}

/* The default problem: the default backend and its default options, the
 * integrator's defaults field by field (test_config test_defaults_agree
 * checks that those agree with the keys), no remeshing, no resets. */
static void test_defaults(void **state) {
  (void)state;
  ves_config c;
  ves_config_default(&c);
  ves_problem_params p;
  ves_problem_params_from_config(&c, &p);
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  assert_ptr_equal(p.backend, ves_backend_find("newton"));
  assert_true(p.bopt.tol == bo.tol && p.bopt.ctol == bo.ctol);
  assert_true(p.bopt.max_iter == bo.max_iter && p.bopt.freeze_hessian == bo.freeze_hessian);
  assert_true(p.ip.t_end == ip.t_end && p.ip.dt_initial == ip.dt_initial &&
              p.ip.dt_max == ip.dt_max && p.ip.dt_min == ip.dt_min);
  assert_true(p.ip.adaptive == ip.adaptive && p.ip.dE_target == ip.dE_target &&
              p.ip.growth_max == ip.growth_max && p.ip.iter_target == ip.iter_target);
  assert_true(p.ip.predictor == ip.predictor && p.ip.retry_memory == ip.retry_memory &&
              p.ip.retry_cap == ip.retry_cap);
  assert_true(p.ip.hold_area == ip.hold_area && p.ip.hold_volume == ip.hold_volume &&
              p.ip.volume_rate == ip.volume_rate && p.ip.volume_final == ip.volume_final);
  assert_true(p.ip.c0_time == ip.c0_time && p.ip.c0_after == ip.c0_after &&
              p.ip.c0_until == ip.c0_until && p.ip.c0_ramp_start == ip.c0_ramp_start &&
              p.ip.c0_ramp_end == ip.c0_ramp_end && p.ip.c0_ramp_to == ip.c0_ramp_to);
  assert_true(p.ip.check_energy == ip.check_energy);
  assert_true(p.ip.reconnect_every == ip.reconnect_every &&
              p.ip.reconnect_cond_max == ip.reconnect_cond_max &&
              p.ip.reconnect_det_min == ip.reconnect_det_min &&
              p.ip.reconnect_nodes == ip.reconnect_nodes);
  assert_int_equal(p.remesh, 0);
  assert_int_equal(p.resets, 0);
}

/* Keys that are not the defaults land in their fields. */
static void test_keys(void **state) {
  (void)state;
  const char *set[] = {"solver.backend=ipopt", "solver.max_iter=7",       "time.t_end=3",
                       "time.dt_min=1e-6",     "reconnect.every=5",       "reconnect.nodes=motion",
                       "remesh.cond_max=4",    "remesh.on_failed_reset=1"};
  ves_config c;
  load(8, set, &c);
  ves_problem_params p;
  ves_problem_params_from_config(&c, &p);
  assert_ptr_equal(p.backend, ves_backend_find("ipopt"));
  assert_int_equal(p.bopt.max_iter, 7);
  assert_true(p.ip.t_end == 3 && p.ip.dt_min == 1e-6);
  assert_int_equal(p.ip.reconnect_every, 5);
  assert_int_equal(p.ip.reconnect_nodes, VES_RESET_NODES_MOTION);
  assert_int_equal(p.remesh, 1);
  assert_true(p.remesh_policy.cond_max == 4 && p.remesh_policy.on_failed_reset == 1 &&
              p.remesh_policy.every == 0 && p.remesh_policy.det_min == 0);
  assert_int_equal(p.resets, 1);
  /* a reset alone makes resets, not remeshings */
  const char *one[] = {"reconnect.det_min=0.5"};
  load(1, one, &c);
  ves_problem_params_from_config(&c, &p);
  assert_int_equal(p.remesh, 0);
  assert_int_equal(p.resets, 1);
  /* NULL arguments: nothing happens */
  ves_problem_params_from_config(NULL, &p);
  ves_problem_params_from_config(&c, NULL);
}

/* The [geometry] keys land in the discretization, [material] and the rest
 * in the model's parameters; a quadrature that names no rule is refused
 * with the key in the message (the rule then {0, 0}). */
static void test_discretization(void **state) {
  (void)state;
  const char *set[] = {"geometry.epsilon=0.1",
                       "geometry.box_r=2.5",
                       "geometry.box_z=3",
                       "geometry.h_band=0.4",
                       "geometry.band=4",
                       "geometry.slope=0.1",
                       "geometry.h_far=0.3",
                       "geometry.gamma=0.8",
                       "geometry.support_tol=1e-7",
                       "geometry.seed=9",
                       "geometry.band_layers=0",
                       "geometry.quadrature=d6x4",
                       "geometry.axis_spacings=12",
                       "geometry.lloyd_iterations=5",
                       "material.mu=1",
                       "material.lambda_ratio=20"};
  ves_config c;
  load(16, set, &c);
  ves_discret_params d;
  char err[256] = "";
  assert_int_equal(ves_problem_discret(&c, &d, err, sizeof err), VES_OK);
  assert_true(d.eps == 0.1 && d.box_r == 2.5 && d.box_z == 3 && d.h_band == 0.4 && d.band == 4);
  assert_true(d.slope == 0.1 && d.h_far == 0.3 && d.gamma == 0.8 && d.support_tol == 1e-7);
  assert_true(d.axis_spacings == 12 && d.lloyd_iterations == 5 && d.band_layers == 0);
  assert_int_equal(d.seed, 9);
  ves_quad_rulespec r;
  assert_int_equal(ves_quad_rule_parse("d6x4", &r), VES_OK);
  assert_true(d.rule.degree == r.degree && d.rule.split == r.split);
  ves_problem_params p;
  ves_problem_params_from_config(&c, &p);
  assert_true(p.discret.eps == d.eps && p.discret.seed == d.seed);
  ves_model_params mp;
  ves_problem_model_params(&c, &mp);
  assert_true(mp.eps == 0.1 && mp.mu == 1 && mp.lambda == 20 && mp.stab == c.stabilization);
  snprintf(c.quadrature, sizeof c.quadrature, "d5");
  assert_int_equal(ves_problem_discret(&c, &d, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "quadrature = d5"));
  assert_true(d.rule.degree == 0 && d.rule.split == 0);
}

int main(void) {
  // clang-format off
  const struct CMUnitTest tests[] = {cmocka_unit_test(test_defaults), cmocka_unit_test(test_keys),
                                     cmocka_unit_test(test_discretization)};
  // clang-format on
  return cmocka_run_group_tests(tests, NULL, NULL);
}
