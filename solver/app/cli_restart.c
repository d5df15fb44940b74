/* vesica run --restart: continue a stored run from its last snapshot (the
 * keys a restart may change, the setup rebuilt from the stored problem
 * text), salvaging a file cut short first. User-facing behaviour:
 * docs/manual.md; docs/design.md, "The program". */

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "app/cli_impl.h"

/* The keys a restart may change: how each step is solved, the controller's
 * halving after a hard step (time.factor_shrink), its largest growth
 * between steps (time.growth_max), its largest step (time.dt_max, at
 * least the file's dt_initial) and its rules that hold dt after a step
 * of many iterations or factorizations (time.iter_target,
 * time.factor_target), its cut after a reset or a remeshing
 * (time.event_cut) — cost knobs for the bud phase of a long run
 * (docs/results.md, "Long runs at ε = 0.01") — and where the run ends; the
 * rest defines the setup, the physics or the protocol the stored steps
 * followed. */
static const char *const RESTART_KEYS[] = {"solver.tol",
                                           "solver.ctol",
                                           "solver.max_iter",
                                           "solver.max_builds",
                                           "solver.max_correction",
                                           "solver.freeze_hessian",
                                           "solver.factor_precision",
                                           "time.factor_shrink",
                                           "time.growth_max",
                                           "time.dt_max",
                                           "time.iter_target",
                                           "time.factor_target",
                                           "time.event_cut",
                                           "time.t_end"};

void cli_restart_keys_print(FILE *f, int col, int indent, int width, const char *tail) {
  const size_t nk = sizeof RESTART_KEYS / sizeof RESTART_KEYS[0];
  for (size_t j = 0; j <= nk; j++) { /* the keys, then the tail as one more word */
    const char *word = j < nk ? RESTART_KEYS[j] : tail;
    const char *sep = j + 2 < nk ? "," : j + 1 < nk ? " and" : "";
    const int len = (int)(strlen(word) + strlen(sep));
    if (j > 0 && width > 0 && col + 1 + len >= width)
      col = fprintf(f, "\n%*s", indent, "") - 1;
    else if (j > 0)
      col += fprintf(f, " ");
    col += fprintf(f, "%s%s", word, sep);
  }
}

/* A file cut short (a torn last write) or whose superblock is behind its
 * data (a write that failed half-way): its last complete snapshot, the
 * rows and references before it salvaged into a new FILE.h5 (io.h), the
 * damaged file kept as FILE.h5.damaged. 0, or exit code 3 with a message. */
static int salvage(const char *file, int quiet) {
  long long size = 0, stored = 0;
  const int cut = ves_io_cut_short(file, &size, &stored);
  if (!cut) ves_io_end_behind(file, &size, &stored);
  char how[160];
  if (cut)
    snprintf(how, sizeof how,
             "cut short (%lld of the %lld bytes its superblock records: a torn "
             "last write)",
             size, stored);
  else
    snprintf(how, sizeof how,
             "damaged (its superblock records %lld of its %lld bytes: a write "
             "that failed half-way)",
             stored, size);
  char tmp[PATH_MAX + 16], kept[PATH_MAX + 16], err[1024] = "";
  snprintf(tmp, sizeof tmp, "%s.salvage", file);
  snprintf(kept, sizeof kept, "%s.damaged", file);
  struct stat sb;
  if (stat(kept, &sb) == 0) {
    fprintf(stderr,
            "vesica run: --restart %s: the file is %s and %s, where its damaged copy would be "
            "kept, exists: move it away\n",
            file, how, kept);
    return 3;
  }
  remove(tmp); /* a salvage interrupted before */
  ves_io_salvaged s;
  ves_status st = ves_io_salvage(file, tmp, &s, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr, "vesica run: --restart %s: the file is %s and cannot be salvaged: %s\n", file,
            how, err);
    return 3;
  }
  if (rename(file, kept) != 0 || rename(tmp, file) != 0) {
    fprintf(stderr, "vesica run: --restart %s: cannot put the salvaged file in place: %s\n", file,
            strerror(errno));
    return 3;
  }
  if (!quiet)
    fprintf(stderr,
            "vesica run: %s was %s: salvaged snapshots 0..%d of %d (step %ld, t* = %.6g), %ld "
            "series rows and %d reference(s) into a new %s; the damaged file is kept as %s\n",
            file, how, s.snapshot, s.snapshots, s.step, s.t, s.rows, s.references, file, kept);
  return 0;
}

/* Whether file is open for writing in another process (a running vesica:
 * HDF5 holds an exclusive flock on a file it writes). */
static int in_use(const char *file) {
  const int fd = open(file, O_RDONLY);
  if (fd < 0) return 0;
  const int busy = flock(fd, LOCK_EX | LOCK_NB) != 0 && errno == EWOULDBLOCK;
  close(fd);
  return busy;
}

/* Whether every --set of a restart of file names one of RESTART_KEYS: 0,
 * else 2 with the allowed keys on stderr. */
static int restart_sets_ok(const char *file, int nset, const char *const *set) {
  for (int i = 0; i < nset; i++) {
    size_t k = 0, nk = sizeof RESTART_KEYS / sizeof RESTART_KEYS[0];
    const size_t len = strcspn(set[i], "=");
    while (k < nk && !(strlen(RESTART_KEYS[k]) == len && !strncmp(set[i], RESTART_KEYS[k], len)))
      k++;
    if (k == nk) { /* the allowed keys listed from RESTART_KEYS, the one list */
      fprintf(stderr, "vesica run: --restart %s: --set %s: a restart may change only ", file,
              set[i]);
      cli_restart_keys_print(stderr, 0, 0, 0,
                             "(the other keys define the setup and the steps already taken)\n");
      return 2;
    }
  }
  return 0;
}

/* The file verified read-only before a restart writes to it (nothing is
 * written to a file that does not verify): its problem text, counted
 * groups, and the snapshot it continues from (from >= 0, else the last)
 * with the series rows, references and remeshings under it. *S: the
 * snapshots it continues after (from + 1, or all). 0, or 2 with the corrupt
 * dataset named and the last intact snapshot offered. */
static int restart_verify(const char *file, int from, int quiet, int *S) {
  char err[2048] = "";
  ves_io *ro = NULL;
  if (ves_io_open(file, VES_IO_CHECK, &ro, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica run: --restart %s\n", err);
    return 2;
  }
  const int n = ves_io_snapshots(ro), K = from >= 0 ? from : n - 1;
  int rc = 0;
  if (n < 1) {
    fprintf(stderr, "vesica run: --restart %s: no snapshot to continue from\n", file);
    rc = 2;
  } else if (K >= n) {
    fprintf(stderr, "vesica run: --restart %s: --from-snapshot %d: the file has snapshots 0..%d\n",
            file, K, n - 1);
    rc = 2;
  } else if (ves_io_verify_snapshot(ro, K) != VES_OK) {
    const int J = ves_io_last_intact(ro, K);
    ves_io_snapinfo si;
    fprintf(stderr, "vesica run: --restart %s: corrupt: %s", file, ves_io_corruption(ro));
    if (J >= 0 && ves_io_read_snapshot(ro, J, NULL, NULL, NULL, &si) == VES_OK)
      fprintf(stderr,
              "; snapshot %d (step %ld, t* = %.6g) is intact: vesica run --restart %s "
              "--from-snapshot %d continues from it\n",
              J, si.state.nstep, si.state.t, file, J);
    else
      fprintf(stderr, "; no snapshot before it is intact\n");
    rc = 2;
  } else if (!quiet && ves_io_note(ro)[0]) {
    fprintf(stderr, "vesica run: --restart %s: note: %s\n", file, ves_io_note(ro));
  }
  *S = K + 1;
  ves_io_close(&ro);
  return rc;
}

/* Continue FILE.h5 from its last snapshot, with the overrides set[nset]
 * (RESTART_KEYS only; recorded in the file). */
int cli_run_restart(run_ctx *r, const char *file, int nset, const char *const *set) {
  char err[1024] = "";
  r->label = file;
  snprintf(r->out, sizeof r->out, "%s", file);
  char xdmf[PATH_MAX], why[128];
  if (!ves_io_xdmf_name_ok(file, why, sizeof why)) {
    fprintf(stderr,
            "vesica run: --restart %s: %s, so its XDMF file could not refer to it: rename the "
            "file\n",
            file, why);
    return 2;
  }
  ves_io_xdmf_path(file, xdmf, sizeof xdmf);
  int rc = cli_check_writable("run", "--restart", xdmf);
  if (rc) return rc;
  if (ves_io_cut_short(file, NULL, NULL) && (rc = salvage(file, r->quiet))) return rc;
  if (ves_io_end_behind(file, NULL, NULL) && !in_use(file)) {
    /* data past the recorded end: read-only first (HDF5 cuts a file it
     * closes after writing to its recorded end), salvaged when HDF5 cannot
     * read it (metadata a flush that stopped half-way left pointing there) */
    ves_io *probe = NULL;
    if (ves_io_open(file, VES_IO_READ, &probe, err, sizeof err) != VES_OK &&
        (rc = salvage(file, r->quiet)))
      return rc;
    ves_io_close(&probe);
  }
  int S = 0;
  if ((rc = restart_verify(file, r->from_snapshot, r->quiet, &S))) return rc;
  ves_status st = ves_io_open(file, VES_IO_WRITE, &r->io, err, sizeof err);
  if (st != VES_OK) {
    fprintf(stderr, "vesica run: --restart %s\n", err);
    return 2;
  }
  const ves_io_info *in = ves_io_get_info(r->io);
  if (S > ves_io_snapshots(r->io)) {
    fprintf(stderr, "vesica run: --restart %s: changed while it was verified\n", file);
    return 2;
  }
  if (ves_config_load_text(in->problem, in->source, &r->cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica run: --restart %s: the stored problem: %s\n", file, err);
    return 2;
  }
  if ((rc = restart_sets_ok(file, nset, set))) return rc;
  if (nset && ves_config_set(&r->cfg, nset, set, err, sizeof err) != VES_OK) {
    fprintf(stderr, "vesica run: --restart %s: %s\n", file, err);
    return 2;
  }
  ves_io_snapinfo si;
  char pre[PATH_MAX + 32];
  snprintf(pre, sizeof pre, "vesica run: --restart %s", file);
  /* Already at t_end (the problem's, or the one a restart before recorded):
   * said before the setup is rebuilt (minutes at the paper's scale),
   * nothing written; the integrator's own test (integrate.c). A file that
   * lacks the references its snapshot needs goes on to cli_rebuild_at's
   * refusal. */
  if (ves_io_read_snapshot(r->io, S - 1, NULL, NULL, NULL, &si) == VES_OK &&
      si.reconnections <= ves_io_references(r->io) &&
      si.state.t >= r->cfg.t_end - 1e-12 * (1.0 + fabs(si.state.t))) {
    fprintf(stderr,
            "vesica run: --restart %s: the run is at t* = %.9g, its [time] t_end = %.9g%s: "
            "nothing to integrate; --set time.t_end=T continues it to T\n",
            file, si.state.t, r->cfg.t_end, nset ? "" : " (recorded in the file)");
    return 0;
  }
  if ((rc = cli_rebuild_at(r, pre, S - 1, &si))) return rc;
  if ((st = ves_io_truncate_snapshots(r->io, S)) != VES_OK ||
      (st = ves_io_truncate(r->io, si.rows)) != VES_OK ||
      (st = ves_io_truncate_references(r->io, si.reconnections)) != VES_OK ||
      (st = ves_io_truncate_remeshes(r->io, ves_sim_remeshings(r->sim))) != VES_OK ||
      (nset && (st = ves_io_set_problem(r->io, &r->cfg)) != VES_OK) ||
      (st = ves_io_set_setup_seconds(r->io, r->setup->seconds_total)) != VES_OK ||
      (st = ves_io_set_status(r->io, "running")) != VES_OK) {
    fprintf(stderr, "vesica run: --restart %s: cannot write: %s\n", file, cli_io_cause(r->io, st));
    return 3;
  }
  r->wall_offset = si.wall_seconds;
  r->last_snapshot_step = si.state.nstep;
  if (!r->quiet) {
    fprintf(stderr, "vesica run: continuing %s from snapshot %d (step %ld, t* = %.6g)", file, S - 1,
            si.state.nstep, si.state.t);
    for (int i = 0; i < nset; i++) fprintf(stderr, "%s%s", i ? ", " : " with ", set[i]);
    fputc('\n', stderr);
  }
  return cli_loop(r);
}
