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
    hid_t g = H5Gopen2(s, name, H5P_DEFAULT);
    st = g < 0 ? VES_ERR_CONFIG : io_attr_read_double(g, "t", &io->snap_t[k]);
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
  /* format 1 snapshots have no x: read-only (a restart would mix formats) */
  if (io->writable && in->format_version != VES_IO_FORMAT) return VES_ERR_CONFIG;
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
  return read_snapshot_times(io);
}

ves_status ves_io_open(const char *path, int writable, ves_io **out, char *err, size_t errlen) {
  VES_CHECK(path && out, VES_ERR_ARG);
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
  if (st != VES_OK) {
    if (st == VES_ERR_CONFIG && io->info.format_version > VES_IO_FORMAT)
      ves_error_say(err, errlen, "%s: format_version %d: this vesica reads format_version 1 to %d",
                    path, io->info.format_version, VES_IO_FORMAT);
    else if (st == VES_ERR_CONFIG && writable && io->info.format_version >= 1 &&
             io->info.format_version < VES_IO_FORMAT)
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

ves_status ves_io_read_snapshot_n(ves_io *io, int k, int nbuf, double *y, double *x, double *phi,
                                  ves_io_snapinfo *si) {
  VES_CHECK(io && k >= 0 && k < io->nsnap && nbuf > 0, VES_ERR_ARG);
  char name[48];
  snprintf(name, sizeof name, "snapshots/%d", k);
  hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  hsize_t n = (hsize_t)nbuf; /* the datasets must have exactly this size */
  ves_status st = VES_OK;
  if (y) st = io_dset_read(g, "y", H5T_NATIVE_DOUBLE, 2 * n, y);
  /* format 1 has no x: its snapshots showed the coefficients */
  if (st == VES_OK && x)
    st = io_dset_read(g, io->info.format_version >= 2 ? "x" : "y", H5T_NATIVE_DOUBLE, 2 * n, x);
  if (st == VES_OK && phi) st = io_dset_read(g, "phi", H5T_NATIVE_DOUBLE, n, phi);
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
