/* vesica — tests of a study's interrupted cells (build/vesica study, run as
 * child processes): a study killed in the middle of a cell (SIGKILL, as a
 * node failure; SIGTERM to the study, or to it and its cell as Slurm does
 * at the end of a job) continues that cell at
 * the next call from its last snapshot with vesica run --restart, and the
 * cell ends in the state of an uninterrupted study bit for bit (restarts
 * are bit for bit: docs/manual.md, "Continuing a run"); so does a cell its
 * time limit stopped, when retried; a cell file that cannot be continued is
 * moved aside, never deleted, and the cell starts over. Run from the
 * repository root. */
#include <sys/file.h>

#include "cli_test_impl.h"

#include "app/study.h"

/* The base problem: TINY's vesicle, 12 constant steps of dt* 5e-3 (about
 * 0.3 s each), a snapshot every 3 steps. */
static const char BASE[] = "[geometry]\nepsilon = 0.2\nbox_r = 2\nbox_z = 2\nband = 2\n"
                           "h_band = 0.7\nh_far = 0.3\n[shape]\nmode = 2\ndelta = 0.15\n"
                           "[time]\ndt_initial = 5e-3\nadaptive = 0\nt_end = 0.06\n"
                           "[output]\nsnapshot_every = 3\n";
static const char STUDY[] = "[study]\nproblem = base.ini\nrun = t_end\n[axes]\nmaterial.c0 = 0\n";

/* Wait until no process holds the HDF5 lock of path (a killed cell is
 * reaped by the kernel shortly after its study). */
static void wait_unlocked(const char *path) {
  for (int i = 0; i < 500; i++) {
    int fd = open(path, O_RDONLY);
    if (fd < 0) return;
    const int held = flock(fd, LOCK_EX | LOCK_NB) != 0;
    close(fd);
    if (!held) return;
    struct timespec nap = {0, 10000000};
    nanosleep(&nap, NULL);
  }
  fail_msg("%s: still held by a process 5 s after its study was killed", path);
}

/* The study file and its base problem in tmpdir; the cell's files under
 * folder dir: h5 (cells/c0=0.h5) and log. */
static void write_study(char *study, size_t len) {
  char base[128];
  write_file(tmp_path(base, sizeof base, "base.ini"), BASE);
  write_file(tmp_path(study, len, "resume.ini"), STUDY);
}

/* The last snapshot's y of an ended cell (malloc'd, *n nodes) and its series
 * (t and E, *rows; step checked to be 1, 2, ... without a gap). */
static double *final_state(const char *h5, int *n, long *rows, double **t, double **E) {
  ves_io *io = open_ro(h5);
  *n = ves_io_get_info(io)->n;
  *rows = ves_io_rows(io);
  double *y = malloc(2 * (size_t)*n * sizeof *y), *step = malloc((size_t)*rows * sizeof *step);
  *t = malloc((size_t)*rows * sizeof **t), *E = malloc((size_t)*rows * sizeof **E);
  assert_true(y && step && *t && *E);
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot(io, ves_io_snapshots(io) - 1, y, NULL, NULL, &si), VES_OK);
  assert_int_equal(ves_io_read_series(io, "step", step), VES_OK);
  assert_int_equal(ves_io_read_series(io, "t", *t), VES_OK);
  assert_int_equal(ves_io_read_series(io, "E", *E), VES_OK);
  for (long i = 0; i < *rows; i++) assert_true(step[i] == (double)(i + 1)); /* one run, no gap */
  assert_int_equal(si.state.nstep, *rows);
  free(step);
  ves_io_close(&io);
  return y;
}

/* The uninterrupted study in folder ref (run once for the tests that
 * compare with it); its cell's .result read into *rr. */
static void reference_cell(const char *study, const char *ref, ves_study_result *rr) {
  char res[PATH_MAX];
  result r;
  snprintf(res, sizeof res, "%s/cells/c0=0.result", ref);
  if (!exists(res)) {
    rm_tree(ref);
    run(&r, "study", study, "--out", ref, "--jobs", "1", "--quiet", NULL);
    if (r.code) fail_msg("study: exit %d: %s", r.code, r.err);
  }
  assert_int_equal(ves_study_result_read(res, rr), VES_OK);
  assert_string_equal(rr->outcome, "converged");
}

/* The final states of two ended cells' files, every row and the last y bit
 * for bit (a restart repeats the trajectory exactly), 12 steps each. */
static void same_final_state(const char *h5a, const char *h5b) {
  int na, nb;
  long ra, rb;
  double *ta, *Ea, *tb, *Eb;
  double *ya = final_state(h5a, &na, &ra, &ta, &Ea), *yb = final_state(h5b, &nb, &rb, &tb, &Eb);
  assert_int_equal(na, nb);
  assert_int_equal(ra, rb);
  assert_int_equal(ra, 12);
  assert_memory_equal(ta, tb, (size_t)ra * sizeof *ta);
  assert_memory_equal(Ea, Eb, (size_t)ra * sizeof *Ea);
  assert_memory_equal(ya, yb, 2 * (size_t)na * sizeof *ya);
  free(ya), free(yb), free(ta), free(tb), free(Ea), free(Eb);
}

/* After a rerun that continued the cell of folder cut: its log says it
 * continued the `how` cell and names `from` (where the restart took up),
 * and its file ends as the uninterrupted one of folder ref; cut removed. */
static void check_continued(const char *cut, const char *ref, const char *how, const char *from) {
  char log[PATH_MAX], h5[PATH_MAX], h5ref[PATH_MAX], text[8192], line[128];
  snprintf(log, sizeof log, "%s/cells/c0=0.log", cut);
  slurp(log, text, sizeof text);
  printf("# the cell's log:\n%s", text);
  snprintf(line, sizeof line, "vesica study: continuing the %s cell from", how);
  assert_non_null(strstr(text, line));
  assert_non_null(strstr(text, from));
  snprintf(h5, sizeof h5, "%s/cells/c0=0.h5", cut);
  snprintf(h5ref, sizeof h5ref, "%s/cells/c0=0.h5", ref);
  same_final_state(h5ref, h5);
  rm_tree(cut);
}

/* A study interrupted by sig in the middle of its cell, then rerun: the
 * cell's log says it continues from a snapshot after step 0, and its file
 * ends as the uninterrupted study's, bit for bit. */
static void interrupted_cell(int sig, int cell_too) {
  char study[128], ref[128], cut[128], h5[PATH_MAX], res[PATH_MAX];
  write_study(study, sizeof study);
  tmp_path(ref, sizeof ref, "ref");
  tmp_path(cut, sizeof cut, sig == SIGKILL ? "killed" : cell_too ? "termed_both" : "termed");
  rm_tree(cut);
  result r;
  ves_study_result rr;
  reference_cell(study, ref, &rr);
  /* the same study, interrupted in its time loop once the cell has written
   * snapshot 2 (step 6 of 12: the XDMF file beside the cell's file is
   * rewritten with every snapshot) */
  char *args[] = {"study", study, "--out", cut, "--jobs", "1", "--quiet", NULL};
  pid_t pid = spawn(args, NULL);
  char xdmf[PATH_MAX], text[8192];
  snprintf(xdmf, sizeof xdmf, "%s/cells/c0=0.xdmf", cut);
  int seen = 0;
  for (int i = 0; i < 6000 && !seen; i++) {
    struct timespec nap = {0, 10000000};
    nanosleep(&nap, NULL);
    slurp(xdmf, text, sizeof text);
    seen = strstr(text, "/snapshots/2/x") != NULL;
  }
  if (!seen) fail_msg("%s: no snapshot 2 within 60 s", xdmf);
  if (cell_too) { /* as Slurm does: the signal to every process of the task, the cell first */
    char children[128], list[256] = "";
    snprintf(children, sizeof children, "/proc/%d/task/%d/children", (int)pid, (int)pid);
    slurp(children, list, sizeof list);
    const int cell = atoi(list);
    assert_true(cell > 0);
    kill(cell, sig);
  }
  kill(pid, sig);
  collect(pid, &r);
  assert_int_equal(r.code, 128 + sig);
  snprintf(h5, sizeof h5, "%s/cells/c0=0.h5", cut);
  snprintf(res, sizeof res, "%s/cells/c0=0.result", cut);
  wait_unlocked(h5);
  assert_false(exists(res)); /* not done: it was running */
  ves_io *io = open_ro(h5);
  const int S = ves_io_snapshots(io);
  const long before = ves_io_rows(io);
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot(io, S - 1, NULL, NULL, NULL, &si), VES_OK);
  ves_io_close(&io);
  printf("# signal %d: the cell had %ld steps, last snapshot %d at step %ld\n", sig, before, S - 1,
         si.state.nstep);
  assert_true(si.state.nstep > 0 && si.state.nstep < 12); /* mid-cell, past step 0 */
  run(&r, "study", study, "--out", cut, "--jobs", "1", NULL);
  if (r.code) fail_msg("rerun: exit %d: %s", r.code, r.err);
  assert_non_null(strstr(r.out, "1 of 1 cells, 1 converged"));
  assert_non_null(strstr(r.err, "cell c0=0: continues from its last snapshot"));
  char want[256];
  snprintf(want, sizeof want, "from snapshot %d (step %ld,", S - 1, si.state.nstep);
  check_continued(cut, ref, "interrupted", want);
}

/* A cell its time limit stops in the middle (half the uninterrupted cell's
 * wall time), then retried with --retry-failed and no limit: continued from
 * the snapshot its SIGTERM saved, not from its problem, and ended as the
 * uninterrupted cell bit for bit. */
static void test_timeout_continued(void **state) {
  (void)state;
  char study[128], ref[128], cut[128], limited[128], text[8192], h5[PATH_MAX], res[PATH_MAX];
  write_study(study, sizeof study);
  tmp_path(ref, sizeof ref, "ref");
  tmp_path(cut, sizeof cut, "timed");
  rm_tree(cut);
  ves_study_result rr;
  reference_cell(study, ref, &rr);
  /* the limit: half the uninterrupted cell's wall time, halved again while
   * the cell still ends its 12 steps within it (the machine's load varies
   * between the runs), raised while it stops the cell before its file
   * exists (in its setup); 8 tries */
  double limit = rr.wall_seconds / 2, factor = 1;
  snprintf(h5, sizeof h5, "%s/cells/c0=0.h5", cut);
  snprintf(res, sizeof res, "%s/cells/c0=0.result", cut);
  ves_study_result tr = {0};
  ves_io_snapinfo si = {0};
  result r;
  write_file(tmp_path(limited, sizeof limited, "limited.ini"), STUDY);
  for (int i = 0; i < 8; i++, limit *= factor) {
    snprintf(text, sizeof text,
             "[study]\nproblem = base.ini\nrun = t_end\ntime_limit = %.3f\n[axes]\nmaterial.c0 = "
             "0\n",
             limit);
    write_file(limited, text);
    rm_tree(cut);
    run(&r, "study", limited, "--out", cut, "--jobs", "1", "--quiet", NULL);
    if (r.code) fail_msg("study with time_limit %.3f s: exit %d: %s", limit, r.code, r.err);
    assert_int_equal(ves_study_result_read(res, &tr), VES_OK);
    factor = 0.5; /* it ended its steps */
    if (strcmp(tr.outcome, "timeout")) continue;
    if (!exists(h5)) {
      factor = 1.5;
      continue;
    }
    ves_io *io = open_ro(h5);
    assert_int_equal(ves_io_read_snapshot(io, ves_io_snapshots(io) - 1, NULL, NULL, NULL, &si),
                     VES_OK);
    ves_io_close(&io);
    if (si.state.nstep < 12) break;
  }
  if (strcmp(tr.outcome, "timeout") || !exists(h5) || si.state.nstep >= 12)
    fail_msg("no time_limit stopped the cell mid-run (the last %.3f s: %s)", limit, tr.outcome);
  printf("# time_limit %.3f s: the cell stopped with its last snapshot at step %ld\n", limit,
         si.state.nstep);
  /* the limit raised: the cell is the same cell (the limit is not in its command) */
  write_file(limited, STUDY);
  run(&r, "study", limited, "--out", cut, "--jobs", "1", "--retry-failed", NULL);
  if (r.code) fail_msg("retry: exit %d: %s", r.code, r.err);
  assert_non_null(strstr(r.out, "1 of 1 cells, 1 converged"));
  assert_non_null(strstr(r.err, "cell c0=0: continues from its last snapshot"));
  char want[128];
  snprintf(want, sizeof want, "(step %ld,", si.state.nstep);
  check_continued(cut, ref, "timed-out", want);
}

/* SIGKILL: the study and its cell die at once (the cell by its parent-death
 * signal); the cell continues from its last regular snapshot. */
static void test_resume_after_sigkill(void **state) {
  (void)state;
  interrupted_cell(SIGKILL, 0);
}

/* SIGTERM (what Slurm sends at a job's end or scancel): the study stops its
 * cell, which saves a snapshot after its current step; the cell continues
 * from that one. */
static void test_resume_after_sigterm(void **state) {
  (void)state;
  interrupted_cell(SIGTERM, 0);
}

/* SIGTERM to the cell and the study at once (Slurm's end of a task: every
 * process of it): the study's own SIGTERM may reach the cell as its second
 * signal, which ends it at once without a stop snapshot; either way the
 * cell continues from the last snapshot in its file. */
static void test_resume_after_sigterm_to_all(void **state) {
  (void)state;
  interrupted_cell(SIGTERM, 1);
}

/* An interrupted cell whose file cannot be continued (not an HDF5 file):
 * moved aside as NAME.h5.unusable with its bytes, a line in the cell's log,
 * and the cell run from its problem. */
static void test_unusable_file_moved_aside(void **state) {
  (void)state;
  char study[128], dir[128], h5[PATH_MAX], res[PATH_MAX], aside[PATH_MAX], log[PATH_MAX];
  write_study(study, sizeof study);
  tmp_path(dir, sizeof dir, "broken");
  rm_tree(dir);
  result r;
  run(&r, "study", study, "--out", dir, "--jobs", "1", "--quiet", NULL);
  if (r.code) fail_msg("study: exit %d: %s", r.code, r.err);
  snprintf(h5, sizeof h5, "%s/cells/c0=0.h5", dir);
  snprintf(res, sizeof res, "%s/cells/c0=0.result", dir);
  snprintf(aside, sizeof aside, "%s/cells/c0=0.h5.unusable", dir);
  snprintf(log, sizeof log, "%s/cells/c0=0.log", dir);
  unlink(res); /* as if killed: no result, its file overwritten by garbage */
  write_file(h5, "not an HDF5 file\n");
  run(&r, "study", study, "--out", dir, "--jobs", "1", NULL);
  if (r.code) fail_msg("rerun: exit %d: %s", r.code, r.err);
  printf("# %s", r.err);
  assert_non_null(strstr(r.err, "c0=0.h5 cannot be continued"));
  assert_non_null(strstr(r.out, "1 of 1 cells, 1 converged"));
  char text[8192];
  slurp(aside, text, sizeof text);
  assert_string_equal(text, "not an HDF5 file\n"); /* kept, not deleted */
  slurp(log, text, sizeof text);
  printf("# the cell's log:\n%s", text);
  assert_non_null(strstr(text, "cannot be continued"));
  assert_non_null(strstr(text, "moved to"));
  ves_io *io = open_ro(h5);
  assert_int_equal(ves_io_rows(io), 12); /* run again from its problem */
  ves_io_close(&io);
  /* an interrupted file started by another command (the study file changed
   * since): kept aside as well, never deleted */
  char cmd[PATH_MAX], aside1[PATH_MAX + 8];
  snprintf(cmd, sizeof cmd, "%s/cells/c0=0.cmd", dir);
  snprintf(aside1, sizeof aside1, "%s.1", aside);
  unlink(res);
  write_file(cmd, "run /elsewhere/other.ini\n");
  run(&r, "study", study, "--out", dir, "--jobs", "1", NULL);
  if (r.code) fail_msg("rerun: exit %d: %s", r.code, r.err);
  printf("# %s", r.err);
  assert_non_null(strstr(r.err, "started with another command"));
  assert_true(exists(aside1));
  assert_non_null(strstr(r.out, "1 of 1 cells, 1 converged"));
  rm_tree(dir);
}

/* The shared reference folder, then the scratch folder's files. */
static int teardown_resume(void **state) {
  char ref[128];
  rm_tree(tmp_path(ref, sizeof ref, "ref"));
  return teardown_all(state);
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_study_resume")) return 1;
  if (getenv("TEST_FILTER")) cmocka_set_test_filter(getenv("TEST_FILTER"));
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_resume_after_sigkill),
      cmocka_unit_test(test_resume_after_sigterm),
      cmocka_unit_test(test_resume_after_sigterm_to_all),
      cmocka_unit_test(test_unusable_file_moved_aside),
      cmocka_unit_test(test_timeout_continued),
  };
  return cmocka_run_group_tests_name("study_resume", tests, setup_all, teardown_resume);
}
