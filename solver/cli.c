/* vesica — the command-line program: parses arguments, drives the library,
 * prints and exits (the library itself never prints or exits).
 * Exit codes: 0 ok, 2 bad input (usage, configuration, files), 3 numerical
 * failure (or a write error during a run), 130/143 stopped by SIGINT/SIGTERM
 * (the last state saved). */
#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <time.h>
#include <unistd.h>

#include "ves/backend.h"
#include "ves/config.h"
#include "ves/integrate.h"
#include "ves/io.h"
#include "ves/plot.h"
#include "ves/quad.h"
#include "ves/reconnect.h"
#include "ves/setup.h"
#include "ves/spectrum.h"
#include "ves/study.h"
#include "blas_core_impl.h"
#include "clock_impl.h"

#define VES_VERSION "0.1.0"
#define MAX_SET 64
/* energy_monotone: a rise above this relative rounding counts (the
 * integrator's own acceptance test uses the same margin) */
#define MONOTONE_TOL 1e-10

static void usage(FILE *f) {
  fprintf(f,
          "usage: vesica <command> [options]\n"
          "commands:\n"
          "  run CONFIG.ini [--backend ipopt|nlopt|newton|euler] [--out FILE.h5]\n"
          "                 [--set section.key=value]... [--max-steps N] [--series FILE.tsv]\n"
          "                 [--quiet] [--force]\n"
          "  run --restart FILE.h5 [--set solver.KEY=V|time.t_end=T]... [--max-steps N] [--quiet]\n"
          "                     integrate in time, writing FILE.h5 (+ FILE.xdmf)\n"
          "  check CONFIG.ini [--set section.key=value]... [--phi0 l2|sampled]\n"
          "                     build the initial state and print its derived quantities\n"
          "  info FILE.h5       summary of a run, one 'key = value' per line\n"
          "  plot FILE.h5 [--outdir DIR] [--times T1,T2,...] [--force]\n"
          "                     PNG figures: energy and dt, node snapshots, constraints\n"
          "  spectrum FILE.h5 [--snapshot K] [--above MU] [--modes M] [--lanczos N]\n"
          "           [--vectors F]\n"
          "                     the linearized flow at a stored state: slow and unstable\n"
          "                     modes, forward Euler's stability limit\n"
          "  study STUDY.ini [--jobs N] [--out DIR] [--retry-failed] [--emit slurm]\n"
          "        [--cell K] [--collect]\n"
          "                     a grid of runs (robustness studies, sweeps): one table, figures\n"
          "  keys               print every problem-file key with its default and range\n"
          "  --version          print the version\n"
          "  --help             this text (also: vesica COMMAND --help)\n"
          "  help [COMMAND]     this text, or the command's (as vesica COMMAND --help)\n"
          "exit codes: 0 ok, 2 bad input (nothing written), 3 numerical failure or an output\n"
          "that cannot be written (last good state saved), 130/143 a run stopped by\n"
          "SIGINT/SIGTERM after its current step (state saved; continue with --restart)\n");
}

/* --------------------------------------------------------------------------
 * check */

static void usage_check(FILE *f) {
  fprintf(f, "usage: vesica check CONFIG.ini [--set section.key=value]... [--phi0 l2|sampled]\n"
             "Validates the problem file, builds shape, adapted nodes, quadrature, LME tables and\n"
             "the least-squares phase field (no time stepping), then prints one 'key = value'\n"
             "per line: nodes, ghosts, quadrature_points, neighbours_mean, energy (E/k),\n"
             "energy_sharp, area_ratio (A over the sharp area), volume_ratio, reduced_volume,\n"
             "epsilon, setup_seconds, ...\n"
             "--phi0 sampled uses phi0(X_a) as coefficients (wrong on purpose: for comparison).\n"
             "Exit 0 ok, 2 bad input (the message names file, key and reason), 3 numerical "
             "failure.\n");
}

/* A setup message names the file itself when it comes from reading one (a
 * points file): then do not name the problem file twice. */
static void setup_error(const char *cmd, const char *label, const char *err) {
  if (!strncmp(err, label, strlen(label)) && err[strlen(label)] == ':')
    fprintf(stderr, "vesica %s: %s\n", cmd, err);
  else
    fprintf(stderr, "vesica %s: %s: %s\n", cmd, label, err);
}

/* Exit code for a failed setup: bad input (configuration, arguments, an
 * unreadable points file) 2, anything numerical 3. */
static int exit_for(ves_status st) {
  return st == VES_ERR_CONFIG || st == VES_ERR_ARG || st == VES_ERR_IO ? 2 : 3;
}

/* The node count of a problem's setup, estimated before building it: the
 * band |d| < band eps on both sides of a meridian of length L = pi R (R0 = 1;
 * a sphere: its radius) at the hexagonal density 2 / (sqrt(3) h^2) of
 * h_band eps, the graded zone from there to h_far at `slope` (its integral
 * halved: the zones overlap), and the box at h_far. Calibrated on four
 * measured setups: 19,391 / 2,225 / 1,203 / 331 nodes estimated within 8%. */
static double estimate_nodes(const ves_config *c) {
  const double L = M_PI * (strcmp(c->shape_type, "sphere") ? 1.0 : c->radius);
  const double h0 = c->h_band * c->epsilon, rho = 2 / sqrt(3.0);
  const double band = L * 2 * c->band * c->epsilon * rho / (h0 * h0);
  const double grade = c->h_far > h0 ? L * rho * (1 / h0 - 1 / c->h_far) / c->slope : 0.0;
  return band + grade + 2 * c->box_r * 2 * c->box_z * rho / (c->h_far * c->h_far);
}

/* Rates measured at the paper's scale (19,391 nodes, bench/RESULTS.md, the
 * scale table, one thread): setup 23 s, peak memory of the run 3.0 GB, a
 * Newton step 22 s growing as n^1.23. */
#define EST_NODES 19391.0
#define EST_SETUP_S 23.0
#define EST_PEAK_GB 3.0
#define EST_STEP_S 22.0
#define EST_LARGE 10000 /* nodes from which the estimate is printed */

/* Before a setup: a line with the estimated size and cost when the problem
 * is large (not with quiet); a refusal when its estimated memory exceeds
 * the machine's. 0 ok, else 2 (message printed). */
static int setup_estimate(const char *cmd, const ves_config *c, int quiet) {
  const double n = estimate_nodes(c), x = n / EST_NODES, gb = EST_PEAK_GB * x;
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
  const double have = pages > 0 && page > 0 ? (double)pages * (double)page / 1e9 : 0.0;
  if (have > 0 && gb > have) {
    fprintf(stderr,
            "vesica %s: about %.3g nodes (estimated from epsilon, band, h_band, slope, h_far and "
            "the box) would need about %.3g GB; this machine has %.3g GB: coarsen the problem\n",
            cmd, n, gb, have);
    return 2;
  }
  if (!quiet && n >= EST_LARGE)
    fprintf(stderr,
            "vesica %s: setting up about %.0f nodes (an estimate): ~%.0f s of setup on one thread, "
            "~%.1f GB peak memory in a run, ~%.0f s a Newton step (scaled from %.0f nodes: "
            "bench/RESULTS.md)\n",
            cmd, n, EST_SETUP_S * x, gb, EST_STEP_S * pow(x, 1.23), EST_NODES);
  return 0;
}

/* The tail shared by the commands that take a problem file: a path must have
 * been given; load it with the overrides. 0 on success, else the exit code. */
static int load_problem(const char *cmd, const char *path, void (*usage_fn)(FILE *), int nset,
                        const char *const *set, ves_config *cfg) {
  char err[1024] = "";
  if (!path) {
    usage_fn(stderr);
    return 2;
  }
  if (ves_config_load(path, nset, set, cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica %s: %s\n", cmd, err);
    return 2;
  }
  return 0;
}

/* A --set argument: 0 when taken, else the exit code (message printed). */
static int take_set(const char *cmd, int argc, char **argv, int *i, int *nset, const char **set) {
  if (*i + 1 >= argc || argv[*i + 1][0] == '-') {
    fprintf(stderr, "vesica %s: --set needs section.key=value\n", cmd);
    return 2;
  }
  if (*nset == MAX_SET) {
    fprintf(stderr, "vesica %s: more than %d --set options\n", cmd, MAX_SET);
    return 2;
  }
  set[(*nset)++] = argv[++*i];
  return 0;
}

static int cmd_check(int argc, char **argv) {
  const char *path = NULL, *set[MAX_SET] = {0};
  int nset = 0, rc;
  ves_phi0_method method = VES_PHI0_L2;
  for (int i = 0; i < argc; i++) {
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      usage_check(stdout);
      return 0;
    } else if (!strcmp(argv[i], "--set")) {
      if ((rc = take_set("check", argc, argv, &i, &nset, set))) return rc;
    } else if (!strcmp(argv[i], "--phi0")) {
      if (i + 1 >= argc || (strcmp(argv[i + 1], "l2") && strcmp(argv[i + 1], "sampled"))) {
        fprintf(stderr, "vesica check: --phi0 takes l2 or sampled\n");
        return 2;
      }
      method = !strcmp(argv[++i], "sampled") ? VES_PHI0_SAMPLED : VES_PHI0_L2;
    } else if (argv[i][0] == '-') {
      fprintf(stderr, "vesica check: unknown option '%s' (see vesica check --help)\n", argv[i]);
      return 2;
    } else if (!path) {
      path = argv[i];
    } else {
      fprintf(stderr, "vesica check: more than one configuration file ('%s')\n", argv[i]);
      return 2;
    }
  }
  ves_config cfg;
  char err[1024] = "";
  if ((rc = load_problem("check", path, usage_check, nset, set, &cfg))) return rc;
  if ((rc = setup_estimate("check", &cfg, 0))) return rc;
  ves_setup *s = NULL;
  ves_status st = ves_setup_create(&cfg, method, &s, err, sizeof err);
  if (st != VES_OK) {
    setup_error("check", path, err);
    return exit_for(st);
  }
  double *y = malloc(2 * (size_t)s->nodes->n * sizeof *y), E = 0, A = 0, V = 0;
  if (!y) {
    fprintf(stderr, "vesica check: out of memory\n");
    ves_setup_destroy(&s);
    return 3;
  }
  ves_model_reference(s->model, y);
  st = ves_model_eval(s->model, y, VES_F_E | VES_F_A | VES_F_V, &E, &A, &V, NULL, NULL, NULL);
  free(y);
  if (st != VES_OK) {
    fprintf(stderr, "vesica check: %s: model evaluation: %s\n", path, ves_status_str(st));
    ves_setup_destroy(&s);
    return 3;
  }
  double R0 = sqrt(A / (4 * M_PI));
  printf("config = %s\n", path);
  printf("nodes = %d\n", s->nodes->n);
  printf("ghosts = %d\n", s->nodes->ng);
  printf("quadrature_points = %d\n", s->quad->nq);
  printf("neighbours_mean = %.1f\n", s->qinfo.m_mean);
  printf("neighbours_max = %d\n", s->qinfo.m_max);
  printf("lme_newton_mean = %.2f\n", s->qinfo.iter_mean);
  printf("phi0_coefficients = %s\n", method == VES_PHI0_L2 ? "l2" : "sampled");
  printf("projection_refinements = %d\nprojection_residual = %.2e\n", s->proj_refinements,
         s->proj_residual);
  printf("energy = %.9f\n", E / cfg.k);
  printf("energy_sharp = %.9f\n", ves_shape_sharp_energy(s->shape, cfg.c0));
  printf("area = %.12f\n", A);
  printf("area_sharp = %.12f\n", s->area_sharp);
  printf("area_ratio = %.12f\n", A / s->area_sharp);
  printf("volume = %.12f\n", V);
  printf("volume_sharp = %.12f\n", s->volume_sharp);
  printf("volume_ratio = %.12f\n", V / s->volume_sharp);
  printf("reduced_volume = %.9f\n", V / (4.0 / 3.0 * M_PI * R0 * R0 * R0));
  printf("epsilon = %g\n", cfg.epsilon / sqrt(s->area_sharp / (4 * M_PI)));
  printf("c0 = %g\n", cfg.c0);
  printf("seconds_nodes = %.3f\n", s->seconds_nodes);
  printf("seconds_tables = %.3f\n", s->seconds_tables);
  printf("seconds_projection = %.3f\n", s->seconds_project);
  printf("setup_seconds = %.3f\n", s->seconds_total);
  ves_setup_destroy(&s);
  return 0;
}

/* --------------------------------------------------------------------------
 * run */

static void usage_run(FILE *f) {
  fprintf(f,
          "usage: vesica run CONFIG.ini [--backend ipopt|nlopt|newton|euler] [--out FILE.h5]\n"
          "                 [--set section.key=value]... [--max-steps N] [--series FILE.tsv]\n"
          "                 [--quiet] [--force]\n"
          "       vesica run --restart FILE.h5 [--set KEY=VALUE]... [--max-steps N] [--quiet]\n"
          "Builds the initial state as 'check' does and integrates to [time] t_end with the\n"
          "chosen backend (default [solver] backend).\n"
          "  --out FILE.h5     the run's HDF5 file (default: the problem file's name with .h5,\n"
          "                    in the current folder), with FILE.xdmf beside it for ParaView:\n"
          "                    parameters, one row per accepted step (flushed at every step),\n"
          "                    snapshots every [output] snapshot_every steps and at the end\n"
          "  --restart FILE.h5 continue the run of FILE.h5 from its last snapshot, appending to\n"
          "                    it; the trajectory is bit for bit the uninterrupted one;\n"
          "                    --set may change solver.tol, solver.ctol, solver.max_iter,\n"
          "                    solver.freeze_hessian and time.t_end (recorded in the file)\n"
          "  --max-steps N     stop (with a snapshot, exit 0) once N steps are accepted in all\n"
          "  --series FILE.tsv also one tab-separated line per accepted step: step t dt E\n"
          "                    A/A0-1 V/Vtarget-1 lambda_A lambda_V iterations f_evals g_evals\n"
          "                    h_evals seconds retries resets (reference resets so far)\n"
          "                    rejected_iterations rejected_seconds (attempts retried at dt/2)\n"
          "  --force           overwrite an existing FILE.h5, FILE.xdmf or --series file\n"
          "                    (without it they are refused, exit 2; the problem file and\n"
          "                    its points file are never overwritten)\n"
          "  --quiet           no progress line (otherwise one line on stderr: step, t*, dt*,\n"
          "                    E*, iterations, ETA (a range lo-hi while adaptive steps\n"
          "                    are below dt_max, 'unknown' when that range spans more than\n"
          "                    10x; --max-steps counted); updated in place on a terminal)\n"
          "Exit 0 at t_end (or --max-steps), 2 on bad input (nothing written), 3 when a step\n"
          "fails down to dt_min (the last good state is saved as the last snapshot), 130/143 on\n"
          "SIGINT/SIGTERM after the current step (state saved; a second signal kills).\n");
}

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
  FILE *series;               /* --series file or NULL */
  int quiet;                  /* --quiet */
  long max_steps;             /* --max-steps (0: none) */
  int ncap;                   /* nodes phi, y, x have room for */
  double wall_offset;         /* wall time of the time loop before this process */
  long last_snapshot_step;    /* step of the last snapshot written */
} run_ctx;

static void run_free(run_ctx *r) {
  ves_io_close(&r->io);
  ves_sim_destroy(&r->sim);
  ves_setup_destroy(&r->setup);
  free(r->phi);
  free(r->y);
  free(r->x);
  if (r->series) fclose(r->series);
}

/* The scratch buffers for n nodes (the node count changes at a remeshing). */
static ves_status ensure_nodes(run_ctx *r, int n) {
  if (n <= r->ncap) return VES_OK;
  double *phi = realloc(r->phi, (size_t)n * sizeof *phi);
  if (phi) r->phi = phi;
  double *y = realloc(r->y, 2 * (size_t)n * sizeof *y);
  if (y) r->y = y;
  double *x = realloc(r->x, 2 * (size_t)n * sizeof *x);
  if (x) r->x = x;
  if (!phi || !y || !x) return VES_ERR_ALLOC;
  r->ncap = n;
  return VES_OK;
}

/* Nodes of the reference in use. */
static int nodes_now(run_ctx *r) { return ves_model_nodes(ves_sim_model(r->sim))->n; }

/* Whether [remesh] asks for remeshings. */
static int remeshing(const ves_config *c) {
  return c->remesh_every > 0 || c->remesh_cond_max > 0 || c->remesh_det_min > 0 ||
         c->remesh_on_failed_reset;
}

/* Setup, phi at the nodes and the integrator for r->cfg and r->bk. */
static int build(run_ctx *r) {
  char err[1024] = "";
  ves_status st = ves_setup_create(&r->cfg, VES_PHI0_L2, &r->setup, err, sizeof err);
  if (st != VES_OK) {
    setup_error("run", r->label, err);
    return exit_for(st);
  }
  if (ensure_nodes(r, r->setup->nodes->n) != VES_OK) {
    fprintf(stderr, "vesica run: out of memory\n");
    return 3;
  }
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  bo.tol = r->cfg.tol, bo.ctol = r->cfg.ctol, bo.max_iter = r->cfg.max_iter;
  bo.freeze_hessian = r->cfg.freeze_hessian;
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  const ves_config *c = &r->cfg;
  ip.t_end = c->t_end, ip.dt_initial = c->dt_initial, ip.dt_max = c->dt_max;
  ip.dt_min = c->dt_min, ip.adaptive = c->adaptive, ip.dE_target = c->dE_target;
  ip.growth_max = c->growth_max, ip.iter_target = c->iter_target;
  ip.predictor = c->predictor;
  ip.retry_memory = c->retry_memory, ip.retry_cap = c->retry_cap;
  ip.hold_area = c->area, ip.hold_volume = c->volume;
  ip.volume_rate = c->volume_rate, ip.volume_final = c->volume_final;
  ip.c0_time = c->c0_time, ip.c0_after = c->c0_after, ip.c0_until = c->c0_until;
  ip.c0_ramp_start = c->c0_ramp_start, ip.c0_ramp_end = c->c0_ramp_end;
  ip.c0_ramp_to = c->c0_ramp_to;
  ip.reconnect_every = c->reconnect_every, ip.reconnect_cond_max = c->reconnect_cond_max;
  ip.reconnect_det_min = c->reconnect_det_min;
  ip.reconnect_nodes =
      strcmp(c->reconnect_nodes, "motion") ? VES_RESET_NODES_COEF : VES_RESET_NODES_MOTION;
  if ((st = ves_sim_create(r->setup->model, r->bk, &bo, &ip, &r->sim)) != VES_OK) {
    fprintf(stderr, "vesica run: %s: cannot start the time loop: %s\n", r->label,
            ves_status_str(st));
    return exit_for(st);
  }
  if (remeshing(c)) { /* r->cfg outlives the simulation */
    ves_remesh_policy pol = {.every = c->remesh_every,
                             .cond_max = c->remesh_cond_max,
                             .det_min = c->remesh_det_min,
                             .on_failed_reset = c->remesh_on_failed_reset};
    if ((st = ves_sim_set_remesh(r->sim, &r->cfg, &pol)) != VES_OK) {
      fprintf(stderr, "vesica run: %s: [remesh]: %s\n", r->label, ves_status_str(st));
      return exit_for(st);
    }
  }
  return 0;
}



/* A snapshot of the current state. */
static ves_status snapshot(run_ctx *r, double wall) {
  ves_io_snapinfo si = {.wall_seconds = wall,
                        .reconnections = ves_sim_reconnections(r->sim),
                        .rows = ves_io_rows(r->io)};
  const int n = nodes_now(r);
  VES_CALL(ensure_nodes(r, n));
  ves_sim_get_state(r->sim, &si.state, r->y);
  si.y_prev = ves_sim_y_prev(r->sim); /* the predictor's state, when held */
  ves_sim_restart_point(r->sim); /* a restart from here repeats the next steps exactly */
  r->last_snapshot_step = si.state.nstep;
  ves_status st = ves_sim_node_material(r->sim, r->x, r->phi);
  if (st != VES_OK) { /* x and phi are for looking at: the run and its state go on */
    for (int i = 0; i < 2 * n; i++) r->x[i] = NAN;
    for (int a = 0; a < n; a++) r->phi[a] = NAN;
    fprintf(stderr,
            "vesica run: warning: step %ld: the material at the nodes could not be evaluated "
            "(%s); snapshot %d holds x and phi as NaN (y, the state, is complete)\n",
            si.state.nstep, ves_status_str(st), ves_io_snapshots(r->io));
  }
  return ves_io_snapshot(r->io, r->y, r->x, r->phi, &si);
}

/* The reference the last reset made, for a restart (io.h). */
static ves_status write_reference(run_ctx *r, long step) {
  const ves_reconnect *ref = ves_sim_reference(r->sim);
  const ves_nodes *nd = ves_reconnect_nodes(ref);
  const ves_quad *q = ves_reconnect_quad(ref);
  double *pd = malloc(6 * (size_t)q->nq * sizeof *pd);
  if (!pd) return VES_ERR_ALLOC;
  ves_model_point_data(ves_reconnect_model_const(ref), pd);
  ves_io_reference io_ref = {
      .step = step, .nq = q->nq, .x = nd->x, .h = nd->h, .xq = q->x, .wq = q->w, .pd = pd};
  ves_status st = ves_io_write_reference(r->io, &io_ref);
  free(pd);
  return st;
}

/* A restart after resets: reference k of the file rebuilt and adopted, with
 * phi of the snapshot (its material at the reference's nodes). */
static ves_status restore_reference(run_ctx *r, int k, int reconnections, const double *phi) {
  ves_model *m = ves_sim_model(r->sim); /* the setup's, or a remeshing's */
  const int n = ves_model_nodes(m)->n, nq = ves_model_quad(m)->nq;
  ves_io_reference_buf b = {.nq = nq, .n = n};
  b.x = malloc(2 * (size_t)n * sizeof *b.x), b.h = malloc((size_t)n * sizeof *b.h);
  b.xq = malloc(2 * (size_t)nq * sizeof *b.xq), b.wq = malloc((size_t)nq * sizeof *b.wq);
  b.pd = malloc(6 * (size_t)nq * sizeof *b.pd);
  ves_status st = b.x && b.h && b.xq && b.wq && b.pd ? VES_OK : VES_ERR_ALLOC;
  ves_reconnect *ref = NULL;
  if (st == VES_OK) st = ves_io_read_reference(r->io, k, &b);
  if (st == VES_OK)
    st = ves_reconnect_restore(m, b.x, b.h, nq, b.xq, b.wq, b.pd, &ref);
  if (st == VES_OK) st = ves_sim_adopt_reference(r->sim, ref, reconnections, b.step, phi);
  free(b.x), free(b.h), free(b.xq), free(b.wq), free(b.pd);
  return st;
}

/* The remeshing just made, for a restart and for the record (io.h). */
static ves_status write_remesh(run_ctx *r, long step, const ves_remesh_info *info) {
  const ves_remesh *rm = ves_sim_remesh(r->sim);
  const ves_nodes *nd = ves_remesh_nodes(rm);
  const ves_quad *q = ves_remesh_quad(rm);
  ves_io_remesh io_rm = {.step = step,
                         .n = nd->n,
                         .x = nd->x,
                         .h = nd->h,
                         .flag = nd->flag,
                         .phi0c = ves_remesh_phi0c(rm),
                         .ntri = q->ntri,
                         .tri = q->tri,
                         .info = info};
  return ves_io_write_remesh(r->io, &io_rm);
}

/* A restart after remeshings: remeshing k of the file (the remeshings-th,
 * made with reconnections resets behind it) rebuilt on the setup's model
 * and adopted. */
static ves_status restore_remesh(run_ctx *r, int k, int remeshings, int reconnections) {
  long step = 0;
  int n = 0;
  ves_status st = ves_io_remesh_size(r->io, k, &step, &n, NULL);
  if (st != VES_OK) return st;
  ves_io_remesh_buf b = {.n = n};
  b.x = malloc(2 * (size_t)n * sizeof *b.x), b.h = malloc((size_t)n * sizeof *b.h);
  b.flag = malloc((size_t)n * sizeof *b.flag), b.phi0c = malloc((size_t)n * sizeof *b.phi0c);
  st = b.x && b.h && b.flag && b.phi0c ? VES_OK : VES_ERR_ALLOC;
  ves_remesh *nm = NULL;
  if (st == VES_OK) st = ves_io_read_remesh(r->io, k, &b);
  if (st == VES_OK) st = ves_remesh_restore(r->setup->model, n, b.x, b.h, b.flag, b.phi0c, &nm);
  if (st == VES_OK) st = ves_sim_adopt_remesh(r->sim, nm, remeshings, b.step, reconnections);
  free(b.x), free(b.h), free(b.flag), free(b.phi0c);
  return st;
}

/* The folder of path must exist and be writable, path must not be a folder. */
static int check_writable(const char *cmd, const char *what, const char *path) {
  char dir[PATH_MAX];
  const char *slash = strrchr(path, '/');
  if (!*path || strlen(path) >= sizeof dir - 8) {
    fprintf(stderr, "vesica %s: %s '%s': not a usable file name\n", cmd, what, path);
    return 2;
  }
  if (slash == path)
    snprintf(dir, sizeof dir, "/");
  else if (slash)
    snprintf(dir, sizeof dir, "%.*s", (int)(slash - path), path);
  else
    snprintf(dir, sizeof dir, ".");
  struct stat sb;
  if (stat(dir, &sb) != 0 || !S_ISDIR(sb.st_mode)) {
    fprintf(stderr, "vesica %s: %s %s: folder %s does not exist\n", cmd, what, path, dir);
    return 2;
  }
  if (access(dir, W_OK) != 0) {
    fprintf(stderr, "vesica %s: %s %s: folder %s is not writable\n", cmd, what, path, dir);
    return 2;
  }
  if (stat(path, &sb) == 0 && !S_ISREG(sb.st_mode)) {
    fprintf(stderr, "vesica %s: %s %s: exists and is not a regular file\n", cmd, what, path);
    return 2;
  }
  return 0;
}

/* Whether a and b name the same existing file. */
static int same_file(const char *a, const char *b) {
  struct stat sa, sb;
  return a && b && stat(a, &sa) == 0 && stat(b, &sb) == 0 && sa.st_dev == sb.st_dev &&
         sa.st_ino == sb.st_ino;
}

/* An output path: never one of the inputs in[nin] (NULL entries skipped),
 * and not an existing file unless force. 0 ok, else 2 (message printed;
 * hint, if any, says how to keep the file instead). */
static int check_new(const char *cmd, const char *what, const char *path, int force,
                     const char *const *in, int nin, const char *hint) {
  for (int i = 0; i < nin; i++)
    if (same_file(path, in[i])) {
      fprintf(stderr, "vesica %s: %s %s: is the input file %s: an input is never overwritten\n",
              cmd, what, path, in[i]);
      return 2;
    }
  struct stat sb;
  if (!force && lstat(path, &sb) == 0) {
    fprintf(stderr, "vesica %s: %s %s: exists; --force overwrites it%s\n", cmd, what, path,
            hint ? hint : "");
    return 2;
  }
  return 0;
}

/* Remove the output of a run that failed before its first step. */
static void remove_output(const char *out) {
  char x[PATH_MAX];
  ves_io_xdmf_path(out, x, sizeof x);
  remove(out);
  remove(x);
}

/* The progress line's time to the end of the run, from the mean wall time
 * w of the recent steps: (t_end - t) / dt steps of w with constant steps;
 * with adaptive ones the step count lies between (t_end - t) / dt_max (dt
 * grows to its cap) and (t_end - t) / dt (it stays); --max-steps caps both.
 * One value once the two are within 1.5x, a range lo-hi within 10x, and
 * "unknown" beyond (a range over orders of magnitude says nothing). A
 * linear extrapolation in t* is off by the growth of dt, orders of
 * magnitude early in a run. */
static double steps_left(double left, double dt) {
  double n = ceil(left / dt - 1e-9); /* a step that ends at t_end up to rounding is the last */
  return n > 0 ? n : 0.0;            /* not -0 */
}

static void eta_text(char *buf, size_t len, const ves_config *c, double t, double dt, double w,
                     long nstep, long max_steps) {
  const double left = c->t_end - t;
  double nhi = steps_left(left, dt), nlo = c->adaptive ? steps_left(left, c->dt_max) : nhi;
  if (max_steps > 0) { /* --max-steps stops the run first when it comes first */
    const double m = max_steps > nstep ? (double)(max_steps - nstep) : 0.0;
    nhi = fmin(nhi, m), nlo = fmin(nlo, m);
  }
  const double hi = w * nhi, lo = w * nlo;
  if (hi <= 1.5 * lo || floor(hi + 0.5) == floor(lo + 0.5))
    snprintf(buf, len, "%.0f s", hi);
  else if (hi <= 10 * lo)
    snprintf(buf, len, "%.0f-%.0f s", lo, hi);
  else
    snprintf(buf, len, "unknown (dt* adapting)");
}

/* Why a write to the output failed: the cause the io module recorded (no
 * space, the file-size limit, the failing write's errno), else the status. */
static const char *io_cause(const ves_io *io, ves_status st) {
  return ves_io_error(io) ? ves_io_error(io) : ves_status_str(st);
}

/* The time loop: steps, rows, snapshots, progress. Returns the exit code. */
static int loop(run_ctx *r) {
  double t0 = ves_wall_seconds(), tend = r->cfg.t_end;
  double recent[10] = {0}; /* wall times at the ends of the last 10 steps (ring) */
  int tty = isatty(2), code = 0;
  long iters = 0, steps = 0;
  ves_step_report rep;
  ves_status st = VES_OK, wst = VES_OK, room = VES_OK;
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = on_signal;
  sa.sa_flags = SA_RESETHAND; /* a second signal kills */
  sigaction(SIGINT, &sa, NULL);
  sigaction(SIGTERM, &sa, NULL);
  for (;;) {
    ves_sim_state now;
    ves_sim_get_state(r->sim, &now, NULL);
    if (r->max_steps > 0 && now.nstep >= r->max_steps) break;
    if (stop_signal) break;
    /* room for this step's writes and a last snapshot after them: a run on a
     * filling disk stops here, between complete writes (io.h) */
    const int due = (now.nstep + 1) % r->cfg.snapshot_every == 0;
    const ves_config *c = &r->cfg;
    const int resets = c->reconnect_every > 0 || c->reconnect_cond_max > 0 ||
                       c->reconnect_det_min > 0 || remeshing(c); /* a remeshing is smaller */
    const int nq = ves_model_quad(ves_sim_model(r->sim))->nq;
    if ((room = ves_io_room(r->io, 1 + due, resets ? nq : 0)) != VES_OK) break;
    if ((st = ves_sim_step(r->sim, &rep)) != VES_OK) break;
    steps++;
    iters += rep.stats.iterations;
    double wall = r->wall_offset + ves_wall_seconds() - t0;
    ves_io_row row = {.step = rep.step,
                      .t = rep.t,
                      .dt = rep.dt,
                      .E = rep.E,
                      .A = rep.A,
                      .V = rep.V,
                      .V_target = rep.V_target,
                      .lambda_A = rep.lambda[0],
                      .lambda_V = rep.lambda[1],
                      .c0 = rep.c0,
                      .iterations = rep.stats.iterations,
                      .f_evals = rep.stats.f_evals,
                      .g_evals = rep.stats.g_evals,
                      .h_evals = rep.stats.h_evals,
                      .violation = rep.stats.violation,
                      .solve_seconds = rep.stats.seconds,
                      .wall_seconds = wall,
                      .retries = rep.retries,
                      .status = rep.solve_status,
                      .reconnections = ves_sim_reconnections(r->sim)};
    if ((wst = ves_io_append(r->io, &row)) != VES_OK) break;
    if (rep.reconnected && (wst = write_reference(r, rep.step)) != VES_OK) break;
    if (rep.remeshed && (wst = write_remesh(r, rep.step, &rep.remesh)) != VES_OK) break;
    if (rep.step % r->cfg.snapshot_every == 0 && (wst = snapshot(r, wall)) != VES_OK) break;
    if (r->series) {
      double A0, V0;
      ves_sim_initial(r->sim, NULL, &A0, &V0);
      fprintf(r->series,
              "%ld\t%.9g\t%.6g\t%.12g\t%.3e\t%.3e\t%.9g\t%.9g\t%d\t%d\t%d\t%d\t%.3f\t%d\t%d\t%d\t%"
              ".3f\n",
              rep.step, rep.t, rep.dt, rep.E, rep.A / A0 - 1, rep.V / rep.V_target - 1,
              rep.lambda[0], rep.lambda[1], rep.stats.iterations, rep.stats.f_evals,
              rep.stats.g_evals, rep.stats.h_evals, rep.stats.seconds, rep.retries,
              ves_sim_reconnections(r->sim), rep.rejected.iterations, rep.rejected.seconds);
      fflush(r->series);
    }
    const double el = ves_wall_seconds() - t0;   /* this process's loop */
    const int nr = steps < 10 ? (int)steps : 10; /* steps in the window */
    const double w = (el - (steps > 10 ? recent[steps % 10] : 0.0)) / nr;
    recent[steps % 10] = el;
    if (!r->quiet && (tty || rep.step % 10 == 0)) {
      char eta[64];
      eta_text(eta, sizeof eta, &r->cfg, rep.t, rep.dt, w, rep.step, r->max_steps);
      fprintf(stderr, "%sstep %ld  t* %.4g/%.4g  dt* %.3g  E* %.6f  iter %d  ETA %s%s",
              tty ? "\r" : "", rep.step, rep.t, tend, rep.dt, rep.E, rep.stats.iterations, eta,
              tty ? "   " : "\n");
    }
    if (rep.retries && !r->quiet) /* the cost of the rejected attempts, and why */
      fprintf(stderr,
              "%sstep %ld: %d attempt(s) rejected from dt* %.3g (last: %s; %d iterations, %d "
              "Hessians, %.1f s), accepted at dt* %.3g\n",
              tty ? "\n" : "", rep.step, rep.retries, rep.reject_dt,
              ves_status_str(rep.reject_status), rep.rejected.iterations, rep.rejected.h_evals,
              rep.rejected.seconds, rep.dt);
    if (rep.reconnected && !r->quiet)
      fprintf(stderr,
              "%sstep %ld: reference reset #%d (max cond F %.3g, min det F %.3g, max "
              "|y^a - y(X_a)|/h_a %.3g, %d node(s) mirrored across the axis, E* %.9g -> %.9g)\n",
              tty ? "\n" : "", rep.step, ves_sim_reconnections(r->sim), rep.cond, rep.det_min,
              rep.shift, rep.mirrored, rep.E, rep.E_reset);
    if (rep.remeshed && !r->quiet) {
      const ves_remesh_info *m = &rep.remesh;
      fprintf(stderr,
              "%sstep %ld: remeshing #%d (%d -> %d nodes; before the correction dE* %.3g, "
              "dA/A %.3g, dV/V %.3g; correction max |delta|/h %.3g, |delta| %.3g in %d "
              "iteration(s), then |A/A0 - 1| %.2g, |V/Vt - 1| %.2g; interface moved max %.3g, "
              "mean %.3g; E* %.9g -> %.9g; %.1f s)\n",
              tty ? "\n" : "", rep.step, ves_sim_remeshings(r->sim), m->n_old, m->n_new, m->dE,
              m->dA, m->dV, m->corr_max, m->corr_norm, m->corr_iter, m->res_A, m->res_V,
              m->disp_max, m->disp_mean, m->E_old, m->E, m->seconds);
    }
    if (rep.remesh_status != VES_OK) /* a warning even with --quiet: a remeshing was skipped */
      fprintf(stderr,
              "%svesica run: warning: step %ld: the remeshing that was due failed (%s); "
              "continuing on the old nodes, retried after the next step\n",
              tty ? "\n" : "", rep.step, ves_status_str(rep.remesh_status));
    if (rep.reconnect_status != VES_OK) /* a warning even with --quiet: a reset was skipped */
      fprintf(stderr,
              "%svesica run: warning: step %ld: the reference reset that was due failed (%s); "
              "continuing on the old reference, retried after the next step\n",
              tty ? "\n" : "", rep.step, ves_status_str(rep.reconnect_status));
  }
  if (tty && !r->quiet && steps) fputc('\n', stderr);
  signal(SIGINT, SIG_DFL);
  signal(SIGTERM, SIG_DFL);
  double wall = r->wall_offset + ves_wall_seconds() - t0;
  ves_sim_state fin;
  ves_sim_get_state(r->sim, &fin, NULL);
  const char *status = "finished";
  if (wst != VES_OK) { /* a write failed half-way: nothing more is written */
    fprintf(stderr,
            "vesica run: %s: cannot write: %s; continue from its last complete snapshot with "
            "vesica run --restart %s\n",
            r->out, io_cause(r->io, wst), r->out);
    return 3; /* the file holds every step written before */
  }
  if (room != VES_OK) {
    fprintf(stderr,
            "vesica run: %s: stopped at step %ld, t* = %.6g: %s; the state is saved as the last "
            "snapshot: free some space (or move the file) and continue with vesica run "
            "--restart %s\n",
            r->out, fin.nstep, fin.t, io_cause(r->io, room), r->out);
    status = "failed", code = 3;
  } else if (st < 0) {
    fprintf(stderr,
            "vesica run: %s: no acceptable step at t* = %.6g down to dt* = %g (%s); the last "
            "good state (step %ld) is the last snapshot of %s\n",
            r->label, fin.t, r->cfg.dt_min, ves_status_str(st), fin.nstep, r->out);
    status = "failed", code = 3;
  } else if (stop_signal) {
    fprintf(stderr,
            "vesica run: stopped by signal %d at step %ld, t* = %.6g; continue with "
            "vesica run --restart %s\n",
            (int)stop_signal, fin.nstep, fin.t, r->out);
    status = "stopped", code = 128 + (int)stop_signal;
  } else if (st != VES_MAXITER && fin.t < tend - 1e-12 * (1 + fabs(tend))) {
    status = "stopped"; /* --max-steps */
  }
  if (fin.nstep != r->last_snapshot_step && (wst = snapshot(r, wall)) != VES_OK) {
    fprintf(stderr, "vesica run: %s: cannot write the last snapshot: %s\n", r->out,
            io_cause(r->io, wst));
    return 3;
  }
  if ((wst = ves_io_set_status(r->io, status)) != VES_OK) {
    fprintf(stderr, "vesica run: %s: cannot write: %s\n", r->out, io_cause(r->io, wst));
    return 3;
  }
  if (!r->quiet && code == 0)
    fprintf(stderr,
            "vesica run: %s at step %ld, t* = %.6g: %ld steps, %ld iterations, %.1f s; "
            "wrote %s\n",
            !strcmp(status, "finished") ? "t_end reached" : "--max-steps reached", fin.nstep, fin.t,
            steps, iters, ves_wall_seconds() - t0, r->out);
  return code;
}

/* A new run: CONFIG.ini [options]. */
static int run_new(run_ctx *r, const char *path, const char *out, const char *backend, int nset,
                   const char *const *set, const char *series, int force) {
  int rc = load_problem("run", path, usage_run, nset, set, &r->cfg);
  if (rc) return rc;
  r->label = path;
  r->bk = ves_backend_find(backend ? backend : r->cfg.backend);
  if (!r->bk) {
    fprintf(stderr, "vesica run: --backend '%s': not one of ipopt, nlopt, newton, euler\n",
            backend ? backend : r->cfg.backend);
    return 2;
  }
  if (out) {
    snprintf(r->out, sizeof r->out, "%s", out);
  } else { /* the problem file's name, .h5, here */
    const char *base = strrchr(path, '/') ? strrchr(path, '/') + 1 : path;
    size_t l = strlen(base);
    if (l > 4 && !strcmp(base + l - 4, ".ini")) l -= 4;
    snprintf(r->out, sizeof r->out, "%.*s.h5", (int)l, base);
  }
  char xdmf[PATH_MAX], points[PATH_MAX + 600] = "", hint[PATH_MAX + 64], why[128];
  if (!ves_io_xdmf_name_ok(r->out, why, sizeof why)) { /* the .xdmf could not name it */
    fprintf(stderr,
            "vesica run: --out %s: %s, so the XDMF file beside it could not refer to it: "
            "choose another name\n",
            r->out, why);
    return 2;
  }
  ves_io_xdmf_path(r->out, xdmf, sizeof xdmf);
  if ((rc = check_writable("run", "--out", r->out)) || (rc = check_writable("run", "--out", xdmf)))
    return rc;
  if (series && (rc = check_writable("run", "--series", series))) return rc;
  if (r->cfg.points[0]) { /* a curve's points file, found as ves_config_read_points does */
    const char *sl = r->cfg.points[0] == '/' ? NULL : strrchr(path, '/');
    snprintf(points, sizeof points, "%.*s%s%s", sl ? (int)(sl - path) : 0, path, sl ? "/" : "",
             r->cfg.points);
  }
  const char *inputs[] = {path, points[0] ? points : NULL};
  snprintf(hint, sizeof hint, ", or vesica run --restart %s continues it", r->out);
  if ((rc = check_new("run", "--out", r->out, force, inputs, 2, hint)) ||
      (rc = check_new("run", "--out", xdmf, force, inputs, 2, NULL)) ||
      (series && (rc = check_new("run", "--series", series, force, inputs, 2, NULL))))
    return rc;
  if (series && (same_file(series, r->out) || !strcmp(series, r->out) || !strcmp(series, xdmf))) {
    fprintf(stderr, "vesica run: --series %s: is the run's output file\n", series);
    return 2;
  }
  char abs[PATH_MAX], *problem = NULL, err[1024] = "";
  if (!realpath(path, abs)) snprintf(abs, sizeof abs, "%s", path);
  if (ves_config_to_text(&r->cfg, &problem) != VES_OK) {
    fprintf(stderr, "vesica run: out of memory\n");
    return 3;
  }
  if ((rc = setup_estimate("run", &r->cfg, r->quiet)) || (rc = build(r))) {
    free(problem);
    return rc;
  }
  double E0, A0, V0;
  ves_sim_initial(r->sim, &E0, &A0, &V0);
  int ncell = 0, *cells = NULL; /* the Delaunay triangles (a rich rule repeats them) */
  if (ves_quad_cells(r->setup->quad, &ncell, &cells) != VES_OK) {
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
    fprintf(stderr, "vesica run: %s\n", err);
    return 2;
  }
  if ((st = snapshot(r, 0.0)) != VES_OK) { /* nothing half-written stays behind */
    fprintf(stderr, "vesica run: %s: cannot write the first snapshot: %s\n", r->out,
            io_cause(r->io, st));
    ves_io_close(&r->io);
    remove_output(r->out);
    return 2;
  }
  if (series) {
    if (!(r->series = fopen(series, "w"))) {
      fprintf(stderr, "vesica run: --series %s: cannot open for writing: %s\n", series,
              strerror(errno));
      ves_io_close(&r->io);
      remove_output(r->out);
      return 2;
    }
    fprintf(r->series,
            "# vesica %s run %s backend %s nodes %d E0 %.12g A0 %.12g V0 %.12g\n"
            "# step\tt\tdt\tE\tA/A0-1\tV/Vt-1\tlambda_A\tlambda_V\titer\tf\tg\th\tseconds\t"
            "retries\tresets\trejected_iterations\trejected_seconds\n",
            VES_VERSION, path, r->bk->name, r->setup->nodes->n, E0, A0, V0);
  }
  return loop(r);
}

/* Rebuild the run stored in r->io (its problem already in r->cfg) at
 * snapshot S: the setup (which must reproduce the file's nodes), the
 * reference in force at S (rebuilt from the file after resets) and the
 * integrator's state there, into r. pre starts every message. Returns 0 or
 * an exit code (a message printed). */
static int rebuild_at(run_ctx *r, const char *pre, int S, ves_io_snapinfo *si) {
  /* after resets the snapshot's y is relative to the last reference made
   * before it, which the file must hold */
  const ves_io_info *in = ves_io_get_info(r->io);
  ves_status st = ves_io_read_snapshot(r->io, S, NULL, NULL, NULL, si);
  if (st != VES_OK) {
    fprintf(stderr, "%s: snapshot %d is unreadable: %s\n", pre, S, ves_status_str(st));
    return 2;
  }
  if (si->reconnections > ves_io_references(r->io)) {
    fprintf(stderr,
            "%s: the run reset its reference configuration %d time(s) before snapshot %d "
            "(step %ld) but the file holds only %d of the references they made "
            "(format_version 1 files hold none): rerun the problem\n",
            pre, si->reconnections, S, si->state.nstep, ves_io_references(r->io));
    return 2;
  }
  if (!(r->bk = ves_backend_find(in->backend))) {
    fprintf(stderr, "%s: unknown backend '%s'\n", pre, in->backend);
    return 2;
  }
  int rc = build(r);
  if (rc) return rc;
  /* the setup is deterministic: the rebuilt nodes must be the file's, bit for bit */
  int n = r->setup->nodes->n;
  const int ncell = r->setup->quad->ntri / (r->setup->quad->sub > 1 ? r->setup->quad->sub : 1);
  if (n != in->n || ncell != in->ntri) {
    fprintf(stderr, "%s: the rebuilt setup has %d nodes, %d triangles; the file %d, %d\n", pre, n,
            ncell, in->n, in->ntri);
    return 2;
  }
  double *X = malloc(2 * (size_t)n * sizeof *X);
  if (!X) return 3;
  st = ves_io_read_mesh(r->io, X, NULL);
  int same = st == VES_OK && !memcmp(X, r->setup->nodes->x, 2 * (size_t)n * sizeof *X);
  free(X);
  if (!same) {
    fprintf(stderr,
            "%s: the rebuilt nodes differ from the file's mesh (another vesica version, or a "
            "changed points file?)\n",
            pre);
    return 2;
  }
  /* after remeshings the snapshot is on the last one made at or before its
   * step (and on a later reset's reference when there is one) */
  const int ns = ves_io_snapshot_nodes(r->io, S);
  if (ns < 1 || ensure_nodes(r, ns) != VES_OK ||
      (st = ves_io_read_snapshot_n(r->io, S, ns, r->y, NULL, r->phi, si)) != VES_OK ||
      si->rows > ves_io_rows(r->io) || si->rows != si->state.nstep) {
    fprintf(stderr, "%s: snapshot %d is unreadable or inconsistent\n", pre, S);
    return 2;
  }
  int R = 0; /* remeshings before the snapshot */
  long rstep = 0, fstep = 0;
  while (R < ves_io_remeshes(r->io) &&
         ves_io_remesh_size(r->io, R, &rstep, NULL, NULL) == VES_OK && rstep <= si->state.nstep)
    R++, fstep = rstep;
  if (R > 0 && (st = restore_remesh(r, R - 1, R, si->reconnections)) != VES_OK) {
    fprintf(stderr, "%s: remeshing %d (step %ld) cannot be rebuilt: %s\n", pre, R - 1, fstep,
            ves_status_str(st));
    return 2;
  }
  long fref = 0; /* the reset of the reference in force came after the remeshing */
  if (si->reconnections > 0 &&
      (st = ves_io_reference_step(r->io, si->reconnections - 1, &fref)) != VES_OK) {
    fprintf(stderr, "%s: reference %d is unreadable: %s\n", pre, si->reconnections - 1,
            ves_status_str(st));
    return 2;
  }
  if (ns != nodes_now(r)) { /* a reset keeps the node count */
    fprintf(stderr, "%s: snapshot %d has %d nodes, its node set %d\n", pre, S, ns, nodes_now(r));
    return 2;
  }
  int phi_ok = 1; /* NaN when the snapshot could not evaluate it: refitted when needed */
  for (int a = 0; a < ns && phi_ok; a++) phi_ok = isfinite(r->phi[a]);
  if (si->reconnections > 0 && (R == 0 || fref > fstep) &&
      (st = restore_reference(r, si->reconnections - 1, si->reconnections,
                              phi_ok ? r->phi : NULL)) != VES_OK) {
    fprintf(stderr, "%s: reference %d (reset #%d) cannot be rebuilt: %s\n", pre,
            si->reconnections - 1, si->reconnections, ves_status_str(st));
    return 2;
  }
  /* the predictor's y^{n-1} when the snapshot holds one (r->x as the buffer: 2 ns) */
  if (si->state.dt_prev > 0 && (st = ves_io_read_snapshot_prev(r->io, S, ns, r->x)) != VES_OK) {
    fprintf(stderr, "%s: snapshot %d: its y_prev (the predictor's state): %s\n", pre, S,
            ves_status_str(st));
    return 2;
  }
  if ((st = ves_sim_set_state(r->sim, &si->state, r->y, r->x)) != VES_OK) {
    fprintf(stderr, "%s: snapshot %d: %s\n", pre, S, ves_status_str(st));
    return 2;
  }
  return 0;
}

/* The keys a restart may change: how each step is solved, and where the run
 * ends; the rest defines the setup, the physics or the protocol the stored
 * steps followed. */
static const char *const RESTART_KEYS[] = {"solver.tol", "solver.ctol", "solver.max_iter",
                                           "solver.freeze_hessian", "time.t_end"};

/* A file cut short (a torn last write): its last complete snapshot, the
 * rows and references before it salvaged into a new FILE.h5 (io.h), the
 * damaged file kept as FILE.h5.damaged. 0, or exit code 3 with a message. */
static int salvage(const char *file, int quiet) {
  char tmp[PATH_MAX + 16], kept[PATH_MAX + 16], err[1024] = "";
  snprintf(tmp, sizeof tmp, "%s.salvage", file);
  snprintf(kept, sizeof kept, "%s.damaged", file);
  struct stat sb;
  if (stat(kept, &sb) == 0) {
    fprintf(stderr,
            "vesica run: --restart %s: the file is cut short (a torn last write) and %s, where "
            "its damaged copy would be kept, exists: move it away\n",
            file, kept);
    return 3;
  }
  remove(tmp); /* a salvage interrupted before */
  ves_io_salvaged s;
  ves_status st = ves_io_salvage(file, tmp, &s, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr,
            "vesica run: --restart %s: the file is cut short (%lld of the %lld bytes its "
            "superblock records: a torn last write) and cannot be salvaged: %s\n",
            file, s.size, s.stored_size, err);
    return 3;
  }
  if (rename(file, kept) != 0 || rename(tmp, file) != 0) {
    fprintf(stderr, "vesica run: --restart %s: cannot put the salvaged file in place: %s\n", file,
            strerror(errno));
    return 3;
  }
  if (!quiet)
    fprintf(stderr,
            "vesica run: %s was cut short (%lld of %lld bytes: a torn last write): salvaged "
            "snapshots 0..%d of %d (step %ld, t* = %.6g), %ld series rows and %d reference(s) "
            "into a new %s; the damaged file is kept as %s\n",
            file, s.size, s.stored_size, s.snapshot, s.snapshots, s.step, s.t, s.rows, s.references,
            file, kept);
  return 0;
}

/* Continue FILE.h5 from its last snapshot, with the overrides set[nset]
 * (RESTART_KEYS only; recorded in the file). */
static int run_restart(run_ctx *r, const char *file, int nset, const char *const *set) {
  char err[1024] = "";
  r->label = file;
  snprintf(r->out, sizeof r->out, "%s", file);
  char xdmf[PATH_MAX], why[128];
  if (!ves_io_xdmf_name_ok(file, why, sizeof why)) {
    fprintf(stderr,
            "vesica run: --restart %s: %s, so its XDMF file could not refer to it: rename the "
            "file\n",
            file, why);
    return 2;
  }
  ves_io_xdmf_path(file, xdmf, sizeof xdmf);
  int rc = check_writable("run", "--restart", xdmf);
  if (rc) return rc;
  if (ves_io_cut_short(file, NULL, NULL) && (rc = salvage(file, r->quiet))) return rc;
  ves_status st = ves_io_open(file, 1, &r->io, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr, "vesica run: --restart %s\n", err);
    return 2;
  }
  const ves_io_info *in = ves_io_get_info(r->io);
  int S = ves_io_snapshots(r->io);
  if (S < 1) {
    fprintf(stderr, "vesica run: --restart %s: no snapshot to continue from\n", file);
    return 2;
  }
  if (ves_config_load_text(in->problem, in->source, &r->cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica run: --restart %s: the stored problem: %s\n", file, err);
    return 2;
  }
  for (int i = 0; i < nset; i++) {
    size_t k = 0, nk = sizeof RESTART_KEYS / sizeof RESTART_KEYS[0];
    const size_t len = strcspn(set[i], "=");
    while (k < nk && !(strlen(RESTART_KEYS[k]) == len && !strncmp(set[i], RESTART_KEYS[k], len)))
      k++;
    if (k == nk) {
      fprintf(stderr,
              "vesica run: --restart %s: --set %s: a restart may change only solver.tol, "
              "solver.ctol, solver.max_iter, solver.freeze_hessian and time.t_end (the other "
              "keys define the setup and the steps already taken)\n",
              file, set[i]);
      return 2;
    }
  }
  if (nset && ves_config_set(&r->cfg, nset, set, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica run: --restart %s: %s\n", file, err);
    return 2;
  }
  ves_io_snapinfo si;
  char pre[PATH_MAX + 32];
  snprintf(pre, sizeof pre, "vesica run: --restart %s", file);
  if ((rc = rebuild_at(r, pre, S - 1, &si))) return rc;
  if ((st = ves_io_truncate(r->io, si.rows)) != VES_OK ||
      (st = ves_io_truncate_references(r->io, si.reconnections)) != VES_OK ||
      (st = ves_io_truncate_remeshes(r->io, ves_sim_remeshings(r->sim))) != VES_OK ||
      (nset && (st = ves_io_set_problem(r->io, &r->cfg)) != VES_OK) ||
      (st = ves_io_set_setup_seconds(r->io, r->setup->seconds_total)) != VES_OK ||
      (st = ves_io_set_status(r->io, "running")) != VES_OK) {
    fprintf(stderr, "vesica run: --restart %s: cannot write: %s\n", file, io_cause(r->io, st));
    return 3;
  }
  r->wall_offset = si.wall_seconds;
  r->last_snapshot_step = si.state.nstep;
  if (!r->quiet) {
    fprintf(stderr, "vesica run: continuing %s from snapshot %d (step %ld, t* = %.6g)", file, S - 1,
            si.state.nstep, si.state.t);
    for (int i = 0; i < nset; i++) fprintf(stderr, "%s%s", i ? ", " : " with ", set[i]);
    fputc('\n', stderr);
  }
  return loop(r);
}

static int cmd_run(int argc, char **argv) {
  const char *path = NULL, *set[MAX_SET] = {0}, *backend = NULL, *series = NULL, *out = NULL;
  const char *restart = NULL;
  int nset = 0, quiet = 0, force = 0, rc;
  long max_steps = 0;
  for (int i = 0; i < argc; i++) {
    const char *a = argv[i];
    int has = i + 1 < argc && argv[i + 1][0] != '-'; /* a value follows */
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      usage_run(stdout);
      return 0;
    } else if (!strcmp(a, "--set")) {
      if ((rc = take_set("run", argc, argv, &i, &nset, set))) return rc;
    } else if (!strcmp(a, "--backend") || !strcmp(a, "--series") || !strcmp(a, "--out") ||
               !strcmp(a, "--restart") || !strcmp(a, "--max-steps")) {
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
      else {
        char *end;
        errno = 0;
        max_steps = strtol(v, &end, 10);
        if (*end || errno || max_steps < 1) {
          fprintf(stderr, "vesica run: --max-steps '%s': not a positive integer\n", v);
          return 2;
        }
      }
    } else if (!strcmp(a, "--quiet")) {
      quiet = 1;
    } else if (!strcmp(a, "--force")) {
      force = 1;
    } else if (a[0] == '-') {
      fprintf(stderr, "vesica run: unknown option '%s' (see vesica run --help)\n", a);
      return 2;
    } else if (!path) {
      path = a;
    } else {
      fprintf(stderr, "vesica run: more than one configuration file ('%s')\n", a);
      return 2;
    }
  }
  if (restart && (path || backend || out || series || force)) {
    fprintf(stderr,
            "vesica run: --restart %s continues the stored problem: no CONFIG.ini, "
            "--backend, --out, --series or --force with it\n",
            restart);
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
  rc = restart ? run_restart(&r, restart, nset, set)
               : run_new(&r, path, out, backend, nset, set, series, force);
  run_free(&r);
  return rc;
}

/* --------------------------------------------------------------------------
 * info */

static void usage_info(FILE *f) {
  fprintf(f, "usage: vesica info FILE.h5\n"
             "Summary of a run, one 'key = value' per line (stable keys, for scripts):\n"
             "  file, format_version, version, status (running = still running or killed,\n"
             "  finished, stopped, failed), backend, nodes, triangles, snapshots,\n"
             "  references (stored reference configurations, one per reset), remeshings\n"
             "  (full remeshings, [remesh]), nodes_final (the last snapshot's nodes), steps,\n"
             "  t_final, t_end, energy_initial, energy_final (E*), energy_monotone (yes/no: E*\n"
             "  never rose by more than 1e-10 relative between accepted steps on the same C0\n"
             "  and volume target),\n"
             "  area_drift_max (max |A/A0 - 1|), volume_drift_max (max |V/V_target - 1|),\n"
             "  reduced_volume_initial, reduced_volume_final, dt_first, dt_largest, retries,\n"
             "  reconnections, newton_iterations (the backend's iterations in all: Newton steps,\n"
             "  Ipopt iterations, ...), hessian_evaluations, wall_seconds (time loop, over\n"
             "  restarts), setup_seconds;\n"
             "  interface_area, interface_volume, interface_reduced_volume and\n"
             "  node_triangles_inverted, each _initial (first snapshot) and _final (last): the\n"
             "  sharp interface the nodes show, phi = 0 of the piecewise-linear phi at the nodes\n"
             "  on the reference triangles moved to the material positions (a check of the\n"
             "  phase-field A and V against that geometry; inverted triangles: the motion folds\n"
             "  at the scale of the nodes; not for format_version 1 files);\n"
             "  interface_area_drift_max, interface_volume_drift_max (max over the snapshots\n"
             "  of |A_I/A_I(initial) - 1|, |V_I/V_I(initial) - 1|), node_triangles_inverted_max;\n"
             "  source;\n"
             "then every parameter as section.key = value.\n");
}

/* v = V / (4 pi R0^3 / 3), R0 = sqrt(A / 4 pi). */
static double reduced_volume(double A, double V) {
  double R0 = sqrt(A / (4 * M_PI));
  return V / (4.0 / 3.0 * M_PI * R0 * R0 * R0);
}

/* The sharp interface the nodes show (ves_plot_interface) at the first and
 * the last snapshot, and its largest drift over the snapshots against the
 * first: a check of the phase-field A and V against that geometry. */
static void interface_lines(ves_io *io) {
  const int S = ves_io_snapshots(io);
  ves_level_set *ls = malloc((size_t)(S > 0 ? S : 1) * sizeof *ls);
  unsigned char *ok = malloc((size_t)(S > 0 ? S : 1));
  if (ls && ok && ves_plot_interface(io, ls, ok) == VES_OK) {
    int k0 = 0, k1 = S - 1, inv = 0, seen = 0;
    while (k0 < S && !ok[k0]) k0++;
    while (k1 >= 0 && !ok[k1]) k1--;
    double da = 0, dv = 0;
    for (int k = k0; k <= k1; k++)
      if (ok[k]) {
        da = fmax(da, fabs(ls[k].area / ls[k0].area - 1));
        dv = fmax(dv, fabs(ls[k].volume / ls[k0].volume - 1));
        inv = ls[k].inverted > inv ? ls[k].inverted : inv, seen++;
      }
    const int ks[2] = {k0, k1};
    const char *when[2] = {"initial", "final"};
    for (int c = 0; c < 2 && seen; c++) {
      const ves_level_set *l = ls + ks[c];
      printf("interface_area_%s = %.9g\ninterface_volume_%s = %.9g\n", when[c], l->area, when[c],
             l->volume);
      printf("interface_reduced_volume_%s = %.9g\n", when[c], reduced_volume(l->area, l->volume));
      printf("node_triangles_inverted_%s = %d\n", when[c], l->inverted);
    }
    if (seen)
      printf("interface_area_drift_max = %.6e\ninterface_volume_drift_max = %.6e\n"
             "node_triangles_inverted_max = %d\n",
             da, dv, inv);
  }
  free(ls), free(ok);
}

static int cmd_info(int argc, char **argv) {
  const char *path = NULL;
  for (int i = 0; i < argc; i++) {
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      usage_info(stdout);
      return 0;
    } else if (argv[i][0] == '-') {
      fprintf(stderr, "vesica info: unknown option '%s' (see vesica info --help)\n", argv[i]);
      return 2;
    } else if (path) {
      fprintf(stderr, "vesica info: more than one file ('%s')\n", argv[i]);
      return 2;
    }
    path = argv[i];
  }
  if (!path) {
    usage_info(stderr);
    return 2;
  }
  char err[1024] = "";
  ves_io *io = NULL;
  if (ves_io_open(path, 0, &io, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica info: %s\n", err);
    return 2;
  }
  const ves_io_info *in = ves_io_get_info(io);
  ves_config cfg;
  if (ves_config_load_text(in->problem, in->source, &cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica info: %s: the stored problem: %s\n", path, err);
    ves_io_close(&io);
    return 2;
  }
  long R = ves_io_rows(io);
  const char *names[] = {"t",           "dt",         "E",       "A",       "V",
                         "V_target",    "iterations", "h_evals", "retries", "reconnections",
                         "wall_seconds", "c0"};
  enum { NC = sizeof names / sizeof names[0] };
  double *col[NC] = {0};
  int rc = 0;
  for (int c = 0; c < NC && !rc; c++) {
    col[c] = malloc((size_t)(R > 0 ? R : 1) * sizeof *col[c]);
    if (!col[c] || ves_io_read_series(io, names[c], col[c]) != VES_OK) rc = 2;
  }
  if (rc) {
    fprintf(stderr, "vesica info: %s: cannot read the series\n", path);
  } else {
    double *t = col[0], *dt = col[1], *E = col[2], *A = col[3], *V = col[4], *Vt = col[5];
    double adrift = 0, vdrift = 0, dtmax = 0, iters = 0, hes = 0, retries = 0;
    int monotone = 1;
    const double *c0 = col[NC - 1];
    for (long i = 0; i < R; i++) {
      /* compared only across steps on the same landscape: a C0 switch or a
       * moving volume target may raise E (the integrator's own rule) */
      double Eprev = i ? E[i - 1] : in->E0;
      double c0prev = i ? c0[i - 1] : cfg.c0, Vtprev = i ? Vt[i - 1] : in->V0;
      if (c0[i] == c0prev && fabs(Vt[i] - Vtprev) <= 1e-14 * in->V0 &&
          E[i] > Eprev + MONOTONE_TOL * fabs(Eprev))
        monotone = 0;
      adrift = fmax(adrift, fabs(A[i] / in->A0 - 1));
      vdrift = fmax(vdrift, fabs(V[i] / Vt[i] - 1));
      dtmax = fmax(dtmax, dt[i]);
      iters += col[6][i], hes += col[7][i], retries += col[8][i];
    }
    printf("file = %s\n", path);
    printf("format_version = %d\nversion = %s\nstatus = %s\nbackend = %s\n", in->format_version,
           in->version, in->status, in->backend);
    printf("nodes = %d\ntriangles = %d\nsnapshots = %d\nreferences = %d\nsteps = %ld\n", in->n,
           in->ntri, ves_io_snapshots(io), ves_io_references(io), R);
    const int S = ves_io_snapshots(io); /* full remeshings: the last snapshot's node count */
    printf("remeshings = %d\nnodes_final = %d\n", ves_io_remeshes(io),
           S > 0 ? ves_io_snapshot_nodes(io, S - 1) : in->n);
    printf("t_final = %.12g\nt_end = %.12g\n", R ? t[R - 1] : 0.0, cfg.t_end);
    printf("energy_initial = %.12g\nenergy_final = %.12g\n", in->E0, R ? E[R - 1] : in->E0);
    printf("energy_monotone = %s\n", monotone ? "yes" : "no");
    printf("area_drift_max = %.6e\nvolume_drift_max = %.6e\n", adrift, vdrift);
    printf("reduced_volume_initial = %.12g\nreduced_volume_final = %.12g\n",
           reduced_volume(in->A0, in->V0),
           R ? reduced_volume(A[R - 1], V[R - 1]) : reduced_volume(in->A0, in->V0));
    printf("dt_first = %.6g\ndt_largest = %.6g\n", R ? dt[0] : 0.0, dtmax);
    printf("retries = %.0f\nreconnections = %.0f\n", retries, R ? col[9][R - 1] : 0.0);
    printf("newton_iterations = %.0f\nhessian_evaluations = %.0f\n", iters, hes);
    printf("wall_seconds = %.3f\nsetup_seconds = %.3f\n", R ? col[10][R - 1] : 0.0,
           in->setup_seconds);
    interface_lines(io);
    printf("source = %s\n", in->source);
    for (int i = 0; i < ves_config_count(); i++) {
      ves_config_entry e;
      ves_config_entry_get(&cfg, i, &e);
      printf("%s.%s = ", e.section, e.key);
      char num[32];
      ves_config_format_real(e.real, num, sizeof num);
      if (e.type == VES_KEY_REAL)
        printf("%s\n", num);
      else if (e.type == VES_KEY_INT)
        printf("%d\n", e.integer);
      else
        printf("%s\n", e.text);
    }
  }
  for (int c = 0; c < NC; c++) free(col[c]);
  ves_io_close(&io);
  return rc;
}

/* --------------------------------------------------------------------------
 * plot */

static void usage_plot(FILE *f) {
  fprintf(f,
          "usage: vesica plot FILE.h5 [--outdir DIR] [--times T1,T2,...] [--force]\n"
          "Writes three PNG figures (gnuplot, pngcairo) named after FILE:\n"
          "  FILE_energy.png       E* and dt* against t* on a log time axis (paper Fig. 4)\n"
          "  FILE_snapshots.png    the nodes at chosen times, mirrored across the axis,\n"
          "                        coloured by phi (paper Figs. 3, 5)\n"
          "  FILE_constraints.png  |A/A0 - 1|, |V/V_target - 1| and V/V0 against t*\n"
          "--outdir DIR    where (default: the folder of FILE.h5; created if missing)\n"
          "--times LIST    the snapshots nearest to these times t* (at most %d; default: the\n"
          "                first, the last and two between them on a log time scale)\n"
          "--force         overwrite existing figures (without it they are refused, exit 2)\n"
          "Exit 0 ok, 2 bad input, 3 when gnuplot fails or a figure cannot be written.\n",
          VES_PLOT_MAXTIMES);
}

/* mkdir -p: dir and every missing folder above it (0 ok, else -1, errno). */
static int mkdir_p(const char *dir) {
  char d[PATH_MAX];
  if (snprintf(d, sizeof d, "%s", dir) >= (int)sizeof d) return errno = ENAMETOOLONG, -1;
  for (char *c = d + 1; *c; c++)
    if (*c == '/') {
      *c = 0;
      if (mkdir(d, 0777) != 0 && errno != EEXIST) return -1;
      *c = '/';
    }
  return mkdir(d, 0777) != 0 && errno != EEXIST ? -1 : 0;
}

/* "t1,t2,..." into p->times. 0 ok, else 2 (message printed). */
static int parse_times(const char *s, ves_plot_params *p) {
  p->ntimes = 0;
  while (*s) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || errno || !isfinite(v) || v < 0 || (*end && *end != ',') ||
        p->ntimes == VES_PLOT_MAXTIMES) {
      fprintf(stderr,
              "vesica plot: --times '%s': expected up to %d times t* >= 0, "
              "comma-separated\n",
              s, VES_PLOT_MAXTIMES);
      return 2;
    }
    p->times[p->ntimes++] = v;
    s = *end ? end + 1 : end;
  }
  if (!p->ntimes) {
    fprintf(stderr, "vesica plot: --times: no time given\n");
    return 2;
  }
  return 0;
}

static int cmd_plot(int argc, char **argv) {
  const char *path = NULL, *outdir = NULL;
  int force = 0;
  ves_plot_params p;
  memset(&p, 0, sizeof p);
  for (int i = 0; i < argc; i++) {
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      usage_plot(stdout);
      return 0;
    } else if (!strcmp(argv[i], "--force")) {
      force = 1;
    } else if (!strcmp(argv[i], "--outdir") || !strcmp(argv[i], "--times")) {
      if (i + 1 >= argc) {
        fprintf(stderr, "vesica plot: %s needs a value\n", argv[i]);
        return 2;
      }
      if (!strcmp(argv[i], "--outdir"))
        outdir = argv[++i];
      else if (parse_times(argv[++i], &p))
        return 2;
    } else if (argv[i][0] == '-') {
      fprintf(stderr, "vesica plot: unknown option '%s' (see vesica plot --help)\n", argv[i]);
      return 2;
    } else if (path) {
      fprintf(stderr, "vesica plot: more than one file ('%s')\n", argv[i]);
      return 2;
    } else {
      path = argv[i];
    }
  }
  if (!path) {
    usage_plot(stderr);
    return 2;
  }
  char err[1024] = "", dir[PATH_MAX], stem[PATH_MAX];
  const char *slash = strrchr(path, '/'), *base = slash ? slash + 1 : path;
  size_t l = strlen(base);
  if (l > 3 && !strcmp(base + l - 3, ".h5")) l -= 3;
  snprintf(stem, sizeof stem, "%.*s", (int)l, base);
  if (outdir)
    snprintf(dir, sizeof dir, "%s", outdir);
  else if (slash)
    snprintf(dir, sizeof dir, "%.*s", slash == path ? 1 : (int)(slash - path), path);
  else
    snprintf(dir, sizeof dir, ".");
  ves_io *io = NULL;
  if (ves_io_open(path, 0, &io, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica plot: %s\n", err);
    return 2;
  }
  struct stat sb;
  if (stat(dir, &sb) != 0 && mkdir_p(dir) != 0) {
    fprintf(stderr, "vesica plot: --outdir %s: cannot create: %s\n", dir, strerror(errno));
    ves_io_close(&io);
    return 2;
  }
  if (stat(dir, &sb) != 0 || !S_ISDIR(sb.st_mode) || access(dir, W_OK) != 0) {
    fprintf(stderr, "vesica plot: --outdir %s: not a writable folder\n", dir);
    ves_io_close(&io);
    return 2;
  }
  for (int k = 0; k < VES_PLOT_NFIG; k++) {
    char png[2 * PATH_MAX + 64];
    snprintf(png, sizeof png, "%s/%s_%s.png", dir, stem, ves_plot_figures[k]);
    const char *in[] = {path};
    if (check_new("plot", "figure", png, force, in, 1, NULL)) {
      ves_io_close(&io);
      return 2;
    }
  }
  p.outdir = dir, p.stem = stem;
  ves_status st = ves_plot_write(io, &p, err, sizeof err);
  ves_io_close(&io);
  if (st != VES_OK) {
    fprintf(stderr, "vesica plot: %s: %s\n", path, err);
    return st == VES_ERR_ARG ? 2 : 3;
  }
  for (int k = 0; k < VES_PLOT_NFIG; k++) printf("%s/%s_%s.png\n", dir, stem, ves_plot_figures[k]);
  return 0;
}

/* --------------------------------------------------------------------------
 * spectrum */

static void usage_spectrum(FILE *f) {
  fprintf(f,
          "usage: vesica spectrum FILE.h5 [--snapshot K] [--above MU] [--modes M] [--lanczos N]\n"
          "                       [--vectors F [--force]]\n"
          "The linearized flow at a stored state: K dy/dt = -A (y - y_s) on the tangent space\n"
          "of the held constraints, A = Hess E + sigma_A Hess A + sigma_V Hess V with sigma\n"
          "the flow's constraint forces at the state. Along an eigenvector (A v = mu K v) a\n"
          "perturbation decays as exp(-mu t*): mu < 0 is an unstable direction (growth rate\n"
          "-mu; a state near a saddle of E lingers ~ 1/|mu| per e-fold), mu ~ 0 a neutral one\n"
          "(the vesicle translated in the box). Forward Euler is stable for dt* <= 2/mu_max.\n"
          "  --snapshot K  the snapshot (0-based; default the last; negative counts from it)\n"
          "  --above MU    the eigenvalues just above MU (1/t*, default -1; shift and invert,\n"
          "                converges fastest for MU just below the wanted ones); 'below' counts\n"
          "                those under MU exactly (the factorization's inertia)\n"
          "  --modes M     how many (default 6)      --lanczos N  Lanczos steps (default 80)\n"
          "  --vectors F   write the modes to the text file F: one row a node (a, its material\n"
          "                position r z, phi, h), then per mode the coefficients' components\n"
          "                u_r u_z and the motion they give at the node du_r du_z (an\n"
          "                existing F is refused unless --force; F is written whole or not\n"
          "                at all)\n"
          "Prints key = value lines: file, snapshot, step, t, energy (E*), reconnections, nodes,\n"
          "sigma_A, sigma_V, dissipation (-dE*/dt* of the flow: ydot^T K ydot),\n"
          "ydot_max (largest nodal speed, R0/t*), mu_max, mu_max_residual, fe_dt_limit,\n"
          "above, below, mu_1..mu_M with mu_i_error (Ritz bounds) and where each mode lives:\n"
          "mu_i_peak_r, mu_i_peak_z, mu_i_peak_phi (the material position and phi of the node\n"
          "with the largest coefficient |u_a|), mu_i_band (share of sum |u_a|^2 on nodes with\n"
          "|phi| < 0.9), mu_i_axis (share on nodes within 2 h_a of the axis), mu_i_material\n"
          "(|du| / |u| over the nodes: ~1 for a smooth motion, << 1 for coefficients that\n"
          "barely move the material), mu_i_from_E, mu_i_from_A, mu_i_from_V (mu's parts:\n"
          "v^T Hess E v, sigma_A v^T Hess A v, sigma_V v^T Hess V v, v K-normalized),\n"
          "mu_i_drift (the K-cosine of the mode with the coefficients' drift d = y^a - y(X_a)),\n"
          "drift_K_norm (sqrt(d^T K d)), drift_in_modes (sum of the squared cosines: the share\n"
          "of d in the modes found), seconds.\n"
          "Costs two factorizations and 2N solves of the step's KKT matrix (the setup and,\n"
          "after resets, the reference are rebuilt first, as a restart does).\n");
}

/* Parse a long in [lo, hi] for option opt; 0 ok, 2 with a message. */
static int parse_long(const char *cmd, const char *opt, const char *v, long lo, long hi,
                      long *out) {
  char *end = NULL;
  errno = 0;
  long x = strtol(v, &end, 10);
  if (errno || end == v || *end || x < lo || x > hi) {
    fprintf(stderr, "vesica %s: %s '%s': not an integer in [%ld, %ld]\n", cmd, opt, v, lo, hi);
    return 2;
  }
  *out = x;
  return 0;
}

/* The text file of --vectors (vesica spectrum --help) from the analysis sp
 * of the state of r: written to vpath.part, then renamed, so nothing
 * partial stays behind. 0, or -1 with errno the cause. */
static int write_modes(const run_ctx *r, const ves_spectrum *sp, const char *vpath) {
  const ves_nodes *nd = ves_model_nodes(ves_sim_model(r->sim));
  const int n = sp->n;
  char part[PATH_MAX + 8];
  snprintf(part, sizeof part, "%s.part", vpath);
  errno = 0;
  FILE *f = fopen(part, "w");
  if (!f) return -1;
  fprintf(f, "# vesica spectrum: the modes of %s, one row a node\n# a r z phi h", r->label);
  for (int j = 0; j < sp->nmodes; j++)
    fprintf(f, " u%d_r u%d_z du%d_r du%d_z", j + 1, j + 1, j + 1, j + 1);
  fprintf(f, "\n# (r z: material position of the node, R0; u: the mode's coefficients,\n"
             "# K-normalized; du: the motion they give at the node)\n");
  for (int a = 0; a < n; a++) {
    fprintf(f, "%d %.9g %.9g %.6g %.6g", a, sp->x[2 * a], sp->x[2 * a + 1], sp->phi[a], nd->h[a]);
    for (int j = 0; j < sp->nmodes; j++) {
      const double *uj = sp->u + 2 * (size_t)n * j, *dj = sp->du + 2 * (size_t)n * j;
      fprintf(f, " %.6e %.6e %.6e %.6e", uj[2 * a], uj[2 * a + 1], dj[2 * a], dj[2 * a + 1]);
    }
    fputc('\n', f);
  }
  errno = 0;
  int bad = fflush(f) != 0 || ferror(f), e = errno; /* the first failure's cause */
  if (fclose(f) != 0) bad = 1, e = e ? e : errno;
  if (!bad && rename(part, vpath) != 0) bad = 1, e = errno;
  if (!bad) return 0;
  remove(part);
  errno = e ? e : EIO;
  return -1;
}

/* The analysis sp of snapshot k (its state si) as key = value lines. */
static void print_spectrum(const char *path, long k, const ves_io_snapinfo *si, const run_ctx *r,
                           const ves_spectrum *sp, double above) {
  const double kk = r->cfg.k;
  printf("file = %s\nsnapshot = %ld\nstep = %ld\nt = %.9g\nenergy = %.9f\n", path, k,
         si->state.nstep, si->state.t, si->state.E / kk);
  printf("reconnections = %d\nnodes = %d\n", si->reconnections, sp->n);
  printf("sigma_A = %.9e\nsigma_V = %.9e\n", sp->sigma[0] / kk, sp->sigma[1] / kk);
  printf("dissipation = %.9e\nydot_max = %.6e\n", sp->dissipation / kk, sp->ydot_max);
  printf("mu_max = %.9e\nmu_max_residual = %.2e\nfe_dt_limit = %.6e\n", sp->mu_max,
         sp->mu_max_resid, 2 / sp->mu_max);
  printf("above = %.9g\nbelow = %d\n", above, sp->below);
  for (long j = 0; j < sp->nmodes; j++) {
    const ves_spectrum_mode *q = sp->mode + j;
    printf("mu_%ld = %.9e\nmu_%ld_error = %.2e\n", j + 1, sp->mu[j], j + 1, sp->mu_err[j]);
    printf("mu_%ld_peak_r = %.4f\nmu_%ld_peak_z = %.4f\nmu_%ld_peak_phi = %.3f\n", j + 1,
           q->peak[0], j + 1, q->peak[1], j + 1, q->peak_phi);
    printf("mu_%ld_band = %.3f\nmu_%ld_axis = %.3f\nmu_%ld_material = %.3e\n", j + 1, q->band,
           j + 1, q->axis, j + 1, q->material);
    printf("mu_%ld_from_E = %.6e\nmu_%ld_from_A = %.6e\nmu_%ld_from_V = %.6e\n", j + 1,
           q->from[0], j + 1, q->from[1], j + 1, q->from[2]);
    printf("mu_%ld_drift = %.3e\n", j + 1, q->drift);
  }
  printf("drift_K_norm = %.6e\ndrift_in_modes = %.3e\n", sp->drift_K_norm, sp->drift_in_modes);
}

static int cmd_spectrum(int argc, char **argv) {
  const char *path = NULL, *vpath = NULL;
  long snap = -1, modes = 6, lanczos = 80;
  double above = -1;
  int force = 0;
  for (int i = 0; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      usage_spectrum(stdout);
      return 0;
    } else if (!strcmp(a, "--force")) {
      force = 1;
    } else if (!strcmp(a, "--snapshot") || !strcmp(a, "--above") || !strcmp(a, "--modes") ||
               !strcmp(a, "--lanczos") || !strcmp(a, "--vectors")) {
      if (i + 1 >= argc) {
        fprintf(stderr, "vesica spectrum: %s needs a value\n", a);
        return 2;
      }
      const char *v = argv[++i];
      int rc = 0;
      if (!strcmp(a, "--snapshot"))
        rc = parse_long("spectrum", a, v, -1000000, 1000000, &snap);
      else if (!strcmp(a, "--modes"))
        rc = parse_long("spectrum", a, v, 1, 100, &modes);
      else if (!strcmp(a, "--lanczos"))
        rc = parse_long("spectrum", a, v, 2, 2000, &lanczos);
      else if (!strcmp(a, "--vectors"))
        vpath = v;
      else {
        char *end = NULL;
        above = strtod(v, &end);
        if (end == v || *end || !isfinite(above)) {
          fprintf(stderr, "vesica spectrum: --above '%s': not a finite number\n", v);
          rc = 2;
        }
      }
      if (rc) return rc;
    } else if (a[0] == '-' && a[1] && !isdigit((unsigned char)a[1])) {
      fprintf(stderr, "vesica spectrum: unknown option '%s' (see vesica spectrum --help)\n", a);
      return 2;
    } else if (path) {
      fprintf(stderr, "vesica spectrum: more than one file ('%s')\n", a);
      return 2;
    } else {
      path = a;
    }
  }
  if (!path) {
    usage_spectrum(stderr);
    return 2;
  }
  if (modes > lanczos) {
    fprintf(stderr, "vesica spectrum: --modes %ld is more than --lanczos %ld\n", modes, lanczos);
    return 2;
  }
  if (vpath) {
    const char *in[] = {path};
    if (check_writable("spectrum", "--vectors", vpath) ||
        check_new("spectrum", "--vectors", vpath, force, in, 1, NULL))
      return 2;
    if (!strcmp(vpath, path)) {
      fprintf(stderr, "vesica spectrum: --vectors %s: is the input file\n", vpath);
      return 2;
    }
  }
  run_ctx r;
  memset(&r, 0, sizeof r);
  r.label = path, r.quiet = 1;
  char err[1024] = "", pre[PATH_MAX + 32];
  snprintf(pre, sizeof pre, "vesica spectrum: %s", path);
  int rc = 2;
  if (ves_io_open(path, 0, &r.io, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica spectrum: %s\n", err);
    goto done;
  }
  const ves_io_info *in = ves_io_get_info(r.io);
  const int S = ves_io_snapshots(r.io);
  const long k = snap < 0 ? S + snap : snap;
  if (k < 0 || k >= S) {
    fprintf(stderr, "%s: --snapshot %ld: the file holds %d snapshot(s)\n", pre, snap, S);
    goto done;
  }
  if (ves_config_load_text(in->problem, in->source, &r.cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "%s: the stored problem: %s\n", pre, err);
    goto done;
  }
  const double t0 = ves_wall_seconds();
  ves_io_snapinfo si;
  if ((rc = rebuild_at(&r, pre, (int)k, &si))) goto done;
  const ves_spectrum_params sprm = {.hold_area = r.cfg.area,
                                    .hold_volume = r.cfg.volume,
                                    .above = above,
                                    .modes = (int)modes,
                                    .lanczos = (int)lanczos};
  ves_spectrum *sp = NULL;
  ves_status st = ves_spectrum_create(r.sim, &sprm, &sp);
  if (st != VES_OK) {
    fprintf(stderr, "%s: snapshot %ld: the spectrum failed: %s%s\n", pre, k, ves_status_str(st),
            st == VES_ERR_SINGULAR ? " (--above is an eigenvalue? move it a little)" : "");
    rc = 3;
  } else if (vpath && write_modes(&r, sp, vpath) != 0) {
    fprintf(stderr, "vesica spectrum: --vectors %s: cannot write: %s\n", vpath, strerror(errno));
    rc = 2;
  } else {
    print_spectrum(path, k, &si, &r, sp, above);
    printf("seconds = %.1f\n", ves_wall_seconds() - t0);
    if (sp->below > 0)
      fprintf(stderr,
              "vesica spectrum: %d eigenvalue(s) lie below --above %g: lower it to see them\n",
              sp->below, above);
    rc = 0;
  }
  ves_spectrum_destroy(&sp);
done:
  run_free(&r);
  return rc;
}

/* --------------------------------------------------------------------------
 * study */

static void usage_study(FILE *f) {
  fprintf(f,
          "usage: vesica study STUDY.ini [--jobs N] [--out DIR] [--retry-failed] [--max-cells N]\n"
          "       vesica study STUDY.ini [--out DIR] --emit slurm | --cell K | --collect\n"
          "Runs the grid of a study file (problems/README.md, 'Study files'): every cell is its\n"
          "own 'vesica run' of the base problem with the cell's --set overrides, writing\n"
          "DIR/cells/NAME.h5 and its log; then DIR/study.csv (one row per cell: the swept\n"
          "values, status and reason, steps, iterations, evaluations, seconds, memory, E*)\n"
          "and, with a time.dt_initial axis, DIR/study_frontier.png and DIR/study_cost.png.\n"
          "A rerun skips the cells that ended (failed ones too: --retry-failed reruns them).\n"
          "  --jobs N        cells at a time (default: the number of cores)\n"
          "  --out DIR       the study folder (default: the study file's name, here)\n"
          "  --max-cells N   allow a grid of up to N cells (default %d)\n"
          "  --emit slurm    write DIR/study.sbatch: a job array, one cell per task (sbatch it,\n"
          "                  then --collect)\n"
          "  --cell K        run cell K (0-based) only, as an array task does\n"
          "  --collect       write the table and figures from the cells that have ended\n"
          "  --quiet         no progress line\n"
          "Exit 0 when every cell ran (whatever its outcome: see the table), 2 on bad input\n"
          "(nothing run), 3 when the folder or table cannot be written, 130/143 when stopped\n"
          "by SIGINT/SIGTERM (running cells are stopped and rerun next time).\n",
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
  ves_status st = ves_study_plot(s, dir, err, sizeof err);
  if (st == VES_OK)
    printf("%s/study_frontier.png\n%s/study_cost.png\n", dir, dir);
  else if (!quiet || st != VES_STEP_REJECTED)
    fprintf(stderr, "vesica study: figures: %s\n", err);
  return st < 0 ? 3 : 0;
}

static int cmd_study(int argc, char **argv) {
  const char *path = NULL, *out = NULL, *emit = NULL;
  long jobs = sysconf(_SC_NPROCESSORS_ONLN), max_cells = VES_STUDY_MAX_CELLS, cell = -1;
  int retry = 0, collect = 0, quiet = 0, rc;
  for (int i = 0; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      usage_study(stdout);
      return 0;
    } else if (!strcmp(a, "--jobs") || !strcmp(a, "--out") || !strcmp(a, "--max-cells") ||
               !strcmp(a, "--cell") || !strcmp(a, "--emit")) {
      if (i + 1 >= argc) {
        fprintf(stderr, "vesica study: %s needs a value (see vesica study --help)\n", a);
        return 2;
      }
      const char *v = argv[++i];
      if (!strcmp(a, "--out"))
        out = v;
      else if (!strcmp(a, "--emit"))
        emit = v;
      else if ((rc = parse_long("study", a, v, !strcmp(a, "--cell") ? 0 : 1,
                                !strcmp(a, "--jobs") ? 1024 : 1000000000L,
                                !strcmp(a, "--jobs")    ? &jobs
                                : !strcmp(a, "--cell") ? &cell
                                                       : &max_cells)))
        return rc;
    } else if (!strcmp(a, "--retry-failed")) {
      retry = 1;
    } else if (!strcmp(a, "--collect")) {
      collect = 1;
    } else if (!strcmp(a, "--quiet")) {
      quiet = 1;
    } else if (a[0] == '-') {
      fprintf(stderr, "vesica study: unknown option '%s' (see vesica study --help)\n", a);
      return 2;
    } else if (path) {
      fprintf(stderr, "vesica study: more than one study file ('%s')\n", a);
      return 2;
    } else {
      path = a;
    }
  }
  if (!path) {
    usage_study(stderr);
    return 2;
  }
  if (emit && strcmp(emit, "slurm")) {
    fprintf(stderr, "vesica study: --emit '%s': only slurm\n", emit);
    return 2;
  }
  if ((emit != NULL) + collect + (cell >= 0) > 1) {
    fprintf(stderr, "vesica study: --emit, --cell and --collect exclude each other\n");
    return 2;
  }
  char err[1024] = "", dir[PATH_MAX], self[PATH_MAX];
  ves_study *s = NULL;
  ves_status st = ves_study_load(path, max_cells, &s, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr, "vesica study: %s\n", err);
    return 2;
  }
  if (cell >= s->ncells) {
    fprintf(stderr, "vesica study: --cell %ld: the grid has %ld cells (0 to %ld)\n", cell,
            s->ncells, s->ncells - 1);
    ves_study_destroy(&s);
    return 2;
  }
  if (out) {
    snprintf(dir, sizeof dir, "%s", out);
  } else { /* the study file's name without .ini, here */
    const char *base = strrchr(path, '/') ? strrchr(path, '/') + 1 : path;
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
  rc = 0;
  if (collect) {
    struct stat sb;
    if (stat(dir, &sb) != 0 || !S_ISDIR(sb.st_mode)) {
      fprintf(stderr, "vesica study: --collect: %s: no such folder (--out DIR?)\n", dir);
      rc = 2;
    } else {
      rc = study_collect(s, dir, quiet);
    }
  } else if (emit) {
    struct stat sb;
    if ((stat(dir, &sb) != 0 && mkdir(dir, 0777) != 0) ||
        ves_study_write_sbatch(s, self, dir, err, sizeof err) != VES_OK) {
      fprintf(stderr, "vesica study: %s: %s\n", dir, err[0] ? err : strerror(errno));
      rc = 3;
    } else {
      printf("%s/study.sbatch: %ld array tasks; sbatch it, then vesica study %s --out %s "
             "--collect\n",
             dir, s->ncells, path, dir);
    }
  } else {
    study_view view = {.tty = isatty(2), .quiet = quiet || cell >= 0, .s = s};
    ves_study_run_opts o = {.program = self,
                            .dir = dir,
                            .jobs = cell >= 0 ? 1 : (int)jobs,
                            .retry_failed = retry,
                            .only = cell,
                            .grace = 10,
                            .stop = &study_stop,
                            .progress = study_progress,
                            .ctx = &view};
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_study_signal;
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    st = ves_study_run(s, &o, err, sizeof err);
    if (view.tty && !view.quiet) fputc('\n', stderr);
    if (st == VES_STEP_REJECTED) {
      fprintf(stderr,
              "vesica study: stopped by signal %d; the cells that ended are kept, rerun to "
              "continue\n",
              (int)study_stop);
      rc = 128 + (int)study_stop;
    } else if (st != VES_OK) {
      fprintf(stderr, "vesica study: %s\n", err[0] ? err : ves_status_str(st));
      rc = 3;
    } else if (cell < 0) {
      rc = study_collect(s, dir, quiet);
    }
  }
  ves_study_destroy(&s);
  return rc;
}

int main(int argc, char **argv) {
  ves_blas_core_fix(argv); /* returns unless OpenBLAS needs a restart */
  if (argc < 2) {
    usage(stderr);
    return 2;
  }
  char *help_argv[4] = {argv[0], NULL, "--help", NULL};
  if (!strcmp(argv[1], "help") && argc == 3) { /* vesica help CMD = vesica CMD --help */
    help_argv[1] = argv[2];
    argc = 3, argv = help_argv;
  } else if (!strcmp(argv[1], "help") && argc > 3) {
    fprintf(stderr, "vesica help: one command at most (see vesica help)\n");
    return 2;
  }
  if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
    usage(stdout);
    return 0;
  }
  if (!strcmp(argv[1], "--version")) {
    printf("vesica %s\n", VES_VERSION);
    return 0;
  }
  if (!strcmp(argv[1], "check")) return cmd_check(argc - 2, argv + 2);
  if (!strcmp(argv[1], "run")) return cmd_run(argc - 2, argv + 2);
  if (!strcmp(argv[1], "info")) return cmd_info(argc - 2, argv + 2);
  if (!strcmp(argv[1], "plot")) return cmd_plot(argc - 2, argv + 2);
  if (!strcmp(argv[1], "spectrum")) return cmd_spectrum(argc - 2, argv + 2);
  if (!strcmp(argv[1], "study")) return cmd_study(argc - 2, argv + 2);
  if (!strcmp(argv[1], "keys")) {
    if (argc > 2 && (!strcmp(argv[2], "--help") || !strcmp(argv[2], "-h"))) {
      printf("usage: vesica keys [--study]\nPrints every problem-file key (--study: every "
             "study-file key) as a Markdown\ntable: section, key, type, default, allowed values "
             "and meaning (as in\nproblems/README.md).\n");
      return 0;
    }
    if (argc == 3 && !strcmp(argv[2], "--study")) {
      ves_study_print_keys(stdout);
      return 0;
    }
    if (argc > 2) {
      fprintf(stderr, "vesica keys: takes no arguments ('%s')\n", argv[2]);
      return 2;
    }
    ves_config_print_keys(stdout);
    return 0;
  }
  fprintf(stderr, "vesica: unknown command '%s' (see vesica --help)\n", argv[1]);
  return 2;
}
