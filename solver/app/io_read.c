/* vesica — reading the run output (vesica info, plot, run --restart):
 * opening and checking the header, snapshots, references, remeshings and
 * the node set each snapshot is on. Layout: app/io.h; docs/design.md,
 * "The program". */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "app/io_impl.h"

/* H5Ewalk2 callback: the description of the innermost error that says why
 * a file cannot be opened ("truncated file: eof = ..., stored_eof = ..."). */
static herr_t hdf5_reason(unsigned n, const H5E_error2_t *e, void *data) {
  char *out = data;
  if (n == 0 && e->desc) snprintf(out, 128, "%s", e->desc);
  if (e->desc && strstr(e->desc, "truncated")) snprintf(out, 128, "%s", e->desc);
  return 0;
}

/* Count the complete snapshots and read their times. */
static ves_status read_snapshot_times(ves_io *io) {
  hid_t s = H5Gopen2(io->file, "snapshots", H5P_DEFAULT);
  if (s < 0) return VES_ERR_CONFIG;
  int count = 0;
  ves_status st = io_attr_read(s, "count", H5T_NATIVE_INT, &count);
  if (st == VES_OK && count < 0) st = VES_ERR_CONFIG;
  if (st == VES_OK && count > 0) {
    io->snap_t = malloc((size_t)count * sizeof *io->snap_t);
    io->snap_cap = count;
    if (!io->snap_t) st = VES_ERR_ALLOC;
  }
  for (int k = 0; k < count && st == VES_OK; k++) {
    char name[32];
    snprintf(name, sizeof name, "%d", k);
    hid_t g = H5Lexists(s, name, H5P_DEFAULT) > 0 ? H5Gopen2(s, name, H5P_DEFAULT) : -1;
    st = g < 0 ? VES_ERR_CONFIG : io_attr_read_double(g, "t", &io->snap_t[k]);
    if (g >= 0) H5Gclose(g);
    if (st != VES_OK && !io->tolerant)
      snprintf(io->corrupt, sizeof io->corrupt,
               "/snapshots/%d: %s (the group's count says %d snapshots)", k,
               g < 0 ? "missing" : "its attribute t does not read", count);
    if (st != VES_OK && io->tolerant) { /* a salvage: the snapshots before it */
      count = k, st = VES_OK;
      break;
    }
  }
  H5Gclose(s);
  if (st == VES_OK) io->nsnap = count;
  return st;
}

/* The header of the open file io->file into io->info, its series opened
 * and its snapshots counted; VES_ERR_CONFIG when it is not a vesica file of
 * a known format (a salvage, io->tolerant, passes a lost status or setup
 * time). */
ves_status io_read_header(ves_io *io) {
  hid_t f = io->file;
  ves_io_info *in = &io->info;
  char prog[32];
  if (io_attr_read(f, "format_version", H5T_NATIVE_INT, &in->format_version) != VES_OK ||
      io_attr_read_buf(f, "program", prog, sizeof prog) != VES_OK || strcmp(prog, "vesica"))
    return VES_ERR_CONFIG;
  if (in->format_version < 1 || in->format_version > VES_IO_FORMAT) return VES_ERR_CONFIG;
  /* format 1 snapshots have no x: read-only (a restart would mix formats); a
   * format 2 file is continued as written (no initial state's row; its new
   * snapshots get interface curves, which its readers pass by) */
  if (io->writable && in->format_version < 2) return VES_ERR_CONFIG;
  VES_CALL(io_attr_read_buf(f, "version", in->version, sizeof in->version));
  VES_CALL(io_attr_read_buf(f, "backend", in->backend, sizeof in->backend));
  /* a salvage takes a file whose status (written last) was lost as killed */
  if (io_attr_read_buf(f, "status", in->status, sizeof in->status) != VES_OK) {
    if (!io->tolerant) return VES_ERR_CONFIG;
    snprintf(in->status, sizeof in->status, "running");
  }
  VES_CALL(io_attr_read(f, "nodes", H5T_NATIVE_INT, &in->n));
  VES_CALL(io_attr_read_str(f, "problem", &in->problem));
  VES_CALL(io_attr_read_str(f, "source", &in->source));
  VES_CALL(io_attr_read_double(f, "E0", &in->E0));
  VES_CALL(io_attr_read_double(f, "A0", &in->A0));
  VES_CALL(io_attr_read_double(f, "V0", &in->V0));
  if (io_attr_read_double(f, "setup_seconds", &in->setup_seconds) != VES_OK && !io->tolerant)
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
  for (int i = 0; i < IO_NSERIES; i++) {
    char name[64];
    snprintf(name, sizeof name, "series/%s", io_series[i].name);
    if (io_col_optional(i) && H5Lexists(f, name, H5P_DEFAULT) == 0)
      continue; /* optional: absent here */
    io->series[i] = H5Dopen2(f, name, H5P_DEFAULT);
    if (io->series[i] < 0 || !io_numeric_type_ok(io->series[i], 0)) return VES_ERR_CONFIG;
  }
  /* the row of the initial state: step 0 first (a step row holds step >= 1) */
  long step0 = -1;
  hsize_t zero = 0, one = 1;
  const hid_t ds = io->series[IO_NSERIES - 1];
  if (io_dset_len(ds) > 0) {
    hid_t fs = H5Dget_space(ds), ms = H5Screate_simple(1, &one, NULL);
    if (fs >= 0 && ms >= 0 && H5Sselect_hyperslab(fs, H5S_SELECT_SET, &zero, NULL, &one, NULL) >= 0)
      H5Dread(ds, H5T_NATIVE_LONG, ms, fs, H5P_DEFAULT, &step0);
    if (ms >= 0) H5Sclose(ms);
    if (fs >= 0) H5Sclose(fs);
  }
  io->row0 = step0 == 0;
  return read_snapshot_times(io);
}

const char *ves_io_corruption(const ves_io *io) { return io ? io->corrupt : ""; }

const char *ves_io_note(const ves_io *io) { return io ? io->note : ""; }

/* Counted group `parent` (absent: fine): its count readable and not
 * negative, its members 0..count-1 there as groups. A group whose count
 * names members it lacks is corruption (a reader would otherwise fail
 * later, mid-way, and a restart write into it). */
static ves_status counted_intact(ves_io *io, const char *parent) {
  if (H5Lexists(io->file, parent, H5P_DEFAULT) <= 0) return VES_OK;
  hid_t g = H5Gopen2(io->file, parent, H5P_DEFAULT);
  int count = -1;
  if (g < 0 || io_attr_read(g, "count", H5T_NATIVE_INT, &count) != VES_OK || count < 0) {
    snprintf(io->corrupt, sizeof io->corrupt, "/%s: %s", parent,
             g < 0 ? "not a group" : "its attribute count is missing, malformed or negative");
    if (g >= 0) H5Gclose(g);
    return VES_ERR_CONFIG;
  }
  ves_status st = VES_OK;
  for (int k = 0; k < count && st == VES_OK; k++) {
    char name[32];
    snprintf(name, sizeof name, "%d", k);
    H5O_info_t oi;
    if (H5Lexists(g, name, H5P_DEFAULT) <= 0 ||
        H5Oget_info_by_name(g, name, &oi, H5P_DEFAULT) < 0 || oi.type != H5O_TYPE_GROUP) {
      snprintf(io->corrupt, sizeof io->corrupt,
               "/%s/%d: missing or not a group (the group's count says %d members)", parent, k,
               count);
      st = VES_ERR_CONFIG;
    }
  }
  H5Gclose(g);
  return st;
}

/* The stored problem text against its checksum (a file without one: a note). */
static ves_status problem_intact(ves_io *io) {
  uint64_t want = 0;
  if (H5Aexists(io->file, "problem_checksum") <= 0) {
    snprintf(io->note, sizeof io->note,
             "the file stores no checksum of its problem text (an older layout): read unchecked");
    return VES_OK;
  }
  if (io_attr_read(io->file, "problem_checksum", H5T_NATIVE_UINT64, &want) != VES_OK ||
      io_fnv(FNV_START, io->info.problem, strlen(io->info.problem)) != want) {
    snprintf(io->corrupt, sizeof io->corrupt,
             "the root attribute problem (the stored problem text) does not match its checksum "
             "(problem_checksum)");
    return VES_ERR_CONFIG;
  }
  return VES_OK;
}

/* The first non-finite value in the first `rows` rows of the double
 * columns col[] (a NaN a bit flip made, say): named into buf. */
static void first_nonfinite(void *const *col, long rows, char *buf, size_t len) {
  buf[0] = 0;
  for (int i = 0; i < IO_NSERIES; i++) {
    if (!col[i] || io_series[i].type != COL_DOUBLE) continue;
    const double *v = col[i];
    for (long r = 0; r < rows; r++)
      if (!isfinite(v[r])) {
        snprintf(buf, len, " (/series/%s row %ld = %g)", io_series[i].name, r, v[r]);
        return;
      }
  }
}

/* The first rows of the series against the series_checksum of snapshot k
 * (a snapshot without one: nothing to check). */
static ves_status series_intact(ves_io *io, int k, long rows) {
  char name[48];
  snprintf(name, sizeof name, "snapshots/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_CONFIG;
  uint64_t want = 0;
  const int has = H5Aexists(g, "series_checksum") > 0;
  ves_status st = has ? io_attr_read(g, "series_checksum", H5T_NATIVE_UINT64, &want) : VES_OK;
  if (st == VES_OK && rows < 0) st = io_attr_read(g, "rows", H5T_NATIVE_LONG, &rows);
  H5Gclose(g);
  if (st != VES_OK || (has && rows < 0)) {
    snprintf(io->corrupt, sizeof io->corrupt,
             "/snapshots/%d: its attribute rows or "
             "series_checksum does not read",
             k);
    return VES_ERR_CONFIG;
  }
  if (!has) return VES_OK;
  rows = io_rows_covered(io, rows); /* with the initial state's row */
  for (int i = 0; i < IO_NSERIES; i++)
    if (io->series[i] >= 0 && io_dset_len(io->series[i]) < (hsize_t)rows) {
      snprintf(io->corrupt, sizeof io->corrupt,
               "/series/%s: %llu rows, fewer than the %ld snapshot %d records", io_series[i].name,
               (unsigned long long)io_dset_len(io->series[i]), rows, k);
      return VES_ERR_CONFIG;
    }
  void *col[IO_NSERIES];
  if ((st = io_cols_read(io->series, rows, col)) != VES_OK) {
    if (st != VES_ERR_ALLOC)
      snprintf(io->corrupt, sizeof io->corrupt,
               "/series: a column does not read (of another shape or type)");
    return st == VES_ERR_ALLOC ? st : VES_ERR_CONFIG;
  }
  if (io_rows_sum(FNV_START, col, rows) != want) {
    char where[160];
    first_nonfinite(col, rows, where, sizeof where);
    snprintf(io->corrupt, sizeof io->corrupt,
             "/series: its first %ld rows do not match the checksum snapshot %d stores "
             "(series_checksum)%s",
             rows, k, where);
    st = VES_ERR_CONFIG;
  }
  for (int i = 0; i < IO_NSERIES; i++) free(col[i]);
  return st;
}

/* What an open verifies: the counted groups, the problem text and (mode
 * VES_IO_READ) the series rows the last snapshot sums. */
static ves_status open_verify(ves_io *io, int mode) {
  VES_CALL(counted_intact(io, "references"));
  VES_CALL(counted_intact(io, "remeshes"));
  VES_CALL(problem_intact(io));
  if (mode == VES_IO_READ && io->nsnap > 0) VES_CALL(series_intact(io, io->nsnap - 1, -1));
  return VES_OK;
}

ves_status ves_io_open(const char *path, int writable, ves_io **out, char *err, size_t errlen) {
  VES_CHECK(path && out, VES_ERR_ARG);
  const int mode = writable;
  writable = writable == VES_IO_WRITE;
  *out = NULL;
  io_quiet_hdf5();
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
  ves_status st = io_read_header(io);
  if (st == VES_OK) st = open_verify(io, mode);
  io->prov_pending = writable; /* a restart: its own provenance, at its first write */
  if (st != VES_OK) {
    if (st == VES_ERR_CONFIG && io->corrupt[0])
      ves_error_say(err, errlen, "%s: corrupt: %s", path, io->corrupt);
    else if (st == VES_ERR_CONFIG && io->info.format_version > VES_IO_FORMAT)
      ves_error_say(err, errlen, "%s: format_version %d: this vesica reads format_version 1 to %d",
                    path, io->info.format_version, VES_IO_FORMAT);
    else if (st == VES_ERR_CONFIG && writable && io->info.format_version >= 1 &&
             io->info.format_version < 2)
      ves_error_say(err, errlen, "%s: format_version %d is read-only: it cannot be continued", path,
                    io->info.format_version);
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

int ves_io_snapshots(const ves_io *io) { return io->nsnap; }

ves_status ves_io_read_snapshot(ves_io *io, int k, double *y, double *x, double *phi,
                                ves_io_snapinfo *si) {
  VES_CHECK(io, VES_ERR_ARG);
  return ves_io_read_snapshot_n(io, k, io->info.n, y, x, phi, si);
}

static ves_status read_snapshot_raw(ves_io *io, int k, int nbuf, double *y, double *x, double *phi,
                                    ves_io_snapinfo *si) {
  char name[48];
  snprintf(name, sizeof name, "snapshots/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  hsize_t n = (hsize_t)nbuf; /* the datasets must have exactly this size */
  ves_status st = VES_OK;
  const char *bad = NULL; /* the dataset that does not read */
  if (y && (st = io_dset_read(g, "y", H5T_NATIVE_DOUBLE, 2 * n, y)) != VES_OK) bad = "y";
  /* format 1 has no x: its snapshots showed the coefficients */
  if (st == VES_OK && x &&
      (st = io_dset_read(g, io->info.format_version >= 2 ? "x" : "y", H5T_NATIVE_DOUBLE, 2 * n,
                         x)) != VES_OK)
    bad = "x";
  if (st == VES_OK && phi && (st = io_dset_read(g, "phi", H5T_NATIVE_DOUBLE, n, phi)) != VES_OK)
    bad = "phi";
  if (bad)
    snprintf(io->corrupt, sizeof io->corrupt,
             "/snapshots/%d/%s: does not read (missing, or of another size or type)", k, bad);
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
      st = io_attr_read_double(g, d[i].name, d[i].v);
    if (st == VES_OK) st = io_attr_read(g, "step", H5T_NATIVE_LONG, &s->nstep);
    if (st == VES_OK) st = io_attr_read(g, "rows", H5T_NATIVE_LONG, &si->rows);
    if (st == VES_OK) st = io_attr_read(g, "reconnections", H5T_NATIVE_INT, &si->reconnections);
    /* the controller's memory of rejected steps (optional: none when absent) */
    if (st == VES_OK && H5Aexists(g, "dt_rejected") > 0)
      st = io_attr_read_double(g, "dt_rejected", &s->dt_rejected);
    if (st == VES_OK && H5Aexists(g, "since_rejected") > 0)
      st = io_attr_read(g, "since_rejected", H5T_NATIVE_LONG, &s->since_rejected);
    /* the predictor's state (optional: absent when none was held) */
    if (st == VES_OK && H5Aexists(g, "dt_prev") > 0)
      st = io_attr_read_double(g, "dt_prev", &s->dt_prev);
    if (st == VES_OK && !(isfinite(s->dt_prev) && s->dt_prev >= 0)) st = VES_ERR_IO;
  }
  H5Gclose(g);
  return st;
}

/* Snapshot k read whole (y, x, phi, its state and y_prev) and checked
 * against its checksum and for finite numbers; the parts asked for copied
 * out. A salvage (io->tolerant) and format 1 read it unchecked. */
ves_status ves_io_read_snapshot_n(ves_io *io, int k, int nbuf, double *y, double *x, double *phi,
                                  ves_io_snapinfo *si) {
  VES_CHECK(io && k >= 0 && k < io->nsnap && nbuf > 0, VES_ERR_ARG);
  if (io->tolerant || io->info.format_version < 2)
    return read_snapshot_raw(io, k, nbuf, y, x, phi, si);
  /* only the state asked for: verified on the snapshot's own node set (a
   * remeshing's, not the header's) */
  const int nk = !y && !x && !phi ? ves_io_snapshot_nodes(io, k) : -1;
  if (nk > 0) nbuf = nk;
  const size_t n = (size_t)nbuf;
  double *ty = y ? y : malloc(2 * n * sizeof *ty), *tx = x ? x : malloc(2 * n * sizeof *tx);
  double *tp = phi ? phi : malloc(n * sizeof *tp), *yp = NULL;
  ves_io_snapinfo tsi, *s = si ? si : &tsi;
  io->corrupt[0] = 0;
  ves_status st = ty && tx && tp ? read_snapshot_raw(io, k, nbuf, ty, tx, tp, s) : VES_ERR_ALLOC;
  if (st != VES_OK && st != VES_ERR_ALLOC && !io->corrupt[0])
    snprintf(io->corrupt, sizeof io->corrupt,
             "/snapshots/%d: an attribute of its state does not read (missing, or of another "
             "type)",
             k);
  const ves_sim_state *ss = &s->state;
  const struct {
    const char *name;
    double v;
  } fin[] = {{"t", ss->t}, {"dt", ss->dt}, {"E", ss->E}, {"A", ss->A}, {"V", ss->V}};
  for (size_t i = 0; st == VES_OK && i < sizeof fin / sizeof fin[0]; i++)
    if (!isfinite(fin[i].v)) {
      snprintf(io->corrupt, sizeof io->corrupt, "/snapshots/%d: attribute %s = %g (not finite)", k,
               fin[i].name, fin[i].v);
      st = VES_ERR_CONFIG;
    }
  char name[48];
  snprintf(name, sizeof name, "snapshots/%d", k);
  hid_t g = st == VES_OK ? H5Gopen2(io->file, name, H5P_DEFAULT) : -1;
  uint64_t want = 0;
  if (g >= 0 && H5Aexists(g, "checksum") > 0) {
    if (ss->dt_prev > 0 && !(yp = malloc(2 * n * sizeof *yp))) st = VES_ERR_ALLOC;
    if (st == VES_OK && ss->dt_prev > 0 &&
        (st = ves_io_read_snapshot_prev(io, k, nbuf, yp)) != VES_OK)
      snprintf(io->corrupt, sizeof io->corrupt, "/snapshots/%d/y_prev: does not read", k);
    if (st == VES_OK && (io_attr_read(g, "checksum", H5T_NATIVE_UINT64, &want) != VES_OK ||
                         io_snap_sum(nbuf, ty, tx, tp, yp, s) != want)) {
      snprintf(io->corrupt, sizeof io->corrupt,
               "/snapshots/%d: its data (y, x, phi%s) and state attributes do not match its "
               "checksum",
               k, ss->dt_prev > 0 ? ", y_prev" : "");
      st = VES_ERR_CONFIG;
    }
  }
  if (g >= 0) H5Gclose(g);
  if (!y) free(ty);
  if (!x) free(tx);
  if (!phi) free(tp);
  free(yp);
  return st;
}

/* Reference k against its checksum. */
static ves_status reference_intact(ves_io *io, int k) {
  char name[48];
  snprintf(name, sizeof name, "references/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_CONFIG;
  static const char *const part[5] = {"x", "h", "points", "weights", "phi0"};
  double *v[5] = {0};
  hsize_t c[5] = {0};
  long step = 0;
  uint64_t want = 0;
  int ok = 1;
  if (H5Aexists(g, "checksum") > 0) {
    ok = io_attr_read(g, "checksum", H5T_NATIVE_UINT64, &want) == VES_OK &&
         io_attr_read(g, "step", H5T_NATIVE_LONG, &step) == VES_OK;
    for (int i = 0; i < 5 && ok; i++) {
      hid_t d = H5Dopen2(g, part[i], H5P_DEFAULT);
      hid_t sp = d < 0 ? -1 : H5Dget_space(d);
      const hssize_t np = sp < 0 ? -1 : H5Sget_simple_extent_npoints(sp);
      ok = np > 0 && io_numeric_type_ok(d, 0) && (v[i] = malloc((size_t)np * sizeof *v[i])) &&
           H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v[i]) >= 0;
      c[i] = ok ? (hsize_t)np : 0;
      if (sp >= 0) H5Sclose(sp);
      if (d >= 0) H5Dclose(d);
    }
    const long n = (long)c[1], nq = (long)c[3];
    ok = ok && c[0] == 2 * (hsize_t)n && c[2] == 2 * c[3] && c[4] == 6 * c[3] &&
         io_ref_sum(n, nq, v[0], v[1], v[2], v[3], v[4], step) == want;
  }
  for (int i = 0; i < 5; i++) free(v[i]);
  H5Gclose(g);
  if (!ok)
    snprintf(io->corrupt, sizeof io->corrupt,
             "/references/%d: its data (x, h, points, weights, phi0) do not match its checksum", k);
  return ok ? VES_OK : VES_ERR_CONFIG;
}

ves_status ves_io_verify_snapshot(ves_io *io, int k) {
  VES_CHECK(io && k >= 0 && k < io->nsnap, VES_ERR_ARG);
  const int nk = ves_io_snapshot_nodes(io, k);
  if (nk <= 0) {
    snprintf(io->corrupt, sizeof io->corrupt, "/snapshots/%d/y: missing or malformed", k);
    return VES_ERR_CONFIG;
  }
  ves_io_snapinfo si;
  VES_CALL(ves_io_read_snapshot_n(io, k, nk, NULL, NULL, NULL, &si));
  VES_CALL(series_intact(io, k, si.rows));
  /* the references it stands on that the file holds (a file with fewer is
   * refused by the restart's rebuild, which says how many it needs) */
  for (int r = 0; r < si.reconnections && r < ves_io_references(io); r++)
    VES_CALL(reference_intact(io, r));
  for (int j = 0; j < ves_io_remeshes(io); j++) {
    long step = 0;
    uint64_t sum = 0;
    char name[48];
    snprintf(name, sizeof name, "remeshes/%d", j);
    hid_t rg = H5Gopen2(io->file, name, H5P_DEFAULT);
    int ok = rg >= 0 && io_attr_read(rg, "step", H5T_NATIVE_LONG, &step) == VES_OK;
    if (ok && step <= si.state.nstep && H5Aexists(rg, "checksum") > 0)
      ok = io_attr_read(rg, "checksum", H5T_NATIVE_UINT64, &sum) == VES_OK &&
           io_group_sum(rg, io_remesh_parts, IO_NREMESH_PARTS) == sum;
    if (rg >= 0) H5Gclose(rg);
    if (!ok) {
      snprintf(io->corrupt, sizeof io->corrupt,
               "/remeshes/%d: its data or step do not match its checksum", j);
      return VES_ERR_CONFIG;
    }
    if (step > si.state.nstep) break;
  }
  return VES_OK;
}

int ves_io_last_intact(ves_io *io, int k) {
  char keep[sizeof io->corrupt];
  snprintf(keep, sizeof keep, "%s", io->corrupt);
  int j = k - 1;
  while (j >= 0 && ves_io_verify_snapshot(io, j) != VES_OK) j--;
  snprintf(io->corrupt, sizeof io->corrupt, "%s", keep);
  return j;
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
    ves_status st = io_dset_read(g, dset, H5T_NATIVE_DOUBLE, 2 * (hsize_t)nbuf, out);
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
  if (X) VES_CALL(io_dset_read(io->file, "mesh/X", H5T_NATIVE_DOUBLE, 2 * (hsize_t)io->info.n, X));
  if (tri)
    VES_CALL(
        io_dset_read(io->file, "mesh/triangles", H5T_NATIVE_INT, 3 * (hsize_t)io->info.ntri, tri));
  return VES_OK;
}

/* The complete references: /references attribute count (0 without the group). */
int ves_io_references(const ves_io *io) {
  if (!io || H5Lexists(io->file, "references", H5P_DEFAULT) <= 0) return 0;
  hid_t g = H5Gopen2(io->file, "references", H5P_DEFAULT);
  int count = 0;
  if (g >= 0 && io_attr_read(g, "count", H5T_NATIVE_INT, &count) != VES_OK) count = 0;
  if (g >= 0) H5Gclose(g);
  return count;
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
  ves_status st = io_dset_read(g, "x", M, 2 * n, out->x);
  if (st == VES_OK) st = io_dset_read(g, "h", M, n, out->h);
  if (st == VES_OK) st = io_dset_read(g, "points", M, 2 * nq, out->xq);
  if (st == VES_OK) st = io_dset_read(g, "weights", M, nq, out->wq);
  if (st == VES_OK) st = io_dset_read(g, "phi0", M, 6 * nq, out->pd);
  if (st == VES_OK) st = io_attr_read(g, "step", H5T_NATIVE_LONG, &out->step);
  H5Gclose(g);
  return st;
}

/* The complete remeshings: /remeshes attribute count (0 without the group). */
int ves_io_remeshes(const ves_io *io) {
  if (!io || H5Lexists(io->file, "remeshes", H5P_DEFAULT) <= 0) return 0;
  hid_t g = H5Gopen2(io->file, "remeshes", H5P_DEFAULT);
  int count = 0;
  if (g >= 0 && io_attr_read(g, "count", H5T_NATIVE_INT, &count) != VES_OK) count = 0;
  if (g >= 0) H5Gclose(g);
  return count;
}

ves_status ves_io_remesh_size(const ves_io *io, int k, long *step, int *n, int *ntri) {
  VES_CHECK(io && k >= 0 && k < ves_io_remeshes(io), VES_ERR_ARG);
  char name[48];
  snprintf(name, sizeof name, "remeshes/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  long s = 0;
  ves_status st = io_attr_read(g, "step", H5T_NATIVE_LONG, &s);
  const int nn = (int)io_dset_rows(g, "x"), nt = (int)io_dset_rows(g, "triangles");
  H5Gclose(g);
  if (st == VES_OK && (nn < 3 || nt < 1)) st = VES_ERR_IO;
  if (st != VES_OK) return st;
  if (step) *step = s;
  if (n) *n = nn;
  if (ntri) *ntri = nt;
  return VES_OK;
}

/* Real nodes of the state now: the last remeshing's, or the header's. */
int io_nodes_now(const ves_io *io) {
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
  const hsize_t n = io_dset_rows(g, "y");
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
  ves_status st = io_attr_read(g, "step", H5T_NATIVE_LONG, &step);
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

ves_status ves_io_read_remesh(ves_io *io, int k, ves_io_remesh_buf *out) {
  VES_CHECK(io && out && out->x && out->h && out->flag && out->phi0c && out->n > 0, VES_ERR_ARG);
  VES_CHECK(k >= 0 && k < ves_io_remeshes(io), VES_ERR_ARG);
  char name[48];
  snprintf(name, sizeof name, "remeshes/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  const hsize_t n = (hsize_t)out->n;
  const hid_t M = H5T_NATIVE_DOUBLE;
  ves_status st = io_dset_read(g, "x", M, 2 * n, out->x);
  if (st == VES_OK) st = io_dset_read(g, "h", M, n, out->h);
  if (st == VES_OK) st = io_dset_read(g, "flag", H5T_NATIVE_INT, n, out->flag);
  if (st == VES_OK) st = io_dset_read(g, "phi0c", M, n, out->phi0c);
  if (st == VES_OK) st = io_attr_read(g, "step", H5T_NATIVE_LONG, &out->step);
  H5Gclose(g);
  return st;
}

ves_status ves_io_reference_step(const ves_io *io, int k, long *step) {
  VES_CHECK(io && step && k >= 0 && k < ves_io_references(io), VES_ERR_ARG);
  char name[48];
  snprintf(name, sizeof name, "references/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  ves_status st = io_attr_read(g, "step", H5T_NATIVE_LONG, step);
  H5Gclose(g);
  return st;
}

ves_status ves_io_read_remesh_triangles(ves_io *io, int k, int *tri) {
  int nt = 0;
  VES_CHECK(tri, VES_ERR_ARG);
  VES_CALL(ves_io_remesh_size(io, k, NULL, NULL, &nt));
  char name[48];
  snprintf(name, sizeof name, "remeshes/%d/triangles", k);
  return io_dset_read(io->file, name, H5T_NATIVE_INT, 3 * (hsize_t)nt, tri);
}
