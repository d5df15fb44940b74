/* vesica plot: the figures of a run, PNG, PDF or SVG (plot.h;
 * docs/manual.md; docs/design.md, "The program"). */

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "app/cli_impl.h"
#include "app/plot.h"

static void usage_plot(FILE *f) {
  fprintf(
      f,
      "usage: vesica plot FILE.h5 [--outdir DIR] [--times T1,T2,...] [--format png|pdf|svg]\n"
      "                   [--script S] [--force]\n"
      "Writes four figures (gnuplot) named after FILE, EXT the format:\n"
      "  FILE_energy.EXT       E* and dt* against t* on a log time axis (paper Fig. 4)\n"
      "  FILE_snapshots.EXT    the nodes at chosen times, mirrored across the axis,\n"
      "                        coloured by phi, and the phi = 0 curve (paper Figs. 3, 5)\n"
      "  FILE_constraints.EXT  |A/A0 - 1|, |V/V_target - 1|, the sharp interface's drift,\n"
      "                        and V/V0 against t* when the volume target varies\n"
      "  FILE_flow.EXT         the flow at the nodes as arrows, one scale for all panels, at\n"
      "                        the chosen times that store a flow (paper Fig. 5; none at t* = 0)\n"
      "--outdir DIR    where (default: the folder of FILE.h5; created if missing)\n"
      "--times LIST    the snapshots nearest to these times t* (at most %d; default: the\n"
      "                first, the last and two between them on a log time scale)\n"
      "--format F      png (default; pngcairo), pdf (pdfcairo) or svg\n"
      "--script S      also keep the gnuplot script in S (data inline): `gnuplot S`\n"
      "                redraws the figures, to restyle them\n"
      "--force         overwrite existing figures and S (without it they are refused, exit 2;\n"
      "                FILE.h5 and a file a running vesica holds never are overwritten)\n"
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

/* "png", "pdf" or "svg" into p->format. 0 ok, else 2 (message printed). */
static int parse_format(const char *s, ves_plot_params *p) {
  for (int k = 0; k < VES_PLOT_NFORMAT; k++)
    if (!strcmp(s, ves_plot_formats[k])) {
      p->format = k;
      return 0;
    }
  fprintf(stderr, "vesica plot: --format '%s': expected png, pdf or svg\n", s);
  return 2;
}

int cmd_plot(int argc, char **argv) {
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
    } else if (!strcmp(argv[i], "--outdir") || !strcmp(argv[i], "--times") ||
               !strcmp(argv[i], "--format") || !strcmp(argv[i], "--script")) {
      if (i + 1 >= argc) {
        fprintf(stderr, "vesica plot: %s needs a value\n", argv[i]);
        return 2;
      }
      if (!strcmp(argv[i], "--outdir"))
        outdir = argv[++i];
      else if (!strcmp(argv[i], "--script"))
        p.script = argv[++i];
      else if (!strcmp(argv[i], "--format") ? parse_format(argv[++i], &p)
                                            : parse_times(argv[++i], &p))
        return 2;
    } else if (cli_operand("plot", "file", argv[i][0] == '-', argv[i], &path)) {
      return 2;
    }
  }
  if (cli_need(path, usage_plot)) return 2;
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
  /* every figure and the .part gnuplot writes it to (plot.c), and the
   * kept script and its .part: never the input, never a file a running
   * vesica holds, an existing one only with --force (a .part is plot's own
   * scratch) */
  const char *ext = ves_plot_formats[p.format];
  for (int k = 0; k <= VES_PLOT_NFIG; k++) {
    char fig[2 * PATH_MAX + 64], part[2 * PATH_MAX + 72];
    if (k < VES_PLOT_NFIG)
      snprintf(fig, sizeof fig, "%s/%s_%s.%s", dir, stem, ves_plot_figures[k], ext);
    else if (p.script)
      snprintf(fig, sizeof fig, "%s", p.script);
    else
      break;
    snprintf(part, sizeof part, "%s.part", fig);
    const char *in[] = {path}, *what = k < VES_PLOT_NFIG ? "figure" : "--script";
    if (cli_check_output("plot", what, fig, force, in, 1, NULL) ||
        cli_check_output("plot", what, part, 1, in, 1, NULL)) {
      ves_io_close(&io);
      return 2;
    }
  }
  p.outdir = dir, p.stem = stem;
  ves_status st = ves_plot_write(io, &p, err, sizeof err);
  ves_io_close(&io);
  if (st != VES_OK) {
    fprintf(stderr, "vesica plot: %s: %s\n", path, err);
    return st == VES_ERR_ARG || st == VES_ERR_CONFIG ? 2 : 3; /* bad or corrupt input: 2 */
  }
  for (int k = 0; k < VES_PLOT_NFIG; k++)
    printf("%s/%s_%s.%s\n", dir, stem, ves_plot_figures[k], ext);
  if (p.script) printf("%s\n", p.script);
  return 0;
}
