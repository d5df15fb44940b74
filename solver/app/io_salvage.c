/* vesica — salvage of an output file cut short, or whose superblock's end
 * of file is behind its data (a flush that stopped half-way): read with its
 * missing end as zeros and its recorded end at its last byte, keep the last
 * snapshot whose data, series rows, references and remeshings match their
 * checksums, and copy them to a new file. Layout: app/io.h;
 * docs/manual.md for `vesica run --restart`. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "app/io_impl.h"

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

/* The size of the file at path and the end of file its superblock records
 * (-1 when it has none of this module's form): 0, or -1 when unreadable. */
static int sizes(const char *path, long long *size, long long *stored) {
  unsigned char b[64];
  FILE *f = path ? fopen(path, "rb") : NULL;
  if (!f) return -1;
  const size_t got = fread(b, 1, sizeof b, f);
  struct stat sb;
  const int ok = fstat(fileno(f), &sb) == 0;
  fclose(f);
  *size = (long long)sb.st_size, *stored = sb_stored_eof(b, got);
  return ok ? 0 : -1;
}

int ves_io_cut_short(const char *path, long long *size, long long *stored) {
  long long sz, eof;
  if (sizes(path, &sz, &eof) != 0 || eof < 0 || sz >= eof) return 0;
  if (size) *size = sz;
  if (stored) *stored = eof;
  return 1;
}

int ves_io_end_behind(const char *path, long long *size, long long *stored) {
  long long sz, eof;
  if (sizes(path, &sz, &eof) != 0 || eof < 0 || sz <= eof) return 0;
  if (size) *size = sz;
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
  ves_status st = np <= 0 || !io_numeric_type_ok(d, 0) ? VES_ERR_IO : VES_OK;
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
 * (SIGSEGV in H5A__close under H5A__attr_release_table, HDF5 1.10.8;
 * tests/fuzz/fuzz_h5.c; docs/results.md, "Reliability and fuzzing"). */
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
 * crashes it (SIGSEGV in H5T_close_real under H5O_copy_header_map, HDF5
 * 1.10.8; tests/fuzz/fuzz_h5.c; docs/results.md, "Reliability and fuzzing"). */
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

/* Object `name` of src copied to dst once it reads whole (object_readable;
 * two levels: a snapshot's interface group and its datasets). */
static ves_status copy_object(hid_t src, hid_t dst, const char *name) {
  if (!object_readable(src, name, 2)) return VES_ERR_IO;
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
  if (st == VES_OK) st = io_attr_int(d, "count", count);
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
  int ok = io_attr_read(g, "checksum", H5T_NATIVE_UINT64, &want) == VES_OK &&
           io_attr_read(g, "step", H5T_NATIVE_LONG, &step) == VES_OK;
  for (int i = 0; i < 5 && ok; i++) ok = dset_read_all(g, part[i], &v[i], &c[i]) == VES_OK;
  const long n = (long)c[1], nq = (long)c[3]; /* after a remeshing not the header's n */
  ok = ok && c[0] == 2 * (hsize_t)n && c[2] == 2 * c[3] && c[4] == 6 * c[3] &&
       io_ref_sum(n, nq, v[0], v[1], v[2], v[3], v[4], step) == want;
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
           io_attr_read(g, "checksum", H5T_NATIVE_UINT64, &want) == VES_OK &&
           io_attr_read(g, "series_checksum", H5T_NATIVE_UINT64, &want_rows) == VES_OK;
  if (ok && si->state.dt_prev > 0) /* the predictor's y^{n-1} is part of the sum */
    ok = (yp = malloc(2 * n * sizeof *yp)) && ves_io_read_snapshot_prev(src, k, nk, yp) == VES_OK;
  ok = ok && io_snap_sum((long)n, y, x, phi, yp, si) == want && si->rows >= 0;
  if (g >= 0) H5Gclose(g);
  free(y), free(x), free(phi), free(yp);
  /* the rows the checksum covers: the initial state's too when the file has it */
  const long rows = io_rows_covered(src, si->rows);
  for (int i = 0; i < IO_NSERIES && ok; i++)
    ok = src->series[i] < 0 || io_dset_len(src->series[i]) >= (hsize_t)rows;
  if (ok && io_cols_read(src->series, rows, col) != VES_OK) ok = 0;
  if (ok) rows_sum_ = io_rows_sum(FNV_START, col, rows);
  if (ok && rows_sum_ != want_rows) ok = 0;
  for (int r = 0; r < si->reconnections && ok; r++) ok = reference_intact(src, r);
  /* the remeshings made at or before its step, every one whole */
  *remeshes = 0;
  for (int j = 0; ok && j < ves_io_remeshes(src); j++) {
    long step = 0;
    uint64_t sum = 0;
    snprintf(name, sizeof name, "remeshes/%d", j);
    hid_t rg = H5Gopen2(src->file, name, H5P_DEFAULT);
    ok = rg >= 0 && io_attr_read(rg, "step", H5T_NATIVE_LONG, &step) == VES_OK;
    if (ok && step <= si->state.nstep) {
      ok = io_attr_read(rg, "checksum", H5T_NATIVE_UINT64, &sum) == VES_OK &&
           io_group_sum(rg, io_remesh_parts, IO_NREMESH_PARTS) == sum;
      *remeshes = j + 1;
    }
    if (rg >= 0) H5Gclose(rg);
    if (ok && step > si->state.nstep) break;
  }
  if (!ok)
    for (int i = 0; i < IO_NSERIES; i++) free(col[i]), col[i] = NULL;
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
  if (st == VES_OK) st = io_attr_status(d, src->info.status); /* written last: maybe lost */
  if (st == VES_OK) st = io_attr_double(d, "setup_seconds", src->info.setup_seconds);
  if (st == VES_OK) {
    step = "the snapshots";
    st = copy_counted(src->file, d, "snapshots", K + 1);
  }
  if (st == VES_OK) { /* the index of the snapshots kept, from their attributes */
    step = "the snapshot index";
    st = io_index_rebuild(dst, K + 1);
  }
  if (st == VES_OK && si->reconnections > 0) {
    step = "the references";
    st = copy_counted(src->file, d, "references", si->reconnections);
  }
  if (st == VES_OK && remeshes > 0) {
    step = "the remeshings";
    st = copy_counted(src->file, d, "remeshes", remeshes);
  }
  int prov = 0; /* the runs' provenance, as far as it reads (not needed for a restart) */
  hid_t pg = H5Lexists(src->file, "provenance", H5P_DEFAULT) > 0
                 ? H5Gopen2(src->file, "provenance", H5P_DEFAULT)
                 : -1;
  if (pg >= 0 && (io_attr_read(pg, "count", H5T_NATIVE_INT, &prov) != VES_OK || prov < 0)) prov = 0;
  if (pg >= 0) H5Gclose(pg);
  if (st == VES_OK && prov > 0 && copy_counted(src->file, d, "provenance", prov) != VES_OK &&
      H5Lexists(d, "provenance", H5P_DEFAULT) > 0)
    H5Ldelete(d, "provenance", H5P_DEFAULT);
  if (st == VES_OK) {
    step = "the series";
    st = io_create_series(dst, src->series);
  }
  const long rows = io_rows_covered(src, si->rows); /* with the initial state's row */
  for (int i = 0; i < IO_NSERIES && st == VES_OK && rows > 0; i++) {
    if (dst->series[i] < 0) continue; /* as in src: an optional column it lacks */
    hsize_t r = (hsize_t)rows;
    if (H5Dset_extent(dst->series[i], &r) < 0 ||
        H5Dwrite(dst->series[i], io_col_mem_type(io_series[i].type), H5S_ALL, H5S_ALL, H5P_DEFAULT,
                 col[i]) < 0)
      st = VES_ERR_IO;
  }
  if (st == VES_OK && H5Fflush(d, H5F_SCOPE_LOCAL) < 0) st = VES_ERR_IO;
  if (st != VES_OK) {
    char reason[128] = ""; /* a system error is the new file's (the image has none) */
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, io_sys_reason, reason);
    if (reason[0])
      ves_error_say(why, whylen, "!%s: cannot write: %s", out, reason);
    else
      ves_error_say(why, whylen, "snapshot %d: %s do not copy", K, step);
  }
  if (st == VES_OK) { /* the XDMF file of path shows the snapshots kept */
    dst->nsnap = dst->snap_cap = K + 1;
    dst->snap_t = malloc((size_t)(K + 1) * sizeof *dst->snap_t);
    if (dst->snap_t) memcpy(dst->snap_t, src->snap_t, (size_t)(K + 1) * sizeof *dst->snap_t);
    if (!dst->snap_t || io_xdmf_write(dst) != VES_OK)
      dst->nsnap = 0; /* rewritten at the next snapshot */
  }
  ves_io_close(&dst);
  if (st != VES_OK) remove(out);
  return st;
}

/* The file at path (size bytes, its superblock recording stored) opened in
 * memory as *psrc (tolerant: what a salvage reads), its missing end as
 * zeros. *psrc may be set on failure too (the caller closes it). */
static ves_status salvage_open(const char *path, long long size, long long stored, ves_io **psrc,
                               char *err, size_t errlen) {
  /* the image is held in memory, twice at its peak (HDF5 copies it): a
   * recorded end past a quarter of the machine's memory is refused, not
   * allocated (a damaged superblock records any size up to 2^50) */
  const long long end = size > stored ? size : stored;
  const double mem = (double)sysconf(_SC_PHYS_PAGES) * (double)sysconf(_SC_PAGESIZE);
  if (mem > 0 && (double)end > mem / 4) {
    ves_error_say(err, errlen,
                  "%s: its superblock records %lld bytes, more than a quarter of this machine's "
                  "memory (%.1f GB), which the salvage holds it in (a damaged superblock?)",
                  path, end, mem / 1e9);
    return VES_ERR_IO;
  }
  /* the file read whole and padded with zeros to its recorded end: lost
   * blocks read back as zeros, which the checksums reject; a file longer
   * than its recorded end (a flush stopped before the superblock) read to
   * its last byte, the end recorded in the image moved there */
  unsigned char *img = calloc((size_t)end, 1);
  FILE *f = img ? fopen(path, "rb") : NULL;
  const int read_ok = f && fread(img, 1, (size_t)size, f) == (size_t)size;
  if (f) fclose(f);
  if (!read_ok) {
    free(img);
    ves_error_say(err, errlen, "%s: %s", path, img ? "cannot read it" : "out of memory");
    return img ? VES_ERR_IO : VES_ERR_ALLOC;
  }
  if (end > stored) { /* the end of file address (base address 0: sb_stored_eof) */
    const size_t at = (img[8] == 0 ? 24 : 28) + 16;
    for (int i = 0; i < 8; i++)
      img[at + (size_t)i] = (unsigned char)((unsigned long long)end >> (8 * i));
  }
  hid_t fapl = H5Pcreate(H5P_FILE_ACCESS);
  ves_io *src = *psrc = io_alloc(path, 0);
  ves_status st = fapl >= 0 && src && H5Pset_fapl_core(fapl, 1 << 20, 0) >= 0 &&
                          H5Pset_file_image(fapl, img, (size_t)end) >= 0
                      ? VES_OK
                      : VES_ERR_ALLOC;
  free(img); /* the property list holds a copy */
  if (st == VES_OK) {
    src->tolerant = 1;
    /* a name no file has: the core driver refuses an image named as a file */
    src->file = H5Fopen("/nonexistent/vesica-salvage-image", H5F_ACC_RDONLY, fapl);
    st = src->file < 0 || io_read_header(src) != VES_OK ? VES_ERR_IO : VES_OK;
    if (st != VES_OK) ves_error_say(err, errlen, "%s: its header is lost too", path);
  }
  if (fapl >= 0) H5Pclose(fapl);
  return st;
}

ves_status ves_io_salvage(const char *path, const char *out, ves_io_salvaged *res, char *err,
                          size_t errlen) {
  VES_CHECK(path && out && res, VES_ERR_ARG);
  memset(res, 0, sizeof *res);
  io_quiet_hdf5();
  long long size = 0, stored = 0;
  if (!ves_io_cut_short(path, &size, &stored) && !ves_io_end_behind(path, &size, &stored)) {
    ves_error_say(err, errlen,
                  "%s: not cut short (its size is the one its superblock records, or more)", path);
    return VES_ERR_ARG;
  }
  res->size = size, res->stored_size = stored;
  ves_io *src = NULL;
  ves_status st = salvage_open(path, size, stored, &src, err, errlen);
  /* the last snapshot that is complete and copies whole (a copy can still
   * meet a lost block the checksums do not cover: then the one before) */
  int K = st == VES_OK ? src->nsnap - 1 : -1, found = 0;
  char why[2 * PATH_MAX] = "";
  ves_io_snapinfo si;
  for (; st == VES_OK && K >= 0; K--) {
    void *col[IO_NSERIES] = {0};
    int remeshes = 0;
    if (!snapshot_intact(src, K, &si, col, &remeshes)) continue;
    found = 1;
    st = salvage_write(src, path, out, K, &si, col, remeshes, why, sizeof why);
    for (int i = 0; i < IO_NSERIES; i++) free(col[i]);
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
      ves_error_say(err, errlen,
                    "%s: none of its %d snapshot(s) survived whole (or they carry no checksums)",
                    path, src->nsnap);
  } else if (st != VES_OK && why[0] == '!') {
    ves_error_say(err, errlen, "%s", why + 1);
  }
  if (st == VES_OK) {
    hid_t g = H5Gopen2(src->file, "snapshots", H5P_DEFAULT); /* as counted, lost or not */
    if (g < 0 || io_attr_read(g, "count", H5T_NATIVE_INT, &res->snapshots) != VES_OK)
      res->snapshots = src->nsnap;
    if (g >= 0) H5Gclose(g);
    res->snapshot = K, res->rows = si.rows;
    res->step = si.state.nstep, res->t = si.state.t, res->references = si.reconnections;
  }
  ves_io_close(&src);
  return st;
}
