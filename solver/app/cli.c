/* vesica — the command-line program: parses the command, hands it to its
 * file (cli_<command>.c), prints and exits (the library itself never prints
 * or exits). Exit codes: 0 ok, 2 bad input (usage, configuration, files), 3
 * numerical failure (or a write error during a run), 130/143 stopped by
 * SIGINT/SIGTERM (the last state saved). User-facing behaviour:
 * docs/manual.md; docs/design.md, "The program". */

#include <stdio.h>
#include <string.h>

#include "app/cli_impl.h"
#include "app/study.h"
#include "app/blas_core_impl.h"

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
          "        [--print-config]\n"
          "                     build the initial state and print its derived quantities\n"
          "                     (--print-config: every key's effective value, a problem file)\n"
          "  info FILE.h5 [--series N]\n"
          "                     summary of a run, one 'key = value' per line (--series:\n"
          "                     its last N series rows)\n"
          "  plot FILE.h5 [--outdir DIR] [--times T1,T2,...] [--format png|pdf|svg] [--script S]\n"
          "       [--force]\n"
          "                     figures (PNG, PDF, SVG): energy and dt, snapshots, constraints,\n"
          "                     flow\n"
          "  spectrum FILE.h5 [--snapshot K] [--above MU] [--modes M] [--lanczos N]\n"
          "           [--vectors F]\n"
          "                     the linearized flow at a stored state: slow and unstable\n"
          "                     modes, forward Euler's stability limit\n"
          "  study STUDY.ini [--jobs N] [--out DIR] [--retry-failed] [--emit slurm]\n"
          "        [--cell K] [--collect]\n"
          "                     a grid of runs (robustness studies, sweeps): one table, figures\n"
          "  keys [--study | KEY]\n"
          "                     every problem-file key (or KEY's row) with default and range\n"
          "  --version          print the version\n"
          "  --help             this text (also: vesica COMMAND --help)\n"
          "  help [COMMAND]     this text, or the command's (as vesica COMMAND --help)\n"
          "exit codes: 0 ok, 2 bad input (nothing written), 3 numerical failure or an output\n"
          "that cannot be written (last good state saved), 130/143 a run stopped by\n"
          "SIGINT/SIGTERM after its current step (state saved; continue with --restart)\n");
}

static int command(int argc, char **argv) {
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
      printf("usage: vesica keys [--study | KEY]\nPrints every problem-file key (--study: every "
             "study-file key) as a Markdown\ntable: section, key, type, default, allowed values "
             "and meaning (as in\nproblems/README.md). KEY (section.key, or key for every "
             "section's key of that\nname): its rows alone, under the table's header; an "
             "unknown KEY exits 2 naming\nthe closest key.\n");
      return 0;
    }
    if (argc == 3 && !strcmp(argv[2], "--study")) {
      ves_study_print_keys(stdout);
      return 0;
    }
    if (argc > 3 || (argc == 3 && argv[2][0] == '-')) {
      fprintf(stderr, "vesica keys: '%s': takes --study or one KEY (see vesica keys --help)\n",
              argv[argc == 3 ? 2 : 3]);
      return 2;
    }
    if (argc == 3) {
      char near[128];
      if (ves_config_print_key(stdout, argv[2], near, sizeof near) > 0) return 0;
      fprintf(stderr,
              "vesica keys: '%s': not a problem-file key (the closest: %s; vesica keys "
              "lists them all)\n",
              argv[2], near);
      return 2;
    }
    ves_config_print_keys(stdout);
    return 0;
  }
  fprintf(stderr, "vesica: unknown command '%s' (see vesica --help)\n", argv[1]);
  return 2;
}

int main(int argc, char **argv) {
  cli_streams_begin(); /* before any file is opened: none takes a closed stream's number */
  return cli_streams_end(argc > 1 ? argv[1] : "", command(argc, argv));
}
