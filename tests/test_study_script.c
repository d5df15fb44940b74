/* vesica — tests of a study as a user scripts it (build/vesica study, run as
 * child processes): --set on the command line (applied to every cell,
 * recorded in the folder, a different one refused), a folder whose cells
 * have names of the key-value_ scheme refused, --emit slurm on a finished
 * study (no script) with a throttle and a set-up line, a problem that
 * fails vesica check's geometric checks refused up front or per cell, and
 * the figures of a sweep of any key. Run from the repository root. */
#include "cli_test_impl.h"

#include "app/study.h"

/* TINY's vesicle (tests/cli_test_impl.h), one step of dt* 5e-3 a cell. */
static const char BASE[] = "[geometry]\nepsilon = 0.2\nbox_r = 2\nbox_z = 2\nband = 2\n"
                           "h_band = 0.7\nh_far = 0.3\n[shape]\nmode = 2\ndelta = 0.15\n"
                           "[time]\ndt_initial = 5e-3\ndE_target = 0.05\n";

/* The study file name (its text) beside the base problem, in tmpdir. */
static void write_study(char *path, size_t len, const char *name, const char *text) {
  char base[128];
  write_file(tmp_path(base, sizeof base, "base.ini"), BASE);
  write_file(tmp_path(path, len, name), text);
}

/* --set applies to every cell (in its command), is recorded in
 * DIR/study.set; a rerun with the same --set finds the cells done, one with
 * another --set (or none) is refused with exit 2 naming both; so is
 * --collect. A --set of an axis key, of an unknown key or with a bad value
 * is bad input. */
static void test_set_identity(void **state) {
  (void)state;
  char study[128], dir[128], path[PATH_MAX], text[4096];
  write_study(study, sizeof study, "set.ini",
              "[study]\nproblem = base.ini\nrun = step\n[axes]\nmaterial.c0 = 0\n");
  tmp_path(dir, sizeof dir, "set");
  rm_tree(dir);
  result r;
  run(&r, "study", study, "--out", dir, "--set", "solver.max_iter=50", "--quiet", NULL);
  if (r.code) fail_msg("study: exit %d: %s", r.code, r.err);
  assert_non_null(strstr(r.out, "1 of 1 cells, 1 converged"));
  /* a sweep of C0 (no dt axis) has its figure */
  assert_non_null(strstr(r.out, "/study_sweep.png\n"));
  snprintf(path, sizeof path, "%s/study_sweep.png", dir);
  slurp(path, text, 8);
  assert_memory_equal(text, "\x89PNG\r\n\x1a", 7);
  snprintf(path, sizeof path, "%s/study.set", dir);
  slurp(path, text, sizeof text);
  assert_non_null(strstr(text, "\nsolver.max_iter=50\n"));
  snprintf(path, sizeof path, "%s/cells/c0=0.result", dir);
  ves_study_result res;
  assert_int_equal(ves_study_result_read(path, &res), VES_OK);
  assert_non_null(strstr(res.signature, "--set solver.max_iter=50"));
  /* the same --set: done, nothing run (the .result is the same file) */
  struct stat before, after;
  assert_int_equal(stat(path, &before), 0);
  run(&r, "study", study, "--out", dir, "--set", "solver.max_iter=50", NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.err, "1/1 cells done (1 before)"));
  assert_int_equal(stat(path, &after), 0);
  assert_true(before.st_ino == after.st_ino && before.st_mtime == after.st_mtime);
  /* another --set, none, or --collect with another: refused, nothing run */
  run(&r, "study", study, "--out", dir, "--set", "solver.max_iter=60", NULL);
  printf("# %s", r.err);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "made with --set solver.max_iter=50"));
  assert_non_null(strstr(r.err, "this call gives --set solver.max_iter=60"));
  run(&r, "study", study, "--out", dir, NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "this call gives no --set"));
  run(&r, "study", study, "--out", dir, "--collect", NULL);
  assert_int_equal(r.code, 2);
  assert_int_equal(stat(path, &after), 0);
  assert_true(before.st_ino == after.st_ino && before.st_mtime == after.st_mtime);
  /* bad --set values: exit 2 before anything */
  const char *bad[][2] = {{"material.c0=1", "is an axis"},
                          {"material.cc=1", "material.cc: unknown key"},
                          {"solver.max_iter=-4", "max_iter"},
                          {"solver.max_iter", "expected section.key=value"}};
  for (int i = 0; i < 4; i++) {
    char other[128];
    tmp_path(other, sizeof other, "set_bad");
    run(&r, "study", study, "--out", other, "--set", bad[i][0], NULL);
    printf("# --set %s: %s", bad[i][0], r.err);
    assert_int_equal(r.code, 2);
    assert_non_null(strstr(r.err, bad[i][1]));
    assert_false(exists(other));
  }
  rm_tree(dir);
}

/* A folder whose cells carry names of the key-value_key-value scheme is
 * refused (exit 2, the file and the name this vesica gives it), not run
 * again under other names. */
static void test_dashed_names_refused(void **state) {
  (void)state;
  char study[128], dir[128], path[PATH_MAX];
  write_study(study, sizeof study, "dash.ini",
              "[study]\nproblem = base.ini\nrun = step\n[axes]\nsolver.backend = newton\n"
              "time.dt_initial = 5e-3\n");
  tmp_path(dir, sizeof dir, "dash");
  rm_tree(dir);
  snprintf(path, sizeof path, "%s/cells", dir);
  assert_int_equal(mkdir(dir, 0755), 0);
  assert_int_equal(mkdir(path, 0755), 0);
  snprintf(path, sizeof path, "%s/cells/backend-newton_dt_initial-5e-3.result", dir);
  write_file(path, "outcome = converged\n");
  result r;
  run(&r, "study", study, "--out", dir, NULL);
  printf("# %s", r.err);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "backend-newton_dt_initial-5e-3.result"));
  assert_non_null(strstr(r.err, "backend=newton,dt_initial=5e-3"));
  snprintf(path, sizeof path, "%s/cells/backend=newton,dt_initial=5e-3.log", dir);
  assert_false(exists(path)); /* nothing run */
  rm_tree(dir);
}

/* --emit slurm: --throttle N (over [slurm] throttle) gives --array=...%N,
 * [slurm] setup goes verbatim before the command; on a finished study it
 * writes no script, removes one an earlier emit wrote, says so and exits 0. */
static void test_emit(void **state) {
  (void)state;
  char study[128], dir[128], sb[PATH_MAX], text[8192];
  write_study(study, sizeof study, "emit.ini",
              "[study]\nproblem = base.ini\nrun = step\n[slurm]\nthrottle = 4\n"
              "setup = \"module load hdf5; echo ready\"\n[axes]\nmaterial.c0 = 0, 0.5\n");
  tmp_path(dir, sizeof dir, "emit");
  rm_tree(dir);
  snprintf(sb, sizeof sb, "%s/study.sbatch", dir);
  result r;
  run(&r, "study", study, "--out", dir, "--emit", "slurm", NULL);
  assert_int_equal(r.code, 0);
  slurp(sb, text, sizeof text);
  assert_non_null(strstr(text, "\n#SBATCH --array=0-1%4\n"));
  char *setup = strstr(text, "\nmodule load hdf5; echo ready\n"), *ex = strstr(text, "\nexec ");
  assert_true(setup && ex && setup < ex);
  run(&r, "study", study, "--out", dir, "--emit", "slurm", "--throttle", "1", NULL);
  assert_int_equal(r.code, 0);
  slurp(sb, text, sizeof text);
  assert_non_null(strstr(text, "\n#SBATCH --array=0-1%1\n"));
  run(&r, "study", study, "--out", dir, "--throttle", "1", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "--throttle goes with --emit slurm"));
  run(&r, "study", study, "--out", dir, "--quiet", NULL); /* the cells, locally */
  if (r.code) fail_msg("study: exit %d: %s", r.code, r.err);
  assert_true(exists(sb)); /* the earlier script */
  run(&r, "study", study, "--out", dir, "--emit", "slurm", NULL);
  printf("# %s", r.out);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "nothing to submit, no script written"));
  assert_false(exists(sb));
  rm_tree(dir);
}

/* A problem that fails vesica check's geometric checks: refused up front
 * (exit 2, check's message, no folder) when no axis changes the geometry;
 * with a geometry axis, the failing cells are recorded bad_input with the
 * message and no process, the others run. */
static void test_check_refused(void **state) {
  (void)state;
  char study[128], dir[128], path[PATH_MAX], base[128];
  /* an oblate spheroid of v 0.7 in a wider box: band*eps 0.2 passes, 0.6
   * exceeds the rim's radius of curvature (the band layers fold) */
  write_file(tmp_path(base, sizeof base, "spheroid.ini"),
             "[geometry]\nepsilon = 0.2\nbox_r = 3\nbox_z = 3\nband = 1\nh_band = 0.7\n"
             "h_far = 0.3\n[shape]\ntype = spheroid\nreduced_volume = 0.7\n"
             "[time]\ndt_initial = 5e-3\n");
  write_study(study, sizeof study, "wide.ini",
              "[study]\nproblem = spheroid.ini\nrun = step\n[set]\ngeometry.band = 3\n"
              "[axes]\nmaterial.c0 = 0, 1\n");
  tmp_path(dir, sizeof dir, "wide");
  rm_tree(dir);
  result r, c;
  run(&c, "check", base, "--set", "geometry.band=3", NULL);
  assert_int_equal(c.code, 2);
  char why[512];
  assert_non_null(strstr(c.err, "band layers: "));
  snprintf(why, sizeof why, "%.*s", (int)strcspn(strstr(c.err, "band layers: "), "\n"),
           strstr(c.err, "band layers: "));
  run(&r, "study", study, "--out", dir, NULL);
  printf("# %s", r.err);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, why)); /* check's own message */
  assert_false(exists(dir));
  /* per cell: band 1 runs, band 3 is recorded without a process */
  write_study(study, sizeof study, "band.ini",
              "[study]\nproblem = spheroid.ini\nrun = step\n[axes]\ngeometry.band = 1, 3\n");
  tmp_path(dir, sizeof dir, "band");
  rm_tree(dir);
  run(&r, "study", study, "--out", dir, "--jobs", "1", NULL);
  if (r.code) fail_msg("study: exit %d: %s", r.code, r.err);
  printf("# %s", r.err);
  assert_non_null(strstr(r.out, "2 of 2 cells"));
  snprintf(path, sizeof path, "%s/cells/band=1.log", dir);
  assert_true(exists(path)); /* band 1 ran (whatever its outcome) */
  snprintf(path, sizeof path, "%s/cells/band=3.result", dir);
  ves_study_result res;
  assert_int_equal(ves_study_result_read(path, &res), VES_OK);
  assert_string_equal(res.outcome, "bad_input");
  assert_int_equal(res.exit_code, 2);
  assert_non_null(strstr(res.reason, "exceeds a radius of curvature"));
  snprintf(path, sizeof path, "%s/cells/band=3.log", dir);
  assert_false(exists(path)); /* no process ran */
  rm_tree(dir);
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_study_script")) return 1;
  if (getenv("TEST_FILTER")) cmocka_set_test_filter(getenv("TEST_FILTER"));
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_set_identity),
      cmocka_unit_test(test_dashed_names_refused),
      cmocka_unit_test(test_emit),
      cmocka_unit_test(test_check_refused),
  };
  return cmocka_run_group_tests_name("study_script", tests, setup_all, teardown_all);
}
