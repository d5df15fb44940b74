/* vesica — the command-line program: parses arguments, drives the library,
 * prints and exits (the library itself never prints or exits).
 * Exit codes: 0 ok, 2 bad input (usage, configuration, files), 3 numerical
 * failure. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <time.h>
#include <unistd.h>

#include "ves/backend.h"
#include "ves/config.h"
#include "ves/integrate.h"
#include "ves/setup.h"
#include "clock_impl.h"

#define VES_VERSION "0.1.0"
#define MAX_SET 64

static void usage(FILE *f) {
  fprintf(f,
          "usage: vesica <command> [options]\n"
          "commands:\n"
          "  check CONFIG.ini [--set section.key=value]... [--phi0 l2|sampled]\n"
          "                     build the initial state and print its derived quantities\n"
          "  run CONFIG.ini [--backend ipopt|nlopt|newton|euler] [--set section.key=value]...\n"
          "                [--series FILE.tsv] [--quiet]\n"
          "                     integrate in time; a progress line on stderr\n"
          "  keys               print every problem-file key with its default and range\n"
          "  --version          print the version\n"
          "  --help             this text (also: vesica COMMAND --help)\n");
}

static void usage_check(FILE *f) {
  fprintf(f, "usage: vesica check CONFIG.ini [--set section.key=value]... [--phi0 l2|sampled]\n"
             "Builds shape, adapted nodes, quadrature, LME tables and the least-squares phase\n"
             "field, then prints one 'key = value' per line: nodes, ghosts, quadrature_points,\n"
             "neighbours_mean, energy (E/k), energy_sharp, area_ratio (A over the sharp area),\n"
             "volume_ratio, reduced_volume, epsilon, setup_seconds, ...\n"
             "--phi0 sampled uses phi0(X_a) as coefficients (wrong on purpose: for comparison).\n");
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

static int cmd_check(int argc, char **argv) {
  const char *path = NULL, *set[MAX_SET] = {0};
  int nset = 0;
  ves_phi0_method method = VES_PHI0_L2;
  for (int i = 0; i < argc; i++) {
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      usage_check(stdout);
      return 0;
    } else if (!strcmp(argv[i], "--set")) {
      if (i + 1 >= argc || nset == MAX_SET) {
        fprintf(stderr, "vesica check: --set needs section.key=value\n");
        return 2;
      }
      set[nset++] = argv[++i];
    } else if (!strcmp(argv[i], "--phi0")) {
      if (i + 1 >= argc || (strcmp(argv[i + 1], "l2") && strcmp(argv[i + 1], "sampled"))) {
        fprintf(stderr, "vesica check: --phi0 takes l2 or sampled\n");
        return 2;
      }
      method = !strcmp(argv[++i], "sampled") ? VES_PHI0_SAMPLED : VES_PHI0_L2;
    } else if (argv[i][0] == '-') {
      fprintf(stderr, "vesica check: unknown option '%s'\n", argv[i]);
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
  int rc = load_problem("check", path, usage_check, nset, set, &cfg);
  if (rc) return rc;
  ves_setup *s = NULL;
  ves_status st = ves_setup_create(&cfg, method, &s, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr, "vesica: %s: %s\n", path, err);
    return st == VES_ERR_CONFIG || st == VES_ERR_ARG ? 2 : 3;
  }
  double *y = malloc(2 * (size_t)s->nodes->n * sizeof *y), E = 0, A = 0, V = 0;
  if (!y) {
    fprintf(stderr, "vesica: out of memory\n");
    ves_setup_destroy(&s);
    return 3;
  }
  ves_model_reference(s->model, y);
  st = ves_model_eval(s->model, y, VES_F_E | VES_F_A | VES_F_V, &E, &A, &V, NULL, NULL, NULL);
  free(y);
  if (st != VES_OK) {
    fprintf(stderr, "vesica: %s: model evaluation: %s\n", path, ves_status_str(st));
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
  printf("projection_refinements = %d\nprojection_residual = %.2e\n", s->proj_refinements, s->proj_residual);
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

static void usage_run(FILE *f) {
  fprintf(f,
          "usage: vesica run CONFIG.ini [--backend ipopt|nlopt|newton|euler]\n"
          "                 [--set section.key=value]... [--series FILE.tsv] [--quiet]\n"
          "Builds the initial state as 'check' does and integrates to [time] t_end with the\n"
          "chosen backend (default [solver] backend). One progress line on stderr (step, t*,\n"
          "dt*, E*, iterations, ETA), updated in place on a terminal; --quiet: none.\n"
          "--series writes one tab-separated line per accepted step: step t dt E A/A0-1\n"
          "V/Vtarget-1 lambda_A lambda_V iterations f_evals g_evals h_evals seconds retries.\n"
          "Exit 0 at t_end, 2 on bad input, 3 when a step fails down to dt_min (the last\n"
          "good state is the last line of the series).\n");
}

static int cmd_run(int argc, char **argv) {
  const char *path = NULL, *set[MAX_SET] = {0}, *backend = NULL, *series = NULL;
  int nset = 0, quiet = 0;
  for (int i = 0; i < argc; i++) {
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      usage_run(stdout);
      return 0;
    } else if (!strcmp(argv[i], "--set") && i + 1 < argc && nset < MAX_SET) {
      set[nset++] = argv[++i];
    } else if (!strcmp(argv[i], "--backend") && i + 1 < argc) {
      backend = argv[++i];
    } else if (!strcmp(argv[i], "--series") && i + 1 < argc) {
      series = argv[++i];
    } else if (!strcmp(argv[i], "--quiet")) {
      quiet = 1;
    } else if (argv[i][0] == '-') {
      fprintf(stderr, "vesica run: unknown or incomplete option '%s' (see vesica run --help)\n",
              argv[i]);
      return 2;
    } else if (!path) {
      path = argv[i];
    } else {
      fprintf(stderr, "vesica run: more than one configuration file ('%s')\n", argv[i]);
      return 2;
    }
  }
  ves_config cfg;
  char err[1024] = "";
  int rc = load_problem("run", path, usage_run, nset, set, &cfg);
  if (rc) return rc;
  const ves_backend_type *bk = ves_backend_find(backend ? backend : cfg.backend);
  if (!bk) {
    fprintf(stderr, "vesica run: --backend '%s': not one of ipopt, nlopt, newton, euler\n",
            backend ? backend : cfg.backend);
    return 2;
  }
  FILE *out = NULL;
  if (series && !(out = fopen(series, "w"))) {
    fprintf(stderr, "vesica run: --series %s: cannot open for writing\n", series);
    return 2;
  }
  ves_setup *s = NULL;
  ves_status st = ves_setup_create(&cfg, VES_PHI0_L2, &s, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr, "vesica: %s: %s\n", path, err);
    if (out) fclose(out), remove(series);
    return st == VES_ERR_CONFIG || st == VES_ERR_ARG ? 2 : 3;
  }
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  bo.tol = cfg.tol, bo.ctol = cfg.ctol, bo.max_iter = cfg.max_iter;
  bo.freeze_hessian = cfg.freeze_hessian;
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  ip.t_end = cfg.t_end, ip.dt_initial = cfg.dt_initial, ip.dt_max = cfg.dt_max;
  ip.dt_min = cfg.dt_min, ip.adaptive = cfg.adaptive, ip.dE_target = cfg.dE_target;
  ip.growth_max = cfg.growth_max, ip.iter_target = cfg.iter_target;
  ip.hold_area = cfg.area, ip.hold_volume = cfg.volume;
  ip.volume_rate = cfg.volume_rate, ip.volume_final = cfg.volume_final;
  ip.c0_time = cfg.c0_time, ip.c0_after = cfg.c0_after;
  ves_sim *sim = NULL;
  if ((st = ves_sim_create(s->model, bk, &bo, &ip, &sim)) != VES_OK) {
    fprintf(stderr, "vesica: %s: cannot start the time loop: %s\n", path, ves_status_str(st));
    ves_setup_destroy(&s);
    if (out) fclose(out);
    return st == VES_ERR_ARG ? 2 : 3;
  }
  double E0, A0, V0, t0 = ves_wall_seconds();
  ves_sim_initial(sim, &E0, &A0, &V0);
  if (out)
    fprintf(out, "# vesica %s run %s backend %s nodes %d E0 %.12g A0 %.12g V0 %.12g\n"
                 "# step\tt\tdt\tE\tA/A0-1\tV/Vt-1\tlambda_A\tlambda_V\titer\tf\tg\th\t"
                 "seconds\tretries\n",
            VES_VERSION, path, bk->name, s->nodes->n, E0, A0, V0);
  int tty = isatty(2), code = 0;
  ves_step_report rep;
  long iters = 0;
  while ((st = ves_sim_step(sim, &rep)) == VES_OK) {
    iters += rep.stats.iterations;
    if (out) {
      fprintf(out, "%ld\t%.9g\t%.6g\t%.12g\t%.3e\t%.3e\t%.9g\t%.9g\t%d\t%d\t%d\t%d\t%.3f\t%d\n",
              rep.step, rep.t, rep.dt, rep.E, rep.A / A0 - 1, rep.V / rep.V_target - 1,
              rep.lambda[0], rep.lambda[1], rep.stats.iterations, rep.stats.f_evals,
              rep.stats.g_evals, rep.stats.h_evals, rep.stats.seconds, rep.retries);
      fflush(out); /* a killed run keeps every completed step */
    }
    if (!quiet && (tty || rep.step % 10 == 0)) {
      double el = ves_wall_seconds() - t0, eta = rep.t > 0 ? el * (cfg.t_end - rep.t) / rep.t : 0;
      fprintf(stderr, "%sstep %ld  t* %.4g/%.4g  dt* %.3g  E* %.6f  iter %d  ETA %.0f s%s",
              tty ? "\r" : "", rep.step, rep.t, cfg.t_end, rep.dt, rep.E, rep.stats.iterations,
              eta, tty ? "   " : "\n");
    }
  }
  if (tty && !quiet) fputc('\n', stderr);
  if (st < 0) {
    fprintf(stderr, "vesica: %s: no acceptable step at t* = %.6g down to dt* = %g (%s); the last "
                    "good state is the last step written\n",
            path, ves_sim_time(sim), cfg.dt_min, ves_status_str(st));
    code = 3;
  } else if (!quiet) {
    fprintf(stderr, "vesica: t* = %.6g reached, %ld iterations in all, %.1f s\n", ves_sim_time(sim),
            iters, ves_wall_seconds() - t0);
  }
  if (out) fclose(out);
  ves_sim_destroy(&sim);
  ves_setup_destroy(&s);
  return code;
}

int main(int argc, char **argv) {
  if (argc < 2) {
    usage(stderr);
    return 2;
  }
  if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
    usage(stdout);
    return 0;
  }
  if (!strcmp(argv[1], "--version")) {
    printf("vesica %s\n", VES_VERSION);
    return 0;
  }
  if (!strcmp(argv[1], "check")) return cmd_check(argc - 2, argv + 2);
  if (!strcmp(argv[1], "run")) return cmd_run(argc - 2, argv + 2);
  if (!strcmp(argv[1], "keys")) {
    ves_config_print_keys(stdout);
    return 0;
  }
  fprintf(stderr, "vesica: unknown command '%s' (see vesica --help)\n", argv[1]);
  return 2;
}
