/* vesica — the checks of a problem's inputs: a long points file checked in
 * time linear in its length, crossing curves still refused, and the
 * reasons given for a folder as points file, a NUL byte in a points line
 * and a comment after a section header. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "cli_test_impl.h"
#include "app/config.h"

/* Processor seconds of this process, and (children) of its waited-for
 * children: the measure of the work, independent of what else the
 * machine's cores run at the time. */
static double cpu(int children) {
  struct rusage ru;
  getrusage(children ? RUSAGE_CHILDREN : RUSAGE_SELF, &ru);
  return (double)ru.ru_utime.tv_sec + (double)ru.ru_stime.tv_sec +
         1e-6 * (double)(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

/* A half circle of n points from the north pole to the south pole, or
 * (cross) the same with points n/2 and n/2 + 2 swapped: the chords from
 * n/2 - 1 to n/2 + 2 and from n/2 to n/2 + 3 of the convex arc cross. */
static void write_curve(const char *path, int n, int cross) {
  FILE *f = fopen(path, "w");
  assert_non_null(f);
  for (int i = 0; i < n; i++) {
    const int j = !cross ? i : i == n / 2 ? i + 2 : i == n / 2 + 2 ? i - 2 : i;
    const double th = M_PI * j / (n - 1);
    fprintf(f, "%.17g %.17g\n", j == 0 || j == n - 1 ? 0.0 : sin(th), cos(th));
  }
  fclose(f);
}

/* The points file p read through a config whose source is in tmpdir. */
static ves_status read_points(const char *p, char *err, size_t len, int *n) {
  ves_config c;
  ves_config_default(&c);
  snprintf(c.source, sizeof c.source, "%s/problem.ini", tmpdir);
  snprintf(c.points, sizeof c.points, "%s", p);
  double *pts = NULL;
  ves_status st = ves_config_read_points(&c, n, &pts, err, len);
  free(pts);
  return st;
}

/* The time bounds below separate the linear curve check from the
 * all-pairs one (minutes at 200,001 points) by two orders of magnitude; a
 * build with AddressSanitizer and UBSan (make test SAN=1) runs this code a
 * few times slower, so its bounds are 5x wider, still far from quadratic. */
#ifdef __SANITIZE_ADDRESS__
#define SLOWDOWN 5.0
#else
#define SLOWDOWN 1.0
#endif

/* 200,001 points read and checked in ~0.2 s, bound 2 s (all segment pairs:
 * minutes); the same curve with one point moved across it is refused,
 * with the lines of the first crossing pair, as the all-pairs test named. */
static void test_long_curve_linear(void **state) {
  (void)state;
  char p[PATH_MAX], err[1024] = "";
  int n = 0;
  tmp_path(p, sizeof p, "long.txt");
  write_curve(p, 200001, 0);
  double t0 = cpu(0);
  assert_int_equal(read_points(p, err, sizeof err, &n), VES_OK);
  const double dt = cpu(0) - t0;
  assert_int_equal(n, 200001);
  assert_true(dt < 2.0 * SLOWDOWN);
  write_curve(p, 200001, 1);
  t0 = cpu(0);
  assert_int_equal(read_points(p, err, sizeof err, &n), VES_ERR_CONFIG);
  assert_true(cpu(0) - t0 < 2.0 * SLOWDOWN);
  printf("200001 points read and checked: %.2f s\n", dt);
  assert_non_null(strstr(err, "crosses itself: the segment of lines 100000-100001 meets that of "
                              "lines 100003-100004"));
  /* the small crossing curves of test_config.c, with their first pair */
  write_file(p, "0 1\n1 0\n1 1\n0.3 -0.5\n0 -1\n");
  assert_int_equal(read_points(p, err, sizeof err, &n), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "the segment of lines 1-2 meets that of lines 3-4"));
  write_file(p, "0 1\n1 0\n0.5 0.5\n0.2 0\n0 -1\n"); /* touching at a point */
  assert_int_equal(read_points(p, err, sizeof err, &n), VES_ERR_CONFIG);
  write_file(p, "0 1\n0.7 0.7\n1 0\n0.7 -0.7\n0 -1\n");
  const ves_status st = read_points(p, err, sizeof err, &n);
  if (st != VES_OK) fprintf(stderr, "%s\n", err);
  assert_int_equal(st, VES_OK);
  unlink(p);
}

/* vesica check of a problem on a 200,001-point curve: 0.9-1.6 s of
 * processor time on this machine, idle or loaded (the whole check, setup
 * included); the bound of 4 s leaves room for a loaded machine's caches and
 * is still 50x below the all-pairs check (~200 s). */
static void test_check_long_curve(void **state) {
  (void)state;
  char p[PATH_MAX], ini[PATH_MAX];
  tmp_path(p, sizeof p, "curve.txt");
  tmp_path(ini, sizeof ini, "curve.ini");
  write_curve(p, 200001, 0);
  write_file(ini, "[geometry]\nepsilon = 0.2\nbox_r = 2\nbox_z = 2\nband = 2\nh_band = 0.7\n"
                  "h_far = 0.3\n\n[shape]\ntype = curve\npoints = curve.txt\n");
  result r;
  const double t0 = cpu(1);
  run(&r, "check", ini, NULL);
  const double dt = cpu(1) - t0;
  if (r.code != 0) fprintf(stderr, "%s", r.err);
  assert_int_equal(r.code, 0);
  printf("vesica check, 200001-point curve: %.2f s\n", dt);
  assert_true(dt < 4.0 * SLOWDOWN);
  unlink(p), unlink(ini);
}

/* A folder given as points file, and a NUL byte in a line: each named. */
static void test_points_reasons(void **state) {
  (void)state;
  char p[PATH_MAX], err[1024] = "";
  int n = 0;
  tmp_path(p, sizeof p, "folder.txt");
  assert_int_equal(mkdir(p, 0755), 0);
  assert_int_equal(read_points(p, err, sizeof err, &n), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "is a folder"));
  rmdir(p);
  tmp_path(p, sizeof p, "nul.txt");
  FILE *f = fopen(p, "wb");
  assert_non_null(f);
  fwrite("0 1\n0.5\0 0.5\n1 0\n0 -1\n", 1, 22, f);
  fclose(f);
  assert_int_equal(read_points(p, err, sizeof err, &n), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "line 2: holds a NUL byte"));
  /* a line longer than 510 characters still says so */
  f = fopen(p, "w");
  assert_non_null(f);
  fprintf(f, "0 1\n0.5 0.5%600s\n1 0\n0 -1\n", "");
  fclose(f);
  assert_int_equal(read_points(p, err, sizeof err, &n), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "line 2: longer than 510 characters"));
  unlink(p);
}

/* A comment after a section header is dropped, as after a value; other
 * text after the ']' is refused with that reason. */
static void test_section_comment(void **state) {
  (void)state;
  ves_config c;
  char err[1024] = "";
  assert_int_equal(
      ves_config_load_text("[geometry] ; the box\nepsilon = 0.1\n[time]# end\nt_end = 2\n", "p.ini",
                           &c, err, sizeof err),
      VES_OK);
  assert_true(c.epsilon == 0.1 && c.t_end == 2);
  assert_int_equal(
      ves_config_load_text("[geometry] box\nepsilon = 0.1\n", "p.ini", &c, err, sizeof err),
      VES_ERR_CONFIG);
  assert_non_null(strstr(err, "line 1"));
  assert_non_null(strstr(err, "text after the section header's ']'"));
  assert_int_equal(ves_config_load_text("[geometry\nepsilon = 0.1\n", "p.ini", &c, err, sizeof err),
                   VES_ERR_CONFIG);
  assert_non_null(strstr(err, "needs a closing ']'"));
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_input_checks")) return 1;
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_long_curve_linear),
      cmocka_unit_test(test_check_long_curve),
      cmocka_unit_test(test_points_reasons),
      cmocka_unit_test(test_section_comment),
  };
  return cmocka_run_group_tests(tests, setup_all, teardown_all);
}
