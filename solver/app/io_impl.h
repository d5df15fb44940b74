/* vesica — what the files of the run output (io_*.c) share: the handle, the
 * table of series columns, and the HDF5 helpers for attributes, datasets,
 * counted groups and checksums. The layout is documented in app/io.h; the
 * output's role in docs/design.md, "The program". Private to solver/app. */
#ifndef VES_IO_IMPL_H
#define VES_IO_IMPL_H

#include <hdf5.h>
#include <limits.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "app/io.h"

#define IO_CHUNK 512 /* rows per chunk of a series (4 KiB of doubles) */

typedef enum { COL_LONG, COL_INT, COL_DOUBLE } col_type;

/* The per-step row as one table of columns, in the file's order: the
 * file's series (create, append, truncate, read, checksum) and the --series
 * text (ves_io_text_*) read it. */
typedef struct {
  const char *name;
  col_type type;
  size_t offset;                   /* into ves_io_row */
  const char *units, *description; /* the dataset's attributes */
} series_spec;

#define IO_NSERIES 21 /* columns of io_series */
extern const series_spec io_series[IO_NSERIES];

struct ves_io {
  hid_t file;               /* the HDF5 file */
  int writable;             /* opened for writing */
  char path[PATH_MAX];      /* the HDF5 file */
  char xdmf[PATH_MAX];      /* the XDMF file beside it */
  hid_t series[IO_NSERIES]; /* open series datasets */
  ves_io_info info;         /* header */
  int nsnap;                /* complete snapshots */
  double *snap_t;           /* nsnap times (for the XDMF file) */
  int snap_cap;             /* capacity of snap_t */
  char error[2 * PATH_MAX]; /* the cause of the last failed write ("" none) */
  uint64_t series_sum;      /* checksum of the first summed_rows series rows */
  long summed_rows;         /* rows in series_sum */
  int tolerant;             /* salvage: count the snapshots up to the first unreadable one */
  long last_step;           /* step of snapshot nsnap - 1 when written here (-1: read it) */
  int intact;               /* the last failed write left the file as last flushed */
  int broken;               /* a write failed half-way: nothing more is written */
  int reserved;             /* io_reserve took blocks past the end (freed at the close) */
  char corrupt[1024];       /* what reading found corrupt ("" none): ves_io_corruption */
  char note[256];           /* what reading could not verify ("" all): ves_io_note */
  int row0;                 /* 1: the series start with the row of the initial state (step
                               0, t = 0), which the API's rows do not count */
  int row0_pending;         /* a new file: that row is written with the first snapshot or
                               row (io_row0_write) */
  ves_io_row row0_row;      /* its values */
  int prov_pending;         /* opened to continue: the run's provenance is written before
                               its first write of a row or snapshot */
  char started[32];         /* UTC ISO 8601 time the handle was made (the run's start) */
  int *tri_now;             /* the triangles of the node set in use (interface curves) */
  int ntri_now;             /* their count (0: not read yet) */
  double iface_bytes;       /* bytes the last snapshot's interface group takes at most */
};

/* The dataset rows a snapshot's series_checksum covers for its `rows` step
 * rows: none for a snapshot before the first step (a salvage of it needs
 * no series), else the initial state's row too when the file has one. */
static inline long io_rows_covered(const ves_io *io, long rows) {
  return rows > 0 ? rows + io->row0 : 0;
}

/* ---- the handle and HDF5's errors (io_hdf5.c) ---- */
ves_io *io_alloc(const char *path, int writable); /* no file open yet */
void io_quiet_hdf5(void);                         /* HDF5 silent, no exit-time cleanup */
herr_t io_sys_reason(unsigned n, const H5E_error2_t *e, void *data); /* H5Ewalk2: errno text */
ves_status io_failed(ves_io *io, ves_status st, int errnum);         /* record io->error */

/* ---- room for the next write (io_hdf5.c) ---- */
#define IO_ROOM_MARGIN (64 * 1024) /* HDF5's metadata beyond the data of one write */
ves_status io_reserve(ves_io *io, double bytes);
double io_row_bytes(const ves_io *io);

/* ---- attributes (io_hdf5.c): scalar, overwritten in place ---- */
ves_status io_attr_double(hid_t obj, const char *name, double v);
ves_status io_attr_int(hid_t obj, const char *name, int v);
ves_status io_attr_long(hid_t obj, const char *name, long v);
ves_status io_attr_u64(hid_t obj, const char *name, uint64_t v);
ves_status io_attr_str(hid_t obj, const char *name, const char *s);
ves_status io_attr_status(hid_t file, const char *status);
ves_status io_describe(hid_t obj, const char *units, const char *description);
ves_status io_describe_at(hid_t loc, const char *path, const char *units, const char *description);
int io_numeric_type_ok(hid_t obj, int is_attr);
ves_status io_attr_read(hid_t obj, const char *name, hid_t mtype, void *v);
ves_status io_attr_read_double(hid_t obj, const char *name, double *v);
ves_status io_attr_read_str(hid_t obj, const char *name, char **out);
ves_status io_attr_read_buf(hid_t obj, const char *name, char *buf, size_t len);

/* ---- datasets (io_hdf5.c) ---- */
ves_status io_dset_write(hid_t loc, const char *name, hid_t ftype, hid_t mtype, hsize_t d0,
                         hsize_t d1, const void *data);
ves_status io_dset_read(hid_t loc, const char *name, hid_t mtype, hsize_t count, void *data);
hsize_t io_dset_len(hid_t d);
hsize_t io_dset_rows(hid_t loc, const char *name);

/* ---- counted groups: snapshots, references, remeshes (io_hdf5.c) ---- */
ves_status io_counted_open(hid_t file, const char *parent, int k, hid_t *ps, hid_t *pg);
ves_status io_counted_close(hid_t file, hid_t s, hid_t g, int k, ves_status st);

/* ---- checksums, FNV-1a 64 (io_hdf5.c) ---- */
#define FNV_START 0xcbf29ce484222325ULL
uint64_t io_fnv(uint64_t h, const void *data, size_t len);
uint64_t io_snap_sum(long n, const double *y, const double *x, const double *phi,
                     const double *y_prev, const ves_io_snapinfo *si);
uint64_t io_ref_sum(long n, long nq, const double *x, const double *h_, const double *xq,
                    const double *wq, const double *pd, long step);
uint64_t io_group_sum(hid_t g, const char *const *part, int np);
ves_status io_attr_problem(hid_t file, const char *text); /* "problem" and its checksum */
#define IO_NREMESH_PARTS 6
extern const char *const io_remesh_parts[IO_NREMESH_PARTS];

/* ---- series (io_series.c) ---- */
int io_col_optional(int i);
hid_t io_col_mem_type(col_type t);
uint64_t io_rows_sum(uint64_t h, void *const *col, long m);
ves_status io_cols_read(hid_t const *series, long rows, void **col);
ves_status io_series_sum(ves_io *io, long rows, uint64_t *out);
ves_status io_create_series(ves_io *io, const hid_t *like);
ves_status io_append_row(ves_io *io, const ves_io_row *row); /* no reservation, no provenance */
ves_status io_row0_write(ves_io *io); /* the initial state's row when pending */

/* ---- the snapshot index /snapshot_index (io_index.c) ---- */
/* Row k (snapshot k, its step and t) written, the index k + 1 rows long;
 * rows 0..k-1 rebuilt from the snapshots when its length was not k. */
ves_status io_index_put(ves_io *io, int k, long step, double t);
ves_status io_index_rebuild(ves_io *io, int count); /* rows 0..count-1 from the snapshots */
ves_status io_index_truncate(ves_io *io, int keep); /* at most keep rows */

/* ---- provenance (io_provenance.c) ---- */
void io_utc_now(char *buf, size_t len); /* UTC ISO 8601, seconds */
ves_status io_provenance_write(ves_io *io);
ves_status io_provenance_pending(ves_io *io); /* io_provenance_write once, when pending */

/* ---- reading (io_read.c) and the XDMF file (io_xdmf.c) ---- */
ves_status io_read_header(ves_io *io);
int io_nodes_now(const ves_io *io);
ves_status io_xdmf_write(const ves_io *io);

#endif
