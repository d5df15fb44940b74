/* vesica — run output: one HDF5 file per run (written as the run goes, read
 * back by `vesica info`, `plot` and restart) and an XDMF file beside it so
 * ParaView opens the snapshots as a time series. The module writes files and
 * never prints (docs/design.md, "The program"; io_*.c implement it).
 *
 * Layout (format_version 3; HDF5 1.10, default (earliest) format bounds, so a
 * killed writer leaves no "file open for writing" flag behind; format 2: the
 * same without the series' initial row, snapshot interfaces and /provenance;
 * docs/manual.md, "Output format", the reader's reference):
 *
 *   /                    attributes
 *     format_version     int 3 (2: read and continued as written; 1: the same
 *                        without snapshot x; read-only)
 *     program, version   "vesica", the program version
 *     backend            step solver of the run
 *     nodes              int n (real nodes; y has 2n entries)
 *     problem            the full problem text after --set overrides (every
 *                        key, reals in their shortest exact form): a restart
 *                        rebuilds the identical setup from it
 *     source             absolute path of the problem file (points files of
 *                        a curve shape are found next to it)
 *     E0, A0, V0         E* (units k), area and volume at t = 0
 *     setup_seconds      wall time of the setup (last run or restart)
 *     status             running | finished | stopped | failed (a killed run
 *                        stays "running")
 *     format_description where this layout is described (this header)
 *   every group and dataset (the root too) has string attributes units and
 *   description (the series' status lists the ves_status codes, and has
 *   them as attribute codes: an HDF5 enumeration of their names); optional:
 *   readers need neither
 *   /parameters          every problem-file key as a typed attribute named
 *                        "section.key" (double, int or string)
 *   /mesh/X              n x 2 reference node positions (R, Z), units R0
 *   /mesh/triangles      ntri x 3 int, the reference Delaunay triangles (fixed
 *                        connectivity: each snapshot is this mesh deformed)
 *   /mesh/vertices       n int 0..n-1 (the nodes as XDMF points)
 *   /series/<name>       1-D extendible chunked datasets, one row per accepted
 *                        step, appended and flushed (H5Fflush) after every
 *                        step: t, dt, E (E*), A, V, V_target, lambda_A,
 *                        lambda_V, c0, iterations, f_evals, g_evals, h_evals,
 *                        violation, solve_seconds, wall_seconds, retries,
 *                        status, reconnections, factorizations (optional:
 *                        a file without it reads -1) and last step (row 0
 *                        the initial state, step 0 at t = 0, written with
 *                        snapshot 0, which the API's rows do not count; row
 *                        i holds step i; the table io_series in io_series.c)
 *   /snapshots           attribute count; groups "0", "1", ... each with
 *     y                  n x 2 nodal coefficients y^a (r, z) of the motion:
 *                        the state a restart continues from
 *     x                  n x 2 positions y(X_a) of the material at the nodes
 *                        of the reference in use (ves_sim_node_material):
 *                        what the XDMF file and `vesica plot` show (the
 *                        coefficients, LME not interpolating, stray from the
 *                        material by many spacings near a squeezed axis)
 *                        (format 1 has no x; its readers get y)
 *     phi                n, phi of that material (phi0 of the reference at
 *                        X_a)
 *     attributes         t, step, rows (series rows at the snapshot), and the
 *                        integrator state (ves_sim_state: dt, E, A, V, E0, A0,
 *                        V0 in model units, E* = E / k; lambda_A, lambda_V,
 *                        c0), wall_seconds, reconnections; checksum (uint64,
 *                        FNV-1a over y, x, phi and the state) and
 *                        series_checksum (over the series rows up to it, the
 *                        initial row included; none before the first step),
 *                        what a salvage of a file cut short checks (optional:
 *                        a snapshot without them is not salvaged)
 *     interface          group: the sharp interface phi = 0 on the triangles
 *                        in use at x (level_set.h): datasets 0..pieces-1 (m x
 *                        2, r z, attribute closed), attributes pieces, area,
 *                        volume, reduced_volume, inverted; outside the
 *                        checksum (derived data)
 *   /snapshot_index      the snapshots in time order (io_index.c): row i the
 *                        compound (k int32, step int64, t float64) of
 *                        /snapshots/<k>, k = i; as many rows as the count
 *                        (a file cut right after a snapshot, or continued
 *                        by an older writer, may hold fewer: the count rules)
 *   /references          (runs with resets) attribute count; groups "0", "1",
 *                        ... one per reset of the reference configuration,
 *                        what ves_reconnect_restore rebuilds it from:
 *     x, h               n x 2 node positions (R, Z) and n spacings h_a
 *     points, weights    nq x 2 quadrature points and nq weights
 *     phi0               nq x 6 point data of phi0 (value, gradient, Hessian)
 *     attribute step     the accepted step after which the reset was made
 *     attribute checksum uint64 FNV-1a over the data and step
 *   /remeshes            (runs with [remesh]) attribute count; groups "0", ...
 *                        one per full remeshing, what ves_remesh_restore
 *                        rebuilds it from: x (n' x 2), h, flag, phi0c (n'),
 *                        triangles (ntri' x 3), vertices (n'); attribute step
 *                        and what it changed (ves_io_remesh). Snapshots and
 *                        references after it have n' nodes (their datasets'
 *                        sizes say so) and the XDMF file shows them on its
 *                        triangles; attribute checksum (uint64 FNV-1a over
 *                        x, h, flag, phi0c, triangles, vertices as doubles)
 *
 *   /provenance          attribute count; groups "0", "1", ... one per run that
 *                        wrote the file (the first, then each restart): string
 *                        attributes version, commit, compiler, cflags, hdf5,
 *                        mumps, ipopt, nlopt, openblas, openblas_core, host,
 *                        started, command; int threads (io_provenance.c)
 *
 * Snapshot 0 is the initial state; then every [output] snapshot_every steps
 * and the last state of a run (finished, stopped or failed). A restart
 * continues from the last snapshot (on reference reconnections - 1 when the
 * run had reset its reference before it) and drops the series rows and
 * references after it. */
#ifndef VES_IO_H
#define VES_IO_H

#include <stddef.h>
#include <stdio.h>

#include "app/config.h"
#include "ves/integrate.h"
#include "ves/status.h"

#define VES_IO_FORMAT                                                                              \
  3 /* format_version written; 1 and 2 are read too, 2 continued (its                              \
       series without the initial state's row, as written) */

/* What a new file starts with (everything borrowed for the call). */
typedef struct {
  const char *version;   /* program version */
  const char *backend;   /* backend name */
  const char *problem;   /* problem text (ves_config_to_text) */
  const char *source;    /* absolute path of the problem file, or "" */
  const ves_config *cfg; /* the parameters, for /parameters */
  int n;                 /* real nodes */
  const double *X;       /* 2n reference positions */
  int ntri;              /* reference triangles */
  const int *tri;        /* 3 ntri node indices */
  double E0, A0, V0;     /* initial E*, A, V */
  double setup_seconds;  /* wall time of the setup */
} ves_io_header;

/* One row of the series: one accepted step. */
typedef struct {
  long step;                     /* accepted-step index (1, 2, ...) */
  double t, dt;                  /* time reached, step taken (t*) */
  double E, A, V;                /* E* (units k), area, volume after the step */
  double V_target;               /* volume target of the step */
  double lambda_A;               /* multiplier of the area constraint */
  double lambda_V;               /* multiplier of the volume constraint */
  double c0;                     /* C0 R0 in force */
  int iterations;                /* backend iterations */
  int f_evals, g_evals, h_evals; /* objective, gradient, Hessian evaluations */
  double violation;              /* max |c_i| / target_i at the solution */
  double solve_seconds;          /* wall time of the accepted solve */
  double wall_seconds;           /* wall time of the time loop since t = 0 (over restarts) */
  int retries;                   /* halvings of dt before acceptance */
  int status;                    /* ves_status of the accepted solve */
  int reconnections;             /* reference-configuration resets so far */
  int factorizations;            /* KKT factorizations of the accepted solve (newton, euler) */
} ves_io_row;

/* The row of an accepted step: the report rep, the resets so far, the wall
 * time of the time loop. */
void ves_io_row_from_step(const ves_step_report *rep, int reconnections, double wall_seconds,
                          ves_io_row *row);

/* The series as tab-separated text in the columns of vesica info --series
 * (vesica run --series; docs/manual.md, "The series"): every column of the
 * file under its name, step first, then the file's order. The name of text
 * column k (0-based; NULL past the last); the header line of the names (no
 * comment mark: numpy.genfromtxt(names=True) and pandas read it); one line
 * a row, each value %.12g as vesica info prints it. VES_ERR_IO when a write
 * fails. */
const char *ves_io_text_column(int k);
ves_status ves_io_text_header(FILE *f);
ves_status ves_io_text_row(FILE *f, const ves_io_row *row);

/* What was written with a snapshot besides y and phi. */
typedef struct {
  ves_sim_state state;    /* the integrator's state (t, step = state.nstep, ...) */
  double wall_seconds;    /* wall time of the time loop at the snapshot */
  int reconnections;      /* resets so far */
  long rows;              /* series rows at the snapshot */
  const double *y_prev;   /* written with the snapshot when state.dt_prev > 0: y^{n-1}
                             (2n, ves_sim_y_prev), dataset y_prev; never set by a read
                             (ves_io_read_snapshot_prev reads it) */
  const double *velocity; /* written when not NULL: the flow at the nodes (2n, R0 per t*:
                             the material's velocity over the last step, at x), dataset
                             velocity, an XDMF vector; for looking at only (not in the
                             snapshot's checksum, not read by a restart); never set by a
                             read (ves_io_read_snapshot_velocity reads it) */
} ves_io_snapinfo;

/* The header of an open file (owned by the handle). */
typedef struct {
  int format_version;
  char version[64], backend[64], status[16];
  char *problem;     /* problem text */
  char *source;      /* absolute path of the problem file */
  int n;             /* real nodes */
  int ntri;          /* reference triangles */
  double E0, A0, V0; /* initial E*, A, V */
  double setup_seconds;
} ves_io_info;

typedef struct ves_io ves_io;

/* Create (truncate) path and write the header, /parameters and /mesh.
 * VES_ERR_IO when the file cannot be created (message in err). The XDMF file
 * is written next to it (path with .h5 replaced by .xdmf) at every snapshot,
 * and FILE_last.xmf, the last snapshot alone as one grid (meshio.read). */
ves_status ves_io_create(const char *path, const ves_io_header *h, ves_io **out, char *err,
                         size_t errlen);

/* Open an existing output file, read-only or (writable) to continue it.
 * VES_ERR_IO: cannot open / not HDF5; VES_ERR_CONFIG: HDF5 but not a vesica
 * file of a known format_version (its header attributes or series of a type
 * this module does not write included: numbers are read only from IEEE f64
 * and little-endian 32/64-bit integers), or a format 1 file opened writable
 * (message in err, naming the file). */
ves_status ves_io_open(const char *path, int writable, ves_io **out, char *err, size_t errlen);

/* ves_io_open's modes: writable 0 (read-only), 1 (to continue it), or
 * VES_IO_CHECK: read-only, the series verified snapshot by snapshot
 * (ves_io_verify_snapshot) rather than against the last one at open: a
 * restart's validation, which looks for the last intact snapshot. */
#define VES_IO_READ 0
#define VES_IO_WRITE 1
#define VES_IO_CHECK 2

/* Reading verifies what it reads: the stored problem text against its
 * checksum (root attribute problem_checksum), every counted group against
 * its count (at open), the series rows a snapshot sums against its
 * series_checksum (at a read-only open: the last snapshot's), and a
 * snapshot's data and state against its checksum (ves_io_read_snapshot*,
 * ves_io_verify_snapshot). A mismatch is corruption: VES_ERR_CONFIG, and
 * this names the dataset and the reason ("" when none was found). */
const char *ves_io_corruption(const ves_io *io);

/* What the file lacks to be verified whole (a file written without the
 * checksum of its problem text), "" when nothing. */
const char *ves_io_note(const ves_io *io);

/* Whether snapshot k is intact: its data and state, the series rows up to
 * it, the references and remeshings it stands on match their checksums and
 * its numbers are finite. VES_ERR_CONFIG with ves_io_corruption naming the
 * dataset when not. */
ves_status ves_io_verify_snapshot(ves_io *io, int k);

/* The last intact snapshot before k (ves_io_verify_snapshot), -1 when none. */
int ves_io_last_intact(ves_io *io, int k);

/* Keep snapshots 0..keep-1 (the count attribute; the XDMF file rewritten):
 * a restart from an earlier snapshot. */
ves_status ves_io_truncate_snapshots(ves_io *io, int keep);

/* Flush and close; accepts NULL and sets *io to NULL. */
void ves_io_close(ves_io **io);

const ves_io_info *ves_io_get_info(const ves_io *io);

/* Append one row to every series and flush the file. */
ves_status ves_io_append(ves_io *io, const ves_io_row *row);

/* Write snapshot number ves_io_snapshots(io) — coefficients y (2n),
 * material positions x (2n), phi (n), and si — flush, and rewrite the XDMF
 * file. */
ves_status ves_io_snapshot(ves_io *io, const double *y, const double *x, const double *phi,
                           const ves_io_snapinfo *si);

/* Whether the folder of the file and the file-size limit (RLIMIT_FSIZE)
 * leave room for what a run writes next: one series row, `snapshots`
 * snapshots and (nq > 0) a reference of nq quadrature points, with a margin
 * for HDF5's metadata. VES_ERR_IO when not, the cause in ves_io_error.
 * Checked before each step, so a run on a filling disk stops between
 * complete writes (a write that fails half-way can leave HDF5 metadata
 * pointing past the end of the file). */
ves_status ves_io_room(ves_io *io, int snapshots, int nq);

/* The cause of the last failed write or room check ("no space left on
 * device ...", strerror of the failing write), or NULL. */
const char *ves_io_error(const ves_io *io);

/* What the file keeps after a failed write: the number of complete
 * snapshots (0 when none), the step and t* of the last (unless NULL), and
 * *intact (unless NULL) 1 when the file is as last flushed (every write is
 * preceded by a reservation of its room, so a full disk refuses it before
 * anything is written), 0 when a write failed half-way (an I/O error, a
 * file system without fallocate): vesica run --restart then salvages it. */
int ves_io_kept(ves_io *io, long *step, double *t, int *intact);

/* Set the root attribute status (at most 15 characters) and flush. */
ves_status ves_io_set_status(ves_io *io, const char *status);

/* Overwrite the problem text (root attribute problem) and /parameters with
 * cfg's (a restart that changed solver settings: what a later restart and
 * info read), and flush. */
ves_status ves_io_set_problem(ves_io *io, const ves_config *cfg);

/* Overwrite the root attribute setup_seconds (a restart's own setup). */
ves_status ves_io_set_setup_seconds(ves_io *io, double seconds);

/* Keep the first `rows` rows of every series (a restart drops the rows
 * after its snapshot). */
ves_status ves_io_truncate(ves_io *io, long rows);

/* Complete rows: the length of the shortest series, less one when its last
 * "step" (written last) is not yet there (a run killed in the middle of an
 * append leaves some series one row longer). */
long ves_io_rows(const ves_io *io);

/* Series `name` (one of the names in the layout) as doubles: out[rows].
 * VES_ERR_ARG for an unknown name. */
ves_status ves_io_read_series(ves_io *io, const char *name, double *out);

/* Whether the file's series start with the row of the initial state (step
 * 0 at t = 0: E0, A0, V0 and the problem's C0; files of this version), which
 * ves_io_rows, ves_io_read_series and the snapshots' rows do not count. */
int ves_io_initial_row(const ves_io *io);

/* Series `name` with that row first when the file has it: out[rows + 1]
 * (ves_io_initial_row), else as ves_io_read_series. */
ves_status ves_io_read_series_all(ves_io *io, const char *name, double *out);

/* Runs recorded in /provenance (0 for a file of an older version). */
int ves_io_provenance_runs(const ves_io *io);

/* Item i (0, 1, ...) of run k's provenance: its name into key and its value
 * as text into value (truncated to fit). VES_ERR_ARG past the last item. */
ves_status ves_io_provenance(ves_io *io, int k, int i, char *key, size_t keylen, char *value,
                             size_t valuelen);

/* The name of the file's series column i, in the layout's order (t first,
 * step last), for 0 <= i < the number of columns; NULL past the last. */
const char *ves_io_series_name(int i);

/* A rise of E* between accepted steps above this relative rounding counts
 * as a rise (the integrator's acceptance test uses the same margin). */
#define VES_IO_MONOTONE_TOL 1e-10

/* The statistics of a run's series (vesica info). */
typedef struct {
  long steps;                              /* rows */
  double t_final;                          /* the last row's t* (0 without rows) */
  double E_final, A_final, V_final;        /* the last row's E*, A, V (E0, A0, V0 without) */
  int energy_monotone;                     /* 1: E* never rose by more than
                                              VES_IO_MONOTONE_TOL relative between accepted
                                              steps on the same C0 and volume target */
  double area_drift_max, volume_drift_max; /* max |A/A0 - 1|, max |V/V_target - 1| */
  double dt_first, dt_largest;             /* t* (0 without rows) */
  double retries, iterations, h_evals;     /* sums over the rows */
  double factorizations;                   /* sum over the rows; -1: not recorded (the
                                              optional column absent) */
  double reconnections, wall_seconds;      /* the last row's (0 without rows) */
} ves_io_summary;

/* The summary of the series of io; c0: the problem's C0 before the first
 * step (a C0 switch at step 1 is not a rise). */
ves_status ves_io_summarize(ves_io *io, double c0, ves_io_summary *s);

/* Number of snapshots (complete ones: a snapshot group without its data is
 * not counted). */
int ves_io_snapshots(const ves_io *io);

/* Snapshot k: y (2n), x (2n; y for a format 1 file) and phi (n) unless
 * NULL, si unless NULL; n the header's nodes (VES_ERR_IO for a snapshot
 * after a remeshing of another node count: ves_io_read_snapshot_n). The
 * snapshot is read whole and verified, whatever is asked for: VES_ERR_IO
 * when a part does not read, VES_ERR_CONFIG when its checksum does not
 * match or t, dt, E, A or V is not finite (ves_io_corruption names it). */
ves_status ves_io_read_snapshot(ves_io *io, int k, double *y, double *x, double *phi,
                                ves_io_snapinfo *si);

/* A reference configuration made by a reset (reconnect.h), what a restart
 * rebuilds it from (ves_reconnect_restore): written at every reset, so a
 * snapshot with r resets behind it continues on reference r - 1. */
typedef struct {
  long step;                  /* the accepted step after which the reset was made */
  int nq;                     /* points */
  const double *x, *h;        /* 2n node positions (r, z), n spacings h_a */
  const double *xq, *wq, *pd; /* 2 nq points, nq weights, 6 nq point data of phi0 */
} ves_io_reference;

/* The same, with the caller's buffers to read into (sizes as above; nq in;
 * n in: the reference's nodes, 0 for the header's). */
typedef struct {
  long step;
  int nq;
  int n;
  double *x, *h, *xq, *wq, *pd;
} ves_io_reference_buf;

/* Write reference number ves_io_references(io) and flush. */
ves_status ves_io_write_reference(ves_io *io, const ves_io_reference *ref);

/* Complete references in the file (0 for a run without resets). */
int ves_io_references(const ves_io *io);

/* Reference k into out's buffers (out->nq must match the file). */
ves_status ves_io_read_reference(ves_io *io, int k, ves_io_reference_buf *out);

/* The step after which reference k was made. */
ves_status ves_io_reference_step(const ves_io *io, int k, long *step);

/* Keep the first count references (a restart drops those made after its
 * snapshot). */
ves_status ves_io_truncate_references(ves_io *io, int count);

/* A full remeshing (remesh.h), what a restart rebuilds it from
 * (ves_remesh_restore) and what it changed: written at every remeshing, so a
 * snapshot continues on the last remeshing made at or before its step (a
 * remeshing comes before the snapshot of its step) and, when a reset came
 * after it, on that reset's reference rebuilt on its model. Snapshots and
 * references written after it have its node count. */
typedef struct {
  long step;                   /* the accepted step after which it was made (>= 1) */
  int n;                       /* real nodes of the new set */
  const double *x, *h;         /* 2n positions (r, z), n spacings */
  const int *flag;             /* n VES_NODE_* flags */
  const double *phi0c;         /* n nodal coefficients of phi0 */
  int ntri;                    /* the new Delaunay triangles (for the XDMF file) */
  const int *tri;              /* 3 ntri node indices */
  const ves_remesh_info *info; /* what it changed: stored as attributes */
} ves_io_remesh;

/* The same, with the caller's buffers (n in: ves_io_remesh_size). */
typedef struct {
  long step;
  int n;
  double *x, *h;
  int *flag;
  double *phi0c;
} ves_io_remesh_buf;

/* Write remeshing number ves_io_remeshes(io) (group /remeshes/<k>) and flush. */
ves_status ves_io_write_remesh(ves_io *io, const ves_io_remesh *rm);

/* Complete remeshings in the file (0 for a run without). */
int ves_io_remeshes(const ves_io *io);

/* Remeshing k: its step, node and triangle counts (each may be NULL). */
ves_status ves_io_remesh_size(const ves_io *io, int k, long *step, int *n, int *ntri);

/* Remeshing k into out's buffers (out->n must match the file). */
ves_status ves_io_read_remesh(ves_io *io, int k, ves_io_remesh_buf *out);

/* Keep the first count remeshings (a restart drops those after its snapshot). */
ves_status ves_io_truncate_remeshes(ves_io *io, int count);

/* Real nodes of snapshot k (the header's, or after a remeshing its node
 * count); -1 when k is out of range or unreadable. */
int ves_io_snapshot_nodes(const ves_io *io, int k);

/* The node set snapshot k is on: the remeshing (its index) made last at or
 * before the snapshot's step, or -1 for the initial mesh; *n and *ntri (may
 * be NULL) its node and triangle counts. */
int ves_io_snapshot_mesh(const ves_io *io, int k, int *n, int *ntri);

/* The triangles of remeshing k (3 ntri, ves_io_remesh_size). */
ves_status ves_io_read_remesh_triangles(ves_io *io, int k, int *tri);

/* y^{n-1} of snapshot k (2 nbuf values; the predictor's state), present
 * exactly when the snapshot's state.dt_prev > 0. VES_ERR_IO when absent or of
 * another size. */
ves_status ves_io_read_snapshot_prev(ves_io *io, int k, int nbuf, double *y_prev);

/* The flow at the nodes of snapshot k (2 nbuf values, ves_io_snapinfo's
 * velocity) into v. Returns 1 when read, 0 when the snapshot has none (the
 * first one, a file without velocities, a state without a last step),
 * negative (a ves_status) on an error or another size. */
int ves_io_read_snapshot_velocity(ves_io *io, int k, int nbuf, double *v);

/* ves_io_read_snapshot with buffers for nbuf nodes: VES_ERR_IO when the
 * snapshot's node count is not nbuf (ves_io_snapshot_nodes). */
ves_status ves_io_read_snapshot_n(ves_io *io, int k, int nbuf, double *y, double *x, double *phi,
                                  ves_io_snapinfo *si);

/* The reference mesh: X (2n) and tri (3 ntri), either may be NULL. */
ves_status ves_io_read_mesh(ves_io *io, double *X, int *tri);

/* Whether the file at path is an HDF5 file cut short: shorter than the end
 * of file its superblock records (a torn last write, a full disk, an
 * interrupted copy). HDF5 refuses to open such a file. Its size and the
 * recorded one in *size and *stored unless NULL. */
int ves_io_cut_short(const char *path, long long *size, long long *stored);

/* Whether the file at path is longer than the end of file its superblock
 * records: data written after the last complete flush (a run killed or a
 * disk filled during a write). HDF5 opens such a file unless a flush that
 * stopped half-way left metadata pointing past the recorded end; then
 * ves_io_salvage recovers it. Sizes as ves_io_cut_short's. */
int ves_io_end_behind(const char *path, long long *size, long long *stored);

/* What ves_io_salvage kept. */
typedef struct {
  long long size, stored_size; /* bytes in the file, bytes its superblock records */
  int snapshots;               /* snapshots the file counted */
  int snapshot;                /* the last one complete: the new file holds 0..snapshot */
  long step, rows;             /* its step and series rows */
  double t;                    /* its time t* */
  int references;              /* references kept (those it needs) */
} ves_io_salvaged;

/* Recover a file cut short (ves_io_cut_short) or whose recorded end is
 * behind its data (ves_io_end_behind) into the new file `out` (which must
 * not exist): read with the missing end as zeros (or to its last byte, the
 * recorded end moved there), it keeps the
 * last snapshot that is complete — its data and state, the series rows up
 * to it, the references and remeshings it stands on all read whole and
 * match the checksums written with them — and copies the header,
 * parameters, mesh, those rows, snapshots 0..K, references and remeshings;
 * the XDMF file of `path` is rewritten for them. The file is read into
 * memory padded to its recorded end (twice that at the peak). VES_ERR_ARG:
 * path is neither; VES_ERR_IO: nothing complete survived, out cannot
 * be written, or the recorded end exceeds a quarter of the machine's memory
 * (nothing left at out); message in err. */
ves_status ves_io_salvage(const char *path, const char *out, ves_io_salvaged *res, char *err,
                          size_t errlen);

/* Whether the XDMF file can name the HDF5 file h5path (its name, the part
 * after the last '/'; folders do not matter: the reference is relative).
 * XDMF readers take a data item's text "NAME:/dataset" apart at the first
 * ':' (ParaView's Xdmf3) or at every ':' (meshio) and at '|', strip
 * leading spaces, and XML holds neither control characters nor bytes that
 * are not UTF-8; no escape exists for these, so such names are refused
 * (0, the reason in why unless NULL). XML's & < > " are escaped. */
int ves_io_xdmf_name_ok(const char *h5path, char *why, size_t len);

/* The XDMF path for an HDF5 path: ".h5" replaced by ".xdmf" (or appended). */
void ves_io_xdmf_path(const char *h5path, char *out, size_t len);
/* FILE_last.xmf beside FILE.h5: the last snapshot as one grid (meshio.read). */
void ves_io_xdmf_last_path(const char *h5path, char *out, size_t len);

#endif
