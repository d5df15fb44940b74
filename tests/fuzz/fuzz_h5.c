/* vesica — libFuzzer target: the reader of vesica's HDF5 output, on a file
 * holding the input, the way the program uses it:
 *   - `vesica info` and `vesica plot`: ves_io_open read-only, the stored
 *     problem, the summary, every series, snapshot (with y_prev), the mesh,
 *     every reference and remeshing, the nodes' interface (ves_plot_interface);
 *   - `vesica run --restart`: a file cut short salvaged (ves_io_salvage) into
 *     a new file, which must open and hold the snapshot it names; then the
 *     file opened for writing, the last snapshot and what it stands on read
 *     as cli_rebuild_at reads them, the truncations and status writes of a
 *     restart, one series row and one snapshot appended (the restart's setup
 *     and time step are not run: they are not the reader).
 * Built and run by `make fuzz` with AddressSanitizer + UBSan on our code
 * (libhdf5 itself is not instrumented: a crash inside it still stops the
 * fuzzer). The contract: no crash, no sanitizer report; a refusal is a
 * status < 0 with a one-line message naming the file; every dataset,
 * group, datatype and attribute closed after each input (H5Fget_obj_count;
 * a file whose H5Fclose failed stays half open in HDF5); a salvage that
 * succeeds gives a file that opens with the snapshots and rows it reports. */
#include <hdf5.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "app/config.h"
#include "app/io.h"
#include "ves/level_set.h"
#include "app/plot.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#define MAX_ITEMS 64        /* snapshots, references, remeshings read at most */
#define MAX_NODES (1 << 22) /* larger counts are not read (the seeds have hundreds) */
/* A salvage holds the file padded to the end its superblock records in
 * memory (refused past a quarter of the machine's: test_io
 * test_salvage_huge_end); here only up to this, under libFuzzer's 2 GB
 * malloc limit. */
#define MAX_IMAGE (256LL << 20)

static char dir[64], path[128], xdmf[128], out[128], out_xdmf[128];

static void die(const char *what, const char *detail) {
  fprintf(stderr, "fuzz_h5: contract broken: %s: %s\n", what, detail);
  abort();
}

static void cleanup(void) {
  char last[160]; /* the salvage's single-grid XDMF file (meshio.read's) */
  snprintf(last, sizeof last, "%s/f.h5.salvage_last.xmf", dir);
  unlink(path), unlink(xdmf), unlink(out), unlink(out_xdmf), unlink(last);
  rmdir(dir);
}

/* The scratch folder in memory (/dev/shm when there is one); HDF5 silent,
 * its exit-time cleanup declined as vesica declines it (io.c). */
int LLVMFuzzerInitialize(int *argc, char ***argv) {
  (void)argc, (void)argv;
  H5dont_atexit();
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
  snprintf(dir, sizeof dir, "/dev/shm/vesica_fuzz_h5_XXXXXX");
  if (!mkdtemp(dir)) {
    snprintf(dir, sizeof dir, "/tmp/vesica_fuzz_h5_XXXXXX");
    if (!mkdtemp(dir)) die("no scratch folder", dir);
  }
  snprintf(path, sizeof path, "%s/f.h5", dir);
  snprintf(xdmf, sizeof xdmf, "%s/f.xdmf", dir);
  snprintf(out, sizeof out, "%s/f.h5.salvage", dir);
  snprintf(out_xdmf, sizeof out_xdmf, "%s/f.h5.salvage.xdmf", dir);
  atexit(cleanup);
  return 0;
}

/* A refusal: a status < 0 and one line naming the file. */
static void check_refused(ves_status st, const char *err, const char *name, const char *what) {
  char msg[1400];
  snprintf(msg, sizeof msg, "%s: status %d, message '%s'", what, (int)st, err);
  if (st >= 0) die("refusal status", msg);
  if (!err[0] || strchr(err, '\n') || !strstr(err, name)) die("refusal message", msg);
}

/* The sizes of reference k's quadrature (the restart takes them from its
 * setup, which must match the file; here from the file itself), or 0. */
static int reference_nq(const char *file, int k) {
  hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  H5Pset_file_locking(fapl, 0, 1);
  hid_t f = H5Fopen(file, H5F_ACC_RDONLY, fapl);
  H5Pclose(fapl);
  if (f < 0) return 0;
  char name[64];
  snprintf(name, sizeof name, "references/%d/weights", k);
  hssize_t np = 0;
  hid_t d = H5Lexists(f, "references", H5P_DEFAULT) > 0 ? H5Dopen2(f, name, H5P_DEFAULT) : -1;
  hid_t sp = d < 0 ? -1 : H5Dget_space(d);
  if (sp >= 0) np = H5Sget_simple_extent_npoints(sp);
  if (sp >= 0) H5Sclose(sp);
  if (d >= 0) H5Dclose(d);
  H5Fclose(f);
  return np > 0 && np <= MAX_NODES ? (int)np : 0;
}

static void *alloc(size_t count, size_t size) { return calloc(count ? count : 1, size); }

/* Reference k into buffers of the sizes the file (or the caller) says. */
static void read_reference(ves_io *io, const char *file, int k, int n) {
  long step = 0;
  ves_io_reference_step(io, k, &step);
  const int nq = reference_nq(file, k);
  if (nq <= 0 || n <= 0 || n > MAX_NODES) return;
  ves_io_reference_buf b = {.nq = nq, .n = n};
  b.x = alloc(2 * (size_t)n, sizeof(double)), b.h = alloc((size_t)n, sizeof(double));
  b.xq = alloc(2 * (size_t)nq, sizeof(double)), b.wq = alloc((size_t)nq, sizeof(double));
  b.pd = alloc(6 * (size_t)nq, sizeof(double));
  if (b.x && b.h && b.xq && b.wq && b.pd) ves_io_read_reference(io, k, &b);
  free(b.x), free(b.h), free(b.xq), free(b.wq), free(b.pd);
}

/* Remeshing k (its nodes and triangles), as a restart and the XDMF use it;
 * its node count, or -1. */
static int read_remesh(ves_io *io, int k) {
  long step = 0;
  int n = 0, nt = 0;
  if (ves_io_remesh_size(io, k, &step, &n, &nt) != VES_OK || n > MAX_NODES || nt > MAX_NODES)
    return -1;
  ves_io_remesh_buf b = {.n = n};
  b.x = alloc(2 * (size_t)n, sizeof(double)), b.h = alloc((size_t)n, sizeof(double));
  b.flag = alloc((size_t)n, sizeof(int)), b.phi0c = alloc((size_t)n, sizeof(double));
  int *tri = alloc(3 * (size_t)nt, sizeof(int));
  if (b.x && b.h && b.flag && b.phi0c && tri) {
    ves_io_read_remesh(io, k, &b);
    ves_io_read_remesh_triangles(io, k, tri);
  }
  free(b.x), free(b.h), free(b.flag), free(b.phi0c), free(tri);
  return n;
}

/* Snapshot k whole (y, x, phi, state, y_prev); 0 when it reads. */
static int read_snapshot(ves_io *io, int k, ves_io_snapinfo *si) {
  const int n = ves_io_snapshot_nodes(io, k);
  int mn = 0, mt = 0;
  ves_io_snapshot_mesh(io, k, &mn, &mt);
  if (n <= 0 || n > MAX_NODES) return -1;
  double *y = alloc(2 * (size_t)n, sizeof *y), *x = alloc(2 * (size_t)n, sizeof *x);
  double *phi = alloc((size_t)n, sizeof *phi);
  ves_status st = VES_ERR_ALLOC;
  if (y && x && phi) st = ves_io_read_snapshot_n(io, k, n, y, x, phi, si);
  if (st == VES_OK && si->state.dt_prev > 0) ves_io_read_snapshot_prev(io, k, n, y);
  free(y), free(x), free(phi);
  return st == VES_OK ? 0 : -1;
}

/* Everything `vesica info` and `vesica plot` read of an open file. */
static void read_all(ves_io *io, const char *file) {
  const ves_io_info *in = ves_io_get_info(io);
  char msg[256], err[1024] = "";
  snprintf(msg, sizeof msg, "nodes %d, triangles %d", in->n, in->ntri);
  if (in->n <= 0 || in->ntri < 0 || !in->problem || !in->source) die("accepted header", msg);
  ves_config cfg;
  ves_config_default(&cfg);
  if (ves_config_load_text(in->problem, in->source, &cfg, err, sizeof err) != VES_OK)
    cfg.c0 = 0; /* info refuses here; plot goes on */
  ves_io_summary u;
  ves_io_summarize(io, cfg.c0, &u);
  const long R = ves_io_rows(io);
  if (R < 0) die("rows", "negative");
  static const char *const names[] = {"t",
                                      "dt",
                                      "E",
                                      "A",
                                      "V",
                                      "V_target",
                                      "lambda_A",
                                      "lambda_V",
                                      "c0",
                                      "iterations",
                                      "f_evals",
                                      "g_evals",
                                      "h_evals",
                                      "violation",
                                      "solve_seconds",
                                      "wall_seconds",
                                      "retries",
                                      "status",
                                      "reconnections",
                                      "step"};
  double *col = R <= MAX_NODES ? alloc((size_t)R, sizeof *col) : NULL;
  for (size_t i = 0; col && i < sizeof names / sizeof names[0]; i++)
    ves_io_read_series(io, names[i], col);
  free(col);
  if (in->n <= MAX_NODES && in->ntri <= MAX_NODES) {
    double *X = alloc(2 * (size_t)in->n, sizeof *X);
    int *tri = alloc(3 * (size_t)in->ntri, sizeof *tri);
    if (X && tri) ves_io_read_mesh(io, X, tri);
    free(X), free(tri);
  }
  const int S = ves_io_snapshots(io);
  if (S < 0) die("snapshots", "negative");
  for (int k = 0; k < S && k < MAX_ITEMS; k++) {
    ves_io_snapinfo si;
    read_snapshot(io, k, &si);
    ves_io_read_snapshot(io, k, NULL, NULL, NULL, &si); /* plot's times */
  }
  for (int k = 0; k < ves_io_references(io) && k < MAX_ITEMS; k++) read_reference(io, file, k, 0);
  for (int k = 0; k < ves_io_remeshes(io) && k < MAX_ITEMS; k++) read_remesh(io, k);
  if (S > 0 && S <= MAX_ITEMS) { /* info's interface lines, plot's constraints figure */
    ves_level_set *ls = alloc((size_t)S, sizeof *ls);
    unsigned char *ok = alloc((size_t)S, 1);
    if (ls && ok) ves_plot_interface(io, ls, ok);
    free(ls), free(ok);
  }
}

/* `vesica run --restart`'s reads of the last snapshot and what it stands on
 * (cli_rebuild_at, restore_nodes), then its writes: the truncations to the
 * snapshot, the status, one row and one snapshot. */
static void restart(ves_io *io) {
  const int S = ves_io_snapshots(io);
  if (S < 1 || S > MAX_ITEMS) return;
  ves_io_snapinfo si;
  if (ves_io_read_snapshot(io, S - 1, NULL, NULL, NULL, &si) != VES_OK) return;
  if (si.reconnections < 0 || si.reconnections > ves_io_references(io)) return;
  const ves_io_info *in = ves_io_get_info(io);
  if (in->n > MAX_NODES || in->ntri > MAX_NODES) return;
  double *X = alloc(2 * (size_t)in->n, sizeof *X);
  if (X) ves_io_read_mesh(io, X, NULL);
  free(X);
  const int ns = ves_io_snapshot_nodes(io, S - 1);
  if (ns < 1 || ns > MAX_NODES || si.rows > ves_io_rows(io) || si.rows != si.state.nstep ||
      si.rows < 0)
    return;
  int R = 0, n_now = in->n; /* the remeshings made at or before the snapshot */
  long rstep = 0;
  while (R < ves_io_remeshes(io) && R < MAX_ITEMS &&
         ves_io_remesh_size(io, R, &rstep, NULL, NULL) == VES_OK && rstep <= si.state.nstep)
    R++;
  if (R > 0 && (n_now = read_remesh(io, R - 1)) < 0) return;
  long fref = 0;
  if (si.reconnections > 0) {
    if (ves_io_reference_step(io, si.reconnections - 1, &fref) != VES_OK) return;
    read_reference(io, path, si.reconnections - 1, ns);
  }
  if (ns != n_now) return; /* the restart refuses: "snapshot K has N nodes, its node set M" */
  double *y = alloc(2 * (size_t)ns, sizeof *y), *x = alloc(2 * (size_t)ns, sizeof *x);
  double *phi = alloc((size_t)ns, sizeof *phi);
  ves_status st =
      y && x && phi ? ves_io_read_snapshot_n(io, S - 1, ns, y, x, phi, &si) : VES_ERR_ALLOC;
  if (st == VES_OK && si.state.dt_prev > 0)
    st = ves_io_read_snapshot_prev(io, S - 1, ns, x); /* as the restart: into x */
  if (st == VES_OK) st = ves_io_truncate(io, si.rows);
  if (st == VES_OK) st = ves_io_truncate_references(io, si.reconnections);
  if (st == VES_OK) st = ves_io_truncate_remeshes(io, R);
  if (st == VES_OK) st = ves_io_set_setup_seconds(io, 1.5);
  if (st == VES_OK) st = ves_io_set_status(io, "running");
  if (st == VES_OK) { /* the next step's row and snapshot */
    ves_io_row row = {.step = si.state.nstep + 1, .t = si.state.t + 1e-3, .dt = 1e-3};
    si.state.nstep++, si.state.t += 1e-3, si.rows++;
    si.y_prev = x; /* y^{n-1} (read, when the snapshot held one: dt_prev > 0) */
    st = ves_io_append(io, &row);
    if (st == VES_OK) st = ves_io_snapshot(io, y, y, phi, &si);
    if (st == VES_OK) st = ves_io_set_status(io, "finished");
  }
  free(y), free(x), free(phi);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
  FILE *f = fopen(path, "wb");
  if (!f) return 0;
  int bad = fwrite(data, 1, size, f) != size;
  if (fclose(f) != 0 || bad) die("cannot write the input", path);
  char err[1024] = "";

  /* info, plot */
  ves_io *io = (ves_io *)1;
  ves_status st = ves_io_open(path, 0, &io, err, sizeof err);
  if (st == VES_OK) {
    read_all(io, path);
    ves_io_close(&io);
  } else {
    check_refused(st, err, path, "open read-only");
    if (io) die("refused open left a handle", err);
  }

  /* run --restart: a file cut short salvaged first */
  long long fsize = 0, stored = 0;
  if (ves_io_cut_short(path, &fsize, &stored) && stored <= MAX_IMAGE) {
    ves_io_salvaged res;
    err[0] = 0;
    st = ves_io_salvage(path, out, &res, err, sizeof err);
    if (st == VES_OK) {
      char msg[256];
      snprintf(msg, sizeof msg, "salvaged snapshot %d, %ld rows", res.snapshot, res.rows);
      ves_io *s = NULL;
      if (ves_io_open(out, 0, &s, err, sizeof err) != VES_OK) die("salvaged file refused", err);
      if (ves_io_snapshots(s) != res.snapshot + 1 || ves_io_rows(s) != res.rows)
        die("salvaged file differs from its report", msg);
      ves_io_snapinfo si;
      if (read_snapshot(s, res.snapshot, &si) != 0) die("salvaged snapshot unreadable", msg);
      read_all(s, out);
      ves_io_close(&s);
    } else {
      check_refused(st, err, path, "salvage");
      if (access(out, F_OK) == 0) die("failed salvage left its file", out);
    }
  }
  /* the restart continues the salvaged file when there is one */
  const char *target = access(out, F_OK) == 0 ? out : path;
  err[0] = 0;
  io = (ves_io *)1;
  st = ves_io_open(target, 1, &io, err, sizeof err);
  if (st == VES_OK) {
    restart(io);
    ves_io_close(&io);
  } else {
    check_refused(st, err, target, "open for writing");
    if (io) die("refused open left a handle", err);
  }
  /* a file itself may stay open: H5Fclose fails, and leaves it half
   * closed, after writes into a damaged file failed (io.c, quiet_hdf5) */
  const unsigned objects = H5F_OBJ_DATASET | H5F_OBJ_GROUP | H5F_OBJ_DATATYPE | H5F_OBJ_ATTR;
  const ssize_t left = H5Fget_obj_count(H5F_OBJ_ALL, objects);
  if (left != 0) { /* say which: type and name of the first few */
    char msg[1024];
    int k = snprintf(msg, sizeof msg, "%zd HDF5 object(s) still open:", left);
    hid_t ids[8];
    const ssize_t m = H5Fget_obj_ids(H5F_OBJ_ALL, objects, 8, ids);
    for (ssize_t i = 0; i < m && k > 0 && k < (int)sizeof msg; i++) {
      char name[256] = "";
      H5Iget_name(ids[i], name, sizeof name);
      k += snprintf(msg + k, sizeof msg - (size_t)k, " [type %d] %s", (int)H5Iget_type(ids[i]),
                    name);
    }
    die("objects left open", msg);
  }
  unlink(path), unlink(xdmf), unlink(out), unlink(out_xdmf);
  return 0;
}
