/* vesica — running a study's cells: each its own process (fork/exec of the
 * given program with the cell's command), a fixed number at a time, each
 * with a wall-time limit; the .result file of a cell is written when its
 * process has ended, so a study stopped or killed at any point loses no
 * ended cell; those that were running continue from their last snapshot
 * at the next call (vesica run --restart; a file that cannot be continued
 * is moved aside and the cell starts over), and so do cells stopped by their
 * time limit when failed cells are retried. A cell whose problem fails the
 * setup's geometric checks is recorded bad_input without a process
 * (study.h; docs/design.md, "The program"). */
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

#include "app/io.h"
#include "core/clock_impl.h"

/* A running cell. */
typedef struct {
  pid_t pid;      /* 0: free slot */
  long cell;      /* grid index */
  double start;   /* ves_wall_seconds at fork */
  double term_at; /* when SIGTERM was sent (0: not yet) */
  int timed_out;  /* the limit ended it */
  int resuming;   /* a vesica run --restart of the cell's interrupted .h5 */
} slot;

static int make_dir(const char *path) {
  struct stat sb;
  if (mkdir(path, 0777) == 0 || (errno == EEXIST && stat(path, &sb) == 0 && S_ISDIR(sb.st_mode)))
    return 0;
  return -1;
}

/* The signature record of cell k (DIR/cells/NAME.cmd: the command it was
 * started with), which tells an interrupted .h5 of this study's cell from
 * one of a changed study. */
static int cmd_matches(const ves_study *s, const ves_study_run_opts *o, long k) {
  char path[PATH_MAX], sig[4096], had[4096] = "";
  ves_study_cell_path(s, k, o->dir, ".cmd", path, sizeof path);
  FILE *f = fopen(path, "r");
  if (!f) return 0;
  if (!fgets(had, sizeof had, f)) had[0] = 0;
  fclose(f);
  had[strcspn(had, "\n")] = 0;
  return ves_study_cell_signature(s, k, sig, sizeof sig) == VES_OK && !strcmp(sig, had);
}

static void write_cmd(const ves_study *s, const ves_study_run_opts *o, long k) {
  char path[PATH_MAX], sig[4096];
  ves_study_cell_path(s, k, o->dir, ".cmd", path, sizeof path);
  if (ves_study_cell_signature(s, k, sig, sizeof sig) != VES_OK) return;
  FILE *f = fopen(path, "w");
  if (f) fprintf(f, "%s\n", sig), fclose(f);
}

/* Whether the cell's .result (path) says its time limit stopped it. */
static int ended_by_time_limit(const char *path) {
  ves_study_result r;
  return ves_study_result_read(path, &r) == VES_OK && !strcmp(r.outcome, "timeout");
}

/* How an interrupted cell's .h5 (path) is continued: -1 from its last
 * snapshot, K >= 0 from snapshot K (its last one does not verify, K is the
 * last intact one before it; -2: none is), as its read-only check says. A
 * file HDF5 cannot open (cut short) is left to the restart's salvage (-1). */
static int resume_from(const char *path) {
  ves_io *ro = NULL;
  if (ves_io_open(path, VES_IO_CHECK, &ro, NULL, 0) != VES_OK) return -1;
  const int n = ves_io_snapshots(ro);
  int from = -1;
  if (n < 1)
    from = -2;
  else if (ves_io_verify_snapshot(ro, n - 1) != VES_OK)
    from = ves_io_last_intact(ro, n - 1) >= 0 ? ves_io_last_intact(ro, n - 1) : -2;
  ves_io_close(&ro);
  return from;
}

/* Move the cell's .h5 that cannot be continued aside (NAME.h5.unusable,
 * .unusable.1, ...: kept, never deleted); a line in log_fd and note[len]
 * say so. */
static void move_aside(const char *h5, int log_fd, const char *why, char *note, size_t len) {
  char to[PATH_MAX + 32];
  struct stat sb;
  snprintf(to, sizeof to, "%s.unusable", h5);
  for (int i = 1; stat(to, &sb) == 0 && i < 1000; i++)
    snprintf(to, sizeof to, "%s.unusable.%d", h5, i);
  if (rename(h5, to) == 0)
    snprintf(note, len, "%s cannot be continued (%s): moved to %s; the cell starts over", h5, why,
             to);
  else
    snprintf(note, len, "%s cannot be continued (%s) nor moved aside: %s", h5, why,
             strerror(errno));
  if (log_fd >= 0) dprintf(log_fd, "vesica study: %s\n", note);
}

/* Start cell k in sl. An interrupted cell of this study (its .h5 and the
 * record of its command, no .result, or a .result of a timeout when it is
 * retried) continues from its last intact snapshot with `program run
 * --restart` (resume, the log appended to);
 * otherwise its old files are removed and it starts from its problem
 * (with resume -1: after a restart that failed, its log kept). 0 or -1. */
static int start_cell(const ves_study *s, const ves_study_run_opts *o, long k, int threads,
                      slot *sl, int resume, char *note, size_t notelen, char *err, size_t errlen) {
  const int append = resume < 0;
  char path[PATH_MAX], log[PATH_MAX], h5[PATH_MAX], res[PATH_MAX];
  ves_study_cell_path(s, k, o->dir, ".h5", h5, sizeof h5);
  ves_study_cell_path(s, k, o->dir, ".result", res, sizeof res);
  ves_study_cell_path(s, k, o->dir, ".log", log, sizeof log);
  struct stat sb;
  int from = -1;
  const int foreign = /* interrupted, but started by another version of the study */
      resume > 0 && stat(res, &sb) != 0 && stat(h5, &sb) == 0 && !cmd_matches(s, o, k);
  /* stopped by its time limit (rerun by --retry-failed): continued as an
   * interrupted cell, its .result dropped so that an interruption of the
   * continuation is continued in turn */
  const int timed_out =
      resume > 0 && stat(h5, &sb) == 0 && ended_by_time_limit(res) && cmd_matches(s, o, k);
  if (resume < 0 ||
      (resume && ((stat(res, &sb) == 0 && !timed_out) || stat(h5, &sb) != 0 || foreign)))
    resume = 0; /* ended otherwise (a retry starts over), not begun, or another study's */
  if (resume && timed_out) remove(res);
  int fd = open(log, O_WRONLY | O_CREAT | (resume || append ? O_APPEND : O_TRUNC), 0644);
  if (fd < 0) {
    ves_error_say(err, errlen, "%s: cannot write: %s", log, strerror(errno));
    return -1;
  }
  if (foreign) /* kept: hours of a run are not deleted for a changed study file */
    move_aside(h5, fd, "started with another command: the study file changed", note, notelen);
  if (resume && (from = resume_from(h5)) == -2) {
    move_aside(h5, fd, "no intact snapshot", note, notelen);
    resume = 0;
  }
  if (!resume) {
    const char *old[] = {".h5", ".xdmf", "_last.xmf", ".result"};
    for (int i = 0; i < 4; i++) {
      ves_study_cell_path(s, k, o->dir, old[i], path, sizeof path);
      remove(path);
    }
    write_cmd(s, o, k);
  }
  int argc = 0;
  char **argv = NULL;
  char msg[1024] = "";
  char steps[32], snap[32];
  const long max_steps = s->mode == VES_STUDY_STEP ? 1 : s->mode == VES_STUDY_STEPS ? s->steps : 0;
  snprintf(steps, sizeof steps, "%ld", max_steps);
  snprintf(snap, sizeof snap, "%d", from);
  char *rargv[10] = {(char *)o->program, "run", "--restart", h5};
  int ra = 4;
  if (resume) { /* the problem and overrides are the file's; --max-steps counts every step */
    if (max_steps) rargv[ra++] = "--max-steps", rargv[ra++] = steps;
    if (from >= 0) rargv[ra++] = "--from-snapshot", rargv[ra++] = snap;
    rargv[ra] = NULL;
    dprintf(fd, "vesica study: continuing the %s cell from %s (vesica run --restart)\n",
            timed_out ? "timed-out" : "interrupted", h5);
    snprintf(note, notelen, "continues from its last snapshot (vesica run --restart)");
  } else if (ves_study_cell_argv(s, k, o->program, o->dir, &argc, &argv, msg, sizeof msg) !=
             VES_OK) {
    ves_error_say(err, errlen, "%s%s", "cell command: ", msg);
    close(fd);
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
    execv(o->program, resume ? rargv : argv);
    dprintf(2, "vesica study: cannot execute %s: %s\n", o->program, strerror(errno));
    _exit(127);
  }
  close(fd), free(argv);
  sl->pid = pid, sl->cell = k, sl->start = ves_wall_seconds(), sl->term_at = 0, sl->timed_out = 0;
  sl->resuming = resume;
  return 0;
}

/* Whether a restart that ended with exit code `code` could not continue
 * the file (exit 2: refused; exit 3 with the restart's own message last in
 * the log: a salvage that failed), as opposed to a run that went on and
 * then failed or stopped. */
static int restart_refused(int code, const char *log) {
  if (code == 2) return 1;
  if (code != 3) return 0;
  char last[1024] = "", line[1024];
  FILE *f = fopen(log, "r");
  while (f && fgets(line, sizeof line, f))
    if (!strncmp(line, "vesica", 6)) snprintf(last, sizeof last, "%s", line);
  if (f) fclose(f);
  return !strncmp(last, "vesica run: --restart ", 22) && !strstr(last, "cannot write");
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
                       int threads, long npending, double *spent, ves_study_progress *p,
                       ves_status *st, char *err, size_t errlen) {
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
    const long k = c->cell;
    c->pid = 0;
    char log[PATH_MAX], h5[PATH_MAX];
    ves_study_cell_path(s, k, o->dir, ".log", log, sizeof log);
    if (c->resuming && !stopping && !c->timed_out && w > 0 && WIFEXITED(status) &&
        restart_refused(WEXITSTATUS(status), log)) { /* the file cannot be continued */
      ves_study_cell_path(s, k, o->dir, ".h5", h5, sizeof h5);
      const int fd = open(log, O_WRONLY | O_APPEND);
      char note[PATH_MAX * 2 + 256] = "";
      move_aside(h5, fd, "the restart refused it: see its log", note, sizeof note);
      if (fd >= 0) close(fd);
      p->cell = k, p->note = note;
      if (o->progress) o->progress(o->ctx, p);
      p->cell = -1, p->note = NULL;
      if (start_cell(s, o, k, threads, c, -1, note, sizeof note, err, errlen) == 0) continue;
      if (*st == VES_OK) *st = VES_ERR_IO;
    }
    p->running--;
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

/* Cell k recorded without a process when its problem fails the setup's
 * geometric checks (ves_study_cell_check: what vesica check refuses): its
 * .result bad_input with check's message, a progress report. 1 when so
 * (*st VES_ERR_IO, the message in err, when the .result cannot be written),
 * 0 when the cell is to run. */
static int refuse_cell(const ves_study *s, const ves_study_run_opts *o, long k,
                       ves_study_progress *p, char *err, size_t errlen, ves_status *st) {
  ves_study_result r;
  memset(&r, 0, sizeof r);
  if (ves_study_cell_check(s, k, r.reason, sizeof r.reason) != VES_ERR_CONFIG) return 0;
  char path[PATH_MAX];
  snprintf(r.outcome, sizeof r.outcome, "bad_input");
  r.exit_code = 2;
  ves_study_cell_signature(s, k, r.signature, sizeof r.signature);
  const char *old[] = {".h5", ".xdmf", "_last.xmf", ".log"};
  for (int i = 0; i < 4; i++) {
    ves_study_cell_path(s, k, o->dir, old[i], path, sizeof path);
    remove(path);
  }
  ves_study_cell_path(s, k, o->dir, ".result", path, sizeof path);
  if (ves_study_result_write(path, &r) != VES_OK) {
    ves_error_say(err, errlen, "%s: cannot write: %s", path, strerror(errno));
    *st = VES_ERR_IO;
  }
  p->done++, p->failed++;
  p->cell = k, p->result = &r;
  if (o->progress) o->progress(o->ctx, p);
  p->cell = -1, p->result = NULL;
  return 1;
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
        if (refuse_cell(s, o, pending[next], &p, err, errlen, &st)) { /* bad input: not run */
          next++, j--;
          continue;
        }
        char note[PATH_MAX * 2 + 256] = "";
        if (start_cell(s, o, pending[next], threads, &sl[j], 1, note, sizeof note, err, errlen)) {
          st = VES_ERR_IO;
          stopping = 1;
          for (int i = 0; i < o->jobs; i++)
            if (sl[i].pid) kill(sl[i].pid, SIGTERM), sl[i].term_at = ves_wall_seconds();
          break;
        }
        if (note[0] && o->progress) { /* continued, or its file moved aside */
          p.cell = pending[next], p.note = note;
          o->progress(o->ctx, &p);
          p.cell = -1, p.note = NULL;
        }
        next++, p.running++;
      }
    if (p.running == 0) break;
    nanosleep(&nap, NULL);
    reap_cells(s, o, sl, stopping, threads, npending, &spent, &p, &st, err, errlen);
  }
  free(pending), free(sl);
  if (st == VES_OK && stopping) st = VES_STEP_REJECTED;
  return st;
}
