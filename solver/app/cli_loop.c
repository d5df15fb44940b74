/* vesica — the time loop of vesica run, new or restarted: steps, the file's
 * rows and snapshots, the --series text, progress, signals, the end
 * (docs/design.md, "The time loop" and "The program"). */

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "app/cli_impl.h"

/* Set by SIGINT/SIGTERM: stop after the current step (which can take
 * minutes: up to max_iter iterations and its halvings). The handler then
 * restores the default action, so a second signal ends the run at once;
 * the file keeps every step written before it (flushed per step). */
static volatile sig_atomic_t stop_signal = 0;
static void on_signal(int sig) {
  static const char msg[] = "\nvesica run: stopping after the current step (signal again to "
                            "stop at once)\n";
  stop_signal = sig;
  signal(sig, SIG_DFL);
  ssize_t w = write(2, msg, sizeof msg - 1);
  (void)w;
}

/* The progress line's time to the end of the run: the steps left times the
 * mean wall time of the recent steps. With constant steps (or adaptive ones
 * at dt_max) the steps left are (t_end - t) / dt. With adaptive steps below
 * dt_max they follow the relative step r = dt/t: a step size that grows with
 * t (as the energy's relaxation lets it) makes steps of constant r, a
 * constant number per e-fold of t, up to dt_max and then steps of dt_max.
 * Two values of r bound the estimate: the next step's (dt_next / t) and the
 * recent window's ((t / t_back)^(1/k) - 1 over its k steps); the range lies
 * within the steps at dt_max and at dt_next, and --max-steps caps both. */
static double steps_left(double left, double dt) {
  double n = ceil(left / dt - 1e-9); /* a step that ends at t_end up to rounding is the last */
  return n > 0 ? n : 0.0;            /* not -0 */
}

/* Steps from t to t_end of relative size r (dt = r t) up to dt_max, then of
 * dt_max. */
static double steps_relative(double t, double t_end, double r, double dt_max) {
  double n = 0, tc = dt_max / r; /* the time at which r t reaches dt_max */
  if (tc > t) {
    const double te = fmin(tc, t_end);
    n += log(te / t) / log1p(r), t = te;
  }
  if (t < t_end) n += (t_end - t) / dt_max;
  return n > 1e-9 ? ceil(n - 1e-9) : 0.0;
}

void cli_eta_steps(const ves_config *c, long max_steps, long nstep, double t, double dt_next,
                   double t_back, int k, double *nlo, double *nhi) {
  const double left = c->t_end - t;
  double lo, hi;
  if (left <= 0) {
    lo = hi = 0;
  } else if (!c->adaptive || dt_next >= c->dt_max || !(t > 0)) { /* steps of dt_next */
    lo = hi = steps_left(left, dt_next);
  } else {
    const double r1 = dt_next / t, r2 = k > 0 && t_back > 0 ? pow(t / t_back, 1.0 / k) - 1 : r1;
    const double lin_lo = steps_left(left, c->dt_max), lin_hi = steps_left(left, dt_next);
    lo = steps_relative(t, c->t_end, fmax(r1, r2), c->dt_max);
    hi = r2 > 0 ? steps_relative(t, c->t_end, fmin(r1, r2), c->dt_max) : lin_hi;
    lo = fmin(fmax(lo, lin_lo), lin_hi), hi = fmin(fmax(hi, lo), lin_hi);
  }
  if (max_steps > 0) { /* --max-steps stops the run first when it comes first */
    const double m = max_steps > nstep ? (double)(max_steps - nstep) : 0.0;
    lo = fmin(lo, m), hi = fmin(hi, m);
  }
  *nlo = lo, *nhi = hi;
}

/* A duration v (seconds) in the unit u (60: minutes, 3600: hours): one
 * decimal below 10 units, whole ones above. */
static void duration(char *buf, size_t len, double v, double u) {
  const double x = v / u;
  snprintf(buf, len, x < 9.95 ? "%.1f" : "%.0f", x);
}

void cli_eta_text(char *buf, size_t len, double lo, double hi) {
  const double u = hi < 120 ? 1 : hi < 7200 ? 60 : 3600;
  const char *unit = u == 1 ? "s" : u == 60 ? "min" : "h";
  char a[32], b[32];
  if (u == 1) /* seconds: whole ones */
    snprintf(a, sizeof a, "%.0f", lo), snprintf(b, sizeof b, "%.0f", hi);
  else
    duration(a, sizeof a, lo, u), duration(b, sizeof b, hi, u);
  if (!strcmp(a, b))
    snprintf(buf, len, "%s %s", b, unit);
  else
    snprintf(buf, len, "%s-%s %s", a, b, unit);
}

/* Why a write to the output failed: the cause the io module recorded (no
 * space, the file-size limit, the failing write's errno), else the status. */
const char *cli_io_cause(const ves_io *io, ves_status st) {
  return ves_io_error(io) ? ves_io_error(io) : cli_why(st);
}

/* What the loop carries from step to step. */
typedef struct {
  double t0;           /* wall clock at the start of this process's loop */
  double recent[10];   /* wall times at the ends of the last 10 steps (ring) */
  double recent_t[10]; /* t* at the ends of the last 10 steps (ring) */
  double t_start;      /* t* at the start of this process's loop */
  double t_first;      /* t* after its first step */
  double t_back;       /* t* at the start of the ETA's window of steps */
  int k_back;          /* the window's steps (0: none) */
  int tty;             /* stderr is a terminal: the progress line is redrawn */
  long iters, steps;   /* backend iterations and steps of this process */
} loop_ctx;

/* Install the handlers of SIGINT and SIGTERM (stop after the current step;
 * a second signal kills). */
static void catch_signals(void) {
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sa.sa_flags = SA_RESETHAND; /* a second signal kills */
  sigaction(SIGINT, &sa, NULL);
  sigaction(SIGTERM, &sa, NULL);
}

/* Room for the next step's writes and a last snapshot after them: a run on
 * a filling disk stops here, between complete writes (io.h); resets: a step
 * may also write a reference. */
static ves_status room_for_step(run_ctx *r, long nstep, int resets) {
  const int due = (nstep + 1) % r->cfg.snapshot_every == 0;
  const int nq = ves_model_quad(ves_sim_model(r->sim))->nq;
  return ves_io_room(r->io, 1 + due, resets ? nq : 0); /* a remeshing is smaller */
}

/* The --series text could not be written: the warning, at once and even
 * with --quiet (the run goes on for hours, perhaps); finish repeats it. */
static void series_warn(const run_ctx *r, const char *pre) {
  char at[64] = "its end";
  if (r->series_step >= 0) snprintf(at, sizeof at, "step %ld", r->series_step);
  fprintf(stderr,
          "%svesica run: %s--series %s: cannot write %s: %s; the text ends before it, the run "
          "goes on (%s holds every row: vesica info %s --series 0) and exits 3\n",
          isatty(2) && !r->quiet ? "\n" : "", pre, r->series_path, at, strerror(r->series_errno),
          r->out, r->out);
}

/* The --series text could not be written (errno e, at step `step`, -1: at
 * its end): it is cut back to its last whole line and closed, and the run
 * goes on to end with exit 3 (finish). The run is not stopped: that would
 * gain nothing (a restart does not continue the text, and FILE.h5 holds
 * every row of it: vesica info FILE.h5 --series 0), and hours of steps are
 * not lost over a view of them; exit 3 still tells a script that an output
 * is incomplete. A full disk that stops FILE.h5 too stops the run by its
 * own room check, with the state saved. */
static void series_failed(run_ctx *r, long step, int e) {
  r->series_errno = e ? e : EIO, r->series_step = step;
  const int cut = ftruncate(fileno(r->series), r->series_good) == 0; /* no partial line */
  (void)cut; /* not cut (a file system that refuses): the partial line is the last */
  fclose(r->series);
  r->series = NULL;
  series_warn(r, "warning: ");
}

/* The accepted step's line of the --series text, flushed with it. */
static void series_row(run_ctx *r, const ves_io_row *row) {
  errno = 0;
  if (ves_io_text_row(r->series, row) != VES_OK || fflush(r->series) != 0) {
    series_failed(r, row->step, errno);
    return;
  }
  r->series_good = ftell(r->series);
}

/* The --series text closed at the end of the loop: its close can fail too
 * (a network file system reports a failed write there). */
static void series_close(run_ctx *r) {
  if (!r->series) return;
  errno = 0;
  if (fflush(r->series) != 0 || ferror(r->series)) {
    series_failed(r, -1, errno);
    return;
  }
  errno = 0;
  const int bad = fclose(r->series) != 0, e = errno;
  r->series = NULL;
  if (bad) {
    r->series_errno = e ? e : EIO, r->series_step = -1;
    series_warn(r, "warning: ");
  }
}

/* The accepted step rep into the file (row, a reset's reference, a
 * remeshing, a due snapshot) and the --series text. */
static ves_status record_step(run_ctx *r, const ves_step_report *rep, double wall) {
  ves_io_row row;
  ves_io_row_from_step(rep, ves_sim_reconnections(r->sim), wall, &row);
  VES_CALL(ves_io_append(r->io, &row));
  if (rep->reconnected) VES_CALL(cli_write_reference(r, rep->step));
  if (rep->remeshed) VES_CALL(cli_write_remesh(r, rep->step, &rep->remesh));
  if (rep->step % r->cfg.snapshot_every == 0) VES_CALL(cli_snapshot(r, wall));
  if (r->series) series_row(r, &row);
  return VES_OK;
}

/* The lines of an accepted step on stderr: progress (with w the mean wall
 * time of the recent steps), retries, a reset, a remeshing, and the
 * warnings of a reset or remeshing that failed (even with --quiet). */
static void report_step(const run_ctx *r, const ves_step_report *rep, const loop_ctx *L, double w) {
  const int tty = L->tty;
  if (!r->quiet && (tty || rep->step % 10 == 0)) {
    char eta[64];
    ves_sim_state now; /* the next step's dt */
    ves_sim_get_state(r->sim, &now, NULL);
    double nlo, nhi;
    cli_eta_steps(&r->cfg, r->max_steps, rep->step, rep->t, now.dt, L->t_back, L->k_back, &nlo,
                  &nhi);
    cli_eta_text(eta, sizeof eta, w * nlo, w * nhi);
    fprintf(stderr, "%sstep %ld  t* %.4g/%.4g  dt* %.3g  E* %.6f  iter %d  ETA %s%s",
            tty ? "\r" : "", rep->step, rep->t, r->cfg.t_end, rep->dt, rep->E,
            rep->stats.iterations, eta, tty ? "   " : "\n");
  }
  if (rep->retries && !r->quiet) { /* why the last attempt failed, and what they all cost */
    const char *key =
        rep->reject_status == VES_MAXITER ? ves_backend_limit_key(rep->rejected.limit) : "";
    fprintf(stderr,
            "%sstep %ld: %d attempt(s) rejected from dt* %.3g (last: %s%s%s%s; in all %d "
            "iterations, %d Hessians, %d factorizations, %.1f s), accepted at dt* %.3g\n",
            tty ? "\n" : "", rep->step, rep->retries, rep->reject_dt,
            ves_status_str(rep->reject_status), *key ? " (" : "", key, *key ? ")" : "",
            rep->rejected.iterations, rep->rejected.h_evals, rep->rejected.factorizations,
            rep->rejected.seconds, rep->dt);
  }
  if (rep->reconnected && !r->quiet)
    fprintf(stderr,
            "%sstep %ld: reference reset #%d (max cond F %.3g, min det F %.3g, max "
            "|y^a - y(X_a)|/h_a %.3g, %d node(s) mirrored across the axis, E* %.9g -> %.9g)\n",
            tty ? "\n" : "", rep->step, ves_sim_reconnections(r->sim), rep->cond, rep->det_min,
            rep->shift, rep->mirrored, rep->E, rep->E_reset);
  if (rep->remeshed && !r->quiet) {
    const ves_remesh_info *m = &rep->remesh;
    char thin[200] = "";
    if (m->proj_cells_refined)
      snprintf(thin, sizeof thin,
               "; %d old cell(s) spread thin refined for the projection, %d of them still thin, "
               "%d of their points outside the domain left out",
               m->proj_cells_refined, m->proj_cells_capped, m->proj_points_dropped);
    fprintf(stderr,
            "%sstep %ld: remeshing #%d (%d -> %d nodes; before the correction dE* %.3g, "
            "dA/A %.3g, dV/V %.3g; correction max |delta|/h %.3g, |delta| %.3g in %d "
            "iteration(s), then |A/A0 - 1| %.2g, |V/Vt - 1| %.2g; interface moved max %.3g, "
            "mean %.3g; E* %.9g -> %.9g; %.1f s%s%s)\n",
            tty ? "\n" : "", rep->step, ves_sim_remeshings(r->sim), m->n_old, m->n_new, m->dE,
            m->dA, m->dV, m->corr_max, m->corr_norm, m->corr_iter, m->res_A, m->res_V, m->disp_max,
            m->disp_mean, m->E_old, m->E, m->seconds,
            m->band_layers ? "" : "; the band without layers", thin);
  }
  if (rep->remesh_status != VES_OK) /* a warning even with --quiet: a remeshing was skipped */
    fprintf(stderr,
            "%svesica run: warning: step %ld: the remeshing that was due failed (%s); "
            "continuing on the old nodes; tried again in max(1, every/4) steps ([remesh] every), "
            "after the next one (distortion)\n",
            tty ? "\n" : "", rep->step, ves_status_str(rep->remesh_status));
  if (rep->reconnect_status != VES_OK) /* a warning even with --quiet: a reset was skipped */
    fprintf(stderr,
            "%svesica run: warning: step %ld: the reference reset that was due failed (%s); "
            "continuing on the old reference, retried after the next step\n",
            tty ? "\n" : "", rep->step, ves_status_str(rep->reconnect_status));
}

/* The one line of a run its output stopped (what: a failed write, no room;
 * cause: why): what the file keeps and how to continue. */
static void say_kept(run_ctx *r, const char *what, const char *cause) {
  long step = -1;
  double t = 0;
  int intact = 1;
  const int N = ves_io_kept(r->io, &step, &t, &intact);
  if (N <= 0) {
    fprintf(stderr, "vesica run: %s: %s: %s; no complete snapshot kept\n", r->out, what, cause);
    return;
  }
  fprintf(stderr,
          "vesica run: %s: %s: %s; kept %d complete snapshot%s up to step %ld, t* %.6g%s; "
          "continue with vesica run --restart %s\n",
          r->out, what, cause, N, N == 1 ? "" : "s", step, t,
          intact ? "" : " (a write failed half-way: the restart salvages them)", r->out);
}

/* The end of the loop: why it stopped (a write wst, the disk room, the step
 * st, a signal, --max-steps or t_end), the last snapshot and the file's
 * status. Returns the exit code. */
static int finish(run_ctx *r, const loop_ctx *L, ves_status st, ves_status wst, ves_status room) {
  const double tend = r->cfg.t_end, wall = r->wall_offset + ves_wall_seconds() - L->t0;
  ves_sim_state fin;
  ves_sim_get_state(r->sim, &fin, NULL);
  const char *status = "finished";
  int code = 0;
  series_close(r);
  char cause[2 * PATH_MAX], what[128];
  if (wst != VES_OK || room != VES_OK) { /* the output stopped the run */
    snprintf(cause, sizeof cause, "%s", cli_io_cause(r->io, wst != VES_OK ? wst : room));
    if (wst != VES_OK) /* a write failed: nothing more but the status (in place) */
      snprintf(what, sizeof what, "cannot write");
    else { /* no room for the next step: its state saved as the last snapshot */
      snprintf(what, sizeof what, "stopped at step %ld, t* = %.6g", fin.nstep, fin.t);
      if (fin.nstep != r->last_snapshot_step) cli_snapshot(r, wall);
    }
    ves_io_set_status(r->io, "failed"); /* refused after a write failed half-way */
    say_kept(r, what, cause);
    return 3;
  }
  if (st < 0) {
    fprintf(stderr,
            "vesica run: %s: no acceptable step at t* = %.6g down to dt* = %g (%s); the last "
            "good state (step %ld) is the last snapshot of %s\n",
            r->label, fin.t, r->cfg.dt_min, cli_why(st), fin.nstep, r->out);
    status = "failed", code = 3;
  } else if (stop_signal) {
    status = "stopped", code = 128 + (int)stop_signal;
  } else if (st != VES_DONE && fin.t < tend - 1e-12 * (1 + fabs(tend))) {
    status = "stopped"; /* --max-steps */
  }
  if (fin.nstep != r->last_snapshot_step && (wst = cli_snapshot(r, wall)) != VES_OK) {
    snprintf(cause, sizeof cause, "%s", cli_io_cause(r->io, wst));
    ves_io_set_status(r->io, "failed");
    say_kept(r, "cannot write the last snapshot", cause);
    return 3;
  }
  if ((wst = ves_io_set_status(r->io, status)) != VES_OK) {
    fprintf(stderr, "vesica run: %s: cannot write: %s\n", r->out, cli_io_cause(r->io, wst));
    return 3;
  }
  /* the closing line: how the run ended, where, and what it cost (a signal's
   * even with --quiet: it says how to continue) */
  char how[64];
  if (stop_signal)
    snprintf(how, sizeof how, "interrupted by signal %d", (int)stop_signal);
  else
    snprintf(how, sizeof how, "%s",
             !strcmp(status, "finished") ? "finished (t_end reached)" : "stopped at --max-steps");
  if (strcmp(status, "failed") && (stop_signal || !r->quiet))
    fprintf(stderr,
            "vesica run: %s at step %ld, t* = %.6g, E* = %.9g: %ld steps, %ld iterations, "
            "%.1f s; %s %s\n",
            how, fin.nstep, fin.t, fin.E / r->cfg.k, L->steps, L->iters, ves_wall_seconds() - L->t0,
            stop_signal ? "continue with vesica run --restart" : "wrote", r->out);
  if (r->series_errno) { /* the run is whole, an output is not */
    series_warn(r, "");
    if (!code) code = 3;
  }
  return code;
}

int cli_loop(run_ctx *r) {
  loop_ctx L = {.t0 = ves_wall_seconds(), .tty = isatty(2)};
  ves_sim_state start;
  ves_sim_get_state(r->sim, &start, NULL);
  L.t_start = start.t;
  ves_problem_params p; /* whether a step may write a reference (resets, remeshings) */
  ves_problem_params_from_config(&r->cfg, &p);
  ves_step_report rep;
  ves_status st = VES_OK, wst = VES_OK, room = VES_OK;
  catch_signals();
  for (;;) {
    ves_sim_state now;
    ves_sim_get_state(r->sim, &now, NULL);
    if (r->max_steps > 0 && now.nstep >= r->max_steps) break;
    if (stop_signal) break;
    if ((room = room_for_step(r, now.nstep, p.resets)) != VES_OK) break;
    ves_error_clear(); /* the record of this step's failure alone */
    if ((st = ves_sim_step(r->sim, &rep)) != VES_OK) break;
    L.steps++;
    L.iters += rep.stats.iterations;
    const double wall = r->wall_offset + ves_wall_seconds() - L.t0;
    if ((wst = record_step(r, &rep, wall)) != VES_OK) break;
    const double el = ves_wall_seconds() - L.t0;     /* this process's loop */
    const int nr = L.steps < 10 ? (int)L.steps : 10; /* steps in the window */
    const double w = (el - (L.steps > 10 ? L.recent[L.steps % 10] : 0.0)) / nr;
    /* the ETA's window in t*: the last 10 steps, or this process's steps
     * so far (from its first step's end when it started at t = 0) */
    if (L.steps == 1) L.t_first = rep.t;
    if (L.steps > 10)
      L.t_back = L.recent_t[L.steps % 10], L.k_back = 10;
    else if (L.t_start > 0)
      L.t_back = L.t_start, L.k_back = (int)L.steps;
    else
      L.t_back = L.t_first, L.k_back = (int)L.steps - 1;
    L.recent[L.steps % 10] = el, L.recent_t[L.steps % 10] = rep.t;
    report_step(r, &rep, &L, w);
  }
  if (L.tty && !r->quiet && L.steps) fputc('\n', stderr);
  signal(SIGINT, SIG_DFL);
  signal(SIGTERM, SIG_DFL);
  return finish(r, &L, st, wst, room);
}
