/* vesica plot: the PNG figures of a run (plot.h; docs/manual.md;
 * docs/design.md, "The program"). */

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
  fprintf(f,
          "usage: vesica plot FILE.h5 [--outdir DIR] [--times T1,T2,...] [--force]\n"
          "Writes four PNG figures (gnuplot, pngcairo) named after FILE:\n"
          "  FILE_energy.png       E* and dt* against t* on a log time axis (paper Fig. 4)\n"
          "  FILE_snapshots.png    the nodes at chosen times, mirrored across the axis,\n"
          "                        coloured by phi (paper Figs. 3, 5)\n"
          "  FILE_constraints.png  |A/A0 - 1|, |V/V_target - 1| and V/V0 against t*\n"
          "  FILE_flow.png         the flow at the nodes as arrows at the same times\n"
          "                        (paper Fig. 5; none at t* = 0 or where no flow is stored)\n"
          "--outdir DIR    where (default: the folder of FILE.h5; created if missing)\n"
          "--times LIST    the snapshots nearest to these times t* (at most %d; default: the\n"
          "                first, the last and two between them on a log time scale)\n"
          "--force         overwrite existing figures (without it they are refused, exit 2;\n"
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
    } else if (!strcmp(argv[i], "--outdir") || !strcmp(argv[i], "--times")) {
      if (i + 1 >= argc) {
        fprintf(stderr, "vesica plot: %s needs a value\n", argv[i]);
        return 2;
      }
      if (!strcmp(argv[i], "--outdir"))
        outdir = argv[++i];
      else if (parse_times(argv[++i], &p))
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
  /* every figure and the .part gnuplot writes it to (plot.c): never the
   * input, never a file a running vesica holds, an existing figure only
   * with --force (a .part is plot's own scratch) */
  for (int k = 0; k < VES_PLOT_NFIG; k++) {
    char png[2 * PATH_MAX + 64], part[2 * PATH_MAX + 72];
    snprintf(png, sizeof png, "%s/%s_%s.png", dir, stem, ves_plot_figures[k]);
    snprintf(part, sizeof part, "%s.part", png);
    const char *in[] = {path};
    if (cli_check_output("plot", "figure", png, force, in, 1, NULL) ||
        cli_check_output("plot", "figure", part, 1, in, 1, NULL)) {
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
  for (int k = 0; k < VES_PLOT_NFIG; k++) printf("%s/%s_%s.png\n", dir, stem, ves_plot_figures[k]);
  return 0;
}
