/* vesica — what the files of the command line share (cli*.c): the run's
 * state, option and file helpers, messages. Private to the program; the
 * library never includes it (docs/design.md, "The program"). */
#ifndef VES_CLI_IMPL_H
#define VES_CLI_IMPL_H

#include <limits.h>
#include <stdio.h>

#include "ves/backend.h"
#include "app/config.h"
#include "ves/integrate.h"
#include "app/io.h"
#include "app/problem.h"
#include "ves/setup.h"
#include "ves/status.h"
#include "core/clock_impl.h"

#define VES_VERSION "1.0.0"
#define MAX_SET 64 /* --set options a command takes */

/* The commands: argc, argv after the command's name; each returns the exit
 * code. */
int cmd_check(int argc, char **argv);
int cmd_run(int argc, char **argv);
int cmd_info(int argc, char **argv);
int cmd_plot(int argc, char **argv);
int cmd_spectrum(int argc, char **argv);
int cmd_study(int argc, char **argv);

/* ---- options, problem files, output paths (cli_common.c) ---------------- */

/* A setup's message err, naming label (the problem file) unless err does. */
void cli_setup_error(const char *cmd, const char *label, const char *err);
/* Exit code for a failed library call: 2 bad input, 3 numerical. */
int cli_exit_for(ves_status st);
/* The text of a failed library call's status st: its meaning and, when the
 * error record holds st (status.h), the condition that failed and where. */
const char *cli_why(ves_status st);
/* The size and cost of a setup, estimated from the problem before it is
 * built: a line when large (unless quiet), a refusal (2) beyond the
 * machine's memory. 0 ok. */
int cli_setup_estimate(const char *cmd, const ves_config *c, int quiet);
/* Load the problem file path with the --set overrides set[nset] into cfg.
 * 0, or the exit code (message printed; the usage when path is NULL). */
int cli_load_problem(const char *cmd, const char *path, void (*usage_fn)(FILE *), int nset,
                     const char *const *set, ves_config *cfg);
/* A --set argument at argv[*i]: 0 when taken, else the exit code. */
int cli_take_set(const char *cmd, int argc, char **argv, int *i, int *nset, const char **set);
/* An operand a of command cmd (what: "file", ...): an unknown option when
 * is_option, a second operand when *path is set (2, message printed), else
 * taken into *path (0). */
int cli_operand(const char *cmd, const char *what, int is_option, const char *a, const char **path);
/* 0 when the operand path was given, else 2 with the usage on stderr. */
int cli_need(const char *path, void (*usage_fn)(FILE *));
/* A long in [lo, hi] for option opt; 0, or 2 with a message. */
int cli_parse_long(const char *cmd, const char *opt, const char *v, long lo, long hi, long *out);
/* The folder of path exists and is writable, path is not a folder: 0, else 2. */
int cli_check_writable(const char *cmd, const char *what, const char *path);
/* Whether a and b name the same existing file. */
int cli_same_file(const char *a, const char *b);
/* The guard of every file a command writes (option what): its folder
 * writable, never one of the inputs in[nin], never a file a running vesica
 * holds (its HDF5 output, XDMF file, --series or --vectors file), whatever
 * force; an existing file only with force: 0, else 2 (hint, if any, says
 * how to keep the file). Called before the command's work and again just
 * before the file is created. */
int cli_check_output(const char *cmd, const char *what, const char *path, int force,
                     const char *const *in, int nin, const char *hint);
/* Whether argument a is an option's value (not an option; "-1" is a value). */
int cli_is_value(const char *a);
/* The standard streams: closed ones opened on /dev/null (stdout on
 * /dev/full) at the start, and the command's exit code rc at the end: 3
 * with a message when its standard output could not be written. */
void cli_streams_begin(void);
int cli_streams_end(const char *cmd, int rc);

/* ---- a run's state (cli_state.c) ------------------------------------------ */

/* Everything a run holds. */
typedef struct {
  const char *label;          /* what messages name: the problem file or FILE.h5 */
  char out[PATH_MAX];         /* the HDF5 file */
  ves_config cfg;             /* parameters */
  const ves_backend_type *bk; /* step solver */
  ves_setup *setup;           /* initial discrete state */
  ves_sim *sim;               /* the integrator */
  ves_io *io;                 /* the output file */
  double *phi;                /* n scratch: phi at the nodes */
  double *y;                  /* 2n scratch: coefficients */
  double *x;                  /* 2n scratch: material positions at the nodes */
  double *v;                  /* 2n scratch: the flow at the nodes */
  FILE *series;               /* --series file or NULL (locked: held while open) */
  const char *series_path;    /* --series FILE.tsv */
  long series_good;           /* its bytes up to the end of the last line written whole */
  int series_errno;           /* why it could not be written (0: it could) */
  long series_step;           /* the step whose line failed (-1: the file's close) */
  int quiet;                  /* --quiet */
  long max_steps;             /* --max-steps (0: none) */
  int ncap;                   /* nodes phi, y, x, v have room for */
  double wall_offset;         /* wall time of the time loop before this process */
  long last_snapshot_step;    /* step of the last snapshot written */
  int from_snapshot;          /* --restart's --from-snapshot K (-1: the last) */
} run_ctx;

void cli_run_free(run_ctx *r);
/* The scratch buffers for n nodes (the node count changes at a remeshing). */
ves_status cli_ensure_nodes(run_ctx *r, int n);
/* Nodes of the reference in use. */
int cli_nodes_now(run_ctx *r);
/* Setup, phi at the nodes and the integrator for r->cfg and r->bk; 0 or
 * the exit code (message printed). */
int cli_build(run_ctx *r);
/* Snapshot of the current state (wall: the loop's time so far). */
ves_status cli_snapshot(run_ctx *r, double wall);
/* The reference the last reset made, and the remeshing just made, for a
 * restart (io.h). */
ves_status cli_write_reference(run_ctx *r, long step);
ves_status cli_write_remesh(run_ctx *r, long step, const ves_remesh_info *info);
/* The run of r->io (its problem in r->cfg) rebuilt at snapshot S into r;
 * pre starts every message. 0 or the exit code. */
int cli_rebuild_at(run_ctx *r, const char *pre, int S, ves_io_snapinfo *si);

/* ---- run (cli_run.c, cli_restart.c) --------------------------------------- */

/* Why a write to the output failed: the io module's cause, else the status. */
const char *cli_io_cause(const ves_io *io, ves_status st);
/* The time loop: steps, rows, snapshots, progress. Returns the exit code. */
int cli_loop(run_ctx *r);
/* The progress line's estimate of the steps left, a range [*nlo, *nhi]
 * (cli_loop.c): t reached, dt_next the next step's dt, t_back the time k
 * steps before (k = 0: none), nstep the steps accepted in all; --max-steps
 * max_steps (0: none) caps it. A pure function of its arguments. */
void cli_eta_steps(const ves_config *c, long max_steps, long nstep, double t, double dt_next,
                   double t_back, int k, double *nlo, double *nhi);
/* The ETA text of the wall-time range [lo, hi] (seconds): "LO-HI UNIT", or
 * "V UNIT" when both print the same; UNIT s (hi below 120 s, whole
 * seconds), min (below 120 min) or h (one decimal below 10). */
void cli_eta_text(char *buf, size_t len, double lo, double hi);
/* vesica spectrum's verdict line into buf (cli_spectrum.c): the modes
 * below -1e-3 1/t* counted from below (the exact count of eigenvalues
 * below --above) and mu[nmodes] (the eigenvalues found above it, in
 * increasing order). Returns that count (a lower bound when every mode
 * found is below -1e-3), or -1 when it cannot be told (eigenvalues below an
 * --above higher than -1e-3). */
int cli_spectrum_verdict(char *buf, size_t len, double above, int below, int nmodes,
                         const double *mu);
/* Continue FILE.h5 from its last snapshot with the overrides set[nset]. */
int cli_run_restart(run_ctx *r, const char *file, int nset, const char *const *set);
/* The keys a restart may change, "a, b and c", then " tail", into f: the
 * first line after `col` characters already printed on it, wrapped before
 * `width` (0: no wrapping) with continuation lines indented by `indent`. */
void cli_restart_keys_print(FILE *f, int col, int indent, int width, const char *tail);

#endif
