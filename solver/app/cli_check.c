/* vesica check: the initial state of a problem and its derived quantities
 * (docs/manual.md; docs/design.md, "The program"). */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app/cli_impl.h"

static void usage_check(FILE *f) {
  fprintf(f, "usage: vesica check CONFIG.ini [--set section.key=value]... [--phi0 l2|sampled]\n"
             "                   [--print-config]\n"
             "Validates the problem file, builds shape, adapted nodes, quadrature, LME tables and\n"
             "the least-squares phase field (no time stepping), then prints one 'key = value'\n"
             "per line: nodes, ghosts, quadrature_points, neighbours_mean, energy (E/k),\n"
             "energy_sharp, area_ratio (A over the sharp area), volume_ratio, reduced_volume,\n"
             "epsilon, setup_seconds, ...\n"
             "--phi0 sampled uses phi0(X_a) as coefficients (wrong on purpose: for comparison).\n"
             "--print-config prints instead, without building anything, every key with its\n"
             "effective value (defaults filled, --set applied) as a problem file that check and\n"
             "run accept as it is.\n"
             "Exit 0 ok, 2 bad input (the message names file, key and reason), 3 numerical "
             "failure.\n");
}

int cmd_check(int argc, char **argv) {
  const char *path = NULL, *set[MAX_SET] = {0};
  int nset = 0, rc, print_config = 0;
  ves_phi0_method method = VES_PHI0_L2;
  for (int i = 0; i < argc; i++) {
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      usage_check(stdout);
      return 0;
    } else if (!strcmp(argv[i], "--set")) {
      if ((rc = cli_take_set("check", argc, argv, &i, &nset, set))) return rc;
    } else if (!strcmp(argv[i], "--print-config")) {
      print_config = 1;
    } else if (!strcmp(argv[i], "--phi0")) {
      if (i + 1 >= argc || (strcmp(argv[i + 1], "l2") && strcmp(argv[i + 1], "sampled"))) {
        fprintf(stderr, "vesica check: --phi0 takes l2 or sampled\n");
        return 2;
      }
      method = !strcmp(argv[++i], "sampled") ? VES_PHI0_SAMPLED : VES_PHI0_L2;
    } else if (cli_operand("check", "configuration file", argv[i][0] == '-', argv[i], &path)) {
      return 2;
    }
  }
  ves_config cfg;
  char err[1024] = "";
  if ((rc = cli_load_problem("check", path, usage_check, nset, set, &cfg))) return rc;
  if (print_config) { /* the effective problem: every key, as a problem file */
    char *text = NULL;
    if (ves_config_to_text(&cfg, &text) != VES_OK) {
      fprintf(stderr, "vesica check: out of memory\n");
      return 3;
    }
    fputs(text, stdout);
    free(text);
    return 0;
  }
  if ((rc = cli_setup_estimate("check", &cfg, 0))) return rc;
  ves_setup *s = NULL;
  ves_status st = ves_problem_setup_create(&cfg, method, &s, err, sizeof err);
  if (st != VES_OK) {
    cli_setup_error("check", path, err);
    return cli_exit_for(st);
  }
  double *y = malloc(2 * (size_t)s->nodes->n * sizeof *y), E = 0, A = 0, V = 0;
  if (!y) {
    fprintf(stderr, "vesica check: out of memory\n");
    ves_setup_destroy(&s);
    return 3;
  }
  ves_model_reference(s->model, y);
  ves_error_clear();
  st = ves_model_eval(s->model, y, VES_F_E | VES_F_A | VES_F_V, &E, &A, &V, NULL, NULL, NULL);
  free(y);
  if (st != VES_OK) {
    fprintf(stderr, "vesica check: %s: model evaluation: %s\n", path, cli_why(st));
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
