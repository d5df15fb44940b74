/* vesica — the small vesicle of the time-loop tests and a simulation on it,
 * shared by test_integrate.c and test_spectrum.c, and the smooth motion of
 * test_reconnect.c and test_remesh.c (include after cmocka.h: failures end
 * the test with fail_msg). */
#ifndef VES_TEST_VESICLE_IMPL_H
#define VES_TEST_VESICLE_IMPL_H

#include <math.h>

#include "ves/backend.h"
#include "app/config.h"
#include "app/problem.h"
#include "ves/integrate.h"
#include "ves/setup.h"

/* The small vesicle's configuration: the unit sphere with a P2 bump of
 * amplitude `delta` ("shape.delta=..."), eps = 0.15, band 3 eps, in a 1.9 x
 * 1.9 box; `stab` the [geometry] stabilization ("geometry.stabilization=0":
 * the paper's E, which the stored trajectories and the reset identities of
 * the tests assume). VES_OK, or the status with the reason in err. */
static inline ves_status bump_config(const char *delta, const char *stab, ves_config *cfg,
                                     char *err, size_t errlen) {
  const char *set[] = {"geometry.epsilon=0.15",
                       "geometry.box_r=1.9",
                       "geometry.box_z=1.9",
                       "geometry.band=3",
                       "shape.mode=2",
                       delta,
                       stab};
  return ves_config_load(NULL, 7, set, cfg, err, errlen);
}

/* The discretization of cfg (ves_problem_discret); a failure ends the test. */
static inline ves_discret_params discret_of(const ves_config *cfg) {
  ves_discret_params d;
  char err[256];
  if (ves_problem_discret(cfg, &d, err, sizeof err) != VES_OK) fail_msg("discretization: %s", err);
  return d;
}

/* Its setup (L2-projected phi0); a failure ends the test. */
static inline ves_setup *bump_setup_stab(const char *delta, const char *stab) {
  ves_config cfg;
  char err[512];
  if (bump_config(delta, stab, &cfg, err, sizeof err) != VES_OK) fail_msg("config: %s", err);
  ves_setup *s = NULL;
  if (ves_problem_setup_create(&cfg, VES_PHI0_L2, &s, err, sizeof err) != VES_OK)
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

/* A smooth motion y = X + u(X) of the nodes (test_reconnect.c, test_remesh.c):
 * u_r = amp R w (1 + 0.5 sin(3Z + 0.7) + 0.3 cos(2R^2) + 2Z) odd in R (0 on
 * the axis), u_z = amp w (sin(2.5Z + 0.3) + 0.5 cos(3R^2 - Z) + 2R^2) even in
 * R, w = (1 - (R/LR)^2)(1 - (Z/LZ)^2) zero on the wall (so the fixed dofs keep
 * their values). The 2Z and 2R^2 terms add shear. X and y may be the same
 * array. */
static inline void smooth_motion(const ves_nodes *nodes, const double *X, double amp, double *y) {
  const double LR = nodes->LR, LZ = nodes->LZ;
  for (int a = 0; a < nodes->n; a++) {
    const double R = X[2 * a], Z = X[2 * a + 1];
    const double w = (1 - (R / LR) * (R / LR)) * (1 - (Z / LZ) * (Z / LZ));
    y[2 * a] = R + amp * R * w * (1 + 0.5 * sin(3 * Z + 0.7) + 0.3 * cos(2 * R * R) + 2 * Z);
    y[2 * a + 1] = Z + amp * w * (sin(2.5 * Z + 0.3) + 0.5 * cos(3 * R * R - Z) + 2 * R * R);
  }
}

#endif
