/* vesica — what the tests of the program share: running build/vesica as a
 * child process and reading what it says and writes (its exit code, stdout,
 * stderr, the HDF5 output). Included by test_cli.c, test_cli_restart.c and
 * test_cli_files.c, each a cmocka program of its own. */
#ifndef VES_CLI_TEST_IMPL_H
#define VES_CLI_TEST_IMPL_H

#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <hdf5.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mount.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "app/io.h"
#include "app/plot.h"

static char vesica[PATH_MAX]; /* the program under test */
static char tmpdir[64];       /* this test's scratch folder */
static rlim_t fsize_limit;    /* > 0: the children's RLIMIT_FSIZE (bytes) */

/* A small out-of-equilibrium vesicle that steps fast (331 nodes, ~0.3 s a
 * step): sphere with a P2 bump at eps = 0.2, coarse band and far field. */
#define TINY                                                                                       \
  "--set", "geometry.epsilon=0.2", "--set", "geometry.box_r=2", "--set", "geometry.box_z=2",       \
      "--set", "geometry.band=2", "--set", "geometry.h_band=0.7", "--set", "geometry.h_far=0.3",   \
      "--set", "shape.mode=2", "--set", "shape.delta=0.15", "--set", "time.dt_initial=5e-3",       \
      "--set", "time.dE_target=0.05"

/* Output of a child: exit code, stdout and stderr (NUL-terminated). */
typedef struct {
  int code;
  char out[16384], err[4096];
} result;

static inline void slurp(const char *path, char *buf, size_t len) {
  FILE *f = fopen(path, "r");
  size_t k = f ? fread(buf, 1, len - 1, f) : 0;
  buf[k] = 0;
  if (f) fclose(f);
}

/* Start vesica with args (NULL-terminated), stdout and stderr to the files
 * tmpdir/<tag>.out and .err; path_env replaces PATH when not NULL. Returns
 * the child's pid. */
static inline pid_t spawn_tag(char *const *args, const char *path_env, const char *tag) {
  char o[128], e[128];
  snprintf(o, sizeof o, "%s/%s.out", tmpdir, tag);
  snprintf(e, sizeof e, "%s/%s.err", tmpdir, tag);
  pid_t pid = fork();
  assert_true(pid >= 0);
  if (pid == 0) {
    int fo = open(o, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    int fe = open(e, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fo < 0 || fe < 0) _exit(127);
    dup2(fo, 1), dup2(fe, 2);
    if (path_env) setenv("PATH", path_env, 1);
    if (fsize_limit > 0) { /* a real failing write (EFBIG), as a full disk's ENOSPC */
      struct rlimit rl = {.rlim_cur = fsize_limit, .rlim_max = RLIM_INFINITY};
      signal(SIGXFSZ, SIG_IGN);
      if (setrlimit(RLIMIT_FSIZE, &rl) != 0) _exit(126);
    }
    char *argv[64];
    int n = 0;
    argv[n++] = vesica;
    for (; args[n - 1] && n < 63; n++) argv[n] = args[n - 1];
    argv[n] = NULL;
    execv(vesica, argv);
    _exit(127);
  }
  return pid;
}

static inline pid_t spawn(char *const *args, const char *path_env) {
  return spawn_tag(args, path_env, "child");
}

/* Wait for pid and read what it wrote under tag. */
static inline void collect_tag(pid_t pid, result *r, const char *tag) {
  int status;
  assert_int_equal(waitpid(pid, &status, 0), pid);
  r->code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  char o[128], e[128];
  snprintf(o, sizeof o, "%s/%s.out", tmpdir, tag);
  snprintf(e, sizeof e, "%s/%s.err", tmpdir, tag);
  slurp(o, r->out, sizeof r->out);
  slurp(e, r->err, sizeof r->err);
  unlink(o), unlink(e);
}

static inline void collect(pid_t pid, result *r) { collect_tag(pid, r, "child"); }

/* Run vesica with the given arguments (a NULL-terminated list). */
static inline void run(result *r, ...) {
  char *args[64];
  int n = 0;
  va_list ap;
  va_start(ap, r);
  while (n < 63 && (args[n] = va_arg(ap, char *))) n++;
  va_end(ap);
  args[n] = NULL;
  collect(spawn(args, NULL), r);
}

static inline char *tmp_path(char *buf, size_t len, const char *name) {
  snprintf(buf, len, "%s/%s", tmpdir, name);
  return buf;
}

static inline void write_file(const char *path, const char *text) {
  FILE *f = fopen(path, "w");
  assert_non_null(f);
  fputs(text, f);
  fclose(f);
}

static inline int exists(const char *path) {
  struct stat sb;
  return stat(path, &sb) == 0;
}

/* Remove path and everything below it (lstat: a link is removed, not
 * followed); what is missing is skipped. */
static inline void rm_tree(const char *path) {
  DIR *d = opendir(path);
  struct dirent *e;
  while (d && (e = readdir(d))) {
    if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
    char p[PATH_MAX];
    if (snprintf(p, sizeof p, "%s/%s", path, e->d_name) >= (int)sizeof p) continue;
    struct stat sb;
    if (lstat(p, &sb) == 0 && S_ISDIR(sb.st_mode))
      rm_tree(p);
    else
      unlink(p);
  }
  if (d) closedir(d);
  if (rmdir(path) != 0) unlink(path);
}

static inline int setup_all(void **state) {
  (void)state;
  snprintf(tmpdir, sizeof tmpdir, "/tmp/vesica_cli_XXXXXX");
  return mkdtemp(tmpdir) ? 0 : -1;
}

static inline int teardown_all(void **state) {
  (void)state;
  DIR *d = opendir(tmpdir);
  struct dirent *e;
  while (d && (e = readdir(d))) {
    char p[PATH_MAX];
    if (e->d_name[0] == '.') continue;
    snprintf(p, sizeof p, "%s/%s", tmpdir, e->d_name);
    unlink(p);
  }
  if (d) closedir(d);
  rmdir(tmpdir);
  return 0;
}

/* The value of "key = " in key-value output, up to the end of its line. */
static inline void value_of(const char *out, const char *key, char *buf, size_t len) {
  const char *p = strstr(out, key);
  snprintf(buf, len, "%.*s", p ? (int)strcspn(p + strlen(key), "\n") : 1,
           p ? p + strlen(key) : "?");
}

/* The stored check values of the problem files (data/check_reference.tsv:
 * file, nodes, energy, area_ratio, volume_ratio, reduced_volume, as vesica
 * check printed them). 0 and the row's values, or -1 when file has no row. */
static inline int stored_check(const char *file, double v[5]) {
  FILE *f = fopen("data/check_reference.tsv", "r");
  if (!f) fail_msg("data/check_reference.tsv: cannot read");
  char line[512], name[256];
  int found = -1;
  while (found < 0 && fgets(line, sizeof line, f))
    if (line[0] != '#' &&
        sscanf(line, "%255s %lf %lf %lf %lf %lf", name, v, v + 1, v + 2, v + 3, v + 4) == 6 &&
        !strcmp(name, file))
      found = 0;
  fclose(f);
  return found;
}

/* One bad problem file (text, or NULL for none) with extra arguments: `run`
 * must exit 2 with every fragment in its message and leave no output. */
static inline void expect_bad_run(const char *text, const char *const *extra, int nextra,
                                  const char *frag1, const char *frag2) {
  char ini[128], out[128], xdmf[128];
  tmp_path(ini, sizeof ini, "bad.ini");
  tmp_path(out, sizeof out, "bad.h5");
  tmp_path(xdmf, sizeof xdmf, "bad.xdmf");
  unlink(out), unlink(xdmf);
  if (text) write_file(ini, text);
  char *args[32];
  int n = 0;
  args[n++] = "run";
  if (text) args[n++] = ini;
  for (int i = 0; i < nextra; i++) args[n++] = (char *)extra[i];
  args[n++] = "--out", args[n++] = out, args[n++] = "--quiet";
  args[n] = NULL;
  result r;
  collect(spawn(args, NULL), &r);
  printf("# bad run -> %d: %s", r.code, r.err);
  if (r.code != 2 || !strstr(r.err, frag1) || (frag2 && !strstr(r.err, frag2)))
    fail_msg("input [%s]: exit %d, message '%s' (want 2 and '%s'%s%s)", text ? text : "(none)",
             r.code, r.err, frag1, frag2 ? ", " : "", frag2 ? frag2 : "");
  assert_false(exists(out)); /* no partial output */
  assert_false(exists(xdmf));
  unlink(ini);
}

/* The value of "key = " in text, NAN when absent. */
static inline double key_value(const char *text, const char *key) {
  char pat[64];
  if (snprintf(pat, sizeof pat, "\n%s = ", key) >= (int)sizeof pat) return NAN;
  const char *p = strstr(text, pat);
  return p ? strtod(p + strlen(pat), NULL) : NAN;
}

/* Series name of a file, rows entries. */
static inline double *series(ves_io *io, const char *name) {
  long R = ves_io_rows(io);
  double *v = malloc((size_t)(R > 0 ? R : 1) * sizeof *v);
  assert_non_null(v);
  assert_int_equal(ves_io_read_series(io, name, v), VES_OK);
  return v;
}

static inline ves_io *open_ro(const char *path) {
  char err[512];
  ves_io *io = NULL;
  if (ves_io_open(path, 0, &io, err, sizeof err) != VES_OK) fail_msg("%s", err);
  return io;
}

/* Rows [0, rows) of t, dt, E, A, V identical, bit for bit. */
static inline void same_series(ves_io *a, ves_io *b, long rows) {
  const char *names[] = {"step", "t", "dt", "E", "A", "V", "lambda_A", "lambda_V"};
  for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
    double *x = series(a, names[i]), *y = series(b, names[i]);
    for (long k = 0; k < rows; k++)
      if (memcmp(x + k, y + k, sizeof *x))
        fail_msg("series %s differs between the runs at row %ld: %.17g against %.17g", names[i], k,
                 x[k], y[k]);
    free(x), free(y);
  }
}

/* The last snapshots of two runs of R steps the same bit for bit: y, x,
 * phi (at the snapshot's own node count: a remeshed run's differs from the
 * header's) and the integrator state. Their resets behind them. */
static inline int same_last_snapshot(ves_io *a, ves_io *b, long R) {
  const int S = ves_io_snapshots(a), n = ves_io_snapshot_nodes(a, S - 1);
  assert_int_equal(ves_io_snapshot_nodes(b, ves_io_snapshots(b) - 1), n);
  double *va = malloc(5 * (size_t)n * sizeof *va), *vb = malloc(5 * (size_t)n * sizeof *vb);
  assert_true(va && vb);
  ves_io_snapinfo sa, sb;
  assert_int_equal(ves_io_read_snapshot_n(a, S - 1, n, va, va + 2 * n, va + 4 * n, &sa), VES_OK);
  assert_int_equal(
      ves_io_read_snapshot_n(b, ves_io_snapshots(b) - 1, n, vb, vb + 2 * n, vb + 4 * n, &sb),
      VES_OK);
  assert_true(sa.state.nstep == R && sb.state.nstep == R);
  assert_int_equal(sa.reconnections, sb.reconnections);
  assert_memory_equal(va, vb, 5 * (size_t)n * sizeof *va); /* y, x, phi bit for bit */
  assert_memory_equal(&sa.state, &sb.state, sizeof sa.state);
  free(va), free(vb);
  return sa.reconnections;
}

/* A run of ini on TINY into full, uninterrupted; the same into part,
 * stopped by --max-steps stop (its status "stopped", stop steps) and
 * continued by --restart to the end. */
static inline void run_split(const char *ini, const char *full, const char *part,
                             const char *stop) {
  result r;
  run(&r, "run", ini, TINY, "--out", full, "--quiet", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  run(&r, "run", ini, TINY, "--out", part, "--quiet", "--max-steps", stop, NULL);
  if (r.code) fail_msg("run to step %s: exit %d: %s", stop, r.code, r.err);
  ves_io *b = open_ro(part);
  assert_string_equal(ves_io_get_info(b)->status, "stopped");
  assert_int_equal(ves_io_rows(b), atol(stop));
  ves_io_close(&b);
  run(&r, "run", "--restart", part, "--quiet", NULL);
  if (r.code) fail_msg("restart: exit %d: %s", r.code, r.err);
}

/* The runs in files full and part the same: as many steps, the series and
 * the last snapshot bit for bit. Their number of steps. */
static inline long same_runs(const char *full, const char *part) {
  ves_io *a = open_ro(full), *b = open_ro(part);
  const long R = ves_io_rows(a);
  assert_int_equal(ves_io_rows(b), R);
  same_series(a, b, R);
  (void)same_last_snapshot(a, b, R);
  ves_io_close(&a), ves_io_close(&b);
  return R;
}

/* Remove a run's file FILE.h5, its FILE.xdmf and FILE_last.xmf. */
static inline void rm_run(const char *h5) {
  char x[PATH_MAX];
  unlink(h5);
  const size_t n = strlen(h5);
  if (n > 3 && !strcmp(h5 + n - 3, ".h5")) {
    snprintf(x, sizeof x, "%.*s.xdmf", (int)(n - 3), h5);
    unlink(x);
    snprintf(x, sizeof x, "%.*s_last.xmf", (int)(n - 3), h5);
    unlink(x);
  }
}

/* Tab-separated fields of a line (without its newline). */
static inline int tsv_fields(const char *line) {
  int n = 1;
  for (const char *c = line; *c && *c != '\n'; c++) n += *c == '\t';
  return n;
}

/* Wait until the run writing path has at least `want` steps (up to 120 s). */
static inline long wait_rows(const char *path, long want) {
  long rows = 0;
  struct timespec nap = {0, 50000000};
  for (int i = 0; i < 2400 && rows < want; i++) {
    nanosleep(&nap, NULL);
    ves_io *io = NULL;
    char err[512];
    if (ves_io_open(path, 0, &io, err, sizeof err) == VES_OK) rows = ves_io_rows(io);
    ves_io_close(&io);
  }
  return rows;
}

static inline double estimate_gb(const char *text, const char *unit) { /* "~X <unit>" in text */
  const char *g = strstr(text, unit);
  assert_non_null(g);
  while (g > text && g[-1] != '~') g--;
  return strtod(g, NULL);
}

/* Run vesica with RLIMIT_FSIZE = limit bytes (SIGXFSZ ignored: the write
 * fails with EFBIG, as on a full disk). */
static inline void run_limited(result *r, rlim_t limit, char *const *args) {
  fsize_limit = limit;
  collect(spawn(args, NULL), r);
  fsize_limit = 0;
}

static inline long file_size(const char *path) {
  struct stat sb;
  return stat(path, &sb) == 0 ? (long)sb.st_size : -1;
}

/* The files in folder d (not . and ..). */
static inline int files_in(const char *d) {
  DIR *dd = opendir(d);
  int n = 0;
  struct dirent *e;
  while (dd && (e = readdir(dd))) n += strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
  if (dd) closedir(dd);
  return n;
}

/* Run the small problem into out until the output cannot grow (the room
 * check before each step, io.h): exit 3 naming the cause (frag), status
 * "failed", the last snapshot at the last step written, every row
 * complete; the file copied elsewhere continues (3 more steps). */
static inline void expect_full(const char *out, const char *frag) {
  char ini[128], copy[128], cmd[640];
  tmp_path(ini, sizeof ini, "full.ini");
  write_file(ini, "[time]\nt_end = 100\nadaptive = 0\ndt_max = 5e-3\n"
                  "[output]\nsnapshot_every = 1\n");
  result r;
  run(&r, "run", ini, TINY, "--out", out, "--quiet", NULL);
  fsize_limit = 0;
  printf("# full -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 3); /* not 139 (SIGSEGV), not 0 */
  assert_non_null(strstr(r.err, frag));
  assert_non_null(strstr(r.err, "--restart"));
  ves_io *io = open_ro(out);
  const long R = ves_io_rows(io);
  const int S = ves_io_snapshots(io);
  ves_io_snapinfo si;
  assert_string_equal(ves_io_get_info(io)->status, "failed");
  assert_int_equal(ves_io_read_snapshot(io, S - 1, NULL, NULL, NULL, &si), VES_OK);
  printf("# the file holds %ld steps, %d snapshots (the last at step %ld)\n", R, S, si.state.nstep);
  assert_true(R >= 1);
  assert_int_equal(si.state.nstep, R); /* the last state saved */
  ves_io_close(&io);
  tmp_path(copy, sizeof copy, "full_copy.h5");
  snprintf(cmd, sizeof cmd, "cp %s %s", out, copy);
  assert_int_equal(system(cmd), 0);
  char max[32];
  snprintf(max, sizeof max, "%ld", R + 3);
  run(&r, "run", "--restart", copy, "--max-steps", max, "--quiet", NULL);
  if (r.code) fail_msg("restart elsewhere: exit %d: %s", r.code, r.err);
  io = open_ro(copy);
  assert_int_equal(ves_io_rows(io), R + 3);
  ves_io_close(&io);
  unlink(ini), rm_run(copy);
}

/* The first `cut` bytes of src as dst: a file whose end was lost. */
static inline void copy_cut(const char *src, const char *dst, long cut) {
  FILE *a = fopen(src, "rb"), *b = fopen(dst, "wb");
  assert_true(a && b);
  char *buf = malloc((size_t)cut + 1);
  assert_non_null(buf);
  assert_int_equal(fread(buf, 1, (size_t)cut, a), (size_t)cut);
  assert_int_equal(fwrite(buf, 1, (size_t)cut, b), (size_t)cut);
  free(buf);
  fclose(a), fclose(b);
}

/* Where the data of snapshot k of file h lie: [lo, hi) over y, x and phi
 * (contiguous datasets, written in that order). */
static inline void snapshot_bytes(hid_t h, int k, long *lo, long *hi) {
  *lo = LONG_MAX, *hi = 0;
  const char *part[] = {"y", "x", "phi"};
  for (int i = 0; i < 3; i++) {
    char name[64];
    snprintf(name, sizeof name, "snapshots/%d/%s", k, part[i]);
    hid_t d = H5Dopen2(h, name, H5P_DEFAULT);
    assert_true(d >= 0);
    const long off = (long)H5Dget_offset(d), end = off + (long)H5Dget_storage_size(d);
    H5Dclose(d);
    if (off < *lo) *lo = off;
    if (end > *hi) *hi = end;
  }
}

/* Run prog with args (NULL-terminated) and its output into r. */
static inline void run_prog(result *r, const char *prog, char *const *args) {
  char o[128], e[128];
  snprintf(o, sizeof o, "%s/prog.out", tmpdir);
  snprintf(e, sizeof e, "%s/prog.err", tmpdir);
  pid_t pid = fork();
  assert_true(pid >= 0);
  if (pid == 0) {
    int fo = open(o, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    int fe = open(e, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fo < 0 || fe < 0) _exit(127);
    dup2(fo, 1), dup2(fe, 2);
    execv(prog, args);
    _exit(127);
  }
  collect_tag(pid, r, "prog");
}

/* BUILD/tests/test_x -> BUILD/vesica into `vesica`; 1 (with a message) when
 * the program is not built. */
static inline int cli_find_vesica(const char *argv0, const char *name) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  if (getenv("TEST_FILTER"))        /* one test by name (a development aid) */
    cmocka_set_test_filter(getenv("TEST_FILTER"));
  char self[PATH_MAX - 16];
  snprintf(self, sizeof self, "%s", argv0);
  char *slash = strrchr(self, '/');
  if (slash)
    *slash = 0;
  else
    snprintf(self, sizeof self, ".");
  snprintf(vesica, sizeof vesica, "%s/../vesica", self);
  if (access(vesica, X_OK)) {
    fprintf(stderr, "%s: %s: not found (build it first)\n", name, vesica);
    return 1;
  }
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
  return 0;
}

#endif
