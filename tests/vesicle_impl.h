/* vesica — the small vesicle of the time-loop tests and a simulation on it,
 * shared by test_integrate.c and test_spectrum.c (include after cmocka.h:
 * failures end the test with fail_msg). */
#ifndef VES_TEST_VESICLE_IMPL_H
#define VES_TEST_VESICLE_IMPL_H

#include "ves/backend.h"
#include "ves/config.h"
#include "ves/integrate.h"
#include "ves/setup.h"

/* A small vesicle: sphere with a P2 bump of amplitude `delta`, eps = 0.15;
 * `stab` the [geometry] stabilization ("0": the paper's E, as the stored
 * trajectories and the reset identities of the tests were made). */
static inline ves_setup *bump_setup_stab(const char *delta, const char *stab) {
  ves_config cfg;
  char err[512];
  const char *set[] = {"geometry.epsilon=0.15",
                       "geometry.box_r=1.9",
                       "geometry.box_z=1.9",
                       "geometry.band=3",
                       "shape.mode=2",
                       delta,
                       stab};
  if (ves_config_load(NULL, 7, set, &cfg, err, sizeof err) != VES_OK) fail_msg("config: %s", err);
  ves_setup *s = NULL;
  if (ves_setup_create(&cfg, VES_PHI0_L2, &s, err, sizeof err) != VES_OK)
    fail_msg("setup: %s", err);
  return s;
}

static inline ves_setup *bump_setup(const char *delta) {
  return bump_setup_stab(delta, "geometry.stabilization=0");
}

/* The out-of-equilibrium vesicle of most tests: delta = 0.15. */
static inline ves_setup *small_setup(void) { return bump_setup("shape.delta=0.15"); }

static inline ves_sim *make_sim(ves_setup *s, const char *backend, ves_integrate_params *ip) {
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  ves_sim *sim = NULL;
  ves_status st = ves_sim_create(s->model, ves_backend_find(backend), &bo, ip, &sim);
  if (st != VES_OK) fail_msg("sim: %s", ves_status_str(st));
  return sim;
}

#endif
