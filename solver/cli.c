/* vesica — the command-line program: parses arguments, drives the library,
 * prints and exits (the library itself never prints or exits).
 * Exit codes: 0 ok, 2 bad input (usage, configuration, files), 3 numerical
 * failure. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ves/config.h"
#include "ves/setup.h"

#define VES_VERSION "0.1.0"
#define MAX_SET 64

static void usage(FILE *f) {
  fprintf(f,
          "usage: vesica <command> [options]\n"
          "commands:\n"
          "  check CONFIG.ini [--set section.key=value]... [--phi0 l2|sampled]\n"
          "                     build the initial state and print its derived quantities\n"
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

static int cmd_check(int argc, char **argv) {
  const char *path = NULL, *set[MAX_SET];
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
  if (!path) {
    usage_check(stderr);
    return 2;
  }
  ves_config cfg;
  char err[1024] = "";
  if (ves_config_load(path, nset, set, &cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica: %s\n", err);
    return 2;
  }
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
  printf("projection_iterations = %d\n", s->cg_iterations);
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
  if (!strcmp(argv[1], "keys")) {
    ves_config_print_keys(stdout);
    return 0;
  }
  fprintf(stderr, "vesica: unknown command '%s' (see vesica --help)\n", argv[1]);
  return 2;
}
