/* vesica — the snapshot index /snapshot_index: one row (k, step, t) per
 * snapshot in time order, so that a reader iterating the dataset meets the
 * snapshots in time order (HDF5 lists the groups "0", "1", "10", "2", ... by
 * name). The /snapshots count stays what defines the complete snapshots;
 * the index is kept equal to it by every writer: a row after each snapshot,
 * rebuilt from the snapshots' own attributes whenever its length disagrees
 * (a file cut between a snapshot and its row, a file of an older writer),
 * shortened with the snapshots and written anew by a salvage. Layout:
 * app/io.h. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "app/io_impl.h"

#define INDEX_NAME "snapshot_index"
#define INDEX_CHUNK 64 /* rows per chunk (1 KiB) */

typedef struct {
  int32_t k;
  int64_t step;
  double t;
} index_row;

/* The compound type of a row: its file layout (packed, little-endian) or
 * the native one. */
static hid_t row_type(int file) {
  size_t size = file ? 4 + 8 + 8 : sizeof(index_row);
  hid_t t = H5Tcreate(H5T_COMPOUND, size);
  if (t < 0) return -1;
  herr_t e =
      H5Tinsert(t, "k", file ? 0 : HOFFSET(index_row, k), file ? H5T_STD_I32LE : H5T_NATIVE_INT32);
  if (e >= 0)
    e = H5Tinsert(t, "step", file ? 4 : HOFFSET(index_row, step),
                  file ? H5T_STD_I64LE : H5T_NATIVE_INT64);
  if (e >= 0)
    e = H5Tinsert(t, "t", file ? 12 : HOFFSET(index_row, t),
                  file ? H5T_IEEE_F64LE : H5T_NATIVE_DOUBLE);
  if (e < 0) {
    H5Tclose(t);
    return -1;
  }
  return t;
}

/* The open index of io's file, created empty when absent. */
static hid_t index_open(ves_io *io) {
  if (H5Lexists(io->file, INDEX_NAME, H5P_DEFAULT) > 0)
    return H5Dopen2(io->file, INDEX_NAME, H5P_DEFAULT);
  hsize_t zero = 0, unlim = H5S_UNLIMITED, chunk = INDEX_CHUNK;
  hid_t sp = H5Screate_simple(1, &zero, &unlim), dcpl = H5Pcreate(H5P_DATASET_CREATE),
        ft = row_type(1), d = -1;
  if (sp >= 0 && dcpl >= 0 && ft >= 0 && H5Pset_chunk(dcpl, 1, &chunk) >= 0)
    d = H5Dcreate2(io->file, INDEX_NAME, ft, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT);
  if (ft >= 0) H5Tclose(ft);
  if (dcpl >= 0) H5Pclose(dcpl);
  if (sp >= 0) H5Sclose(sp);
  if (d >= 0 &&
      io_describe(d, "t in t*",
                  "the snapshots in time order: row i is /snapshots/<k> (k = i), its step and "
                  "t; rows beyond /snapshots count are not snapshots") != VES_OK) {
    H5Dclose(d);
    return -1;
  }
  return d;
}

/* Rows from..to-1 of d written from buf (the extent is the caller's). */
static ves_status rows_write(hid_t d, hsize_t from, hsize_t m, const index_row *buf) {
  if (m == 0) return VES_OK;
  hid_t mt = row_type(0), fs = H5Dget_space(d), ms = H5Screate_simple(1, &m, NULL);
  herr_t e = mt < 0 || fs < 0 || ms < 0
                 ? -1
                 : H5Sselect_hyperslab(fs, H5S_SELECT_SET, &from, NULL, &m, NULL);
  if (e >= 0) e = H5Dwrite(d, mt, ms, fs, H5P_DEFAULT, buf);
  if (ms >= 0) H5Sclose(ms);
  if (fs >= 0) H5Sclose(fs);
  if (mt >= 0) H5Tclose(mt);
  return e < 0 ? VES_ERR_IO : VES_OK;
}

/* Rows 0..count-1 of d from the attributes step and t of /snapshots/0..count-1. */
static ves_status rows_rebuild(ves_io *io, hid_t d, int count) {
  if (count <= 0) return VES_OK;
  index_row *r = malloc((size_t)count * sizeof *r);
  if (!r) return VES_ERR_ALLOC;
  ves_status st = VES_OK;
  for (int k = 0; k < count && st == VES_OK; k++) {
    char name[48];
    snprintf(name, sizeof name, "snapshots/%d", k);
    hid_t g = H5Gopen2(io->file, name, H5P_DEFAULT);
    long step = -1;
    r[k].k = k;
    st = g < 0 ? VES_ERR_IO : io_attr_read(g, "step", H5T_NATIVE_LONG, &step);
    if (st == VES_OK) st = io_attr_read_double(g, "t", &r[k].t);
    r[k].step = step;
    if (g >= 0) H5Gclose(g);
  }
  if (st == VES_OK) st = rows_write(d, 0, (hsize_t)count, r);
  free(r);
  return st;
}

ves_status io_index_put(ves_io *io, int k, long step, double t) {
  hid_t d = index_open(io);
  if (d < 0) return VES_ERR_IO;
  const hsize_t have = io_dset_len(d), want = (hsize_t)k + 1;
  ves_status st = H5Dset_extent(d, &want) < 0 ? VES_ERR_IO : VES_OK;
  /* rows 0..k-1 stand for the snapshots before when the index held exactly
   * them; any other length: written anew from the snapshots */
  if (st == VES_OK && have != (hsize_t)k) st = rows_rebuild(io, d, k);
  const index_row row = {.k = k, .step = step, .t = t};
  if (st == VES_OK) st = rows_write(d, (hsize_t)k, 1, &row);
  H5Dclose(d);
  return st;
}

ves_status io_index_rebuild(ves_io *io, int count) {
  hid_t d = index_open(io);
  if (d < 0) return VES_ERR_IO;
  const hsize_t want = (hsize_t)count;
  ves_status st = H5Dset_extent(d, &want) < 0 ? VES_ERR_IO : rows_rebuild(io, d, count);
  H5Dclose(d);
  return st;
}

ves_status io_index_truncate(ves_io *io, int keep) {
  if (H5Lexists(io->file, INDEX_NAME, H5P_DEFAULT) <= 0) return VES_OK; /* the next put builds it */
  hid_t d = H5Dopen2(io->file, INDEX_NAME, H5P_DEFAULT);
  if (d < 0) return VES_ERR_IO;
  const hsize_t want = (hsize_t)keep;
  ves_status st = VES_OK;
  if (io_dset_len(d) > want && H5Dset_extent(d, &want) < 0) st = VES_ERR_IO;
  H5Dclose(d);
  return st;
}
