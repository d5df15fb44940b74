/* vesica — tests of the restoration of the phase field's profile
 * (profile.h, [solver] profile_every): a profile widened by 30% about its
 * zero set is brought back to the tanh profile and its energy; a tanh
 * profile is left nearly unchanged; in the time loop with A and V held, the
 * steps after each restoration bring A and V back to their targets, and
 * the restoration is off by default. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "ves/integrate.h"
#include "ves/profile.h"
#include "ves/project.h"
#include "ves/setup.h"
#include "vesicle_impl.h"

/* max over the points of |a - b| of the phi0 rows of two point data sets */
static double max_dphi(int nq, const double *a, const double *b) {
  double m = 0;
  for (int al = 0; al < nq; al++) m = fmax(m, fabs(a[6 * (size_t)al] - b[6 * (size_t)al]));
  return m;
}

/* A profile widened by 30% about the same zero set (tanh(atanh(phi)/1.3),
 * fitted onto the basis) is restored to the tanh profile: phi and E come
 * back, where the widening moved phi by ~0.1 and E by O(1). A second
 * restoration changes the first one's result much less than the widening. */
static void test_restore_widened(void **state) {
  (void)state;
  ves_setup *s = bump_setup("shape.delta=0.15");
  ves_model *m = s->model;
  const ves_quad *q = s->quad;
  const int n = s->nodes->n, nq = q->nq;
  double *y = malloc(2 * (size_t)n * sizeof *y), *pd0 = malloc(6 * (size_t)nq * sizeof *pd0);
  double *pd = malloc(6 * (size_t)nq * sizeof *pd), *f = malloc((size_t)nq * sizeof *f);
  double *c = malloc((size_t)n * sizeof *c);
  assert_non_null(y && pd0 && pd && f && c);
  ves_model_reference(m, y);
  ves_model_point_data(m, pd0);
  double E0, A0, V0, E, A, V;
  assert_int_equal(ves_model_eval(m, y, VES_F_E | VES_F_A | VES_F_V, &E0, &A0, &V0, 0, 0, 0),
                   VES_OK);
  for (int al = 0; al < nq; al++)
    f[al] = tanh(atanh(fmax(-1 + 1e-15, fmin(1 - 1e-15, pd0[6 * (size_t)al]))) / 1.3);
  assert_int_equal(ves_project_l2(q, n, f, c, 1e-12, 3, NULL, NULL), VES_OK);
  ves_quad_field(q, c, 2, pd);
  assert_int_equal(ves_model_set_points(m, pd), VES_OK);
  double Ew;
  assert_int_equal(ves_model_eval(m, y, VES_F_E, &Ew, 0, 0, 0, 0, 0), VES_OK);
  const double dw = max_dphi(nq, pd, pd0);

  ves_profile *p = NULL;
  assert_int_equal(ves_profile_create(&p), VES_OK);
  ves_profile_info info;
  assert_int_equal(ves_profile_restore(p, m, y, &info), VES_OK);
  ves_model_point_data(m, pd);
  assert_int_equal(ves_model_eval(m, y, VES_F_E | VES_F_A | VES_F_V, &E, &A, &V, 0, 0, 0), VES_OK);
  const double dr = max_dphi(nq, pd, pd0);
  printf("# widened: max dphi %.3e, E %.6f; restored: max dphi %.3e, E %.6f (E0 %.6f), "
         "A/A0 - 1 %.2e, V/V0 - 1 %.2e, %d segments\n",
         dw, Ew, dr, E, E0, A / A0 - 1, V / V0 - 1, info.segments);
  /* the widening is a large change; the restoration undoes it to the fit's
   * own error (the L2 fit at eps 0.15, h_band 0.5 eps deviates from tanh by
   * ~1e-3 at the points): 20x below the widening, E to 1% of its change */
  assert_true(dw > 0.05);
  assert_true(dr < dw / 20);
  assert_true(fabs(E - E0) < 0.01 * fabs(Ew - E0));
  /* the zero set stays: A and V to the smoothing's error, O(1e-4) relative */
  assert_true(fabs(A / A0 - 1) < 1e-3 && fabs(V / V0 - 1) < 1e-3);

  /* a second restoration of the restored (tanh) profile: a small change */
  assert_int_equal(ves_profile_restore(p, m, y, &info), VES_OK);
  double *pd2 = malloc(6 * (size_t)nq * sizeof *pd2);
  assert_non_null(pd2);
  ves_model_point_data(m, pd2);
  const double d2 = max_dphi(nq, pd2, pd);
  printf("# restored again: max dphi %.3e\n", d2);
  assert_true(d2 < dw / 20); /* the fit's error again, not a drift */

  ves_profile_destroy(&p);
  assert_null(p);
  free(y), free(pd0), free(pd), free(pd2), free(f), free(c);
  ves_setup_destroy(&s);
}

/* The time loop with A and V held and a restoration after every step: each
 * step brings A and V back to their targets (the restoration moves them),
 * the report says so, and E* falls over the run. */
static void test_sim_constrained(void **state) {
  (void)state;
  ves_setup *s = small_setup();
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  ip.t_end = 0.05, ip.adaptive = 0, ip.dt_initial = ip.dt_max = 0.01;
  ip.profile_every = 1;
  ves_sim *sim = make_sim(s, "newton", &ip);
  double E0, A0, V0;
  ves_sim_initial(sim, &E0, &A0, &V0);
  ves_step_report rep;
  int steps = 0;
  while (ves_sim_step(sim, &rep) == VES_OK) {
    steps++;
    ves_sim_state st;
    ves_sim_get_state(sim, &st, NULL);
    printf("# step %ld E* %.6f (restored %.6f) |A/A0-1| %.1e |V/V0-1| %.1e, restored A/A0-1 "
           "%.1e, shift %.2e\n",
           rep.step, rep.E, st.E, fabs(rep.A / A0 - 1), fabs(rep.V / V0 - 1), st.A / A0 - 1,
           rep.profile_shift);
    assert_int_equal(rep.profile_status, VES_OK);
    assert_int_equal(rep.profile_restored, 1);
    /* constraints solved to ctol = 1e-10 relative (backend default), also
     * from a start the restoration moved off them */
    assert_true(fabs(rep.A / A0 - 1) <= 1e-8);
    assert_true(fabs(rep.V / V0 - 1) <= 1e-8);
    /* the restoration itself moved A off A0 (by the smoothing of the zero
     * set and the profile's stretch, ~1e-5 here), 1000x above the solve's
     * tolerance: the step above started off the constraint */
    assert_true(fabs(st.A / A0 - 1) > 1e-7);
  }
  assert_int_equal(steps, 5);
  assert_true(rep.E < E0);
  ves_sim_destroy(&sim);

  /* off by default: no restoration reported */
  ves_integrate_params_default(&ip);
  assert_int_equal(ip.profile_every, 0);
  ip.t_end = 0.01, ip.adaptive = 0, ip.dt_initial = ip.dt_max = 0.01;
  sim = make_sim(s, "newton", &ip);
  assert_int_equal(ves_sim_step(sim, &rep), VES_OK);
  assert_int_equal(rep.profile_restored, 0);
  ves_sim_destroy(&sim);
  ves_setup_destroy(&s);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_restore_widened),
      cmocka_unit_test(test_sim_constrained),
  };
  return cmocka_run_group_tests_name("profile", tests, NULL, NULL);
}
