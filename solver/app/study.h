/* vesica — studies: a grid of runs of one problem file (robustness studies,
 * parameter sweeps). A study file (INI) names a base problem, fixed
 * overrides and axes (lists or log ranges of any problem key); the grid's
 * cells are run as separate `vesica run` processes, each writing
 * DIR/cells/NAME.h5 and, once it has ended, DIR/cells/NAME.result (how it
 * ended: outcome, reason, wall and CPU seconds, peak memory). A cell with a
 * .result file is done: a rerun skips it (failed ones too, unless asked to
 * retry them); one interrupted (an .h5, no .result) continues from its last
 * snapshot (vesica run --restart). The table DIR/study.csv is collected from the .result and .h5
 * files of whatever cells are done, so a local run, a Slurm job array
 * (ves_study_write_sbatch) and a partial study give the same table.
 *
 * Layers: parsing, expansion, naming, resume, the table, the plots and the
 * sbatch file never start a process (ves_study_*); ves_study_run starts the
 * cells (fork/exec of a given program) and waits for them. Nothing here
 * prints; progress goes through a callback. User-facing behaviour:
 * docs/manual.md; docs/design.md, "The program". */
#ifndef VES_STUDY_H
#define VES_STUDY_H

#include <limits.h>
#include <signal.h>
#include <stddef.h>
#include <stdio.h>

#include "ves/status.h"

#define VES_STUDY_MAX_AXES 8     /* axes of a grid */
#define VES_STUDY_MAX_VALUES 256 /* values of one axis */
#define VES_STUDY_MAX_SET 64     /* fixed overrides */
#define VES_STUDY_VALUE 64       /* characters of one value (with the NUL) */
#define VES_STUDY_SETLEN 192     /* characters of one "section.key=value" */
#define VES_STUDY_MAX_CELLS 1000 /* a larger grid needs an explicit, higher limit */

/* What each cell runs. */
typedef enum {
  VES_STUDY_STEP,  /* one step of constant dt = time.dt_initial from the initial state, no
                      halving (the robustness question: does this step converge?) */
  VES_STUDY_STEPS, /* `steps` accepted steps of the problem as set */
  VES_STUDY_T_END  /* the problem to its t_end */
} ves_study_mode;

/* One axis: a problem key and its values, as text handed to --set. */
typedef struct {
  char key[64]; /* "section.key", the problem table's spelling */
  int nvalues;  /* >= 1 */
  char values[VES_STUDY_MAX_VALUES][VES_STUDY_VALUE]; /* in the study file's order */
} ves_study_axis;

/* A parsed, validated study (plain data; ves_study_load allocates it). */
typedef struct {
  char path[PATH_MAX];    /* the study file */
  char problem[PATH_MAX]; /* the base problem file (absolute when resolvable) */
  ves_study_mode mode;    /* [study] run */
  long steps;             /* [study] steps (VES_STUDY_STEPS) */
  double time_limit;      /* [study] time_limit: wall seconds per cell, 0 none */
  int nset;               /* fixed overrides, applied to every cell */
  char set[VES_STUDY_MAX_SET][VES_STUDY_SETLEN]; /* "section.key=value" */
  int ncli; /* the command line's --set overrides, applied to every cell after [set] */
  char cli[VES_STUDY_MAX_SET][VES_STUDY_SETLEN]; /* "section.key=value", key canonical */
  int naxes;                                     /* >= 1 */
  ves_study_axis axis[VES_STUDY_MAX_AXES];       /* the first axis varies slowest */
  long ncells;                                   /* product of the axes' sizes */
  /* [slurm] resources of one array task */
  char partition[64]; /* "" for the cluster's default */
  char account[64];   /* "" for none */
  char mem[32];       /* e.g. "4G" */
  int cpus_per_task;  /* threads of one cell */
  long throttle;      /* array tasks at a time (--array=...%N), 0 none */
  char setup[1024];   /* shell lines run by each task before the cell ("" none) */
} ves_study;

/* Read and validate the study file `path`: unknown sections or keys, an
 * empty axis, a malformed range, a value the problem table rejects, a cell
 * whose problem is inconsistent, or more than max_cells cells are errors
 * (VES_ERR_CONFIG; VES_ERR_IO when a file cannot be read) with one line
 * "FILE: [section] key: reason" in err. Every cell's problem is loaded
 * (ves_config_load), nothing is run or written. *out is taken by the caller. */
ves_status ves_study_load(const char *path, long max_cells, ves_study **out, char *err,
                          size_t errlen);

/* ves_study_load with the command line's overrides set[nset]
 * ("section.key=value", as vesica run --set): a problem key (its value
 * checked in every cell's problem), not an axis; one that [set] fixes
 * replaces it. They are part of the cells' commands and signatures. */
ves_status ves_study_load_set(const char *path, long max_cells, int nset, const char *const *set,
                              ves_study **out, char *err, size_t errlen);

/* The study folder dir against this study, before anything in it is run,
 * written or read: its cells must not be named in the "key-value_key-value"
 * scheme (not parsed back: refused, renaming them is the user's choice), and
 * its record of the command line's --set (DIR/study.set, one override a
 * line) must be this study's. A folder without the record is taken as made
 * without --set; with write_record the record is written when missing.
 * VES_ERR_CONFIG with what differs in err; VES_ERR_IO when the record
 * cannot be written. */
ves_status ves_study_check_folder(const ves_study *s, const char *dir, int write_record, char *err,
                                  size_t errlen);

/* Print the study file's sections and keys as a Markdown table (section,
 * key, type, default, allowed, meaning), as problems/README.md has it. */
void ves_study_print_keys(FILE *f);

/* Free a study; accepts NULL and nulls the pointer. */
void ves_study_destroy(ves_study **s);

/* Parse one axis value list "a, b, c" or a log range "log(from, to, count)"
 * (count >= 2 values from..to geometric, printed with 12 significant digits)
 * into ax (key untouched). VES_ERR_CONFIG with the reason in err. */
ves_status ves_study_parse_axis(const char *text, ves_study_axis *ax, char *err, size_t errlen);

/* The value index of every axis in cell k (0 <= k < ncells; the first axis
 * varies slowest). */
void ves_study_cell_index(const ves_study *s, long k, int idx[VES_STUDY_MAX_AXES]);

/* The cell's name: its axis values, "key=value" joined by "," (key without
 * its section unless two axes share it; bytes other than letters, digits,
 * '.', '_', '+' and '-' as %XX, so the name parses back to its keys and
 * values), e.g. "backend=newton,dt_initial=0.001". Independent of the axes' order of values, so a
 * grown grid keeps the names of its old cells. */
void ves_study_cell_name(const ves_study *s, long k, char *buf, size_t len);

/* The overrides of cell k: the fixed ones ([set], then the command line's),
 * the axis values, then for
 * VES_STUDY_STEP time.adaptive=0 and dt_min = dt_max = t_end = dt_initial.
 * set[*nset] point into buf (VES_STUDY_CELL_SETS entries of
 * VES_STUDY_SETLEN). VES_ERR_CONFIG when the cell's problem does
 * not load (message in err). */
#define VES_STUDY_CELL_SETS (2 * VES_STUDY_MAX_SET + VES_STUDY_MAX_AXES + 4)
ves_status ves_study_cell_sets(const ves_study *s, long k, char buf[][VES_STUDY_SETLEN], int *nset,
                               char *err, size_t errlen);

/* Whether cell k's problem passes the setup's geometric checks that come
 * before any node is made (its shape with the band of (band + 1) eps inside
 * the box; with band_layers, band*eps within the shape's radii of
 * curvature), as vesica check applies them: VES_ERR_CONFIG with check's
 * message in err when not. ves_study_load refuses a study whose every cell
 * fails them; ves_study_run records the others as bad_input unrun. */
ves_status ves_study_cell_check(const ves_study *s, long k, char *err, size_t errlen);

/* The command of cell k: program run PROBLEM --out DIR/cells/NAME.h5 --quiet
 * [--max-steps N] --set ... ; argv (NULL-terminated, *argc entries) and its
 * strings in one malloc'd block *argv, taken by the caller (free(*argv)). */
ves_status ves_study_cell_argv(const ves_study *s, long k, const char *program, const char *dir,
                               int *argc, char ***argv, char *err, size_t errlen);

/* How a cell ended (DIR/cells/NAME.result, written once the process ended). */
typedef struct {
  char outcome[16];     /* converged | failed | timeout | crashed | bad_input */
  char reason[256];     /* the run's last message, the signal, the limit; "" when converged */
  int exit_code;        /* of the process; -1 when killed by a signal */
  int signal;           /* the signal that ended it, 0 none */
  double wall_seconds;  /* the process, start to end */
  double cpu_seconds;   /* user + system time of the process */
  double peak_mb;       /* its peak resident memory (MB) */
  char signature[4096]; /* the cell's command without the program: a changed study reruns it */
} ves_study_result;

/* Paths of a cell's files: DIR/cells/NAME + suffix (".h5", ".log", ".result"). */
void ves_study_cell_path(const ves_study *s, long k, const char *dir, const char *suffix, char *buf,
                         size_t len);

/* Write (atomically: a temporary file renamed) and read a .result file. */
ves_status ves_study_result_write(const char *path, const ves_study_result *r);
ves_status ves_study_result_read(const char *path, ves_study_result *r);

/* The cell's signature (its command after the program, --out excluded). */
ves_status ves_study_cell_signature(const ves_study *s, long k, char *buf, size_t len);

/* Whether cell k is done: its .result exists, holds this study's command
 * for it, and (with retry_failed) its outcome is converged. */
int ves_study_cell_done(const ves_study *s, long k, const char *dir, int retry_failed);

/* The outcome of an ended cell from its exit code or signal, whether the
 * limit killed it, and its log (the last line naming vesica is the reason). */
void ves_study_classify(int exit_code, int sig, int timed_out, double time_limit,
                        const char *log_path, ves_study_result *r);

/* Counts of a collected table. */
typedef struct {
  long cells;     /* in the grid */
  long rows;      /* done, written to the table */
  long converged; /* rows with status converged */
} ves_study_table;

/* DIR/study.csv from the done cells (one row per cell in grid order, the
 * cells not done left out): cell, every axis key, status, reason, exit_code,
 * steps, t_final, dt_first, iterations, f_evals, g_evals, h_evals, retries,
 * violation_max, energy_initial, energy_final, area_drift_max,
 * volume_drift_max, nodes, setup_seconds, loop_seconds, seconds_per_step,
 * wall_seconds, cpu_seconds, peak_mb (RFC 4180; an unknown number is an
 * empty field). In the one-step mode a step that raised E* (explicit Euler's
 * instability) has status energy_rose. */
ves_status ves_study_collect(const ves_study *s, const char *dir, ves_study_table *t, char *err,
                             size_t errlen);

/* Figures of the done cells through gnuplot (pngcairo): DIR/study_sweep.png
 * for any grid (E*_final, accepted steps and wall seconds against the
 * first numeric axis, or the first axis as named categories; one curve per
 * value of the other axes; log x when the values span more than a decade;
 * cells that did not converge crossed in red), and with a time.dt_initial
 * axis DIR/study_frontier.png (per group of the other axes' values: the
 * largest converged dt and the status of every dt) and DIR/study_cost.png
 * (seconds per step against dt, log axes). VES_ERR_IO with gnuplot's
 * message. */
ves_status ves_study_plot(const ves_study *s, const char *dir, char *err, size_t errlen);

/* DIR/study.sbatch: a Slurm job array of the cells not done
 * (ves_study_cell_done with retry_failed), one task per cell (--array=
 * their indices as ranges, e.g. 0-3,7, with %N for s->throttle), each
 * running [slurm] setup verbatim, then `program study STUDY --out DIR
 * [--set ...] [--retry-failed] --cell $SLURM_ARRAY_TASK_ID`; --time from
 * the cell limit (+ 5 minutes), resources from [slurm]; task logs in
 * DIR/slurm/. *ntasks gets the number of tasks; with none, nothing is
 * written (DIR not created either; a DIR/study.sbatch of an earlier call
 * removed) and VES_OK. DIR is created when missing
 * (its parent must exist). Every name goes into the script as one bash
 * word on one line ('...', or $'...' with \xHH escapes for control bytes
 * and bytes that are not UTF-8); the values of the #SBATCH lines, which
 * sbatch reads with its own rules, are refused (VES_ERR_CONFIG, nothing
 * written) when they hold a control byte, a byte that is not UTF-8, '"',
 * '\\' or the word packjob or hetjob. VES_ERR_IO when DIR cannot be
 * resolved, created or written. */
ves_status ves_study_write_sbatch(const ves_study *s, const char *program, const char *dir,
                                  int retry_failed, long *ntasks, char *err, size_t errlen);

/* Progress of a run (for the caller's progress line). */
typedef struct {
  long total;   /* cells to consider */
  long skipped; /* done before this run */
  long done;    /* ended in this run */
  long failed;  /* of those, not converged */
  int running;  /* processes now */
  double eta;   /* seconds to the end (mean cell time x cells left / jobs), -1 unknown */
  long cell;    /* the cell that just ended, or -1 */
  const ves_study_result *result; /* its result, or NULL */
  const char *note; /* about cell: it continues from its snapshot, or its file was moved
                       aside (result NULL); NULL otherwise */
} ves_study_progress;

typedef void (*ves_study_progress_fn)(void *ctx, const ves_study_progress *p);

/* Options of ves_study_run. */
typedef struct {
  const char *program;            /* the vesica binary (borrowed) */
  const char *dir;                /* the study folder (created with cells/ if missing) */
  int jobs;                       /* cells at a time (>= 1) */
  int retry_failed;               /* rerun cells that ended but did not converge */
  long only;                      /* run this cell only (the Slurm task), -1 all */
  double grace;                   /* seconds between SIGTERM and SIGKILL at the limit */
  volatile sig_atomic_t *stop;    /* set (by a signal handler) to stop: running cells are
                                     terminated and stay not done; may be NULL */
  ves_study_progress_fn progress; /* called at the start and after every cell, may be NULL */
  void *ctx;                      /* passed to progress */
} ves_study_run_opts;

/* Run the cells not done, opts->jobs at a time, each with its own process,
 * stdout and stderr to DIR/cells/NAME.log, OMP_NUM_THREADS (unless set) from
 * the cores and jobs, OPENBLAS_NUM_THREADS=1 (unless set); a cell past
 * time_limit gets SIGTERM, then SIGKILL after opts->grace. Writes each
 * ended cell's .result. A cell interrupted before (its .h5 and .cmd, no
 * .result) continues from its last intact snapshot with `program run
 * --restart`; a file that cannot be continued is moved to NAME.h5.unusable
 * and the cell starts over. A cell failing ves_study_cell_check gets a
 * bad_input .result without a process. VES_ERR_IO when the folder cannot be made (err);
 * VES_STEP_REJECTED when stopped through opts->stop. */
ves_status ves_study_run(const ves_study *s, const ves_study_run_opts *opts, char *err,
                         size_t errlen);

#endif
