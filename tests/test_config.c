/* vesica — tests of problem-file parsing: defaults, overrides, and every
 * error path with a message naming the file, the key and the reason. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ves/backend.h"
#include "app/config.h"
#include "ves/geom.h"
#include "ves/integrate.h"
#include "ves/lme.h"
#include "ves/reconnect.h"
#include "ves/shape.h"

/* Write text to a fresh temporary file; returns its path in buf. */
static void write_tmp(char *buf, size_t len, const char *text) {
  snprintf(buf, len, "/tmp/vesica_cfg_XXXXXX");
  int fd = mkstemp(buf);
  assert_true(fd >= 0);
  FILE *f = fdopen(fd, "w");
  assert_non_null(f);
  fputs(text, f);
  fclose(f);
}

static void test_defaults_and_overrides(void **state) {
  (void)state;
  char path[64], err[512] = "";
  write_tmp(path, sizeof path,
            "; comment\n[geometry]\nepsilon = 0.02\n\n[shape]\ntype = spheroid\n"
            "reduced_volume = 0.9\norientation = prolate\n[material]\nc0 = 1.5\n");
  ves_config c;
  const char *set[] = {"material.c0=2.5", "geometry.h_band=0.4"};
  assert_int_equal(ves_config_load(path, 2, set, &c, err, sizeof err), VES_OK);
  assert_true(c.epsilon == 0.02 && c.reduced_volume == 0.9 && c.c0 == 2.5 && c.h_band == 0.4);
  assert_string_equal(c.shape_type, "spheroid");
  assert_string_equal(c.orientation, "prolate");
  assert_true(c.gamma == 0.6 && c.band_layers == 1); /* defaults untouched */
  assert_true(c.reconnect_every == 0 && c.reconnect_cond_max == 0 && c.reconnect_det_min == 0);
  const char *rc[] = {"reconnect.every=20", "reconnect.cond_max=1.5", "reconnect.det_min=0.5"};
  ves_config c2;
  assert_int_equal(ves_config_load(NULL, 3, rc, &c2, err, sizeof err), VES_OK);
  assert_true(c2.reconnect_every == 20 && c2.reconnect_cond_max == 1.5 &&
              c2.reconnect_det_min == 0.5);
  unlink(path);
}

/* Each bad input: the status and a fragment the message must contain. */
static void expect_error(const char *text, int nset, const char *const *set, ves_status want,
                         const char *fragment) {
  char path[64], err[512] = "";
  ves_config c;
  if (text)
    write_tmp(path, sizeof path, text);
  else
    snprintf(path, sizeof path, "/nonexistent/vesica.ini");
  ves_status st = ves_config_load(path, nset, set, &c, err, sizeof err);
  if (st != want || !strstr(err, fragment))
    fail_msg("input [%s]: status %d (want %d), message '%s' (want '%s')", text ? text : path, st,
             want, err, fragment);
  if (text) {
    /* the message names the file, or --set for an override */
    assert_non_null(strstr(err, nset ? "--set" : path));
    unlink(path);
  }
}

static void test_errors(void **state) {
  (void)state;
  /* a table of cases, laid out by hand */
  // clang-format off
  expect_error(NULL, 0, NULL, VES_ERR_IO, "cannot open");
  expect_error("[geometry]\nepsilon = abc\n", 0, NULL, VES_ERR_CONFIG, "epsilon");
  expect_error("[geometry]\nepsilon = abc\n", 0, NULL, VES_ERR_CONFIG, "not a number");
  expect_error("[geometry]\nepsilon = 0.9\n", 0, NULL, VES_ERR_CONFIG, "out of range");
  expect_error("[geometry]\nepsilon = 0.04 0.05\n", 0, NULL, VES_ERR_CONFIG, "not a number");
  expect_error("[geometry]\nepsilom = 0.04\n", 0, NULL, VES_ERR_CONFIG, "unknown key");
  expect_error("[geometri]\nepsilon = 0.04\n", 0, NULL, VES_ERR_CONFIG, "unknown section");
  expect_error("[shape]\ntype = cube\n", 0, NULL, VES_ERR_CONFIG, "allowed: sphere|spheroid|discocyte");
  expect_error("[shape]\nmode = 2.5\n", 0, NULL, VES_ERR_CONFIG, "not an integer");
  expect_error("[shape]\nreduced_volume = 1.2\n", 0, NULL, VES_ERR_CONFIG, "reduced_volume");
  expect_error("[material]\nlambda_ratio = 5\n", 0, NULL, VES_ERR_CONFIG, "lambda_ratio");
  expect_error("[geometry]\nbox_r = 0.5\n", 0, NULL, VES_ERR_CONFIG, "do not fit");
  expect_error("[geometry]\nh_far = 0.001\n", 0, NULL, VES_ERR_CONFIG, "h_far");
  expect_error("[geometry]\nepsilon =\n", 0, NULL, VES_ERR_CONFIG, "epsilon");
  expect_error("[shape]\ntype = curve\n", 0, NULL, VES_ERR_CONFIG, "needs a points file");
  expect_error("[time]\ndt_initial = 1\ndt_max = 0.1\n", 0, NULL, VES_ERR_CONFIG, "dt_initial");
  /* BDF2 (time.order = 2): zero-stable only for step ratios below 1 + sqrt 2,
   * and an implicit scheme */
  expect_error("[time]\norder = 2\ngrowth_max = 3\n", 0, NULL, VES_ERR_CONFIG,
               "order = 2 needs at most 2.4");
  expect_error("[time]\norder = 2\n[solver]\nbackend = euler\n", 0, NULL, VES_ERR_CONFIG,
               "explicit steps");
  /* ... and the message names the override that runs such a file with euler */
  expect_error("[time]\norder = 2\n[solver]\nbackend = euler\n", 0, NULL, VES_ERR_CONFIG,
               "--set time.order=1");
  expect_error("[solver]\nbackend = cg\n", 0, NULL, VES_ERR_CONFIG, "ipopt|nlopt|newton|euler");
  expect_error("[constraints]\narea = 2\n", 0, NULL, VES_ERR_CONFIG, "out of range");
  expect_error("[geometry]\nepsilon = 0.3\n", 0, NULL, VES_ERR_CONFIG, "too large for the box");
  expect_error("epsilon = 0.1\n[geometry]\n", 0, NULL, VES_ERR_CONFIG, "outside a section");
  expect_error("[geometry\nepsilon = 0.1\n", 0, NULL, VES_ERR_CONFIG,
               "line 1: '[geometry': a section header needs a closing ']'");
  expect_error("[protocol]\nvolume_rate = -1\nvolume_final = 0.8\n[constraints]\nvolume = 0\n", 0,
               NULL, VES_ERR_CONFIG, "volume_rate");
  expect_error("[protocol]\nvolume_rate = -1\n", 0, NULL, VES_ERR_CONFIG, "must be below 1");
  expect_error("[protocol]\nvolume_rate = 1\nvolume_final = 0.5\n", 0, NULL, VES_ERR_CONFIG,
               "must be above 1");
  expect_error("[protocol]\nc0_after = 3\n", 0, NULL, VES_ERR_CONFIG, "c0_after");
  expect_error("[protocol]\nc0_until = 3\n", 0, NULL, VES_ERR_CONFIG, "c0_until");
  expect_error("[protocol]\nc0_time = 0.5\nc0_after = 1\nc0_until = 0.5\n", 0, NULL,
               VES_ERR_CONFIG, "c0_until");
  /* the C0 ramp: its keys need its start, an end after it, no c0_time, a change, a start
   * before t_end (default t_end 1) */
  expect_error("[protocol]\nc0_ramp_to = 3\n", 0, NULL, VES_ERR_CONFIG, "c0_ramp_to: has no effect");
  expect_error("[protocol]\nc0_ramp_end = 3\n", 0, NULL, VES_ERR_CONFIG, "c0_ramp_end: has no");
  expect_error("[protocol]\nc0_ramp_start = 0.5\nc0_ramp_end = 0.5\nc0_ramp_to = 2\n", 0, NULL,
               VES_ERR_CONFIG, "c0_ramp_end must come after it");
  expect_error("[protocol]\nc0_ramp_start = 0\nc0_ramp_end = 0.5\nc0_ramp_to = 2\nc0_time = 0.1\n"
               "c0_after = 1\n",
               0, NULL, VES_ERR_CONFIG, "excludes c0_time");
  expect_error("[protocol]\nc0_ramp_start = 0\nc0_ramp_end = 0.5\n", 0, NULL, VES_ERR_CONFIG,
               "nothing to do");
  expect_error("[protocol]\nc0_ramp_start = 1\nc0_ramp_end = 2\nc0_ramp_to = 2\n", 0, NULL,
               VES_ERR_CONFIG, "before [time] t_end");
  /* k and mu are the units (E* = E/k, t* = t k/(mu R0^3)): any other value is refused, with why */
  expect_error("[material]\nk = 2\n", 0, NULL, VES_ERR_CONFIG, "the energy unit (E* = E/k), so 1 only");
  expect_error("[material]\nmu = 0.5\n", 0, NULL, VES_ERR_CONFIG, "the time unit");
  expect_error("[reconnect]\ncond_max = 1\n", 0, NULL, VES_ERR_CONFIG, "above 1");
  expect_error("[reconnect]\ndet_min = 1\n", 0, NULL, VES_ERR_CONFIG, "below 1");
  expect_error("[reconnect]\nevery = -1\n", 0, NULL, VES_ERR_CONFIG, "out of range");
  expect_error("[protocol]\nc0_time = 2\nc0_after = 3\n", 0, NULL, VES_ERR_CONFIG,
               "after [time] t_end");
  // clang-format on
  const char *s1[] = {"geometry.epsilon"};
  expect_error("", 1, s1, VES_ERR_CONFIG, "section.key=value");
  const char *s2[] = {"geometry.nope=1"};
  expect_error("", 1, s2, VES_ERR_CONFIG, "unknown key");
  const char *s3[] = {"geometry.epsilon=-1"};
  expect_error("", 1, s3, VES_ERR_CONFIG, "out of range");
  const char *s4[] = {"=3"};
  expect_error("", 1, s4, VES_ERR_CONFIG, "section.key=value");
  ves_config c;
  assert_int_equal(ves_config_load(NULL, 1, NULL, &c, NULL, 0), VES_ERR_ARG);
}

/* The problem-file syntax: every error names the line and the cause;
 * what INI files in the wild hold (a byte-order mark, CRLF, long comment
 * lines, inline comments, quotes, upper case) is accepted. */
static void test_syntax(void **state) {
  (void)state;
  char big[6000], longval[700];
  memset(big, 'x', sizeof big);
  big[0] = ';', big[sizeof big - 1] = 0;
  memset(longval, '1', sizeof longval);
  longval[sizeof longval - 1] = 0;
  struct {
    const char *text, *frag;
  } bad[] = {
      {"[geometry]\nepsilon = 0.02\nepsilon = 0.03\n",
       "line 3: [geometry] epsilon: duplicate key (first at line 2)"},
      {"[geometry]\nepsilon = 0.02\n[shape]\n[geometry]\nband = 4\n",
       "line 4: [geometry]: duplicate section (first at line 1)"},
      {"[geometry]\nEPSILON = 0.02\nepsilon = 0.03\n", "line 3: [geometry] epsilon: duplicate key"},
      {"[geometry]\nepsilon 0.02\n", "line 2: 'epsilon 0.02': expected key = value"},
      {"[geometry]\n= 0.02\n", "line 2: '= 0.02': not a key name"},
      {"[]\n", "line 1: '[]': not a section name"},
      {"\n\n[geometry]\nepsilon = abc\n", "line 4: [geometry] epsilon = 'abc': not a number"},
      {"[geometry]\nepsilon = 0.02\n[nope]\n", "line 3: [nope]: unknown section"},
      {"[shape]\nnope = 1\n", "line 2: [shape] nope: unknown key"},
      {"\xef\xbb\xbf[geometry]\nepsilon = 0.9\n", "line 2: [geometry] epsilon = '0.9'"},
      {"a = 1\n", "line 1: a: key outside a section"},
      {"[geometry]\r\nepsilon = 2e\r\n", "line 2: [geometry] epsilon = '2e': not a number"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
    expect_error(bad[i].text, 0, NULL, VES_ERR_CONFIG, bad[i].frag);
  char text[8000];
  snprintf(text, sizeof text, "[shape]\npoints = %s\n", longval);
  expect_error(text, 0, NULL, VES_ERR_CONFIG, "line 2: [shape] points: value longer than");
  /* a NUL byte: not a text file, the line named */
  char path[64], err[512] = "";
  snprintf(path, sizeof path, "/tmp/vesica_cfg_XXXXXX");
  int fd = mkstemp(path);
  assert_true(fd >= 0);
  assert_int_equal(write(fd, "[geometry]\nepsilon = 0.1\0\n", 26), 26);
  close(fd);
  ves_config c;
  assert_int_equal(ves_config_load(path, 0, NULL, &c, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "line 2: a NUL byte"));
  unlink(path);
  /* a folder is not a problem file */
  assert_int_equal(ves_config_load("/tmp", 0, NULL, &c, err, sizeof err), VES_ERR_IO);
  assert_non_null(strstr(err, "/tmp: is a folder"));
  assert_int_equal(ves_config_load("/dev/null", 0, NULL, &c, err, sizeof err), VES_ERR_IO);
  assert_non_null(strstr(err, "not a regular file"));
  /* accepted: a BOM, CRLF, a 6,000-character comment line, inline comments,
   * quotes, upper case, blanks around names */
  snprintf(text, sizeof text,
           "\xef\xbb\xbf%s\r\n# c\r\n[ Geometry ]\r\nEpsilon = 0.02 ; inline\r\n"
           "band=4.5# inline\n[shape]\ntype = \"spheroid\"\nreduced_volume = '0.9'\n"
           "orientation = prolate",
           big);
  write_tmp(path, sizeof path, text);
  assert_int_equal(ves_config_load(path, 0, NULL, &c, err, sizeof err), VES_OK);
  assert_true(c.epsilon == 0.02 && c.band == 4.5 && c.reduced_volume == 0.9);
  assert_string_equal(c.shape_type, "spheroid");
  assert_string_equal(c.orientation, "prolate");
  unlink(path);
}

/* Points files: read relative to the problem file's folder; bad lines and
 * curves not starting and ending on the axis are refused. */
static void test_points_file(void **state) {
  (void)state;
  char pts[64], err[512] = "";
  write_tmp(pts, sizeof pts, "# a square-ish curve\n0 1\n0.7 0.7\n1 0\n0.7 -0.7\n0 -1\n");
  ves_config c;
  ves_config_default(&c);
  snprintf(c.source, sizeof c.source, "/tmp/problem.ini");
  snprintf(c.points, sizeof c.points, "%s", pts + 5); /* relative to /tmp */
  int n = 0;
  double *p = NULL;
  assert_int_equal(ves_config_read_points(&c, &n, &p, err, sizeof err), VES_OK);
  assert_int_equal(n, 5);
  assert_true(p[2] == 0.7 && p[9] == -1.0);
  free(p);
  unlink(pts);
  write_tmp(pts, sizeof pts, "0 1\n0.7 x\n");
  snprintf(c.points, sizeof c.points, "%s", pts);
  assert_int_equal(ves_config_read_points(&c, &n, &p, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "line 2"));
  unlink(pts);
  write_tmp(pts, sizeof pts, "0.1 1\n0.7 0.7\n1 0\n0 -1\n");
  snprintf(c.points, sizeof c.points, "%s", pts);
  assert_int_equal(ves_config_read_points(&c, &n, &p, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "R = 0"));
  unlink(pts);
  snprintf(c.points, sizeof c.points, "/nonexistent/points.txt");
  assert_int_equal(ves_config_read_points(&c, &n, &p, err, sizeof err), VES_ERR_IO);
  assert_null(p);
  /* curves the shape cannot use, each refused with the lines at fault */
  struct {
    const char *text, *frag;
  } bad[] = {
      /* segment (0,1)-(1,0) crossed by (1,1)-(0.3,-0.5) */
      {"0 1\n1 0\n1 1\n0.3 -0.5\n0 -1\n",
       "crosses itself: the segment of lines 1-2 meets that of lines 3-4"},
      /* a figure-eight: the lower lobe comes back across the upper */
      {"0 1\n0.8 0.5\n0.2 0\n0.8 -0.5\n0.5 0.6\n0 -1\n", "crosses itself"},
      /* touching itself at a point */
      {"0 1\n1 0\n0.5 0.5\n0.2 0\n0 -1\n", "crosses itself"},
      {"# south to north\n0 -1\n0.7 -0.7\n1 0\n0.7 0.7\n0 1\n",
       "run from Z = -1 (line 2) to Z = 1 (line 6): a curve goes from the north pole"},
      {"0 1\n0.7 0.7\n0 0\n0.7 -0.7\n0 -1\n", "line 3: R = 0 inside the curve"},
      {"0 1\n0.7 0.7\n0.7 0.7\n1 0\n0 -1\n", "line 3: repeats the point of line 2"},
  };
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    write_tmp(pts, sizeof pts, bad[i].text);
    snprintf(c.points, sizeof c.points, "%s", pts);
    err[0] = 0;
    assert_int_equal(ves_config_read_points(&c, &n, &p, err, sizeof err), VES_ERR_CONFIG);
    if (!strstr(err, bad[i].frag) || !strstr(err, pts))
      fail_msg("curve %zu: '%s' (want '%s')", i, err, bad[i].frag);
    assert_null(p);
    unlink(pts);
  }
  /* the project's cup passes */
  snprintf(c.source, sizeof c.source, "data/x.ini");
  snprintf(c.points, sizeof c.points, "cup.txt");
  assert_int_equal(ves_config_read_points(&c, &n, &p, err, sizeof err), VES_OK);
  assert_true(n > 200);
  free(p);
}

/* Regressions from `make fuzz` (tests/fuzz/): (1) a value with no ';' or
 * '#' after it anywhere in the file: the inline-comment search ran past the
 * file's text, which is not NUL-terminated (a heap over-read that
 * AddressSanitizer reports: run with make test SAN=1); (2) a curve whose
 * polygon is valid but whose spline swings across the axis (a long last
 * segment after short ones), whose area would be NaN: the shape refuses
 * it, and the setup says why with exit code 2. */
static void test_fuzz_regressions(void **state) {
  (void)state;
  char path[64], err[512] = "";
  ves_config c;
  write_tmp(path, sizeof path, "[time]\nt_end = 2\ndt_initial = 1e-3");
  assert_int_equal(ves_config_load(path, 0, NULL, &c, err, sizeof err), VES_OK);
  assert_true(c.t_end == 2 && c.dt_initial == 1e-3);
  unlink(path);
  write_tmp(path, sizeof path, "[time]\nt_end = 2 ; c\ndt_initial = 1e-3\n");
  assert_int_equal(ves_config_load(path, 0, NULL, &c, err, sizeof err), VES_OK);
  assert_true(c.t_end == 2 && c.dt_initial == 1e-3);
  unlink(path);

  char pts[64];
  write_tmp(pts, sizeof pts, "0 1\n0.5 0.8\n1 0\n0.5 -0.8\n0 -18"); /* the fuzzer's input */
  ves_config_default(&c);
  snprintf(c.source, sizeof c.source, "/tmp/problem.ini");
  snprintf(c.shape_type, sizeof c.shape_type, "curve");
  snprintf(c.points, sizeof c.points, "%s", pts);
  int n = 0;
  double *p = NULL;
  assert_int_equal(ves_config_read_points(&c, &n, &p, err, sizeof err), VES_OK); /* polygon ok */
  ves_shape_params sp;
  ves_shape_params_default(&sp);
  sp.kind = VES_SHAPE_CURVE, sp.npts = n, sp.pts = p;
  ves_shape *shape = NULL;
  assert_int_equal(ves_shape_create(&sp, &shape), VES_ERR_GEOM);
  assert_null(shape);
  /* the same points with the last one at Z = -1: accepted, area 4 pi */
  free(p);
  unlink(pts);
  write_tmp(pts, sizeof pts, "0 1\n0.5 0.8\n1 0\n0.5 -0.8\n0 -1\n");
  snprintf(c.points, sizeof c.points, "%s", pts);
  assert_int_equal(ves_config_read_points(&c, &n, &p, err, sizeof err), VES_OK);
  sp.npts = n, sp.pts = p;
  assert_int_equal(ves_shape_create(&sp, &shape), VES_OK);
  double A, V;
  ves_shape_sharp(shape, &A, &V);
  assert_true(fabs(A / (4 * M_PI) - 1) < 1e-9 && V > 0);
  ves_shape_destroy(&shape);
  free(p);
  unlink(pts);
}

/* geometry.resolution names h_band (0.6, 0.5, 0.4), the last of the two
 * keys wins, the name follows a given h_band (custom for any other), custom
 * alone is refused, and the stored text reads back to the same pair. */
static void test_resolution(void **state) {
  (void)state;
  char err[512] = "", *text = NULL;
  ves_config c, d;
  ves_config_default(&c);
  assert_true(c.h_band == 0.5);
  assert_string_equal(c.resolution, "standard");
  const struct {
    const char *set[2];
    double h_band;
    const char *name;
  } cases[] = {
      {{"geometry.resolution=coarse", NULL}, 0.6, "coarse"},
      {{"geometry.resolution=FINE", NULL}, 0.4, "fine"},
      {{"geometry.resolution=coarse", "geometry.h_band=0.45"}, 0.45, "custom"},
      {{"geometry.h_band=0.45", "geometry.resolution=coarse"}, 0.6, "coarse"},
      {{"geometry.h_band=0.4", NULL}, 0.4, "fine"},
      {{"geometry.resolution=custom", "geometry.h_band=0.7"}, 0.7, "custom"},
      {{"geometry.h_band=0.7", "geometry.resolution=custom"}, 0.7, "custom"},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    const int n = cases[i].set[1] ? 2 : 1;
    assert_int_equal(ves_config_load(NULL, n, cases[i].set, &c, err, sizeof err), VES_OK);
    assert_true(c.h_band == cases[i].h_band);
    assert_string_equal(c.resolution, cases[i].name);
    assert_int_equal(ves_config_to_text(&c, &text), VES_OK);
    assert_int_equal(ves_config_load_text(text, "stored", &d, err, sizeof err), VES_OK);
    assert_true(d.h_band == c.h_band);
    assert_string_equal(d.resolution, c.resolution);
    free(text), text = NULL;
  }
  const char *custom[] = {"geometry.resolution=custom"};
  assert_int_equal(ves_config_load(NULL, 1, custom, &c, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "resolution = custom"));
  const char *bad[] = {"geometry.resolution=medium"};
  assert_int_equal(ves_config_load(NULL, 1, bad, &c, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "coarse|standard|fine|custom"));
}

/* Text round trip: every key back bit for bit (reals in their shortest
 * exact form), strings with ';' and '#' intact; the name stands for the file
 * in messages and points files. */
static void test_text_roundtrip(void **state) {
  (void)state;
  ves_config c, d;
  char err[512] = "", *text = NULL;
  ves_config_default(&c);
  c.epsilon = 0.1 / 3, c.c0 = -2.0 / 7, c.t_end = 1e-7 * 3, c.seed = 12345, c.dt_min = 1e-15 / 3;
  snprintf(c.points, sizeof c.points, "a;b#c.txt");
  snprintf(c.shape_type, sizeof c.shape_type, "curve");
  assert_int_equal(ves_config_to_text(&c, &text), VES_OK);
  assert_non_null(strstr(text, "[geometry]\nepsilon = 0.0333333333333333"));
  assert_non_null(strstr(text, "\nh_band = 0.5\n")); /* short where exact */
  assert_int_equal(ves_config_load_text(text, "/data/run.ini", &d, err, sizeof err), VES_OK);
  assert_string_equal(d.source, "/data/run.ini");
  for (int i = 0; i < ves_config_count(); i++) {
    ves_config_entry a, b;
    ves_config_entry_get(&c, i, &a);
    ves_config_entry_get(&d, i, &b);
    assert_string_equal(a.section, b.section);
    assert_string_equal(a.key, b.key);
    if (a.type == VES_KEY_REAL)
      assert_memory_equal(&a.real, &b.real, sizeof a.real);
    else if (a.type == VES_KEY_INT)
      assert_int_equal(a.integer, b.integer);
    else
      assert_string_equal(a.text, b.text);
  }
  free(text);
  /* errors in stored text name the given name */
  assert_int_equal(ves_config_load_text("[geometry]\nnope = 1\n", "stored.h5", &d, err, sizeof err),
                   VES_ERR_CONFIG);
  assert_non_null(strstr(err, "stored.h5: line 2: [geometry] nope: unknown key"));
  char buf[32];
  ves_config_format_real(0.1, buf, sizeof buf);
  assert_string_equal(buf, "0.1");
  ves_config_format_real(1.0 / 3, buf, sizeof buf);
  assert_true(strtod(buf, NULL) == 1.0 / 3);
}

static void test_key_listing(void **state) {
  (void)state;
  char *buf = NULL;
  size_t len = 0;
  FILE *f = open_memstream(&buf, &len);
  assert_non_null(f);
  ves_config_print_keys(f);
  fclose(f);
  assert_non_null(strstr(buf, "| geometry | epsilon |"));
  assert_non_null(strstr(buf, "| material | c0 |"));
  free(buf);
}

/* Every default has one source, the table of keys (ves_config_default):
 * each library *_default() of a parameter that is also a problem-file key
 * gives the table's value, exactly (the same decimal literal parsed, or
 * copied from the configuration). Where the two once disagreed, vesica run
 * (which sets every field from the configuration) had the table's:
 * [solver] max_iter 40 (ves_backend_options_default had 100),
 * freeze_hessian 1 (0), [geometry] gamma 0.6 (ves_lme_params_default 0.8),
 * [reconnect] cond_max and det_min 0, off (ves_reconnect_params_default 2
 * and 0.5). */
static void test_defaults_agree(void **state) {
  (void)state;
  ves_config c;
  ves_config_default(&c);
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  assert_true(bo.tol == c.tol && bo.ctol == c.ctol);
  assert_int_equal(bo.max_iter, c.max_iter);
  assert_int_equal(bo.freeze_hessian, c.freeze_hessian);
  assert_int_equal(bo.verbose, 0);
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  assert_true(ip.t_end == c.t_end && ip.dt_initial == c.dt_initial && ip.dt_max == c.dt_max);
  assert_true(ip.dt_min == c.dt_min && ip.dE_target == c.dE_target);
  assert_true(ip.growth_max == c.growth_max && ip.retry_cap == c.retry_cap);
  assert_true(ip.event_cut == c.event_cut);
  assert_int_equal(ip.adaptive, c.adaptive);
  assert_int_equal(ip.iter_target, c.iter_target);
  assert_int_equal(ip.predictor, c.predictor);
  assert_int_equal(ip.retry_memory, c.retry_memory);
  assert_int_equal(ip.hold_area, c.area);
  assert_int_equal(ip.hold_volume, c.volume);
  assert_true(ip.volume_rate == c.volume_rate && ip.volume_final == c.volume_final);
  assert_true(ip.c0_time == c.c0_time && ip.c0_after == c.c0_after && ip.c0_until == c.c0_until);
  assert_true(ip.c0_ramp_start == c.c0_ramp_start && ip.c0_ramp_end == c.c0_ramp_end);
  assert_true(ip.c0_ramp_to == c.c0_ramp_to);
  assert_int_equal(ip.reconnect_every, c.reconnect_every);
  assert_true(ip.reconnect_cond_max == c.reconnect_cond_max);
  assert_true(ip.reconnect_det_min == c.reconnect_det_min);
  assert_int_equal(ip.reconnect_nodes, strcmp(c.reconnect_nodes, "motion")
                                           ? VES_RESET_NODES_COEF
                                           : VES_RESET_NODES_MOTION);
  ves_reconnect_params rp;
  ves_reconnect_params_default(&rp);
  assert_int_equal(rp.every, c.reconnect_every);
  assert_true(rp.cond_max == c.reconnect_cond_max && rp.det_min == c.reconnect_det_min);
  ves_lme_params lp;
  ves_lme_params_default(&lp);
  assert_true(lp.gamma == c.gamma && lp.tol0 == c.support_tol);
  ves_nodes_params np;
  ves_nodes_params_default(&np);
  assert_true(np.axis_spacings == c.axis_spacings);
  assert_int_equal(np.lloyd_iter, c.lloyd_iterations);
  assert_int_equal((int)np.seed, c.seed);
  ves_shape_params sp;
  ves_shape_params_default(&sp);
  assert_int_equal(sp.kind, VES_SHAPE_SPHERE);
  assert_string_equal(c.shape_type, "sphere");
  assert_true(sp.radius == c.radius && sp.v == c.reduced_volume && sp.delta == c.delta);
  assert_int_equal(sp.mode, c.mode);
  assert_int_equal(sp.prolate, !strcmp(c.orientation, "prolate"));
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_defaults_and_overrides),
      cmocka_unit_test(test_errors),
      cmocka_unit_test(test_syntax),
      cmocka_unit_test(test_points_file),
      cmocka_unit_test(test_fuzz_regressions),
      cmocka_unit_test(test_text_roundtrip), cmocka_unit_test(test_resolution),
      cmocka_unit_test(test_key_listing),
      cmocka_unit_test(test_defaults_agree),
  };
  // clang-format on
  return cmocka_run_group_tests_name("config", tests, NULL, NULL);
}
