/* vesica — tests of what a study takes from outside: names in the Slurm
 * script (`vesica study --emit slurm` with --out folders and study files
 * whose names hold a newline, quotes, a space, $, a backquote, ';', '#',
 * '%', a tab, a backslash, bytes that are not UTF-8: refused with exit 2 and
 * nothing written, or a script that bash parses and that, run as an array
 * task under a PATH of stand-ins recording their arguments, runs exactly
 * the intended command and nothing else); the [slurm] values; the study
 * file read with the problem files' rules (a repeated section or key, two
 * values of an axis that are one value: refused naming the file, the line
 * or section and the key); and the array of a partly or wholly finished
 * study (only the cells without a result; none: no script). Run from the
 * repository root. */
#include <sys/file.h>

#include "cli_test_impl.h"

#include "app/study.h"

/* The tiny problem of cli_test_impl.h as [set] lines. */
static const char TINY_SET[] = "geometry.epsilon = 0.2\ngeometry.box_r = 2\ngeometry.box_z = 2\n"
                               "geometry.band = 2\ngeometry.h_band = 0.7\ngeometry.h_far = 0.3\n"
                               "shape.mode = 2\nshape.delta = 0.15\n";

static char base_ini[PATH_MAX]; /* the base problem (absolute) */

/* Whether a file named `name` lies anywhere under path. */
static int find_name(const char *path, const char *name) {
  DIR *d = opendir(path);
  struct dirent *e;
  int found = 0;
  while (d && !found && (e = readdir(d))) {
    if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
    char p[PATH_MAX];
    snprintf(p, sizeof p, "%s/%s", path, e->d_name);
    struct stat sb;
    found = !strcmp(e->d_name, name) ||
            (lstat(p, &sb) == 0 && S_ISDIR(sb.st_mode) && find_name(p, name));
  }
  if (d) closedir(d);
  return found;
}

static int input_setup(void **state) {
  (void)state;
  snprintf(tmpdir, sizeof tmpdir, "/tmp/vesica_study_input_XXXXXX");
  if (!mkdtemp(tmpdir)) return -1;
  write_file(tmp_path(base_ini, sizeof base_ini, "base.ini"), "[shape]\ntype = sphere\n");
  return 0;
}

static int input_teardown(void **state) {
  (void)state;
  rm_tree(tmpdir);
  return 0;
}

/* A two-cell study (material.c0 = 0, 1; one step) at path, its problem
 * named by absolute path; extra goes first into [study]. */
static void write_study(const char *path, const char *extra) {
  char text[8192];
  snprintf(text, sizeof text,
           "[study]\nproblem = %s\nrun = step\n%s[set]\n%s[axes]\nmaterial.c0 = 0, 1\n", base_ini,
           extra, TINY_SET);
  write_file(path, text);
}

/* Run a program (argv[0] a path) with the environment env (NULL-terminated)
 * in the folder cwd; its exit code. */
static int run_env(char *const *argv, char *const *env, const char *cwd) {
  pid_t pid = fork();
  assert_true(pid >= 0);
  if (pid == 0) {
    int null = open("/dev/null", O_WRONLY);
    if (null >= 0) dup2(null, 1), dup2(null, 2);
    if (cwd && chdir(cwd) != 0) _exit(126);
    execve(argv[0], argv, env);
    _exit(127);
  }
  int status;
  assert_int_equal(waitpid(pid, &status, 0), pid);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

/* The names under test: each as the --out folder and as the study file's
 * folder and name. */
static const char *const NAMES[] = {
    "nl\ntouch INJECTED #",
    "it's",
    "say \"hi\"",
    "a b",
    "$(touch INJECTED)",
    "$HOME",
    "`touch INJECTED`",
    "a;touch INJECTED",
    "#x",
    "50%A",
    "tab\there",
    "back\\slash",
    "\xff\xfe",
    "caf\xc3\xa9",
    "mypackjob",
};
#define NNAMES (sizeof NAMES / sizeof NAMES[0])

/* The script written for study file `study` into folder `out` by the
 * library with a stand-in program (a shell script recording its arguments,
 * NUL-separated, in ARGV_FILE), run as array task 0 by bash in an empty
 * folder under PATH = the stand-ins' folder (vesica and srun recording
 * too), /usr/bin, /bin: the recorded arguments are exactly the intended
 * command, and no file named INJECTED appears anywhere under tmpdir. */
static void dry_run(const char *study, const char *out) {
  char bin[PATH_MAX / 2], stub[PATH_MAX], argv_file[PATH_MAX], cwd[PATH_MAX], err[1024] = "";
  tmp_path(bin, sizeof bin, "bin dir 'q'");
  mkdir(bin, 0777);
  const char *const stubs[] = {"prog", "vesica", "srun"};
  for (int i = 0; i < 3; i++) {
    snprintf(stub, sizeof stub, "%s/%s", bin, stubs[i]);
    write_file(stub, "#!/bin/sh\nprintf '%s\\0' \"$0\" \"$@\" > \"$ARGV_FILE\"\n");
    assert_int_equal(chmod(stub, 0755), 0);
  }
  snprintf(stub, sizeof stub, "%s/prog", bin);
  tmp_path(argv_file, sizeof argv_file, "argv");
  tmp_path(cwd, sizeof cwd, "cwd");
  mkdir(cwd, 0777);
  unlink(argv_file);
  ves_study *s = NULL;
  assert_int_equal(ves_study_load(study, 1000, &s, err, sizeof err), VES_OK);
  long ntasks = 0;
  ves_status st = ves_study_write_sbatch(s, stub, out, 0, &ntasks, err, sizeof err);
  ves_study_destroy(&s);
  if (st == VES_ERR_CONFIG) { /* refused: a one-line reason, nothing written */
    printf("#   refused: %s\n", err);
    assert_null(strchr(err, '\n'));
    struct stat sb;
    assert_true(stat(out, &sb) != 0);
    return;
  }
  assert_int_equal(st, VES_OK);
  assert_int_equal(ntasks, 2);
  char script[PATH_MAX + 16], path_env[PATH_MAX + 32], argv_env[PATH_MAX + 16];
  snprintf(script, sizeof script, "%s/study.sbatch", out);
  char *check[] = {"/bin/bash", "-n", script, NULL};
  char *plain[] = {"PATH=/usr/bin:/bin", NULL};
  assert_int_equal(run_env(check, plain, NULL), 0);
  snprintf(path_env, sizeof path_env, "PATH=%s:/usr/bin:/bin", bin);
  snprintf(argv_env, sizeof argv_env, "ARGV_FILE=%s", argv_file);
  char *task[] = {"/bin/bash", script, NULL};
  char *env[] = {path_env, argv_env, "SLURM_ARRAY_TASK_ID=0", NULL};
  assert_int_equal(run_env(task, env, cwd), 0);
  /* the recorded arguments: the intended ones, byte for byte */
  char got[4 * PATH_MAX], want[4 * PATH_MAX], rs[PATH_MAX], ro[PATH_MAX];
  assert_non_null(realpath(study, rs));
  assert_non_null(realpath(out, ro));
  const char *const args[] = {stub, "study", rs, "--out", ro, "--max-cells", "1000", "--cell", "0"};
  size_t wn = 0;
  for (size_t i = 0; i < sizeof args / sizeof args[0]; i++) {
    memcpy(want + wn, args[i], strlen(args[i]) + 1);
    wn += strlen(args[i]) + 1;
  }
  FILE *f = fopen(argv_file, "rb");
  assert_non_null(f);
  size_t gn = fread(got, 1, sizeof got, f);
  fclose(f);
  assert_int_equal(gn, wn);
  assert_memory_equal(got, want, wn);
  assert_false(find_name(tmpdir, "INJECTED"));
  DIR *d = opendir(cwd); /* nothing made in the task's folder */
  struct dirent *e;
  int n = 0;
  while (d && (e = readdir(d))) n += e->d_name[0] != '.';
  if (d) closedir(d);
  assert_int_equal(n, 0);
  /* every line of the script one of vesica's: comments, options, the two
   * exports and the exec */
  char text[16384];
  slurp(script, text, sizeof text);
  int lines = 0;
  for (const char *c = text; *c; c++) lines += *c == '\n';
  assert_int_equal(lines, 14); /* 4 comments, 7 #SBATCH (time included), 2 exports, exec */
  rm_tree(out);
}

/* The CLI on the name: exit 2 with one line and nothing written, or 0
 * with a script bash parses. */
static void cli_emit(const char *study, const char *out) {
  result r;
  run(&r, "study", study, "--out", out, "--emit", "slurm", NULL);
  printf("#   cli -> %d: %s", r.code, r.code ? r.err : r.out);
  assert_true(r.code == 0 || r.code == 2);
  char script[PATH_MAX + 16];
  snprintf(script, sizeof script, "%s/study.sbatch", out);
  if (r.code == 2) {
    assert_non_null(strstr(r.err, "#SBATCH"));
    assert_int_equal(strchr(r.err, '\n') - r.err, (long)strlen(r.err) - 1);
    assert_false(exists(out));
    return;
  }
  char *check[] = {"/bin/bash", "-n", script, NULL};
  char *plain[] = {"PATH=/usr/bin:/bin", NULL};
  assert_int_equal(run_env(check, plain, NULL), 0);
  char text[16384]; /* vesica's lines only: no name adds one */
  slurp(script, text, sizeof text);
  int lines = 0;
  for (const char *c = text; *c; c++) lines += *c == '\n';
  assert_int_equal(lines, 14);
  rm_tree(out);
}

static void test_slurm_names(void **state) {
  (void)state;
  char study[PATH_MAX], out[PATH_MAX], dir[PATH_MAX];
  tmp_path(study, sizeof study, "s.ini");
  write_study(study, "");
  for (size_t i = 0; i < NNAMES; i++) {
    printf("# name %zu as --out\n", i);
    snprintf(out, sizeof out, "%s/o_%s", tmpdir, NAMES[i]);
    cli_emit(study, out);
    dry_run(study, out);
    printf("# name %zu as the study's folder and file\n", i);
    snprintf(dir, sizeof dir, "%s/d_%s", tmpdir, NAMES[i]);
    assert_int_equal(mkdir(dir, 0777), 0);
    char named[2 * PATH_MAX];
    snprintf(named, sizeof named, "%s/%s.ini", dir, NAMES[i]);
    write_study(named, "");
    tmp_path(out, sizeof out, "o_plain");
    cli_emit(named, out);
    dry_run(named, out);
    rm_tree(dir);
  }
  /* the reported injection: refused, nothing made */
  result r;
  snprintf(out, sizeof out, "%s/o\ntouch INJECTED #", tmpdir);
  run(&r, "study", study, "--out", out, "--emit", "slurm", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "control character"));
  assert_false(exists(out));
  assert_false(find_name(tmpdir, "INJECTED"));
}

/* [slurm] values go into #SBATCH lines: anything but letters, digits and
 * . _ - , is refused when the study file is read, an empty mem too, and a
 * value naming a heterogeneous-job separator at --emit slurm; exit 2 and
 * nothing written. */
static void test_slurm_keys(void **state) {
  (void)state;
  const char *const bad[] = {
      "[slurm]\npartition = \"a b\"\n", "[slurm]\naccount = x$(touch INJECTED)\n",
      "[slurm]\nmem = '4G\"'\n",        "[slurm]\nmem =\n",
      "[slurm]\npartition = a\\b\n",    "[slurm]\naccount = `x`\n",
      "[slurm]\npartition = hetjob\n",  "[slurm]\naccount = packjob1\n",
      "[slurm]\nmem = 4G\nmem = 8G\n",
  };
  char study[PATH_MAX], out[PATH_MAX], text[8192];
  tmp_path(study, sizeof study, "k.ini");
  tmp_path(out, sizeof out, "k_out");
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    snprintf(text, sizeof text,
             "[study]\nproblem = %s\nrun = step\n%s[set]\n%s[axes]\nmaterial.c0 = 0, 1\n", base_ini,
             bad[i], TINY_SET);
    write_file(study, text);
    result r;
    run(&r, "study", study, "--out", out, "--emit", "slurm", NULL);
    printf("# [slurm] %zu -> %d: %s", i, r.code, r.err);
    assert_int_equal(r.code, 2);
    assert_false(exists(out));
  }
  assert_false(find_name(tmpdir, "INJECTED"));
}

/* Study files with the problem files' rules: a repeated section or key
 * (names case-insensitive) and two values of an axis that are one value
 * are refused (exit 2) naming the file, the line or section and the key;
 * distinct values pass. */
static void test_study_duplicates(void **state) {
  (void)state;
  struct {
    const char *text; /* after "[study]\nproblem = BASE\n" */
    const char *want;
  } cases[] = {
      {"[study]\nrun = step\n[axes]\nmaterial.c0 = 0, 1\n",
       "line 3: [study]: duplicate section (first at line 1)"},
      {"run = step\nrun = steps\n[axes]\nmaterial.c0 = 0, 1\n",
       "line 4: [study] run: duplicate key (first at line 3)"},
      {"run = step\nRun = step\n[axes]\nmaterial.c0 = 0, 1\n",
       "line 4: [study] run: duplicate key (first at line 3)"},
      {"[axes]\nmaterial.c0 = 0, 1\n[axes]\nshape.delta = 0.1, 0.2\n",
       "line 5: [axes]: duplicate section (first at line 3)"},
      {"[axes]\nmaterial.c0 = 0, 1\nMaterial.C0 = 2, 3\n",
       "line 5: [axes] material.c0: duplicate key (first at line 4)"},
      {"[set]\nmaterial.k = 1\nmaterial.k = 2\n[axes]\nmaterial.c0 = 0, 1\n",
       "line 5: [set] material.k: duplicate key (first at line 4)"},
      {"[axes]\nmaterial.c0 = 1, 1.0\n",
       "[axes] material.c0: values '1' and '1.0' are the same value"},
      {"[axes]\nmaterial.c0 = 0.5, 2, 5e-1\n",
       "[axes] material.c0: values '0.5' and '5e-1' are the same value"},
      {"[axes]\nsolver.backend = newton, NEWTON\n",
       "[axes] solver.backend: values 'newton' and 'NEWTON' are the same value"},
      {"run = step\n[axes]\ntime.dt_initial = 1e-3, 0.001\n",
       "[axes] time.dt_initial: values '1e-3' and '0.001' are the same value"},
  };
  char study[PATH_MAX], out[PATH_MAX], text[8192];
  tmp_path(study, sizeof study, "dup.ini");
  tmp_path(out, sizeof out, "dup_out");
  for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
    snprintf(text, sizeof text, "[study]\nproblem = %s\n%s", base_ini, cases[i].text);
    write_file(study, text);
    result r;
    run(&r, "study", study, "--out", out, "--emit", "slurm", NULL);
    printf("# duplicate %zu -> %d: %s", i, r.code, r.err);
    assert_int_equal(r.code, 2);
    assert_non_null(strstr(r.err, study));
    assert_non_null(strstr(r.err, cases[i].want));
    assert_false(exists(out));
  }
  /* distinct values (and one value per axis) pass */
  snprintf(text, sizeof text,
           "[study]\nproblem = %s\nrun = step\n[set]\n%s[axes]\nmaterial.c0 = 0.5, 0.25\n"
           "solver.backend = newton\n",
           base_ini, TINY_SET);
  write_file(study, text);
  result r;
  run(&r, "study", study, "--out", out, "--emit", "slurm", NULL);
  assert_int_equal(r.code, 0);
  rm_tree(out);
}

/* Write the .result of cell k of the study at path into out, with the
 * given outcome (as the runner would). */
static void fake_result(const char *path, const char *out, long k, const char *outcome) {
  char err[1024] = "", rp[PATH_MAX + 64], cells[PATH_MAX + 8], ro[PATH_MAX];
  ves_study *s = NULL;
  assert_int_equal(ves_study_load(path, 1000, &s, err, sizeof err), VES_OK);
  assert_non_null(realpath(out, ro));
  snprintf(cells, sizeof cells, "%s/cells", ro);
  mkdir(cells, 0777);
  ves_study_result r;
  memset(&r, 0, sizeof r);
  snprintf(r.outcome, sizeof r.outcome, "%s", outcome);
  assert_int_equal(ves_study_cell_signature(s, k, r.signature, sizeof r.signature), VES_OK);
  ves_study_cell_path(s, k, ro, ".result", rp, sizeof rp);
  assert_int_equal(ves_study_result_write(rp, &r), VES_OK);
  ves_study_destroy(&s);
}

/* --emit slurm leaves out every cell with a result: a finished study gets
 * no script (exit 0, said so), a partial one an array of the others;
 * --retry-failed takes the failed ones back in (and passes it on). */
static void test_slurm_pending(void **state) {
  (void)state;
  char study[PATH_MAX], out[PATH_MAX], script[PATH_MAX + 16], text[8192];
  tmp_path(study, sizeof study, "p.ini");
  tmp_path(out, sizeof out, "p_out");
  write_study(study, "");
  snprintf(script, sizeof script, "%s/study.sbatch", out);
  mkdir(out, 0777);
  fake_result(study, out, 0, "converged");
  fake_result(study, out, 1, "failed");
  result r;
  run(&r, "study", study, "--out", out, "--emit", "slurm", NULL);
  printf("# finished -> %d: %s%s", r.code, r.out, r.err);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "nothing to submit"));
  assert_false(exists(script));
  run(&r, "study", study, "--out", out, "--emit", "slurm", "--retry-failed", NULL);
  assert_int_equal(r.code, 0);
  slurp(script, text, sizeof text);
  assert_non_null(strstr(text, "#SBATCH --array=1\n"));
  assert_non_null(strstr(text, " --retry-failed --cell "));
  unlink(script);
  char rp[PATH_MAX + 64];
  snprintf(rp, sizeof rp, "%s/cells/c0=0.result", out);
  assert_int_equal(unlink(rp), 0);
  run(&r, "study", study, "--out", out, "--emit", "slurm", NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "1 array tasks (of 2 cells)"));
  slurp(script, text, sizeof text);
  assert_non_null(strstr(text, "#SBATCH --array=0\n"));
  assert_null(strstr(text, "--retry-failed"));
  rm_tree(out);
}

/* A local study holds its folder: a second `vesica study` on the folder a
 * running one holds (here this process's flock stands for it) is refused
 * with exit 2 and runs nothing; a study file or a file as --out is refused;
 * once the folder is free the study runs. */
static void test_study_folder_held(void **state) {
  (void)state;
  char study[PATH_MAX], out[PATH_MAX], cells[PATH_MAX + 8];
  tmp_path(study, sizeof study, "h.ini");
  tmp_path(out, sizeof out, "h_out");
  write_study(study, "");
  mkdir(out, 0777);
  int fd = open(out, O_RDONLY | O_DIRECTORY);
  assert_true(fd >= 0);
  assert_int_equal(flock(fd, LOCK_EX | LOCK_NB), 0);
  result r;
  run(&r, "study", study, "--out", out, "--quiet", NULL);
  printf("# held -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "in use by a running vesica study"));
  snprintf(cells, sizeof cells, "%s/cells", out);
  assert_false(exists(cells)); /* nothing run */
  run(&r, "study", study, "--out", study, "--quiet", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "is the study file itself"));
  close(fd);
  run(&r, "study", study, "--out", out, "--quiet", NULL);
  if (r.code != 0) printf("# free -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 0);
  assert_true(exists(cells));
  rm_tree(out);
  unlink(study);
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_study_input")) return 1;
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_slurm_names),
      cmocka_unit_test(test_slurm_keys),
      cmocka_unit_test(test_study_duplicates),
      cmocka_unit_test(test_slurm_pending),
      cmocka_unit_test(test_study_folder_held),
  };
  // clang-format on
  return cmocka_run_group_tests_name("study_input", tests, input_setup, input_teardown);
}
