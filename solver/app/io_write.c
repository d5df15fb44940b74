/* vesica — writing the run output: a new file's header, parameters and
 * mesh; snapshots, references and remeshings as counted groups; the status
 * and problem text; the room check before a step. Layout: app/io.h;
 * docs/design.md, "The program". */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>

#include "app/io_impl.h"
#include "ves/level_set.h"

/* The bytes `snapshots` snapshots write into the HDF5 file at most (y, x,
 * phi, y_prev, velocity: 9 values a node, and HDF5's metadata: IO_ROOM_MARGIN,
 * a bound measured with room to spare: a 64-snapshot file grows by < 8 KiB
 * a snapshot beyond its data). */
static double snapshot_bytes(const ves_io *io, int snapshots) {
  /* and the interface: twice the last one's (io->iface_bytes; a snapshot
   * reserves its own, known then, before it writes) */
  return IO_ROOM_MARGIN + snapshots * (9 * 8.0 * io_nodes_now(io) + 4096 + 2 * io->iface_bytes);
}

/* Every configuration key as a typed attribute of /parameters. */
static ves_status write_parameters(hid_t file, const ves_config *cfg) {
  hid_t g = H5Lexists(file, "parameters", H5P_DEFAULT) > 0
                ? H5Gopen2(file, "parameters", H5P_DEFAULT)
                : H5Gcreate2(file, "parameters", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  ves_status st = io_describe(g, "see vesica keys",
                              "every problem-file key as an attribute section.key (units and "
                              "meaning: vesica keys, problems/README.md)");
  for (int i = 0; i < ves_config_count() && st == VES_OK; i++) {
    ves_config_entry e;
    char name[128];
    ves_config_entry_get(cfg, i, &e);
    snprintf(name, sizeof name, "%s.%s", e.section, e.key);
    if (e.type == VES_KEY_REAL)
      st = io_attr_double(g, name, e.real);
    else if (e.type == VES_KEY_INT)
      st = io_attr_int(g, name, e.integer);
    else
      st = io_attr_str(g, name, e.text);
  }
  H5Gclose(g);
  return st;
}

static ves_status write_header(ves_io *io, const ves_io_header *h) {
  hid_t f = io->file;
  VES_CALL(io_attr_int(f, "format_version", VES_IO_FORMAT));
  VES_CALL(io_attr_str(f, "program", "vesica"));
  VES_CALL(io_attr_str(f, "version", h->version));
  VES_CALL(io_attr_str(f, "backend", h->backend));
  VES_CALL(io_attr_int(f, "nodes", h->n));
  VES_CALL(io_attr_problem(f, h->problem));
  VES_CALL(io_attr_str(f, "source", h->source ? h->source : ""));
  VES_CALL(io_attr_double(f, "E0", h->E0));
  VES_CALL(io_attr_double(f, "A0", h->A0));
  VES_CALL(io_attr_double(f, "V0", h->V0));
  VES_CALL(io_attr_double(f, "setup_seconds", h->setup_seconds));
  VES_CALL(io_attr_status(f, "running"));
  VES_CALL(io_attr_str(f, "format_description",
                       "vesica HDF5 output, layout format_version 3: docs/manual.md (Output "
                       "format) and solver/app/io.h of vesica"));
  VES_CALL(io_describe(f,
                       "lengths R0 = sqrt(A0/4 pi), time t* = t k/(mu R0^3), energy k (E* = E/k)",
                       "a vesica run: header attributes, parameters, mesh, series, snapshots"));
  VES_CALL(write_parameters(f, h->cfg));
  hid_t g = H5Gcreate2(f, "mesh", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (g < 0) return VES_ERR_IO;
  int *v = malloc((size_t)h->n * sizeof *v);
  ves_status st = v ? VES_OK : VES_ERR_ALLOC;
  for (int a = 0; v && a < h->n; a++) v[a] = a;
  if (st == VES_OK)
    st = io_dset_write(g, "X", H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, (hsize_t)h->n, 2, h->X);
  if (st == VES_OK)
    st = io_dset_write(g, "triangles", H5T_STD_I32LE, H5T_NATIVE_INT, (hsize_t)h->ntri, 3, h->tri);
  if (st == VES_OK)
    st = io_dset_write(g, "vertices", H5T_STD_I32LE, H5T_NATIVE_INT, (hsize_t)h->n, 0, v);
  if (st == VES_OK) st = io_describe(g, "R0", "the reference configuration the run started from");
  if (st == VES_OK) st = io_describe_at(g, "X", "R0", "n x 2 reference node positions (R, Z)");
  if (st == VES_OK)
    st = io_describe_at(g, "triangles", "1",
                        "ntri x 3 node indices of the reference Delaunay triangles (fixed "
                        "connectivity)");
  if (st == VES_OK) st = io_describe_at(g, "vertices", "1", "node indices 0..n-1 (XDMF points)");
  free(v);
  H5Gclose(g);
  VES_CALL(st);
  hid_t s = H5Gcreate2(f, "snapshots", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  if (s < 0) return VES_ERR_IO;
  st = io_attr_int(s, "count", 0);
  if (st == VES_OK)
    st = io_describe(s, "per member",
                     "states of the run, groups 0..count-1 in time order (the initial state, "
                     "every [output] snapshot_every steps, the last)");
  H5Gclose(s);
  VES_CALL(st);
  VES_CALL(io_create_series(io, NULL));
  /* the series' first row, the initial state (step 0 at t = 0), is written
   * with the first snapshot or row (io_row0_write): the series' chunks then
   * come after snapshot 0 in the file, which a salvage of a file cut short
   * keeps more often */
  io->row0_row =
      (ves_io_row){.E = h->E0, .A = h->A0, .V = h->V0, .V_target = h->V0, .c0 = h->cfg->c0};
  io->row0_pending = 1;
  VES_CALL(io_provenance_write(io));
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
  io_quiet_hdf5();
  if (strlen(path) >= PATH_MAX - 8) {
    ves_error_say(err, errlen, "%s: path too long", path);
    return VES_ERR_ARG;
  }
  /* an HDF5 file there may be the output of a running vesica (which holds
   * a lock on it): never truncate that one */
  if (H5Fis_hdf5(path) > 0) {
    hid_t f = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
    if (f < 0) {
      ves_error_say(err, errlen,
                    "%s: exists and cannot be opened for writing (in use by a running vesica?)",
                    path);
      return VES_ERR_ARG;
    }
    H5Fclose(f);
  }
  ves_io *io = io_alloc(path, 1);
  if (!io) return VES_ERR_ALLOC;
  struct stat sb;
  const int existed = stat(path, &sb) == 0;
  io->file = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  if (io->file < 0) {
    if (!existed) remove(path); /* an empty file a full disk left: not a run's */
    char reason[128] = "";
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, io_sys_reason, reason);
    ves_error_say(err, errlen, "%s: cannot create the HDF5 file%s%s", path, reason[0] ? ": " : "",
                  reason);
    ves_io_close(&io);
    return VES_ERR_IO;
  }
  fill_info(io, h);
  errno = 0;
  ves_status st = io->info.problem && io->info.source ? VES_OK : VES_ERR_ALLOC;
  if (st == VES_OK) /* the header, mesh and series: reserved first, as every write */
    st = io_reserve(io,
                    IO_ROOM_MARGIN + 8 * (3.0 * h->n + 1.5 * h->ntri) + 2.0 * strlen(h->problem));
  if (st == VES_OK) st = write_header(io, h);
  if (st != VES_OK) { /* the file is ours (just created): nothing half-written stays */
    io_failed(io, st, errno);
    ves_error_say(err, errlen, "%s: cannot write the header: %s", path,
                  io->error[0] ? io->error : ves_status_str(st));
    ves_io_close(&io);
    remove(path);
    return st;
  }
  *out = io;
  return VES_OK;
}

static ves_status snapshot_attrs(hid_t g, const ves_io_snapinfo *si) {
  const ves_sim_state *s = &si->state;
  VES_CALL(io_attr_double(g, "t", s->t));
  VES_CALL(io_attr_long(g, "step", s->nstep));
  VES_CALL(io_attr_long(g, "rows", si->rows));
  VES_CALL(io_attr_double(g, "dt", s->dt));
  VES_CALL(io_attr_double(g, "E", s->E));
  VES_CALL(io_attr_double(g, "A", s->A));
  VES_CALL(io_attr_double(g, "V", s->V));
  VES_CALL(io_attr_double(g, "E0", s->E0));
  VES_CALL(io_attr_double(g, "A0", s->A0));
  VES_CALL(io_attr_double(g, "V0", s->V0));
  VES_CALL(io_attr_double(g, "lambda_A", s->lambda[0]));
  VES_CALL(io_attr_double(g, "lambda_V", s->lambda[1]));
  VES_CALL(io_attr_double(g, "c0", s->c0));
  VES_CALL(io_attr_double(g, "wall_seconds", si->wall_seconds));
  VES_CALL(io_attr_double(g, "dt_rejected", s->dt_rejected));
  VES_CALL(io_attr_long(g, "since_rejected", s->since_rejected));
  if (s->dt_prev > 0) VES_CALL(io_attr_double(g, "dt_prev", s->dt_prev));
  return io_attr_int(g, "reconnections", si->reconnections);
}

/* The triangles of the node set in use (the last remeshing's, or the
 * mesh's): read once, again after a remeshing is written or dropped. */
static ves_status triangles_now(ves_io *io) {
  if (io->ntri_now > 0) return VES_OK;
  const int R = ves_io_remeshes(io);
  int nt = io->info.ntri;
  if (R > 0) VES_CALL(ves_io_remesh_size(io, R - 1, NULL, NULL, &nt));
  int *t = malloc(3 * (size_t)nt * sizeof *t);
  if (!t) return VES_ERR_ALLOC;
  ves_status st =
      R > 0 ? ves_io_read_remesh_triangles(io, R - 1, t) : ves_io_read_mesh(io, NULL, t);
  if (st != VES_OK) {
    free(t);
    return st;
  }
  free(io->tri_now);
  io->tri_now = t, io->ntri_now = nt;
  return VES_OK;
}

/* The sharp interface {phi = 0} of the piecewise-linear phi on the
 * triangles in use moved to x (level_set.h): *have 0 when the level set
 * refuses the state (a non-finite x or phi), which then gets no group;
 * io->iface_bytes what the group takes in the file at most. */
static ves_status interface_of(ves_io *io, int n, const double *x, const double *phi,
                               ves_level_set *ls, ves_level_set_curves *c, int *have) {
  *have = 0;
  VES_CALL(triangles_now(io));
  if (ves_level_set_eval(n, io->ntri_now, io->tri_now, x, phi, ls) != VES_OK) return VES_OK;
  const ves_status cs = ves_level_set_curves_eval(n, io->ntri_now, io->tri_now, x, phi, c);
  if (cs != VES_OK) return cs == VES_ERR_ALLOC ? cs : VES_OK;
  *have = 1;
  /* 16 bytes a point, a dataset's object header and attributes a piece, the group's */
  io->iface_bytes = 16.0 * c->start[c->npieces] + 1024.0 * c->npieces + 2048;
  return VES_OK;
}

/* Group `interface` of snapshot g (interface_of): one dataset per piece
 * ("0", "1", ...: m x 2, r z in R0, attribute closed) and the measures as
 * attributes. Derived data (recomputable from x, phi and the triangles):
 * outside the snapshot's checksum, read by no restart. */
static ves_status write_interface(hid_t g, const ves_level_set *pls,
                                  const ves_level_set_curves *pc) {
  const ves_level_set ls = *pls;
  const ves_level_set_curves c = *pc;
  hid_t ig = H5Gcreate2(g, "interface", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  ves_status st = ig < 0 ? VES_ERR_IO : VES_OK;
  for (int i = 0; i < c.npieces && st == VES_OK; i++) {
    char name[32];
    snprintf(name, sizeof name, "%d", i);
    st = io_dset_write(ig, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE,
                       (hsize_t)(c.start[i + 1] - c.start[i]), 2, c.rz + 2 * c.start[i]);
    hid_t d = st == VES_OK ? H5Dopen2(ig, name, H5P_DEFAULT) : -1;
    if (st == VES_OK && d < 0) st = VES_ERR_IO;
    if (st == VES_OK) st = io_attr_int(d, "closed", c.closed[i]);
    if (st == VES_OK)
      st =
          io_describe(d, "R0",
                      c.closed[i] ? "m x 2 points (r, z) of a closed loop, clockwise from its top, "
                                    "the first point repeated at the end"
                                  : "m x 2 points (r, z) of an open piece, from its end of larger "
                                    "z (north pole) to the other");
    if (d >= 0) H5Dclose(d);
  }
  const double R0 = sqrt(ls.area / (4 * M_PI));
  if (st == VES_OK) st = io_attr_int(ig, "pieces", c.npieces);
  if (st == VES_OK) st = io_attr_double(ig, "area", ls.area);
  if (st == VES_OK) st = io_attr_double(ig, "volume", ls.volume);
  if (st == VES_OK)
    st = io_attr_double(ig, "reduced_volume",
                        ls.area > 0 ? ls.volume / (4.0 / 3.0 * M_PI * R0 * R0 * R0) : 0.0);
  if (st == VES_OK) st = io_attr_int(ig, "inverted", ls.inverted);
  if (st == VES_OK)
    st = io_describe(
        ig, "area R0^2, volume R0^3, reduced_volume 1, points R0",
        "the sharp interface phi = 0 of the piecewise-linear phi on the triangles in use moved to "
        "x: datasets 0..pieces-1 its pieces (sorted by their largest z), attributes area "
        "(2 pi int r ds), volume (2 pi int r dA over phi > 0), reduced_volume (V / (4 pi/3 "
        "(A/4 pi)^(3/2))), inverted (triangles of non-positive image area)");
  if (ig >= 0) H5Gclose(ig);
  return st;
}

static ves_status snapshot(ves_io *io, const double *y, const double *x, const double *phi,
                           const ves_io_snapinfo *si) {
  if (io->nsnap == io->snap_cap) {
    int cap = io->snap_cap ? 2 * io->snap_cap : 16;
    double *t = realloc(io->snap_t, (size_t)cap * sizeof *t);
    if (!t) return VES_ERR_ALLOC;
    io->snap_t = t, io->snap_cap = cap;
  }
  const hsize_t n = (hsize_t)io_nodes_now(io); /* the last remeshing's node set */
  ves_level_set ls;
  ves_level_set_curves c = {0};
  int have = 0;
  ves_status st = interface_of(io, (int)n, x, phi, &ls, &c, &have);
  if (st == VES_OK)
    st = io_reserve(io, snapshot_bytes(io, 1) + (io->row0_pending ? io_row_bytes(io) : 0));
  hid_t s, g;
  if (st == VES_OK) st = io_counted_open(io->file, "snapshots", io->nsnap, &s, &g);
  if (st != VES_OK) {
    ves_level_set_curves_free(&c);
    return st;
  }
  const hid_t F = H5T_IEEE_F64LE, M = H5T_NATIVE_DOUBLE;
  st = io_dset_write(g, "y", F, M, n, 2, y);
  if (st == VES_OK) st = io_dset_write(g, "x", F, M, n, 2, x);
  if (st == VES_OK) st = io_dset_write(g, "phi", F, M, n, 0, phi);
  if (st == VES_OK && si->state.dt_prev > 0)
    st = io_dset_write(g, "y_prev", F, M, n, 2, si->y_prev);
  if (st == VES_OK && si->velocity) st = io_dset_write(g, "velocity", F, M, n, 2, si->velocity);
  if (st == VES_OK) st = snapshot_attrs(g, si);
  if (st == VES_OK && have) st = write_interface(g, &ls, &c);
  ves_level_set_curves_free(&c);
  /* checksums for a salvage: of the snapshot, and of the series rows up to
   * it (when the file holds them: always in a run) */
  uint64_t rows_checksum = 0;
  if (st == VES_OK)
    st = io_attr_u64(g, "checksum", io_snap_sum((long)n, y, x, phi, si->y_prev, si));
  if (st == VES_OK && si->rows >= 0 && ves_io_rows(io) >= si->rows) {
    st = io_series_sum(io, si->rows, &rows_checksum);
    if (st == VES_OK) st = io_attr_u64(g, "series_checksum", rows_checksum);
  }
  if (st == VES_OK)
    st = io_describe(g, "t, dt in t*; E in k; A in R0^2; V in R0^3; c0 in 1/R0",
                     "one state: what a restart continues from; attributes the integrator state");
  if (st == VES_OK)
    st = io_describe_at(g, "y", "R0", "n x 2 nodal coefficients y^a (r, z) of the motion");
  if (st == VES_OK)
    st = io_describe_at(g, "x", "R0", "n x 2 positions y(X_a) of the material at the nodes");
  if (st == VES_OK) st = io_describe_at(g, "phi", "1", "phase field phi of that material (-1..1)");
  if (st == VES_OK && si->state.dt_prev > 0)
    st = io_describe_at(g, "y_prev", "R0",
                        "n x 2 coefficients before the last step (the predictor's start, dt_prev)");
  if (st == VES_OK && si->velocity)
    st = io_describe_at(g, "velocity", "R0 per t*",
                        "n x 2 flow at the nodes (r, z): the material's velocity over the last "
                        "step, (y^n(X_a) - y^{n-1}(X_a)) / dt_prev, at x");
  VES_CALL(io_counted_close(io->file, s, g, io->nsnap, st));
  /* the initial state's row after the snapshot whole (its series_checksum
   * already covers it): the snapshot's object headers and their
   * continuations stay together, before the series' first chunks */
  VES_CALL(io_row0_write(io));
  io->snap_t[io->nsnap++] = si->state.t;
  io->last_step = si->state.nstep;
  /* its row of the index once it is counted: a file cut in between has
   * one row fewer, which the next snapshot's put rebuilds */
  VES_CALL(io_index_put(io, io->nsnap - 1, si->state.nstep, si->state.t));
  if (H5Fflush(io->file, H5F_SCOPE_LOCAL) < 0) return VES_ERR_IO;
  errno = 0;
  st = io_xdmf_write(io);
  if (st == VES_ERR_IO) { /* the HDF5 file is complete: the XDMF file is rewritten at the next */
    snprintf(io->error, sizeof io->error, "%s: %s", io->xdmf,
             errno ? strerror(errno) : "cannot write it");
    io->intact = 1;
  }
  return st;
}

ves_status ves_io_snapshot(ves_io *io, const double *y, const double *x, const double *phi,
                           const ves_io_snapinfo *si) {
  VES_CHECK(io && y && x && phi && si && io->writable, VES_ERR_ARG);
  VES_CHECK(si->state.dt_prev >= 0 && (si->state.dt_prev == 0 || si->y_prev), VES_ERR_ARG);
  errno = 0;
  ves_status st = io_provenance_pending(io); /* a restart's, before its first snapshot */
  return io_failed(io, st == VES_OK ? snapshot(io, y, x, phi, si) : st, errno);
}

static ves_status write_reference(ves_io *io, const ves_io_reference *ref) {
  const int k = ves_io_references(io);
  VES_CALL(io_reserve(io, IO_ROOM_MARGIN + 8 * (3.0 * io_nodes_now(io) + 9.0 * ref->nq)));
  hid_t s, g;
  VES_CALL(io_counted_open(io->file, "references", k, &s, &g));
  const hsize_t n = (hsize_t)io_nodes_now(io), nq = (hsize_t)ref->nq;
  const hid_t F = H5T_IEEE_F64LE, M = H5T_NATIVE_DOUBLE;
  ves_status st = io_dset_write(g, "x", F, M, n, 2, ref->x);
  if (st == VES_OK) st = io_dset_write(g, "h", F, M, n, 0, ref->h);
  if (st == VES_OK) st = io_dset_write(g, "points", F, M, nq, 2, ref->xq);
  if (st == VES_OK) st = io_dset_write(g, "weights", F, M, nq, 0, ref->wq);
  if (st == VES_OK) st = io_dset_write(g, "phi0", F, M, nq, 6, ref->pd);
  if (st == VES_OK) st = io_attr_long(g, "step", ref->step);
  if (st == VES_OK)
    st = io_attr_u64(
        g, "checksum",
        io_ref_sum((long)n, (long)nq, ref->x, ref->h, ref->xq, ref->wq, ref->pd, ref->step));
  if (st == VES_OK)
    st =
        io_describe(s, "per member", "reference configurations, one per reset (groups 0..count-1)");
  if (st == VES_OK)
    st = io_describe(g, "R0",
                     "the reference made after accepted step `step`: what a restart rebuilds");
  if (st == VES_OK) st = io_describe_at(g, "x", "R0", "n x 2 node positions (R, Z)");
  if (st == VES_OK) st = io_describe_at(g, "h", "R0", "n node spacings h_a");
  if (st == VES_OK) st = io_describe_at(g, "points", "R0", "nq x 2 quadrature points (R, Z)");
  if (st == VES_OK) st = io_describe_at(g, "weights", "R0^2", "nq quadrature weights");
  if (st == VES_OK)
    st = io_describe_at(g, "phi0", "1, 1/R0, 1/R0^2",
                        "nq x 6 point data of phi0: value, gradient (2), Hessian (3)");
  return io_counted_close(io->file, s, g, k, st);
}

ves_status ves_io_write_reference(ves_io *io, const ves_io_reference *ref) {
  VES_CHECK(io && ref && io->writable && ref->x && ref->h && ref->xq && ref->wq && ref->pd,
            VES_ERR_ARG);
  VES_CHECK(ref->nq > 0 && ref->step >= 0, VES_ERR_ARG);
  errno = 0;
  return io_failed(io, write_reference(io, ref), errno);
}

/* Drop the counted group's members count..have-1 (the count attribute first: the rest is
   then stray) and flush. */
static ves_status truncate_counted(ves_io *io, const char *group, int have, int count) {
  VES_CHECK(io && io->writable && count >= 0 && count <= have, VES_ERR_ARG);
  if (count == have) return VES_OK;
  VES_CALL(io_reserve(io, IO_ROOM_MARGIN));
  hid_t s = H5Gopen2(io->file, group, H5P_DEFAULT);
  if (s < 0) return VES_ERR_IO;
  ves_status st = io_attr_int(s, "count", count); /* first: the rest is then stray */
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
  return io_failed(io, truncate_counted(io, "references", ves_io_references(io), count), 0);
}

ves_status ves_io_set_status(ves_io *io, const char *status) {
  VES_CHECK(io && status && io->writable && strlen(status) < sizeof io->info.status, VES_ERR_ARG);
  errno = 0;
  /* rewritten in place (16 bytes): no room needed, so a run stopped by a
   * full disk still marks its file; not after a write failed half-way */
  io->intact = 0;
  if (io->broken) return VES_ERR_IO;
  ves_status st = io_attr_status(io->file, status);
  if (st == VES_OK && H5Fflush(io->file, H5F_SCOPE_LOCAL) < 0) st = VES_ERR_IO;
  if (st == VES_OK) snprintf(io->info.status, sizeof io->info.status, "%s", status);
  return io_failed(io, st, errno);
}

ves_status ves_io_set_problem(ves_io *io, const ves_config *cfg) {
  VES_CHECK(io && io->writable && cfg, VES_ERR_ARG);
  char *text = NULL;
  VES_CALL(ves_config_to_text(cfg, &text));
  ves_status st = io_reserve(io, IO_ROOM_MARGIN + 4.0 * strlen(text));
  if (st == VES_OK) st = io_attr_problem(io->file, text);
  if (st == VES_OK) st = write_parameters(io->file, cfg);
  if (st == VES_OK) {
    free(io->info.problem);
    io->info.problem = text;
  } else {
    free(text);
  }
  if (st == VES_OK && H5Fflush(io->file, H5F_SCOPE_LOCAL) < 0) st = VES_ERR_IO;
  return io_failed(io, st, 0);
}

ves_status ves_io_set_setup_seconds(ves_io *io, double seconds) {
  VES_CHECK(io && io->writable, VES_ERR_ARG);
  VES_CALL(io_attr_double(io->file, "setup_seconds", seconds));
  io->info.setup_seconds = seconds;
  return VES_OK;
}

/* What the next writes of a run need at most, in bytes: one series row,
 * `snapshots` snapshots (and the XDMF file, four data items a grid,
 * rewritten beside its old copy) and, with nq > 0, a reference of nq
 * points. */
static double room_needed(const ves_io *io, int snapshots, int nq) {
  const double n = io_nodes_now(io);
  double need = io_row_bytes(io) + snapshot_bytes(io, snapshots) - IO_ROOM_MARGIN; /* one margin */
  const double xdmf = 2.0 * (io->nsnap + snapshots) * (1536 + 5.0 * strlen(io->path));
  need += snapshots ? 2 * xdmf : 0;
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
  struct stat fs; /* the blocks an earlier reservation holds past the end are the file's */
  const double held = stat(io->path, &fs) == 0 && (double)fs.st_blocks * 512 > fs.st_size
                          ? (double)fs.st_blocks * 512 - (double)fs.st_size
                          : 0;
  if (statvfs(dir, &vs) == 0) {
    const double avail = (double)vs.f_bavail * (double)vs.f_frsize + held;
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
  /* the step's writes and a last snapshot reserved here: another program
   * filling the disk during the step cannot take their blocks */
  return io_reserve(io, need);
}

int ves_io_kept(ves_io *io, long *step, double *t, int *intact) {
  long s = io && io->nsnap > 0 ? io->last_step : -1;
  if (io && io->nsnap > 0 && s < 0) { /* opened, not written here: the group says */
    char name[48];
    snprintf(name, sizeof name, "snapshots/%d", io->nsnap - 1);
    hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
    if (g < 0 || io_attr_read(g, "step", H5T_NATIVE_LONG, &s) != VES_OK) s = -1;
    if (g >= 0) H5Gclose(g);
  }
  if (step) *step = s;
  if (t) *t = io && io->nsnap > 0 ? io->snap_t[io->nsnap - 1] : 0.0;
  if (intact) *intact = io && !io->broken;
  return io ? io->nsnap : 0;
}

const char *ves_io_error(const ves_io *io) { return io && io->error[0] ? io->error : NULL; }

/* What a remeshing changed (ves_remesh_info), as attributes of its group g. */
static ves_status remesh_attrs(hid_t g, const ves_remesh_info *in) {
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
  ves_status st = VES_OK;
  for (size_t i = 0; i < sizeof a / sizeof a[0] && st == VES_OK; i++)
    st = io_attr_double(g, a[i].name, a[i].v);
  return st;
}

/* The units and descriptions of the group /remeshes (s), its member g and
 * g's datasets. */
static ves_status remesh_describe(hid_t s, hid_t g) {
  ves_status st = io_describe(
      s, "per member", "full remeshings, one per member (groups 0..count-1): the new node sets");
  if (st == VES_OK)
    st = io_describe(
        g, "R0; E in k",
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
  if (st == VES_OK) st = io_describe_at(g, "x", "R0", "n x 2 node positions (R, Z)");
  if (st == VES_OK) st = io_describe_at(g, "h", "R0", "n node spacings h_a");
  if (st == VES_OK)
    st = io_describe_at(g, "flag", "1", "n node flags (1 axis, 2 wall, 4 lattice, 8 band)");
  if (st == VES_OK)
    st = io_describe_at(g, "phi0c", "1", "n nodal coefficients of the projected phi0");
  if (st == VES_OK)
    st = io_describe_at(g, "triangles", "1", "ntri x 3 Delaunay triangles of the new nodes");
  if (st == VES_OK)
    st = io_describe_at(g, "vertices", "1", "n int 0..n-1 (the nodes as XDMF points)");
  return st;
}

static ves_status write_remesh(ves_io *io, const ves_io_remesh *rm) {
  const int k = ves_io_remeshes(io);
  io->ntri_now = 0; /* the interface's triangles: this remeshing's from now */
  VES_CALL(io_reserve(io, IO_ROOM_MARGIN + 40.0 * rm->n + 12.0 * rm->ntri));
  hid_t s, g;
  VES_CALL(io_counted_open(io->file, "remeshes", k, &s, &g));
  const hsize_t n = (hsize_t)rm->n, nt = (hsize_t)rm->ntri;
  const hid_t F = H5T_IEEE_F64LE, M = H5T_NATIVE_DOUBLE;
  int *v = malloc((size_t)rm->n * sizeof *v);
  for (int a = 0; v && a < rm->n; a++) v[a] = a;
  ves_status st = v ? VES_OK : VES_ERR_ALLOC;
  if (st == VES_OK) st = io_dset_write(g, "x", F, M, n, 2, rm->x);
  if (st == VES_OK) st = io_dset_write(g, "h", F, M, n, 0, rm->h);
  if (st == VES_OK) st = io_dset_write(g, "flag", H5T_STD_I32LE, H5T_NATIVE_INT, n, 0, rm->flag);
  if (st == VES_OK) st = io_dset_write(g, "phi0c", F, M, n, 0, rm->phi0c);
  if (st == VES_OK)
    st = io_dset_write(g, "triangles", H5T_STD_I32LE, H5T_NATIVE_INT, nt, 3, rm->tri);
  if (st == VES_OK) st = io_dset_write(g, "vertices", H5T_STD_I32LE, H5T_NATIVE_INT, n, 0, v);
  free(v);
  if (st == VES_OK) st = io_attr_long(g, "step", rm->step);
  if (st == VES_OK) st = remesh_attrs(g, rm->info);
  if (st == VES_OK) st = remesh_describe(s, g);
  if (st == VES_OK) /* for a salvage (ves_io_salvage), read back as written */
    st = io_attr_u64(g, "checksum", io_group_sum(g, io_remesh_parts, IO_NREMESH_PARTS));
  return io_counted_close(io->file, s, g, k, st);
}

ves_status ves_io_write_remesh(ves_io *io, const ves_io_remesh *rm) {
  VES_CHECK(io && rm && io->writable && rm->x && rm->h && rm->flag && rm->phi0c && rm->tri &&
                rm->info,
            VES_ERR_ARG);
  VES_CHECK(rm->n >= 3 && rm->ntri > 0 && rm->step >= 1, VES_ERR_ARG);
  errno = 0;
  return io_failed(io, write_remesh(io, rm), errno);
}

ves_status ves_io_truncate_remeshes(ves_io *io, int count) {
  VES_CHECK(io, VES_ERR_ARG);
  io->ntri_now = 0;
  return io_failed(io, truncate_counted(io, "remeshes", ves_io_remeshes(io), count), 0);
}
