/* vesica — tests of the status codes and the per-thread error record
 * (status.h): VES_CHECK records the failed condition and its place, VES_CALL
 * the places it passes, a plain return is named by the call that received
 * it, and the formatted text carries all of it. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <string.h>

#include "ves/status.h"

static ves_status inner(int x) {
  VES_CHECK(x > 0, VES_ERR_ARG);
  return VES_OK;
}
static ves_status plain(void) { return VES_ERR_SINGULAR; }
static ves_status outer(int x) {
  VES_CALL(inner(x));
  return VES_OK;
}
static ves_status outer_plain(void) {
  VES_CALL(plain());
  return VES_OK;
}
static ves_status failing(void) { VES_FAIL(VES_ERR_GEOM, "the curve crosses the axis"); }

static void test_check_and_call(void **state) {
  (void)state;
  ves_error_clear();
  assert_int_equal(ves_error_last()->code, VES_OK);
  assert_int_equal(outer(1), VES_OK);
  assert_int_equal(ves_error_last()->code, VES_OK); /* success records nothing */
  assert_int_equal(outer(-1), VES_ERR_ARG);
  const ves_error *e = ves_error_last();
  assert_int_equal(e->code, VES_ERR_ARG);
  assert_string_equal(e->what, "failed: x > 0");
  assert_string_equal(e->origin.func, "inner");
  assert_int_equal(e->depth, 1);
  assert_string_equal(e->trace[0].func, "outer");
  char buf[512];
  ves_error_format(VES_ERR_ARG, buf, sizeof buf);
  assert_non_null(strstr(buf, "invalid argument: failed: x > 0 (test_status.c:"));
  assert_non_null(strstr(buf, " in inner; via test_status.c:"));
  /* another code than the record's: the status text alone */
  ves_error_format(VES_ERR_IO, buf, sizeof buf);
  assert_string_equal(buf, "input/output error");
}

static void test_plain_return(void **state) {
  (void)state;
  ves_error_clear();
  assert_int_equal(outer(-1), VES_ERR_ARG); /* a stale record of another code */
  assert_int_equal(outer_plain(), VES_ERR_SINGULAR);
  const ves_error *e = ves_error_last();
  assert_int_equal(e->code, VES_ERR_SINGULAR);
  assert_string_equal(e->what, "plain() returned");
  assert_string_equal(e->origin.func, "outer_plain");
  assert_int_equal(failing(), VES_ERR_GEOM);
  assert_string_equal(ves_error_last()->what, "the curve crosses the axis");
  /* a small buffer: cut, terminated */
  char small[16];
  ves_error_format(VES_ERR_GEOM, small, sizeof small);
  assert_int_equal(strlen(small), sizeof small - 1);
}

/* The trace keeps VES_ERROR_TRACE places and drops the outer ones. */
static ves_status deep(int k) {
  if (k == 0) VES_CHECK(0, VES_ERR_NOCONV);
  VES_CALL(deep(k - 1));
  return VES_OK;
}
static void test_trace_bounded(void **state) {
  (void)state;
  ves_error_clear();
  assert_int_equal(deep(2 * VES_ERROR_TRACE), VES_ERR_NOCONV);
  assert_int_equal(ves_error_last()->depth, VES_ERROR_TRACE);
  char buf[1024];
  ves_error_format(VES_ERR_NOCONV, buf, sizeof buf);
  assert_non_null(strstr(buf, "failed: 0"));
}

int main(void) {
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_check_and_call),
      cmocka_unit_test(test_plain_return),
      cmocka_unit_test(test_trace_bounded),
  };
  // clang-format on
  return cmocka_run_group_tests(tests, NULL, NULL);
}
