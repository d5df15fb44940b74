/* vesica — running a study's cells: each its own process (fork/exec of the
 * given program with the cell's command), a fixed number at a time, each
 * with a wall-time limit; the .result file of a cell is written when its
 * process has ended, so a study stopped or killed at any point loses no
 * ended cell, and reruns only those that were running (study.h;
 * docs/design.md, "The program"). */
/* wait4 (one child's own CPU time and peak memory) is a BSD call */
#define _DEFAULT_SOURCE
#include "app/study.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "core/clock_impl.h"

/* A running cell. */
typedef struct {
  pid_t pid;      /* 0: free slot */
  long cell;      /* grid index */
  double start;   /* ves_wall_seconds at fork */
  double term_at; /* when SIGTERM was sent (0: not yet) */
  int timed_out;  /* the limit ended it */
} slot;

static int make_dir(const char *path) {
  struct stat sb;
  if (mkdir(path, 0777) == 0 || (errno == EEXIST && stat(path, &sb) == 0 && S_ISDIR(sb.st_mode)))
    return 0;
  return -1;
}

/* Start cell k in sl: its old files removed, its log opened. 0 or -1 (errno). */
static int start_cell(const ves_study *s, const ves_study_run_opts *o, long k, int threads,
                      slot *sl, char *err, size_t errlen) {
  char path[PATH_MAX], log[PATH_MAX];
  const char *old[] = {".h5", ".xdmf", ".result"};
  for (int i = 0; i < 3; i++) {
    ves_study_cell_path(s, k, o->dir, old[i], path, sizeof path);
    remove(path);
  }
  ves_study_cell_path(s, k, o->dir, ".log", log, sizeof log);
  int argc = 0;
  char **argv = NULL;
  char msg[1024] = "";
  if (ves_study_cell_argv(s, k, o->program, o->dir, &argc, &argv, msg, sizeof msg) != VES_OK) {
    ves_error_say(err, errlen, "%s%s", "cell command: ", msg);
    return -1;
  }
  int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) {
    ves_error_say(err, errlen, "%s: cannot write: %s", log, strerror(errno));
    free(argv);
    return -1;
  }
  fflush(NULL);
  pid_t pid = fork();
  if (pid < 0) {
    ves_error_say(err, errlen, "%s: cannot fork: %s", log, strerror(errno));
    close(fd), free(argv);
    return -1;
  }
  if (pid == 0) {
    prctl(PR_SET_PDEATHSIG, SIGKILL); /* a killed study leaves no cell running */
    int in = open("/dev/null", O_RDONLY);
    if (in >= 0) dup2(in, 0);
    dup2(fd, 1), dup2(fd, 2);
    char n[16];
    snprintf(n, sizeof n, "%d", threads);
    setenv("OMP_NUM_THREADS", n, 0);
    setenv("OPENBLAS_NUM_THREADS", "1", 0);
    execv(o->program, argv);
    dprintf(2, "vesica study: cannot execute %s: %s\n", o->program, strerror(errno));
    _exit(127);
  }
  close(fd), free(argv);
  sl->pid = pid, sl->cell = k, sl->start = ves_wall_seconds(), sl->term_at = 0, sl->timed_out = 0;
  return 0;
}

/* The result of cell k of slot c, ended at now (wait4's w, status and ru):
 * classified from its exit and its log, with its wall and CPU time and
 * peak memory, written to the cell's .result file (VES_ERR_IO, the message
 * in err, when that fails). */
static ves_status finish_cell(const ves_study *s, const ves_study_run_opts *o, const slot *c,
                              long k, pid_t w, int status, const struct rusage *ru, double now,
                              ves_study_result *r, char *err, size_t errlen) {
  memset(r, 0, sizeof *r);
  char log[PATH_MAX], path[PATH_MAX];
  ves_study_cell_path(s, k, o->dir, ".log", log, sizeof log);
  const int sig = w > 0 && WIFSIGNALED(status) ? WTERMSIG(status) : 0;
  const int code = w > 0 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  ves_study_classify(code, sig, c->timed_out, s->time_limit, log, r);
  r->wall_seconds = now - c->start;
  if (w > 0) {
    r->cpu_seconds = (double)ru->ru_utime.tv_sec + 1e-6 * (double)ru->ru_utime.tv_usec +
                     (double)ru->ru_stime.tv_sec + 1e-6 * (double)ru->ru_stime.tv_usec;
    r->peak_mb = (double)ru->ru_maxrss / 1024.0; /* kilobytes on Linux */
  }
  ves_study_cell_signature(s, k, r->signature, sizeof r->signature);
  ves_study_cell_path(s, k, o->dir, ".result", path, sizeof path);
  if (ves_study_result_write(path, r) != VES_OK) {
    ves_error_say(err, errlen, "%s: cannot write: %s", path, strerror(errno));
    return VES_ERR_IO;
  }
  return VES_OK;
}

/* The cells of the slots sl that have ended (finished, each with its
 * .result and a progress report) and the limits of those still running
 * (SIGTERM past the time limit, SIGKILL past the grace after it); p, *spent
 * and *st (the first error, in err) updated. stopping: cells that end
 * stopped by us are not done. */
static void reap_cells(const ves_study *s, const ves_study_run_opts *o, slot *sl, int stopping,
                       long npending, double *spent, ves_study_progress *p, ves_status *st,
                       char *err, size_t errlen) {
  const double now = ves_wall_seconds();
  for (int j = 0; j < o->jobs; j++) {
    slot *c = &sl[j];
    if (!c->pid) continue;
    int status = 0;
    struct rusage ru;
    pid_t w = wait4(c->pid, &status, WNOHANG, &ru);
    if (w == 0) { /* still running: the limit, then the grace */
      if (!c->term_at && s->time_limit > 0 && now - c->start > s->time_limit) {
        kill(c->pid, SIGTERM);
        c->term_at = now, c->timed_out = 1;
      } else if (c->term_at && now - c->term_at > o->grace) {
        kill(c->pid, SIGKILL);
      }
      continue;
    }
    if (w < 0 && errno == EINTR) continue;
    p->running--;
    const long k = c->cell;
    c->pid = 0;
    if (stopping && !c->timed_out) continue; /* stopped by us: not done */
    ves_study_result r;
    if (finish_cell(s, o, c, k, w, status, &ru, now, &r, *st == VES_OK ? err : NULL, errlen) !=
            VES_OK &&
        *st == VES_OK)
      *st = VES_ERR_IO;
    *spent += r.wall_seconds;
    p->done++;
    p->failed += strcmp(r.outcome, "converged") != 0;
    p->eta = *spent / (double)p->done * (double)(npending - p->done) / (double)o->jobs;
    p->cell = k, p->result = &r;
    if (o->progress) o->progress(o->ctx, p);
    p->cell = -1, p->result = NULL;
  }
}

/* The cells as processes, o->jobs at a time (study.h). A little over 80
 * lines, on purpose: one polling loop (stop, start, watch the limits, reap)
 * whose state (the slots, the progress, stopping) all four parts share. */
ves_status ves_study_run(const ves_study *s, const ves_study_run_opts *o, char *err,
                         size_t errlen) {
  VES_CHECK(s && o && o->program && o->dir && o->jobs >= 1, VES_ERR_ARG);
  VES_CHECK(o->only < s->ncells, VES_ERR_ARG);
  char cells[PATH_MAX];
  snprintf(cells, sizeof cells, "%s/cells", o->dir);
  if (make_dir(o->dir) || make_dir(cells)) {
    ves_error_say(err, errlen, "%s: cannot create: %s", errno == EEXIST ? o->dir : cells,
                  strerror(errno));
    return VES_ERR_IO;
  }
  const long first = o->only >= 0 ? o->only : 0, last = o->only >= 0 ? o->only : s->ncells - 1;
  long *pending = malloc((size_t)(last - first + 1) * sizeof *pending), npending = 0;
  slot *sl = calloc((size_t)o->jobs, sizeof *sl);
  if (!pending || !sl) {
    free(pending), free(sl);
    return VES_ERR_ALLOC;
  }
  for (long k = first; k <= last; k++)
    if (!ves_study_cell_done(s, k, o->dir, o->retry_failed)) pending[npending++] = k;
  long cores = sysconf(_SC_NPROCESSORS_ONLN);
  const int threads = cores > o->jobs ? (int)(cores / o->jobs) : 1;
  ves_study_progress p = {
      .total = last - first + 1, .skipped = last - first + 1 - npending, .eta = -1, .cell = -1};
  if (o->progress) o->progress(o->ctx, &p);
  long next = 0;
  double spent = 0; /* wall seconds of the cells ended in this run */
  int stopping = 0;
  ves_status st = VES_OK;
  struct timespec nap = {0, 20000000};
  for (;;) {
    if (o->stop && *o->stop && !stopping) { /* terminate what runs; those cells stay not done */
      stopping = 1;
      for (int j = 0; j < o->jobs; j++)
        if (sl[j].pid) kill(sl[j].pid, SIGTERM), sl[j].term_at = ves_wall_seconds();
    }
    for (int j = 0; j < o->jobs && next < npending && !stopping && st == VES_OK; j++)
      if (!sl[j].pid) {
        if (start_cell(s, o, pending[next], threads, &sl[j], err, errlen)) {
          st = VES_ERR_IO;
          stopping = 1;
          for (int i = 0; i < o->jobs; i++)
            if (sl[i].pid) kill(sl[i].pid, SIGTERM), sl[i].term_at = ves_wall_seconds();
          break;
        }
        next++, p.running++;
      }
    if (p.running == 0) break;
    nanosleep(&nap, NULL);
    reap_cells(s, o, sl, stopping, npending, &spent, &p, &st, err, errlen);
  }
  free(pending), free(sl);
  if (st == VES_OK && stopping) st = VES_STEP_REJECTED;
  return st;
}
