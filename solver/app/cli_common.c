/* vesica — the command line's shared pieces: options, the problem file, the
 * setup's estimate, output paths, the library's error text (cli_impl.h;
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

/* A setup message names the file itself when it comes from reading one (a
 * points file): then do not name the problem file twice. */
void cli_setup_error(const char *cmd, const char *label, const char *err) {
  if (!strncmp(err, label, strlen(label)) && err[strlen(label)] == ':')
    fprintf(stderr, "vesica %s: %s\n", cmd, err);
  else
    fprintf(stderr, "vesica %s: %s: %s\n", cmd, label, err);
}

/* Exit code for a failed setup: bad input (configuration, arguments, an
 * unreadable points file) 2, anything numerical 3. */
int cli_exit_for(ves_status st) {
  return st == VES_ERR_CONFIG || st == VES_ERR_ARG || st == VES_ERR_IO ? 2 : 3;
}

/* The node count of a problem's setup, estimated before building it: the
 * band |d| < band eps on both sides of the meridian (the shape's own
 * generating curve, of length L from pole to pole) at the hexagonal density
 * rho = 2 / (sqrt(3) h^2) of h_band eps, the graded zone from there to h_far
 * at `slope` (width D = (h_far - h0) / slope on each side), and the part of
 * the box [0, box_r] x [-box_z, box_z] beyond that zone at h_far; times
 * EST_FILL, the nodes the layers, the axis lattice and the Lloyd smoothing
 * add, fitted on two setups at eps 0.01 (the oblate 19,391 and the prolate
 * of prolate_c0.ini 27,447 nodes: 19,356 and 27,446 estimated) and within
 * +1% to +6% on four more (docs/results.md, "Performance and its scaling").
 * L is the shape's own meridian, not pi: a prolate's is longer. Memory
 * scales linearly from the oblate's below (no resets); a reset or a
 * remeshing builds the new reference's tables beside the old ones
 * (integrate.c), EST_RESET more: that prolate peaks at 4.1 GB before its
 * first reset, 6.7 GB after it and 8.85 GB by t* 3.6 after several, 2.08x
 * the 4.25 GB the steps' scaling gives (docs/results.md, "Resets and
 * remeshing").
 * Returns 0 when the shape cannot be built (the setup then says why). */
#define EST_FILL 1.27
static double estimate_nodes(const ves_config *c) {
  char err[256];
  ves_shape *shape = NULL;
  if (ves_problem_shape(c, &shape, err, sizeof err) != VES_OK) return 0.0;
  const double L = ves_shape_length(shape);
  ves_shape_destroy(&shape);
  const double h0 = c->h_band * c->epsilon, rho = 2 / sqrt(3.0);
  const double band = L * 2 * c->band * c->epsilon * rho / (h0 * h0);
  const double grade = c->h_far > h0 ? L * rho * (1 / h0 - 1 / c->h_far) / c->slope : 0.0;
  const double D = c->h_far > h0 ? (c->h_far - h0) / c->slope : 0.0;
  const double far = fmax(0.0, c->box_r * 2 * c->box_z - 2 * L * D) * rho / (c->h_far * c->h_far);
  return EST_FILL * (band + grade) + far;
}

/* Rates at the paper's scale (19,391 nodes, one thread, OpenBLAS's own
 * kernels; docs/results.md, "Performance and its scaling"): setup 11 s (+2 s
 * for the stabilization's rows), peak memory of the run 2.9 GB (+0.1 GB), a
 * Newton step with its matrix 8.3 s growing as n^1.22 (a slower machine or
 * AVX2 kernels: up to 1.7x). */
#define EST_NODES 19391.0
#define EST_SETUP_S 13.0
#define EST_PEAK_GB 3.0
#define EST_STEP_S 8.0
#define EST_LARGE 10000 /* nodes from which the estimate is printed */
#define EST_RESET 2.1   /* the peak with resets or remeshings against the steps' */
/* A remeshing builds a new node set adapted to the interface as it is: the
 * Fig. 6 run at eps 0.01 grew from 24,537 to 39,746 nodes over three and its
 * peak from the estimated 8.0 GB to 11.1 GB (docs/results.md, "Resets and
 * remeshing"):
 * the line says so rather than guessing the growth. */

/* Before a setup: a line with the estimated size and cost when the problem
 * is large (not with quiet); a refusal when its estimated memory exceeds
 * the machine's. 0 ok, else 2 (message printed). */
int cli_setup_estimate(const char *cmd, const ves_config *c, int quiet) {
  ves_problem_params pp; /* its .resets: the one reading of [reconnect] and [remesh] */
  ves_problem_params_from_config(c, &pp);
  const int resets = pp.resets;
  const double n = estimate_nodes(c), x = n / EST_NODES,
               gb = EST_PEAK_GB * x * (resets ? EST_RESET : 1.0);
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
            "~%.1f GB peak memory in a run%s, ~%.0f s a Newton step (scaled from %.0f nodes: "
            "docs/results.md)\n",
            cmd, n, EST_SETUP_S * x, gb,
            pp.remesh ? " (with its resets, for this node set: a remeshing that adds nodes raises "
                        "it in proportion)"
            : resets  ? " (with its resets)"
                      : "",
            EST_STEP_S * pow(x, 1.22), EST_NODES);
  return 0;
}

/* The tail shared by the commands that take a problem file: a path must have
 * been given; load it with the overrides. 0 on success, else the exit code. */
int cli_load_problem(const char *cmd, const char *path, void (*usage_fn)(FILE *), int nset,
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
int cli_take_set(const char *cmd, int argc, char **argv, int *i, int *nset, const char **set) {
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

/* The folder of path must exist and be writable, path must not be a folder. */
int cli_check_writable(const char *cmd, const char *what, const char *path) {
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
int cli_same_file(const char *a, const char *b) {
  struct stat sa, sb;
  return a && b && stat(a, &sa) == 0 && stat(b, &sb) == 0 && sa.st_dev == sb.st_dev &&
         sa.st_ino == sb.st_ino;
}

/* An output path: never one of the inputs in[nin] (NULL entries skipped),
 * and not an existing file unless force. 0 ok, else 2 (message printed;
 * hint, if any, says how to keep the file instead). */
int cli_check_new(const char *cmd, const char *what, const char *path, int force,
                  const char *const *in, int nin, const char *hint) {
  for (int i = 0; i < nin; i++)
    if (cli_same_file(path, in[i])) {
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

/* Parse a long in [lo, hi] for option opt; 0 ok, 2 with a message. */
int cli_parse_long(const char *cmd, const char *opt, const char *v, long lo, long hi, long *out) {
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

const char *cli_why(ves_status st) { return ves_error_text(st); }

int cli_operand(const char *cmd, const char *what, int is_option, const char *a,
                const char **path) {
  if (is_option) {
    fprintf(stderr, "vesica %s: unknown option '%s' (see vesica %s --help)\n", cmd, a, cmd);
    return 2;
  }
  if (*path) {
    fprintf(stderr, "vesica %s: more than one %s ('%s')\n", cmd, what, a);
    return 2;
  }
  *path = a;
  return 0;
}

int cli_need(const char *path, void (*usage_fn)(FILE *)) {
  if (path) return 0;
  usage_fn(stderr);
  return 2;
}
