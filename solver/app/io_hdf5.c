/* vesica — the HDF5 helpers of the run output: the handle, HDF5's error
 * stack, typed scalar attributes, contiguous datasets, counted groups (a
 * member written whole, then counted) and the FNV-1a checksums a salvage
 * checks. Layout: app/io.h; docs/design.md, "The program". */
#define _GNU_SOURCE /* fallocate, FALLOC_FL_KEEP_SIZE */
#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "app/io_impl.h"

/* HDF5 prints its error stack by default: the library stays silent. Its
 * exit-time cleanup is declined: after a failed write (a full disk) H5Fclose
 * fails and leaves the file half-closed, and that cleanup then crashes
 * (SIGSEGV in H5F__close_cb, HDF5 1.10.8); every file is closed explicitly
 * anyway. H5dont_atexit acts only as the process's first HDF5 call (vesica's
 * case) and is otherwise a harmless no-op. */
void io_quiet_hdf5(void) {
  H5dont_atexit();
  H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
}

/* H5Ewalk2 callback: the system's reason of the innermost failing file
 * operation, from the sec2 driver's "..., errno = 28, error message = 'No
 * space left on device', ..." (errno itself does not survive HDF5's error
 * handling). */
herr_t io_sys_reason(unsigned n, const H5E_error2_t *e, void *data) {
  (void)n;
  char *out = data;
  const char *p = e->desc ? strstr(e->desc, "error message = '") : NULL;
  if (p && !out[0]) {
    p += strlen("error message = '");
    snprintf(out, 128, "%.*s", (int)strcspn(p, "'"), p);
  }
  return 0;
}

/* Record the cause of a failed write: the system's reason from HDF5's error
 * stack, errno as the failing write left it, or the status. A write refused
 * before HDF5 wrote anything (io_reserve, the XDMF file after a flush) has
 * recorded its cause and left the file as last flushed (io->intact); an
 * I/O error may have stopped half-way (io->broken: nothing more is written). */
ves_status io_failed(ves_io *io, ves_status st, int errnum) {
  if (st == VES_OK) return st;
  if (io->intact) return st;
  if (st == VES_ERR_IO) io->broken = 1; /* an I/O error, not a refused call */
  if (st == VES_ERR_ALLOC) return st;
  char reason[128] = "";
  H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, io_sys_reason, reason);
  snprintf(io->error, sizeof io->error, "%s",
           reason[0] ? reason
           : errnum  ? strerror(errnum)
                     : ves_status_str(st));
  return st;
}

/* Reserve `bytes` past the end of the file for the writes about to be made
 * (fallocate, FALLOC_FL_KEEP_SIZE: blocks the file owns, its size unchanged).
 * HDF5 1.10 rewrites metadata in place (the superblock's end of file, group
 * heaps and B-trees, object headers) and a flush stops at the first write
 * that fails: a disk filled by another program during a flush leaves
 * metadata on disk that points past the end of file the superblock records,
 * a file HDF5 then refuses to read. With the blocks reserved first, a write
 * either is refused here, before HDF5 is called (the file stays as last
 * flushed, io->intact), or does not fail for want of space (docs/results.md,
 * "Reliability and fuzzing"). A file system without fallocate counts as
 * reserved: the free-space check of ves_io_room stands alone there. After
 * a write failed half-way (io->broken) nothing more is written. VES_ERR_IO
 * with the cause in io->error when refused. */
ves_status io_reserve(ves_io *io, double bytes) {
  io->intact = 0;
  if (io->broken) {
    io->intact = 1; /* the cause of the first failure stays recorded */
    return VES_ERR_IO;
  }
#ifdef FALLOC_FL_KEEP_SIZE
  void *h = NULL;
  struct stat sb;
  if (H5Fget_vfd_handle(io->file, H5P_DEFAULT, &h) < 0 || !h || fstat(*(int *)h, &sb) != 0)
    return VES_OK; /* not the sec2 driver's file descriptor: nothing to reserve on */
  if (fallocate(*(int *)h, FALLOC_FL_KEEP_SIZE, sb.st_size, (off_t)bytes) == 0) {
    io->reserved = 1;
    return VES_OK;
  }
  const int e = errno;
  if (e != ENOSPC && e != EDQUOT && e != EFBIG && e != EIO) return VES_OK; /* unsupported */
  snprintf(io->error, sizeof io->error,
           "%s (the next write needs up to %.0f KiB beyond the %.0f KiB of %s)", strerror(e),
           bytes / 1024, (double)sb.st_size / 1024, io->path);
  io->intact = 1;
  return VES_ERR_IO;
#else
  (void)bytes;
  return VES_OK;
#endif
}

/* What one series row writes at most, in bytes: a new chunk of every series
 * every IO_CHUNK rows (with its B-tree node), and HDF5's metadata. */
double io_row_bytes(const ves_io *io) {
  double need = IO_ROOM_MARGIN;
  const long next = ves_io_rows(io) + io->row0; /* the dataset row written next */
  if (next % IO_CHUNK == 0 || io->row0_pending) need += IO_NSERIES * (IO_CHUNK * 8.0 + 4096);
  return need;
}

/* FNV-1a (64 bits) over the bytes of data, continuing from h (FNV_START to
 * begin). Snapshots and references carry one over their data and state, so
 * that a salvage (ves_io_salvage) tells a member whose blocks survived from
 * one whose blocks were lost and read back as zeros. */
uint64_t io_fnv(uint64_t h, const void *data, size_t len) {
  const unsigned char *p = data;
  for (size_t i = 0; i < len; i++) h = (h ^ p[i]) * 0x100000001b3ULL;
  return h;
}

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

ves_status io_attr_double(hid_t obj, const char *name, double v) {
  return attr_write(obj, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, &v);
}

ves_status io_attr_int(hid_t obj, const char *name, int v) {
  return attr_write(obj, name, H5T_STD_I32LE, H5T_NATIVE_INT, &v);
}

ves_status io_attr_long(hid_t obj, const char *name, long v) {
  return attr_write(obj, name, H5T_STD_I64LE, H5T_NATIVE_LONG, &v);
}

ves_status io_attr_u64(hid_t obj, const char *name, uint64_t v) {
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

ves_status io_attr_str(hid_t obj, const char *name, const char *s) {
  return attr_str_size(obj, name, s, 0);
}

/* The root attribute status: 16 bytes whatever its value, rewritten in place. */
ves_status io_attr_status(hid_t file, const char *status) {
  return attr_str_size(file, "status", status, sizeof((ves_io_info *)0)->status);
}

/* The attributes `units` and `description` every group and dataset carries
 * (readers need neither). */
ves_status io_describe(hid_t obj, const char *units, const char *description) {
  VES_CALL(io_attr_str(obj, "units", units));
  return io_attr_str(obj, "description", description);
}

/* The same on the object at `path` below loc. */
ves_status io_describe_at(hid_t loc, const char *path, const char *units, const char *description) {
  hid_t o = H5Oopen(loc, path, H5P_DEFAULT);
  if (o < 0) return VES_ERR_IO;
  ves_status st = io_describe(o, units, description);
  H5Oclose(o);
  return st;
}

/* Whether the type of a dataset (is_attr = 0) or attribute (1) is one of
 * the numeric types this module writes (IEEE f64, signed 32- and 64-bit,
 * unsigned 64-bit integers, little-endian), between which HDF5 converts
 * safely. Data of any other type is refused unread: a damaged type message
 * (a float with a 51-bit mantissa, say) sends HDF5's conversion code far
 * past its buffers (HDF5 1.10.8, H5T__conv_f_f; tests/fuzz/fuzz_h5.c;
 * docs/results.md, "Reliability and fuzzing"). */
int io_numeric_type_ok(hid_t obj, int is_attr) {
  hid_t t = is_attr ? H5Aget_type(obj) : H5Dget_type(obj);
  const hid_t ours[] = {H5T_IEEE_F64LE, H5T_STD_I32LE, H5T_STD_I64LE, H5T_STD_U64LE};
  int ok = 0;
  for (size_t i = 0; t >= 0 && i < sizeof ours / sizeof ours[0] && !ok; i++)
    ok = H5Tequal(t, ours[i]) > 0;
  if (t >= 0) H5Tclose(t);
  return ok;
}

ves_status io_attr_read(hid_t obj, const char *name, hid_t mtype, void *v) {
  if (H5Aexists(obj, name) <= 0) return VES_ERR_CONFIG;
  hid_t a = H5Aopen(obj, name, H5P_DEFAULT);
  if (a < 0) return VES_ERR_IO;
  if (!io_numeric_type_ok(a, 1)) {
    H5Aclose(a);
    return VES_ERR_CONFIG;
  }
  herr_t e = H5Aread(a, mtype, v);
  H5Aclose(a);
  return e < 0 ? VES_ERR_IO : VES_OK;
}

ves_status io_attr_read_double(hid_t obj, const char *name, double *v) {
  return io_attr_read(obj, name, H5T_NATIVE_DOUBLE, v);
}

/* A string attribute, malloc'd (taken by the caller). */
ves_status io_attr_read_str(hid_t obj, const char *name, char **out) {
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
ves_status io_attr_read_buf(hid_t obj, const char *name, char *buf, size_t len) {
  char *s;
  VES_CALL(io_attr_read_str(obj, name, &s));
  snprintf(buf, len, "%s", s);
  free(s);
  return VES_OK;
}

/* A contiguous dataset of rank 1 or 2 (dims[1] = 0 for rank 1), written once. */
ves_status io_dset_write(hid_t loc, const char *name, hid_t ftype, hid_t mtype, hsize_t d0,
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
ves_status io_dset_read(hid_t loc, const char *name, hid_t mtype, hsize_t count, void *data) {
  hid_t d = H5Dopen2(loc, name, H5P_DEFAULT);
  if (d < 0) return VES_ERR_IO;
  ves_status st = VES_ERR_IO;
  hid_t sp = H5Dget_space(d);
  if (sp >= 0 && (hsize_t)H5Sget_simple_extent_npoints(sp) == count && io_numeric_type_ok(d, 0) &&
      H5Dread(d, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) >= 0)
    st = VES_OK;
  if (sp >= 0) H5Sclose(sp);
  H5Dclose(d);
  return st;
}

hsize_t io_dset_len(hid_t d) {
  hsize_t dims[1] = {0};
  hid_t sp = H5Dget_space(d);
  if (sp < 0) return 0;
  if (H5Sget_simple_extent_ndims(sp) != 1 || H5Sget_simple_extent_dims(sp, dims, NULL) < 0)
    dims[0] = 0;
  H5Sclose(sp);
  return dims[0];
}

/* The checksum of a snapshot: y, x, phi (n nodes) and every stored field of si. */
uint64_t io_snap_sum(long n, const double *y, const double *x, const double *phi,
                     const double *y_prev, const ves_io_snapinfo *si) {
  const ves_sim_state *s = &si->state;
  const double d[] = {s->t,          s->dt, s->E,         s->A,         s->V,  s->E0,
                      s->A0,         s->V0, s->lambda[0], s->lambda[1], s->c0, si->wall_seconds,
                      s->dt_rejected};
  const long l[] = {s->nstep, si->rows, s->since_rejected, si->reconnections};
  uint64_t h = io_fnv(FNV_START, y, 2 * (size_t)n * sizeof *y);
  h = io_fnv(h, x, 2 * (size_t)n * sizeof *x);
  h = io_fnv(h, phi, (size_t)n * sizeof *phi);
  h = io_fnv(h, d, sizeof d);
  h = io_fnv(h, l, sizeof l);
  if (s->dt_prev > 0) { /* the predictor's state, summed only when held */
    h = io_fnv(h, &s->dt_prev, sizeof s->dt_prev);
    h = io_fnv(h, y_prev, 2 * (size_t)n * sizeof *y_prev);
  }
  return h;
}

/* The checksum of a reference: its data (n nodes, nq points) and step. */
uint64_t io_ref_sum(long n, long nq, const double *x, const double *h_, const double *xq,
                    const double *wq, const double *pd, long step) {
  uint64_t h = io_fnv(FNV_START, x, 2 * (size_t)n * sizeof *x);
  h = io_fnv(h, h_, (size_t)n * sizeof *h_);
  h = io_fnv(h, xq, 2 * (size_t)nq * sizeof *xq);
  h = io_fnv(h, wq, (size_t)nq * sizeof *wq);
  h = io_fnv(h, pd, 6 * (size_t)nq * sizeof *pd);
  return io_fnv(h, &step, sizeof step);
}

ves_io *io_alloc(const char *path, int writable) {
  ves_io *io = calloc(1, sizeof *io);
  if (!io) return NULL;
  io->file = -1;
  io->writable = writable;
  io->last_step = -1;
  io->series_sum = FNV_START;
  for (int i = 0; i < IO_NSERIES; i++) io->series[i] = -1;
  snprintf(io->path, sizeof io->path, "%s", path);
  ves_io_xdmf_path(path, io->xdmf, sizeof io->xdmf);
  io_utc_now(io->started, sizeof io->started);
  return io;
}

void ves_io_close(ves_io **pio) {
  if (!pio || !*pio) return;
  ves_io *io = *pio;
  for (int i = 0; i < IO_NSERIES; i++)
    if (io->series[i] >= 0) H5Dclose(io->series[i]);
  if (io->file >= 0) {
    if (io->writable && !io->broken) H5Fflush(io->file, H5F_SCOPE_LOCAL);
    H5Fclose(io->file);
    /* the blocks io_reserve took past the end and no write filled: freed
     * (a truncation to its own size drops them) */
    struct stat sb;
    if (io->reserved && stat(io->path, &sb) == 0 && (double)sb.st_blocks * 512 > sb.st_size &&
        truncate(io->path, sb.st_size) != 0)
      errno = 0;
  }
  free(io->info.problem);
  free(io->info.source);
  free(io->snap_t);
  free(io->tri_now);
  free(io);
  *pio = NULL;
}

/* Members "0", "1", ... of a group whose attribute count says how many are
 * complete: a member is written whole, then counted, so a writer killed in
 * between leaves an uncounted member that the next write replaces. */

/* Open (or create) group `parent` of the file and create its member k anew
 * (dropping a stray one). On VES_OK *ps and *pg are open (close them with
 * counted_close); on failure nothing is open. */
ves_status io_counted_open(hid_t file, const char *parent, int k, hid_t *ps, hid_t *pg) {
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
ves_status io_counted_close(hid_t file, hid_t s, hid_t g, int k, ves_status st) {
  H5Gclose(g);
  if (st == VES_OK) st = io_attr_int(s, "count", k + 1); /* complete once counted */
  H5Gclose(s);
  VES_CALL(st);
  return H5Fflush(file, H5F_SCOPE_LOCAL) < 0 ? VES_ERR_IO : VES_OK;
}

/* The first dimension of dataset `name` in loc (0 when absent or unreadable). */
hsize_t io_dset_rows(hid_t loc, const char *name) {
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

/* The checksum of the datasets named in part[np] of group g (each read
 * whole as doubles, in that order), or 0 when one does not read. */
uint64_t io_group_sum(hid_t g, const char *const *part, int np) {
  uint64_t h = FNV_START;
  for (int i = 0; i < np; i++) {
    double *v = NULL;
    hsize_t c = 0;
    hid_t d = H5Dopen2(g, part[i], H5P_DEFAULT);
    hid_t sp = d < 0 ? -1 : H5Dget_space(d);
    const hssize_t np_ = sp < 0 ? -1 : H5Sget_simple_extent_npoints(sp);
    int ok = np_ > 0 && io_numeric_type_ok(d, 0) && (v = malloc((size_t)np_ * sizeof *v)) &&
             H5Dread(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, v) >= 0;
    c = ok ? (hsize_t)np_ : 0;
    if (ok) h = io_fnv(h, v, (size_t)c * sizeof *v);
    free(v);
    if (sp >= 0) H5Sclose(sp);
    if (d >= 0) H5Dclose(d);
    if (!ok) return 0;
  }
  return h;
}

/* The datasets of a remeshing group its checksum covers. */
const char *const io_remesh_parts[IO_NREMESH_PARTS] = {"x",     "h",         "flag",
                                                       "phi0c", "triangles", "vertices"};

/* The root attributes "problem" (the stored problem text) and
 * "problem_checksum" (FNV-1a of its bytes): a restart rebuilds the run
 * from that text, so a reader refuses one that does not match. */
ves_status io_attr_problem(hid_t file, const char *text) {
  VES_CALL(io_attr_str(file, "problem", text));
  return io_attr_u64(file, "problem_checksum", io_fnv(FNV_START, text, strlen(text)));
}

/* Drop the snapshots from `keep` on (the count says keep; the members
 * after it are replaced by the next writes): a restart from an earlier
 * snapshot (vesica run --restart FILE --from-snapshot K). */
ves_status ves_io_truncate_snapshots(ves_io *io, int keep) {
  VES_CHECK(io && io->writable && keep >= 1 && keep <= io->nsnap, VES_ERR_ARG);
  if (keep == io->nsnap) return VES_OK;
  hid_t s = H5Gopen2(io->file, "snapshots", H5P_DEFAULT);
  if (s < 0) return io_failed(io, VES_ERR_IO, 0);
  ves_status st = io_attr_int(s, "count", keep);
  H5Gclose(s);
  if (st == VES_OK) st = io_index_truncate(io, keep);
  if (st == VES_OK && H5Fflush(io->file, H5F_SCOPE_LOCAL) < 0) st = VES_ERR_IO;
  if (st == VES_OK) io->nsnap = keep;
  if (st == VES_OK) st = io_xdmf_write(io);
  return io_failed(io, st, errno);
}
