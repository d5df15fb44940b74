/* vesica — tests of the progress line's estimate of the time left
 * (cli_eta_steps, cli_eta_text in solver/app/cli_loop.c), pure functions of
 * the run's state: exact with constant steps, a range that holds the steps
 * of a run whose relative step dt/t stays constant, bounded by the steps at
 * dt_max and at the next dt, never "unknown", capped by --max-steps; the
 * text's units and rounding. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "app/cli_impl.h"

static ves_config problem(double t_end, double dt_max, int adaptive) {
  ves_config c;
  memset(&c, 0, sizeof c);
  c.t_end = t_end, c.dt_max = dt_max, c.adaptive = adaptive;
  return c;
}

/* Steps of a run from t with steps of r t up to dt_max, the last one
 * ending at t_end: counted one by one (an independent count). */
static long count_steps(double t, double t_end, double r, double dt_max) {
  long n = 0;
  while (t < t_end * (1 - 1e-12)) t += fmin(r * t, dt_max), n++;
  return n;
}

/* Constant steps, and adaptive ones at dt_max: (t_end - t)/dt, one value;
 * 0 at t_end. */
static void test_constant_steps(void **state) {
  (void)state;
  ves_config c = problem(0.1, 5e-3, 0);
  double lo, hi;
  cli_eta_steps(&c, 0, 10, 0.05, 5e-3, 0.0, 0, &lo, &hi);
  assert_true(lo == 10 && hi == 10);
  cli_eta_steps(&c, 0, 20, 0.1, 5e-3, 0.05, 10, &lo, &hi);
  assert_true(lo == 0 && hi == 0);
  c = problem(4, 0.5, 1);
  cli_eta_steps(&c, 0, 30, 1.0, 0.5, 0.9, 10, &lo, &hi);
  assert_true(lo == 6 && hi == 6);
}

/* A run whose relative step stays r: both values of r agree, and the
 * range is the steps of that run (the closed form against a count one by
 * one: they differ by the last geometric step's overshoot past the time
 * dt reaches dt_max, at most one step). */
static void test_constant_relative_step(void **state) {
  (void)state;
  const double rs[] = {0.05, 0.2, 1.0};
  for (int i = 0; i < 3; i++) {
    const double r = rs[i], t = 1e-3, t_end = 4, dt_max = 0.5;
    ves_config c = problem(t_end, dt_max, 1);
    const double t_back = t / pow(1 + r, 10); /* 10 steps of r before t */
    double lo, hi;
    cli_eta_steps(&c, 0, 50, t, r * t, t_back, 10, &lo, &hi);
    const long n = count_steps(t, t_end, r, dt_max);
    printf("# r %.2f: %.0f-%.0f steps, counted %ld\n", r, lo, hi, n);
    assert_true(fabs(lo - hi) <= 1e-9 * hi); /* one relative step: one value */
    assert_true(fabs(lo - (double)n) <= 1);
  }
}

/* Two relative steps (the next step's larger than the window's): a range
 * between their runs' steps, within the steps at dt_max and at dt_next,
 * narrowing as they come together; and finite from the first step on,
 * where the linear bounds are orders of magnitude apart. */
static void test_range(void **state) {
  (void)state;
  const double t = 0.02, t_end = 4, dt_max = 1;
  ves_config c = problem(t_end, dt_max, 1);
  double lo, hi, lo2, hi2;
  cli_eta_steps(&c, 0, 12, t, 0.2 * t, t / pow(1.1, 10), 10, &lo, &hi);
  printf("# r 0.2 and 0.1: %.0f-%.0f steps\n", lo, hi);
  assert_true(lo < hi);
  assert_true(fabs(lo - (double)count_steps(t, t_end, 0.2, dt_max)) <= 1);
  assert_true(fabs(hi - (double)count_steps(t, t_end, 0.1, dt_max)) <= 1);
  assert_true(lo >= ceil((t_end - t) / dt_max) && hi <= ceil((t_end - t) / (0.2 * t)));
  cli_eta_steps(&c, 0, 12, t, 0.2 * t, t / pow(1.18, 10), 10, &lo2, &hi2);
  assert_true(lo2 == lo && hi2 < hi); /* the window's r nearer: narrower */
  /* the first step of a run (dt 1e-4 doubled): no window yet */
  c = problem(4, 1, 1);
  cli_eta_steps(&c, 0, 1, 1e-4, 2e-4, 1e-4, 0, &lo, &hi);
  printf("# first step: %.0f-%.0f steps (linear bounds 4-20000)\n", lo, hi);
  assert_true(isfinite(lo) && isfinite(hi) && lo >= 4 && hi <= 20000 && hi < 100);
  char text[64];
  cli_eta_text(text, sizeof text, 0.5 * lo, 0.5 * hi);
  assert_null(strstr(text, "unknown"));
}

/* --max-steps comes first: both ends capped by the steps it leaves. */
static void test_max_steps(void **state) {
  (void)state;
  ves_config c = problem(1, 10, 1);
  double lo, hi;
  cli_eta_steps(&c, 12, 10, 0.05, 6e-3, 0.03, 9, &lo, &hi);
  assert_true(lo <= 2 && hi == 2);
  cli_eta_steps(&c, 12, 12, 0.05, 6e-3, 0.03, 9, &lo, &hi);
  assert_true(lo == 0 && hi == 0);
}

/* The text: whole seconds below 120 s, minutes below 120 min, else hours,
 * one decimal below 10; one value when both ends print the same. */
static void test_text(void **state) {
  (void)state;
  const struct {
    double lo, hi;
    const char *want;
  } cases[] = {
      {13.4, 32.2, "13-32 s"},  {5.2, 5.4, "5 s"},        {0, 0, "0 s"},
      {90, 150, "1.5-2.5 min"}, {600, 1800, "10-30 min"}, {3 * 3600.0, 7200 * 10.0, "3.0-20 h"},
      {119.6, 119.9, "120 s"}};
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    char text[64];
    cli_eta_text(text, sizeof text, cases[i].lo, cases[i].hi);
    assert_string_equal(text, cases[i].want);
  }
}

int main(void) {
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_constant_steps), cmocka_unit_test(test_constant_relative_step),
      cmocka_unit_test(test_range),          cmocka_unit_test(test_max_steps),
      cmocka_unit_test(test_text),
  };
  return cmocka_run_group_tests_name("eta", tests, NULL, NULL);
}
