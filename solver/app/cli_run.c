/* vesica run: the command, and a new run: its outputs checked, the setup
 * built, the file's header written, then the time loop of cli_loop.c
 * (docs/manual.md; docs/design.md, "The program"). */

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <unistd.h>

#include "app/cli_impl.h"
#include "ves/quad.h"

static void usage_run(FILE *f) {
  fprintf(f,
          "usage: vesica run CONFIG.ini [--backend ipopt|nlopt|newton|euler] [--out FILE.h5]\n"
          "                 [--set section.key=value]... [--max-steps N] [--series FILE.tsv]\n"
          "                 [--quiet] [--force]\n"
          "       vesica run --restart FILE.h5 [--from-snapshot K] [--set KEY=VALUE]...\n"
          "                 [--max-steps N] [--quiet]\n"
          "Builds the initial state as 'check' does and integrates to [time] t_end with the\n"
          "chosen backend (default [solver] backend).\n"
          "  --out FILE.h5     the run's HDF5 file (default: the problem file's name with .h5,\n"
          "                    in the current folder), with FILE.xdmf beside it for ParaView:\n"
          "                    parameters, one row per accepted step (flushed at every step),\n"
          "                    snapshots every [output] snapshot_every steps and at the end\n"
          "  --restart FILE.h5 continue the run of FILE.h5 from its last snapshot, appending to\n"
          "                    it; the trajectory is bit for bit the uninterrupted one;\n");
  cli_restart_keys_print(f, fprintf(f, "                    --set may change "), 20, 86,
                         "(recorded in the file)\n");
  fprintf(f,
          "  --from-snapshot K with --restart: continue from snapshot K (the snapshots after it\n"
          "                    are dropped), the way past a corrupt last snapshot\n"
          "  --max-steps N     stop (with a snapshot, exit 0) once N steps are accepted in all\n"
          "  --series FILE.tsv also the series as tab-separated text: one header line of the\n"
          "                    column names, the row of the initial state (t = 0), then one\n"
          "                    line per accepted step; the columns of vesica info --series,\n"
          "                    described in docs/manual.md, \"The series\"; a write that fails\n"
          "                    (a full disk) ends the text, not the run, which then exits 3\n"
          "                    (vesica info FILE.h5 --series 0: every row)\n"
          "  --force           overwrite an existing FILE.h5, FILE.xdmf, FILE_last.xmf or --series "
          "file\n"
          "                    (without it they are refused, exit 2; the problem file, its\n"
          "                    points file and the files of a running vesica never are)\n"
          "  --quiet           no progress line and no closing line (otherwise on stderr:\n"
          "                    step, t*, dt*, E*, iterations, ETA (a range lo-hi while adaptive\n"
          "                    steps are below dt_max: the steps left at the next step's and\n"
          "                    the recent steps' dt/t; --max-steps counted), updated in place\n"
          "                    on a terminal; at the end how the run ended (finished, stopped\n"
          "                    at --max-steps, interrupted), its step, t*, E*, steps and time)\n"
          "Exit 0 at t_end (or --max-steps), 2 on bad input (nothing written), 3 when a step\n"
          "fails down to dt_min (the last good state is saved as the last snapshot) or an\n"
          "output cannot be written, 130/143 on SIGINT/SIGTERM after the current step (state\n"
          "saved; a second signal kills).\n");
}

/* Remove the output of a run that failed before its first step. */
static void remove_output(const char *out) {
  char x[PATH_MAX], last[PATH_MAX + 16];
  ves_io_xdmf_path(out, x, sizeof x);
  ves_io_xdmf_last_path(out, last, sizeof last);
  remove(out);
  remove(x);
  remove(last);
}

/* The outputs of a new run from the problem file path: r->out (out, or the
 * problem's name with .h5 here), its XDMF file (and the temporary it is
 * written to), the --series file, each through the guard of
 * cli_check_output: writable, none an input (the problem file, its points
 * file), none a file a running vesica holds, none existing unless force.
 * Checked before the setup and again after it, just before the files are
 * created (the setup can take minutes). 0 or 2. */
static int check_outputs(run_ctx *r, const char *path, const char *out, const char *series,
                         int force) {
  int rc;
  if (out) {
    snprintf(r->out, sizeof r->out, "%s", out);
  } else { /* the problem file's name, .h5, here */
    const char *base = strrchr(path, '/') ? strrchr(path, '/') + 1 : path;
    size_t l = strlen(base);
    if (l > 4 && !strcmp(base + l - 4, ".ini")) l -= 4;
    snprintf(r->out, sizeof r->out, "%.*s.h5", (int)l, base);
  }
  char xdmf[PATH_MAX], xtmp[PATH_MAX + 8], last[PATH_MAX + 16],
      points[PATH_MAX + 600] = "", hint[PATH_MAX + 64], why[128];
  if (!ves_io_xdmf_name_ok(r->out, why, sizeof why)) { /* the .xdmf could not name it */
    fprintf(stderr,
            "vesica run: --out %s: %s, so the XDMF file beside it could not refer to it: "
            "choose another name\n",
            r->out, why);
    return 2;
  }
  ves_io_xdmf_path(r->out, xdmf, sizeof xdmf);
  snprintf(xtmp, sizeof xtmp, "%s.tmp", xdmf); /* io_xdmf.c writes it, then renames it */
  ves_io_xdmf_last_path(r->out, last, sizeof last);
  if (r->cfg.points[0]) { /* a curve's points file, found as ves_config_read_points does */
    const char *sl = r->cfg.points[0] == '/' ? NULL : strrchr(path, '/');
    snprintf(points, sizeof points, "%.*s%s%s", sl ? (int)(sl - path) : 0, path, sl ? "/" : "",
             r->cfg.points);
  }
  const char *inputs[] = {path, points[0] ? points : NULL};
  snprintf(hint, sizeof hint, ", or vesica run --restart %s continues it", r->out);
  if ((rc = cli_check_output("run", "--out", r->out, force, inputs, 2, hint)) ||
      (rc = cli_check_output("run", "--out", xdmf, force, inputs, 2, NULL)) ||
      (rc = cli_check_output("run", "--out", xtmp, 1, inputs, 2, NULL)) ||
      (rc = cli_check_output("run", "--out", last, force, inputs, 2, NULL)) ||
      (series && (rc = cli_check_output("run", "--series", series, force, inputs, 2, NULL))))
    return rc;
  if (series && (cli_same_file(series, r->out) || !strcmp(series, r->out) ||
                 !strcmp(series, xdmf) || !strcmp(series, xtmp) || !strcmp(series, last))) {
    fprintf(stderr, "vesica run: --series %s: is the run's output file\n", series);
    return 2;
  }
  return 0;
}

/* The new file r->out of the built run (problem file path): header, mesh,
 * the first snapshot. 0, or the exit code (nothing left behind). */
static int create_output(run_ctx *r, const char *path) {
  char abs[PATH_MAX], *problem = NULL, err[1024] = "";
  if (!realpath(path, abs)) snprintf(abs, sizeof abs, "%s", path);
  double E0, A0, V0;
  ves_sim_initial(r->sim, &E0, &A0, &V0);
  int ncell = 0, *cells = NULL; /* the Delaunay triangles (a rich rule repeats them) */
  if (ves_config_to_text(&r->cfg, &problem) != VES_OK ||
      ves_quad_cells(r->setup->quad, &ncell, &cells) != VES_OK) {
    free(problem);
    fprintf(stderr, "vesica run: out of memory\n");
    return 3;
  }
  ves_io_header h = {.version = VES_VERSION,
                     .backend = r->bk->name,
                     .problem = problem,
                     .source = abs,
                     .cfg = &r->cfg,
                     .n = r->setup->nodes->n,
                     .X = r->setup->nodes->x,
                     .ntri = ncell,
                     .tri = cells,
                     .E0 = E0,
                     .A0 = A0,
                     .V0 = V0,
                     .setup_seconds = r->setup->seconds_total};
  ves_status st = ves_io_create(r->out, &h, &r->io, err, sizeof err);
  free(problem), free(cells);
  if (st != VES_OK) { /* not created: nothing of ours to remove */
    fprintf(stderr, "vesica run: %s%s\n", err, st == VES_ERR_ARG ? "" : "; nothing kept");
    return st == VES_ERR_ARG ? 2 : 3; /* refused, or a write that failed */
  }
  if ((st = cli_snapshot(r, 0.0)) != VES_OK) { /* nothing half-written stays behind */
    fprintf(stderr, "vesica run: %s: cannot write the first snapshot: %s; nothing kept\n", r->out,
            cli_io_cause(r->io, st));
    ves_io_close(&r->io);
    remove_output(r->out);
    return 3;
  }
  return 0;
}

/* The --series text's first row: the initial state at t = 0 (step 0; E, A,
 * V, V_target = V0, the multipliers and C0 the integrator starts from; the
 * counts, times and dt of a step 0). */
static void initial_row(const run_ctx *r, ves_io_row *row) {
  ves_sim_state s;
  ves_sim_get_state(r->sim, &s, NULL);
  *row = (ves_io_row){.step = s.nstep,
                      .t = s.t,
                      .E = s.E / r->cfg.k, /* E*, as the rows after it */
                      .A = s.A,
                      .V = s.V,
                      .V_target = s.V0,
                      .lambda_A = s.lambda[0],
                      .lambda_V = s.lambda[1],
                      .c0 = s.c0,
                      .reconnections = ves_sim_reconnections(r->sim)};
}

/* The --series file: opened without truncating, locked (held until the
 * run closes it: no other vesica writes it meanwhile, cli_check_output),
 * then emptied, and its header line (the column names) and the row of the
 * initial state written and flushed. A file another vesica locked in the
 * moment since the check is refused (2; on a file system without locks it
 * is written unlocked); a header that cannot be written (a full disk) ends
 * the run before its first step (3): nothing is lost, and the files
 * created are removed. 0 or the exit code. */
static int open_series(run_ctx *r, const char *series) {
  int rc = 0, fd = open(series, O_WRONLY | O_CREAT | O_CLOEXEC, 0666);
  r->series_path = series;
  if (fd < 0) {
    fprintf(stderr, "vesica run: --series %s: cannot open for writing: %s\n", series,
            strerror(errno));
    rc = 2;
  } else if (flock(fd, LOCK_EX | LOCK_NB) != 0 && errno == EWOULDBLOCK) {
    fprintf(stderr,
            "vesica run: --series %s: in use by a running vesica (it holds a lock on the "
            "file): never overwritten, even with --force\n",
            series);
    close(fd);
    rc = 2;
  } else if (ftruncate(fd, 0) != 0 || !(r->series = fdopen(fd, "w"))) {
    fprintf(stderr, "vesica run: --series %s: cannot write: %s\n", series, strerror(errno));
    close(fd);
    remove(series);
    rc = 3;
  }
  if (rc) {
    ves_io_close(&r->io);
    remove_output(r->out);
    return rc;
  }
  ves_io_row row0;
  initial_row(r, &row0);
  errno = 0;
  int bad = ves_io_text_header(r->series) != VES_OK;
  bad |= ves_io_text_row(r->series, &row0) != VES_OK;
  bad |= fflush(r->series) != 0;
  if (bad) {
    const int e = errno ? errno : EIO;
    fprintf(stderr, "vesica run: --series %s: cannot write: %s; nothing run, nothing kept\n",
            series, strerror(e));
    fclose(r->series);
    r->series = NULL;
    remove(series);
    ves_io_close(&r->io);
    remove_output(r->out);
    return 3;
  }
  r->series_good = ftell(r->series);
  return 0;
}

/* A new run: CONFIG.ini [options]. */
static int run_new(run_ctx *r, const char *path, const char *out, const char *backend, int nset,
                   const char *const *set, const char *series, int force) {
  int rc = cli_load_problem("run", path, usage_run, nset, set, &r->cfg);
  if (rc) return rc;
  r->label = path;
  if (backend) { /* applied as --set solver.backend is: the stored problem records it */
    char kv[96], err[512];
    const char *one[1] = {kv};
    snprintf(kv, sizeof kv, "solver.backend=%s", backend);
    if (ves_config_set(&r->cfg, 1, one, err, sizeof err) != VES_OK) {
      fprintf(stderr, "vesica run: --backend %s: %s\n", backend, err);
      return 2;
    }
  }
  r->bk = ves_backend_find(r->cfg.backend);
  if (!r->bk) {
    fprintf(stderr, "vesica run: --backend '%s': not one of ipopt, nlopt, newton, euler\n",
            backend ? backend : r->cfg.backend);
    return 2;
  }
  if ((rc = check_outputs(r, path, out, series, force)) ||
      (rc = cli_setup_estimate("run", &r->cfg, r->quiet)) || (rc = cli_build(r)) ||
      (rc = check_outputs(r, path, out, series, force)) || (rc = create_output(r, path)) ||
      (series && (rc = open_series(r, series))))
    return rc;
  return cli_loop(r);
}

int cmd_run(int argc, char **argv) {
  const char *path = NULL, *set[MAX_SET] = {0}, *backend = NULL, *series = NULL, *out = NULL;
  const char *restart = NULL;
  int nset = 0, quiet = 0, force = 0, rc, from_snapshot = -1;
  long max_steps = 0;
  for (int i = 0; i < argc; i++) {
    const char *a = argv[i];
    const int has = i + 1 < argc && cli_is_value(argv[i + 1]); /* a value follows */
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      usage_run(stdout);
      return 0;
    } else if (!strcmp(a, "--set")) {
      if ((rc = cli_take_set("run", argc, argv, &i, &nset, set))) return rc;
    } else if (!strcmp(a, "--backend") || !strcmp(a, "--series") || !strcmp(a, "--out") ||
               !strcmp(a, "--restart") || !strcmp(a, "--max-steps") ||
               !strcmp(a, "--from-snapshot")) {
      if (!has) {
        fprintf(stderr, "vesica run: %s needs a value (see vesica run --help)\n", a);
        return 2;
      }
      const char *v = argv[++i];
      if (!strcmp(a, "--backend"))
        backend = v;
      else if (!strcmp(a, "--series"))
        series = v;
      else if (!strcmp(a, "--out"))
        out = v;
      else if (!strcmp(a, "--restart"))
        restart = v;
      else if (!strcmp(a, "--from-snapshot")) {
        char *end;
        errno = 0;
        const long k = strtol(v, &end, 10);
        if (*end || errno || k < 0 || k > INT_MAX) {
          fprintf(stderr, "vesica run: --from-snapshot '%s': not a snapshot number\n", v);
          return 2;
        }
        from_snapshot = (int)k;
      } else {
        char *end;
        errno = 0;
        max_steps = strtol(v, &end, 10);
        if (end == v || *end || errno || max_steps < 1) {
          fprintf(stderr, "vesica run: --max-steps '%s': not a positive integer (1 or more)\n", v);
          return 2;
        }
      }
    } else if (!strcmp(a, "--quiet")) {
      quiet = 1;
    } else if (!strcmp(a, "--force")) {
      force = 1;
    } else if (cli_operand("run", "configuration file", a[0] == '-', a, &path)) {
      return 2;
    }
  }
  if (restart && series) { /* the text of the first part ends where that process stopped */
    fprintf(stderr,
            "vesica run: --series with --restart: a restart does not continue a --series text "
            "(the steps after the last snapshot would repeat in it); vesica info %s --series 0 "
            "prints every row of the run\n",
            restart);
    return 2;
  }
  if (restart && (path || backend || out || series || force)) {
    fprintf(stderr,
            "vesica run: --restart %s continues the stored problem: no CONFIG.ini, "
            "--backend, --out, --series or --force with it\n",
            restart);
    return 2;
  }
  if (from_snapshot >= 0 && !restart) {
    fprintf(stderr, "vesica run: --from-snapshot goes with --restart FILE.h5\n");
    return 2;
  }
  if (backend && !ves_backend_find(backend)) {
    fprintf(stderr, "vesica run: --backend '%s': not one of ipopt, nlopt, newton, euler\n",
            backend);
    return 2;
  }
  run_ctx r;
  memset(&r, 0, sizeof r);
  r.quiet = quiet, r.max_steps = max_steps, r.last_snapshot_step = -1;
  r.from_snapshot = from_snapshot;
  rc = restart ? cli_run_restart(&r, restart, nset, set)
               : run_new(&r, path, out, backend, nset, set, series, force);
  cli_run_free(&r);
  return rc;
}
