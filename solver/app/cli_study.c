/* vesica study: a grid of runs, locally or through Slurm (study.h;
 * docs/manual.md; docs/design.md, "The program"). */

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "app/cli_impl.h"
#include "app/study.h"

static void usage_study(FILE *f) {
  fprintf(f,
          "usage: vesica study STUDY.ini [--set section.key=value]... [--jobs N] [--out DIR]\n"
          "                   [--retry-failed] [--max-cells N] [--quiet]\n"
          "       vesica study STUDY.ini [--set ...]... [--out DIR] --emit slurm [--throttle N]\n"
          "       vesica study STUDY.ini [--set ...]... [--out DIR] --cell K | --collect\n"
          "Runs the grid of a study file (problems/README.md, 'Study files'): every cell is its\n"
          "own 'vesica run' of the base problem with the cell's --set overrides, writing\n"
          "DIR/cells/NAME.h5 and its log; then DIR/study.csv (one row per cell: the swept\n"
          "values, status and reason, steps, iterations, evaluations, seconds, memory, E*)\n"
          "and DIR/study_sweep.png (E*, steps and wall time against the first numeric axis),\n"
          "with a time.dt_initial axis also DIR/study_frontier.png and DIR/study_cost.png.\n"
          "A rerun skips the cells that ended (failed ones too: --retry-failed reruns them) and\n"
          "continues an interrupted cell from its last snapshot (vesica run --restart), as\n"
          "--retry-failed does a cell its time limit stopped.\n"
          "  --set k=v       override a problem key in every cell (repeatable; part of the\n"
          "                  study: DIR/study.set records it, a rerun must give the same)\n"
          "  --jobs N        cells at a time (default: the number of cores)\n"
          "  --out DIR       the study folder (default: the study file's name, here)\n"
          "  --max-cells N   allow a grid of up to N cells (default %d)\n"
          "  --emit slurm    write DIR/study.sbatch: a job array, one task per cell without a\n"
          "                  result (sbatch it, then --collect)\n"
          "  --throttle N    with --emit slurm: at most N array tasks at a time (--array=...%%N)\n"
          "  --cell K        run cell K (0-based) only, as an array task does\n"
          "  --collect       write the table and figures from the cells that have ended\n"
          "  --quiet         no progress line\n"
          "Exit 0 when every cell ran (whatever its outcome: see the table), 2 on bad input\n"
          "(nothing run), 3 when the folder or table cannot be written, 130/143 when stopped\n"
          "by SIGINT/SIGTERM (running cells save a snapshot and continue from it next time).\n",
          VES_STUDY_MAX_CELLS);
}

static volatile sig_atomic_t study_stop = 0;
static void on_study_signal(int sig) { study_stop = sig; }

typedef struct {
  int tty, quiet;
  const ves_study *s;
} study_view;

/* The progress line: cells done, failed, running, ETA; a line per ended cell. */
static void study_progress(void *ctx, const ves_study_progress *p) {
  const study_view *v = ctx;
  if (v->quiet) return;
  if (p->cell >= 0 && p->note) { /* a cell continued, or its file moved aside */
    char name[PATH_MAX / 2];
    ves_study_cell_name(v->s, p->cell, name, sizeof name);
    fprintf(stderr, "%scell %s: %s\n", v->tty ? "\r\033[K" : "", name, p->note);
    return;
  }
  if (p->cell >= 0 && p->result && (!v->tty || strcmp(p->result->outcome, "converged"))) {
    char name[PATH_MAX / 2];
    ves_study_cell_name(v->s, p->cell, name, sizeof name);
    fprintf(stderr, "%scell %s: %s%s%s (%.1f s)\n", v->tty ? "\r\033[K" : "", name,
            p->result->outcome, p->result->reason[0] ? ": " : "", p->result->reason,
            p->result->wall_seconds);
  }
  char eta[32] = "?";
  if (p->eta >= 0) snprintf(eta, sizeof eta, "%.0f s", p->eta);
  if (v->tty || p->cell < 0)
    fprintf(stderr, "%sstudy: %ld/%ld cells done (%ld before), %ld failed, %d running, ETA %s%s",
            v->tty ? "\r\033[K" : "", p->skipped + p->done, p->total, p->skipped, p->failed,
            p->running, eta, v->tty ? "" : "\n");
}

/* Table and figures of the study in dir; returns the exit code. */
static int study_collect(const ves_study *s, const char *dir, int quiet) {
  char err[1024] = "";
  ves_study_table t;
  if (ves_study_collect(s, dir, &t, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica study: %s\n", err);
    return 3;
  }
  printf("%s/study.csv: %ld of %ld cells, %ld converged\n", dir, t.rows, t.cells, t.converged);
  (void)quiet;
  ves_status st = ves_study_plot(s, dir, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr, "vesica study: figures: %s\n", err);
    return 3;
  }
  printf("%s/study_sweep.png\n", dir);
  for (int a = 0; a < s->naxes; a++)
    if (!strcmp(s->axis[a].key, "time.dt_initial"))
      printf("%s/study_frontier.png\n%s/study_cost.png\n", dir, dir);
  return 0;
}

/* The command's options. */
typedef struct {
  const char *path, *out, *emit;
  long jobs, max_cells, cell, throttle; /* cell -1: every cell; throttle 0: none given */
  int retry, collect, quiet, nset;
  const char *set[MAX_SET]; /* --set, as given */
} study_args;

/* argv into o. 0 to go on, -1 after --help, else the exit code. */
static int study_parse(int argc, char **argv, study_args *o) {
  *o = (study_args){
      .jobs = sysconf(_SC_NPROCESSORS_ONLN), .max_cells = VES_STUDY_MAX_CELLS, .cell = -1};
  int rc;
  for (int i = 0; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      usage_study(stdout);
      return -1;
    } else if (!strcmp(a, "--jobs") || !strcmp(a, "--out") || !strcmp(a, "--max-cells") ||
               !strcmp(a, "--cell") || !strcmp(a, "--emit") || !strcmp(a, "--throttle")) {
      if (i + 1 >= argc) {
        fprintf(stderr, "vesica study: %s needs a value (see vesica study --help)\n", a);
        return 2;
      }
      const char *v = argv[++i];
      if (!strcmp(a, "--out"))
        o->out = v;
      else if (!strcmp(a, "--emit"))
        o->emit = v;
      else if ((rc = cli_parse_long("study", a, v, !strcmp(a, "--cell") ? 0 : 1,
                                    !strcmp(a, "--jobs") ? 1024 : 1000000000L,
                                    !strcmp(a, "--jobs")       ? &o->jobs
                                    : !strcmp(a, "--cell")     ? &o->cell
                                    : !strcmp(a, "--throttle") ? &o->throttle
                                                               : &o->max_cells)))
        return rc;
    } else if (!strcmp(a, "--set")) {
      if ((rc = cli_take_set("study", argc, argv, &i, &o->nset, o->set))) return rc;
    } else if (!strcmp(a, "--retry-failed")) {
      o->retry = 1;
    } else if (!strcmp(a, "--collect")) {
      o->collect = 1;
    } else if (!strcmp(a, "--quiet")) {
      o->quiet = 1;
    } else if (cli_operand("study", "study file", a[0] == '-', a, &o->path)) {
      return 2;
    }
  }
  if (cli_need(o->path, usage_study)) return 2;
  if (o->emit && strcmp(o->emit, "slurm")) {
    fprintf(stderr, "vesica study: --emit '%s': only slurm\n", o->emit);
    return 2;
  }
  if (o->throttle && !o->emit) {
    fprintf(stderr, "vesica study: --throttle goes with --emit slurm\n");
    return 2;
  }
  if ((o->emit != NULL) + o->collect + (o->cell >= 0) > 1) {
    fprintf(stderr, "vesica study: --emit, --cell and --collect exclude each other\n");
    return 2;
  }
  return 0;
}

/* Run the cells of s (all, or --cell) in dir with this program self, then
 * the table and figures. Returns the exit code. */
static int study_run(const ves_study *s, const study_args *o, const char *dir, const char *self) {
  char err[1024] = "";
  study_view view = {.tty = isatty(2), .quiet = o->quiet || o->cell >= 0, .s = s};
  ves_study_run_opts ro = {.program = self,
                           .dir = dir,
                           .jobs = o->cell >= 0 ? 1 : (int)o->jobs,
                           .retry_failed = o->retry,
                           .only = o->cell,
                           .grace = 10,
                           .stop = &study_stop,
                           .progress = study_progress,
                           .ctx = &view};
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_study_signal;
  sigaction(SIGINT, &sa, NULL);
  sigaction(SIGTERM, &sa, NULL);
  ves_status st = ves_study_run(s, &ro, err, sizeof err);
  if (view.tty && !view.quiet) fputc('\n', stderr);
  if (st == VES_STEP_REJECTED) {
    fprintf(stderr,
            "vesica study: stopped by signal %d; the cells that ended are kept, rerun to "
            "continue\n",
            (int)study_stop);
    return 128 + (int)study_stop;
  }
  if (st != VES_OK) {
    fprintf(stderr, "vesica study: %s\n", err[0] ? err : ves_status_str(st));
    return 3;
  }
  return o->cell < 0 ? study_collect(s, dir, o->quiet) : 0;
}

/* --collect, or --emit slurm. Returns the exit code. */
static int study_other(const ves_study *s, const study_args *o, const char *dir, const char *self) {
  char err[1024] = "";
  struct stat sb;
  if (o->collect) {
    if (stat(dir, &sb) != 0 || !S_ISDIR(sb.st_mode)) {
      fprintf(stderr, "vesica study: --collect: %s: no such folder (--out DIR?)\n", dir);
      return 2;
    }
    return study_collect(s, dir, o->quiet);
  }
  long ntasks = 0;
  ves_status st = ves_study_write_sbatch(s, self, dir, o->retry, &ntasks, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr, "vesica study: %s\n", err[0] ? err : ves_status_str(st));
    return st == VES_ERR_CONFIG ? 2 : 3;
  }
  char sets[MAX_SET * (VES_STUDY_SETLEN + 10)] = ""; /* the --set to give again */
  size_t at = 0;
  for (int i = 0; i < s->ncli && at < sizeof sets; i++)
    at += (size_t)snprintf(sets + at, sizeof sets - at, " --set '%s'", s->cli[i]);
  if (ntasks == 0) {
    printf("every cell of the study has its result: nothing to submit, no script written "
           "(vesica study %s%s --out %s --collect for the table)\n",
           o->path, sets, dir);
    return 0;
  }
  if (ves_study_check_folder(s, dir, 1, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica study: %s\n", err);
    return 3;
  }
  printf("%s/study.sbatch: %ld array tasks (of %ld cells); sbatch it, then vesica study %s%s "
         "--out %s --collect\n",
         dir, ntasks, s->ncells, o->path, sets, dir);
  return 0;
}

/* The study folder dir of a local run, made if missing and held with an
 * exclusive flock on it for the run (*fd, closed on exec so that the cells
 * do not inherit it): never the study file itself or a file, never a folder
 * another vesica study is running in (two runners would run its cells
 * twice and write the same files). The Slurm tasks (--cell) share the
 * folder and take no lock. 0, or 2 with the reason (3 when the folder
 * cannot be made). */
static int study_hold(const char *dir, const char *study, int *fd) {
  struct stat sb;
  if (cli_same_file(dir, study)) {
    fprintf(stderr, "vesica study: --out %s: is the study file itself\n", dir);
    return 2;
  }
  if (mkdir(dir, 0777) != 0 && errno != EEXIST) {
    fprintf(stderr, "vesica study: --out %s: cannot make the folder: %s\n", dir, strerror(errno));
    return 3;
  }
  if (stat(dir, &sb) != 0 || !S_ISDIR(sb.st_mode)) {
    fprintf(stderr, "vesica study: --out %s: is a file, not a study folder\n", dir);
    return 2;
  }
  *fd = open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (*fd < 0) {
    fprintf(stderr, "vesica study: --out %s: %s\n", dir, strerror(errno));
    return 3;
  }
  if (flock(*fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    close(*fd), *fd = -1;
    if (e == EWOULDBLOCK) {
      fprintf(stderr,
              "vesica study: --out %s: in use by a running vesica study (it holds a lock on "
              "the folder); wait for it, or stop it and rerun to continue\n",
              dir);
      return 2;
    }
    /* a file system without locks: run unguarded, as the outputs of run do */
  }
  return 0;
}

int cmd_study(int argc, char **argv) {
  study_args o;
  int rc = study_parse(argc, argv, &o);
  if (rc) return rc < 0 ? 0 : rc;
  char err[1024] = "", dir[PATH_MAX], self[PATH_MAX];
  ves_study *s = NULL;
  ves_status st = ves_study_load_set(o.path, o.max_cells, o.nset, o.set, &s, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr, "vesica study: %s\n", err);
    return 2;
  }
  if (o.throttle) s->throttle = o.throttle; /* over [slurm] throttle */
  for (int i = 0; i < s->ncli && s->mode == VES_STUDY_STEP; i++)
    for (int j = 0; j < 4; j++) { /* what run = step sets in every cell */
      static const char *const fixed[] = {
          "time.t_end=", "time.dt_min=", "time.dt_max=", "time.adaptive="};
      if (!strncmp(s->cli[i], fixed[j], strlen(fixed[j])))
        fprintf(stderr,
                "vesica study: note: --set %s has no effect: with run = step every cell takes one "
                "step of dt_initial (t_end = dt_min = dt_max = dt_initial, adaptive = 0)\n",
                s->cli[i]);
    }
  if (o.cell >= s->ncells) {
    fprintf(stderr, "vesica study: --cell %ld: the grid has %ld cells (0 to %ld)\n", o.cell,
            s->ncells, s->ncells - 1);
    ves_study_destroy(&s);
    return 2;
  }
  if (o.out) {
    snprintf(dir, sizeof dir, "%s", o.out);
  } else { /* the study file's name without .ini, here */
    const char *base = strrchr(o.path, '/') ? strrchr(o.path, '/') + 1 : o.path;
    size_t l = strlen(base);
    if (l > 4 && !strcmp(base + l - 4, ".ini")) l -= 4;
    snprintf(dir, sizeof dir, "%.*s", (int)l, base);
  }
  ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
  if (n <= 0) {
    fprintf(stderr, "vesica study: cannot find this program's path: %s\n", strerror(errno));
    ves_study_destroy(&s);
    return 3;
  }
  self[n] = 0;
  int lock = -1; /* a local run holds its folder: another vesica study is refused */
  if (!o.collect && !o.emit && o.cell < 0 && (rc = study_hold(dir, o.path, &lock))) {
    ves_study_destroy(&s);
    return rc;
  }
  if (!o.collect && !o.emit && o.cell >= 0 && mkdir(dir, 0777) != 0 && errno != EEXIST) {
    fprintf(stderr, "vesica study: --out %s: cannot make the folder: %s\n", dir, strerror(errno));
    rc = 3;
  } else if ((st = ves_study_check_folder(s, dir, !o.collect && !o.emit, err, sizeof err)) !=
             VES_OK) { /* another study's folder, or cells under names not parsed back */
    fprintf(stderr, "vesica study: %s\n", err);
    rc = st == VES_ERR_CONFIG ? 2 : 3;
  } else
    rc = o.collect || o.emit ? study_other(s, &o, dir, self) : study_run(s, &o, dir, self);
  if (lock >= 0) close(lock); /* releases the folder */
  ves_study_destroy(&s);
  return rc;
}
