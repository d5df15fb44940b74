/* vesica — reading verifies what it reads: a snapshot, the series and the
 * stored problem text against their checksums, counted groups against
 * their counts; corruption is refused (exit 2) with the dataset named and
 * the file left as it was, a restart offered the last intact snapshot.
 * Also: the stored problem records the backend a run used. Each file is a
 * copy of one small run, damaged through the HDF5 C API or by patching
 * the bytes of a contiguous dataset at its file offset. */
#include "cli_test_impl.h"

static char base[PATH_MAX]; /* the small run every test copies */
static int nsnap;           /* its snapshots */

/* The whole file at path (malloc'd) and its size. */
static unsigned char *file_bytes(const char *path, long *size) {
  *size = file_size(path);
  assert_true(*size > 0);
  unsigned char *b = malloc((size_t)*size);
  FILE *f = fopen(path, "rb");
  assert_true(b && f);
  assert_int_equal(fread(b, 1, (size_t)*size, f), (size_t)*size);
  fclose(f);
  return b;
}

/* Whether the file at path holds exactly the bytes b[size]. */
static int same_bytes(const char *path, const unsigned char *b, long size) {
  long n;
  unsigned char *now = file_bytes(path, &n);
  const int same = n == size && !memcmp(now, b, (size_t)n);
  free(now);
  return same;
}

static void copy_base(const char *name, char *out, size_t len) {
  tmp_path(out, len, name);
  copy_cut(base, out, file_size(base));
}

/* XOR `mask` into byte `at` of the contiguous dataset `dset` of file path. */
static void flip(const char *path, const char *dset, long at, unsigned char mask) {
  hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
  assert_true(f >= 0);
  hid_t d = H5Dopen2(f, dset, H5P_DEFAULT);
  assert_true(d >= 0);
  const haddr_t off = H5Dget_offset(d);
  H5Dclose(d), H5Fclose(f);
  assert_true(off != HADDR_UNDEF);
  int fd = open(path, O_RDWR);
  assert_true(fd >= 0);
  unsigned char c;
  assert_int_equal(pread(fd, &c, 1, (off_t)off + at), 1);
  c ^= mask;
  assert_int_equal(pwrite(fd, &c, 1, (off_t)off + at), 1);
  close(fd);
}

/* Overwrite the double attribute `name` of object `obj`. */
static void set_attr(const char *path, const char *obj, const char *name, double v) {
  hid_t f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  assert_true(f >= 0);
  hid_t o = H5Oopen(f, obj, H5P_DEFAULT), a = H5Aopen(o, name, H5P_DEFAULT);
  assert_true(o >= 0 && a >= 0);
  assert_true(H5Awrite(a, H5T_NATIVE_DOUBLE, &v) >= 0);
  H5Aclose(a), H5Oclose(o), H5Fclose(f);
}

/* Run vesica on args and check that the file at path is unchanged. */
static void run_unchanged(result *r, const char *path, char *const *args) {
  long size;
  unsigned char *b = file_bytes(path, &size);
  collect(spawn(args, NULL), r);
  assert_true(same_bytes(path, b, size));
  free(b);
}

static void expect(const result *r, int code, const char *frag) {
  if (r->code != code || !strstr(r->err, frag))
    fprintf(stderr, "exit %d, stderr: %s(expected %d and '%s')\n", r->code, r->err, code, frag);
  assert_int_equal(r->code, code);
  assert_non_null(strstr(r->err, frag));
}

/* The run: a few steps, a snapshot after each, with --backend ipopt. */
static int setup(void **state) {
  if (setup_all(state)) return -1;
  char ini[PATH_MAX];
  tmp_path(ini, sizeof ini, "p.ini");
  tmp_path(base, sizeof base, "base.h5");
  write_file(ini, "[output]\nsnapshot_every = 1\n");
  result r;
  run(&r, "run", ini, "--out", base, "--backend", "ipopt", "--max-steps", "3", "--quiet", TINY,
      NULL);
  if (r.code != 0) {
    fprintf(stderr, "the run failed (%d): %s\n", r.code, r.err);
    return -1;
  }
  ves_io *io = open_ro(base);
  nsnap = ves_io_snapshots(io);
  ves_io_close(&io);
  return nsnap >= 3 ? 0 : -1;
}

/* --backend is recorded as --set solver.backend would be: the stored
 * problem and /parameters say ipopt, as the root attribute does. */
static void test_backend_recorded(void **state) {
  (void)state;
  ves_io *io = open_ro(base);
  const ves_io_info *in = ves_io_get_info(io);
  assert_string_equal(in->backend, "ipopt");
  assert_non_null(strstr(in->problem, "backend = \"ipopt\""));
  ves_io_close(&io);
  hid_t f = H5Fopen(base, H5F_ACC_RDONLY, H5P_DEFAULT);
  hid_t g = H5Gopen2(f, "parameters", H5P_DEFAULT);
  char buf[64] = "";
  hid_t a = H5Aopen(g, "solver.backend", H5P_DEFAULT), t = H5Aget_type(a);
  assert_true(H5Aread(a, t, buf) >= 0);
  H5Tclose(t), H5Aclose(a), H5Gclose(g), H5Fclose(f);
  assert_string_equal(buf, "ipopt");
  result r;
  run(&r, "info", base, NULL);
  assert_int_equal(r.code, 0);
  assert_null(strstr(r.out, "= newton"));
}

/* One low bit of the last snapshot's y flipped: the restart refuses (exit
 * 2), names the snapshot, offers the one before, writes nothing; that
 * offer then continues the run. */
static void test_low_bit_flip(void **state) {
  (void)state;
  char p[PATH_MAX], dset[64], from[16];
  copy_base("low.h5", p, sizeof p);
  snprintf(dset, sizeof dset, "snapshots/%d/y", nsnap - 1);
  flip(p, dset, 0, 0x01);
  result r;
  run_unchanged(&r, p, (char *[]){"run", "--restart", p, "--quiet", NULL});
  char want[64];
  snprintf(want, sizeof want, "corrupt: /snapshots/%d:", nsnap - 1);
  expect(&r, 2, want);
  snprintf(want, sizeof want, "--from-snapshot %d", nsnap - 2);
  expect(&r, 2, want);
  /* info and plot read no snapshot data there, or refuse it */
  run_unchanged(&r, p, (char *[]){"plot", p, "--outdir", tmpdir, NULL});
  expect(&r, 2, "corrupt");
  snprintf(from, sizeof from, "%d", nsnap - 2);
  run(&r, "run", "--restart", p, "--from-snapshot", from, "--max-steps", "4", "--quiet", NULL);
  if (r.code) fprintf(stderr, "%s", r.err);
  assert_int_equal(r.code, 0);
  ves_io *io = open_ro(p);
  const int S = ves_io_snapshots(io);
  ves_io_snapinfo si;
  assert_true(S > nsnap - 1); /* 0..nsnap-2 kept, then one a step to step 4 */
  for (int k = 0; k < S; k++) assert_int_equal(ves_io_verify_snapshot(io, k), VES_OK);
  assert_int_equal(ves_io_read_snapshot(io, S - 1, NULL, NULL, NULL, &si), VES_OK);
  assert_int_equal(si.state.nstep, 4);
  ves_io_close(&io);
}

/* A high bit (the exponent of y's first value): corruption, named as such
 * (not "point outside the domain"). */
static void test_high_bit_flip(void **state) {
  (void)state;
  char p[PATH_MAX], dset[64];
  copy_base("high.h5", p, sizeof p);
  snprintf(dset, sizeof dset, "snapshots/%d/y", nsnap - 1);
  flip(p, dset, 7, 0x40);
  result r;
  run_unchanged(&r, p, (char *[]){"run", "--restart", p, "--quiet", NULL});
  expect(&r, 2, "do not match its checksum");
  assert_null(strstr(r.err, "outside the domain"));
}

/* NaN written into /series/E: info, plot and a restart refuse it, naming it. */
static void test_series_nan(void **state) {
  (void)state;
  char p[PATH_MAX];
  copy_base("nan.h5", p, sizeof p);
  hid_t f = H5Fopen(p, H5F_ACC_RDWR, H5P_DEFAULT);
  hid_t d = H5Dopen2(f, "series/E", H5P_DEFAULT), fs = H5Dget_space(d);
  const hsize_t at = 1, one = 1;
  hid_t ms = H5Screate_simple(1, &one, NULL);
  const double nan_ = NAN;
  assert_true(H5Sselect_hyperslab(fs, H5S_SELECT_SET, &at, NULL, &one, NULL) >= 0);
  assert_true(H5Dwrite(d, H5T_NATIVE_DOUBLE, ms, fs, H5P_DEFAULT, &nan_) >= 0);
  H5Sclose(ms), H5Sclose(fs), H5Dclose(d), H5Fclose(f);
  result r;
  run_unchanged(&r, p, (char *[]){"info", p, NULL});
  expect(&r, 2, "/series/E row 1 = nan");
  run_unchanged(&r, p, (char *[]){"run", "--restart", p, "--quiet", NULL});
  expect(&r, 2, "/series/E row 1 = nan");
}

/* The stored problem text edited (dE_target): refused, not obeyed. */
static void test_problem_edited(void **state) {
  (void)state;
  char p[PATH_MAX];
  copy_base("problem.h5", p, sizeof p);
  hid_t f = H5Fopen(p, H5F_ACC_RDWR, H5P_DEFAULT);
  hid_t a = H5Aopen(f, "problem", H5P_DEFAULT), t = H5Aget_type(a);
  const size_t len = H5Tget_size(t);
  char *text = calloc(len + 1, 1);
  assert_true(H5Aread(a, t, text) >= 0);
  char *k = strstr(text, "dE_target = 0.05");
  assert_non_null(k);
  k[strlen("dE_target = 0.0")] = '9'; /* 0.05 -> 0.09, the same length */
  assert_true(H5Awrite(a, t, text) >= 0);
  free(text);
  H5Tclose(t), H5Aclose(a), H5Fclose(f);
  result r;
  run_unchanged(&r, p, (char *[]){"run", "--restart", p, "--quiet", NULL});
  expect(&r, 2, "problem_checksum");
  run_unchanged(&r, p, (char *[]){"info", p, NULL});
  expect(&r, 2, "the stored problem text");
}

/* A file without the problem's checksum (an older layout) still opens;
 * a restart says it reads the text unchecked. */
static void test_no_problem_checksum(void **state) {
  (void)state;
  char p[PATH_MAX];
  copy_base("old.h5", p, sizeof p);
  hid_t f = H5Fopen(p, H5F_ACC_RDWR, H5P_DEFAULT);
  assert_true(H5Adelete(f, "problem_checksum") >= 0);
  H5Fclose(f);
  result r;
  run(&r, "info", p, NULL);
  assert_int_equal(r.code, 0);
  ves_io *io = open_ro(p);
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot(io, nsnap - 1, NULL, NULL, NULL, &si), VES_OK);
  ves_io_close(&io);
  char tend[64], set[80];
  snprintf(tend, sizeof tend, "%.17g", si.state.t);
  snprintf(set, sizeof set, "time.t_end=%s", tend);
  run(&r, "run", "--restart", p, "--set", set, NULL);
  expect(&r, 0, "note: the file stores no checksum of its problem text");
}

/* A /remeshes group that counts 3 members and has none: every reader
 * refuses it (exit 2, named) and none changes the file. */
static void test_fake_remeshes(void **state) {
  (void)state;
  char p[PATH_MAX];
  copy_base("remeshes.h5", p, sizeof p);
  hid_t f = H5Fopen(p, H5F_ACC_RDWR, H5P_DEFAULT);
  hid_t g = H5Gcreate2(f, "remeshes", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  hid_t sp = H5Screate(H5S_SCALAR);
  hid_t a = H5Acreate2(g, "count", H5T_STD_I32LE, sp, H5P_DEFAULT, H5P_DEFAULT);
  const int three = 3;
  assert_true(H5Awrite(a, H5T_NATIVE_INT, &three) >= 0);
  H5Aclose(a), H5Sclose(sp), H5Gclose(g), H5Fclose(f);
  result r;
  run_unchanged(&r, p, (char *[]){"info", p, NULL});
  expect(&r, 2, "/remeshes/0: missing");
  run_unchanged(&r, p, (char *[]){"plot", p, "--outdir", tmpdir, NULL});
  expect(&r, 2, "/remeshes/0: missing");
  run_unchanged(&r, p, (char *[]){"run", "--restart", p, "--quiet", NULL});
  expect(&r, 2, "/remeshes/0: missing");
}

/* t = inf in the last snapshot: named, whatever t_end is asked for. */
static void test_t_inf(void **state) {
  (void)state;
  char p[PATH_MAX], obj[64];
  copy_base("tinf.h5", p, sizeof p);
  snprintf(obj, sizeof obj, "snapshots/%d", nsnap - 1);
  set_attr(p, obj, "t", INFINITY);
  result r;
  run_unchanged(&r, p,
                (char *[]){"run", "--restart", p, "--set", "time.t_end=7.25", "--quiet", NULL});
  expect(&r, 2, "attribute t = inf");
  assert_null(strstr(r.err, "7.25"));
}

/* A snapshot's y written as a string: plot names the reason (exit 2). */
static void test_plot_string_field(void **state) {
  (void)state;
  char p[PATH_MAX];
  copy_base("string.h5", p, sizeof p);
  hid_t f = H5Fopen(p, H5F_ACC_RDWR, H5P_DEFAULT);
  assert_true(H5Ldelete(f, "snapshots/0/phi", H5P_DEFAULT) >= 0);
  hid_t t = H5Tcopy(H5T_C_S1);
  H5Tset_size(t, 8);
  const hsize_t n = 4;
  hid_t sp = H5Screate_simple(1, &n, NULL);
  hid_t d = H5Dcreate2(f, "snapshots/0/phi", t, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  static const char text[33] = "aaaaaaaabbbbbbbbccccccccdddddddd";
  assert_true(H5Dwrite(d, t, H5S_ALL, H5S_ALL, H5P_DEFAULT, text) >= 0);
  H5Dclose(d), H5Sclose(sp), H5Tclose(t), H5Fclose(f);
  result r;
  run_unchanged(&r, p, (char *[]){"plot", p, "--outdir", tmpdir, NULL});
  expect(&r, 2, "/snapshots/0/phi: does not read (missing, or of another size or type)");
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_io_verify")) return 1;
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_backend_recorded),  cmocka_unit_test(test_low_bit_flip),
      cmocka_unit_test(test_high_bit_flip),     cmocka_unit_test(test_series_nan),
      cmocka_unit_test(test_problem_edited),    cmocka_unit_test(test_no_problem_checksum),
      cmocka_unit_test(test_fake_remeshes),     cmocka_unit_test(test_t_inf),
      cmocka_unit_test(test_plot_string_field),
  };
  return cmocka_run_group_tests(tests, setup, teardown_all);
}
