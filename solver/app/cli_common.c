/* vesica — the command line's shared pieces: options, the problem file, the
 * setup's estimate, output paths, the library's error text (cli_impl.h;
 * docs/design.md, "The program"). */

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
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

/* Whether a process holds a lock on the file path: a shared lock taken
 * without waiting fails when another open of the file holds an exclusive
 * one. A running vesica holds one on each file it writes: HDF5 locks its
 * output for as long as it is open for writing (H5Fopen and H5Fcreate
 * flock it), and run locks its --series text and spectrum its --vectors
 * file (open_series, write_modes). The probe's lock goes with its close. */
static int locked(const char *path) {
  int fd = open(path, O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
  if (fd < 0) return 0;
  const int held = flock(fd, LOCK_SH | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  close(fd);
  return held;
}

/* The file a running vesica holds that writing path would destroy: path
 * itself, or, when path is the XDMF file of a run or its temporary (B.xdmf
 * or B.xdmf.tmp, ves_io_xdmf_path), that run's B.h5 or B (the XDMF file of
 * a running run is rewritten at its snapshots). Into buf; NULL when none. */
static const char *held_file(const char *path, char *buf, size_t len) {
  if (locked(path)) return path;
  size_t l = strlen(path);
  if (l > 4 && !strcmp(path + l - 4, ".tmp")) l -= 4;
  if (l <= 5 || strncmp(path + l - 5, ".xdmf", 5)) return NULL;
  l -= 5;
  snprintf(buf, len, "%.*s.h5", (int)l, path);
  if (locked(buf)) return buf;
  snprintf(buf, len, "%.*s", (int)l, path);
  return locked(buf) ? buf : NULL;
}

/* Every file a command writes passes here, before its first write and
 * again just before it is created: its folder writable; never one of the
 * command's inputs in[nin] (NULL entries skipped); never a file a running
 * vesica holds (whatever force: a running run's file is not a finished
 * output, and replacing it loses the run); an existing file only with
 * force. 0 ok, else 2 (message printed; hint, if any, says how to keep the
 * file instead). */
int cli_check_output(const char *cmd, const char *what, const char *path, int force,
                     const char *const *in, int nin, const char *hint) {
  int rc = cli_check_writable(cmd, what, path);
  if (rc) return rc;
  for (int i = 0; i < nin; i++)
    if (in[i] && (cli_same_file(path, in[i]) || !strcmp(path, in[i]))) {
      fprintf(stderr, "vesica %s: %s %s: is the input file %s: an input is never overwritten\n",
              cmd, what, path, in[i]);
      return 2;
    }
  char buf[PATH_MAX + 8];
  const char *held = held_file(path, buf, sizeof buf);
  if (held == path) {
    fprintf(stderr,
            "vesica %s: %s %s: in use by a running vesica (it holds a lock on the file): "
            "never overwritten, even with --force\n",
            cmd, what, path);
    return 2;
  }
  if (held) {
    fprintf(stderr,
            "vesica %s: %s %s: the XDMF file of %s, which a running vesica holds: never "
            "overwritten, even with --force\n",
            cmd, what, path, held);
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

/* An option's value is the next argument unless that is an option itself:
 * '-' then not a digit or '.' ("-1", "-.5" and "-2e-3" are values, so that
 * --max-steps -1 says the value is out of range, not that it is missing). */
int cli_is_value(const char *a) {
  return a && (a[0] != '-' || isdigit((unsigned char)a[1]) ||
               (a[1] == '.' && isdigit((unsigned char)a[2])));
}

/* 1 when standard output is closed at the start of the program (fd 1 then
 * holds /dev/full, cli_streams_begin). */
static int stdout_closed;

/* A standard stream closed at the start (fd 0, 1 or 2 not open) is opened
 * on /dev/null, standard output on /dev/full: otherwise the first file the
 * command opens takes that number, and printf or a message on stderr
 * writes into it (the run's HDF5 file). What a command prints to a closed
 * standard output then fails, and cli_streams_end says so. */
void cli_streams_begin(void) {
  for (int fd = 0; fd < 3; fd++) {
    if (fcntl(fd, F_GETFD) != -1 || errno != EBADF) continue;
    int k = open(fd == 1 ? "/dev/full" : "/dev/null", fd ? O_WRONLY : O_RDONLY);
    if (k < 0) k = open("/dev/null", fd ? O_WRONLY : O_RDONLY);
    if (k >= 0 && k != fd) dup2(k, fd), close(k);
    if (fd == 1) stdout_closed = 1;
  }
}

/* The exit code of a command that returned rc, once its standard output is
 * written out: a result that does not reach its reader (a full disk, a
 * closed standard output) is a write failure, exit 3 with a message (rc
 * kept when the command failed already). */
int cli_streams_end(const char *cmd, int rc) {
  errno = 0;
  const int flushed = fflush(stdout) == 0, e = errno;
  if (flushed && !ferror(stdout)) return rc;
  fprintf(stderr, "vesica%s%s: standard output: cannot write: %s\n", *cmd ? " " : "", cmd,
          stdout_closed   ? "it is closed"
          : !flushed && e ? strerror(e)
                          : "a write failed");
  return rc ? rc : 3;
}

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
