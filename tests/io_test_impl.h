/* vesica — what the tests of the output module share: a scratch folder, a
 * synthetic file (4 nodes, 2 triangles) and the helpers that write, read,
 * cut and damage output files. Included by test_io.c and test_io_damage.c,
 * each a cmocka program. */
#ifndef VES_IO_TEST_IMPL_H
#define VES_IO_TEST_IMPL_H

#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <hdf5.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <errno.h>
#include <signal.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "app/io.h"
#include "ves/reconnect.h"
#include "ves/setup.h"
#include "app/problem.h"

static char dir[64]; /* scratch folder */

static inline int setup_all(void **state) {
  (void)state;
  snprintf(dir, sizeof dir, "/tmp/vesica_io_XXXXXX");
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
  return mkdtemp(dir) ? 0 : -1;
}

static inline int teardown_all(void **state) {
  (void)state;
  char cmd[128];
  snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
  return system(cmd) == 0 ? 0 : -1;
}

static inline void path_in(char *buf, size_t len, const char *name) {
  snprintf(buf, len, "%s/%s", dir, name);
}

/* A synthetic file: 4 nodes, 2 triangles, default parameters; rows and
 * snapshots are added by the tests. */
typedef struct {
  ves_config cfg;
  char *problem;
  double X[8];
  int tri[6];
  ves_io_header h;
} fake;

static inline void fake_init(fake *f) {
  ves_config_default(&f->cfg);
  snprintf(f->cfg.source, sizeof f->cfg.source, "/somewhere/p.ini");
  assert_int_equal(ves_config_to_text(&f->cfg, &f->problem), VES_OK);
  const double X[8] = {0, -1, 1, -1, 1, 1, 0, 1};
  const int tri[6] = {0, 1, 2, 0, 2, 3};
  memcpy(f->X, X, sizeof X), memcpy(f->tri, tri, sizeof tri);
  f->h = (ves_io_header){.version = "9.9.9",
                         .backend = "newton",
                         .problem = f->problem,
                         .source = "/somewhere/p.ini",
                         .cfg = &f->cfg,
                         .n = 4,
                         .X = f->X,
                         .ntri = 2,
                         .tri = f->tri,
                         .E0 = 7.5,
                         .A0 = 12.5,
                         .V0 = 4.25,
                         .setup_seconds = 1.25};
}

/* Row i of a test series: every column distinct and not round. */
static inline ves_io_row row_of(long i) {
  ves_io_row r = {.step = i + 1,
                  .t = 0.1 * (i + 1) / 3,
                  .dt = 1e-3 * (i + 1) / 7,
                  .E = 7.5 - 0.01 * i / 3,
                  .A = 12.5 * (1 + 1e-13 * i),
                  .V = 4.25 / 3,
                  .V_target = 4.25 / 3 + 1e-14,
                  .lambda_A = -1.0 / 3 - i,
                  .lambda_V = 2.0 / 7 + i,
                  .c0 = 0.5 * i,
                  .iterations = 3 + (int)i,
                  .f_evals = 4 + (int)i,
                  .g_evals = 5 + (int)i,
                  .h_evals = 1,
                  .violation = 1e-15 * (i + 1),
                  .solve_seconds = 0.25 * (i + 1),
                  .wall_seconds = 0.5 * (i + 1),
                  .retries = (int)i % 2,
                  .status = 0,
                  .reconnections = 0,
                  .factorizations = 1 + (int)i % 3};
  return r;
}

static inline ves_io_snapinfo snap_of(long step) {
  ves_io_snapinfo si = {.wall_seconds = 0.5 * step, .reconnections = 0, .rows = step};
  si.state = (ves_sim_state){.t = 0.1 * step / 3,
                             .dt = 1e-3 / 7,
                             .nstep = step,
                             .E = 7.5 / 3,
                             .A = 12.5,
                             .V = 4.25,
                             .E0 = 7.5,
                             .A0 = 12.5,
                             .V0 = 4.25,
                             .lambda = {-1.0 / 3, 2.0 / 7},
                             .c0 = 0.1 * step,
                             .dt_rejected = 2e-3 / 7,
                             .since_rejected = step % 5};
  return si;
}

/* Check the series of io against rows 0..R-1 of row_of. */
static inline void check_rows(ves_io *io, long R) {
  assert_int_equal(ves_io_rows(io), R);
  double v[16];
  const struct {
    const char *name;
    size_t off;
    int is_double, is_long;
  } cols[] = {{"step", offsetof(ves_io_row, step), 0, 1},
              {"t", offsetof(ves_io_row, t), 1, 0},
              {"dt", offsetof(ves_io_row, dt), 1, 0},
              {"E", offsetof(ves_io_row, E), 1, 0},
              {"A", offsetof(ves_io_row, A), 1, 0},
              {"lambda_V", offsetof(ves_io_row, lambda_V), 1, 0},
              {"iterations", offsetof(ves_io_row, iterations), 0, 0},
              {"violation", offsetof(ves_io_row, violation), 1, 0},
              {"retries", offsetof(ves_io_row, retries), 0, 0},
              {"factorizations", offsetof(ves_io_row, factorizations), 0, 0}};
  for (size_t c = 0; c < sizeof cols / sizeof cols[0]; c++) {
    assert_int_equal(ves_io_read_series(io, cols[c].name, v), VES_OK);
    for (long i = 0; i < R; i++) {
      ves_io_row r = row_of(i);
      const char *p = (const char *)&r + cols[c].off;
      double want = cols[c].is_double ? *(const double *)p
                    : cols[c].is_long ? (double)*(const long *)p
                                      : (double)*(const int *)p;
      if (v[i] != want)
        fail_msg("series %s row %ld: %.17g, want %.17g", cols[c].name, i, v[i], want);
    }
  }
}

/* The snapshot index of the file at path: `count` rows, row i naming
 * /snapshots/i with that group's own step and t, bit for bit. */
static inline void check_index(const char *path, int count) {
  typedef struct {
    int32_t k;
    int64_t step;
    double t;
  } row;
  hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
  assert_true(f >= 0);
  hid_t d = H5Dopen2(f, "snapshot_index", H5P_DEFAULT);
  if (d < 0) fail_msg("%s: no /snapshot_index", path);
  hid_t sp = H5Dget_space(d);
  hsize_t n = 0;
  assert_int_equal(H5Sget_simple_extent_ndims(sp), 1);
  H5Sget_simple_extent_dims(sp, &n, NULL);
  if (n != (hsize_t)count)
    fail_msg("%s: %llu index rows, want %d", path, (unsigned long long)n, count);
  hid_t mt = H5Tcreate(H5T_COMPOUND, sizeof(row));
  H5Tinsert(mt, "k", HOFFSET(row, k), H5T_NATIVE_INT32);
  H5Tinsert(mt, "step", HOFFSET(row, step), H5T_NATIVE_INT64);
  H5Tinsert(mt, "t", HOFFSET(row, t), H5T_NATIVE_DOUBLE);
  row r[64];
  assert_true(count <= 64);
  if (count > 0) assert_true(H5Dread(d, mt, H5S_ALL, H5S_ALL, H5P_DEFAULT, r) >= 0);
  for (int i = 0; i < count; i++) {
    char name[32];
    snprintf(name, sizeof name, "snapshots/%d", i);
    hid_t g = H5Gopen2(f, name, H5P_DEFAULT);
    assert_true(g >= 0);
    long step = -1;
    double t = -1;
    hid_t a = H5Aopen(g, "step", H5P_DEFAULT);
    H5Aread(a, H5T_NATIVE_LONG, &step), H5Aclose(a);
    a = H5Aopen(g, "t", H5P_DEFAULT);
    H5Aread(a, H5T_NATIVE_DOUBLE, &t), H5Aclose(a);
    H5Gclose(g);
    if (r[i].k != i || r[i].step != step || r[i].t != t)
      fail_msg("%s: index row %d is (%d, %lld, %.17g), snapshot %d has step %ld t %.17g", path, i,
               (int)r[i].k, (long long)r[i].step, r[i].t, i, step, t);
  }
  H5Tclose(mt), H5Sclose(sp), H5Dclose(d), H5Fclose(f);
}

/* A fake header, and a new file named name in the test folder (path out). */
static inline ves_io *fake_file(fake *f, const char *name, char *path, size_t len) {
  char err[512] = "";
  ves_io *io = NULL;
  fake_init(f);
  path_in(path, len, name);
  if (ves_io_create(path, &f->h, &io, err, sizeof err) != VES_OK) fail_msg("%s", err);
  return io;
}

/* A sphere of radius 1 at eps = 0.2, coarse (331 nodes with a P2 bump, 300
 * without): fast to build. */
static inline ves_setup *tiny_setup(int bump) {
  ves_config cfg;
  char err[512];
  const char *set[] = {"geometry.epsilon=0.2", "geometry.box_r=2",    "geometry.box_z=2",
                       "geometry.band=2",      "geometry.h_band=0.7", "geometry.h_far=0.3",
                       "shape.mode=2",         "shape.delta=0.15"};
  if (ves_config_load(NULL, bump ? 8 : 6, set, &cfg, err, sizeof err) != VES_OK)
    fail_msg("config: %s", err);
  ves_setup *s = NULL;
  if (ves_problem_setup_create(&cfg, VES_PHI0_L2, &s, err, sizeof err) != VES_OK)
    fail_msg("setup: %s", err);
  return s;
}

/* The child of test_write_failure, a fresh process whose first HDF5 call is
 * the io module's (as in vesica): open path writable, limit the size of the
 * files it writes to the current size plus 1 KiB (RLIMIT_FSIZE: a real
 * failing write, EFBIG, as a full disk's ENOSPC), and append rows past the
 * room check until a write fails. Prints what it saw; exits 0 unless it
 * crashes on the way out (HDF5's exit-time cleanup after a failed
 * H5Fclose must not segfault). */
static inline int write_fail_child(const char *path) {
  char err[512] = "";
  ves_io *io = NULL;
  struct stat sb;
  if (ves_io_open(path, 1, &io, err, sizeof err) != VES_OK || stat(path, &sb) != 0) return 10;
  signal(SIGXFSZ, SIG_IGN); /* the write then fails with EFBIG */
  struct rlimit rl = {.rlim_cur = (rlim_t)sb.st_size + 1024, .rlim_max = RLIM_INFINITY};
  if (setrlimit(RLIMIT_FSIZE, &rl) != 0) return 11;
  printf("room: %s\n", ves_io_room(io, 1, 0) == VES_ERR_IO ? ves_io_error(io) : "ok");
  ves_status st = VES_OK;
  for (long i = 0; i < 2000 && st == VES_OK; i++) {
    ves_io_row r = row_of(i);
    st = ves_io_append(io, &r);
  }
  printf("append: %s: %s\n", ves_status_str(st), ves_io_error(io) ? ves_io_error(io) : "-");
  fflush(stdout);
  ves_io_close(&io);
  return 0;
}

/* Salvage (io.h) at the library level: rows 0..5 with snapshots at steps
 * 0, 3, 6 (checksums written with them). Copies cut every 2,500 bytes:
 * each salvage either fails with VES_ERR_IO, leaving nothing, or keeps a
 * snapshot K and rows 0..3K - 1 exactly as written (a cut in this small
 * file can land in space HDF5 reused early in the file, hence no order by
 * offset is assumed), and the salvaged file continues. An intact file is
 * not salvaged (VES_ERR_ARG), an existing output not overwritten, and a
 * file whose snapshots carry no checksums (an older writer) is refused. */
/* The whole of file path (malloc'd, taken by the caller; its size in *size). */
static inline char *file_bytes(const char *path, long *size) {
  struct stat sb;
  assert_int_equal(stat(path, &sb), 0);
  FILE *in = fopen(path, "rb");
  char *bytes = malloc((size_t)sb.st_size);
  assert_true(in && bytes && fread(bytes, 1, (size_t)sb.st_size, in) == (size_t)sb.st_size);
  fclose(in);
  *size = (long)sb.st_size;
  return bytes;
}

/* File path made of the first n bytes (a file cut short). */
static inline void write_prefix(const char *path, const char *bytes, long n) {
  FILE *o = fopen(path, "wb");
  assert_true(o && fwrite(bytes, 1, (size_t)n, o) == (size_t)n);
  fclose(o);
}

/* A fake file named name (path out) with nsnap snapshots (y = 0..7) and as
 * many rows; its bytes (malloc'd) returned, their count in *size. */
static inline unsigned char *fake_bytes(const char *name, char *path, size_t len, int nsnap,
                                        long *size) {
  fake f;
  ves_io *io = fake_file(&f, name, path, len);
  double y[8] = {0, 1, 2, 3, 4, 5, 6, 7}, phi[4] = {0};
  for (long i = 0; i < nsnap; i++) {
    ves_io_snapinfo si = snap_of(i);
    assert_int_equal(ves_io_snapshot(io, y, y, phi, &si), VES_OK);
    ves_io_row r = row_of(i);
    assert_int_equal(ves_io_append(io, &r), VES_OK);
  }
  ves_io_close(&io);
  free(f.problem);
  return (unsigned char *)file_bytes(path, size);
}

/* The first size bytes of b as the file path; b freed. */
static inline void put_bytes(const char *path, unsigned char *b, long size) {
  FILE *fp = fopen(path, "wb");
  assert_true(fp && fwrite(b, 1, (size_t)size, fp) == (size_t)size);
  fclose(fp);
  free(b);
}

/* The salvage of path refused (VES_ERR_IO) with `why` in its message, and
 * nothing left at its output. */
static inline void salvage_refused(const char *path, const char *why) {
  char out[192], err[1024] = "";
  snprintf(out, sizeof out, "%s.salvage", path);
  ves_io_salvaged res;
  assert_int_equal(ves_io_salvage(path, out, &res, err, sizeof err), VES_ERR_IO);
  printf("# %s\n", err);
  assert_non_null(strstr(err, path));
  assert_non_null(strstr(err, why));
  assert_int_equal(access(out, F_OK), -1);
}

/* H5Ovisit callback: every group and dataset (the root included) has the
 * string attributes units and description; counts them in *data. */
static inline herr_t described(hid_t obj, const char *name, const H5O_info_t *info, void *data) {
  int *count = data;
  if (info->type != H5O_TYPE_GROUP && info->type != H5O_TYPE_DATASET) return 0;
  for (int i = 0; i < 2; i++) {
    const char *attr = i ? "description" : "units";
    if (H5Aexists_by_name(obj, name, attr, H5P_DEFAULT) <= 0)
      fail_msg("%s: no attribute %s", name, attr);
    hid_t a = H5Aopen_by_name(obj, name, attr, H5P_DEFAULT, H5P_DEFAULT);
    hid_t t = H5Aget_type(a);
    assert_int_equal(H5Tget_class(t), H5T_STRING);
    assert_true(H5Tget_size(t) > 1); /* not empty */
    H5Tclose(t), H5Aclose(a);
  }
  (*count)++;
  return 0;
}

#endif
