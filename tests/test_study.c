/* vesica — tests of studies (study.h): axis lists and ranges, the grid's
 * order and cell names, the cells' commands, every kind of bad study file,
 * .result files and resuming, the classification of ended cells, the CSV
 * table; the runner with a stand-in program (a shell script that converges,
 * fails, crashes or hangs by its arguments: no solver needed) for
 * timeouts, crashes, resuming, --retry-failed and a stop mid-way; and the
 * program itself on a tiny problem: a real study, its table, and the Slurm
 * path (--emit slurm, the script run once per array task without Slurm,
 * --collect) giving the local run's table. Run from the repository root. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "app/study.h"
#include "core/clock_impl.h"

static char vesica[PATH_MAX]; /* the program under test */
static char tmpdir[64];       /* this test's scratch folder */

/* The tiny problem of cli_test_impl.h (331 nodes, ~1 s a one-step cell). */
static const char TINY_SET[] = "geometry.epsilon = 0.2\ngeometry.box_r = 2\ngeometry.box_z = 2\n"
                               "geometry.band = 2\ngeometry.h_band = 0.7\ngeometry.h_far = 0.3\n"
                               "shape.mode = 2\nshape.delta = 0.15\n";

static void write_file(const char *path, const char *text) {
  FILE *f = fopen(path, "w");
  assert_non_null(f);
  fputs(text, f);
  fclose(f);
}

static char *tmp_path(char *buf, size_t len, const char *name) {
  snprintf(buf, len, "%s/%s", tmpdir, name);
  return buf;
}

static long slurp(const char *path, char *buf, size_t len) {
  FILE *f = fopen(path, "r");
  size_t k = f ? fread(buf, 1, len - 1, f) : 0;
  buf[k] = 0;
  if (f) fclose(f);
  return f ? (long)k : -1;
}

static void rm_tree(const char *path) {
  DIR *d = opendir(path);
  struct dirent *e;
  while (d && (e = readdir(d))) {
    if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
    char p[PATH_MAX];
    snprintf(p, sizeof p, "%s/%s", path, e->d_name);
    struct stat sb;
    if (lstat(p, &sb) == 0 && S_ISDIR(sb.st_mode))
      rm_tree(p);
    else
      unlink(p);
  }
  if (d) closedir(d);
  rmdir(path);
}

static int setup_all(void **state) {
  (void)state;
  snprintf(tmpdir, sizeof tmpdir, "/tmp/vesica_study_XXXXXX");
  if (!mkdtemp(tmpdir)) return -1;
  char p[PATH_MAX];
  write_file(tmp_path(p, sizeof p, "base.ini"), "[shape]\ntype = sphere\n");
  return 0;
}

static int teardown_all(void **state) {
  (void)state;
  rm_tree(tmpdir);
  return 0;
}

/* Write tmpdir/name with text, load it with max_cells: the status, the study
 * (or NULL) and the message. */
static ves_status load_text(const char *name, const char *text, long max_cells, ves_study **s,
                            char *err, size_t errlen) {
  char p[PATH_MAX];
  write_file(tmp_path(p, sizeof p, name), text);
  err[0] = 0;
  return ves_study_load(p, max_cells, s, err, errlen);
}

/* ---- axes ------------------------------------------------------------------ */

static void test_parse_axis(void **state) {
  (void)state;
  ves_study_axis *ax = malloc(sizeof *ax);
  char err[256];
  assert_int_equal(ves_study_parse_axis(" newton ,ipopt,  euler ", ax, err, sizeof err), VES_OK);
  assert_int_equal(ax->nvalues, 3);
  assert_string_equal(ax->values[0], "newton");
  assert_string_equal(ax->values[1], "ipopt");
  assert_string_equal(ax->values[2], "euler");
  /* decades print as decades: 10^k through pow and 12 digits, no 0.000999999 */
  assert_int_equal(ves_study_parse_axis("log(1e-4, 1e2, 7)", ax, err, sizeof err), VES_OK);
  const char *dec[] = {"0.0001", "0.001", "0.01", "0.1", "1", "10", "100"};
  assert_int_equal(ax->nvalues, 7);
  for (int i = 0; i < 7; i++) assert_string_equal(ax->values[i], dec[i]);
  assert_int_equal(ves_study_parse_axis("log(1, 100, 5)", ax, err, sizeof err), VES_OK);
  /* 10^0.5 = 3.16227766017 to 12 digits; the ratio between neighbours is exact */
  assert_string_equal(ax->values[1], "3.16227766017");
  assert_string_equal(ax->values[2], "10");
  assert_int_equal(ves_study_parse_axis("LIN(0, 1, 5)", ax, err, sizeof err), VES_OK);
  const char *lin[] = {"0", "0.25", "0.5", "0.75", "1"};
  for (int i = 0; i < 5; i++) assert_string_equal(ax->values[i], lin[i]);
  assert_int_equal(ves_study_parse_axis("log(10, 0.1, 3)", ax, err, sizeof err), VES_OK);
  assert_string_equal(ax->values[0], "10"); /* descending ranges keep their order */
  assert_string_equal(ax->values[2], "0.1");
  const char *bad[] = {"",
                       "  ",
                       "a,,b",
                       "a,",
                       "1, 1",
                       "log(0,1,3)",
                       "log(1,10,1)",
                       "log(1,10)",
                       "log(1,10,2.5)",
                       "log(1,1,3)",
                       "lin(0,1,3",
                       "log(1,10,3) x",
                       "log(1,10,300)"};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    err[0] = 0;
    assert_int_equal(ves_study_parse_axis(bad[i], ax, err, sizeof err), VES_ERR_CONFIG);
    assert_true(err[0] != 0);
    printf("# axis '%s': %s\n", bad[i], err);
  }
  free(ax);
}

/* ---- the grid ------------------------------------------------------------------ */

static void test_grid(void **state) {
  (void)state;
  char err[1024], text[2048];
  ves_study *s = NULL;
  snprintf(text, sizeof text,
           "; a study\n[study]\nproblem = base.ini\nrun = step\ntime_limit = 60\n[set]\n%s"
           "solver.max_iter = 100\n[axes]\nsolver.backend = newton, ipopt, euler\n"
           "TIME.DT_INITIAL = log(1e-3, 1e-1, 2)\n",
           TINY_SET);
  assert_int_equal(load_text("grid.ini", text, VES_STUDY_MAX_CELLS, &s, err, sizeof err), VES_OK);
  assert_int_equal(s->ncells, 6);
  assert_int_equal(s->naxes, 2);
  assert_string_equal(s->axis[1].key, "time.dt_initial"); /* the table's spelling */
  assert_int_equal(s->mode, VES_STUDY_STEP);
  assert_true(s->problem[0] == '/'); /* resolved next to the study file */
  /* the first axis varies slowest */
  const char *names[] = {"backend=newton,dt_initial=0.001", "backend=newton,dt_initial=0.1",
                         "backend=ipopt,dt_initial=0.001",  "backend=ipopt,dt_initial=0.1",
                         "backend=euler,dt_initial=0.001",  "backend=euler,dt_initial=0.1"};
  for (long k = 0; k < 6; k++) {
    char name[256];
    int idx[VES_STUDY_MAX_AXES];
    ves_study_cell_index(s, k, idx);
    assert_int_equal(idx[0], k / 2);
    assert_int_equal(idx[1], k % 2);
    ves_study_cell_name(s, k, name, sizeof name);
    assert_string_equal(name, names[k]);
  }
  /* cell 3's command: fixed overrides, its values, then the one-step settings */
  int argc = 0;
  char **argv = NULL;
  assert_int_equal(ves_study_cell_argv(s, 3, "/bin/prog", "/d", &argc, &argv, err, sizeof err),
                   VES_OK);
  assert_string_equal(argv[0], "/bin/prog");
  assert_string_equal(argv[1], "run");
  assert_string_equal(argv[2], s->problem);
  assert_string_equal(argv[3], "--out");
  assert_string_equal(argv[4], "/d/cells/backend=ipopt,dt_initial=0.1.h5");
  assert_string_equal(argv[5], "--quiet");
  assert_string_equal(argv[6], "--max-steps");
  assert_string_equal(argv[7], "1");
  const char *sets[] = {"geometry.epsilon=0.2", "geometry.box_r=2",    "geometry.box_z=2",
                        "geometry.band=2",      "geometry.h_band=0.7", "geometry.h_far=0.3",
                        "shape.mode=2",         "shape.delta=0.15",    "solver.max_iter=100",
                        "solver.backend=ipopt", "time.dt_initial=0.1", "time.adaptive=0",
                        "time.dt_min=0.1",      "time.dt_max=0.1",     "time.t_end=0.1"};
  const int ns = sizeof sets / sizeof sets[0];
  assert_int_equal(argc, 8 + 2 * ns);
  for (int i = 0; i < ns; i++) {
    assert_string_equal(argv[8 + 2 * i], "--set");
    assert_string_equal(argv[9 + 2 * i], sets[i]);
  }
  assert_null(argv[argc]);
  free(argv);
  /* the names do not depend on the order or number of values: a grown axis
   * keeps the old cells' names (resume) */
  ves_study *t = NULL;
  snprintf(text, sizeof text,
           "[study]\nproblem = base.ini\nrun = steps\nsteps = 3\n[set]\n%s[axes]\n"
           "time.dt_initial = 0.1, 0.05, 0.001\nsolver.backend = euler, newton, ipopt\n",
           TINY_SET);
  assert_int_equal(load_text("grid2.ini", text, VES_STUDY_MAX_CELLS, &t, err, sizeof err), VES_OK);
  assert_int_equal(t->ncells, 9);
  char name[256];
  ves_study_cell_name(t, 0, name, sizeof name);
  assert_string_equal(name, "dt_initial=0.1,backend=euler");
  assert_int_equal(ves_study_cell_argv(t, 0, "/p", "/d", &argc, &argv, err, sizeof err), VES_OK);
  assert_string_equal(argv[7], "3"); /* --max-steps 3, no one-step settings */
  assert_string_equal(argv[argc - 1], "solver.backend=euler");
  free(argv);
  ves_study_destroy(&t);
  ves_study_destroy(&s);
  assert_null(s);
  ves_study_destroy(NULL);
}

/* Every bad study file (21 kinds): VES_ERR_CONFIG (or _IO for a missing file) with one
 * message naming the file and what is wrong, before anything runs. */
static void test_bad_studies(void **state) {
  (void)state;
  char err[1024], text[2048];
  struct {
    const char *body; /* after "[study]\nproblem = base.ini\n" unless starting with '!' */
    const char *want; /* in the message */
    long max_cells;
  } cases[] = {
      {"[axes]\nmaterial.c0 = 0, 1\n[oops]\nx = 1\n", "[oops]: unknown section", 1000},
      {"speed = 1\n[axes]\nmaterial.c0 = 0, 1\n", "[study] speed: unknown key", 1000},
      {"run = walk\n[axes]\nmaterial.c0 = 0, 1\n", "[study] run = 'walk'", 1000},
      {"time_limit = -1\n[axes]\nmaterial.c0 = 0, 1\n", "[study] time_limit", 1000},
      {"[axes]\nmaterial.cc = 0, 1\n", "[axes] material.cc: unknown problem key", 1000},
      {"[axes]\nmaterial.c0 =\n", "[axes] material.c0: empty axis", 1000},
      {"[axes]\nmaterial.c0 = 0, 1, 0\n", "[axes] material.c0: value '0' given twice", 1000},
      {"[axes]\nmaterial.c0 = 0, 1e9\n", "out of range", 1000},
      {"[axes]\nsolver.backend = newton, cg\n", "not one of the allowed values", 1000},
      {"[set]\nmaterial.c0 = 1\n[axes]\nmaterial.c0 = 0, 1\n", "[axes] material.c0: also fixed",
       1000},
      {"[set]\nmaterial.cc = 1\n[axes]\nmaterial.c0 = 0, 1\n", "[set] material.cc: unknown", 1000},
      {"[axes]\nmaterial.c0 = lin(0, 1, 11)\nshape.delta = lin(0, 0.1, 11)\n",
       "the grid has 121 cells, more than the limit 100", 100},
      {"[set]\n", "[axes]: no axis", 1000},
      {"[axes]\ngeometry.epsilon = 0.04, 0.4\n", "too large for the box", 1000}, /* a cell */
      {"[slurm]\nsetup = module\tload hdf5\n[axes]\nmaterial.c0 = 0, 1\n",
       "[slurm] setup: empty, longer than 1023 characters, or holding a control", 1000},
      {"[slurm]\nthrottle = 0\n[axes]\nmaterial.c0 = 0, 1\n", "[slurm] throttle", 1000},
      {"[axes]\nmaterial.c0 = 0.10000000000000000000000000000000000000000000000000000001\n"
       "material.k = 1.0000000000000000000000000000000000000000000000000000001\n"
       "material.mu = 1.0000000000000000000000000000000000000000000000000000001\n"
       "shape.delta = 0.0000000000000000000000000000000000000000000000000000001\n",
       "more than 200", 1000},
      {"[slurm]\nmem = 4G$(reboot)\n[axes]\nmaterial.c0 = 0, 1\n", "[slurm] mem", 1000},
      {"[slurm]\ncpus_per_task = 0\n[axes]\nmaterial.c0 = 0, 1\n", "[slurm] cpus_per_task", 1000},
      {"!x = 1\n[study]\nproblem = base.ini\n", "key outside a section", 1000},
      {"![study]\nrun = step\n[axes]\nmaterial.c0 = 0, 1\n", "[study] problem: missing", 1000},
      {"![study]\nproblem = nothere.ini\n[axes]\nmaterial.c0 = 0, 1\n", "cannot open", 1000},
  };
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    if (cases[i].body[0] == '!')
      snprintf(text, sizeof text, "%s", cases[i].body + 1);
    else
      snprintf(text, sizeof text, "[study]\nproblem = base.ini\n%s", cases[i].body);
    ves_study *s = NULL;
    ves_status st = load_text("bad.ini", text, cases[i].max_cells, &s, err, sizeof err);
    printf("# bad study %zu: %s\n", i, err);
    assert_true(st == VES_ERR_CONFIG || st == VES_ERR_IO);
    assert_null(s);
    assert_non_null(strstr(err, "bad.ini"));
    assert_non_null(strstr(err, cases[i].want));
  }
  ves_study *s = NULL;
  assert_int_equal(ves_study_load("/nonexistent/x.ini", 10, &s, err, sizeof err), VES_ERR_IO);
}

/* ---- .result files, resuming, classification ------------------------------------ */

static ves_study *small_study(const char *name, const char *extra) {
  char err[1024], text[2048];
  ves_study *s = NULL;
  snprintf(text, sizeof text,
           "[study]\nproblem = base.ini\nrun = step\n%s[set]\n%s[axes]\n"
           "time.dt_initial = 0.001, 0.002, 0.003, 0.004\n",
           extra, TINY_SET);
  assert_int_equal(load_text(name, text, 1000, &s, err, sizeof err), VES_OK);
  return s;
}

static void test_result_resume(void **state) {
  (void)state;
  ves_study *s = small_study("resume.ini", "");
  char dir[PATH_MAX], cells[PATH_MAX + 8], path[PATH_MAX];
  tmp_path(dir, sizeof dir, "resume");
  snprintf(cells, sizeof cells, "%s/cells", dir);
  assert_int_equal(mkdir(dir, 0777), 0);
  assert_int_equal(mkdir(cells, 0777), 0);
  ves_study_result r, q;
  memset(&r, 0, sizeof r);
  snprintf(r.outcome, sizeof r.outcome, "failed");
  snprintf(r.reason, sizeof r.reason, "a reason, with \"quotes\"\nand a newline");
  r.exit_code = 3, r.wall_seconds = 1.25, r.cpu_seconds = 0.5, r.peak_mb = 12.5;
  assert_int_equal(ves_study_cell_signature(s, 1, r.signature, sizeof r.signature), VES_OK);
  ves_study_cell_path(s, 1, dir, ".result", path, sizeof path);
  assert_int_equal(ves_study_result_write(path, &r), VES_OK);
  assert_int_equal(ves_study_result_read(path, &q), VES_OK);
  assert_string_equal(q.outcome, "failed");
  assert_string_equal(q.reason, "a reason, with \"quotes\" and a newline"); /* one line */
  assert_int_equal(q.exit_code, 3);
  assert_true(q.wall_seconds == 1.25 && q.cpu_seconds == 0.5 && q.peak_mb == 12.5);
  assert_string_equal(q.signature, r.signature);
  /* done: cell 1 (failed: not with retry_failed); not done: the others */
  for (long k = 0; k < 4; k++) {
    assert_int_equal(ves_study_cell_done(s, k, dir, 0), k == 1);
    assert_int_equal(ves_study_cell_done(s, k, dir, 1), 0);
  }
  snprintf(r.outcome, sizeof r.outcome, "converged");
  assert_int_equal(ves_study_result_write(path, &r), VES_OK);
  assert_int_equal(ves_study_cell_done(s, 1, dir, 1), 1);
  /* the same study in another file: done; the same cell name under a
   * changed study (another fixed value): stale, not done */
  ves_study *t = small_study("resume2.ini", "");
  assert_int_equal(ves_study_cell_done(t, 1, dir, 0), 1);
  ves_study_destroy(&t);
  char err[1024], text[2048];
  snprintf(text, sizeof text,
           "[study]\nproblem = base.ini\nrun = step\n[set]\n%smaterial.c0 = 0.5\n[axes]\n"
           "time.dt_initial = 0.001, 0.002, 0.003, 0.004\n",
           TINY_SET);
  assert_int_equal(load_text("resume3.ini", text, 1000, &t, err, sizeof err), VES_OK);
  assert_int_equal(ves_study_cell_done(t, 1, dir, 0), 0);
  ves_study_destroy(&t);
  /* a truncated .result (a write cut short) is not done */
  write_file(path, "outcome = converged\n");
  assert_int_equal(ves_study_cell_done(s, 1, dir, 0), 0);
  ves_study_destroy(&s);
}

static void test_classify(void **state) {
  (void)state;
  char log[PATH_MAX];
  tmp_path(log, sizeof log, "classify.log");
  write_file(log, "some output\nvesica run: /a/b.ini: no acceptable step at t* = 0 down to dt* = "
                  "1 (iteration did not converge); the last good state (step 0) is ...\n");
  ves_study_result r;
  ves_study_classify(3, 0, 0, 10, log, &r);
  assert_string_equal(r.outcome, "failed");
  assert_string_equal(r.reason,
                      "no acceptable step at t* = 0 down to dt* = 1 (iteration did not converge)");
  assert_int_equal(r.exit_code, 3);
  /* a ';' inside the parenthesis is the solver's reason, kept whole */
  write_file(log, "vesica run: /a/b.ini: no acceptable step at t* = 0 down to dt* = 1000 (det F "
                  "<= 0 at a trial point; the step is too long); the last good state ...\n");
  ves_study_classify(3, 0, 0, 10, log, &r);
  assert_string_equal(r.reason, "no acceptable step at t* = 0 down to dt* = 1000 (det F <= 0 at a "
                                "trial point; the step is too long)");
  write_file(log, "vesica run: /a/b.ini: [time] dt_initial = 10: must lie in [dt_min, dt_max]\n");
  ves_study_classify(2, 0, 0, 10, log, &r);
  assert_string_equal(r.outcome, "bad_input");
  assert_string_equal(r.reason, "/a/b.ini: [time] dt_initial = 10: must lie in [dt_min, dt_max]");
  ves_study_classify(0, 0, 0, 10, log, &r);
  assert_string_equal(r.outcome, "converged");
  assert_string_equal(r.reason, "");
  ves_study_classify(-1, SIGSEGV, 0, 10, log, &r);
  assert_string_equal(r.outcome, "crashed");
  assert_non_null(strstr(r.reason, "signal 11"));
  assert_int_equal(r.exit_code, -1);
  ves_study_classify(143, 0, 1, 2.5, log, &r); /* stopped by the limit's SIGTERM */
  assert_string_equal(r.outcome, "timeout");
  assert_string_equal(r.reason, "time limit 2.5 s");
  ves_study_classify(127, 0, 0, 10, NULL, &r);
  assert_string_equal(r.outcome, "crashed");
  assert_string_equal(r.reason, "exit code 127");
}

/* ---- the table ------------------------------------------------------------------ */

/* Split one CSV line (RFC 4180, no embedded newlines) into fields; returns
 * the count. */
static int csv_split(const char *line, char fields[][256], int max) {
  int n = 0;
  const char *p = line;
  for (;;) {
    char *out = fields[n];
    size_t k = 0;
    if (*p == '"') {
      p++;
      while (*p && !(*p == '"' && p[1] != '"')) {
        if (*p == '"') p++;
        if (k < 255) out[k++] = *p;
        p++;
      }
      if (*p == '"') p++;
    } else {
      while (*p && *p != ',' && *p != '\n')
        if (k < 255) out[k++] = *p++;
    }
    out[k] = 0;
    n++;
    if (*p != ',' || n == max) break;
    p++;
  }
  return n;
}

static void test_csv(void **state) {
  (void)state;
  ves_study *s = small_study("csv.ini", "");
  char dir[PATH_MAX], cells[PATH_MAX + 8], path[PATH_MAX + 16], err[1024];
  tmp_path(dir, sizeof dir, "csv");
  snprintf(cells, sizeof cells, "%s/cells", dir);
  assert_int_equal(mkdir(dir, 0777), 0);
  assert_int_equal(mkdir(cells, 0777), 0);
  /* cells 0 and 2 done (no .h5: a bad_input and a converged one), 1 and 3 not */
  ves_study_result r;
  memset(&r, 0, sizeof r);
  snprintf(r.outcome, sizeof r.outcome, "bad_input");
  snprintf(r.reason, sizeof r.reason, "x.ini: [time] dt = \"1\", or so");
  r.exit_code = 2, r.wall_seconds = 0.125, r.cpu_seconds = 0.0625, r.peak_mb = 7.5;
  assert_int_equal(ves_study_cell_signature(s, 0, r.signature, sizeof r.signature), VES_OK);
  ves_study_cell_path(s, 0, dir, ".result", path, sizeof path);
  assert_int_equal(ves_study_result_write(path, &r), VES_OK);
  snprintf(r.outcome, sizeof r.outcome, "converged");
  r.reason[0] = 0, r.exit_code = 0;
  assert_int_equal(ves_study_cell_signature(s, 2, r.signature, sizeof r.signature), VES_OK);
  ves_study_cell_path(s, 2, dir, ".result", path, sizeof path);
  assert_int_equal(ves_study_result_write(path, &r), VES_OK);
  ves_study_table t;
  assert_int_equal(ves_study_collect(s, dir, &t, err, sizeof err), VES_OK);
  assert_int_equal(t.cells, 4);
  assert_int_equal(t.rows, 2);
  assert_int_equal(t.converged, 0); /* exit 0 without output is no_output */
  char csv[8192], line[3][2048], f[40][256];
  snprintf(path, sizeof path, "%s/study.csv", dir);
  assert_true(slurp(path, csv, sizeof csv) > 0);
  printf("# %s", csv);
  int nl = 0;
  for (char *p = csv, *e; *p && nl < 3; p = e + 1, nl++) {
    e = strchr(p, '\n');
    assert_non_null(e);
    snprintf(line[nl], sizeof line[nl], "%.*s", (int)(e - p), p);
  }
  assert_int_equal(nl, 3);
  const int nh = csv_split(line[0], f, 40);
  assert_string_equal(f[0], "cell");
  assert_string_equal(f[1], "time.dt_initial");
  assert_string_equal(f[2], "status");
  assert_string_equal(f[nh - 1], "peak_mb");
  int col_wall = -1;
  for (int i = 0; i < nh; i++)
    if (!strcmp(f[i], "wall_seconds")) col_wall = i;
  assert_true(col_wall > 0);
  assert_int_equal(csv_split(line[1], f, 40), nh); /* every row as wide as the header */
  assert_string_equal(f[0], "dt_initial=0.001");
  assert_string_equal(f[1], "0.001");
  assert_string_equal(f[2], "bad_input");
  assert_string_equal(f[3], "x.ini: [time] dt = \"1\", or so"); /* quoted, quotes doubled */
  assert_string_equal(f[4], "2");
  assert_string_equal(f[5], ""); /* steps: unknown without an output file */
  assert_string_equal(f[col_wall], "0.125");
  assert_int_equal(csv_split(line[2], f, 40), nh);
  assert_string_equal(f[0], "dt_initial=0.003");
  assert_string_equal(f[2], "no_output");
  ves_study_destroy(&s);
}

/* ---- the runner with a stand-in program ------------------------------------------ */

/* A shell script standing in for vesica: it appends its cell's dt to
 * tmpdir/starts, then by dt: 0.001 converges after 0.3 s, 0.002 fails as a
 * run does (exit 3 with its message), 0.003 crashes (SIGSEGV), 0.004 hangs. */
static void write_fake(char *prog, size_t len) {
  tmp_path(prog, len, "fake.sh");
  char text[1024];
  snprintf(text, sizeof text,
           "#!/bin/sh\n"
           "dt=$(printf '%%s\\n' \"$@\" | sed -n 's/^time.dt_initial=//p')\n"
           "echo \"$dt\" >> %s/starts\n"
           "case \"$dt\" in\n"
           "  0.001) sleep 0.3; exit 0;;\n"
           "  0.002) echo 'vesica run: p.ini: no acceptable step at t* = 0 down to dt* = 0.002 "
           "(iteration limit reached); the last good state' >&2; exit 3;;\n"
           "  0.003) kill -SEGV $$;;\n"
           "  *) exec sleep 30;;\n"
           "esac\n",
           tmpdir);
  write_file(prog, text);
  chmod(prog, 0755);
}

static int count_lines(const char *path) {
  char buf[4096];
  if (slurp(path, buf, sizeof buf) < 0) return 0;
  int n = 0;
  for (char *p = buf; *p; p++) n += *p == '\n';
  return n;
}

typedef struct {
  long ended;                  /* cells ended so far */
  long stop_after;             /* set *stop once this many ended (0: never) */
  volatile sig_atomic_t *stop; /* the runner's stop flag */
  long skipped;                /* as reported at the start */
} fake_ctx;

static void fake_progress(void *ctx, const ves_study_progress *p) {
  fake_ctx *c = ctx;
  if (p->cell < 0 && p->done == 0) c->skipped = p->skipped;
  if (p->cell >= 0) c->ended++;
  if (c->stop_after && c->ended >= c->stop_after) *c->stop = 1;
}

static void test_run_fake(void **state) {
  (void)state;
  char prog[PATH_MAX], dir[PATH_MAX], starts[PATH_MAX], path[PATH_MAX], err[1024];
  write_fake(prog, sizeof prog);
  tmp_path(dir, sizeof dir, "fake");
  tmp_path(starts, sizeof starts, "starts");
  ves_study *s = small_study("fake.ini", "time_limit = 1\n");
  volatile sig_atomic_t stop = 0;
  fake_ctx c = {0};
  c.stop = &stop;
  ves_study_run_opts o = {.program = prog,
                          .dir = dir,
                          .jobs = 2,
                          .only = -1,
                          .grace = 0.5,
                          .stop = &stop,
                          .progress = fake_progress,
                          .ctx = &c};
  double t0 = ves_wall_seconds();
  assert_int_equal(ves_study_run(s, &o, err, sizeof err), VES_OK);
  double sec = ves_wall_seconds() - t0;
  /* the hanging cell ends at its limit (1 s, SIGTERM; sleep dies of it), not
   * at its 30 s: bound 1 + 0.5 grace + the others, generously 10 s */
  printf("# fake study: %.2f s\n", sec);
  assert_true(sec >= 1.0 && sec < 10.0);
  assert_int_equal(c.ended, 4);
  assert_int_equal(count_lines(starts), 4);
  const char *want[] = {"converged", "failed", "crashed", "timeout"};
  for (long k = 0; k < 4; k++) {
    ves_study_result r;
    ves_study_cell_path(s, k, dir, ".result", path, sizeof path);
    assert_int_equal(ves_study_result_read(path, &r), VES_OK);
    printf("# cell %ld: %s: %s (%.2f s)\n", k, r.outcome, r.reason, r.wall_seconds);
    assert_string_equal(r.outcome, want[k]);
  }
  ves_study_result r;
  ves_study_cell_path(s, 1, dir, ".result", path, sizeof path);
  assert_int_equal(ves_study_result_read(path, &r), VES_OK);
  assert_non_null(strstr(r.reason, "(iteration limit reached)"));
  ves_study_cell_path(s, 0, dir, ".result", path, sizeof path);
  assert_int_equal(ves_study_result_read(path, &r), VES_OK);
  assert_true(r.wall_seconds >= 0.3); /* the stand-in slept 0.3 s */
  /* a rerun starts nothing; --retry-failed reruns exactly the three others */
  c.ended = 0;
  assert_int_equal(ves_study_run(s, &o, err, sizeof err), VES_OK);
  assert_int_equal(c.skipped, 4);
  assert_int_equal(c.ended, 0);
  assert_int_equal(count_lines(starts), 4);
  o.retry_failed = 1;
  assert_int_equal(ves_study_run(s, &o, err, sizeof err), VES_OK);
  assert_int_equal(c.skipped, 1);
  assert_int_equal(c.ended, 3);
  assert_int_equal(count_lines(starts), 7);
  /* --cell: one cell, here one already done */
  o.retry_failed = 0, o.only = 0, c.ended = 0;
  assert_int_equal(ves_study_run(s, &o, err, sizeof err), VES_OK);
  assert_int_equal(c.skipped, 1);
  assert_int_equal(count_lines(starts), 7);
  ves_study_destroy(&s);
}

/* Stopped mid-way (as by SIGINT): the ended cells are kept, the running one
 * is stopped and not recorded; the rerun runs exactly the cells not ended. */
static void test_run_stop(void **state) {
  (void)state;
  char prog[PATH_MAX], dir[PATH_MAX], starts[PATH_MAX], err[1024], text[2048];
  write_fake(prog, sizeof prog);
  tmp_path(dir, sizeof dir, "stop");
  tmp_path(starts, sizeof starts, "starts");
  unlink(starts);
  ves_study *s = NULL;
  snprintf(text, sizeof text,
           "[study]\nproblem = base.ini\nrun = step\n[set]\n%stime.dt_initial = 0.001\n[axes]\n"
           "material.c0 = 0, 1, 2, 3, 4\n",
           TINY_SET);
  assert_int_equal(load_text("stop.ini", text, 1000, &s, err, sizeof err), VES_OK);
  volatile sig_atomic_t stop = 0;
  fake_ctx c = {.stop_after = 2, .stop = &stop};
  ves_study_run_opts o = {.program = prog,
                          .dir = dir,
                          .jobs = 1,
                          .only = -1,
                          .grace = 0.5,
                          .stop = &stop,
                          .progress = fake_progress,
                          .ctx = &c};
  assert_int_equal(ves_study_run(s, &o, err, sizeof err), VES_STEP_REJECTED);
  assert_int_equal(c.ended, 2);
  int done = 0;
  for (long k = 0; k < 5; k++) done += ves_study_cell_done(s, k, dir, 0);
  assert_int_equal(done, 2);
  const int started = count_lines(starts); /* 2, or 3 when the third had started */
  assert_true(started == 2 || started == 3);
  stop = 0, c.stop_after = 0, c.ended = 0;
  assert_int_equal(ves_study_run(s, &o, err, sizeof err), VES_OK);
  assert_int_equal(c.skipped, 2);
  assert_int_equal(c.ended, 3);
  assert_int_equal(count_lines(starts), started + 3);
  ves_study_destroy(&s);
}

/* ---- the program: a real study on the tiny problem ---------------------------------- */

typedef struct {
  int code;
  char out[8192], err[8192];
} result;

/* Run argv (NULL-terminated; argv[0] the program) with the environment
 * variable env ("NAME=value", or NULL) added. */
static void run_prog(result *r, char *const *argv, const char *env) {
  char o[PATH_MAX], e[PATH_MAX];
  tmp_path(o, sizeof o, "prog.out");
  tmp_path(e, sizeof e, "prog.err");
  pid_t pid = fork();
  assert_true(pid >= 0);
  if (pid == 0) {
    int fo = open(o, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    int fe = open(e, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fo < 0 || fe < 0) _exit(127);
    dup2(fo, 1), dup2(fe, 2);
    if (env) putenv((char *)env);
    execv(argv[0], argv);
    _exit(127);
  }
  int status;
  assert_int_equal(waitpid(pid, &status, 0), pid);
  r->code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  slurp(o, r->out, sizeof r->out);
  slurp(e, r->err, sizeof r->err);
}

/* The columns of a table that do not depend on timing, one line per row. */
static void stable_columns(const char *path, char *out, size_t len) {
  char csv[16384], f[40][256];
  assert_true(slurp(path, csv, sizeof csv) > 0);
  const char *keep[] = {"cell",    "solver.backend", "time.dt_initial", "status",
                        "reason",  "steps",          "iterations",      "g_evals",
                        "h_evals", "energy_initial", "energy_final"};
  enum { NK = sizeof keep / sizeof keep[0] };
  int col[NK];
  size_t at = 0;
  out[0] = 0;
  char *save = NULL;
  int row = 0;
  for (char *line = strtok_r(csv, "\n", &save); line; line = strtok_r(NULL, "\n", &save), row++) {
    int n = csv_split(line, f, 40);
    for (int i = 0; i < NK; i++) {
      if (row == 0) {
        col[i] = -1;
        for (int j = 0; j < n; j++)
          if (!strcmp(f[j], keep[i])) col[i] = j;
        assert_true(col[i] >= 0);
      }
      at += (size_t)snprintf(out + at, len - at, "%s%s", f[col[i]], i + 1 < NK ? "," : "\n");
    }
  }
}

static void test_program(void **state) {
  (void)state;
  char study[PATH_MAX], dir[PATH_MAX], dir2[PATH_MAX], csv[PATH_MAX + 16], text[2048];
  tmp_path(study, sizeof study, "real.ini");
  tmp_path(dir, sizeof dir, "real");
  tmp_path(dir2, sizeof dir2, "real_slurm");
  /* newton converges at dt* 5e-3; explicit Euler fails at dt* 1 */
  snprintf(text, sizeof text,
           "[study]\nproblem = base.ini\nrun = step\ntime_limit = 120\n[set]\n%s[axes]\n"
           "solver.backend = newton, euler\ntime.dt_initial = 5e-3, 1\n",
           TINY_SET);
  write_file(study, text);
  result r;
  char *run_args[] = {vesica, "study", study, "--out", dir, "--jobs", "2", NULL};
  double t0 = ves_wall_seconds();
  run_prog(&r, run_args, NULL);
  printf("# vesica study (%.1f s) -> %d\n%s%s", ves_wall_seconds() - t0, r.code, r.out, r.err);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "4 of 4 cells"));
  snprintf(csv, sizeof csv, "%s/study.csv", dir);
  char table[4096];
  stable_columns(csv, table, sizeof table);
  printf("# %s", table);
  /* newton at 5e-3: converged in one step, E* down; euler at 1: failed */
  char *l = strstr(table, "backend=newton,dt_initial=5e-3,newton,5e-3,converged,,1,");
  assert_non_null(l);
  double it, g, h, E0, E1;
  assert_int_equal(sscanf(l + strlen("backend=newton,dt_initial=5e-3,newton,5e-3,converged,,1,"),
                          "%lf,%lf,%lf,%lf,%lf", &it, &g, &h, &E0, &E1),
                   5);
  assert_true(it >= 1 && g >= 1 && h >= 1 && E1 < E0);
  assert_non_null(strstr(table, "backend=euler,dt_initial=1,euler,1,failed,no acceptable step"));
  /* the figures exist and are PNG files */
  char png[PATH_MAX + 32], head[8];
  snprintf(png, sizeof png, "%s/study_frontier.png", dir);
  assert_true(slurp(png, head, sizeof head) == 7 && !memcmp(head + 1, "PNG", 3));
  /* a rerun starts nothing and writes the same table */
  run_prog(&r, run_args, NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.err, "4/4 cells done (4 before)"));
  char table2[4096];
  stable_columns(csv, table2, sizeof table2);
  assert_string_equal(table, table2);

  /* Slurm: the job-array script, each task run as Slurm would (its
   * environment), then --collect: the same table as the local run's */
  char *emit[] = {vesica, "study", study, "--out", dir2, "--emit", "slurm", NULL};
  run_prog(&r, emit, NULL);
  assert_int_equal(r.code, 0);
  char sb[PATH_MAX + 16], script[4096];
  snprintf(sb, sizeof sb, "%s/study.sbatch", dir2);
  assert_true(slurp(sb, script, sizeof script) > 0);
  printf("# %s", script);
  assert_non_null(strstr(script, "#SBATCH --array=0-3\n"));
  assert_non_null(strstr(script, "#SBATCH --time=7\n")); /* 120 s: 2 min + 5 */
  assert_non_null(strstr(script, "--cell \"${SLURM_ARRAY_TASK_ID"));
  char *bash[] = {"/bin/bash", sb, NULL};
  run_prog(&r, bash, NULL); /* outside an array: refuses */
  assert_true(r.code != 0);
  for (int k = 0; k < 4; k++) {
    static char env[64];
    snprintf(env, sizeof env, "SLURM_ARRAY_TASK_ID=%d", k);
    run_prog(&r, bash, env);
    assert_int_equal(r.code, 0);
  }
  char *coll[] = {vesica, "study", study, "--out", dir2, "--collect", NULL};
  run_prog(&r, coll, NULL);
  assert_int_equal(r.code, 0);
  snprintf(csv, sizeof csv, "%s/study.csv", dir2);
  stable_columns(csv, table2, sizeof table2);
  assert_string_equal(table, table2);

  /* a cell past its time limit and a bad cell key: recorded or refused */
  snprintf(text, sizeof text,
           "[study]\nproblem = base.ini\nrun = t_end\ntime_limit = 1\n[set]\n%stime.t_end = 1e6\n"
           "time.dt_max = 1e-3\n[axes]\nsolver.backend = newton\n",
           TINY_SET);
  write_file(study, text);
  char dir3[PATH_MAX];
  tmp_path(dir3, sizeof dir3, "real_timeout");
  char *tl[] = {vesica, "study", study, "--out", dir3, "--quiet", NULL};
  t0 = ves_wall_seconds();
  run_prog(&r, tl, NULL);
  printf("# time limit (%.1f s): %s%s", ves_wall_seconds() - t0, r.out, r.err);
  assert_int_equal(r.code, 0);
  snprintf(csv, sizeof csv, "%s/study.csv", dir3);
  char buf[4096];
  assert_true(slurp(csv, buf, sizeof buf) > 0);
  assert_non_null(strstr(buf, ",timeout,\"time limit 1 s\","));
  snprintf(text, sizeof text, "[study]\nproblem = base.ini\n[axes]\nsolver.bakend = newton\n");
  write_file(study, text);
  run_prog(&r, tl, NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "real.ini: [axes] solver.bakend: unknown problem key"));
}

/* Killed with SIGKILL mid-way (no chance to clean up): the rerun keeps
 * every cell that had ended (their .result files unchanged) and runs only
 * the others. Also the command's usage errors. */
static void test_program_kill(void **state) {
  (void)state;
  char study[PATH_MAX], dir[PATH_MAX], cells[PATH_MAX + 8], text[2048];
  tmp_path(study, sizeof study, "kill.ini");
  tmp_path(dir, sizeof dir, "kill");
  snprintf(cells, sizeof cells, "%s/cells", dir);
  snprintf(text, sizeof text,
           "[study]\nproblem = base.ini\nrun = step\n[set]\n%s[axes]\n"
           "time.dt_initial = 1e-3, 2e-3, 3e-3, 4e-3\n",
           TINY_SET);
  write_file(study, text);
  pid_t pid = fork();
  assert_true(pid >= 0);
  if (pid == 0) {
    int fd = open("/dev/null", O_WRONLY);
    if (fd >= 0) dup2(fd, 1), dup2(fd, 2);
    execl(vesica, vesica, "study", study, "--out", dir, "--jobs", "1", (char *)NULL);
    _exit(127);
  }
  /* wait for two ended cells (up to 120 s), then kill the study at once */
  ves_study *s = NULL;
  char err[1024];
  assert_int_equal(ves_study_load(study, 1000, &s, err, sizeof err), VES_OK);
  int ended = 0;
  struct timespec nap = {0, 20000000};
  for (int i = 0; i < 6000 && ended < 2; i++) {
    nanosleep(&nap, NULL);
    ended = 0;
    for (long k = 0; k < 4; k++) ended += ves_study_cell_done(s, k, dir, 0);
  }
  assert_int_equal(kill(pid, SIGKILL), 0);
  int status;
  assert_int_equal(waitpid(pid, &status, 0), pid);
  char before[4][2048], path[PATH_MAX];
  ended = 0;
  for (long k = 0; k < 4; k++) {
    ves_study_cell_path(s, k, dir, ".result", path, sizeof path);
    before[k][0] = 0;
    if (ves_study_cell_done(s, k, dir, 0)) ended++, slurp(path, before[k], sizeof before[k]);
  }
  printf("# killed with %d cell(s) ended\n", ended);
  assert_true(ended >= 2 && ended < 4);
  result r;
  char *again[] = {vesica, "study", study, "--out", dir, "--jobs", "1", NULL};
  run_prog(&r, again, NULL);
  printf("# rerun -> %d\n%s", r.code, r.err);
  assert_int_equal(r.code, 0);
  char want[64]; /* the start line counts the kept cells among the done ones */
  snprintf(want, sizeof want, "%d/4 cells done (%d before)", ended, ended);
  assert_non_null(strstr(r.err, want));
  int started = 0;
  for (const char *p = r.err; (p = strstr(p, "\ncell ")) != NULL; p++) started++;
  assert_int_equal(started, 4 - ended); /* one line per cell run */
  for (long k = 0; k < 4; k++) {
    char now[2048];
    ves_study_cell_path(s, k, dir, ".result", path, sizeof path);
    assert_true(slurp(path, now, sizeof now) > 0);
    if (before[k][0]) assert_string_equal(before[k], now); /* kept, not rerun */
  }
  ves_study_destroy(&s);

  /* usage */
  char *bad[][8] = {{vesica, "study", NULL},
                    {vesica, "study", study, "--emit", "pbs", NULL},
                    {vesica, "study", study, "--cell", "4", NULL},
                    {vesica, "study", study, "--jobs", "0", NULL},
                    {vesica, "study", study, "--cell", "1", "--collect", NULL},
                    {vesica, "study", study, "--out", "/nonexistent/x", "--collect", NULL},
                    {vesica, "study", study, "--frobnicate", NULL}};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    run_prog(&r, bad[i], NULL);
    printf("# usage %zu -> %d: %s", i, r.code, r.err);
    assert_int_equal(r.code, 2);
    assert_true(r.err[0] != 0);
  }
  char *help[] = {vesica, "study", "--help", NULL};
  run_prog(&r, help, NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "usage: vesica study"));
  char *keys[] = {vesica, "keys", "--study", NULL};
  run_prog(&r, keys, NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "| study | time_limit | real | 3600 |"));
}

int main(int argc, char **argv) {
  setvbuf(stdout, NULL, _IOLBF, 0);
  (void)argc;
  if (getenv("TEST_FILTER")) cmocka_set_test_filter(getenv("TEST_FILTER"));
  char self[PATH_MAX - 16];
  snprintf(self, sizeof self, "%s", argv[0]);
  char *slash = strrchr(self, '/');
  if (slash)
    *slash = 0;
  else
    snprintf(self, sizeof self, ".");
  snprintf(vesica, sizeof vesica, "%s/../vesica", self);
  if (access(vesica, X_OK)) {
    fprintf(stderr, "test_study: %s: not found (build it first)\n", vesica);
    return 1;
  }
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_parse_axis),    cmocka_unit_test(test_grid),
      cmocka_unit_test(test_bad_studies),   cmocka_unit_test(test_result_resume),
      cmocka_unit_test(test_classify),      cmocka_unit_test(test_csv),
      cmocka_unit_test(test_run_fake),      cmocka_unit_test(test_run_stop),
      cmocka_unit_test(test_program),       cmocka_unit_test(test_program_kill),
  };
  // clang-format on
  return cmocka_run_group_tests_name("study", tests, setup_all, teardown_all);
}
