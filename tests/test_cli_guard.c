/* vesica — tests of the guard on every file the program writes
 * (build/vesica, run as a child process): a file a running vesica holds is
 * never overwritten, whatever the option that names it (--out, --series,
 * spectrum --vectors, plot's figures) and even with --force, and the run
 * finishes untouched; a command's own input is never its output; a
 * --series text that cannot be written ends with exit 3, the run kept
 * whole; a standard output that cannot be written exits 3; an option's
 * negative value is out of range, not missing. Run from the repository
 * root (make test does; the full-disk case needs root to mount a tmpfs). */
#include "cli_test_impl.h"

/* The steps of the running run: long enough for every attempt to meet it
 * running (each attempt is refused before any setup: ~0.1 s), short
 * enough for the test (~0.3 s a step). */
#define LIVE_STEPS "25"

/* The columns of the --series text (docs/manual.md, "The series"). */
#define TSV_COLUMNS 21

/* The tmpfs of the full-disk case, unmounted at the end whatever happens. */
static char mnt[128];

static int teardown_guard(void **state) {
  if (mnt[0] && umount(mnt) == 0) rmdir(mnt);
  return teardown_all(state);
}

/* A problem of fixed steps: --max-steps ends its runs. */
static void long_problem(const char *ini) {
  write_file(ini, "[time]\nt_end = 100\nadaptive = 0\ndt_max = 5e-3\n");
}

/* Run vesica with args and its standard output on /dev/full (how: 'f') or
 * closed ('c'), stderr into r->err. */
static void run_stdout(result *r, char how, char *const *args) {
  char e[128];
  snprintf(e, sizeof e, "%s/stdout.err", tmpdir);
  pid_t pid = fork();
  assert_true(pid >= 0);
  if (pid == 0) {
    int fe = open(e, O_WRONLY | O_CREAT | O_TRUNC, 0644), fo = -1;
    if (fe < 0) _exit(127);
    dup2(fe, 2);
    if (how == 'f') {
      if ((fo = open("/dev/full", O_WRONLY)) < 0) _exit(127);
      dup2(fo, 1);
    } else {
      close(1);
    }
    char *argv[32];
    int n = 0;
    argv[n++] = vesica;
    for (; args[n - 1] && n < 31; n++) argv[n] = args[n - 1];
    argv[n] = NULL;
    execv(vesica, argv);
    _exit(127);
  }
  int status;
  assert_int_equal(waitpid(pid, &status, 0), pid);
  r->code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  r->out[0] = 0;
  slurp(e, r->err, sizeof r->err);
  unlink(e);
}

/* What a child said, one line "# what -> exit: message". */
static void say(const char *what, const result *r) {
  const size_t n = strlen(r->err);
  printf("# %s -> %d: %s%s", what, r->code, r->err, n && r->err[n - 1] == '\n' ? "" : "\n");
}

/* An attempt on the running run's files: exit 2, the message naming the
 * file as in use (frag), nothing written (no file `absent`). */
static void refused(const char *what, const char *frag, const char *absent, char *const *args) {
  result r;
  collect(spawn(args, NULL), &r);
  say(what, &r);
  if (r.code != 2 || !strstr(r.err, frag))
    fail_msg("%s: exit %d, '%s' (want 2 and '%s')", what, r.code, r.err, frag);
  if (absent && exists(absent)) fail_msg("%s: %s written", what, absent);
}

/* The rows of the --series text path after its header line (the t = 0
 * row first), each checked to be whole with `fields` tab-separated fields. */
static long tsv_rows(const char *path, int fields) {
  FILE *f = fopen(path, "r");
  assert_non_null(f);
  char line[4096];
  long rows = 0;
  if (!fgets(line, sizeof line, f) || strncmp(line, "step\t", 5) || tsv_fields(line) != fields)
    fail_msg("%s: no header line of %d names: '%s'", path, fields, line);
  while (fgets(line, sizeof line, f)) {
    if (!strchr(line, '\n') || tsv_fields(line) != fields)
      fail_msg("%s: row %ld incomplete: '%s'", path, rows + 1, line);
    rows++;
  }
  fclose(f);
  return rows;
}

/* While a run writes live.h5 (and live_energy.png, its --series text, so
 * that `plot live.h5` meets it as a figure), every command that would
 * write one of its files is refused with exit 2, --force or not: another
 * run's --series or --out, spectrum's --vectors, plot's figures, the
 * XDMF file beside it. The running run then finishes with exit 0, its
 * file whole (vesica info reads every step) and its text whole. */
static void test_live_files(void **state) {
  (void)state;
  char ini[128], src[128], live[128], ltsv[128], lxdmf[128], other[128], oxdmf[128];
  tmp_path(ini, sizeof ini, "live.ini");
  tmp_path(src, sizeof src, "src.h5");
  tmp_path(live, sizeof live, "live.h5");
  tmp_path(ltsv, sizeof ltsv, "live_energy.png");
  tmp_path(lxdmf, sizeof lxdmf, "live.xdmf");
  tmp_path(other, sizeof other, "other.h5");
  tmp_path(oxdmf, sizeof oxdmf, "other.xdmf");
  long_problem(ini);
  result r;
  run(&r, "run", ini, TINY, "--out", src, "--quiet", "--max-steps", "1", NULL);
  if (r.code) fail_msg("the finished run: exit %d: %s", r.code, r.err);
  char *largs[] = {"run", ini,       TINY,          "--out",    live, "--series",
                   ltsv,  "--quiet", "--max-steps", LIVE_STEPS, NULL};
  pid_t pid = spawn_tag(largs, NULL, "live");
  assert_true(wait_rows(live, 1) >= 1); /* running: its files created and locked */
  const char *held = "in use by a running vesica";
  char *a1[] = {"run", ini,       TINY,          "--out", other,     "--series",
                live,  "--force", "--max-steps", "1",     "--quiet", NULL};
  refused("run --series (the running run's HDF5 file) --force", held, other, a1);
  char *a2[] = {"run", ini,       TINY,          "--out", other,     "--series",
                ltsv,  "--force", "--max-steps", "1",     "--quiet", NULL};
  refused("run --series (the running run's --series text) --force", held, other, a2);
  char *a3[] = {"run", ini,       TINY,          "--out", other,     "--series",
                lxdmf, "--force", "--max-steps", "1",     "--quiet", NULL};
  refused("run --series (the running run's XDMF file) --force", "the XDMF file of", other, a3);
  char *a4[] = {"run", ini, TINY, "--out", live, "--force", "--max-steps", "1", "--quiet", NULL};
  refused("run --out (the running run's file) --force", held, NULL, a4);
  char *a5[] = {"spectrum", src,         "--modes", "2",       "--lanczos",
                "10",       "--vectors", live,      "--force", NULL};
  refused("spectrum --vectors (the running run's HDF5 file) --force", held, NULL, a5);
  char *a6[] = {"spectrum", src,         "--modes", "2",       "--lanczos",
                "10",       "--vectors", ltsv,      "--force", NULL};
  refused("spectrum --vectors (the running run's --series text) --force", held, NULL, a6);
  char *a7[] = {"plot", live, "--force", NULL};
  refused("plot --force (a figure is the running run's --series text)", held, NULL, a7);
  /* the attempts met the run running: it had not finished before them */
  int status;
  if (waitpid(pid, &status, WNOHANG) != 0)
    fail_msg("the running run ended before the attempts were over: make LIVE_STEPS larger");
  collect_tag(pid, &r, "live");
  say("the running run", &r);
  assert_int_equal(r.code, 0);
  run(&r, "info", live, NULL);
  if (r.code) fail_msg("info of the run's file: exit %d: %s", r.code, r.err);
  char v[64];
  value_of(r.out, "steps = ", v, sizeof v);
  assert_string_equal(v, LIVE_STEPS);
  value_of(r.out, "status = ", v, sizeof v);
  assert_string_equal(v, "stopped");
  assert_int_equal(tsv_rows(ltsv, TSV_COLUMNS), atol(LIVE_STEPS) + 1); /* and t = 0 */
  /* a finished, unlocked output: --force replaces it */
  run(&r, "spectrum", src, "--modes", "2", "--lanczos", "10", "--vectors", ltsv, "--force", NULL);
  if (r.code)
    fail_msg("spectrum --vectors over a finished file --force: exit %d: %s", r.code, r.err);
  assert_false(exists(other));
  unlink(ini), rm_run(src), rm_run(live), unlink(ltsv), unlink(oxdmf);
}

/* A command's own input is never its output, even with --force: the
 * problem file and its points file for run (--out, --series), the file
 * spectrum reads for --vectors, the file plot reads for a figure (reached
 * through a link named as the figure); nor the scratch files the output is
 * written to before its rename (F.part, a figure's .part) when they are
 * links to the input. */
static void test_own_input(void **state) {
  (void)state;
  char ini[128], pts[128], src[128], out[128], fig[160], dir[128], cmd[512];
  tmp_path(ini, sizeof ini, "own.ini");
  tmp_path(pts, sizeof pts, "own_points.txt");
  tmp_path(src, sizeof src, "own.h5");
  tmp_path(out, sizeof out, "own_out.h5");
  tmp_path(dir, sizeof dir, "own_figs");
  snprintf(cmd, sizeof cmd, "cp data/cup.txt %s", pts);
  assert_int_equal(system(cmd), 0);
  write_file(ini, "[shape]\ntype = curve\npoints = own_points.txt\n");
  const char *frag = "is the input file";
  char *a1[] = {"run", ini, "--out", pts, "--force", "--quiet", NULL};
  refused("run --out (its points file) --force", frag, NULL, a1);
  char *a2[] = {"run", ini, "--out", out, "--series", pts, "--force", "--quiet", NULL};
  refused("run --series (its points file) --force", frag, out, a2);
  char *a3[] = {"run", ini, "--out", out, "--series", ini, "--force", "--quiet", NULL};
  refused("run --series (its problem file) --force", frag, out, a3);
  long_problem(ini);
  result r;
  run(&r, "run", ini, TINY, "--out", src, "--quiet", "--max-steps", "1", NULL);
  if (r.code) fail_msg("the run: exit %d: %s", r.code, r.err);
  const long size = file_size(src);
  char *a4[] = {"spectrum", src,         "--modes", "2",       "--lanczos",
                "10",       "--vectors", src,       "--force", NULL};
  refused("spectrum --vectors (its input) --force", frag, NULL, a4);
  /* the scratch file F.part that F is written to, a link to the input */
  char vec[128], part[160];
  tmp_path(vec, sizeof vec, "own_vec.txt");
  snprintf(part, sizeof part, "%s.part", vec);
  assert_int_equal(symlink(src, part), 0);
  char *a6[] = {"spectrum", src, "--modes", "2", "--lanczos", "10", "--vectors", vec, NULL};
  refused("spectrum --vectors F (F.part a link to its input)", frag, vec, a6);
  unlink(part);
  assert_int_equal(file_size(src), size);
  assert_int_equal(mkdir(dir, 0755), 0);
  snprintf(fig, sizeof fig, "%s/own_energy.png", dir);
  assert_int_equal(symlink(src, fig), 0);
  char *a5[] = {"plot", src, "--outdir", dir, "--force", NULL};
  refused("plot --force (a figure that is its input)", frag, NULL, a5);
  unlink(fig);
  /* the .part gnuplot writes a figure to, a link to the input */
  snprintf(fig, sizeof fig, "%s/own_flow.png.part", dir);
  assert_int_equal(symlink(src, fig), 0);
  char *a7[] = {"plot", src, "--outdir", dir, NULL};
  refused("plot (a figure's .part a link to its input)", frag, NULL, a7);
  assert_int_equal(file_size(src), size);
  run(&r, "info", src, NULL);
  assert_int_equal(r.code, 0);
  unlink(fig), rmdir(dir), unlink(ini), unlink(pts), rm_run(src);
}

/* --series on a full disk (a tmpfs of 8 KiB, root): a text whose header
 * cannot be written ends the run before its first step (exit 3, nothing
 * left); a text that fills the disk during the run ends there, cut back to
 * its last whole line, and the run goes on to its end with the HDF5 file
 * whole, then exits 3 naming the cause. */
static void test_series_full_disk(void **state) {
  (void)state;
  char ini[128], fill[160], tsv[160], out[128], xdmf[128];
  tmp_path(ini, sizeof ini, "fd.ini");
  tmp_path(mnt, sizeof mnt, "fd_tmpfs");
  tmp_path(out, sizeof out, "fd.h5");
  tmp_path(xdmf, sizeof xdmf, "fd.xdmf");
  snprintf(fill, sizeof fill, "%s/fill", mnt);
  snprintf(tsv, sizeof tsv, "%s/fd.tsv", mnt);
  long_problem(ini);
  assert_int_equal(mkdir(mnt, 0755), 0);
  if (mount("tmpfs", mnt, "tmpfs", 0, "size=8k") != 0) {
    printf("# tmpfs: not mounted (%s): the full-disk case is not run\n", strerror(errno));
    rmdir(mnt), unlink(ini);
    mnt[0] = 0;
    skip();
  }
  /* no room at all: the header fails */
  char page[8192];
  memset(page, 'x', sizeof page);
  FILE *f = fopen(fill, "w");
  assert_non_null(f);
  fwrite(page, 1, sizeof page, f);
  fclose(f);
  assert_int_equal(file_size(fill), 8192); /* the tmpfs full */
  result r;
  run(&r, "run", ini, TINY, "--out", out, "--series", tsv, "--quiet", "--max-steps", "3", NULL);
  say("--series on a full disk", &r);
  assert_int_equal(r.code, 3);
  assert_non_null(strstr(r.err, tsv));
  assert_non_null(strstr(r.err, "No space left on device"));
  assert_false(exists(out)); /* nothing run, nothing left */
  assert_false(exists(xdmf));
  assert_false(exists(tsv));
  /* one page free: the header and about 20 rows fit, the run goes on */
  assert_int_equal(truncate(fill, 4096), 0);
  const char *steps = "45";
  run(&r, "run", ini, TINY, "--out", out, "--series", tsv, "--quiet", "--max-steps", steps, NULL);
  say("--series filling the disk during the run", &r);
  assert_int_equal(r.code, 3);
  assert_non_null(strstr(r.err, "No space left on device"));
  assert_non_null(strstr(r.err, "vesica info"));
  const long rows = tsv_rows(tsv, TSV_COLUMNS); /* every line whole */
  printf("# the text holds %ld rows (t = 0 included) of %s steps\n", rows, steps);
  assert_true(rows >= 1 && rows <= atol(steps)); /* rows: steps + 1 with t = 0 */
  run(&r, "info", out, NULL);
  if (r.code) fail_msg("info of the run's file: exit %d: %s", r.code, r.err);
  char v[64];
  value_of(r.out, "steps = ", v, sizeof v);
  assert_string_equal(v, steps); /* the run whole */
  value_of(r.out, "status = ", v, sizeof v);
  assert_string_equal(v, "stopped");
  unlink(tsv), unlink(fill);
  if (umount(mnt) == 0) rmdir(mnt), mnt[0] = 0;
  unlink(ini), rm_run(out);
}

/* A standard output that cannot be written: a full one (/dev/full) and a
 * closed one exit 3 naming it, not 0. */
static void test_stdout(void **state) {
  (void)state;
  char ini[128], src[128];
  tmp_path(ini, sizeof ini, "so.ini");
  tmp_path(src, sizeof src, "so.h5");
  long_problem(ini);
  result r;
  run(&r, "run", ini, TINY, "--out", src, "--quiet", "--max-steps", "1", NULL);
  if (r.code) fail_msg("the run: exit %d: %s", r.code, r.err);
  char *info[] = {"info", src, NULL};
  run_stdout(&r, 'f', info);
  say("info > /dev/full", &r);
  assert_int_equal(r.code, 3);
  assert_non_null(strstr(r.err, "standard output"));
  assert_non_null(strstr(r.err, "No space left on device"));
  char *series[] = {"info", src, "--series", "0", NULL};
  run_stdout(&r, 'c', series);
  say("info --series 0 >&-", &r);
  assert_int_equal(r.code, 3);
  assert_non_null(strstr(r.err, "standard output"));
  assert_non_null(strstr(r.err, "closed"));
  unlink(ini), rm_run(src);
}

/* --max-steps -1: the value out of range, not "needs a value"; an option
 * after --max-steps is still a missing value. */
static void test_negative_value(void **state) {
  (void)state;
  char ini[128];
  tmp_path(ini, sizeof ini, "neg.ini");
  long_problem(ini);
  result r;
  run(&r, "run", ini, "--max-steps", "-1", NULL);
  say("--max-steps -1", &r);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "--max-steps '-1': not a positive integer"));
  assert_null(strstr(r.err, "needs a value"));
  run(&r, "run", ini, "--max-steps", "--quiet", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "--max-steps needs a value"));
  unlink(ini);
}

/* FILE_last.xmf, written beside FILE.h5 and FILE.xdmf, is an output like
 * them: an existing one is refused without --force and replaced with it. */
static void test_last_xmf(void **state) {
  (void)state;
  char ini[128], out[128], last[128];
  tmp_path(ini, sizeof ini, "lx.ini");
  tmp_path(out, sizeof out, "lx.h5");
  tmp_path(last, sizeof last, "lx_last.xmf");
  long_problem(ini);
  write_file(last, "not vesica's\n");
  result r;
  run(&r, "run", ini, TINY, "--out", out, "--quiet", "--max-steps", "1", NULL);
  say("existing _last.xmf", &r);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "lx_last.xmf"));
  assert_false(exists(out));
  run(&r, "run", ini, TINY, "--out", out, "--quiet", "--max-steps", "1", "--force", NULL);
  assert_int_equal(r.code, 0);
  char text[256];
  slurp(last, text, sizeof text);
  assert_null(strstr(text, "not vesica's")); /* replaced by the run's */
  rm_run(out);
  unlink(last), unlink(ini);
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_cli_guard")) return 1;
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_live_files),
      cmocka_unit_test(test_series_full_disk),
      cmocka_unit_test(test_own_input),
      cmocka_unit_test(test_stdout),
      cmocka_unit_test(test_last_xmf),
      cmocka_unit_test(test_negative_value),
  };
  // clang-format on
  return cmocka_run_group_tests_name("cli_guard", tests, setup_all, teardown_guard);
}
