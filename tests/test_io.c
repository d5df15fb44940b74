/* vesica — tests of the output module: the HDF5 layout written and read back
 * bit for bit, truncation and continuation, a file left by a writer killed
 * in the middle of an append or a snapshot, every refusal of a foreign file,
 * phi at the nodes against the exact profile, and the restart chain at the
 * library level (state -> snapshot -> file -> state -> the same steps). */
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

static int setup_all(void **state) {
  (void)state;
  snprintf(dir, sizeof dir, "/tmp/vesica_io_XXXXXX");
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
  return mkdtemp(dir) ? 0 : -1;
}

static int teardown_all(void **state) {
  (void)state;
  char cmd[128];
  snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
  return system(cmd) == 0 ? 0 : -1;
}

static void path_in(char *buf, size_t len, const char *name) {
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

static void fake_init(fake *f) {
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
static ves_io_row row_of(long i) {
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

static ves_io_snapinfo snap_of(long step) {
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
static void check_rows(ves_io *io, long R) {
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

/* A fake header, and a new file named name in the test folder (path out). */
static ves_io *fake_file(fake *f, const char *name, char *path, size_t len) {
  char err[512] = "";
  ves_io *io = NULL;
  fake_init(f);
  path_in(path, len, name);
  if (ves_io_create(path, &f->h, &io, err, sizeof err) != VES_OK) fail_msg("%s", err);
  return io;
}

static void test_roundtrip(void **state) {
  (void)state;
  fake f;
  char path[128], err[512] = "";
  ves_io *io = fake_file(&f, "rt.h5", path, sizeof path);
  double y[8], x[8], phi[4] = {1, 0.5, -0.25, -1};
  for (long i = 0; i < 3; i++) {
    ves_io_row r = row_of(i);
    assert_int_equal(ves_io_append(io, &r), VES_OK);
  }
  for (int k = 0; k < 2; k++) {
    for (int j = 0; j < 8; j++) y[j] = f.X[j] * (1 + 0.125 * k) + 1.0 / 3, x[j] = y[j] - 0.0625;
    ves_io_snapinfo si = snap_of(k * 3);
    assert_int_equal(ves_io_snapshot(io, y, x, phi, &si), VES_OK);
  }
  assert_int_equal(ves_io_set_status(io, "finished"), VES_OK);
  ves_io_close(&io);
  assert_null(io);

  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  const ves_io_info *in = ves_io_get_info(io);
  assert_int_equal(in->format_version, VES_IO_FORMAT);
  assert_string_equal(in->version, "9.9.9");
  assert_string_equal(in->backend, "newton");
  assert_string_equal(in->status, "finished");
  assert_string_equal(in->problem, f.problem);
  assert_string_equal(in->source, "/somewhere/p.ini");
  assert_int_equal(in->n, 4);
  assert_int_equal(in->ntri, 2);
  assert_true(in->E0 == 7.5 && in->A0 == 12.5 && in->V0 == 4.25 && in->setup_seconds == 1.25);
  check_rows(io, 3);
  assert_int_equal(ves_io_snapshots(io), 2);
  double y2[8], x2[8], phi2[4], X2[8];
  int tri2[6];
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot(io, 1, y2, x2, phi2, &si), VES_OK);
  assert_memory_equal(y, y2, sizeof y);
  assert_memory_equal(x, x2, sizeof x);
  assert_memory_equal(phi, phi2, sizeof phi);
  ves_io_snapinfo want = snap_of(3);
  assert_memory_equal(&want.state, &si.state, sizeof si.state); /* every field, bit for bit */
  assert_true(si.wall_seconds == want.wall_seconds && si.rows == 3 && si.reconnections == 0);
  assert_int_equal(ves_io_read_mesh(io, X2, tri2), VES_OK);
  assert_memory_equal(f.X, X2, sizeof X2);
  assert_memory_equal(f.tri, tri2, sizeof tri2);
  /* the stored problem text gives back the identical configuration */
  ves_config back;
  assert_int_equal(ves_config_load_text(in->problem, in->source, &back, err, sizeof err), VES_OK);
  for (int i = 0; i < ves_config_count(); i++) {
    ves_config_entry a, b;
    ves_config_entry_get(&f.cfg, i, &a);
    ves_config_entry_get(&back, i, &b);
    assert_true(a.real == b.real && a.integer == b.integer);
    if (a.text) assert_string_equal(a.text, b.text);
  }
  /* misuse */
  assert_int_equal(ves_io_read_series(io, "nope", y2), VES_ERR_ARG);
  assert_int_equal(ves_io_read_snapshot(io, 2, y2, NULL, NULL, NULL), VES_ERR_ARG);
  ves_io_row r = row_of(0);
  assert_int_equal(ves_io_append(io, &r), VES_ERR_ARG); /* read-only */
  ves_io_close(&io);

  /* typed parameters, read with plain HDF5 */
  hid_t h = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
  assert_true(h >= 0);
  hid_t g = H5Gopen2(h, "parameters", H5P_DEFAULT);
  double eps = 0;
  int every = 0;
  hid_t a = H5Aopen(g, "geometry.epsilon", H5P_DEFAULT);
  assert_true(H5Aread(a, H5T_NATIVE_DOUBLE, &eps) >= 0 && eps == f.cfg.epsilon);
  hid_t t = H5Aget_type(a);
  assert_int_equal(H5Tget_class(t), H5T_FLOAT);
  H5Tclose(t), H5Aclose(a);
  a = H5Aopen(g, "output.snapshot_every", H5P_DEFAULT);
  t = H5Aget_type(a);
  assert_int_equal(H5Tget_class(t), H5T_INTEGER);
  assert_true(H5Aread(a, H5T_NATIVE_INT, &every) >= 0 && every == f.cfg.snapshot_every);
  H5Tclose(t), H5Aclose(a);
  a = H5Aopen(g, "solver.backend", H5P_DEFAULT);
  t = H5Aget_type(a);
  assert_int_equal(H5Tget_class(t), H5T_STRING);
  H5Tclose(t), H5Aclose(a);
  H5Gclose(g), H5Fclose(h);

  /* the XDMF file beside it: both collections, every snapshot */
  char xpath[160], text[16384];
  ves_io_xdmf_path(path, xpath, sizeof xpath);
  assert_string_equal(xpath + strlen(xpath) - 8, "/rt.xdmf");
  FILE *xf = fopen(xpath, "r");
  assert_non_null(xf);
  size_t len = fread(text, 1, sizeof text - 1, xf);
  text[len] = 0;
  fclose(xf);
  assert_non_null(strstr(text, "CollectionType=\"Temporal\""));
  assert_non_null(strstr(text, "rt.h5:/snapshots/1/x")); /* the material, not y^a */
  assert_null(strstr(text, "/snapshots/1/y"));
  assert_non_null(strstr(text, "rt.h5:/snapshots/1/phi"));
  assert_non_null(strstr(text, "rt.h5:/mesh/triangles"));
  assert_non_null(strstr(text, "TopologyType=\"Polyvertex\""));
  assert_null(strstr(text, "/snapshots/2/"));
  /* four time stamps (two collections, two snapshots), exact in %.17g */
  const char *p = text;
  double times[4];
  int nt = 0;
  while (nt < 4 && (p = strstr(p, "<Time Value=\""))) times[nt++] = strtod(p += 13, NULL);
  assert_int_equal(nt, 4);
  assert_null(strstr(p, "<Time Value=\"")); /* and no more */
  assert_true(times[0] == 0.0 && times[1] == snap_of(3).state.t && times[3] == times[1]);
  free(f.problem);
}

/* Reopened for writing: rows dropped after a snapshot, appends and
 * snapshots continue the numbering. */
static void test_truncate_continue(void **state) {
  (void)state;
  fake f;
  char path[128], err[512] = "";
  ves_io *io = fake_file(&f, "tc.h5", path, sizeof path);
  double y[8] = {0}, phi[4] = {0};
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s0), VES_OK);
  for (long i = 0; i < 5; i++) {
    ves_io_row r = row_of(i);
    assert_int_equal(ves_io_append(io, &r), VES_OK);
  }
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_OK);
  check_rows(io, 5);
  assert_int_equal(ves_io_truncate(io, 2), VES_OK);
  check_rows(io, 2);
  assert_int_equal(ves_io_truncate(io, 3), VES_ERR_ARG); /* cannot grow */
  ves_io_row r = row_of(2);
  assert_int_equal(ves_io_append(io, &r), VES_OK);
  ves_io_snapinfo s3 = snap_of(3);
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s3), VES_OK);
  assert_int_equal(ves_io_snapshots(io), 2);
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  check_rows(io, 3);
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot(io, 1, NULL, NULL, NULL, &si), VES_OK);
  assert_int_equal(si.state.nstep, 3);
  ves_io_close(&io);
  free(f.problem);
}

/* References (resets): written and read back bit for bit, counted, the
 * point count checked, truncated, and the next one written in place. */
static void test_references(void **state) {
  (void)state;
  fake f;
  char path[128], err[512] = "";
  ves_io *io = fake_file(&f, "ref.h5", path, sizeof path);
  assert_int_equal(ves_io_references(io), 0);
  enum { NQ = 12 };
  double x[8], h[4], xq[2 * NQ], wq[NQ], pd[6 * NQ];
  for (int k = 0; k < 3; k++) {
    for (int i = 0; i < 8; i++) x[i] = f.X[i] + 0.01 * k;
    for (int i = 0; i < 4; i++) h[i] = 0.1 + i + k;
    for (int i = 0; i < 2 * NQ; i++) xq[i] = i / 7.0 + k;
    for (int i = 0; i < NQ; i++) wq[i] = 1.0 / (i + 3 + k);
    for (int i = 0; i < 6 * NQ; i++) pd[i] = sin(i + k);
    ves_io_reference ref = {
        .step = 10 * (k + 1), .nq = NQ, .x = x, .h = h, .xq = xq, .wq = wq, .pd = pd};
    assert_int_equal(ves_io_write_reference(io, &ref), VES_OK);
    assert_int_equal(ves_io_references(io), k + 1);
  }
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_references(io), 3);
  double bx[8], bh[4], bxq[2 * NQ], bwq[NQ], bpd[6 * NQ];
  ves_io_reference_buf b = {.nq = NQ, .x = bx, .h = bh, .xq = bxq, .wq = bwq, .pd = bpd};
  assert_int_equal(ves_io_read_reference(io, 2, &b), VES_OK);
  assert_int_equal(b.step, 30);
  assert_memory_equal(bx, x, sizeof x);
  assert_memory_equal(bh, h, sizeof h);
  assert_memory_equal(bxq, xq, sizeof xq);
  assert_memory_equal(bwq, wq, sizeof wq);
  assert_memory_equal(bpd, pd, sizeof pd);
  assert_int_equal(ves_io_read_reference(io, 3, &b), VES_ERR_ARG);
  b.nq = NQ - 1; /* not the file's */
  assert_int_equal(ves_io_read_reference(io, 0, &b), VES_ERR_IO);
  assert_int_equal(ves_io_truncate_references(io, 1), VES_ERR_ARG); /* read-only */
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_truncate_references(io, 4), VES_ERR_ARG); /* cannot grow */
  assert_int_equal(ves_io_truncate_references(io, 1), VES_OK);
  assert_int_equal(ves_io_references(io), 1);
  ves_io_reference ref = {.step = 99, .nq = NQ, .x = x, .h = h, .xq = xq, .wq = wq, .pd = pd};
  assert_int_equal(ves_io_write_reference(io, &ref), VES_OK);
  assert_int_equal(ves_io_references(io), 2);
  b.nq = NQ;
  assert_int_equal(ves_io_read_reference(io, 1, &b), VES_OK);
  assert_int_equal(b.step, 99);
  ves_io_close(&io);
  free(f.problem);
}

/* A writer killed in the middle: one series a row longer than the others,
 * and a snapshot group written but not counted. The reader sees the
 * complete rows and snapshots; the next snapshot replaces the stray group. */
static void test_killed_writer(void **state) {
  (void)state;
  fake f;
  char path[128], err[512] = "";
  ves_io *io = fake_file(&f, "kw.h5", path, sizeof path);
  double y[8] = {0}, phi[4] = {0};
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s0), VES_OK);
  for (long i = 0; i < 2; i++) {
    ves_io_row r = row_of(i);
    assert_int_equal(ves_io_append(io, &r), VES_OK);
  }
  ves_io_close(&io);
  hid_t h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  assert_true(h >= 0);
  hid_t d = H5Dopen2(h, "series/E", H5P_DEFAULT);
  hsize_t three = 3;
  assert_true(H5Dset_extent(d, &three) >= 0);
  H5Dclose(d);
  hid_t g = H5Gcreate2(h, "snapshots/1", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  assert_true(g >= 0);
  H5Gclose(g), H5Fclose(h);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  check_rows(io, 2); /* the shortest series */
  ves_io_close(&io);
  /* every series extended, "step" (written last) not yet written: its fill
   * value 0 marks the row incomplete */
  h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  g = H5Gopen2(h, "series", H5P_DEFAULT);
  H5G_info_t gi;
  assert_true(H5Gget_info(g, &gi) >= 0 && gi.nlinks == 21);
  for (hsize_t i = 0; i < gi.nlinks; i++) {
    char name[64];
    assert_true(H5Lget_name_by_idx(g, ".", H5_INDEX_NAME, H5_ITER_INC, i, name, sizeof name,
                                   H5P_DEFAULT) > 0);
    d = H5Dopen2(g, name, H5P_DEFAULT);
    assert_true(H5Dset_extent(d, &three) >= 0);
    H5Dclose(d);
  }
  H5Gclose(g), H5Fclose(h);

  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_OK);
  check_rows(io, 2);
  assert_int_equal(ves_io_snapshots(io), 1);
  ves_io_snapinfo s2 = snap_of(2);
  y[3] = 0.75;
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s2), VES_OK);
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  double y2[8];
  ves_io_snapinfo si;
  assert_int_equal(ves_io_snapshots(io), 2);
  assert_int_equal(ves_io_read_snapshot(io, 1, y2, NULL, NULL, &si), VES_OK);
  assert_true(y2[3] == 0.75 && si.state.nstep == 2);
  ves_io_close(&io);
  free(f.problem);
}

/* Every file that is not ours is refused with the reason, naming it. */
static void test_refusals(void **state) {
  (void)state;
  char path[128], err[512];
  ves_io *io = NULL;
  path_in(path, sizeof path, "missing.h5");
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_ERR_IO);
  assert_non_null(strstr(err, "cannot open"));
  assert_non_null(strstr(err, path));
  path_in(path, sizeof path, "text.h5");
  FILE *t = fopen(path, "w");
  fputs("plain text\n", t);
  fclose(t);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_ERR_IO);
  assert_non_null(strstr(err, "not an HDF5 file"));
  path_in(path, sizeof path, "foreign.h5");
  hid_t h = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  H5Fclose(h);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "not a vesica output file"));
  /* ours, but from a future version */
  fake f;
  fake_init(&f);
  path_in(path, sizeof path, "future.h5");
  assert_int_equal(ves_io_create(path, &f.h, &io, err, sizeof err), VES_OK);
  ves_io_close(&io);
  h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  int v = 99;
  hid_t a = H5Aopen(h, "format_version", H5P_DEFAULT);
  H5Awrite(a, H5T_NATIVE_INT, &v);
  H5Aclose(a), H5Fclose(h);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "format_version 99"));
  assert_null(io);
  /* format 1 (no snapshot x): read, x given as y; not continued */
  path_in(path, sizeof path, "format1.h5");
  assert_int_equal(ves_io_create(path, &f.h, &io, err, sizeof err), VES_OK);
  double y[8], x[8], phi[4] = {0};
  for (int j = 0; j < 8; j++) y[j] = j + 0.5, x[j] = -j;
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, x, phi, &s0), VES_OK);
  ves_io_close(&io);
  h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  v = 1;
  a = H5Aopen(h, "format_version", H5P_DEFAULT);
  H5Awrite(a, H5T_NATIVE_INT, &v);
  H5Aclose(a);
  assert_true(H5Ldelete(h, "snapshots/0/x", H5P_DEFAULT) >= 0);
  H5Fclose(h);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_get_info(io)->format_version, 1);
  assert_int_equal(ves_io_read_snapshot(io, 0, NULL, x, NULL, NULL), VES_OK);
  assert_memory_equal(x, y, sizeof y);
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "format_version 1"));
  assert_non_null(strstr(err, "read-only"));
  assert_null(io);
  /* cannot create */
  assert_int_equal(ves_io_create("/nonexistent/dir/x.h5", &f.h, &io, err, sizeof err), VES_ERR_IO);
  assert_non_null(strstr(err, "/nonexistent/dir/x.h5"));
  assert_null(io);
  free(f.problem);
}

/* A sphere of radius 1 at eps = 0.2, coarse (331 nodes with a P2 bump, 300
 * without): fast to build. */
static ves_setup *tiny_setup(int bump) {
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

/* The material at the nodes (ves_sim_node_material), what the snapshots
 * hold. Sphere of radius 1, eps 0.2 (300 nodes), newton, dt 5e-3.
 *  - t = 0: x = X (the motion is the identity, reproduced by LME to its
 *    Newton tolerance 1e-14 h: bound 1e-12), axis r = 0 and wall nodes
 *    exactly; phi against the exact profile tanh((1 - |X|)/(sqrt2 eps)) to
 *    1e-3 (the least-squares fit at h = 0.7 eps: measured 2.9e-4, 2.2e-4 at
 *    the wall nodes, moved 1e-3 h inwards), and against the setup's own
 *    field sum_b p_b(X_a) phi0c_b to 1e-10 (a refit of that field gives
 *    back phi0c to the projection's 1e-12); with those coefficients given
 *    (ves_sim_set_phi0_coefficients), that field itself;
 *  - after 2 steps: phi bit for bit the same (no reset: the same material),
 *    x moved, axis and walls as above;
 *  - a reset after 2 steps with nodes at y(X_a): x as after the same 2
 *    steps without it (the new nodes are where the material went; LME's
 *    identity to 1e-12), phi carried over bit for bit; with nodes at y^a,
 *    other material: phi refitted on the new reference, within 1e-2 of the
 *    values at t = 0 (the node sets differ by the coefficients' shift, a
 *    small fraction of eps on this smooth motion; measured below). */
static void test_node_material(void **state) {
  (void)state;
  ves_setup *s = tiny_setup(0);
  const ves_nodes *nd = s->nodes;
  const int n = nd->n;
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  ip.t_end = 1, ip.dt_initial = 5e-3, ip.dE_target = 0.05;
  const ves_backend_type *bk = ves_backend_find("newton");
  double *x = malloc(2 * (size_t)n * sizeof *x), *x2 = malloc(2 * (size_t)n * sizeof *x2);
  double *phi = malloc((size_t)n * sizeof *phi), *phi2 = malloc((size_t)n * sizeof *phi2);
  double *f = malloc(6 * (size_t)n * sizeof *f);
  ves_sim *sim = NULL;
  ves_step_report rep;
  assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &sim), VES_OK);
  assert_int_equal(ves_sim_node_material(sim, x, phi), VES_OK);
  ves_quad *pq = NULL;
  assert_int_equal(ves_quad_create_at_nodes(nd, &pq), VES_OK);
  assert_int_equal(ves_quad_tables(pq, nd, &s->quad->lme, NULL), VES_OK);
  ves_quad_field(pq, s->phi0c, 0, f);
  ves_quad_destroy(&pq);
  int walls = 0, axis = 0;
  double ex = 0, worst = 0, worst_wall = 0, efit = 0;
  for (int a = 0; a < n; a++) {
    double R = nd->x[2 * a], Z = nd->x[2 * a + 1];
    double exact = tanh((1 - sqrt(R * R + Z * Z)) / (M_SQRT2 * 0.2)), e = fabs(phi[a] - exact);
    worst = fmax(worst, e);
    efit = fmax(efit, fabs(phi[a] - f[6 * a]));
    ex = fmax(ex, hypot(x[2 * a] - R, x[2 * a + 1] - Z));
    if (nd->flag[a] & VES_NODE_WALL) {
      walls++, worst_wall = fmax(worst_wall, e);
      assert_true(x[2 * a] == R && x[2 * a + 1] == Z);
    }
    if (nd->flag[a] & VES_NODE_AXIS) axis++, assert_true(x[2 * a] == 0.0);
  }
  printf("# %d nodes (%d wall, %d axis): t = 0: max |x - X| = %.1e; max |phi - phi0| = %.2e "
         "(wall %.2e); against the setup's field %.1e\n",
         n, walls, axis, ex, worst, worst_wall, efit);
  assert_true(ex < 1e-12);
  assert_true(worst < 1e-3);
  assert_true(walls > 0 && axis > 0 && worst_wall < 1e-3);
  assert_true(efit < 1e-10);
  for (int i = 0; i < 2; i++) assert_int_equal(ves_sim_step(sim, &rep), VES_OK);
  assert_int_equal(ves_sim_node_material(sim, x2, phi2), VES_OK);
  assert_memory_equal(phi, phi2, (size_t)n * sizeof *phi);
  double moved = 0;
  for (int a = 0; a < n; a++) {
    moved = fmax(moved, hypot(x2[2 * a] - x[2 * a], x2[2 * a + 1] - x[2 * a + 1]));
    if (nd->flag[a] & VES_NODE_WALL) assert_true(x2[2 * a] == x[2 * a]);
    if (nd->flag[a] & VES_NODE_AXIS) assert_true(x2[2 * a] == 0.0);
  }
  printf("# after 2 steps: the material at the nodes moved up to %.2e R0\n", moved);
  assert_true(moved > 1e-6);
  ves_sim_destroy(&sim);

  /* with the setup's coefficients given (as vesica run does): phi is their
   * field at the nodes, bit for bit (no refit), within the refit's 1e-12 of
   * the refitted values above (bound 1e-10, as efit); refused when NULL,
   * non-finite, or after a reset (below) */
  assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &sim), VES_OK);
  assert_int_equal(ves_sim_set_phi0_coefficients(NULL, s->phi0c), VES_ERR_ARG);
  assert_int_equal(ves_sim_set_phi0_coefficients(sim, NULL), VES_ERR_ARG);
  const double keep = s->phi0c[n / 2];
  s->phi0c[n / 2] = NAN;
  assert_int_equal(ves_sim_set_phi0_coefficients(sim, s->phi0c), VES_ERR_ARG);
  s->phi0c[n / 2] = keep;
  assert_int_equal(ves_sim_set_phi0_coefficients(sim, s->phi0c), VES_OK);
  assert_int_equal(ves_sim_node_material(sim, NULL, phi2), VES_OK);
  double dref = 0;
  for (int a = 0; a < n; a++) {
    assert_true(phi2[a] == f[6 * a]);
    dref = fmax(dref, fabs(phi2[a] - phi[a]));
  }
  printf("# with the setup's coefficients: max |phi - phi(refit)| = %.1e\n", dref);
  assert_true(dref < 1e-10);
  ves_sim_destroy(&sim);

  /* a reset after 2 steps: x (against x2, the same 2 steps without a reset)
   * and phi (carried or refitted) */
  for (int mode = 0; mode < 2; mode++) {
    ip.reconnect_every = 2;
    ip.reconnect_nodes = mode ? VES_RESET_NODES_COEF : VES_RESET_NODES_MOTION;
    assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &sim), VES_OK);
    for (int i = 0; i < 2; i++) assert_int_equal(ves_sim_step(sim, &rep), VES_OK);
    assert_int_equal(ves_sim_reconnections(sim), 1);
    assert_int_equal(ves_sim_set_phi0_coefficients(sim, s->phi0c), VES_ERR_ARG); /* a reset's */
    double *phir = mode ? phi2 : x; /* x is free scratch here (2n >= n) */
    assert_int_equal(ves_sim_node_material(sim, f, phir), VES_OK);
    double dx = 0, dphi = 0;
    for (int a = 0; a < n; a++) {
      dx = fmax(dx, hypot(f[2 * a] - x2[2 * a], f[2 * a + 1] - x2[2 * a + 1]));
      dphi = fmax(dphi, fabs(phir[a] - phi[a]));
    }
    printf("# reset, nodes at %s: max |x - x(no reset)| = %.2e, max |phi - phi(t = 0)| = %.2e\n",
           mode ? "y^a" : "y(X_a)", dx, dphi);
    if (mode == 0) {
      assert_true(dx < 1e-12); /* the nodes are where the material went */
      assert_memory_equal(phi, phir, (size_t)n * sizeof *phi);
    } else {
      assert_true(dx > 0); /* new nodes at the coefficients: other material */
      assert_true(dphi > 0 && dphi < 1e-2);
    }
    ves_sim_destroy(&sim);
  }
  free(x), free(x2), free(phi), free(phi2), free(f);
  ves_setup_destroy(&s);
}

/* The restart chain through the library: 4 steps straight, or 2 steps, a
 * snapshot (with the predictor's y^{n-1}), a fresh simulation set from the
 * file and 2 more steps: the same positions, energy, time and next step,
 * bit for bit. */
static void test_restart_chain(void **state) {
  (void)state;
  ves_setup *s = tiny_setup(1);
  int n = s->nodes->n;
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  ip.t_end = 1, ip.dt_initial = 5e-3, ip.dE_target = 0.05;
  const ves_backend_type *bk = ves_backend_find("newton");
  ves_sim *a = NULL, *b = NULL;
  ves_step_report rep;
  assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &a), VES_OK);
  for (int i = 0; i < 4; i++) assert_int_equal(ves_sim_step(a, &rep), VES_OK);
  ves_sim_state sa;
  double *ya = malloc(2 * (size_t)n * sizeof *ya), *yb = malloc(2 * (size_t)n * sizeof *yb);
  double *phi = calloc((size_t)n, sizeof *phi);
  ves_sim_get_state(a, &sa, ya);
  ves_sim_destroy(&a);

  assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &b), VES_OK);
  for (int i = 0; i < 2; i++) assert_int_equal(ves_sim_step(b, &rep), VES_OK);
  ves_io_snapinfo si = {.rows = 2};
  ves_sim_get_state(b, &si.state, yb);
  /* the predictor's y^{n-1} goes with the state (a default run has one) */
  double *ypb = malloc(2 * (size_t)n * sizeof *ypb), *ypr = malloc(2 * (size_t)n * sizeof *ypr);
  assert_true(si.state.dt_prev > 0 && ves_sim_y_prev(b));
  memcpy(ypb, ves_sim_y_prev(b), 2 * (size_t)n * sizeof *ypb);
  si.y_prev = ypb;
  ves_sim_destroy(&b);
  char path[128], err[512] = "";
  path_in(path, sizeof path, "chain.h5");
  char *problem;
  ves_config cfg;
  ves_config_default(&cfg);
  assert_int_equal(ves_config_to_text(&cfg, &problem), VES_OK);
  ves_io_header h = {.version = "t",
                     .backend = "newton",
                     .problem = problem,
                     .source = "",
                     .cfg = &cfg,
                     .n = n,
                     .X = s->nodes->x,
                     .ntri = s->quad->ntri,
                     .tri = s->quad->tri,
                     .E0 = 1,
                     .A0 = 1,
                     .V0 = 1};
  ves_io *io = NULL;
  assert_int_equal(ves_io_create(path, &h, &io, err, sizeof err), VES_OK);
  si.y_prev = NULL; /* a held y^{n-1} must be given */
  assert_int_equal(ves_io_snapshot(io, yb, yb, phi, &si), VES_ERR_ARG);
  si.y_prev = ypb;
  assert_int_equal(ves_io_snapshot(io, yb, yb, phi, &si), VES_OK);
  ves_io_close(&io);
  memset(yb, 0, 2 * (size_t)n * sizeof *yb);

  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  ves_io_snapinfo back;
  assert_int_equal(ves_io_read_snapshot(io, 0, yb, NULL, NULL, &back), VES_OK);
  assert_true(back.state.dt_prev == si.state.dt_prev && !back.y_prev);
  assert_int_equal(ves_io_read_snapshot_prev(io, 0, n, ypr), VES_OK);
  assert_memory_equal(ypr, ypb, 2 * (size_t)n * sizeof *ypr);
  ves_io_close(&io);
  assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &b), VES_OK);
  /* dt_prev > 0 without y^{n-1} is refused */
  assert_int_equal(ves_sim_set_state(b, &back.state, yb, NULL), VES_ERR_ARG);
  assert_int_equal(ves_sim_set_state(b, &back.state, yb, ypr), VES_OK);
  ves_sim_state chk;
  ves_sim_get_state(b, &chk, NULL);
  assert_memory_equal(&chk, &back.state, sizeof chk);
  for (int i = 0; i < 2; i++) assert_int_equal(ves_sim_step(b, &rep), VES_OK);
  ves_sim_state sb;
  ves_sim_get_state(b, &sb, yb);
  printf("# straight: t %.6g E %.12g; restarted: t %.6g E %.12g\n", sa.t, sa.E, sb.t, sb.E);
  assert_memory_equal(ya, yb, 2 * (size_t)n * sizeof *ya);
  assert_memory_equal(&sa, &sb, sizeof sa);

  /* bad states are refused and leave the simulation as it was */
  ves_sim_state bad = sb;
  bad.dt = 0;
  assert_int_equal(ves_sim_set_state(b, &bad, yb, ypr), VES_ERR_ARG);
  bad = sb, bad.E = NAN;
  assert_int_equal(ves_sim_set_state(b, &bad, yb, ypr), VES_ERR_ARG);
  yb[0] = INFINITY;
  assert_int_equal(ves_sim_set_state(b, &sb, yb, ypr), VES_ERR_ARG);
  ves_sim_get_state(b, &chk, NULL);
  assert_memory_equal(&chk, &sb, sizeof chk);
  ves_sim_destroy(&b);
  free(ya), free(yb), free(phi), free(problem), free(ypb), free(ypr);
  ves_setup_destroy(&s);
}

/* ---- a write that fails (a full disk) ------------------------------------ */

static char self[4096]; /* this program, re-executed for the child below */

/* The child of test_write_failure, a fresh process whose first HDF5 call is
 * the io module's (as in vesica): open path writable, limit the size of the
 * files it writes to the current size plus 1 KiB (RLIMIT_FSIZE: a real
 * failing write, EFBIG, as a full disk's ENOSPC), and append rows past the
 * room check until a write fails. Prints what it saw; exits 0 unless it
 * crashes on the way out (HDF5's exit-time cleanup after a failed
 * H5Fclose must not segfault). */
static int write_fail_child(const char *path) {
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

/* A write that fails: the room check sees the limit first; a write past
 * it fails with the cause recorded (strerror(EFBIG)), and the process
 * closes the file and exits without crashing. */
static void test_write_failure(void **state) {
  (void)state;
  fake f;
  char path[128], out[128], cmd[4096 + 512];
  ves_io *io = fake_file(&f, "full.h5", path, sizeof path);
  double y[8] = {0}, phi[4] = {0};
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s0), VES_OK);
  assert_int_equal(ves_io_room(io, 1, 100), VES_OK); /* no limit here */
  assert_null(ves_io_error(io));
  ves_io_close(&io);
  free(f.problem);
  path_in(out, sizeof out, "full.out");
  snprintf(cmd, sizeof cmd, "%s --write-fail %s > %s 2>&1", self, path, out);
  int rc = system(cmd);
  char text[1024] = "";
  FILE *fo = fopen(out, "r");
  size_t k = fo ? fread(text, 1, sizeof text - 1, fo) : 0;
  text[k] = 0;
  if (fo) fclose(fo);
  printf("# child exit %d:\n%s", WIFEXITED(rc) ? WEXITSTATUS(rc) : 128 + WTERMSIG(rc), text);
  assert_true(WIFEXITED(rc) && WEXITSTATUS(rc) == 0); /* not 139 */
  assert_non_null(strstr(text, "room: file size limit reached"));
  char want[128];
  snprintf(want, sizeof want, "append: input/output error: %s\n", strerror(EFBIG));
  assert_non_null(strstr(text, want));
}

/* A file cut short (a copy interrupted, a full disk) is named damaged and
 * truncated, not "in use by a running vesica", writable or not. */
static void test_truncated(void **state) {
  (void)state;
  fake f;
  char path[128], err[512] = "";
  ves_io *io = fake_file(&f, "cut.h5", path, sizeof path);
  double y[8] = {0}, phi[4] = {0};
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s0), VES_OK);
  ves_io_close(&io);
  free(f.problem);
  struct stat sb;
  assert_int_equal(stat(path, &sb), 0);
  assert_int_equal(truncate(path, sb.st_size / 2), 0);
  for (int w = 0; w < 2; w++) {
    assert_int_equal(ves_io_open(path, w, &io, err, sizeof err), VES_ERR_IO);
    printf("# cut to half, writable %d: %s\n", w, err);
    assert_non_null(strstr(err, "damaged: truncated file"));
    assert_null(strstr(err, "in use"));
  }
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
static char *file_bytes(const char *path, long *size) {
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
static void write_prefix(const char *path, const char *bytes, long n) {
  FILE *o = fopen(path, "wb");
  assert_true(o && fwrite(bytes, 1, (size_t)n, o) == (size_t)n);
  fclose(o);
}

static void test_salvage(void **state) {
  (void)state;
  fake f;
  char path[128], cut[160], out[192], err[512] = "";
  ves_io *io = fake_file(&f, "salv.h5", path, sizeof path);
  double y[8], x[8], phi[4] = {1, 0.5, -0.25, -1};
  for (long i = 0; i <= 6; i++) {
    if (i % 3 == 0) {
      for (int j = 0; j < 8; j++) y[j] = f.X[j] + 0.01 * (double)i, x[j] = y[j] + 1e-3;
      ves_io_snapinfo si = snap_of(i);
      assert_int_equal(ves_io_snapshot(io, y, x, phi, &si), VES_OK);
    }
    if (i < 6) {
      ves_io_row r = row_of(i);
      assert_int_equal(ves_io_append(io, &r), VES_OK);
    }
  }
  ves_io_close(&io);
  free(f.problem);
  snprintf(out, sizeof out, "%s.salvage", path);
  ves_io_salvaged s;
  assert_int_equal(ves_io_salvage(path, out, &s, err, sizeof err), VES_ERR_ARG);
  assert_non_null(strstr(err, "not cut short"));
  assert_int_equal(ves_io_cut_short(path, NULL, NULL), 0);
  long fsize;
  char *bytes = file_bytes(path, &fsize);
  snprintf(cut, sizeof cut, "%s.cut", path);
  int kept[3] = {0}, refused = 0;
  for (long c = 500; c < fsize; c += 2500) {
    write_prefix(cut, bytes, c);
    long long size = 0, stored = 0;
    assert_int_equal(ves_io_cut_short(cut, &size, &stored), 1);
    assert_true(size == c && stored == fsize);
    ves_status st = ves_io_salvage(cut, out, &s, err, sizeof err);
    if (st != VES_OK) {
      if (st != VES_ERR_IO) fail_msg("cut at %ld: %s (%s)", c, ves_status_str(st), err);
      assert_int_equal(access(out, F_OK), -1);
      refused++;
      continue;
    }
    assert_true(s.snapshot >= 0 && s.snapshot <= 2 && s.snapshots == 3);
    assert_int_equal(s.rows, 3 * s.snapshot);
    kept[s.snapshot]++;
    assert_int_equal(ves_io_open(out, 1, &io, err, sizeof err), VES_OK);
    assert_int_equal(ves_io_snapshots(io), s.snapshot + 1);
    check_rows(io, s.rows);
    double y1[8], x1[8], phi1[4];
    ves_io_snapinfo si1, want = snap_of(s.rows);
    assert_int_equal(ves_io_read_snapshot(io, s.snapshot, y1, x1, phi1, &si1), VES_OK);
    for (int j = 0; j < 8; j++) y[j] = f.X[j] + 0.01 * (double)s.rows, x[j] = y[j] + 1e-3;
    assert_memory_equal(y, y1, sizeof y), assert_memory_equal(x, x1, sizeof x);
    assert_memory_equal(phi, phi1, sizeof phi);
    assert_memory_equal(&want.state, &si1.state, sizeof want.state);
    ves_io_row r = row_of(s.rows); /* it continues */
    assert_int_equal(ves_io_append(io, &r), VES_OK);
    ves_io_close(&io);
    if (kept[0] + kept[1] + kept[2] == 1) { /* an existing output is not replaced */
      assert_int_equal(ves_io_salvage(cut, out, &s, err, sizeof err), VES_ERR_IO);
      assert_non_null(strstr(err, "must not exist"));
    }
    remove(out);
  }
  printf("# %ld cuts: snapshot 0 kept %d times, 1 %d, 2 %d; %d refused\n", (fsize + 2000) / 2500,
         kept[0], kept[1], kept[2], refused);
  assert_true(kept[1] + kept[2] >= 1); /* the end cut off keeps a later snapshot */
  assert_true(kept[0] + kept[1] + kept[2] > refused);
  free(bytes);
  remove(cut);
  /* snapshots without checksums (an older writer): refused, nothing written */
  char plain[128];
  fake g;
  io = fake_file(&g, "plain.h5", plain, sizeof plain);
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, x, phi, &s0), VES_OK);
  ves_io_close(&io);
  free(g.problem);
  hid_t h = H5Fopen(plain, H5F_ACC_RDWR, H5P_DEFAULT);
  assert_true(h >= 0);
  assert_true(H5Adelete_by_name(h, "snapshots/0", "checksum", H5P_DEFAULT) >= 0);
  H5Fclose(h);
  struct stat sb;
  assert_int_equal(stat(plain, &sb), 0);
  assert_int_equal(truncate(plain, sb.st_size - 1), 0);
  snprintf(out, sizeof out, "%s.salvage", plain);
  assert_int_equal(ves_io_salvage(plain, out, &s, err, sizeof err), VES_ERR_IO);
  printf("# no checksums: %s\n", err);
  assert_non_null(strstr(err, "carry no checksums"));
  assert_int_equal(access(out, F_OK), -1);
}

/* ---- damaged files (found by tests/fuzz/fuzz_h5.c) ------------------------ */

/* A fake file named name (path out) with nsnap snapshots (y = 0..7) and as
 * many rows; its bytes (malloc'd) returned, their count in *size. */
static unsigned char *fake_bytes(const char *name, char *path, size_t len, int nsnap, long *size) {
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
static void put_bytes(const char *path, unsigned char *b, long size) {
  FILE *fp = fopen(path, "wb");
  assert_true(fp && fwrite(b, 1, (size_t)size, fp) == (size_t)size);
  fclose(fp);
  free(b);
}

/* The salvage of path refused (VES_ERR_IO) with `why` in its message, and
 * nothing left at its output. */
static void salvage_refused(const char *path, const char *why) {
  char out[192], err[1024] = "";
  snprintf(out, sizeof out, "%s.salvage", path);
  ves_io_salvaged res;
  assert_int_equal(ves_io_salvage(path, out, &res, err, sizeof err), VES_ERR_IO);
  printf("# %s\n", err);
  assert_non_null(strstr(err, path));
  assert_non_null(strstr(err, why));
  assert_int_equal(access(out, F_OK), -1);
}

/* A superblock recording an end far beyond the file (the salvage allocated
 * it) is refused before anything is allocated or written. */
static void test_salvage_huge_end(void **state) {
  (void)state;
  char path[128];
  long size;
  unsigned char *b = fake_bytes("huge.h5", path, sizeof path, 1, &size);
  assert_true(b[8] == 0 || b[8] == 1); /* superblock version: its end of file at 40 or 44 */
  const long long huge = 1LL << 45;    /* 32 TiB, below the 2^50 ves_io_cut_short accepts */
  for (int i = 0; i < 8; i++) b[(b[8] == 0 ? 40 : 44) + i] = (unsigned char)(huge >> (8 * i));
  put_bytes(path, b, size);
  long long got = 0, stored = 0;
  assert_int_equal(ves_io_cut_short(path, &got, &stored), 1);
  assert_true(stored == huge && got == size);
  salvage_refused(path, "superblock records 35184372088832 bytes");
}

/* Data whose HDF5 type is not one this module writes is refused unread,
 * without a crash: a damaged float type (bit offset 7 in a 64-bit double)
 * sends HDF5 1.10.8's conversion (H5T__conv_f_f) far past its buffers:
 * such a file opened, and `vesica run --restart` crashed (SIGSEGV)
 * appending its first series row. Here every double of the file so
 * damaged, then a snapshot's y replaced by a valid but foreign float type. */
static void test_foreign_types(void **state) {
  (void)state;
  char path[128], copy[160], err[512] = "";
  long size;
  unsigned char *b = fake_bytes("types.h5", path, sizeof path, 1, &size);
  /* the datatype message of an IEEE little-endian double (version 1, class
   * 1; size 8; bit offset 0, precision 64; exponent at 52, 11 bits;
   * mantissa at 0, 52 bits; bias 1023): its bit offset set to 7 */
  static const unsigned char f64[20] = {0x11, 0x20, 0x3f, 0,  8, 0,    0,    0,    0, 0,
                                        0x40, 0,    0x34, 11, 0, 0x34, 0xff, 0x03, 0, 0};
  int found = 0;
  for (long i = 0; i + 20 <= size; i++)
    if (!memcmp(b + i, f64, sizeof f64)) b[i + 8] = 7, found++;
  assert_true(found >= 10);
  snprintf(copy, sizeof copy, "%s.damaged", path);
  put_bytes(copy, b, size);
  ves_io *io = NULL;
  for (int w = 0; w < 2; w++) {
    assert_int_equal(ves_io_open(copy, w, &io, err, sizeof err), VES_ERR_CONFIG);
    assert_non_null(strstr(err, "not a vesica output file"));
    assert_null(io);
  }
  printf("# %d doubles' types damaged: %s\n", found, err);
  /* a valid float type that is not ours (a 32-bit float) in a snapshot */
  const double y[8] = {0, 1, 2, 3, 4, 5, 6, 7};
  hid_t h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  assert_true(h >= 0 && H5Ldelete(h, "snapshots/0/y", H5P_DEFAULT) >= 0);
  hsize_t dims[2] = {4, 2};
  hid_t sp = H5Screate_simple(2, dims, NULL);
  hid_t d =
      H5Dcreate2(h, "snapshots/0/y", H5T_IEEE_F32LE, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  assert_true(d >= 0 && H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, y) >= 0);
  H5Dclose(d), H5Sclose(sp), H5Fclose(h);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  double y1[8];
  assert_int_equal(ves_io_read_snapshot(io, 0, y1, NULL, NULL, NULL), VES_ERR_IO);
  /* x is ours, but a read verifies the snapshot whole (its checksum covers y) */
  assert_int_equal(ves_io_read_snapshot(io, 0, NULL, y1, NULL, NULL), VES_ERR_IO);
  assert_non_null(strstr(ves_io_corruption(io), "/snapshots/0/y: does not read"));
  ves_io_close(&io);
}

/* A salvage copies only what reads whole: a contiguous dataset whose
 * layout records more stored bytes than its data holds crashed HDF5's
 * H5Ocopy (SIGSEGV); snapshot 0's y so damaged in a file cut short, the
 * salvage refuses (every snapshot stands on snapshot 0) without a crash. */
static void test_salvage_bad_layout(void **state) {
  (void)state;
  char path[128];
  long size;
  unsigned char *b = fake_bytes("layout.h5", path, sizeof path, 2, &size);
  hid_t h = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
  hid_t d = H5Dopen2(h, "snapshots/0/y", H5P_DEFAULT);
  const haddr_t at = H5Dget_offset(d);
  H5Dclose(d), H5Fclose(h);
  /* its layout message: version 3, contiguous, address, size 64 */
  unsigned char msg[18] = {3, 1};
  for (int i = 0; i < 8; i++) msg[2 + i] = (unsigned char)(at >> (8 * i));
  msg[10] = 64;
  int found = 0;
  for (long i = 0; i + 18 <= size; i++)
    if (!memcmp(b + i, msg, sizeof msg)) b[i + 12] = 7, found++; /* size 64 + 7 << 16 */
  assert_int_equal(found, 1);
  put_bytes(path, b, size - 100);
  salvage_refused(path, "cannot be copied whole");
}

/* A salvage with a damaged attribute message in /parameters (a string
 * type of size 0 and an unknown padding): iterating the attributes
 * (H5Aiterate2) crashed in HDF5 1.10.8 (SIGSEGV in H5A__close); they are
 * first decoded one by one (io.c attrs_decode), and the salvage refuses. */
static void test_salvage_bad_attribute(void **state) {
  (void)state;
  char path[128];
  long size;
  unsigned char *b = fake_bytes("attr.h5", path, sizeof path, 1, &size);
  /* the attribute geometry.quadrature: its name, then (8-byte aligned) its
   * datatype message, a fixed string (class 3, version 1: 0x13) */
  static const char name[] = "geometry.quadrature";
  int found = 0;
  for (long i = 0; i + 40 <= size && !found; i++)
    if (!memcmp(b + i, name, sizeof name))
      for (long j = i + (long)sizeof name; j < i + 32 && !found; j++)
        if (b[j] == 0x13) b[j + 1] = 8, b[j + 4] = 0, found = 1; /* padding 8, size 0 */
  assert_true(found);
  put_bytes(path, b, size - 100);
  salvage_refused(path, "cannot be copied whole");
}

/* H5Ovisit callback: every group and dataset (the root included) has the
 * string attributes units and description; counts them in *data. */
static herr_t described(hid_t obj, const char *name, const H5O_info_t *info, void *data) {
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

/* Self-describing output: units and description on every group and
 * dataset of a file with series, snapshots and references; the root names
 * the program, version, problem and where the format is described. */
static void test_self_describing(void **state) {
  (void)state;
  fake f;
  char path[128];
  ves_io *io = fake_file(&f, "desc.h5", path, sizeof path);
  ves_io_row r = row_of(0);
  assert_int_equal(ves_io_append(io, &r), VES_OK);
  double y[8], x[8], phi[4] = {1, 0.5, -0.25, -1};
  for (int j = 0; j < 8; j++) y[j] = x[j] = f.X[j];
  ves_io_snapinfo si = snap_of(1);
  assert_int_equal(ves_io_snapshot(io, y, x, phi, &si), VES_OK);
  enum { NQ = 3 };
  double h[4] = {0.1, 0.1, 0.1, 0.1}, xq[2 * NQ] = {0}, wq[NQ] = {1, 1, 1}, pd[6 * NQ] = {0};
  ves_io_reference ref = {.step = 1, .nq = NQ, .x = x, .h = h, .xq = xq, .wq = wq, .pd = pd};
  assert_int_equal(ves_io_write_reference(io, &ref), VES_OK);
  ves_io_close(&io);
  hid_t h5 = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
  assert_true(h5 >= 0);
  int count = 0;
  assert_true(H5Ovisit(h5, H5_INDEX_NAME, H5_ITER_INC, described, &count) >= 0);
  /* root, parameters, mesh + 3, series + 21, snapshots + 0 + 3, references + 0 + 5 */
  assert_int_equal(count, 1 + 1 + 4 + 22 + 5 + 7);
  const char *root[] = {"program", "version",        "problem",
                        "source",  "format_version", "format_description"};
  for (size_t i = 0; i < sizeof root / sizeof root[0]; i++)
    if (H5Aexists(h5, root[i]) <= 0) fail_msg("root: no attribute %s", root[i]);
  /* the status codes as an enumeration: every value with its name */
  hid_t a = H5Aopen_by_name(h5, "series/status", "codes", H5P_DEFAULT, H5P_DEFAULT);
  assert_true(a >= 0);
  hid_t t = H5Aget_type(a);
  assert_int_equal(H5Tget_class(t), H5T_ENUM);
  assert_int_equal(H5Tget_nmembers(t), 14); /* VES_STATUS_LIST */
  char name[32];
  int v = VES_ERR_IO;
  assert_true(H5Tenum_nameof(t, &v, name, sizeof name) >= 0);
  assert_string_equal(name, "VES_ERR_IO");
  v = VES_MAXITER;
  assert_true(H5Tenum_nameof(t, &v, name, sizeof name) >= 0);
  assert_string_equal(name, "VES_MAXITER");
  H5Tclose(t), H5Aclose(a);
  H5Fclose(h5);
  /* and the file still reads */
  char err[512] = "";
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_snapshots(io), 1);
  ves_io_close(&io);
  unlink(path);
  free(f.problem);
}

/* The --series text from the table of columns: the header the program
 * wrote before the table (17 names, in its order) and a row whose values
 * print in their formats, the drifts against A0 and V_target. */
static void test_tsv_row(void **state) {
  (void)state;
  char buf[1024] = "";
  FILE *f = fmemopen(buf, sizeof buf, "w");
  assert_non_null(f);
  assert_int_equal(ves_io_tsv_header(f), VES_OK);
  ves_io_row row = {.step = 7,
                    .t = 0.125,
                    .dt = 0.5,
                    .E = 6.25,
                    .A = 12.6,
                    .V = 4.2,
                    .V_target = 4.0,
                    .lambda_A = -1.5,
                    .lambda_V = 2.5,
                    .iterations = 3,
                    .f_evals = 4,
                    .g_evals = 5,
                    .h_evals = 6,
                    .solve_seconds = 1.25,
                    .retries = 1,
                    .reconnections = 2,
                    .rejected_iterations = 9,
                    .rejected_seconds = 0.5,
                    .factorizations = 8,
                    .c0 = 3,
                    .violation = 1e-12,
                    .status = 0};
  assert_int_equal(ves_io_tsv_row(f, &row, 12.0), VES_OK);
  fclose(f);
  assert_string_equal(buf, "# step\tt\tdt\tE\tA/A0-1\tV/Vt-1\tlambda_A\tlambda_V\titer\tf\tg\th\t"
                           "seconds\tretries\tresets\trejected_iterations\trejected_seconds\t"
                           "factorizations\n"
                           "7\t0.125\t0.5\t6.25\t5.000e-02\t5.000e-02\t-1.5\t2.5\t3\t4\t5\t6\t1.250"
                           "\t1\t2\t9\t0.500\t8\n");
}

/* A file of an older writer, without the series column "factorizations"
 * (added on 2026-12-05 within format_version 2): it opens and continues
 * without the column (appends, snapshots), reads it as -1 and summarizes it
 * as not recorded; its checksums, written without the column, hold, so a
 * copy cut short is salvaged, and the salvaged file lacks the column too. */
static void test_older_file(void **state) {
  (void)state;
  fake f;
  char path[128], cut[160], out[192], err[512] = "";
  ves_io *io = fake_file(&f, "old.h5", path, sizeof path);
  ves_io_close(&io);
  hid_t h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  assert_true(h >= 0 && H5Ldelete(h, "series/factorizations", H5P_DEFAULT) >= 0);
  H5Fclose(h);
  ves_io_summary sum;
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_summarize(io, 0, &sum), VES_OK);
  assert_true(sum.steps == 0 && sum.factorizations == -1); /* not recorded, even without rows */
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_OK);
  double y[8], x[8], phi[4] = {1, 0.5, -0.25, -1};
  for (int j = 0; j < 8; j++) y[j] = f.X[j], x[j] = y[j] + 1e-3;
  for (long i = 0; i <= 6; i++) {
    if (i % 3 == 0) {
      ves_io_snapinfo si = snap_of(i);
      assert_int_equal(ves_io_snapshot(io, y, x, phi, &si), VES_OK);
    }
    ves_io_row r = row_of(i);
    if (i < 6) assert_int_equal(ves_io_append(io, &r), VES_OK);
  }
  assert_int_equal(ves_io_truncate(io, 6), VES_OK);
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_rows(io), 6);
  double v[6], it[6];
  assert_int_equal(ves_io_read_series(io, "factorizations", v), VES_OK);
  assert_int_equal(ves_io_read_series(io, "iterations", it), VES_OK);
  for (int i = 0; i < 6; i++) assert_true(v[i] == -1 && it[i] == row_of(i).iterations);
  assert_int_equal(ves_io_summarize(io, 0, &sum), VES_OK);
  assert_true(sum.factorizations == -1 && sum.iterations == 3 + 4 + 5 + 6 + 7 + 8);
  ves_io_close(&io);
  /* cut short at every 997th byte: some copy keeps a later snapshot, whose
   * series checksum (without the column) held */
  long fsize;
  char *bytes = file_bytes(path, &fsize);
  snprintf(cut, sizeof cut, "%s.cut", path);
  snprintf(out, sizeof out, "%s.salvage", path);
  int later = 0;
  for (long c = 500; c < fsize; c += 997) {
    write_prefix(cut, bytes, c);
    ves_io_salvaged s;
    if (ves_io_salvage(cut, out, &s, err, sizeof err) != VES_OK) continue;
    later += s.snapshot > 0;
    assert_int_equal(ves_io_open(out, 1, &io, err, sizeof err), VES_OK);
    assert_int_equal(ves_io_rows(io), s.rows);
    ves_io_row r = row_of(s.rows); /* it continues, still without the column */
    assert_int_equal(ves_io_append(io, &r), VES_OK);
    double w[7];
    assert_int_equal(ves_io_read_series(io, "factorizations", w), VES_OK);
    for (long i = 0; i <= s.rows; i++) assert_true(w[i] == -1);
    ves_io_close(&io);
    h = H5Fopen(out, H5F_ACC_RDONLY, H5P_DEFAULT);
    assert_true(h >= 0 && H5Lexists(h, "series/factorizations", H5P_DEFAULT) == 0);
    H5Fclose(h);
    remove(out);
  }
  printf("# an older file cut short: %d salvaged copies kept a later snapshot\n", later);
  assert_true(later > 0);
  free(bytes);
  remove(cut), remove(path);
  free(f.problem);
}

int main(int argc, char **argv) {
  if (argc == 3 && !strcmp(argv[1], "--write-fail")) return write_fail_child(argv[2]);
  snprintf(self, sizeof self, "%s", argv[0]);
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_roundtrip),       cmocka_unit_test(test_truncate_continue),
      cmocka_unit_test(test_killed_writer),   cmocka_unit_test(test_references),
      cmocka_unit_test(test_refusals),        cmocka_unit_test(test_node_material),
      cmocka_unit_test(test_restart_chain),   cmocka_unit_test(test_write_failure),
      cmocka_unit_test(test_truncated),       cmocka_unit_test(test_salvage),
      cmocka_unit_test(test_salvage_huge_end), cmocka_unit_test(test_foreign_types),
      cmocka_unit_test(test_salvage_bad_layout), cmocka_unit_test(test_salvage_bad_attribute),
      cmocka_unit_test(test_self_describing), cmocka_unit_test(test_tsv_row),
      cmocka_unit_test(test_older_file),
  };
  // clang-format on
  return cmocka_run_group_tests_name("io", tests, setup_all, teardown_all);
}
