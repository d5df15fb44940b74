/* vesica — run output in HDF5 (+ XDMF): header, typed parameters, reference
 * mesh, per-step series appended and flushed step by step, snapshots with the
 * integrator state for restart. Layout: solver/app/io.h. */
#include "app/io.h"

#include <errno.h>
#include <hdf5.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#define IO_CHUNK 512 /* rows per chunk of a series (4 KiB of doubles) */

typedef enum { COL_LONG, COL_INT, COL_DOUBLE } col_type;

/* How a column of the --series text shows its field (ves_io_tsv_row). */
typedef enum {
  TSV_NONE,  /* not in the text */
  TSV_VALUE, /* the field */
  TSV_OF_A0, /* field / A0 - 1 (the area's drift) */
  TSV_OF_VT, /* field / V_target - 1 (the volume's drift) */
} tsv_kind;

/* The per-step row, one table of columns for the file's series (create,
 * append, truncate, read, checksum: in this order) and the --series text
 * (its own order, tsv = 1, 2, ...; its header names and formats). The last
 * NTSV_ONLY columns are in the text only. */
typedef struct {
  const char *name;
  col_type type;
  size_t offset;                   /* into ves_io_row */
  const char *units, *description; /* the dataset's attributes */
  int tsv;                         /* column of the text (1-based; 0: not in it) */
  tsv_kind how;                    /* how the text shows it */
  const char *tsv_name, *tsv_fmt;  /* the text's header name and printf format */
} series_spec;

#define ROW(f) offsetof(ves_io_row, f)
/* "step" comes last in the file: a row is complete once its step is written
 * (rows i holds step i + 1; ves_io_rows checks it). */
#define STATUS_DOC_ "ves_status of the accepted solve: " VES_STATUS_LIST(STATUS_DOC_ITEM_)
#define STATUS_DOC_ITEM_(name, value, msg) #value " " msg "; "
#define V_ TSV_VALUE
/* one column a line, a table to read across (clang-format would break the lines) */
// clang-format off
static const series_spec SERIES[] = {
    {"t", COL_DOUBLE, ROW(t), "t*", "time at the end of the step, t* = t k/(mu R0^3)", 2, V_, "t", "%.9g"},
    {"dt", COL_DOUBLE, ROW(dt), "t*", "accepted time step", 3, V_, "dt", "%.6g"},
    {"E", COL_DOUBLE, ROW(E), "k", "energy the steps minimize, in model units (E* = E/k with [material] k): bending energy plus the stabilization E_s ([geometry] stabilization; 0 after a reset)", 4, V_, "E", "%.12g"},
    {"A", COL_DOUBLE, ROW(A), "R0^2", "area of the phase-field vesicle", 5, TSV_OF_A0, "A/A0-1", "%.3e"},
    {"V", COL_DOUBLE, ROW(V), "R0^3", "enclosed volume of the phase-field vesicle", 6, TSV_OF_VT, "V/Vt-1", "%.3e"},
    {"V_target", COL_DOUBLE, ROW(V_target), "R0^3", "volume the step held (V0, or the protocol's ramp)", 0, TSV_NONE, NULL, NULL},
    {"lambda_A", COL_DOUBLE, ROW(lambda_A), "k/R0^2", "multiplier of the area constraint (tension)", 7, V_, "lambda_A", "%.9g"},
    {"lambda_V", COL_DOUBLE, ROW(lambda_V), "k/R0^3", "multiplier of the volume constraint (pressure)", 8, V_, "lambda_V", "%.9g"},
    {"c0", COL_DOUBLE, ROW(c0), "1/R0", "spontaneous curvature C0 in force during the step", 0, TSV_NONE, NULL, NULL},
    {"iterations", COL_INT, ROW(iterations), "1", "solver iterations of the accepted attempt", 9, V_, "iter", "%d"},
    {"f_evals", COL_INT, ROW(f_evals), "1", "energy evaluations of the accepted attempt", 10, V_, "f", "%d"},
    {"g_evals", COL_INT, ROW(g_evals), "1", "gradient evaluations of the accepted attempt", 11, V_, "g", "%d"},
    {"h_evals", COL_INT, ROW(h_evals), "1", "Hessian evaluations of the accepted attempt", 12, V_, "h", "%d"},
    {"violation", COL_DOUBLE, ROW(violation), "1", "constraint violation, relative to A0 and V", 0, TSV_NONE, NULL, NULL},
    {"solve_seconds", COL_DOUBLE, ROW(solve_seconds), "s", "wall time of the accepted solve", 13, V_, "seconds", "%.3f"},
    {"wall_seconds", COL_DOUBLE, ROW(wall_seconds), "s", "wall time of the run's time loop so far", 0, TSV_NONE, NULL, NULL},
    {"retries", COL_INT, ROW(retries), "1", "rejected attempts before the accepted one (each at dt/2)", 14, V_, "retries", "%d"},
    {"status", COL_INT, ROW(status), "1", STATUS_DOC_, 0, TSV_NONE, NULL, NULL},
    {"reconnections", COL_INT, ROW(reconnections), "1", "resets of the reference configuration so far", 15, V_, "resets", "%d"},
    {"factorizations", COL_INT, ROW(factorizations), "1", "KKT factorizations of the accepted attempt, each rung of an inertia correction one (newton, euler; 0 for ipopt and nlopt, which do not report theirs); absent in files written before 2026-12-05 (read as -1)", 18, V_, "factorizations", "%d"},
    {"step", COL_LONG, ROW(step), "1", "accepted step number (row i holds step i + 1; written last: a row is complete once its step is)", 1, V_, "step", "%ld"},
    /* the text only */
    {"rejected_iterations", COL_INT, ROW(rejected_iterations), "1", "iterations of the attempts rejected before the accepted one", 16, V_, "rejected_iterations", "%d"},
    {"rejected_seconds", COL_DOUBLE, ROW(rejected_seconds), "s", "wall time of those attempts", 17, V_, "rejected_seconds", "%.3f"},
};
// clang-format on
#undef V_
#define NTSV_ONLY 2
#define NCOLS ((int)(sizeof SERIES / sizeof SERIES[0]))
#define NSERIES (NCOLS - NTSV_ONLY) /* columns in the file */

/* A column added to format_version 2 after its first files were written: an
 * older file lacks it (its handle -1 once opened), and appends,
 * truncations, checksums and salvaged copies pass it by; ves_io_read_series
 * reads it as -1. */
static int col_optional(int i) { return !strcmp(SERIES[i].name, "factorizations"); }

struct ves_io {
  hid_t file;               /* the HDF5 file */
  int writable;             /* opened for writing */
  char path[PATH_MAX];      /* the HDF5 file */
  char xdmf[PATH_MAX];      /* the XDMF file beside it */
  hid_t series[NSERIES];    /* open series datasets */
  ves_io_info info;         /* header */
  int nsnap;                /* complete snapshots */
  double *snap_t;           /* nsnap times (for the XDMF file) */
  int snap_cap;             /* capacity of snap_t */
  char error[2 * PATH_MAX]; /* the cause of the last failed write ("" none) */
  uint64_t series_sum;      /* checksum of the first summed_rows series rows */
  long summed_rows;         /* rows in series_sum */
  int tolerant;             /* salvage: count the snapshots up to the first unreadable one */
};

/* HDF5 prints its error stack by default: the library stays silent. Its
 * exit-time cleanup is declined: after a failed write (a full disk) H5Fclose
 * fails and leaves the file half-closed, and that cleanup then crashes
 * (SIGSEGV in H5F__close_cb, HDF5 1.10.8); every file is closed explicitly
 * anyway. H5dont_atexit acts only as the process's first HDF5 call (vesica's
 * case) and is otherwise a harmless no-op. */
static void quiet_hdf5(void) {
  H5dont_atexit();
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
}

/* H5Ewalk2 callback: the system's reason of the innermost failing file
 * operation, from the sec2 driver's "..., errno = 28, error message = 'No
 * space left on device', ..." (errno itself does not survive HDF5's error
 * handling). */
static herr_t sys_reason(unsigned n, const H5E_error2_t *e, void *data) {
  (void)n;
  char *out = data;
  const char *p = e->desc ? strstr(e->desc, "error message = '") : NULL;
  if (p && !out[0]) {
    p += strlen("error message = '");
    snprintf(out, 128, "%.*s", (int)strcspn(p, "'"), p);
  }
  return 0;
}

/* H5Ewalk2 callback: the description of the innermost error that says why
 * a file cannot be opened ("truncated file: eof = ..., stored_eof = ..."). */
static herr_t hdf5_reason(unsigned n, const H5E_error2_t *e, void *data) {
  char *out = data;
  if (n == 0 && e->desc) snprintf(out, 128, "%s", e->desc);
  if (e->desc && strstr(e->desc, "truncated")) snprintf(out, 128, "%s", e->desc);
  return 0;
}

/* Record the cause of a failed write: the system's reason from HDF5's error
 * stack, errno as the failing write left it (the XDMF file), or the status. */
static ves_status io_failed(ves_io *io, ves_status st, int errnum) {
  if (st == VES_OK || st == VES_ERR_ALLOC) return st;
  char reason[128] = "";
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, sys_reason, reason);
  snprintf(io->error, sizeof io->error, "%s",
           reason[0] ? reason
           : errnum  ? strerror(errnum)
                     : ves_status_str(st));
  return st;
}

/* ---- checksums ------------------------------------------------------------ */

/* FNV-1a (64 bits) over the bytes of data, continuing from h (FNV_START to
 * begin). Snapshots and references carry one over their data and state, so
 * that a salvage (ves_io_salvage) tells a member whose blocks survived from
 * one whose blocks were lost and read back as zeros. */
#define FNV_START 0xcbf29ce484222325ULL
static uint64_t fnv(uint64_t h, const void *data, size_t len) {
  const unsigned char *p = data;
  for (size_t i = 0; i < len; i++) h = (h ^ p[i]) * 0x100000001b3ULL;
  return h;
}

/* ---- attributes ----------------------------------------------------------- */

/* A scalar attribute; one of the same type is overwritten in place, so the
 * object header neither grows nor moves to the end of the file (where a
 * torn last write would take it: ves_io_salvage reads the header). */
static ves_status attr_write(hid_t obj, const char *name, hid_t ftype, hid_t mtype, const void *v) {
  if (H5Aexists(obj, name) > 0) {
    hid_t a = H5Aopen(obj, name, H5P_DEFAULT), t = a < 0 ? -1 : H5Aget_type(a);
    const htri_t same = t < 0 ? -1 : H5Tequal(t, ftype);
    const herr_t e = same > 0 ? H5Awrite(a, mtype, v) : 0;
    if (t >= 0) H5Tclose(t);
    if (a >= 0) H5Aclose(a);
    if (same > 0) return e < 0 ? VES_ERR_IO : VES_OK;
    if (H5Adelete(obj, name) < 0) return VES_ERR_IO;
  }
  hid_t sp = H5Screate(H5S_SCALAR);
  hid_t a = sp < 0 ? -1 : H5Acreate2(obj, name, ftype, sp, H5P_DEFAULT, H5P_DEFAULT);
  herr_t e = a < 0 ? -1 : H5Awrite(a, mtype, v);
  if (a >= 0) H5Aclose(a);
  if (sp >= 0) H5Sclose(sp);
  return e < 0 ? VES_ERR_IO : VES_OK;
}

static ves_status attr_double(hid_t obj, const char *name, double v) {
  return attr_write(obj, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &v);
}

static ves_status attr_int(hid_t obj, const char *name, int v) {
  return attr_write(obj, name, H5T_STD_I32LE, H5T_NATIVE_INT, &v);
}

static ves_status attr_long(hid_t obj, const char *name, long v) {
  return attr_write(obj, name, H5T_STD_I64LE, H5T_NATIVE_LONG, &v);
}

static ves_status attr_u64(hid_t obj, const char *name, uint64_t v) {
  return attr_write(obj, name, H5T_STD_U64LE, H5T_NATIVE_UINT64, &v);
}

/* A fixed-length, NUL-terminated string attribute of size bytes (s and
 * zeros; at least strlen(s) + 1). */
static ves_status attr_str_size(hid_t obj, const char *name, const char *s, size_t size) {
  const size_t len = strlen(s) + 1 > size ? strlen(s) + 1 : size;
  char *buf = calloc(len, 1);
  hid_t t = buf ? H5Tcopy(H5T_C_S1) : -1;
  ves_status st = buf ? VES_ERR_IO : VES_ERR_ALLOC;
  if (buf) memcpy(buf, s, strlen(s));
  if (t >= 0 && H5Tset_size(t, len) >= 0 && H5Tset_strpad(t, H5T_STR_NULLTERM) >= 0)
    st = attr_write(obj, name, t, t, buf);
  if (t >= 0) H5Tclose(t);
  free(buf);
  return st;
}

static ves_status attr_str(hid_t obj, const char *name, const char *s) {
  return attr_str_size(obj, name, s, 0);
}

/* The root attribute status: 16 bytes whatever its value, rewritten in place. */
static ves_status attr_status(hid_t file, const char *status) {
  return attr_str_size(file, "status", status, sizeof((ves_io_info *)0)->status);
}

/* The attributes `units` and `description` every group and dataset carries
 * (added in format_version 2 files without a bump: readers need neither). */
static ves_status describe(hid_t obj, const char *units, const char *description) {
  VES_CALL(attr_str(obj, "units", units));
  return attr_str(obj, "description", description);
}

/* The same on the object at `path` below loc. */
static ves_status describe_at(hid_t loc, const char *path, const char *units,
                              const char *description) {
  hid_t o = H5Oopen(loc, path, H5P_DEFAULT);
  if (o < 0) return VES_ERR_IO;
  ves_status st = describe(o, units, description);
  H5Oclose(o);
  return st;
}

/* Whether the type of a dataset (is_attr = 0) or attribute (1) is one of
 * the numeric types this module writes (IEEE f64, signed 32- and 64-bit,
 * unsigned 64-bit integers, little-endian), between which HDF5 converts
 * safely. Data of any other type is refused unread: a damaged type message
 * (a float with a 51-bit mantissa, say) sends HDF5's conversion code far
 * past its buffers (HDF5 1.10.8, H5T__conv_f_f; found by
 * tests/fuzz/fuzz_h5.c). */
static int numeric_type_ok(hid_t obj, int is_attr) {
  hid_t t = is_attr ? H5Aget_type(obj) : H5Dget_type(obj);
  const hid_t ours[] = {H5T_IEEE_F64LE, H5T_STD_I32LE, H5T_STD_I64LE, H5T_STD_U64LE};
  int ok = 0;
  for (size_t i = 0; t >= 0 && i < sizeof ours / sizeof ours[0] && !ok; i++)
    ok = H5Tequal(t, ours[i]) > 0;
  if (t >= 0) H5Tclose(t);
  return ok;
}

static ves_status attr_read(hid_t obj, const char *name, hid_t mtype, void *v) {
  if (H5Aexists(obj, name) <= 0) return VES_ERR_CONFIG;
  hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  if (a < 0) return VES_ERR_IO;
  if (!numeric_type_ok(a, 1)) {
    H5Aclose(a);
    return VES_ERR_CONFIG;
  }
  herr_t e = H5Aread(a, mtype, v);
  H5Aclose(a);
  return e < 0 ? VES_ERR_IO : VES_OK;
}

static ves_status attr_read_double(hid_t obj, const char *name, double *v) {
  return attr_read(obj, name, H5T_NATIVE_DOUBLE, v);
}

/* A string attribute, malloc'd (taken by the caller). */
static ves_status attr_read_str(hid_t obj, const char *name, char **out) {
  *out = NULL;
  if (H5Aexists(obj, name) <= 0) return VES_ERR_CONFIG;
  hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  if (a < 0) return VES_ERR_IO;
  ves_status st = VES_ERR_IO;
  hid_t ft = H5Aget_type(a), mt = -1;
  if (ft >= 0 && H5Tget_class(ft) == H5T_STRING && !H5Tis_variable_str(ft)) {
    size_t len = H5Tget_size(ft);
    char *s = calloc(len + 1, 1);
    mt = H5Tcopy(H5T_C_S1);
    if (!s)
      st = VES_ERR_ALLOC;
    else if (mt >= 0 && H5Tset_size(mt, len + 1) >= 0 && H5Aread(a, mt, s) >= 0)
      *out = s, st = VES_OK;
    if (st != VES_OK) free(s);
  }
  if (mt >= 0) H5Tclose(mt);
  if (ft >= 0) H5Tclose(ft);
  H5Aclose(a);
  return st;
}

/* Into a fixed buffer (truncated to fit). */
static ves_status attr_read_buf(hid_t obj, const char *name, char *buf, size_t len) {
  char *s;
  VES_CALL(attr_read_str(obj, name, &s));
  snprintf(buf, len, "%s", s);
  free(s);
  return VES_OK;
}

/* ---- datasets ------------------------------------------------------------- */

/* A contiguous dataset of rank 1 or 2 (dims[1] = 0 for rank 1), written once. */
static ves_status dset_write(hid_t loc, const char *name, hid_t ftype, hid_t mtype, hsize_t d0,
                             hsize_t d1, const void *data) {
  hsize_t dims[2] = {d0, d1};
  hid_t sp = H5Screate_simple(d1 ? 2 : 1, dims, NULL);
  hid_t d = sp < 0 ? -1 : H5Dcreate2(loc, name, ftype, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  herr_t e = d < 0 ? -1 : H5Dwrite(d, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, data);
  if (d >= 0) H5Dclose(d);
  if (sp >= 0) H5Sclose(sp);
  return e < 0 ? VES_ERR_IO : VES_OK;
}

/* Read a whole dataset of exactly `count` elements. */
static ves_status dset_read(hid_t loc, const char *name, hid_t mtype, hsize_t count, void *data) {
  hid_t d = H5Dopen2(loc, name, H5P_DEFAULT);
  if (d < 0) return VES_ERR_IO;
  ves_status st = VES_ERR_IO;
  hid_t sp = H5Dget_space(d);
  if (sp >= 0 && (hsize_t)H5Sget_simple_extent_npoints(sp) == count && numeric_type_ok(d, 0) &&
      H5Dread(d, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) >= 0)
    st = VES_OK;
  if (sp >= 0) H5Sclose(sp);
  H5Dclose(d);
  return st;
}

static hsize_t dset_len(hid_t d) {
  hsize_t dims[1] = {0};
  hid_t sp = H5Dget_space(d);
  if (sp < 0) return 0;
  if (H5Sget_simple_extent_ndims(sp) != 1 || H5Sget_simple_extent_dims(sp, dims, NULL) < 0)
    dims[0] = 0;
  H5Sclose(sp);
  return dims[0];
}

static hid_t col_file_type(col_type t) {
  return t == COL_LONG ? H5T_STD_I64LE : t == COL_INT ? H5T_STD_I32LE : H5T_IEEE_F64LE;
}

static hid_t col_mem_type(col_type t) {
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
  if (e >= 0) e = H5Dread(d, col_mem_type(t), ms, fs, H5P_DEFAULT, buf);
  if (ms >= 0) H5Sclose(ms);
  if (fs >= 0) H5Sclose(fs);
  return e < 0 ? VES_ERR_IO : VES_OK;
}

/* The series checksum continued over m rows held column by column in
 * col[NSERIES]: row by row, each row's values in the order of SERIES (a
 * column the file lacks, col[i] NULL, passed by). */
static uint64_t rows_sum(uint64_t h, void *const *col, long m) {
  for (long r = 0; r < m; r++)
    for (int i = 0; i < NSERIES; i++) {
      if (!col[i]) continue;
      const size_t sz = col_size(SERIES[i].type);
      h = fnv(h, (const char *)col[i] + (size_t)r * sz, sz);
    }
  return h;
}

/* Read the first `rows` rows of every series into col[] (malloc'd, taken
 * by the caller; freed and NULL on failure). */
static ves_status cols_read(hid_t const *series, long rows, void **col) {
  ves_status st = VES_OK;
  for (int i = 0; i < NSERIES; i++) col[i] = NULL;
  for (int i = 0; i < NSERIES && st == VES_OK; i++) {
    if (series[i] < 0) continue; /* an optional column the file lacks */
    col[i] = malloc((size_t)(rows > 0 ? rows : 1) * col_size(SERIES[i].type));
    st = !col[i] ? VES_ERR_ALLOC : col_read(series[i], SERIES[i].type, 0, (hsize_t)rows, col[i]);
  }
  if (st != VES_OK)
    for (int i = 0; i < NSERIES; i++) free(col[i]), col[i] = NULL;
  return st;
}

/* The checksum of the first `rows` rows of the series (extended over the
 * rows written since the last call; recomputed after a truncation). */
static ves_status series_sum(ves_io *io, long rows, uint64_t *out) {
  if (io->summed_rows > rows) io->summed_rows = 0, io->series_sum = FNV_START;
  const long from = io->summed_rows, m = rows - from;
  void *col[NSERIES];
  ves_status st = VES_OK;
  for (int i = 0; i < NSERIES; i++) col[i] = NULL;
  for (int i = 0; i < NSERIES && st == VES_OK && m > 0; i++) {
    if (io->series[i] < 0) continue; /* an optional column the file lacks */
    col[i] = malloc((size_t)m * col_size(SERIES[i].type));
    st = !col[i] ? VES_ERR_ALLOC
                 : col_read(io->series[i], SERIES[i].type, (hsize_t)from, (hsize_t)m, col[i]);
  }
  if (st == VES_OK && m > 0) io->series_sum = rows_sum(io->series_sum, col, m);
  for (int i = 0; i < NSERIES; i++) free(col[i]);
  VES_CALL(st);
  io->summed_rows = rows;
  *out = io->series_sum;
  return VES_OK;
}

/* The checksum of a snapshot: y, x, phi (n nodes) and every stored field of si. */
static uint64_t snap_sum(long n, const double *y, const double *x, const double *phi,
                         const double *y_prev, const ves_io_snapinfo *si) {
  const ves_sim_state *s = &si->state;
  const double d[] = {s->t,          s->dt, s->E,         s->A,         s->V,  s->E0,
                      s->A0,         s->V0, s->lambda[0], s->lambda[1], s->c0, si->wall_seconds,
                      s->dt_rejected};
  const long l[] = {s->nstep, si->rows, s->since_rejected, si->reconnections};
  uint64_t h = fnv(FNV_START, y, 2 * (size_t)n * sizeof *y);
  h = fnv(h, x, 2 * (size_t)n * sizeof *x);
  h = fnv(h, phi, (size_t)n * sizeof *phi);
  h = fnv(h, d, sizeof d);
  h = fnv(h, l, sizeof l);
  if (s->dt_prev > 0) { /* the predictor's state (absent from older files: their sums stand) */
    h = fnv(h, &s->dt_prev, sizeof s->dt_prev);
    h = fnv(h, y_prev, 2 * (size_t)n * sizeof *y_prev);
  }
  return h;
}

/* The checksum of a reference: its data (n nodes, nq points) and step. */
static uint64_t ref_sum(long n, long nq, const double *x, const double *h_, const double *xq,
                        const double *wq, const double *pd, long step) {
  uint64_t h = fnv(FNV_START, x, 2 * (size_t)n * sizeof *x);
  h = fnv(h, h_, (size_t)n * sizeof *h_);
  h = fnv(h, xq, 2 * (size_t)nq * sizeof *xq);
  h = fnv(h, wq, (size_t)nq * sizeof *wq);
  h = fnv(h, pd, 6 * (size_t)nq * sizeof *pd);
  return fnv(h, &step, sizeof step);
}

/* ---- XDMF ------------------------------------------------------------------ */

void ves_io_xdmf_path(const char *h5path, char *out, size_t len) {
  size_t l = strlen(h5path);
  if (l > 3 && !strcmp(h5path + l - 3, ".h5"))
    snprintf(out, len, "%.*s.xdmf", (int)(l - 3), h5path);
  else
    snprintf(out, len, "%s.xdmf", h5path);
}

int ves_io_xdmf_name_ok(const char *h5path, char *why, size_t len) {
  const char *slash = strrchr(h5path, '/');
  const unsigned char *b = (const unsigned char *)(slash ? slash + 1 : h5path), *p = b;
  const char *bad = NULL;
  for (; *p && !bad; p++) {
    int more = *p < 0x80             ? 0
               : (*p & 0xe0) == 0xc0 ? 1
               : (*p & 0xf0) == 0xe0 ? 2
               : (*p & 0xf8) == 0xf0 ? 3
                                     : -1;
    for (int i = 1; i <= more && more > 0; i++)
      if ((p[i] & 0xc0) != 0x80) more = -1;
    if (more < 0 || (more == 1 && *p < 0xc2))
      bad = "a byte that is not UTF-8 (XML files are)";
    else if (*p == ':')
      bad = "':' (XDMF readers split NAME:/dataset at ':')";
    else if (*p == '|')
      bad = "'|' (XDMF readers split a data item's text at '|')";
    else if (*p < 0x20 || *p == 0x7f)
      bad = "a control character (XML files cannot hold it)";
    else if (p == b && *p == ' ')
      bad = "a leading space (XDMF readers strip it from the data item)";
    else if (more > 0)
      p += more;
  }
  if (bad && why) snprintf(why, len, "its name holds %s", bad);
  return !bad;
}

/* Text with the XML special characters escaped. */
static void xml_text(FILE *f, const char *s) {
  for (; *s; s++) {
    if (*s == '&')
      fputs("&amp;", f);
    else if (*s == '<')
      fputs("&lt;", f);
    else if (*s == '>')
      fputs("&gt;", f);
    else if (*s == '"')
      fputs("&quot;", f);
    else
      fputc(*s, f);
  }
}

static void xdmf_item(FILE *f, const char *h5, const char *dims, const char *num, int prec,
                      const char *dset) {
  fprintf(f, "     <DataItem Dimensions=\"%s\" NumberType=\"%s\" Precision=\"%d\" Format=\"HDF\">",
          dims, num, prec);
  xml_text(f, h5);
  fprintf(f, ":%s</DataItem>\n", dset);
}

static int nodes_now(const ves_io *io);

/* Two temporal collections over the snapshots: the nodes alone as points,
 * and the reference triangles at the material positions x of their nodes,
 * with phi and, from the second snapshot on, the flow (velocity) at the
 * nodes (XDMF 3 with the XDMF 2 attribute names, which ParaView's
 * readers and meshio's time-series reader take; meshio reads the last
 * collection). Written to a temporary name and renamed, so a reader never
 * sees half a file. */
static ves_status xdmf_write(const ves_io *io) {
  const char *slash = strrchr(io->path, '/');
  const char *h5 = slash ? slash + 1 : io->path; /* relative: the pair moves together */
  if (!ves_io_xdmf_name_ok(io->path, NULL, 0)) return VES_ERR_ARG; /* never a broken XDMF */
  char tmp[PATH_MAX + 8], dims[64];
  snprintf(tmp, sizeof tmp, "%s.tmp", io->xdmf);
  FILE *f = fopen(tmp, "w");
  if (!f) return VES_ERR_IO;
  fprintf(f, "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n"
             "<Xdmf Version=\"3.0\">\n <Domain>\n");
  for (int pass = 1; pass >= 0; pass--) { /* meshio reads the last collection: the mesh */
    fprintf(f, "  <Grid Name=\"%s\" GridType=\"Collection\" CollectionType=\"Temporal\">\n",
            pass ? "nodes" : "mesh");
    for (int k = 0; k < io->nsnap; k++) {
      char y[64], phi[64], tri[64] = "/mesh/triangles", vert[64] = "/mesh/vertices";
      int n = io->info.n, nt = io->info.ntri;
      const int j = ves_io_snapshot_mesh(io, k, &n, &nt); /* after remeshings: their node sets */
      if (j >= 0) {
        snprintf(tri, sizeof tri, "/remeshes/%d/triangles", j);
        snprintf(vert, sizeof vert, "/remeshes/%d/vertices", j);
      }
      snprintf(y, sizeof y, "/snapshots/%d/x", k);
      snprintf(phi, sizeof phi, "/snapshots/%d/phi", k);
      fprintf(f, "   <Grid Name=\"%s_%d\" GridType=\"Uniform\">\n    <Time Value=\"%.17g\"/>\n",
              pass ? "nodes" : "mesh", k, io->snap_t[k]);
      if (pass == 0) {
        fprintf(f,
                "    <Topology TopologyType=\"Triangle\" NumberOfElements=\"%d\" "
                "NodesPerElement=\"3\">\n",
                nt);
        snprintf(dims, sizeof dims, "%d 3", nt);
        xdmf_item(f, h5, dims, "Int", 4, tri);
      } else {
        fprintf(f,
                "    <Topology TopologyType=\"Polyvertex\" NumberOfElements=\"%d\" "
                "NodesPerElement=\"1\">\n",
                n);
        snprintf(dims, sizeof dims, "%d", n);
        xdmf_item(f, h5, dims, "Int", 4, vert);
      }
      fprintf(f, "    </Topology>\n    <Geometry GeometryType=\"XY\">\n");
      snprintf(dims, sizeof dims, "%d 2", n);
      xdmf_item(f, h5, dims, "Float", 8, y);
      fprintf(f, "    </Geometry>\n    <Attribute Name=\"phi\" AttributeType=\"Scalar\" "
                 "Center=\"Node\">\n");
      snprintf(dims, sizeof dims, "%d", n);
      xdmf_item(f, h5, dims, "Float", 8, phi);
      fprintf(f, "    </Attribute>\n");
      char v[64];
      snprintf(v, sizeof v, "/snapshots/%d/velocity", k);
      if (H5Lexists(io->file, v, H5P_DEFAULT) > 0) { /* not the first snapshot's */
        fprintf(f, "    <Attribute Name=\"velocity\" AttributeType=\"Vector\" "
                   "Center=\"Node\">\n");
        snprintf(dims, sizeof dims, "%d 2", n);
        xdmf_item(f, h5, dims, "Float", 8, v);
        fprintf(f, "    </Attribute>\n");
      }
      fprintf(f, "   </Grid>\n");
    }
    fprintf(f, "  </Grid>\n");
  }
  fprintf(f, " </Domain>\n</Xdmf>\n");
  int bad = ferror(f);
  if (fclose(f) != 0 || bad || rename(tmp, io->xdmf) != 0) {
    remove(tmp);
    return VES_ERR_IO;
  }
  return VES_OK;
}

/* ---- create / open / close ----------------------------------------------- */

static ves_io *io_alloc(const char *path, int writable) {
  ves_io *io = calloc(1, sizeof *io);
  if (!io) return NULL;
  io->file = -1;
  io->writable = writable;
  io->series_sum = FNV_START;
  for (int i = 0; i < NSERIES; i++) io->series[i] = -1;
  snprintf(io->path, sizeof io->path, "%s", path);
  ves_io_xdmf_path(path, io->xdmf, sizeof io->xdmf);
  return io;
}

void ves_io_close(ves_io **pio) {
  if (!pio || !*pio) return;
  ves_io *io = *pio;
  for (int i = 0; i < NSERIES; i++)
    if (io->series[i] >= 0) H5Dclose(io->series[i]);
  if (io->file >= 0) {
    if (io->writable) H5Fflush(io->file, H5F_SCOPE_LOCAL);
    H5Fclose(io->file);
  }
  free(io->info.problem);
  free(io->info.source);
  free(io->snap_t);
  free(io);
  *pio = NULL;
}

/* Every configuration key as a typed attribute of /parameters. */
static ves_status write_parameters(hid_t file, const ves_config *cfg) {
  hid_t g = H5Lexists(file, "parameters", H5P_DEFAULT) > 0
                ? H5Gopen2(file, "parameters", H5P_DEFAULT)
                : H5Gcreate2(file, "parameters", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  ves_status st = describe(g, "see vesica keys",
                           "every problem-file key as an attribute section.key (units and "
                           "meaning: vesica keys, problems/README.md)");
  for (int i = 0; i < ves_config_count() && st == VES_OK; i++) {
    ves_config_entry e;
    char name[128];
    ves_config_entry_get(cfg, i, &e);
    snprintf(name, sizeof name, "%s.%s", e.section, e.key);
    if (e.type == VES_KEY_REAL)
      st = attr_double(g, name, e.real);
    else if (e.type == VES_KEY_INT)
      st = attr_int(g, name, e.integer);
    else
      st = attr_str(g, name, e.text);
  }
  H5Gclose(g);
  return st;
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
static ves_status create_series(ves_io *io, const hid_t *like) {
  hid_t g = H5Gcreate2(io->file, "series", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  hsize_t zero = 0, unlim = H5S_UNLIMITED, chunk = IO_CHUNK;
  hid_t sp = H5Screate_simple(1, &zero, &unlim), dcpl = H5Pcreate(H5P_DATASET_CREATE);
  ves_status st = sp >= 0 && dcpl >= 0 && H5Pset_chunk(dcpl, 1, &chunk) >= 0 ? VES_OK : VES_ERR_IO;
  for (int i = 0; i < NSERIES && st == VES_OK; i++) {
    if (like && like[i] < 0) continue;
    io->series[i] = H5Dcreate2(g, SERIES[i].name, col_file_type(SERIES[i].type), sp, H5P_DEFAULT,
                               dcpl, H5P_DEFAULT);
    if (io->series[i] < 0) st = VES_ERR_IO;
    if (st == VES_OK) st = describe(io->series[i], SERIES[i].units, SERIES[i].description);
    if (st == VES_OK && !strcmp(SERIES[i].name, "status")) st = status_codes(io->series[i]);
  }
  if (st == VES_OK)
    st = describe(g, "per dataset", "one row per accepted step, flushed after every step");
  if (dcpl >= 0) H5Pclose(dcpl);
  if (sp >= 0) H5Sclose(sp);
  H5Gclose(g);
  return st;
}

static ves_status write_header(ves_io *io, const ves_io_header *h) {
  hid_t f = io->file;
  VES_CALL(attr_int(f, "format_version", VES_IO_FORMAT));
  VES_CALL(attr_str(f, "program", "vesica"));
  VES_CALL(attr_str(f, "version", h->version));
  VES_CALL(attr_str(f, "backend", h->backend));
  VES_CALL(attr_int(f, "nodes", h->n));
  VES_CALL(attr_str(f, "problem", h->problem));
  VES_CALL(attr_str(f, "source", h->source ? h->source : ""));
  VES_CALL(attr_double(f, "E0", h->E0));
  VES_CALL(attr_double(f, "A0", h->A0));
  VES_CALL(attr_double(f, "V0", h->V0));
  VES_CALL(attr_double(f, "setup_seconds", h->setup_seconds));
  VES_CALL(attr_status(f, "running"));
  VES_CALL(attr_str(f, "format_description",
                    "vesica HDF5 output, layout format_version 2: solver/app/io.h and "
                    "README.md (Output) of vesica"));
  VES_CALL(describe(f, "lengths R0 = sqrt(A0/4 pi), time t* = t k/(mu R0^3), energy k (E* = E/k)",
                    "a vesica run: header attributes, parameters, mesh, series, snapshots"));
  VES_CALL(write_parameters(f, h->cfg));
  hid_t g = H5Gcreate2(f, "mesh", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  int *v = malloc((size_t)h->n * sizeof *v);
  ves_status st = v ? VES_OK : VES_ERR_ALLOC;
  for (int a = 0; v && a < h->n; a++) v[a] = a;
  if (st == VES_OK)
    st = dset_write(g, "X", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, (hsize_t)h->n, 2, h->X);
  if (st == VES_OK)
    st = dset_write(g, "triangles", H5T_STD_I32LE, H5T_NATIVE_INT, (hsize_t)h->ntri, 3, h->tri);
  if (st == VES_OK)
    st = dset_write(g, "vertices", H5T_STD_I32LE, H5T_NATIVE_INT, (hsize_t)h->n, 0, v);
  if (st == VES_OK) st = describe(g, "R0", "the reference configuration the run started from");
  if (st == VES_OK) st = describe_at(g, "X", "R0", "n x 2 reference node positions (R, Z)");
  if (st == VES_OK)
    st = describe_at(g, "triangles", "1",
                     "ntri x 3 node indices of the reference Delaunay triangles (fixed "
                     "connectivity)");
  if (st == VES_OK) st = describe_at(g, "vertices", "1", "node indices 0..n-1 (XDMF points)");
  free(v);
  H5Gclose(g);
  VES_CALL(st);
  hid_t s = H5Gcreate2(f, "snapshots", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (s < 0) return VES_ERR_IO;
  st = attr_int(s, "count", 0);
  if (st == VES_OK)
    st = describe(s, "per member",
                  "states of the run, groups 0..count-1 (the initial state, every [output] "
                  "snapshot_every steps, the last)");
  H5Gclose(s);
  VES_CALL(st);
  VES_CALL(create_series(io, NULL));
  return H5Fflush(f, H5F_SCOPE_LOCAL) < 0 ? VES_ERR_IO : VES_OK;
}

static void fill_info(ves_io *io, const ves_io_header *h) {
  ves_io_info *in = &io->info;
  in->format_version = VES_IO_FORMAT;
  snprintf(in->version, sizeof in->version, "%s", h->version);
  snprintf(in->backend, sizeof in->backend, "%s", h->backend);
  snprintf(in->status, sizeof in->status, "running");
  in->problem = strdup(h->problem);
  in->source = strdup(h->source ? h->source : "");
  in->n = h->n, in->ntri = h->ntri;
  in->E0 = h->E0, in->A0 = h->A0, in->V0 = h->V0;
  in->setup_seconds = h->setup_seconds;
}

ves_status ves_io_create(const char *path, const ves_io_header *h, ves_io **out, char *err,
                         size_t errlen) {
  VES_CHECK(path && h && out && h->cfg && h->version && h->backend && h->problem && h->X &&
                h->tri && h->n > 0 && h->ntri > 0,
            VES_ERR_ARG);
  *out = NULL;
  quiet_hdf5();
  if (strlen(path) >= PATH_MAX - 8) {
    ves_error_say(err, errlen, "%s: path too long", path);
    return VES_ERR_IO;
  }
  /* an HDF5 file there may be the output of a running vesica (which holds
   * a lock on it): never truncate that one */
  if (H5Fis_hdf5(path) > 0) {
    hid_t f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
    if (f < 0) {
      ves_error_say(err, errlen,
                    "%s: exists and cannot be opened for writing (in use by a running vesica?)",
                    path);
      return VES_ERR_IO;
    }
    H5Fclose(f);
  }
  ves_io *io = io_alloc(path, 1);
  if (!io) return VES_ERR_ALLOC;
  io->file = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (io->file < 0) {
    ves_error_say(err, errlen, "%s: cannot create the HDF5 file", path);
    ves_io_close(&io);
    return VES_ERR_IO;
  }
  fill_info(io, h);
  errno = 0;
  ves_status st = io->info.problem && io->info.source ? write_header(io, h) : VES_ERR_ALLOC;
  if (st != VES_OK) { /* the file is ours (just created): nothing half-written stays */
    int e = errno;
    ves_error_say(err, errlen, "%s: cannot write the header: %s", path,
                  e && st == VES_ERR_IO ? strerror(e) : ves_status_str(st));
    ves_io_close(&io);
    remove(path);
    return st;
  }
  *out = io;
  return VES_OK;
}

/* Count the complete snapshots and read their times. */
static ves_status read_snapshot_times(ves_io *io) {
  hid_t s = H5Gopen2(io->file, "snapshots", H5P_DEFAULT);
  if (s < 0) return VES_ERR_CONFIG;
  int count = 0;
  ves_status st = attr_read(s, "count", H5T_NATIVE_INT, &count);
  if (st == VES_OK && count < 0) st = VES_ERR_CONFIG;
  if (st == VES_OK && count > 0) {
    io->snap_t = malloc((size_t)count * sizeof *io->snap_t);
    io->snap_cap = count;
    if (!io->snap_t) st = VES_ERR_ALLOC;
  }
  for (int k = 0; k < count && st == VES_OK; k++) {
    char name[32];
    snprintf(name, sizeof name, "%d", k);
    hid_t g = H5Gopen2(s, name, H5P_DEFAULT);
    st = g < 0 ? VES_ERR_CONFIG : attr_read_double(g, "t", &io->snap_t[k]);
    if (g >= 0) H5Gclose(g);
    if (st != VES_OK && io->tolerant) { /* a salvage: the snapshots before it */
      count = k, st = VES_OK;
      break;
    }
  }
  H5Gclose(s);
  if (st == VES_OK) io->nsnap = count;
  return st;
}

static ves_status read_header(ves_io *io) {
  hid_t f = io->file;
  ves_io_info *in = &io->info;
  char prog[32];
  if (attr_read(f, "format_version", H5T_NATIVE_INT, &in->format_version) != VES_OK ||
      attr_read_buf(f, "program", prog, sizeof prog) != VES_OK || strcmp(prog, "vesica"))
    return VES_ERR_CONFIG;
  if (in->format_version < 1 || in->format_version > VES_IO_FORMAT) return VES_ERR_CONFIG;
  /* format 1 snapshots have no x: read-only (a restart would mix formats) */
  if (io->writable && in->format_version != VES_IO_FORMAT) return VES_ERR_CONFIG;
  VES_CALL(attr_read_buf(f, "version", in->version, sizeof in->version));
  VES_CALL(attr_read_buf(f, "backend", in->backend, sizeof in->backend));
  /* a salvage takes a file whose status (written last) was lost as killed */
  if (attr_read_buf(f, "status", in->status, sizeof in->status) != VES_OK) {
    if (!io->tolerant) return VES_ERR_CONFIG;
    snprintf(in->status, sizeof in->status, "running");
  }
  VES_CALL(attr_read(f, "nodes", H5T_NATIVE_INT, &in->n));
  VES_CALL(attr_read_str(f, "problem", &in->problem));
  VES_CALL(attr_read_str(f, "source", &in->source));
  VES_CALL(attr_read_double(f, "E0", &in->E0));
  VES_CALL(attr_read_double(f, "A0", &in->A0));
  VES_CALL(attr_read_double(f, "V0", &in->V0));
  if (attr_read_double(f, "setup_seconds", &in->setup_seconds) != VES_OK && !io->tolerant)
    return VES_ERR_CONFIG;
  hid_t d = H5Dopen2(f, "mesh/triangles", H5P_DEFAULT);
  if (d < 0) return VES_ERR_CONFIG;
  hsize_t dims[2] = {0, 0};
  hid_t sp = H5Dget_space(d);
  int ok = sp >= 0 && H5Sget_simple_extent_ndims(sp) == 2 &&
           H5Sget_simple_extent_dims(sp, dims, NULL) >= 0 && dims[1] == 3 && dims[0] <= INT_MAX;
  if (sp >= 0) H5Sclose(sp);
  H5Dclose(d);
  if (!ok || in->n <= 0) return VES_ERR_CONFIG;
  in->ntri = (int)dims[0];
  for (int i = 0; i < NSERIES; i++) {
    char name[64];
    snprintf(name, sizeof name, "series/%s", SERIES[i].name);
    if (col_optional(i) && H5Lexists(f, name, H5P_DEFAULT) == 0) continue; /* an older file */
    io->series[i] = H5Dopen2(f, name, H5P_DEFAULT);
    if (io->series[i] < 0 || !numeric_type_ok(io->series[i], 0)) return VES_ERR_CONFIG;
  }
  return read_snapshot_times(io);
}

ves_status ves_io_open(const char *path, int writable, ves_io **out, char *err, size_t errlen) {
  VES_CHECK(path && out, VES_ERR_ARG);
  *out = NULL;
  quiet_hdf5();
  FILE *probe = fopen(path, writable ? "r+" : "r");
  if (!probe) {
    ves_error_say(err, errlen, "%s: cannot open%s: %s", path, writable ? " for writing" : "",
                  strerror(errno));
    return VES_ERR_IO;
  }
  fclose(probe);
  if (H5Fis_hdf5(path) <= 0) {
    ves_error_say(err, errlen, "%s: not an HDF5 file", path);
    return VES_ERR_IO;
  }
  ves_io *io = io_alloc(path, writable);
  if (!io) return VES_ERR_ALLOC;
  hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  /* readers take no lock: `vesica info` works on the file of a running run */
  if (fapl >= 0 && !writable) H5Pset_file_locking(fapl, 0, 1);
  io->file = H5Fopen(path, writable ? H5F_ACC_RDWR : H5F_ACC_RDONLY, fapl);
  char why[128] = ""; /* read before the next call clears HDF5's error stack */
  if (io->file < 0) H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, hdf5_reason, why);
  if (fapl >= 0) H5Pclose(fapl);
  if (io->file < 0) {
    /* a file HDF5 cannot open read-only without a lock is damaged (cut
     * short: its end of file before the end of its data), not in use */
    hid_t ro = H5Pcreate(H5P_FILE_ACCESS), f = -1;
    if (ro >= 0 && writable) {
      H5Pset_file_locking(ro, 0, 1);
      f = H5Fopen(path, H5F_ACC_RDONLY, ro);
    }
    if (ro >= 0) H5Pclose(ro);
    if (f >= 0) {
      H5Fclose(f);
      ves_error_say(err, errlen,
                    "%s: cannot open the HDF5 file for writing (in use by a running vesica?)",
                    path);
    } else {
      ves_error_say(
          err, errlen, "%s: the HDF5 file is damaged: %s%s", path, why[0] ? why : "unreadable",
          strstr(why, "truncated") ? " (cut short: a copy interrupted, or a full disk; vesica run "
                                     "--restart salvages its last complete snapshot)"
                                   : "");
    }
    ves_io_close(&io);
    return VES_ERR_IO;
  }
  ves_status st = read_header(io);
  if (st != VES_OK) {
    if (st == VES_ERR_CONFIG && io->info.format_version > VES_IO_FORMAT)
      ves_error_say(err, errlen, "%s: format_version %d: this vesica reads format_version 1 to %d",
                    path, io->info.format_version, VES_IO_FORMAT);
    else if (st == VES_ERR_CONFIG && writable && io->info.format_version >= 1 &&
             io->info.format_version < VES_IO_FORMAT)
      ves_error_say(err, errlen,
                    "%s: format_version %d (an older vesica) is read-only: it cannot be continued",
                    path, io->info.format_version);
    else if (st == VES_ERR_CONFIG)
      ves_error_say(err, errlen, "%s: not a vesica output file (missing or malformed layout)",
                    path);
    else
      ves_error_say(err, errlen, "%s: cannot read the header: %s", path, ves_status_str(st));
    ves_io_close(&io);
    return st;
  }
  *out = io;
  return VES_OK;
}

const ves_io_info *ves_io_get_info(const ves_io *io) { return &io->info; }

/* ---- series ----------------------------------------------------------------- */

static ves_status append(ves_io *io, const ves_io_row *row) {
  for (int i = 0; i < NSERIES; i++) {
    hid_t d = io->series[i];
    if (d < 0) continue; /* an optional column the file lacks */
    hsize_t len = dset_len(d), one = 1, next = len + 1;
    if (H5Dset_extent(d, &next) < 0) return VES_ERR_IO;
    hid_t fs = H5Dget_space(d), ms = H5Screate_simple(1, &one, NULL);
    herr_t e =
        fs < 0 || ms < 0 ? -1 : H5Sselect_hyperslab(fs, H5S_SELECT_SET, &len, NULL, &one, NULL);
    if (e >= 0)
      e = H5Dwrite(d, col_mem_type(SERIES[i].type), ms, fs, H5P_DEFAULT,
                   (const char *)row + SERIES[i].offset);
    if (ms >= 0) H5Sclose(ms);
    if (fs >= 0) H5Sclose(fs);
    if (e < 0) return VES_ERR_IO;
  }
  return H5Fflush(io->file, H5F_SCOPE_LOCAL) < 0 ? VES_ERR_IO : VES_OK;
}

ves_status ves_io_append(ves_io *io, const ves_io_row *row) {
  VES_CHECK(io && row && io->writable, VES_ERR_ARG);
  errno = 0;
  return io_failed(io, append(io, row), errno);
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
                      .factorizations = rep->stats.factorizations,
                      .rejected_iterations = rep->rejected.iterations,
                      .rejected_seconds = rep->rejected.seconds};
}

/* The column of the text at position k (1-based), or NULL. */
static const series_spec *tsv_column(int k) {
  for (int i = 0; i < NCOLS; i++)
    if (SERIES[i].tsv == k) return SERIES + i;
  return NULL;
}

ves_status ves_io_tsv_header(FILE *f) {
  VES_CHECK(f, VES_ERR_ARG);
  int e = fputs("# ", f) < 0;
  for (int k = 1; tsv_column(k); k++)
    e |= fprintf(f, "%s%s", k > 1 ? "\t" : "", tsv_column(k)->tsv_name) < 0;
  e |= fputc('\n', f) == EOF;
  return e ? VES_ERR_IO : VES_OK;
}

ves_status ves_io_tsv_row(FILE *f, const ves_io_row *row, double A0) {
  VES_CHECK(f && row, VES_ERR_ARG);
  int e = 0;
  for (int k = 1; tsv_column(k); k++) {
    const series_spec *c = tsv_column(k);
    const char *p = (const char *)row + c->offset;
    if (k > 1) e |= fputc('\t', f) == EOF;
    if (c->type == COL_LONG) {
      long v;
      memcpy(&v, p, sizeof v);
      e |= fprintf(f, c->tsv_fmt, v) < 0;
    } else if (c->type == COL_INT) {
      int v;
      memcpy(&v, p, sizeof v);
      e |= fprintf(f, c->tsv_fmt, v) < 0;
    } else {
      double v;
      memcpy(&v, p, sizeof v);
      v = c->how == TSV_OF_A0 ? v / A0 - 1 : c->how == TSV_OF_VT ? v / row->V_target - 1 : v;
      e |= fprintf(f, c->tsv_fmt, v) < 0;
    }
  }
  e |= fputc('\n', f) == EOF;
  return e ? VES_ERR_IO : VES_OK;
}

long ves_io_rows(const ves_io *io) {
  hsize_t rows = 0, one = 1;
  for (int i = 0; i < NSERIES; i++) {
    if (io->series[i] < 0) continue; /* an optional column the file lacks ("t" never is) */
    hsize_t l = dset_len(io->series[i]);
    if (i == 0 || l < rows) rows = l;
  }
  /* a writer killed between extending "step" and writing it leaves the
   * fill value 0 there: that row is not complete */
  long step = 0;
  if (rows > 0) {
    hsize_t last = rows - 1;
    hid_t d = io->series[NSERIES - 1], fs = H5Dget_space(d), ms = H5Screate_simple(1, &one, NULL);
    if (fs >= 0 && ms >= 0 && H5Sselect_hyperslab(fs, H5S_SELECT_SET, &last, NULL, &one, NULL) >= 0)
      H5Dread(d, H5T_NATIVE_LONG, ms, fs, H5P_DEFAULT, &step);
    if (ms >= 0) H5Sclose(ms);
    if (fs >= 0) H5Sclose(fs);
    if (step != (long)rows) rows--;
  }
  return (long)rows;
}

ves_status ves_io_truncate(ves_io *io, long rows) {
  VES_CHECK(io && io->writable && rows >= 0, VES_ERR_ARG);
  hsize_t r = (hsize_t)rows;
  if (io->summed_rows > rows) io->summed_rows = 0, io->series_sum = FNV_START;
  for (int i = 0; i < NSERIES; i++) {
    if (io->series[i] < 0) continue; /* an optional column the file lacks */
    if (dset_len(io->series[i]) < r) return VES_ERR_ARG;
    if (H5Dset_extent(io->series[i], &r) < 0) return VES_ERR_IO;
  }
  return H5Fflush(io->file, H5F_SCOPE_LOCAL) < 0 ? VES_ERR_IO : VES_OK;
}

const char *ves_io_series_name(int i) { return i >= 0 && i < NSERIES ? SERIES[i].name : NULL; }

ves_status ves_io_read_series(ves_io *io, const char *name, double *out) {
  VES_CHECK(io && name && out, VES_ERR_ARG);
  int i = 0;
  while (i < NSERIES && strcmp(SERIES[i].name, name)) i++;
  VES_CHECK(i < NSERIES, VES_ERR_ARG);
  hsize_t rows = (hsize_t)ves_io_rows(io), zero = 0;
  if (rows == 0) return VES_OK;
  if (io->series[i] < 0) { /* an optional column the file lacks */
    for (hsize_t r = 0; r < rows; r++) out[r] = -1;
    return VES_OK;
  }
  hid_t fs = H5Dget_space(io->series[i]), ms = H5Screate_simple(1, &rows, NULL);
  herr_t e =
      fs < 0 || ms < 0 ? -1 : H5Sselect_hyperslab(fs, H5S_SELECT_SET, &zero, NULL, &rows, NULL);
  if (e >= 0) e = H5Dread(io->series[i], H5T_NATIVE_DOUBLE, ms, fs, H5P_DEFAULT, out);
  if (ms >= 0) H5Sclose(ms);
  if (fs >= 0) H5Sclose(fs);
  return e < 0 ? VES_ERR_IO : VES_OK;
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
  for (int i = 0; i < NSERIES; i++) /* the column absent (an older file): not recorded */
    if (io->series[i] < 0 && col_optional(i)) s->factorizations = -1;
  for (int c = 0; c < NSUM; c++) free(col[c]);
  return st;
}

/* ---- counted groups (snapshots, references) ------------------------------ */

/* Members "0", "1", ... of a group whose attribute count says how many are
 * complete: a member is written whole, then counted, so a writer killed in
 * between leaves an uncounted member that the next write replaces. */

/* Open (or create) group `parent` of the file and create its member k anew
 * (dropping a stray one). On VES_OK *ps and *pg are open (close them with
 * counted_close); on failure nothing is open. */
static ves_status counted_open(hid_t file, const char *parent, int k, hid_t *ps, hid_t *pg) {
  hid_t s = H5Lexists(file, parent, H5P_DEFAULT) > 0
                ? H5Gopen2(file, parent, H5P_DEFAULT)
                : H5Gcreate2(file, parent, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (s < 0) return VES_ERR_IO;
  char name[32];
  snprintf(name, sizeof name, "%d", k);
  if (H5Lexists(s, name, H5P_DEFAULT) > 0) H5Ldelete(s, name, H5P_DEFAULT);
  hid_t g = H5Gcreate2(s, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (g < 0) {
    H5Gclose(s);
    return VES_ERR_IO;
  }
  *ps = s, *pg = g;
  return VES_OK;
}

/* Close member k (g) of group s; when its writing went well (st) count it
 * (count = k + 1) and flush the file. Returns st or the first I/O error. */
static ves_status counted_close(hid_t file, hid_t s, hid_t g, int k, ves_status st) {
  H5Gclose(g);
  if (st == VES_OK) st = attr_int(s, "count", k + 1); /* complete once counted */
  H5Gclose(s);
  VES_CALL(st);
  return H5Fflush(file, H5F_SCOPE_LOCAL) < 0 ? VES_ERR_IO : VES_OK;
}

/* ---- snapshots -------------------------------------------------------------- */

int ves_io_snapshots(const ves_io *io) { return io->nsnap; }

static ves_status snapshot_attrs(hid_t g, const ves_io_snapinfo *si) {
  const ves_sim_state *s = &si->state;
  VES_CALL(attr_double(g, "t", s->t));
  VES_CALL(attr_long(g, "step", s->nstep));
  VES_CALL(attr_long(g, "rows", si->rows));
  VES_CALL(attr_double(g, "dt", s->dt));
  VES_CALL(attr_double(g, "E", s->E));
  VES_CALL(attr_double(g, "A", s->A));
  VES_CALL(attr_double(g, "V", s->V));
  VES_CALL(attr_double(g, "E0", s->E0));
  VES_CALL(attr_double(g, "A0", s->A0));
  VES_CALL(attr_double(g, "V0", s->V0));
  VES_CALL(attr_double(g, "lambda_A", s->lambda[0]));
  VES_CALL(attr_double(g, "lambda_V", s->lambda[1]));
  VES_CALL(attr_double(g, "c0", s->c0));
  VES_CALL(attr_double(g, "wall_seconds", si->wall_seconds));
  VES_CALL(attr_double(g, "dt_rejected", s->dt_rejected));
  VES_CALL(attr_long(g, "since_rejected", s->since_rejected));
  if (s->dt_prev > 0) VES_CALL(attr_double(g, "dt_prev", s->dt_prev));
  return attr_int(g, "reconnections", si->reconnections);
}

static ves_status snapshot(ves_io *io, const double *y, const double *x, const double *phi,
                           const ves_io_snapinfo *si) {
  if (io->nsnap == io->snap_cap) {
    int cap = io->snap_cap ? 2 * io->snap_cap : 16;
    double *t = realloc(io->snap_t, (size_t)cap * sizeof *t);
    if (!t) return VES_ERR_ALLOC;
    io->snap_t = t, io->snap_cap = cap;
  }
  hid_t s, g;
  VES_CALL(counted_open(io->file, "snapshots", io->nsnap, &s, &g));
  const hsize_t n = (hsize_t)nodes_now(io); /* the last remeshing's node set */
  const hid_t F = H5T_IEEE_F64LE, M = H5T_NATIVE_DOUBLE;
  ves_status st = dset_write(g, "y", F, M, n, 2, y);
  if (st == VES_OK) st = dset_write(g, "x", F, M, n, 2, x);
  if (st == VES_OK) st = dset_write(g, "phi", F, M, n, 0, phi);
  if (st == VES_OK && si->state.dt_prev > 0) st = dset_write(g, "y_prev", F, M, n, 2, si->y_prev);
  if (st == VES_OK && si->velocity) st = dset_write(g, "velocity", F, M, n, 2, si->velocity);
  if (st == VES_OK) st = snapshot_attrs(g, si);
  /* checksums for a salvage: of the snapshot, and of the series rows up to
   * it (when the file holds them: always in a run) */
  uint64_t rows_checksum = 0;
  if (st == VES_OK) st = attr_u64(g, "checksum", snap_sum((long)n, y, x, phi, si->y_prev, si));
  if (st == VES_OK && si->rows >= 0 && ves_io_rows(io) >= si->rows) {
    st = series_sum(io, si->rows, &rows_checksum);
    if (st == VES_OK) st = attr_u64(g, "series_checksum", rows_checksum);
  }
  if (st == VES_OK)
    st = describe(g, "t, dt in t*; E in k; A in R0^2; V in R0^3; c0 in 1/R0",
                  "one state: what a restart continues from; attributes the integrator state");
  if (st == VES_OK)
    st = describe_at(g, "y", "R0", "n x 2 nodal coefficients y^a (r, z) of the motion");
  if (st == VES_OK)
    st = describe_at(g, "x", "R0", "n x 2 positions y(X_a) of the material at the nodes");
  if (st == VES_OK) st = describe_at(g, "phi", "1", "phase field phi of that material (-1..1)");
  if (st == VES_OK && si->state.dt_prev > 0)
    st = describe_at(g, "y_prev", "R0",
                     "n x 2 coefficients before the last step (the predictor's start, dt_prev)");
  if (st == VES_OK && si->velocity)
    st = describe_at(g, "velocity", "R0 per t*",
                     "n x 2 flow at the nodes (r, z): the material's velocity over the last "
                     "step, (y^n(X_a) - y^{n-1}(X_a)) / dt_prev, at x");
  VES_CALL(counted_close(io->file, s, g, io->nsnap, st));
  io->snap_t[io->nsnap++] = si->state.t;
  return xdmf_write(io);
}

ves_status ves_io_snapshot(ves_io *io, const double *y, const double *x, const double *phi,
                           const ves_io_snapinfo *si) {
  VES_CHECK(io && y && x && phi && si && io->writable, VES_ERR_ARG);
  VES_CHECK(si->state.dt_prev >= 0 && (si->state.dt_prev == 0 || si->y_prev), VES_ERR_ARG);
  errno = 0;
  return io_failed(io, snapshot(io, y, x, phi, si), errno);
}

ves_status ves_io_read_snapshot(ves_io *io, int k, double *y, double *x, double *phi,
                                ves_io_snapinfo *si) {
  VES_CHECK(io, VES_ERR_ARG);
  return ves_io_read_snapshot_n(io, k, io->info.n, y, x, phi, si);
}

ves_status ves_io_read_snapshot_n(ves_io *io, int k, int nbuf, double *y, double *x, double *phi,
                                  ves_io_snapinfo *si) {
  VES_CHECK(io && k >= 0 && k < io->nsnap && nbuf > 0, VES_ERR_ARG);
  char name[48];
  snprintf(name, sizeof name, "snapshots/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  hsize_t n = (hsize_t)nbuf; /* the datasets must have exactly this size */
  ves_status st = VES_OK;
  if (y) st = dset_read(g, "y", H5T_NATIVE_DOUBLE, 2 * n, y);
  /* format 1 has no x: its snapshots showed the coefficients */
  if (st == VES_OK && x)
    st = dset_read(g, io->info.format_version >= 2 ? "x" : "y", H5T_NATIVE_DOUBLE, 2 * n, x);
  if (st == VES_OK && phi) st = dset_read(g, "phi", H5T_NATIVE_DOUBLE, n, phi);
  if (st == VES_OK && si) {
    ves_sim_state *s = &si->state;
    memset(si, 0, sizeof *si);
    const struct {
      const char *name;
      double *v;
    } d[] = {{"t", &s->t},
             {"dt", &s->dt},
             {"E", &s->E},
             {"A", &s->A},
             {"V", &s->V},
             {"E0", &s->E0},
             {"A0", &s->A0},
             {"V0", &s->V0},
             {"lambda_A", &s->lambda[0]},
             {"lambda_V", &s->lambda[1]},
             {"c0", &s->c0},
             {"wall_seconds", &si->wall_seconds}};
    for (size_t i = 0; i < sizeof d / sizeof d[0] && st == VES_OK; i++)
      st = attr_read_double(g, d[i].name, d[i].v);
    if (st == VES_OK) st = attr_read(g, "step", H5T_NATIVE_LONG, &s->nstep);
    if (st == VES_OK) st = attr_read(g, "rows", H5T_NATIVE_LONG, &si->rows);
    if (st == VES_OK) st = attr_read(g, "reconnections", H5T_NATIVE_INT, &si->reconnections);
    /* the controller's memory of rejected steps (absent before 2026-11-25: none) */
    if (st == VES_OK && H5Aexists(g, "dt_rejected") > 0)
      st = attr_read_double(g, "dt_rejected", &s->dt_rejected);
    if (st == VES_OK && H5Aexists(g, "since_rejected") > 0)
      st = attr_read(g, "since_rejected", H5T_NATIVE_LONG, &s->since_rejected);
    /* the predictor's state (absent before 2026-12-02 and when none was held) */
    if (st == VES_OK && H5Aexists(g, "dt_prev") > 0)
      st = attr_read_double(g, "dt_prev", &s->dt_prev);
    if (st == VES_OK && !(isfinite(s->dt_prev) && s->dt_prev >= 0)) st = VES_ERR_IO;
  }
  H5Gclose(g);
  return st;
}

/* A dataset of snapshot k that not every snapshot holds (2 nbuf values):
 * 1 read, 0 absent, negative (a ves_status) on an error or another size. */
static int snapshot_optional(ves_io *io, int k, const char *dset, int nbuf, double *out) {
  VES_CHECK(io && k >= 0 && k < io->nsnap && nbuf > 0 && out, VES_ERR_ARG);
  char name[48];
  snprintf(name, sizeof name, "snapshots/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  int r = 0;
  if (H5Lexists(g, dset, H5P_DEFAULT) > 0) {
    ves_status st = dset_read(g, dset, H5T_NATIVE_DOUBLE, 2 * (hsize_t)nbuf, out);
    r = st == VES_OK ? 1 : (int)st;
  }
  H5Gclose(g);
  return r;
}

ves_status ves_io_read_snapshot_prev(ves_io *io, int k, int nbuf, double *y_prev) {
  const int r = snapshot_optional(io, k, "y_prev", nbuf, y_prev);
  return r == 1 ? VES_OK : r == 0 ? VES_ERR_IO : (ves_status)r;
}

int ves_io_read_snapshot_velocity(ves_io *io, int k, int nbuf, double *v) {
  return snapshot_optional(io, k, "velocity", nbuf, v);
}

ves_status ves_io_read_mesh(ves_io *io, double *X, int *tri) {
  VES_CHECK(io, VES_ERR_ARG);
  if (X) VES_CALL(dset_read(io->file, "mesh/X", H5T_NATIVE_DOUBLE, 2 * (hsize_t)io->info.n, X));
  if (tri)
    VES_CALL(
        dset_read(io->file, "mesh/triangles", H5T_NATIVE_INT, 3 * (hsize_t)io->info.ntri, tri));
  return VES_OK;
}

/* ---- references (resets of the reference configuration) ----------------- */

/* The complete references: /references attribute count (0 without the group). */
int ves_io_references(const ves_io *io) {
  if (!io || H5Lexists(io->file, "references", H5P_DEFAULT) <= 0) return 0;
  hid_t g = H5Gopen2(io->file, "references", H5P_DEFAULT);
  int count = 0;
  if (g >= 0 && attr_read(g, "count", H5T_NATIVE_INT, &count) != VES_OK) count = 0;
  if (g >= 0) H5Gclose(g);
  return count;
}

static ves_status write_reference(ves_io *io, const ves_io_reference *ref) {
  const int k = ves_io_references(io);
  hid_t s, g;
  VES_CALL(counted_open(io->file, "references", k, &s, &g));
  const hsize_t n = (hsize_t)nodes_now(io), nq = (hsize_t)ref->nq;
  const hid_t F = H5T_IEEE_F64LE, M = H5T_NATIVE_DOUBLE;
  ves_status st = dset_write(g, "x", F, M, n, 2, ref->x);
  if (st == VES_OK) st = dset_write(g, "h", F, M, n, 0, ref->h);
  if (st == VES_OK) st = dset_write(g, "points", F, M, nq, 2, ref->xq);
  if (st == VES_OK) st = dset_write(g, "weights", F, M, nq, 0, ref->wq);
  if (st == VES_OK) st = dset_write(g, "phi0", F, M, nq, 6, ref->pd);
  if (st == VES_OK) st = attr_long(g, "step", ref->step);
  if (st == VES_OK)
    st = attr_u64(g, "checksum",
                  ref_sum((long)n, (long)nq, ref->x, ref->h, ref->xq, ref->wq, ref->pd, ref->step));
  if (st == VES_OK)
    st = describe(s, "per member", "reference configurations, one per reset (groups 0..count-1)");
  if (st == VES_OK)
    st =
        describe(g, "R0", "the reference made after accepted step `step`: what a restart rebuilds");
  if (st == VES_OK) st = describe_at(g, "x", "R0", "n x 2 node positions (R, Z)");
  if (st == VES_OK) st = describe_at(g, "h", "R0", "n node spacings h_a");
  if (st == VES_OK) st = describe_at(g, "points", "R0", "nq x 2 quadrature points (R, Z)");
  if (st == VES_OK) st = describe_at(g, "weights", "R0^2", "nq quadrature weights");
  if (st == VES_OK)
    st = describe_at(g, "phi0", "1, 1/R0, 1/R0^2",
                     "nq x 6 point data of phi0: value, gradient (2), Hessian (3)");
  return counted_close(io->file, s, g, k, st);
}

ves_status ves_io_write_reference(ves_io *io, const ves_io_reference *ref) {
  VES_CHECK(io && ref && io->writable && ref->x && ref->h && ref->xq && ref->wq && ref->pd,
            VES_ERR_ARG);
  VES_CHECK(ref->nq > 0 && ref->step >= 0, VES_ERR_ARG);
  errno = 0;
  return io_failed(io, write_reference(io, ref), errno);
}

ves_status ves_io_read_reference(ves_io *io, int k, ves_io_reference_buf *out) {
  VES_CHECK(io && out && out->x && out->h && out->xq && out->wq && out->pd, VES_ERR_ARG);
  VES_CHECK(k >= 0 && k < ves_io_references(io) && out->nq > 0, VES_ERR_ARG);
  char name[48];
  snprintf(name, sizeof name, "references/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  const hsize_t n = (hsize_t)(out->n > 0 ? out->n : io->info.n), nq = (hsize_t)out->nq;
  const hid_t M = H5T_NATIVE_DOUBLE;
  ves_status st = dset_read(g, "x", M, 2 * n, out->x);
  if (st == VES_OK) st = dset_read(g, "h", M, n, out->h);
  if (st == VES_OK) st = dset_read(g, "points", M, 2 * nq, out->xq);
  if (st == VES_OK) st = dset_read(g, "weights", M, nq, out->wq);
  if (st == VES_OK) st = dset_read(g, "phi0", M, 6 * nq, out->pd);
  if (st == VES_OK) st = attr_read(g, "step", H5T_NATIVE_LONG, &out->step);
  H5Gclose(g);
  return st;
}

/* Drop the counted group's members count..have-1 (the count attribute first: the rest is
   then stray) and flush. */
static ves_status truncate_counted(ves_io *io, const char *group, int have, int count) {
  VES_CHECK(io && io->writable && count >= 0 && count <= have, VES_ERR_ARG);
  if (count == have) return VES_OK;
  hid_t s = H5Gopen2(io->file, group, H5P_DEFAULT);
  if (s < 0) return VES_ERR_IO;
  ves_status st = attr_int(s, "count", count); /* first: the rest is then stray */
  for (int k = count; k < have && st == VES_OK; k++) {
    char name[32];
    snprintf(name, sizeof name, "%d", k);
    if (H5Ldelete(s, name, H5P_DEFAULT) < 0) st = VES_ERR_IO;
  }
  H5Gclose(s);
  VES_CALL(st);
  return H5Fflush(io->file, H5F_SCOPE_LOCAL) < 0 ? VES_ERR_IO : VES_OK;
}

ves_status ves_io_truncate_references(ves_io *io, int count) {
  VES_CHECK(io, VES_ERR_ARG);
  return truncate_counted(io, "references", ves_io_references(io), count);
}

ves_status ves_io_set_status(ves_io *io, const char *status) {
  VES_CHECK(io && status && io->writable && strlen(status) < sizeof io->info.status, VES_ERR_ARG);
  errno = 0;
  ves_status st = attr_status(io->file, status);
  if (st == VES_OK && H5Fflush(io->file, H5F_SCOPE_LOCAL) < 0) st = VES_ERR_IO;
  if (st == VES_OK) snprintf(io->info.status, sizeof io->info.status, "%s", status);
  return io_failed(io, st, errno);
}

ves_status ves_io_set_problem(ves_io *io, const ves_config *cfg) {
  VES_CHECK(io && io->writable && cfg, VES_ERR_ARG);
  char *text = NULL;
  VES_CALL(ves_config_to_text(cfg, &text));
  ves_status st = attr_str(io->file, "problem", text);
  if (st == VES_OK) st = write_parameters(io->file, cfg);
  if (st == VES_OK) {
    free(io->info.problem);
    io->info.problem = text;
  } else {
    free(text);
  }
  VES_CALL(st);
  return H5Fflush(io->file, H5F_SCOPE_LOCAL) < 0 ? VES_ERR_IO : VES_OK;
}

ves_status ves_io_set_setup_seconds(ves_io *io, double seconds) {
  VES_CHECK(io && io->writable, VES_ERR_ARG);
  VES_CALL(attr_double(io->file, "setup_seconds", seconds));
  io->info.setup_seconds = seconds;
  return VES_OK;
}

/* ---- room for the next writes ------------------------------------------- */

/* Bytes HDF5 adds for metadata beyond the data of one step's writes (object
 * headers growing, group link storage turning dense, B-tree nodes): a bound
 * measured with room to spare (a 64-snapshot file grows by < 8 KiB a
 * snapshot beyond its data). */
#define IO_ROOM_MARGIN (64 * 1024)

/* What the next writes of a run need at most, in bytes: one series row (a
 * new chunk of every series every IO_CHUNK rows, with its B-tree node),
 * `snapshots` snapshots (y, x, phi, y_prev, velocity: 9 values a node; and
 * the XDMF file, four data items a grid, rewritten beside its old copy) and,
 * with nq > 0, a reference of nq points. */
static double room_needed(const ves_io *io, int snapshots, int nq) {
  const double n = nodes_now(io);
  double need = IO_ROOM_MARGIN;
  if (ves_io_rows(io) % IO_CHUNK == 0) need += NSERIES * (IO_CHUNK * 8.0 + 4096);
  const double xdmf = 2.0 * (io->nsnap + snapshots) * (1536 + 5.0 * strlen(io->path));
  need += snapshots * (9 * 8 * n + 4096) + (snapshots ? 2 * xdmf : 0);
  if (nq > 0) need += 8 * (3 * n + 9.0 * nq) + 4096;
  return need;
}

ves_status ves_io_room(ves_io *io, int snapshots, int nq) {
  VES_CHECK(io && io->writable && snapshots >= 0 && nq >= 0, VES_ERR_ARG);
  const double need = room_needed(io, snapshots, nq);
  char dir[PATH_MAX];
  const char *slash = strrchr(io->path, '/');
  if (!slash)
    snprintf(dir, sizeof dir, ".");
  else
    snprintf(dir, sizeof dir, "%.*s", slash == io->path ? 1 : (int)(slash - io->path), io->path);
  struct statvfs vs;
  if (statvfs(dir, &vs) == 0) {
    const double avail = (double)vs.f_bavail * (double)vs.f_frsize;
    if (avail < need) {
      snprintf(io->error, sizeof io->error,
               "no space left on device (%.0f KiB free in %s, the next step's output needs up "
               "to %.0f KiB)",
               avail / 1024, dir, need / 1024);
      return VES_ERR_IO;
    }
  }
  struct rlimit rl;
  struct stat sb;
  if (getrlimit(RLIMIT_FSIZE, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY &&
      stat(io->path, &sb) == 0 && (double)sb.st_size + need > (double)rl.rlim_cur) {
    snprintf(io->error, sizeof io->error,
             "file size limit reached (ulimit -f: %.0f KiB; %s holds %.0f KiB, the next step's "
             "output needs up to %.0f KiB)",
             (double)rl.rlim_cur / 1024, io->path, (double)sb.st_size / 1024, need / 1024);
    return VES_ERR_IO;
  }
  return VES_OK;
}

const char *ves_io_error(const ves_io *io) { return io && io->error[0] ? io->error : NULL; }

/* ---- remeshings (full remeshing, remesh.h) -------------------------------- */

/* The complete remeshings: /remeshes attribute count (0 without the group). */
int ves_io_remeshes(const ves_io *io) {
  if (!io || H5Lexists(io->file, "remeshes", H5P_DEFAULT) <= 0) return 0;
  hid_t g = H5Gopen2(io->file, "remeshes", H5P_DEFAULT);
  int count = 0;
  if (g >= 0 && attr_read(g, "count", H5T_NATIVE_INT, &count) != VES_OK) count = 0;
  if (g >= 0) H5Gclose(g);
  return count;
}

/* The first dimension of dataset `name` in loc (0 when absent or unreadable). */
static hsize_t dset_rows(hid_t loc, const char *name) {
  hid_t d = H5Dopen2(loc, name, H5P_DEFAULT);
  if (d < 0) return 0;
  hsize_t dims[2] = {0, 0};
  hid_t sp = H5Dget_space(d);
  if (sp < 0 || H5Sget_simple_extent_ndims(sp) < 1 ||
      H5Sget_simple_extent_dims(sp, dims, NULL) < 0 || dims[0] > INT_MAX)
    dims[0] = 0;
  if (sp >= 0) H5Sclose(sp);
  H5Dclose(d);
  return dims[0];
}

ves_status ves_io_remesh_size(const ves_io *io, int k, long *step, int *n, int *ntri) {
  VES_CHECK(io && k >= 0 && k < ves_io_remeshes(io), VES_ERR_ARG);
  char name[48];
  snprintf(name, sizeof name, "remeshes/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  long s = 0;
  ves_status st = attr_read(g, "step", H5T_NATIVE_LONG, &s);
  const int nn = (int)dset_rows(g, "x"), nt = (int)dset_rows(g, "triangles");
  H5Gclose(g);
  if (st == VES_OK && (nn < 3 || nt < 1)) st = VES_ERR_IO;
  if (st != VES_OK) return st;
  if (step) *step = s;
  if (n) *n = nn;
  if (ntri) *ntri = nt;
  return VES_OK;
}

/* Real nodes of the state now: the last remeshing's, or the header's. */
static int nodes_now(const ves_io *io) {
  const int R = ves_io_remeshes(io);
  int n = io->info.n;
  if (R > 0 && ves_io_remesh_size(io, R - 1, NULL, &n, NULL) != VES_OK) n = io->info.n;
  return n;
}

int ves_io_snapshot_nodes(const ves_io *io, int k) {
  if (!io || k < 0 || k >= io->nsnap) return -1;
  char name[48];
  snprintf(name, sizeof name, "snapshots/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return -1;
  const hsize_t n = dset_rows(g, "y");
  H5Gclose(g);
  return n > 0 ? (int)n : -1;
}

int ves_io_snapshot_mesh(const ves_io *io, int k, int *n, int *ntri) {
  if (n) *n = io->info.n;
  if (ntri) *ntri = io->info.ntri;
  const int R = ves_io_remeshes(io);
  if (R == 0) return -1;
  char name[48];
  snprintf(name, sizeof name, "snapshots/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  long step = 0;
  if (g < 0) return -1;
  ves_status st = attr_read(g, "step", H5T_NATIVE_LONG, &step);
  H5Gclose(g);
  for (int j = R - 1; st == VES_OK && j >= 0; j--) {
    long sj;
    int nj, tj;
    if (ves_io_remesh_size(io, j, &sj, &nj, &tj) != VES_OK) return -1;
    if (sj <= step) {
      if (n) *n = nj;
      if (ntri) *ntri = tj;
      return j;
    }
  }
  return -1;
}

/* The checksum of the datasets named in part[np] of group g (each read
 * whole as doubles, in that order), or 0 when one does not read. */
static uint64_t group_sum(hid_t g, const char *const *part, int np) {
  uint64_t h = FNV_START;
  for (int i = 0; i < np; i++) {
    double *v = NULL;
    hsize_t c = 0;
    hid_t d = H5Dopen2(g, part[i], H5P_DEFAULT);
    hid_t sp = d < 0 ? -1 : H5Dget_space(d);
    const hssize_t np_ = sp < 0 ? -1 : H5Sget_simple_extent_npoints(sp);
    int ok = np_ > 0 && numeric_type_ok(d, 0) && (v = malloc((size_t)np_ * sizeof *v)) &&
             H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v) >= 0;
    c = ok ? (hsize_t)np_ : 0;
    if (ok) h = fnv(h, v, (size_t)c * sizeof *v);
    free(v);
    if (sp >= 0) H5Sclose(sp);
    if (d >= 0) H5Dclose(d);
    if (!ok) return 0;
  }
  return h;
}

/* The datasets of a remeshing group its checksum covers. */
static const char *const REMESH_PARTS[] = {"x", "h", "flag", "phi0c", "triangles", "vertices"};
#define NREMESH_PARTS ((int)(sizeof REMESH_PARTS / sizeof REMESH_PARTS[0]))

static ves_status write_remesh(ves_io *io, const ves_io_remesh *rm) {
  const int k = ves_io_remeshes(io);
  hid_t s, g;
  VES_CALL(counted_open(io->file, "remeshes", k, &s, &g));
  const hsize_t n = (hsize_t)rm->n, nt = (hsize_t)rm->ntri;
  const hid_t F = H5T_IEEE_F64LE, M = H5T_NATIVE_DOUBLE;
  int *v = malloc((size_t)rm->n * sizeof *v);
  for (int a = 0; v && a < rm->n; a++) v[a] = a;
  ves_status st = v ? VES_OK : VES_ERR_ALLOC;
  if (st == VES_OK) st = dset_write(g, "x", F, M, n, 2, rm->x);
  if (st == VES_OK) st = dset_write(g, "h", F, M, n, 0, rm->h);
  if (st == VES_OK) st = dset_write(g, "flag", H5T_STD_I32LE, H5T_NATIVE_INT, n, 0, rm->flag);
  if (st == VES_OK) st = dset_write(g, "phi0c", F, M, n, 0, rm->phi0c);
  if (st == VES_OK) st = dset_write(g, "triangles", H5T_STD_I32LE, H5T_NATIVE_INT, nt, 3, rm->tri);
  if (st == VES_OK) st = dset_write(g, "vertices", H5T_STD_I32LE, H5T_NATIVE_INT, n, 0, v);
  free(v);
  if (st == VES_OK) st = attr_long(g, "step", rm->step);
  const ves_remesh_info *in = rm->info;
  const struct {
    const char *name;
    double v;
  } a[] = {{"n_old", in->n_old},
           {"n_new", in->n_new},
           {"nq_old", in->nq_old},
           {"nq_new", in->nq_new},
           {"E_old", in->E_old},
           {"A_old", in->A_old},
           {"V_old", in->V_old},
           {"E_proj", in->E_proj},
           {"A_proj", in->A_proj},
           {"V_proj", in->V_proj},
           {"E", in->E},
           {"A", in->A},
           {"V", in->V},
           {"dE", in->dE},
           {"dA", in->dA},
           {"dV", in->dV},
           {"corr_max", in->corr_max},
           {"corr_norm", in->corr_norm},
           {"corr_iter", in->corr_iter},
           {"res_A", in->res_A},
           {"res_V", in->res_V},
           {"disp_max", in->disp_max},
           {"disp_mean", in->disp_mean},
           {"seconds", in->seconds},
           {"seconds_interface", in->seconds_interface},
           {"seconds_nodes", in->seconds_nodes},
           {"seconds_tables", in->seconds_tables},
           {"seconds_project", in->seconds_project},
           {"seconds_correct", in->seconds_correct},
           {"band_layers", in->band_layers},
           {"proj_points", in->proj_points},
           {"proj_cells_refined", in->proj_cells_refined},
           {"proj_cells_capped", in->proj_cells_capped},
           {"proj_points_dropped", in->proj_points_dropped}};
  for (size_t i = 0; i < sizeof a / sizeof a[0] && st == VES_OK; i++)
    st = attr_double(g, a[i].name, a[i].v);
  if (st == VES_OK)
    st = describe(s, "per member",
                  "full remeshings, one per member (groups 0..count-1): the new node sets");
  if (st == VES_OK)
    st = describe(g, "R0; E in k",
                  "the node set made after accepted step `step`: what a restart rebuilds "
                  "(ves_remesh_restore); attributes what it changed: E_old/E_proj/E (E*), "
                  "A, V before (old), projected (proj, before the correction) and corrected; "
                  "dE = E_proj - E_old, dA = A_proj/A_old - 1, dV = V_proj/V_old - 1; "
                  "corr_max (max |delta_a|/h_a), corr_norm (|delta|, R0), corr_iter, res_A, "
                  "res_V (|A/A_target - 1|, |V/V_target - 1| after it), disp_max, disp_mean "
                  "(the interface's displacement, R0), seconds (wall; its parts seconds_interface, "
                  "seconds_nodes, seconds_tables, seconds_project, seconds_correct: the "
                  "interface's extraction, the nodes, the quadrature and LME tables, phi's "
                  "projection, the model and the A, V correction), band_layers (1: the band on "
                  "layers, 0: without, as band_layers = 0 or where the layers fold), "
                  "proj_points (points of the phi projection), proj_cells_refined (old cells "
                  "the motion spread too thin for the new basis, their points replaced by a "
                  "finer rule), proj_cells_capped (still too thin at the finest), "
                  "proj_points_dropped (of the finer rule's points, those the motion puts "
                  "outside the domain, left out)");
  if (st == VES_OK) st = describe_at(g, "x", "R0", "n x 2 node positions (R, Z)");
  if (st == VES_OK) st = describe_at(g, "h", "R0", "n node spacings h_a");
  if (st == VES_OK)
    st = describe_at(g, "flag", "1", "n node flags (1 axis, 2 wall, 4 lattice, 8 band)");
  if (st == VES_OK) st = describe_at(g, "phi0c", "1", "n nodal coefficients of the projected phi0");
  if (st == VES_OK)
    st = describe_at(g, "triangles", "1", "ntri x 3 Delaunay triangles of the new nodes");
  if (st == VES_OK) st = describe_at(g, "vertices", "1", "n int 0..n-1 (the nodes as XDMF points)");
  if (st == VES_OK) /* for a salvage (ves_io_salvage), read back as written */
    st = attr_u64(g, "checksum", group_sum(g, REMESH_PARTS, NREMESH_PARTS));
  return counted_close(io->file, s, g, k, st);
}

ves_status ves_io_write_remesh(ves_io *io, const ves_io_remesh *rm) {
  VES_CHECK(io && rm && io->writable && rm->x && rm->h && rm->flag && rm->phi0c && rm->tri &&
                rm->info,
            VES_ERR_ARG);
  VES_CHECK(rm->n >= 3 && rm->ntri > 0 && rm->step >= 1, VES_ERR_ARG);
  errno = 0;
  return io_failed(io, write_remesh(io, rm), errno);
}

ves_status ves_io_read_remesh(ves_io *io, int k, ves_io_remesh_buf *out) {
  VES_CHECK(io && out && out->x && out->h && out->flag && out->phi0c && out->n > 0, VES_ERR_ARG);
  VES_CHECK(k >= 0 && k < ves_io_remeshes(io), VES_ERR_ARG);
  char name[48];
  snprintf(name, sizeof name, "remeshes/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  const hsize_t n = (hsize_t)out->n;
  const hid_t M = H5T_NATIVE_DOUBLE;
  ves_status st = dset_read(g, "x", M, 2 * n, out->x);
  if (st == VES_OK) st = dset_read(g, "h", M, n, out->h);
  if (st == VES_OK) st = dset_read(g, "flag", H5T_NATIVE_INT, n, out->flag);
  if (st == VES_OK) st = dset_read(g, "phi0c", M, n, out->phi0c);
  if (st == VES_OK) st = attr_read(g, "step", H5T_NATIVE_LONG, &out->step);
  H5Gclose(g);
  return st;
}

ves_status ves_io_truncate_remeshes(ves_io *io, int count) {
  VES_CHECK(io, VES_ERR_ARG);
  return truncate_counted(io, "remeshes", ves_io_remeshes(io), count);
}

ves_status ves_io_reference_step(const ves_io *io, int k, long *step) {
  VES_CHECK(io && step && k >= 0 && k < ves_io_references(io), VES_ERR_ARG);
  char name[48];
  snprintf(name, sizeof name, "references/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  ves_status st = attr_read(g, "step", H5T_NATIVE_LONG, step);
  H5Gclose(g);
  return st;
}

ves_status ves_io_read_remesh_triangles(ves_io *io, int k, int *tri) {
  int nt = 0;
  VES_CHECK(tri, VES_ERR_ARG);
  VES_CALL(ves_io_remesh_size(io, k, NULL, NULL, &nt));
  char name[48];
  snprintf(name, sizeof name, "remeshes/%d/triangles", k);
  return dset_read(io->file, name, H5T_NATIVE_INT, 3 * (hsize_t)nt, tri);
}

/* ---- salvage of a file cut short ------------------------------------------ */

/* The end-of-file address a version 0 or 1 superblock records (8-byte
 * addresses, no user block: what this module writes), or -1. */
static long long sb_stored_eof(const unsigned char *b, size_t len) {
  static const unsigned char sig[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
  if (len < 64 || memcmp(b, sig, 8) || (b[8] != 0 && b[8] != 1) || b[13] != 8) return -1;
  const size_t at = b[8] == 0 ? 24 : 28; /* base address, free space, end of file */
  unsigned long long base = 0, eof = 0;
  for (int i = 7; i >= 0; i--) base = base << 8 | b[at + (size_t)i];
  for (int i = 7; i >= 0; i--) eof = eof << 8 | b[at + 16 + (size_t)i];
  return base + eof > (1ULL << 50) ? -1 : (long long)(base + eof);
}

int ves_io_cut_short(const char *path, long long *size, long long *stored) {
  unsigned char b[64];
  FILE *f = path ? fopen(path, "rb") : NULL;
  if (!f) return 0;
  const size_t got = fread(b, 1, sizeof b, f);
  struct stat sb;
  const int ok = fstat(fileno(f), &sb) == 0;
  fclose(f);
  const long long eof = sb_stored_eof(b, got);
  if (!ok || eof < 0 || (long long)sb.st_size >= eof) return 0;
  if (size) *size = (long long)sb.st_size;
  if (stored) *stored = eof;
  return 1;
}

/* H5Aiterate2 callback: read attribute `name` of obj whole in its own type
 * (fixed-size types, as this module writes) and, when data is not NULL,
 * copy it to the object *data. */
static herr_t copy_attr(hid_t obj, const char *name, const H5A_info_t *info, void *data) {
  (void)info;
  hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  hid_t t = a < 0 ? -1 : H5Aget_type(a), sp = a < 0 ? -1 : H5Aget_space(a);
  const hssize_t np = sp < 0 ? -1 : H5Sget_simple_extent_npoints(sp);
  const size_t sz = t < 0 || np < 0 ? 0 : H5Tget_size(t) * (size_t)np;
  char *buf = sz && !(t >= 0 && H5Tis_variable_str(t) > 0) ? malloc(sz) : NULL;
  herr_t e = buf && H5Aread(a, t, buf) >= 0 ? 0 : -1;
  hid_t b = e < 0 || !data ? -1 : H5Acreate2(*(hid_t *)data, name, t, sp, H5P_DEFAULT, H5P_DEFAULT);
  if (data && (b < 0 || H5Awrite(b, t, buf) < 0)) e = -1;
  if (b >= 0) H5Aclose(b);
  free(buf);
  if (sp >= 0) H5Sclose(sp);
  if (t >= 0) H5Tclose(t);
  if (a >= 0) H5Aclose(a);
  return e;
}

/* A whole dataset of doubles at loc/name (malloc'd into *out, its size in
 * *count). */
static ves_status dset_read_all(hid_t loc, const char *name, double **out, hsize_t *count) {
  *out = NULL, *count = 0;
  hid_t d = H5Dopen2(loc, name, H5P_DEFAULT);
  hid_t sp = d < 0 ? -1 : H5Dget_space(d);
  const hssize_t np = sp < 0 ? -1 : H5Sget_simple_extent_npoints(sp);
  ves_status st = np <= 0 || !numeric_type_ok(d, 0) ? VES_ERR_IO : VES_OK;
  if (st == VES_OK && !(*out = malloc((size_t)np * sizeof **out))) st = VES_ERR_ALLOC;
  if (st == VES_OK && H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, *out) < 0)
    st = VES_ERR_IO;
  if (st == VES_OK) *count = (hsize_t)np;
  if (st != VES_OK) free(*out), *out = NULL;
  if (sp >= 0) H5Sclose(sp);
  if (d >= 0) H5Dclose(d);
  return st;
}

/* Whether every attribute message of obj decodes: asking for a name no
 * attribute has makes HDF5 decode them one by one, failing cleanly at a
 * damaged one. H5Aiterate2 (and H5Aopen_by_idx) first build a table of
 * them all and, when one fails to decode, crash releasing that table
 * (SIGSEGV in H5A__close under H5A__attr_release_table, HDF5 1.10.8; found
 * by tests/fuzz/fuzz_h5.c). */
static int attrs_decode(hid_t obj) {
  return H5Aexists(obj, "vesica: no attribute has this name") == 0;
}

/* Whether dataset d's stored size is its data's (elements times type
 * size) when its layout is contiguous (every dataset H5Ocopy copies here). */
static int contiguous_size_ok(hid_t d) {
  hid_t dcpl = H5Dget_create_plist(d), t = H5Dget_type(d), sp = H5Dget_space(d);
  const hssize_t np = sp < 0 ? -1 : H5Sget_simple_extent_npoints(sp);
  const size_t ts = t < 0 ? 0 : H5Tget_size(t);
  int ok = dcpl >= 0 && np >= 0 && ts > 0;
  if (ok && H5Pget_layout(dcpl) == H5D_CONTIGUOUS) ok = H5Dget_storage_size(d) == (hsize_t)np * ts;
  if (sp >= 0) H5Sclose(sp);
  if (t >= 0) H5Tclose(t);
  if (dcpl >= 0) H5Pclose(dcpl);
  return ok;
}

/* Whether object `name` below loc reads whole through HDF5's checking
 * readers: every attribute in its own type, a dataset's data (of our
 * types, its stored size that of its data), a group's members (depth
 * levels down) likewise. H5Ocopy copies raw metadata and trusts it: a
 * contiguous dataset whose recorded storage size exceeds its data (one
 * byte of its layout message changed), which H5Dopen2 and H5Dread accept,
 * crashed it (SIGSEGV in H5T_close_real under H5O_copy_header_map, HDF5
 * 1.10.8; found by tests/fuzz/fuzz_h5.c). */
static int object_readable(hid_t loc, const char *name, int depth) {
  hid_t o = H5Oopen(loc, name, H5P_DEFAULT);
  if (o < 0) return 0;
  const H5I_type_t type = H5Iget_type(o);
  int ok =
      attrs_decode(o) && H5Aiterate2(o, H5_INDEX_NAME, H5_ITER_INC, NULL, copy_attr, NULL) >= 0;
  if (ok && type == H5I_DATASET) {
    double *v = NULL;
    hsize_t count = 0;
    ok = contiguous_size_ok(o) && dset_read_all(loc, name, &v, &count) == VES_OK;
    free(v);
  } else if (ok && type == H5I_GROUP) {
    H5G_info_t gi;
    ok = depth > 0 && H5Gget_info(o, &gi) >= 0;
    for (hsize_t i = 0; ok && i < gi.nlinks; i++) {
      char member[64];
      const ssize_t len = H5Lget_name_by_idx(o, ".", H5_INDEX_NAME, H5_ITER_INC, i, member,
                                             sizeof member, H5P_DEFAULT);
      ok = len > 0 && len < (ssize_t)sizeof member && object_readable(o, member, depth - 1);
    }
  } else {
    ok = 0;
  }
  H5Oclose(o);
  return ok;
}

/* Object `name` of src copied to dst once it reads whole (object_readable). */
static ves_status copy_object(hid_t src, hid_t dst, const char *name) {
  if (!object_readable(src, name, 1)) return VES_ERR_IO;
  return H5Ocopy(src, name, dst, name, H5P_DEFAULT, H5P_DEFAULT) < 0 ? VES_ERR_IO : VES_OK;
}

/* Group `name` of src re-created in dst with the attributes of src's, and
 * count set to `count`. */
static ves_status copy_counted(hid_t src, hid_t dst, const char *name, int count) {
  hid_t s = H5Gopen2(src, name, H5P_DEFAULT);
  hid_t d = H5Gcreate2(dst, name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  ves_status st = s < 0 || d < 0 ? VES_ERR_IO : VES_OK;
  if (st == VES_OK &&
      (!attrs_decode(s) || H5Aiterate2(s, H5_INDEX_NAME, H5_ITER_INC, NULL, copy_attr, &d) < 0))
    st = VES_ERR_IO;
  if (st == VES_OK) st = attr_int(d, "count", count);
  for (int k = 0; k < count && st == VES_OK; k++) {
    char m[32];
    snprintf(m, sizeof m, "%d", k);
    st = copy_object(s, d, m);
  }
  if (d >= 0) H5Gclose(d);
  if (s >= 0) H5Gclose(s);
  return st;
}

/* Whether reference k of src reads whole and matches its checksum. */
static int reference_intact(ves_io *src, int k) {
  char name[48];
  snprintf(name, sizeof name, "references/%d", k);
  hid_t g = H5Gopen2(src->file, name, H5P_DEFAULT);
  if (g < 0) return 0;
  static const char *const part[5] = {"x", "h", "points", "weights", "phi0"};
  double *v[5] = {0};
  hsize_t c[5] = {0};
  long step = 0;
  uint64_t want = 0;
  int ok = attr_read(g, "checksum", H5T_NATIVE_UINT64, &want) == VES_OK &&
           attr_read(g, "step", H5T_NATIVE_LONG, &step) == VES_OK;
  for (int i = 0; i < 5 && ok; i++) ok = dset_read_all(g, part[i], &v[i], &c[i]) == VES_OK;
  const long n = (long)c[1], nq = (long)c[3]; /* after a remeshing not the header's n */
  ok = ok && c[0] == 2 * (hsize_t)n && c[2] == 2 * c[3] && c[4] == 6 * c[3] &&
       ref_sum(n, nq, v[0], v[1], v[2], v[3], v[4], step) == want;
  for (int i = 0; i < 5; i++) free(v[i]);
  H5Gclose(g);
  return ok;
}

/* Whether snapshot k of src is complete: its data and state, the series
 * rows up to it (read into col[], malloc'd), the references and the
 * remeshings it stands on read whole and match their checksums. *si gets
 * its state, *remeshes the number of those remeshings. */
static int snapshot_intact(ves_io *src, int k, ves_io_snapinfo *si, void **col, int *remeshes) {
  const int nk = ves_io_snapshot_nodes(src, k); /* after a remeshing not the header's n */
  const size_t n = nk > 0 ? (size_t)nk : 1;
  double *y = malloc(2 * n * sizeof *y), *x = malloc(2 * n * sizeof *x);
  double *phi = malloc(n * sizeof *phi), *yp = NULL;
  uint64_t want = 0, want_rows = 1, rows_sum_ = 0;
  char name[48];
  snprintf(name, sizeof name, "snapshots/%d", k);
  hid_t g = H5Gopen2(src->file, name, H5P_DEFAULT);
  int ok = nk > 0 && y && x && phi && g >= 0 &&
           ves_io_read_snapshot_n(src, k, nk, y, x, phi, si) == VES_OK &&
           attr_read(g, "checksum", H5T_NATIVE_UINT64, &want) == VES_OK &&
           attr_read(g, "series_checksum", H5T_NATIVE_UINT64, &want_rows) == VES_OK;
  if (ok && si->state.dt_prev > 0) /* the predictor's y^{n-1} is part of the sum */
    ok = (yp = malloc(2 * n * sizeof *yp)) && ves_io_read_snapshot_prev(src, k, nk, yp) == VES_OK;
  ok = ok && snap_sum((long)n, y, x, phi, yp, si) == want && si->rows >= 0;
  if (g >= 0) H5Gclose(g);
  free(y), free(x), free(phi), free(yp);
  for (int i = 0; i < NSERIES && ok; i++)
    ok = src->series[i] < 0 || dset_len(src->series[i]) >= (hsize_t)si->rows;
  if (ok && cols_read(src->series, si->rows, col) != VES_OK) ok = 0;
  if (ok) rows_sum_ = rows_sum(FNV_START, col, si->rows);
  if (ok && rows_sum_ != want_rows) ok = 0;
  for (int r = 0; r < si->reconnections && ok; r++) ok = reference_intact(src, r);
  /* the remeshings made at or before its step, every one whole */
  *remeshes = 0;
  for (int j = 0; ok && j < ves_io_remeshes(src); j++) {
    long step = 0;
    uint64_t sum = 0;
    snprintf(name, sizeof name, "remeshes/%d", j);
    hid_t rg = H5Gopen2(src->file, name, H5P_DEFAULT);
    ok = rg >= 0 && attr_read(rg, "step", H5T_NATIVE_LONG, &step) == VES_OK;
    if (ok && step <= si->state.nstep) {
      ok = attr_read(rg, "checksum", H5T_NATIVE_UINT64, &sum) == VES_OK &&
           group_sum(rg, REMESH_PARTS, NREMESH_PARTS) == sum;
      *remeshes = j + 1;
    }
    if (rg >= 0) H5Gclose(rg);
    if (ok && step > si->state.nstep) break;
  }
  if (!ok)
    for (int i = 0; i < NSERIES; i++) free(col[i]), col[i] = NULL;
  return ok;
}

/* The salvaged file `out` of src: header, parameters and mesh copied, the
 * series rows up to snapshot K (col[]) written anew, snapshots 0..K and the
 * references they need copied; the XDMF file of path rewritten for them. On
 * failure nothing is left at out, and why says what failed (starting with
 * '!' when out itself cannot be written: no point in another snapshot). */
static ves_status salvage_write(ves_io *src, const char *path, const char *out, int K,
                                const ves_io_snapinfo *si, void *const *col, int remeshes,
                                char *why, size_t whylen) {
  ves_io *dst = io_alloc(path, 1);
  if (!dst) return VES_ERR_ALLOC;
  hid_t d = H5Fcreate(out, H5F_ACC_EXCL, H5P_DEFAULT, H5P_DEFAULT);
  if (d < 0) {
    ves_error_say(why, whylen, "!%s: cannot create it (it must not exist)", out);
    ves_io_close(&dst);
    return VES_ERR_IO;
  }
  dst->file = d;
  dst->info.n = src->info.n, dst->info.ntri = src->info.ntri;
  errno = 0;
  const char *step = "the header";
  ves_status st = VES_OK;
  if (!attrs_decode(src->file) ||
      H5Aiterate2(src->file, H5_INDEX_NAME, H5_ITER_INC, NULL, copy_attr, &d) < 0 ||
      copy_object(src->file, d, "parameters") != VES_OK ||
      copy_object(src->file, d, "mesh") != VES_OK)
    st = VES_ERR_IO;
  if (st == VES_OK) st = attr_status(d, src->info.status); /* written last: maybe lost */
  if (st == VES_OK) st = attr_double(d, "setup_seconds", src->info.setup_seconds);
  if (st == VES_OK) {
    step = "the snapshots";
    st = copy_counted(src->file, d, "snapshots", K + 1);
  }
  if (st == VES_OK && si->reconnections > 0) {
    step = "the references";
    st = copy_counted(src->file, d, "references", si->reconnections);
  }
  if (st == VES_OK && remeshes > 0) {
    step = "the remeshings";
    st = copy_counted(src->file, d, "remeshes", remeshes);
  }
  if (st == VES_OK) {
    step = "the series";
    st = create_series(dst, src->series);
  }
  for (int i = 0; i < NSERIES && st == VES_OK && si->rows > 0; i++) {
    if (dst->series[i] < 0) continue; /* as in src: an optional column it lacks */
    hsize_t r = (hsize_t)si->rows;
    if (H5Dset_extent(dst->series[i], &r) < 0 ||
        H5Dwrite(dst->series[i], col_mem_type(SERIES[i].type), H5S_ALL, H5S_ALL, H5P_DEFAULT,
                 col[i]) < 0)
      st = VES_ERR_IO;
  }
  if (st == VES_OK && H5Fflush(d, H5F_SCOPE_LOCAL) < 0) st = VES_ERR_IO;
  if (st != VES_OK) {
    char reason[128] = ""; /* a system error is the new file's (the image has none) */
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, sys_reason, reason);
    if (reason[0])
      ves_error_say(why, whylen, "!%s: cannot write: %s", out, reason);
    else
      ves_error_say(why, whylen, "snapshot %d: %s do not copy", K, step);
  }
  if (st == VES_OK) { /* the XDMF file of path shows the snapshots kept */
    dst->nsnap = dst->snap_cap = K + 1;
    dst->snap_t = malloc((size_t)(K + 1) * sizeof *dst->snap_t);
    if (dst->snap_t) memcpy(dst->snap_t, src->snap_t, (size_t)(K + 1) * sizeof *dst->snap_t);
    if (!dst->snap_t || xdmf_write(dst) != VES_OK)
      dst->nsnap = 0; /* rewritten at the next snapshot */
  }
  ves_io_close(&dst);
  if (st != VES_OK) remove(out);
  return st;
}

ves_status ves_io_salvage(const char *path, const char *out, ves_io_salvaged *res, char *err,
                          size_t errlen) {
  VES_CHECK(path && out && res, VES_ERR_ARG);
  memset(res, 0, sizeof *res);
  quiet_hdf5();
  long long size = 0, stored = 0;
  if (!ves_io_cut_short(path, &size, &stored)) {
    ves_error_say(err, errlen, "%s: not cut short (its size is the one its superblock records)",
                  path);
    return VES_ERR_ARG;
  }
  res->size = size, res->stored_size = stored;
  /* the image is held in memory, twice at its peak (HDF5 copies it): a
   * recorded end past a quarter of the machine's memory is refused, not
   * allocated (a damaged superblock records any size up to 2^50) */
  const double mem = (double)sysconf(_SC_PHYS_PAGES) * (double)sysconf(_SC_PAGESIZE);
  if (mem > 0 && (double)stored > mem / 4) {
    ves_error_say(err, errlen,
                  "%s: its superblock records %lld bytes, more than a quarter of this machine's "
                  "memory (%.1f GB), which the salvage holds it in (a damaged superblock?)",
                  path, stored, mem / 1e9);
    return VES_ERR_IO;
  }
  /* the file read whole and padded with zeros to its recorded end: lost
   * blocks read back as zeros, which the checksums reject */
  unsigned char *img = calloc((size_t)stored, 1);
  FILE *f = img ? fopen(path, "rb") : NULL;
  const int read_ok = f && fread(img, 1, (size_t)size, f) == (size_t)size;
  if (f) fclose(f);
  if (!read_ok) {
    free(img);
    ves_error_say(err, errlen, "%s: %s", path, img ? "cannot read it" : "out of memory");
    return img ? VES_ERR_IO : VES_ERR_ALLOC;
  }
  hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  ves_io *src = io_alloc(path, 0);
  ves_status st = fapl >= 0 && src && H5Pset_fapl_core(fapl, 1 << 20, 0) >= 0 &&
                          H5Pset_file_image(fapl, img, (size_t)stored) >= 0
                      ? VES_OK
                      : VES_ERR_ALLOC;
  free(img); /* the property list holds a copy */
  if (st == VES_OK) {
    src->tolerant = 1;
    /* a name no file has: the core driver refuses an image named as a file */
    src->file = H5Fopen("/nonexistent/vesica-salvage-image", H5F_ACC_RDONLY, fapl);
    st = src->file < 0 || read_header(src) != VES_OK ? VES_ERR_IO : VES_OK;
    if (st != VES_OK) ves_error_say(err, errlen, "%s: its header is lost too", path);
  }
  if (fapl >= 0) H5Pclose(fapl);
  /* the last snapshot that is complete and copies whole (a copy can still
   * meet a lost block the checksums do not cover: then the one before) */
  int K = st == VES_OK ? src->nsnap - 1 : -1, found = 0;
  char why[2 * PATH_MAX] = "";
  ves_io_snapinfo si;
  for (; st == VES_OK && K >= 0; K--) {
    void *col[NSERIES] = {0};
    int remeshes = 0;
    if (!snapshot_intact(src, K, &si, col, &remeshes)) continue;
    found = 1;
    st = salvage_write(src, path, out, K, &si, col, remeshes, why, sizeof why);
    for (int i = 0; i < NSERIES; i++) free(col[i]);
    if (st == VES_OK) break;
    if (st == VES_ERR_ALLOC || why[0] == '!') break; /* out of memory, out not writable */
    st = VES_OK;
  }
  if (st == VES_OK && K < 0) {
    st = VES_ERR_IO;
    if (found)
      ves_error_say(err, errlen, "%s: its surviving snapshots cannot be copied whole (%s)", path,
                    why);
    else
      ves_error_say(
          err, errlen,
          "%s: none of its %d snapshot(s) survived whole (or they carry no checksums: written "
          "by an older vesica)",
          path, src->nsnap);
  } else if (st != VES_OK && why[0] == '!') {
    ves_error_say(err, errlen, "%s", why + 1);
  }
  if (st == VES_OK) {
    hid_t g = H5Gopen2(src->file, "snapshots", H5P_DEFAULT); /* as counted, lost or not */
    if (g < 0 || attr_read(g, "count", H5T_NATIVE_INT, &res->snapshots) != VES_OK)
      res->snapshots = src->nsnap;
    if (g >= 0) H5Gclose(g);
    res->snapshot = K, res->rows = si.rows;
    res->step = si.state.nstep, res->t = si.state.t, res->references = si.reconnections;
  }
  ves_io_close(&src);
  return st;
}
