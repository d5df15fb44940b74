/* vesica spectrum: the linearized flow at a stored state, its slowest and
 * negative modes (docs/design.md, "Analysis"; docs/manual.md). */

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <unistd.h>

#include "app/cli_impl.h"
#include "ves/spectrum.h"

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
          "                existing F is refused unless --force; FILE.h5 and a file a\n"
          "                running vesica holds never are F; F is written whole or not at all)\n"
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

/* The command's options. */
typedef struct {
  const char *path, *vpath; /* FILE.h5, --vectors F */
  long snap, modes, lanczos;
  double above;
  int force;
} spectrum_args;

/* F and (with_part) the F.part it is written to through the guard of
 * every output (cli_check_output): never the input, never a file a running
 * vesica holds, an existing F only with --force. 0 or 2. */
static int check_vectors(const spectrum_args *o, int with_part) {
  char part[PATH_MAX + 8];
  snprintf(part, sizeof part, "%s.part", o->vpath);
  const char *in[] = {o->path};
  if (cli_check_output("spectrum", "--vectors", o->vpath, o->force, in, 1, NULL) ||
      (with_part && cli_check_output("spectrum", "--vectors", part, 1, in, 1, NULL)))
    return 2;
  return 0;
}

/* The text file of --vectors (vesica spectrum --help) from the analysis sp
 * of the state of r: written to F.part (locked while written, so no other
 * vesica replaces it), checked again (the analysis takes minutes: F may be
 * another vesica's by then), then renamed, so nothing partial stays behind.
 * 0; 2 when refused (message printed); -1 with errno the cause. */
static int write_modes(const run_ctx *r, const ves_spectrum *sp, const spectrum_args *o) {
  const ves_nodes *nd = ves_model_nodes(ves_sim_model(r->sim));
  const int n = sp->n;
  char part[PATH_MAX + 8];
  snprintf(part, sizeof part, "%s.part", o->vpath);
  if (check_vectors(o, 1)) return 2;
  errno = 0;
  const int fd = open(part, O_WRONLY | O_CREAT | O_CLOEXEC, 0666);
  if (fd < 0) return -1;
  if (flock(fd, LOCK_EX | LOCK_NB) != 0 && errno == EWOULDBLOCK) { /* another spectrum: F */
    close(fd);
    fprintf(stderr,
            "vesica spectrum: --vectors %s: %s is in use by a running vesica: never "
            "overwritten\n",
            o->vpath, part);
    return 2;
  }
  FILE *f = ftruncate(fd, 0) == 0 ? fdopen(fd, "w") : NULL;
  if (!f) {
    const int e = errno;
    close(fd), remove(part);
    errno = e;
    return -1;
  }
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
  if (!bad && check_vectors(o, 0)) { /* F taken since the start: refused, nothing kept */
    fclose(f), remove(part);
    return 2;
  }
  if (!bad && rename(part, o->vpath) != 0) bad = 1, e = errno;
  if (fclose(f) != 0 && !bad) bad = 1, e = errno; /* the lock goes with it */
  if (!bad) return 0;
  remove(bad && !access(part, F_OK) ? part : o->vpath);
  errno = e ? e : EIO;
  return -1;
}

/* The verdict line's threshold: a mode below it is unstable. -1e-3 1/t*
 * (an e-fold of growth per 1000 t*, far slower than any relaxation the
 * runs resolve) is the project's criterion for the discrete energy's
 * negative modes (docs/results.md, "The discrete energy's negative modes"):
 * the default stabilization keeps the sphere at rest above it, and the
 * neutral modes (the vesicle translated in the box, mu ~ 0 up to the
 * solves' rounding) stay clear of it. */
#define UNSTABLE_BELOW (-1e-3)

int cli_spectrum_verdict(char *buf, size_t len, double above, int below, int nmodes,
                         const double *mu) {
  int found = 0, valid = 0; /* the modes found below the threshold; found at all (not NaN) */
  while (valid < nmodes && !isnan(mu[valid])) valid++;
  while (found < valid && mu[found] < UNSTABLE_BELOW) found++;
  const double lowest = valid > 0 ? mu[0] : NAN;
  if (below > 0 && above > UNSTABLE_BELOW) { /* those below --above may lie either side */
    snprintf(buf, len,
             "verdict: undetermined (%d eigenvalue(s) below --above %g, above -1e-3 or not; "
             "rerun with --above -1e-3 or lower)",
             below, above);
    return -1;
  }
  const int n = below + found;
  if (valid == 0 && n == 0) {
    snprintf(buf, len,
             "verdict: undetermined (no eigenvalue found above --above %g; raise "
             "--lanczos)",
             above);
    return -1;
  }
  if (n == 0)
    snprintf(buf, len, "verdict: stable (no mode below -1e-3; lowest mu_1 = %.3e)", lowest);
  else if (found == valid) /* the modes found end below the threshold: more may follow */
    snprintf(buf, len,
             "verdict: at least %d unstable modes (below -1e-3; %d below --above %g, lowest found "
             "mu_1 = %.3e; raise --modes to count them all)",
             n, below, above, lowest);
  else
    snprintf(buf, len,
             "verdict: %d unstable mode%s (below -1e-3; %d below --above %g, lowest "
             "found mu_1 = %.3e)",
             n, n == 1 ? "" : "s", below, above, lowest);
  return n;
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
    printf("mu_%ld_from_E = %.6e\nmu_%ld_from_A = %.6e\nmu_%ld_from_V = %.6e\n", j + 1, q->from[0],
           j + 1, q->from[1], j + 1, q->from[2]);
    printf("mu_%ld_drift = %.3e\n", j + 1, q->drift);
  }
  printf("drift_K_norm = %.6e\ndrift_in_modes = %.3e\n", sp->drift_K_norm, sp->drift_in_modes);
}

/* The value v of option a into o: 0, or 2 with a message. */
static int spectrum_value(const char *a, const char *v, spectrum_args *o) {
  if (!strcmp(a, "--snapshot"))
    return cli_parse_long("spectrum", a, v, -1000000, 1000000, &o->snap);
  if (!strcmp(a, "--modes")) return cli_parse_long("spectrum", a, v, 1, 100, &o->modes);
  if (!strcmp(a, "--lanczos")) return cli_parse_long("spectrum", a, v, 2, 2000, &o->lanczos);
  if (!strcmp(a, "--vectors")) {
    o->vpath = v;
    return 0;
  }
  char *end = NULL;
  o->above = strtod(v, &end);
  if (end == v || *end || !isfinite(o->above)) {
    fprintf(stderr, "vesica spectrum: --above '%s': not a finite number\n", v);
    return 2;
  }
  return 0;
}

/* argv into o. 0 to go on, -1 after --help, else the exit code. */
static int spectrum_parse(int argc, char **argv, spectrum_args *o) {
  *o = (spectrum_args){.snap = -1, .modes = 6, .lanczos = 80, .above = -1};
  for (int i = 0; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
      usage_spectrum(stdout);
      return -1;
    } else if (!strcmp(a, "--force")) {
      o->force = 1;
    } else if (!strcmp(a, "--snapshot") || !strcmp(a, "--above") || !strcmp(a, "--modes") ||
               !strcmp(a, "--lanczos") || !strcmp(a, "--vectors")) {
      if (i + 1 >= argc) {
        fprintf(stderr, "vesica spectrum: %s needs a value\n", a);
        return 2;
      }
      int rc = spectrum_value(a, argv[++i], o);
      if (rc) return rc;
    } else if (cli_operand("spectrum", "file", a[0] == '-' && a[1] && !isdigit((unsigned char)a[1]),
                           a, &o->path)) {
      return 2;
    }
  }
  if (cli_need(o->path, usage_spectrum)) return 2;
  if (o->modes > o->lanczos) {
    fprintf(stderr, "vesica spectrum: --modes %ld is more than --lanczos %ld\n", o->modes,
            o->lanczos);
    return 2;
  }
  return o->vpath ? check_vectors(o, 1) : 0;
}

/* The analysis of the rebuilt state r at snapshot k (si): printed, the
 * modes written to --vectors. Returns the exit code. */
static int analyse(run_ctx *r, const spectrum_args *o, const char *pre, long k,
                   const ves_io_snapinfo *si, double t0) {
  const ves_spectrum_params sprm = {.hold_area = r->cfg.area,
                                    .hold_volume = r->cfg.volume,
                                    .above = o->above,
                                    .modes = (int)o->modes,
                                    .lanczos = (int)o->lanczos};
  ves_spectrum *sp = NULL;
  int rc = 0;
  ves_error_clear();
  ves_status st = ves_spectrum_create(r->sim, &sprm, &sp);
  if (st != VES_OK) {
    fprintf(stderr, "%s: snapshot %ld: the spectrum failed: %s%s\n", pre, k, cli_why(st),
            st == VES_ERR_SINGULAR ? " (--above is an eigenvalue? move it a little)" : "");
    rc = 3;
  } else if (o->vpath && (rc = write_modes(r, sp, o)) != 0) {
    if (rc < 0)
      fprintf(stderr, "vesica spectrum: --vectors %s: cannot write: %s\n", o->vpath,
              strerror(errno));
    rc = rc < 0 ? 3 : rc; /* an output that cannot be written (a full disk), as plot's */
  } else {
    print_spectrum(o->path, k, si, r, sp, o->above);
    printf("seconds = %.1f\n", ves_wall_seconds() - t0);
    char verdict[320];
    cli_spectrum_verdict(verdict, sizeof verdict, o->above, sp->below, sp->nmodes, sp->mu);
    printf("%s\n", verdict);
    if (sp->below > 0)
      fprintf(stderr,
              "vesica spectrum: %d eigenvalue(s) lie below --above %g: lower it to see them\n",
              sp->below, o->above);
  }
  ves_spectrum_destroy(&sp);
  return rc;
}

int cmd_spectrum(int argc, char **argv) {
  spectrum_args o;
  int rc = spectrum_parse(argc, argv, &o);
  if (rc) return rc < 0 ? 0 : rc;
  const char *path = o.path;
  run_ctx r;
  memset(&r, 0, sizeof r);
  r.label = path, r.quiet = 1;
  char err[1024] = "", pre[PATH_MAX + 32];
  snprintf(pre, sizeof pre, "vesica spectrum: %s", path);
  rc = 2;
  if (ves_io_open(path, 0, &r.io, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica spectrum: %s\n", err);
    goto done;
  }
  const ves_io_info *in = ves_io_get_info(r.io);
  const int S = ves_io_snapshots(r.io);
  const long k = o.snap < 0 ? S + o.snap : o.snap;
  if (k < 0 || k >= S) {
    fprintf(stderr, "%s: --snapshot %ld: the file holds %d snapshot(s)\n", pre, o.snap, S);
    goto done;
  }
  if (ves_config_load_text(in->problem, in->source, &r.cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "%s: the stored problem: %s\n", pre, err);
    goto done;
  }
  const double t0 = ves_wall_seconds();
  ves_io_snapinfo si;
  if ((rc = cli_rebuild_at(&r, pre, (int)k, &si))) goto done;
  rc = analyse(&r, &o, pre, k, &si, t0);
done:
  cli_run_free(&r);
  return rc;
}
