/* vesica — tests of `vesica plot` (build/vesica run as a child process):
 * the formats (--format png|pdf|svg: complete files of that type; another
 * format refused), the phi = 0 curve drawn in every shape panel and equal to
 * the interface `vesica info` measures (before and after a remeshing), one
 * arrow scale across the flow panels and no flow panel at t* = 0, the V/V0
 * panel only when the volume target varies, the kept script (--script)
 * redrawing the figures, and a PDF write that fails. The figures' content
 * is read from the kept script: the data gnuplot draws. Run from the
 * repository root (make test does). */
#include "cli_test_impl.h"

static char h5[128]; /* the remeshed run every test plots (group setup) */

/* A small run of 4 steps with a snapshot at each and a remeshing every 2
 * (its node count changes: the last panels use the remeshing's triangles). */
static int setup_run(void **state) {
  if (setup_all(state)) return -1;
  char ini[128];
  tmp_path(ini, sizeof ini, "rm.ini");
  tmp_path(h5, sizeof h5, "rm.h5");
  write_file(ini, "[time]\nt_end = 1\n[output]\nsnapshot_every = 1\n[remesh]\nevery = 2\n");
  result r;
  run(&r, "run", ini, TINY, "--out", h5, "--quiet", "--max-steps", "4", NULL);
  unlink(ini);
  if (r.code) fprintf(stderr, "run: exit %d: %s", r.code, r.err);
  return r.code ? -1 : 0;
}

/* The file at path into a malloc'ed NUL-terminated buffer, its size in *n. */
static char *read_all(const char *path, long *n) {
  FILE *f = fopen(path, "rb");
  if (!f) fail_msg("%s: cannot read", path);
  fseek(f, 0, SEEK_END);
  *n = ftell(f);
  fseek(f, 0, SEEK_SET);
  char *b = malloc((size_t)*n + 1);
  assert_non_null(b);
  assert_int_equal((long)fread(b, 1, (size_t)*n, f), *n);
  b[*n] = 0;
  fclose(f);
  return b;
}

/* Whether the file is a complete one of the format: its magic bytes at
 * the start and its format's end mark. */
static void expect_kind(const char *path, const char *fmt) {
  long n;
  char *b = read_all(path, &n);
  if (!strcmp(fmt, "png")) {
    assert_true(n > 20);
    assert_memory_equal(b, "\x89PNG\r\n\x1a\n", 8);
    assert_memory_equal(b + n - 8, "IEND", 4);
  } else if (!strcmp(fmt, "pdf")) {
    assert_memory_equal(b, "%PDF-", 5);
    if (!strstr(b + (n > 64 ? n - 64 : 0), "%%EOF")) fail_msg("%s: no %%%%EOF at its end", path);
  } else {
    assert_memory_equal(b, "<?xml", 5);
    if (!strstr(b, "<svg")) fail_msg("%s: no <svg element", path);
    long e = n;
    while (e > 0 && strchr(" \r\n\t", b[e - 1])) e--;
    assert_true(e >= 6);
    assert_memory_equal(b + e - 6, "</svg>", 6);
  }
  free(b);
}

/* --format png|pdf|svg: the four figures of that type, named with its
 * extension; stdout lists them. */
static void test_plot_formats(void **state) {
  (void)state;
  const char *fmts[] = {"png", "pdf", "svg"};
  for (int i = 0; i < 3; i++) {
    char dir[160];
    snprintf(dir, sizeof dir, "%s/fmt_%s", tmpdir, fmts[i]);
    result r;
    run(&r, "plot", h5, "--outdir", dir, "--format", fmts[i], NULL);
    if (r.code) fail_msg("plot --format %s: exit %d: %s", fmts[i], r.code, r.err);
    for (int k = 0; k < VES_PLOT_NFIG; k++) {
      char fig[256];
      snprintf(fig, sizeof fig, "%s/rm_%s.%s", dir, ves_plot_figures[k], fmts[i]);
      if (!strstr(r.out, fig)) fail_msg("stdout lacks %s:\n%s", fig, r.out);
      expect_kind(fig, fmts[i]);
      unlink(fig);
    }
    assert_int_equal(files_in(dir), 0); /* nothing else: no .part */
    rmdir(dir);
  }
}

/* Another format: exit 2 naming it, nothing written (not even --outdir). */
static void test_plot_format_refused(void **state) {
  (void)state;
  char dir[160];
  snprintf(dir, sizeof dir, "%s/fmt_jpg", tmpdir);
  result r;
  run(&r, "plot", h5, "--outdir", dir, "--format", "jpg", NULL);
  printf("# plot --format jpg -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "--format 'jpg'"));
  assert_false(exists(dir));
  run(&r, "plot", h5, "--outdir", dir, "--format", NULL);
  assert_int_equal(r.code, 2);
  assert_false(exists(dir));
}

/* The points of datablock name in script text ("$name << EOD" ... "EOD"):
 * up to max (r, z) pairs into p, pieces apart by a blank line as a NaN
 * pair; their count, -1 when there is no such block. */
static int datablock(const char *text, const char *name, double *p, int max) {
  char head[64];
  snprintf(head, sizeof head, "$%s << EOD\n", name);
  const char *c = strstr(text, head);
  if (!c) return -1;
  c += strlen(head);
  int n = 0;
  while (*c && strncmp(c, "EOD\n", 4) && n < max) {
    if (*c == '\n') {
      p[2 * n] = p[2 * n + 1] = NAN, n++;
    } else {
      char *e;
      p[2 * n] = strtod(c, &e);
      p[2 * n + 1] = strtod(e, NULL);
      n++;
    }
    c = strchr(c, '\n');
    if (!c) break;
    c++;
  }
  return n;
}

/* The volume and area the polyline pieces p[n] enclose with the axis, as
 * level_set.h gives them: V = pi sum (ra^2 + ra rb + rb^2)(za - zb)/3,
 * A = 2 pi sum (ra + rb)/2 |b - a|. */
static void curve_measures(const double *p, int n, double *V, double *A) {
  *V = 0, *A = 0;
  for (int i = 0; i + 1 < n; i++) {
    const double ra = p[2 * i], za = p[2 * i + 1], rb = p[2 * i + 2], zb = p[2 * i + 3];
    if (isnan(ra) || isnan(rb)) continue;
    *V += M_PI * (ra * ra + ra * rb + rb * rb) * (za - zb) / 3;
    *A += M_PI * (ra + rb) * hypot(rb - ra, zb - za);
  }
}

/* The plot commands of figure fig (from its set output to the next). */
static char *figure_section(const char *text, const char *fig) {
  char key[64];
  snprintf(key, sizeof key, "_%s.png' . part", fig);
  const char *a = strstr(text, key);
  if (!a) {
    fail_msg("the script has no figure %s", fig);
    return NULL; /* not reached; tells the compiler a is not NULL below */
  }
  const char *b = strstr(a + 1, "set output");
  size_t n = b ? (size_t)(b - a) : strlen(a);
  char *s = malloc(n + 1);
  assert_non_null(s);
  memcpy(s, a, n), s[n] = 0;
  return s;
}

/* `vesica plot FILE --script gp --force` into the test folder: the kept
 * gnuplot script, read whole. */
static char *plot_script(const char *file, const char *gp) {
  result r;
  run(&r, "plot", file, "--outdir", tmpdir, "--script", gp, "--force", NULL);
  if (r.code) fail_msg("plot %s --script: exit %d: %s", file, r.code, r.err);
  long n;
  return read_all(gp, &n);
}

/* Every shape panel (snapshots and flow) draws its phi = 0 curve and its
 * mirror; the first and the last panel's curves (the last after a
 * remeshing, on its triangles) enclose the volume and area `vesica info`
 * measures at the first and last snapshot (ves_level_set_eval, another
 * code path). The kept script's first line writes the figures' own names. */
static void test_plot_outline(void **state) {
  (void)state;
  char gp[128];
  tmp_path(gp, sizeof gp, "rm.gp");
  char *text = plot_script(h5, gp);
  assert_memory_equal(text, "part = ''\n", 10);
  result r;
  run(&r, "info", h5, NULL);
  assert_int_equal(r.code, 0);
  static double p[2 * 20000];
  int panels = 0;
  for (int j = 0; j < VES_PLOT_MAXTIMES; j++) {
    char name[32];
    snprintf(name, sizeof name, "snap%d", j);
    if (datablock(text, name, p, 20000) < 0) break;
    panels++;
    snprintf(name, sizeof name, "curve%d", j);
    const int m = datablock(text, name, p, 20000);
    if (m < 3) fail_msg("panel %d: no phi = 0 curve (%d points)", j, m);
    for (int i = 0; i < m; i++) /* on the meridian plane's right half, in the box */
      assert_true(isnan(p[2 * i]) || (p[2 * i] > -0.2 && p[2 * i] < 2 && fabs(p[2 * i + 1]) < 2));
  }
  printf("# %d shape panels, each with its phi = 0 curve\n", panels);
  assert_int_equal(panels, 4); /* 5 snapshots: the first, the last and two between */
  const char *when[2] = {"initial", "final"};
  for (int c = 0; c < 2; c++) {
    char name[32], kv[64], ka[64];
    snprintf(name, sizeof name, "curve%d", c ? panels - 1 : 0);
    const int m = datablock(text, name, p, 20000);
    double V, A;
    curve_measures(p, m, &V, &A);
    snprintf(kv, sizeof kv, "interface_volume_%s", when[c]);
    snprintf(ka, sizeof ka, "interface_area_%s", when[c]);
    const double Vi = key_value(r.out, kv), Ai = key_value(r.out, ka);
    printf("# %s: curve V %.7g A %.7g, info V %.7g A %.7g\n", name, V, A, Vi, Ai);
    /* the script prints the points to 6 digits: a relative error of ~1e-6
     * a point, far below 1e-4; a curve on other triangles or another
     * snapshot's positions is off by the motion (~1e-3 here) or more */
    assert_true(fabs(V / Vi - 1) < 1e-4);
    assert_true(fabs(A / Ai - 1) < 1e-4);
  }
  const char *figs[2] = {"snapshots", "flow"};
  for (int f = 0; f < 2; f++) {
    char *sec = figure_section(text, figs[f]);
    int plots = 0;
    for (const char *c = sec; (c = strstr(c, "\nplot $snap")); c++, plots++) {
      const int j = atoi(c + strlen("\nplot $snap"));
      char want[96], mirror[96];
      snprintf(want, sizeof want, "$curve%d using 1:2 with lines", j);
      snprintf(mirror, sizeof mirror, "$curve%d using (-$1):2 with lines", j);
      const char *eol = strchr(c + 1, '\n');
      char line[4096];
      snprintf(line, sizeof line, "%.*s", eol ? (int)(eol - c) : (int)strlen(c), c);
      if (!strstr(line, want) || !strstr(line, mirror))
        fail_msg("%s panel %d draws no phi = 0 curve:%s", figs[f], j, line);
    }
    assert_int_equal(plots, f ? panels - 1 : panels); /* flow: not at t* = 0 */
    free(sec);
  }
  free(text);
  for (int k = 0; k < VES_PLOT_NFIG; k++) {
    char fig[256];
    snprintf(fig, sizeof fig, "%s/rm_%s.png", tmpdir, ves_plot_figures[k]);
    unlink(fig);
  }
  /* `gnuplot SCRIPT` redraws the figures under their own names */
  char cmd[512];
  snprintf(cmd, sizeof cmd, "gnuplot %s 2>/dev/null", gp);
  assert_int_equal(system(cmd), 0);
  for (int k = 0; k < VES_PLOT_NFIG; k++) {
    char fig[256];
    snprintf(fig, sizeof fig, "%s/rm_%s.png", tmpdir, ves_plot_figures[k]);
    expect_kind(fig, "png");
  }
  /* the kept script is an output: refused without --force, never the input */
  run(&r, "plot", h5, "--outdir", tmpdir, "--script", gp, "--force", NULL);
  assert_int_equal(r.code, 0);
  run(&r, "plot", h5, "--outdir", tmpdir, "--script", gp, NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "exists; --force"));
  run(&r, "plot", h5, "--outdir", tmpdir, "--script", h5, "--force", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "is the input file"));
  for (int k = 0; k < VES_PLOT_NFIG; k++) {
    char fig[256];
    snprintf(fig, sizeof fig, "%s/rm_%s.png", tmpdir, ves_plot_figures[k]);
    unlink(fig);
  }
  unlink(gp);
}

/* The flow panels share one arrow scale: in every panel the longest arrow
 * drawn over the fastest node's speed (its title) is the scale the
 * figure's title states (length 0.1 R0 = speed S R0/t*); no panel at t* = 0
 * (it has no flow). */
static void test_plot_flow_scale(void **state) {
  (void)state;
  char gp[128];
  tmp_path(gp, sizeof gp, "flow.gp");
  char *text = plot_script(h5, gp);
  char *sec = figure_section(text, "flow");
  const char *s = strstr(sec, "length 0.1 R_0 = speed ");
  assert_non_null(s);
  const double scale = 0.1 / strtod(s + strlen("length 0.1 R_0 = speed "), NULL);
  static double p[4 * 5000];
  int panels = 0, drawn = 0;
  for (const char *c = sec; (c = strstr(c, "set title \"t* = ")); c++, panels++) {
    const double t = strtod(c + strlen("set title \"t* = "), NULL);
    const char *v = strstr(c, "fastest node ");
    assert_non_null(v);
    const double vmax = strtod(v + strlen("fastest node "), NULL);
    assert_true(t > 0); /* no flow panel at t* = 0 */
    const char *pl = strstr(c, "\nplot $snap");
    assert_non_null(pl);
    const int j = atoi(pl + strlen("\nplot $snap"));
    char head[32];
    snprintf(head, sizeof head, "$flowv%d << EOD\n", j);
    const char *b = strstr(text, head);
    if (!b) continue; /* a panel slower than the arrows show */
    b += strlen(head);
    double lmax = 0;
    int m = 0;
    for (; strncmp(b, "EOD\n", 4) && m < 5000; b = strchr(b, '\n') + 1, m++) {
      char *e;
      for (int q = 0; q < 4; q++) p[4 * m + q] = strtod(q ? e : b, &e);
      lmax = fmax(lmax, hypot(p[4 * m + 2], p[4 * m + 3]));
    }
    printf("# flow panel t* = %g: longest arrow %g R0, fastest node %g R0/t*: %g t* (figure: %g)\n",
           t, lmax, vmax, lmax / vmax, scale);
    /* speeds and lengths are printed to 3 digits: ratios agree to 1%; a
     * panel scaled to its own fastest arrow is off by its speed ratio */
    assert_true(fabs(lmax / vmax / scale - 1) < 1e-2);
    drawn++;
  }
  assert_int_equal(panels, 3); /* the 4 panels of the snapshots but t* = 0 */
  assert_true(drawn >= 2);
  free(sec), free(text);
  unlink(gp);
  for (int k = 0; k < VES_PLOT_NFIG; k++) {
    char fig[256];
    snprintf(fig, sizeof fig, "%s/rm_%s.png", tmpdir, ves_plot_figures[k]);
    unlink(fig);
  }
}

/* The V/V0 panel: left out when the volume target is V0 at every step
 * (the title says so), drawn when a protocol changes it. */
static void test_plot_volume_panel(void **state) {
  (void)state;
  char gp[128], ini[128], dv[128];
  tmp_path(gp, sizeof gp, "vol.gp");
  tmp_path(ini, sizeof ini, "dv.ini");
  tmp_path(dv, sizeof dv, "dv.h5");
  write_file(ini, "[time]\nt_end = 1\n[protocol]\nvolume_rate = -0.5\nvolume_final = 0.95\n");
  result r;
  run(&r, "run", ini, TINY, "--out", dv, "--quiet", "--max-steps", "2", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  const char *files[2] = {h5, dv};
  for (int c = 0; c < 2; c++) {
    char *text = plot_script(files[c], gp);
    char *sec = figure_section(text, "constraints");
    const int panel = strstr(sec, "set ylabel 'V / V_0'") != NULL;
    const int said = strstr(sec, "V_{target} = V_0 at every step") != NULL;
    printf("# %s: V/V0 panel %d, title says constant %d\n", files[c], panel, said);
    assert_int_equal(panel, c);
    assert_int_equal(said, !c);
    free(sec), free(text);
  }
  unlink(gp), unlink(ini), rm_run(dv);
  for (int k = 0; k < VES_PLOT_NFIG; k++) {
    char fig[256];
    snprintf(fig, sizeof fig, "%s/rm_%s.png", tmpdir, ves_plot_figures[k]);
    unlink(fig);
    snprintf(fig, sizeof fig, "%s/dv_%s.png", tmpdir, ves_plot_figures[k]);
    unlink(fig);
  }
}

/* A PDF write that fails (file-size limit: gnuplot exits 0 and leaves a
 * truncated file): exit 3 naming the figure, no figure, part or kept
 * script left. */
static void test_plot_pdf_fails(void **state) {
  (void)state;
  char dir[160], gp[192];
  snprintf(dir, sizeof dir, "%s/full", tmpdir);
  snprintf(gp, sizeof gp, "%s/full.gp", tmpdir);
  assert_int_equal(mkdir(dir, 0777), 0);
  char *args[] = {"plot", h5, "--outdir", dir, "--format", "pdf", "--script", gp, NULL};
  /* the script (~50 KiB) and the energy figure (~15 KiB) fit in 64 KiB,
   * the snapshots' (~90 KiB) does not */
  result r;
  run_limited(&r, 64 * 1024, args);
  printf("# plot --format pdf into a 64 KiB file-size limit -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 3);
  assert_non_null(strstr(r.err, "incomplete pdf"));
  assert_non_null(strstr(r.err, "_snapshots.pdf"));
  assert_int_equal(files_in(dir), 0);
  assert_false(exists(gp));
  char part[208];
  snprintf(part, sizeof part, "%s.part", gp);
  assert_false(exists(part));
  rmdir(dir);
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_plot")) return 1;
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_plot_formats),
      cmocka_unit_test(test_plot_format_refused),
      cmocka_unit_test(test_plot_outline),
      cmocka_unit_test(test_plot_flow_scale),
      cmocka_unit_test(test_plot_volume_panel),
      cmocka_unit_test(test_plot_pdf_fails),
  };
  // clang-format on
  return cmocka_run_group_tests_name("plot", tests, setup_run, teardown_all);
}
