/* vesica info: the summary of a run, one key = value a line
 * (docs/manual.md; docs/design.md, "The program"). */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app/cli_impl.h"
#include "app/plot.h"

static void usage_info(FILE *f) {
  fprintf(f, "usage: vesica info FILE.h5 [--series N | --provenance]\n"
             "  --series N  instead of the summary, the last N rows of the file's series (every\n"
             "              row with N = 0) as tab-separated text, a '# name...' header first:\n"
             "              the columns of /series, step first (manual: \"The series\"),\n"
             "              from the initial state's row (step 0, t = 0) when the file has\n"
             "              it; also of a run still being written.\n"
             "  --provenance  instead of the summary, the provenance of every run that wrote\n"
             "              the file (the first, then each restart): 'run.K.key = value' lines\n"
             "              (version, commit, compiler, cflags, hdf5, mumps, ipopt, nlopt,\n"
             "              openblas, openblas_core, host, threads, started, command).\n"
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
             "  Ipopt iterations, ...), hessian_evaluations, kkt_factorizations (newton and\n"
             "  euler; left out when the file lacks the column), wall_seconds (time loop, over\n"
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

/* The summary's lines (vesica info --help names them). */
static void print_summary(const char *path, ves_io *io, const ves_config *cfg,
                          const ves_io_summary *u) {
  const ves_io_info *in = ves_io_get_info(io);
  const long R = u->steps;
  printf("file = %s\n", path);
  printf("format_version = %d\nversion = %s\nstatus = %s\nbackend = %s\n", in->format_version,
         in->version, in->status, in->backend);
  printf("nodes = %d\ntriangles = %d\nsnapshots = %d\nreferences = %d\nsteps = %ld\n", in->n,
         in->ntri, ves_io_snapshots(io), ves_io_references(io), R);
  const int S = ves_io_snapshots(io); /* full remeshings: the last snapshot's node count */
  printf("remeshings = %d\nnodes_final = %d\n", ves_io_remeshes(io),
         S > 0 ? ves_io_snapshot_nodes(io, S - 1) : in->n);
  printf("t_final = %.12g\nt_end = %.12g\n", u->t_final, cfg->t_end);
  printf("energy_initial = %.12g\nenergy_final = %.12g\n", in->E0, u->E_final);
  printf("energy_monotone = %s\n", u->energy_monotone ? "yes" : "no");
  printf("area_drift_max = %.6e\nvolume_drift_max = %.6e\n", u->area_drift_max,
         u->volume_drift_max);
  printf("reduced_volume_initial = %.12g\nreduced_volume_final = %.12g\n",
         reduced_volume(in->A0, in->V0), reduced_volume(u->A_final, u->V_final));
  printf("dt_first = %.6g\ndt_largest = %.6g\n", u->dt_first, u->dt_largest);
  printf("retries = %.0f\nreconnections = %.0f\n", u->retries, u->reconnections);
  printf("newton_iterations = %.0f\nhessian_evaluations = %.0f\n", u->iterations, u->h_evals);
  if (u->factorizations >= 0) printf("kkt_factorizations = %.0f\n", u->factorizations);
  printf("wall_seconds = %.3f\nsetup_seconds = %.3f\n", u->wall_seconds, in->setup_seconds);
}

/* Every parameter as section.key = value. */
static void print_parameters(const ves_config *cfg) {
  for (int i = 0; i < ves_config_count(); i++) {
    ves_config_entry e;
    ves_config_entry_get(cfg, i, &e);
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

/* The last `last` rows of every series (all with last = 0), tab-separated. */
static int print_series(const char *path, ves_io *io, long last) {
  const long R = ves_io_rows(io) + ves_io_initial_row(io), r0 = last > 0 && last < R ? R - last : 0;
  int nc = 0;
  while (ves_io_series_name(nc)) nc++;
  double *col = malloc((size_t)nc * (size_t)(R > 0 ? R : 1) * sizeof *col);
  if (!col) {
    fprintf(stderr, "vesica info: out of memory\n");
    return 2;
  }
  for (int c = 0; c < nc; c++)
    if (R > 0 && ves_io_read_series_all(io, ves_io_series_name(c), col + (size_t)c * R) != VES_OK) {
      fprintf(stderr, "vesica info: %s: cannot read the series %s\n", path, ves_io_series_name(c));
      free(col);
      return 2;
    }
  /* step (the file's last column) first */
  for (int k = 0; k < nc; k++)
    printf("%s%s", k ? "\t" : "# ", ves_io_series_name((k + nc - 1) % nc));
  printf("\n");
  for (long r = r0; r < R; r++)
    for (int k = 0; k < nc; k++)
      printf("%.12g%s", col[(size_t)((k + nc - 1) % nc) * R + r], k + 1 < nc ? "\t" : "\n");
  free(col);
  return 0;
}

/* The provenance of every run that wrote the file (ves_io_provenance). */
static int print_provenance(const char *path, ves_io *io) {
  const int runs = ves_io_provenance_runs(io);
  if (runs <= 0) {
    fprintf(stderr, "vesica info: %s: no provenance recorded (a file of an older version)\n", path);
    return 2;
  }
  for (int k = 0; k < runs; k++) {
    char key[64], value[4096];
    for (int i = 0; ves_io_provenance(io, k, i, key, sizeof key, value, sizeof value) == VES_OK;
         i++)
      printf("run.%d.%s = %s\n", k, key, value);
  }
  return 0;
}

int cmd_info(int argc, char **argv) {
  const char *path = NULL;
  int provenance = 0;
  long last = -1; /* --series N (-1: the summary) */
  for (int i = 0; i < argc; i++) {
    if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
      usage_info(stdout);
      return 0;
    } else if (!strcmp(argv[i], "--series")) {
      if (i + 1 >= argc) {
        fprintf(stderr, "vesica info: --series needs a row count (0: all)\n");
        return 2;
      }
      if (cli_parse_long("info", "--series", argv[++i], 0, 1000000000L, &last)) return 2;
    } else if (!strcmp(argv[i], "--provenance")) {
      provenance = 1;
    } else if (cli_operand("info", "file", argv[i][0] == '-', argv[i], &path)) {
      return 2;
    }
  }
  if (cli_need(path, usage_info)) return 2;
  char err[1024] = "";
  ves_io *io = NULL;
  if (ves_io_open(path, 0, &io, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica info: %s\n", err);
    return 2;
  }
  if (provenance && last >= 0) {
    fprintf(stderr, "vesica info: --series and --provenance exclude each other\n");
    ves_io_close(&io);
    return 2;
  }
  if (provenance || last >= 0) {
    const int rc = provenance ? print_provenance(path, io) : print_series(path, io, last);
    ves_io_close(&io);
    return rc;
  }
  const ves_io_info *in = ves_io_get_info(io);
  ves_config cfg;
  if (ves_config_load_text(in->problem, in->source, &cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica info: %s: the stored problem: %s\n", path, err);
    ves_io_close(&io);
    return 2;
  }
  ves_io_summary u;
  if (ves_io_summarize(io, cfg.c0, &u) != VES_OK) {
    fprintf(stderr, "vesica info: %s: cannot read the series\n", path);
    ves_io_close(&io);
    return 2;
  }
  print_summary(path, io, &cfg, &u);
  interface_lines(io);
  printf("source = %s\n", in->source);
  print_parameters(&cfg);
  ves_io_close(&io);
  return 0;
}
