/* vesica — the per-step series of the run output: the table of columns
 * shared by the file's extendible datasets and the --series text; append,
 * truncate, read, the rows' checksum and the run's summary (vesica info).
 * Layout: app/io.h; docs/design.md, "The program". */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "app/io_impl.h"

#define ROW(f) offsetof(ves_io_row, f)
/* "step" comes last in the file: a row is complete once its step is written
 * (ves_io_rows checks it). */
#define STATUS_DOC_ "ves_status of the accepted solve: " VES_STATUS_LIST(STATUS_DOC_ITEM_)
#define STATUS_DOC_ITEM_(name, value, msg) #value " " msg "; "
/* one column a line, a table to read across (clang-format would break the lines) */
// clang-format off
const series_spec io_series[] = {
    {"t", COL_DOUBLE, ROW(t), "t*", "time at the end of the step, t* = t k/(mu R0^3)"},
    {"dt", COL_DOUBLE, ROW(dt), "t*", "accepted time step"},
    {"E", COL_DOUBLE, ROW(E), "k", "energy the steps minimize, in model units (E* = E/k with [material] k): bending energy plus the stabilization E_s ([geometry] stabilization; 0 after a reset)"},
    {"A", COL_DOUBLE, ROW(A), "R0^2", "area of the phase-field vesicle"},
    {"V", COL_DOUBLE, ROW(V), "R0^3", "enclosed volume of the phase-field vesicle"},
    {"V_target", COL_DOUBLE, ROW(V_target), "R0^3", "volume the step held (V0, or the protocol's ramp)"},
    {"lambda_A", COL_DOUBLE, ROW(lambda_A), "k/R0^2", "multiplier of the area constraint (tension)"},
    {"lambda_V", COL_DOUBLE, ROW(lambda_V), "k/R0^3", "multiplier of the volume constraint (pressure)"},
    {"c0", COL_DOUBLE, ROW(c0), "1/R0", "spontaneous curvature C0 in force during the step"},
    {"iterations", COL_INT, ROW(iterations), "1", "solver iterations of the accepted attempt"},
    {"f_evals", COL_INT, ROW(f_evals), "1", "energy evaluations of the accepted attempt"},
    {"g_evals", COL_INT, ROW(g_evals), "1", "gradient evaluations of the accepted attempt"},
    {"h_evals", COL_INT, ROW(h_evals), "1", "Hessian evaluations of the accepted attempt"},
    {"violation", COL_DOUBLE, ROW(violation), "1", "constraint violation, relative to A0 and V"},
    {"solve_seconds", COL_DOUBLE, ROW(solve_seconds), "s", "wall time of the accepted solve"},
    {"wall_seconds", COL_DOUBLE, ROW(wall_seconds), "s", "wall time of the run's time loop so far"},
    {"retries", COL_INT, ROW(retries), "1", "rejected attempts before the accepted one (each at dt/2)"},
    {"status", COL_INT, ROW(status), "1", STATUS_DOC_},
    {"reconnections", COL_INT, ROW(reconnections), "1", "resets of the reference configuration so far"},
    {"factorizations", COL_INT, ROW(factorizations), "1", "KKT factorizations of the accepted attempt, each rung of an inertia correction one (newton, euler; 0 for ipopt and nlopt, which do not report theirs); optional: a file without it reads as -1"},
    {"step", COL_LONG, ROW(step), "1", "accepted step number (row 0 holds step 0, the initial state at t = 0, and row i step i; written last: a row is complete once its step is)"},
};
// clang-format on

/* An optional column of format_version 2: a file may lack it (its handle
 * -1 once opened), and appends, truncations, checksums and salvaged copies
 * pass it by; ves_io_read_series reads it as -1. */
int io_col_optional(int i) { return !strcmp(io_series[i].name, "factorizations"); }

static hid_t col_file_type(col_type t) {
  return t == COL_LONG ? H5T_STD_I64LE : t == COL_INT ? H5T_STD_I32LE : H5T_IEEE_F64LE;
}

hid_t io_col_mem_type(col_type t) {
  return t == COL_LONG ? H5T_NATIVE_LONG : t == COL_INT ? H5T_NATIVE_INT : H5T_NATIVE_DOUBLE;
}

static size_t col_size(col_type t) {
  return t == COL_LONG ? sizeof(long) : t == COL_INT ? sizeof(int) : sizeof(double);
}

/* Rows [from, from + m) of series dataset d (column type t) into buf. */
static ves_status col_read(hid_t d, col_type t, hsize_t from, hsize_t m, void *buf) {
  if (m == 0) return VES_OK;
  hid_t fs = H5Dget_space(d), ms = H5Screate_simple(1, &m, NULL);
  herr_t e = fs < 0 || ms < 0 ? -1 : H5Sselect_hyperslab(fs, H5S_SELECT_SET, &from, NULL, &m, NULL);
  if (e >= 0) e = H5Dread(d, io_col_mem_type(t), ms, fs, H5P_DEFAULT, buf);
  if (ms >= 0) H5Sclose(ms);
  if (fs >= 0) H5Sclose(fs);
  return e < 0 ? VES_ERR_IO : VES_OK;
}

/* The series checksum continued over m rows held column by column in
 * col[IO_NSERIES]: row by row, each row's values in the order of io_series (a
 * column the file lacks, col[i] NULL, passed by). */
uint64_t io_rows_sum(uint64_t h, void *const *col, long m) {
  for (long r = 0; r < m; r++)
    for (int i = 0; i < IO_NSERIES; i++) {
      if (!col[i]) continue;
      const size_t sz = col_size(io_series[i].type);
      h = io_fnv(h, (const char *)col[i] + (size_t)r * sz, sz);
    }
  return h;
}

/* Read the first `rows` rows of every series into col[] (malloc'd, taken
 * by the caller; freed and NULL on failure). */
ves_status io_cols_read(hid_t const *series, long rows, void **col) {
  ves_status st = VES_OK;
  for (int i = 0; i < IO_NSERIES; i++) col[i] = NULL;
  for (int i = 0; i < IO_NSERIES && st == VES_OK; i++) {
    if (series[i] < 0) continue; /* an optional column the file lacks */
    col[i] = malloc((size_t)(rows > 0 ? rows : 1) * col_size(io_series[i].type));
    st = !col[i] ? VES_ERR_ALLOC : col_read(series[i], io_series[i].type, 0, (hsize_t)rows, col[i]);
  }
  if (st != VES_OK)
    for (int i = 0; i < IO_NSERIES; i++) free(col[i]), col[i] = NULL;
  return st;
}

/* The checksum of the first `rows` rows of the series (extended over the
 * rows written since the last call; recomputed after a truncation). */
ves_status io_series_sum(ves_io *io, long rows, uint64_t *out) {
  rows = io_rows_covered(io, rows);
  if (io->summed_rows > rows) io->summed_rows = 0, io->series_sum = FNV_START;
  const long from = io->summed_rows, m = rows - from;
  void *col[IO_NSERIES];
  ves_status st = VES_OK;
  for (int i = 0; i < IO_NSERIES; i++) col[i] = NULL;
  for (int i = 0; i < IO_NSERIES && st == VES_OK && m > 0; i++) {
    if (io->series[i] < 0) continue; /* an optional column the file lacks */
    col[i] = malloc((size_t)m * col_size(io_series[i].type));
    st = !col[i] ? VES_ERR_ALLOC
                 : col_read(io->series[i], io_series[i].type, (hsize_t)from, (hsize_t)m, col[i]);
  }
  if (st == VES_OK && m > 0) io->series_sum = io_rows_sum(io->series_sum, col, m);
  for (int i = 0; i < IO_NSERIES; i++) free(col[i]);
  VES_CALL(st);
  io->summed_rows = rows;
  *out = io->series_sum;
  return VES_OK;
}

/* Attribute "codes" of the series' status: every ves_status value, typed by
 * an HDF5 enumeration of their names (h5dump and h5py show the names). */
static ves_status status_codes(hid_t obj) {
#define STATUS_VALUE_(name, value, msg) value,
  static const int values[] = {VES_STATUS_LIST(STATUS_VALUE_)};
#undef STATUS_VALUE_
#define STATUS_NAME_(name, value, msg) #name,
  static const char *const names[] = {VES_STATUS_LIST(STATUS_NAME_)};
#undef STATUS_NAME_
  const hsize_t count = sizeof values / sizeof values[0];
  hid_t t = H5Tenum_create(H5T_NATIVE_INT), sp = H5Screate_simple(1, &count, NULL), a = -1;
  herr_t e = t < 0 || sp < 0 ? -1 : 0;
  for (hsize_t i = 0; i < count && e >= 0; i++) e = H5Tenum_insert(t, names[i], &values[i]);
  if (e >= 0 && H5Aexists(obj, "codes") > 0) e = H5Adelete(obj, "codes");
  if (e >= 0) a = H5Acreate2(obj, "codes", t, sp, H5P_DEFAULT, H5P_DEFAULT);
  if (a < 0 || H5Awrite(a, t, values) < 0) e = -1;
  if (a >= 0) H5Aclose(a);
  if (sp >= 0) H5Sclose(sp);
  if (t >= 0) H5Tclose(t);
  return e < 0 ? VES_ERR_IO : VES_OK;
}

/* The extendible series datasets (empty): every column, or with `like` the
 * columns present there (like[i] >= 0: a salvaged copy keeps its source's
 * columns, and so its checksums). */
ves_status io_create_series(ves_io *io, const hid_t *like) {
  hid_t g = H5Gcreate2(io->file, "series", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  hsize_t zero = 0, unlim = H5S_UNLIMITED, chunk = IO_CHUNK;
  hid_t sp = H5Screate_simple(1, &zero, &unlim), dcpl = H5Pcreate(H5P_DATASET_CREATE);
  ves_status st = sp >= 0 && dcpl >= 0 && H5Pset_chunk(dcpl, 1, &chunk) >= 0 ? VES_OK : VES_ERR_IO;
  for (int i = 0; i < IO_NSERIES && st == VES_OK; i++) {
    if (like && like[i] < 0) continue;
    io->series[i] = H5Dcreate2(g, io_series[i].name, col_file_type(io_series[i].type), sp,
                               H5P_DEFAULT, dcpl, H5P_DEFAULT);
    if (io->series[i] < 0) st = VES_ERR_IO;
    if (st == VES_OK) st = io_describe(io->series[i], io_series[i].units, io_series[i].description);
    if (st == VES_OK && !strcmp(io_series[i].name, "status")) st = status_codes(io->series[i]);
  }
  if (st == VES_OK)
    st = io_describe(g, "per dataset",
                     "row 0 the initial state (step 0, t = 0), then one row per accepted step, "
                     "flushed after every step");
  if (dcpl >= 0) H5Pclose(dcpl);
  if (sp >= 0) H5Sclose(sp);
  H5Gclose(g);
  return st;
}

ves_status io_append_row(ves_io *io, const ves_io_row *row) {
  for (int i = 0; i < IO_NSERIES; i++) {
    hid_t d = io->series[i];
    if (d < 0) continue; /* an optional column the file lacks */
    hsize_t len = io_dset_len(d), one = 1, next = len + 1;
    if (H5Dset_extent(d, &next) < 0) return VES_ERR_IO;
    hid_t fs = H5Dget_space(d), ms = H5Screate_simple(1, &one, NULL);
    herr_t e =
        fs < 0 || ms < 0 ? -1 : H5Sselect_hyperslab(fs, H5S_SELECT_SET, &len, NULL, &one, NULL);
    if (e >= 0)
      e = H5Dwrite(d, io_col_mem_type(io_series[i].type), ms, fs, H5P_DEFAULT,
                   (const char *)row + io_series[i].offset);
    if (ms >= 0) H5Sclose(ms);
    if (fs >= 0) H5Sclose(fs);
    if (e < 0) return VES_ERR_IO;
  }
  return H5Fflush(io->file, H5F_SCOPE_LOCAL) < 0 ? VES_ERR_IO : VES_OK;
}

ves_status ves_io_append(ves_io *io, const ves_io_row *row) {
  VES_CHECK(io && row && io->writable, VES_ERR_ARG);
  errno = 0;
  ves_status st = io_provenance_pending(io);               /* a restart's, before its first row */
  if (st == VES_OK) st = io_reserve(io, io_row_bytes(io)); /* before HDF5 writes anything */
  if (st == VES_OK) st = io_row0_write(io);
  return io_failed(io, st == VES_OK ? io_append_row(io, row) : st, errno);
}

ves_status io_row0_write(ves_io *io) {
  if (!io->row0_pending) return VES_OK;
  VES_CALL(io_append_row(io, &io->row0_row));
  io->row0 = 1, io->row0_pending = 0;
  return VES_OK;
}

void ves_io_row_from_step(const ves_step_report *rep, int reconnections, double wall_seconds,
                          ves_io_row *row) {
  *row = (ves_io_row){.step = rep->step,
                      .t = rep->t,
                      .dt = rep->dt,
                      .E = rep->E,
                      .A = rep->A,
                      .V = rep->V,
                      .V_target = rep->V_target,
                      .lambda_A = rep->lambda[0],
                      .lambda_V = rep->lambda[1],
                      .c0 = rep->c0,
                      .iterations = rep->stats.iterations,
                      .f_evals = rep->stats.f_evals,
                      .g_evals = rep->stats.g_evals,
                      .h_evals = rep->stats.h_evals,
                      .violation = rep->stats.violation,
                      .solve_seconds = rep->stats.seconds,
                      .wall_seconds = wall_seconds,
                      .retries = rep->retries,
                      .status = rep->solve_status,
                      .reconnections = reconnections,
                      .factorizations = rep->stats.factorizations};
}

long ves_io_rows(const ves_io *io) {
  hsize_t rows = 0, one = 1;
  for (int i = 0; i < IO_NSERIES; i++) {
    if (io->series[i] < 0) continue; /* an optional column the file lacks ("t" never is) */
    hsize_t l = io_dset_len(io->series[i]);
    if (i == 0 || l < rows) rows = l;
  }
  /* a writer killed between extending "step" and writing it leaves the
   * fill value 0 there: that row is not complete */
  long step = 0;
  if (rows > 0) {
    hsize_t last = rows - 1;
    hid_t d = io->series[IO_NSERIES - 1], fs = H5Dget_space(d),
          ms = H5Screate_simple(1, &one, NULL);
    if (fs >= 0 && ms >= 0 && H5Sselect_hyperslab(fs, H5S_SELECT_SET, &last, NULL, &one, NULL) >= 0)
      H5Dread(d, H5T_NATIVE_LONG, ms, fs, H5P_DEFAULT, &step);
    if (ms >= 0) H5Sclose(ms);
    if (fs >= 0) H5Sclose(fs);
    if (step != (long)rows - io->row0) rows--;
  }
  return (long)rows - (rows > 0 ? io->row0 : 0);
}

ves_status ves_io_truncate(ves_io *io, long rows) {
  VES_CHECK(io && io->writable && rows >= 0, VES_ERR_ARG);
  rows += io->row0; /* the row of the initial state stays */
  hsize_t r = (hsize_t)rows;
  if (io->summed_rows > rows) io->summed_rows = 0, io->series_sum = FNV_START;
  for (int i = 0; i < IO_NSERIES; i++) {
    if (io->series[i] < 0) continue; /* an optional column the file lacks */
    if (io_dset_len(io->series[i]) < r) return VES_ERR_ARG;
    if (H5Dset_extent(io->series[i], &r) < 0) return VES_ERR_IO;
  }
  return H5Fflush(io->file, H5F_SCOPE_LOCAL) < 0 ? VES_ERR_IO : VES_OK;
}

const char *ves_io_series_name(int i) {
  return i >= 0 && i < IO_NSERIES ? io_series[i].name : NULL;
}

/* Series `name`: `rows` rows of its dataset from row `first` on. */
static ves_status read_series_from(ves_io *io, const char *name, hsize_t first, hsize_t rows,
                                   double *out) {
  VES_CHECK(io && name && out, VES_ERR_ARG);
  int i = 0;
  while (i < IO_NSERIES && strcmp(io_series[i].name, name)) i++;
  VES_CHECK(i < IO_NSERIES, VES_ERR_ARG);
  if (rows == 0) return VES_OK;
  if (io->series[i] < 0) { /* an optional column the file lacks */
    for (hsize_t r = 0; r < rows; r++) out[r] = -1;
    return VES_OK;
  }
  hid_t fs = H5Dget_space(io->series[i]), ms = H5Screate_simple(1, &rows, NULL);
  herr_t e =
      fs < 0 || ms < 0 ? -1 : H5Sselect_hyperslab(fs, H5S_SELECT_SET, &first, NULL, &rows, NULL);
  if (e >= 0) e = H5Dread(io->series[i], H5T_NATIVE_DOUBLE, ms, fs, H5P_DEFAULT, out);
  if (ms >= 0) H5Sclose(ms);
  if (fs >= 0) H5Sclose(fs);
  return e < 0 ? VES_ERR_IO : VES_OK;
}

ves_status ves_io_read_series(ves_io *io, const char *name, double *out) {
  VES_CHECK(io, VES_ERR_ARG);
  return read_series_from(io, name, (hsize_t)io->row0, (hsize_t)ves_io_rows(io), out);
}

int ves_io_initial_row(const ves_io *io) {
  return io && io->row0 && io_dset_len(io->series[0]) > 0;
}

ves_status ves_io_read_series_all(ves_io *io, const char *name, double *out) {
  VES_CHECK(io, VES_ERR_ARG);
  return read_series_from(io, name, 0, (hsize_t)(ves_io_rows(io) + ves_io_initial_row(io)), out);
}

/* The summary's columns, read by name (ves_io_summarize). */
enum {
  S_T,
  S_DT,
  S_E,
  S_A,
  S_V,
  S_VT,
  S_ITER,
  S_HEV,
  S_RETRIES,
  S_RECONN,
  S_WALL,
  S_C0,
  S_FACT,
  NSUM
};
static const char *const SUM_COLS[NSUM] = {"t",
                                           "dt",
                                           "E",
                                           "A",
                                           "V",
                                           "V_target",
                                           "iterations",
                                           "h_evals",
                                           "retries",
                                           "reconnections",
                                           "wall_seconds",
                                           "c0",
                                           "factorizations"};

/* The statistics of the rows col[NSUM][R] into s (E0, A0, V0 the header's,
 * c0 the problem's initial C0). */
static void summarize(const ves_io_info *in, double c0, long R, double *const *col,
                      ves_io_summary *s) {
  const double *E = col[S_E], *A = col[S_A], *V = col[S_V], *Vt = col[S_VT], *C = col[S_C0];
  *s = (ves_io_summary){
      .steps = R, .energy_monotone = 1, .E_final = in->E0, .A_final = in->A0, .V_final = in->V0};
  for (long i = 0; i < R; i++) {
    /* compared only across steps on the same landscape: a C0 switch or a
     * moving volume target may raise E (the integrator's own rule) */
    double Eprev = i ? E[i - 1] : in->E0;
    double c0prev = i ? C[i - 1] : c0, Vtprev = i ? Vt[i - 1] : in->V0;
    if (C[i] == c0prev && fabs(Vt[i] - Vtprev) <= 1e-14 * in->V0 &&
        E[i] > Eprev + VES_IO_MONOTONE_TOL * fabs(Eprev))
      s->energy_monotone = 0;
    s->area_drift_max = fmax(s->area_drift_max, fabs(A[i] / in->A0 - 1));
    s->volume_drift_max = fmax(s->volume_drift_max, fabs(V[i] / Vt[i] - 1));
    s->dt_largest = fmax(s->dt_largest, col[S_DT][i]);
    s->iterations += col[S_ITER][i], s->h_evals += col[S_HEV][i];
    s->retries += col[S_RETRIES][i];
    s->factorizations += col[S_FACT][i];
  }
  if (R > 0) {
    s->t_final = col[S_T][R - 1], s->E_final = E[R - 1];
    s->A_final = A[R - 1], s->V_final = V[R - 1], s->dt_first = col[S_DT][0];
    s->reconnections = col[S_RECONN][R - 1], s->wall_seconds = col[S_WALL][R - 1];
  }
}

ves_status ves_io_summarize(ves_io *io, double c0, ves_io_summary *s) {
  VES_CHECK(io && s, VES_ERR_ARG);
  const long R = ves_io_rows(io);
  double *col[NSUM] = {0};
  ves_status st = VES_OK;
  for (int c = 0; c < NSUM && st == VES_OK; c++) {
    col[c] = malloc((size_t)(R > 0 ? R : 1) * sizeof *col[c]);
    st = !col[c] ? VES_ERR_ALLOC : ves_io_read_series(io, SUM_COLS[c], col[c]);
  }
  if (st == VES_OK) summarize(&io->info, c0, R, col, s);
  for (int i = 0; i < IO_NSERIES; i++) /* the optional column absent: not recorded */
    if (io->series[i] < 0 && io_col_optional(i)) s->factorizations = -1;
  for (int c = 0; c < NSUM; c++) free(col[c]);
  return st;
}

/* The series as text, in the columns of vesica info --series: every column
 * of the file (the first IO_NSERIES of io_series) under its file name,
 * "step" first, then the file's order; each value with 12 significant
 * digits (%.12g of the value as a double, as vesica info prints the file's
 * rows), so the text of a row and info's line of it are the same. */
static const series_spec *text_column(int k) {
  return k < 0 || k >= IO_NSERIES ? NULL : io_series + (k + IO_NSERIES - 1) % IO_NSERIES;
}

const char *ves_io_text_column(int k) {
  const series_spec *c = text_column(k);
  return c ? c->name : NULL;
}

ves_status ves_io_text_header(FILE *f) {
  VES_CHECK(f, VES_ERR_ARG);
  int e = 0;
  for (int k = 0; text_column(k); k++)
    e |= fprintf(f, "%s%s", k ? "\t" : "", text_column(k)->name) < 0;
  e |= fputc('\n', f) == EOF;
  return e ? VES_ERR_IO : VES_OK;
}

ves_status ves_io_text_row(FILE *f, const ves_io_row *row) {
  VES_CHECK(f && row, VES_ERR_ARG);
  int e = 0;
  for (int k = 0; text_column(k); k++) {
    const series_spec *c = text_column(k);
    const char *p = (const char *)row + c->offset;
    double v;
    if (c->type == COL_LONG) {
      long l;
      memcpy(&l, p, sizeof l);
      v = (double)l;
    } else if (c->type == COL_INT) {
      int i;
      memcpy(&i, p, sizeof i);
      v = i;
    } else {
      memcpy(&v, p, sizeof v);
    }
    e |= fprintf(f, "%s%.12g", k ? "\t" : "", v) < 0;
  }
  e |= fputc('\n', f) == EOF;
  return e ? VES_ERR_IO : VES_OK;
}
