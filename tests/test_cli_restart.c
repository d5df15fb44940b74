/* vesica — tests of the program's restarts (build/vesica, run as a child
 * process): a restarted run repeats the uninterrupted one bit for bit,
 * across resets and remeshings and with --set; SIGTERM finishes the step and
 * saves the state; a run killed with SIGKILL leaves a readable file holding
 * every completed step, and can be continued. Run from the repository root. */
#include "cli_test_impl.h"

/* A run that reset its reference configuration continues on the reference
 * the file stores (io.h /references): resets every 2 steps, stopped after 3
 * (last snapshot: step 3, one reset behind it, on reference 0) and
 * restarted, against the same run uninterrupted: the series, the resets,
 * the last y, x and phi bit for bit. The run carries a C0 pulse over its
 * second step: E* jumps up and down with C0, and `info` still calls the
 * energy monotone (rises across a switch do not count). A file whose
 * snapshot has more resets behind it than references stored (a format 1
 * run, or references lost) is refused with exit 2 and left as it was. */
static void test_restart_after_reset(void **state) {
  (void)state;
  char ini[128], part[128], full[128];
  tmp_path(ini, sizeof ini, "reset.ini");
  tmp_path(part, sizeof part, "reset.h5");
  tmp_path(full, sizeof full, "reset_full.h5");
  write_file(ini, "[time]\nt_end = 0.04\nadaptive = 0\n[output]\nsnapshot_every = 2\n"
                  "[reconnect]\nevery = 2\nnodes = motion\n"
                  "[protocol]\nc0_time = 0.005\nc0_after = 3\nc0_until = 0.01\n");
  result r;
  run(&r, "run", ini, TINY, "--out", full, "--quiet", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  run(&r, "run", ini, TINY, "--out", part, "--quiet", "--max-steps", "3", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  ves_io *b = open_ro(part);
  assert_int_equal(ves_io_rows(b), 3);
  int S = ves_io_snapshots(b);
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot(b, S - 1, NULL, NULL, NULL, &si), VES_OK);
  assert_int_equal(si.reconnections, 1); /* the reset after step 2 */
  assert_int_equal(ves_io_references(b), 1);
  double E[3], c0[3];
  assert_int_equal(ves_io_read_series(b, "E", E), VES_OK);
  assert_int_equal(ves_io_read_series(b, "c0", c0), VES_OK);
  printf("# pulse: c0 %g %g %g, E* %.6f %.6f %.6f\n", c0[0], c0[1], c0[2], E[0], E[1], E[2]);
  assert_true(c0[0] == 0 && c0[1] == 3 && c0[2] == 0);
  assert_true(E[1] > E[0] && E[2] < E[1]); /* the jumps that must not count */
  ves_io_close(&b);
  run(&r, "info", part, NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "energy_monotone = yes\n"));
  assert_non_null(strstr(r.out, "references = 1\n"));

  run(&r, "run", "--restart", part, "--quiet", NULL);
  if (r.code) fail_msg("restart after a reset: exit %d: %s", r.code, r.err);
  ves_io *a = open_ro(full);
  b = open_ro(part);
  long R = ves_io_rows(a);
  printf("# resets every 2 steps: uninterrupted %ld steps, %d references; stopped at 3 and "
         "restarted: %ld steps, %d references\n",
         R, ves_io_references(a), ves_io_rows(b), ves_io_references(b));
  assert_true(R == 8 && ves_io_references(a) == 4); /* t_end 0.04 at the TINY dt 5e-3 */
  assert_int_equal(ves_io_rows(b), R);
  assert_int_equal(ves_io_references(b), ves_io_references(a));
  same_series(a, b, R);
  double *ra = series(a, "reconnections"), *rb = series(b, "reconnections");
  assert_memory_equal(ra, rb, (size_t)R * sizeof *ra);
  free(ra), free(rb);
  assert_int_equal(same_last_snapshot(a, b, R), 4);
  ves_io_close(&a), ves_io_close(&b);

  /* references lost: refused, file untouched */
  char err[512];
  assert_int_equal(ves_io_open(part, 1, &b, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_truncate_references(b, 2), VES_OK);
  ves_io_close(&b);
  run(&r, "run", "--restart", part, "--quiet", NULL);
  printf("# restart without its references -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "reset its reference configuration 4 time(s)"));
  b = open_ro(part);
  assert_int_equal(ves_io_rows(b), R); /* untouched */
  assert_int_equal(ves_io_references(b), 2);
  ves_io_close(&b);
  unlink(ini), unlink(part), unlink(full);
}

/* A reset and a remeshing due on the same step (resets every step,
 * remeshings every 2): the remeshing replaces the reset (integrate.c,
 * after_step), and a run stopped after step 3 and restarted continues bit
 * for bit. Before, the remeshing discarded the reset's reference before the
 * file recorded it, and vesica crashed (SIGSEGV) writing it. */
static void test_reset_and_remesh_same_step(void **state) {
  (void)state;
  char ini[128], part[128], full[128];
  tmp_path(ini, sizeof ini, "both.ini");
  tmp_path(part, sizeof part, "both.h5");
  tmp_path(full, sizeof full, "both_full.h5");
  write_file(ini, "[time]\nt_end = 0.03\nadaptive = 0\n[output]\nsnapshot_every = 1\n"
                  "[reconnect]\nevery = 1\n[remesh]\nevery = 2\n");
  run_split(ini, full, part, "3");
  const long R = same_runs(full, part);
  assert_int_equal(R, 6);
  ves_io *a = open_ro(full), *b = open_ro(part);
  double *ra = series(a, "reconnections");
  printf("# resets after each step:");
  for (long k = 0; k < R; k++) printf(" %g", ra[k]);
  printf("; remeshings %d\n", ves_io_remeshes(a));
  /* resets after the odd steps, remeshings after the even ones */
  for (long k = 0; k < R; k++) assert_true(ra[k] == (double)((k + 2) / 2));
  assert_int_equal(ves_io_remeshes(a), 3);
  assert_int_equal(ves_io_remeshes(b), 3);
  free(ra);
  ves_io_close(&a), ves_io_close(&b);
}

/* The flow at the nodes a snapshot holds (io.h ves_io_snapinfo.velocity):
 * with a snapshot every step and no reset, the material at the nodes of
 * consecutive snapshots is the same (one reference), so v dt_prev must be
 * x_k - x_{k-1}, the material's displacement over the step; both come from
 * the same linear map of the same coefficients (y_prev is y^{k-1} copied),
 * so they differ only by the division by dt_prev and the product with it:
 * two roundings, <= 2 eps_mach of |x_k - x_{k-1}|, checked at 1e-12 of its
 * largest entry (a velocity not divided by dt, or taken from the
 * coefficients y instead of x, fails by orders of magnitude). The first
 * snapshot has none; the XDMF file names it for the others only. */
static void test_flow_at_nodes(void **state) {
  (void)state;
  char ini[128], h5[128], xdmf[160];
  tmp_path(ini, sizeof ini, "flow.ini");
  tmp_path(h5, sizeof h5, "flow.h5");
  write_file(ini, "[time]\nt_end = 0.02\nadaptive = 0\n[output]\nsnapshot_every = 1\n");
  result r;
  run(&r, "run", ini, TINY, "--out", h5, "--quiet", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  ves_io *io = open_ro(h5);
  const int S = ves_io_snapshots(io), n = ves_io_get_info(io)->n;
  assert_int_equal(S, 5);
  double *x0 = malloc(2 * (size_t)n * sizeof *x0), *x1 = malloc(2 * (size_t)n * sizeof *x1);
  double *v = malloc(2 * (size_t)n * sizeof *v);
  assert_true(x0 && x1 && v);
  ves_io_snapinfo s0, s1;
  assert_int_equal(ves_io_read_snapshot(io, 0, NULL, x0, NULL, &s0), VES_OK);
  assert_int_equal(ves_io_read_snapshot_velocity(io, 0, n, v), 0); /* none at t = 0 */
  double worst = 0;
  for (int k = 1; k < S; k++) {
    assert_int_equal(ves_io_read_snapshot(io, k, NULL, x1, NULL, &s1), VES_OK);
    assert_int_equal(ves_io_read_snapshot_velocity(io, k, n, v), 1);
    assert_int_equal(s1.reconnections, 0);
    assert_true(s1.state.dt_prev > 0 && fabs(s1.state.t - s0.state.t - s1.state.dt_prev) <= 1e-15);
    double dmax = 0, err = 0;
    for (int i = 0; i < 2 * n; i++) {
      dmax = fmax(dmax, fabs(x1[i] - x0[i]));
      err = fmax(err, fabs(v[i] * s1.state.dt_prev - (x1[i] - x0[i])));
    }
    assert_true(dmax > 0); /* the vesicle moves */
    assert_true(err <= 1e-12 * dmax);
    worst = fmax(worst, err / dmax);
    memcpy(x0, x1, 2 * (size_t)n * sizeof *x0), s0 = s1;
  }
  printf("# flow: |v dt - dx| / max |dx| <= %.2e over %d snapshots\n", worst, S - 1);
  assert_int_equal(ves_io_read_snapshot_velocity(io, 1, n - 1, v), VES_ERR_IO); /* wrong size */
  free(x0), free(x1), free(v);
  ves_io_close(&io);
  /* the XDMF file: a vector attribute in both collections, snapshots 1..S-1 */
  snprintf(xdmf, sizeof xdmf, "%.*s.xdmf", (int)strlen(h5) - 3, h5);
  FILE *f = fopen(xdmf, "r");
  assert_non_null(f);
  char line[1024];
  int vec = 0, first = 0;
  while (fgets(line, sizeof line, f)) {
    vec += strstr(line, "Name=\"velocity\" AttributeType=\"Vector\"") != NULL;
    first += strstr(line, "/snapshots/0/velocity") != NULL;
  }
  fclose(f);
  assert_int_equal(vec, 2 * (S - 1));
  assert_int_equal(first, 0);
}

/* A run with full remeshings (io.h /remeshes) continues across them bit for
 * bit: resets every 2 steps and remeshings every 3 (reset after step 2,
 * remeshing after 3, reset after 5, remeshing after 6). Stopped after step 4
 * (its snapshot on the remeshing of step 3; the reset before it no longer in
 * force), restarted up to step 5 (the snapshot on the reset made after the
 * remeshing, rebuilt on the remeshing's model), restarted to the end, and
 * compared with the uninterrupted run: the series, the remeshings' node
 * sets, the last y, x, phi and integrator state with ==. The remeshings must
 * change the node set (else the test shows nothing about rebuilding it).
 * Kept whole (98 lines): one scenario whose checks build on each other. */
static void test_restart_after_remesh(void **state) {
  (void)state;
  char ini[128], part[128], full[128];
  tmp_path(ini, sizeof ini, "remesh.ini");
  tmp_path(part, sizeof part, "remesh.h5");
  tmp_path(full, sizeof full, "remesh_full.h5");
  write_file(ini, "[time]\nt_end = 0.03\nadaptive = 0\n[output]\nsnapshot_every = 2\n"
                  "[reconnect]\nevery = 2\n[remesh]\nevery = 3\n");
  result r;
  run(&r, "run", ini, TINY, "--out", full, NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  printf("# %s", strstr(r.err, "step 3: remeshing") ? strstr(r.err, "step 3: remeshing") : r.err);
  assert_non_null(strstr(r.err, "step 3: remeshing #1 ("));
  assert_non_null(strstr(r.err, "step 6: remeshing #2 ("));
  { /* the remeshing's wall time and its parts, each >= 0, their sum within the whole */
    const char *parts[] = {"seconds_interface", "seconds_nodes",   "seconds_tables",
                           "seconds_project",   "seconds_correct", "seconds"};
    double v[6], sum = 0;
    hid_t h = H5Fopen(full, H5F_ACC_RDONLY, H5P_DEFAULT),
          g = H5Gopen2(h, "remeshes/0", H5P_DEFAULT);
    assert_true(h >= 0 && g >= 0);
    for (int k = 0; k < 6; k++) {
      hid_t at = H5Aopen(g, parts[k], H5P_DEFAULT);
      assert_true(at >= 0);
      assert_true(H5Aread(at, H5T_NATIVE_DOUBLE, v + k) >= 0);
      H5Aclose(at);
      assert_true(v[k] >= 0);
      if (k < 5) sum += v[k];
    }
    H5Gclose(g), H5Fclose(h);
    printf("# remeshing #1: %.3f s, of which the parts %.3f s\n", v[5], sum);
    assert_true(sum <= v[5] && v[5] > 0);
  }
  run(&r, "run", ini, TINY, "--out", part, "--quiet", "--max-steps", "4", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  run(&r, "run", "--restart", part, "--quiet", "--max-steps", "5", NULL);
  if (r.code) fail_msg("restart on a remeshing: exit %d: %s", r.code, r.err);
  ves_io *b = open_ro(part);
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot_n(b, ves_io_snapshots(b) - 1,
                                          ves_io_snapshot_nodes(b, ves_io_snapshots(b) - 1), NULL,
                                          NULL, NULL, &si),
                   VES_OK);
  printf("# stopped at step %ld: %d resets, %d remeshings\n", si.state.nstep, si.reconnections,
         ves_io_remeshes(b));
  assert_true(si.state.nstep == 5 && si.reconnections == 2 && ves_io_remeshes(b) == 1);
  ves_io_close(&b);
  run(&r, "run", "--restart", part, "--quiet", NULL);
  if (r.code) fail_msg("restart on a reset after a remeshing: exit %d: %s", r.code, r.err);

  ves_io *a = open_ro(full);
  b = open_ro(part);
  const long R = ves_io_rows(a);
  assert_int_equal(R, 6); /* t_end 0.03 at the TINY dt 5e-3 */
  assert_int_equal(ves_io_rows(b), R);
  same_series(a, b, R);
  assert_int_equal(ves_io_remeshes(a), 2);
  assert_int_equal(ves_io_remeshes(b), 2);
  const int n0 = ves_io_get_info(a)->n;
  for (int k = 0; k < 2; k++) { /* the node sets: the same, and not the initial one */
    long sa_, sb_;
    int na, nb, ta, tb;
    assert_int_equal(ves_io_remesh_size(a, k, &sa_, &na, &ta), VES_OK);
    assert_int_equal(ves_io_remesh_size(b, k, &sb_, &nb, &tb), VES_OK);
    assert_true(sa_ == 3 * (k + 1) && sb_ == sa_ && na == nb && ta == tb);
    ves_io_remesh_buf ba = {.n = na}, bb = {.n = nb};
    double *d = malloc(8 * (size_t)na * sizeof *d);
    int *fl = malloc(2 * (size_t)na * sizeof *fl);
    ba.x = d, ba.h = d + 2 * na, ba.phi0c = d + 3 * na, ba.flag = fl;
    bb.x = d + 4 * na, bb.h = d + 6 * na, bb.phi0c = d + 7 * na, bb.flag = fl + na;
    assert_int_equal(ves_io_read_remesh(a, k, &ba), VES_OK);
    assert_int_equal(ves_io_read_remesh(b, k, &bb), VES_OK);
    assert_memory_equal(d, d + 4 * na, 4 * (size_t)na * sizeof *d);
    assert_memory_equal(fl, fl + na, (size_t)na * sizeof *fl);
    if (k == 0) {
      double *X = malloc(2 * (size_t)n0 * sizeof *X);
      assert_int_equal(ves_io_read_mesh(a, X, NULL), VES_OK);
      printf("# remeshing 1: %d -> %d nodes\n", n0, na);
      assert_true(na != n0 || memcmp(X, ba.x, 2 * (size_t)n0 * sizeof *X)); /* a new node set */
      free(X);
    }
    free(d), free(fl);
  }
  (void)same_last_snapshot(a, b, R);
  /* the header's node count no longer reads such a snapshot: an error, not an overrun */
  const int S = ves_io_snapshots(a), n = ves_io_snapshot_nodes(a, S - 1);
  if (n != n0) {
    double *y = malloc(2 * (size_t)(n > n0 ? n : n0) * sizeof *y);
    assert_int_equal(ves_io_read_snapshot(a, S - 1, y, NULL, NULL, NULL), VES_ERR_IO);
    free(y);
  }
  ves_io_close(&a), ves_io_close(&b);
  run(&r, "info", part, NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "remeshings = 2\n"));
  assert_non_null(strstr(r.out, "interface_area_final = "));
  unlink(ini), rm_run(part), rm_run(full);
}

/* freeze_hessian = 2 keeps the factorization across steps; every snapshot
 * is a restart point (the next step builds its matrix), so a restart from
 * a regular snapshot repeats the uninterrupted run bit for bit. Fixed dt
 * (the matrix is reused only while dt stays within 1.25x), snapshots every
 * 3 steps, the interrupted run stopped at step 3; the run must really
 * reuse (fewer matrices than steps), else the test proves nothing. (A stop
 * between snapshots, --max-steps N or a signal, writes a snapshot the
 * uninterrupted run does not have: a restart from it is the same within
 * the step tolerance, not bit for bit; README.) */
static void test_restart_bitwise_freeze2(void **state) {
  (void)state;
  char ini[128], full[128], part[128];
  tmp_path(ini, sizeof ini, "tiny2.ini");
  tmp_path(full, sizeof full, "full2.h5");
  tmp_path(part, sizeof part, "part2.h5");
  write_file(ini, "[time]\nt_end = 0.04\nadaptive = 0\n" /* TINY's dt* 5e-3: 8 steps */
                  "[solver]\nfreeze_hessian = 2\n[output]\nsnapshot_every = 3\n");
  run_split(ini, full, part, "3");
  const long R = same_runs(full, part);
  assert_int_equal(R, 8);
  result r;
  run(&r, "info", full, NULL);
  assert_int_equal(r.code, 0);
  const char *h = strstr(r.out, "hessian_evaluations = ");
  assert_non_null(h);
  const long nh = atol(h + strlen("hessian_evaluations = "));
  printf("# freeze 2: %ld matrices in %ld steps\n", nh, R);
  assert_true(nh < R); /* the factorization was reused */
  unlink(ini), rm_run(full), rm_run(part);
}

static void test_restart_bitwise(void **state) {
  (void)state;
  char ini[128], full[128], part[128];
  tmp_path(ini, sizeof ini, "tiny.ini");
  tmp_path(full, sizeof full, "full.h5");
  tmp_path(part, sizeof part, "part.h5");
  write_file(ini, "[time]\nt_end = 0.1\n[output]\nsnapshot_every = 2\n");
  run_split(ini, full, part, "3");
  const long R = same_runs(full, part);
  printf("# uninterrupted: %ld steps, the same after an interruption at 3 and a restart\n", R);
  assert_true(R >= 5); /* the restart had steps to repeat */
  ves_io *b = open_ro(part);
  assert_string_equal(ves_io_get_info(b)->status, "finished");
  ves_io_close(&b);
  result r;

  /* info: the stable keys */
  run(&r, "info", part, NULL);
  assert_int_equal(r.code, 0);
  const char *keys[] = {"backend = newton\n",  "steps = ",
                        "t_final = 0.1\n",     "energy_initial = ",
                        "energy_final = ",     "energy_monotone = yes\n",
                        "area_drift_max = ",   "reduced_volume_final = ",
                        "reconnections = 0\n", "newton_iterations = ",
                        "wall_seconds = ",     "geometry.epsilon = 0.2\n",
                        "time.t_end = 0.1\n"};
  for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++)
    if (!strstr(r.out, keys[i])) fail_msg("info lacks '%s':\n%s", keys[i], r.out);

  /* plot: three PNG files; with gnuplot missing, exit 3 and the reason */
  run(&r, "plot", part, "--outdir", tmpdir, NULL);
  if (r.code) fail_msg("plot: exit %d: %s", r.code, r.err);
  for (int k = 0; k < VES_PLOT_NFIG; k++) {
    char png[256], sig[8] = {0};
    snprintf(png, sizeof png, "%s/part_%s.png", tmpdir, ves_plot_figures[k]);
    FILE *f = fopen(png, "rb");
    assert_non_null(f);
    assert_int_equal(fread(sig, 1, 8, f), 8);
    fclose(f);
    assert_memory_equal(sig, "\x89PNG\r\n\x1a\n", 8);
    unlink(png);
  }
  char *args[] = {"plot", part, "--outdir", tmpdir, NULL};
  collect(spawn(args, "/nonexistent"), &r);
  printf("# plot without gnuplot -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 3);
  assert_non_null(strstr(r.err, "gnuplot failed"));
  unlink(ini), rm_run(full), rm_run(part);
}

/* A restart may change the solver settings and t_end (recorded in the file:
 * info and a later restart see them), nothing else. */
static void test_restart_set(void **state) {
  (void)state;
  char ini[128], out[128];
  tmp_path(ini, sizeof ini, "rset.ini");
  tmp_path(out, sizeof out, "rset.h5");
  write_file(ini, "[time]\nt_end = 0.1\n");
  result r;
  run(&r, "run", ini, TINY, "--out", out, "--quiet", "--max-steps", "2", NULL);
  assert_int_equal(r.code, 0);
  run(&r, "run", "--restart", out, "--set", "geometry.epsilon=0.1", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "a restart may change only"));
  { /* run --help names the same keys (both print the one list) */
    char keys[1024];
    snprintf(keys, sizeof keys, "%s", strstr(r.err, "may change only ") + 16);
    char *end = strstr(keys, " (the other keys");
    assert_non_null(end);
    *end = '\0';
    run(&r, "run", "--help", NULL);
    assert_int_equal(r.code, 0);
    int n = 0;
    for (char *k = strtok(keys, ", "); k; k = strtok(NULL, ", "))
      if (strcmp(k, "and")) n++, assert_non_null(strstr(r.out, k));
    assert_true(n >= 7); /* solver.tol ... time.t_end */
  }
  run(&r, "run", "--restart", out, "--set", "solver.max_iter=0", NULL);
  assert_int_equal(r.code, 2); /* out of range */
  run(&r, "run", "--restart", out, "--set", "solver.max_iter=7", "--set", "time.t_end=0.03", NULL);
  if (r.code) fail_msg("restart: exit %d: %s", r.code, r.err);
  assert_non_null(strstr(r.err, "with solver.max_iter=7, time.t_end=0.03"));
  run(&r, "info", out, NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "solver.max_iter = 7\n"));
  assert_non_null(strstr(r.out, "time.t_end = 0.03\n"));
  assert_non_null(strstr(r.out, "t_final = 0.03\n"));
  assert_non_null(strstr(r.out, "status = finished\n"));
  /* a later restart keeps them: t_end 0.03 is reached, nothing to do, said
   * before any setup, nothing written (its size, status and t_final; the
   * modification time moves: the library's read-write open and close) */
  struct stat before, after;
  assert_int_equal(stat(out, &before), 0);
  run(&r, "run", "--restart", out, NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.err, "nothing to integrate; --set time.t_end=T continues it"));
  assert_non_null(strstr(r.err, "t_end = 0.03 (recorded in the file)"));
  assert_int_equal(stat(out, &after), 0);
  assert_true(after.st_size == before.st_size);
  run(&r, "info", out, NULL);
  assert_non_null(strstr(r.out, "t_final = 0.03\n"));
  assert_non_null(strstr(r.out, "status = finished\n"));
  run(&r, "run", "--restart", out, "--set", "time.t_end=0.04", NULL); /* continues */
  if (r.code) fail_msg("restart to 0.04: exit %d: %s", r.code, r.err);
  run(&r, "info", out, NULL);
  assert_non_null(strstr(r.out, "t_final = 0.04\n"));
  /* time.dt_max: a lower cap holds from the first step after the restart,
   * though the stored dt is above it (checked on the last row first) */
  ves_io *f = open_ro(out);
  const long R0 = ves_io_rows(f);
  double dt0[64];
  assert_true(R0 <= 64);
  assert_int_equal(ves_io_read_series(f, "dt", dt0), VES_OK);
  ves_io_close(&f);
  assert_true(dt0[R0 - 1] > 5e-3 * (1 + 1e-9)); /* the controller grew it past the new cap */
  run(&r, "run", "--restart", out, "--quiet", "--set", "time.dt_max=5e-3", "--set",
      "time.t_end=0.06", NULL);
  if (r.code) fail_msg("restart with dt_max: exit %d: %s", r.code, r.err);
  f = open_ro(out);
  const long R1 = ves_io_rows(f);
  double dt1[64];
  assert_true(R1 > R0 && R1 <= 64);
  assert_int_equal(ves_io_read_series(f, "dt", dt1), VES_OK);
  ves_io_close(&f);
  for (long i = R0; i < R1; i++) assert_true(dt1[i] <= 5e-3); /* the cap itself, not rounded */
  run(&r, "run", "--restart", out, "--set", "time.dt_max=1e-3", NULL); /* below dt_initial */
  assert_int_equal(r.code, 2);
  unlink(ini), rm_run(out);
}

static void test_sigterm(void **state) {
  (void)state;
  char ini[128], out[128];
  tmp_path(ini, sizeof ini, "term.ini");
  tmp_path(out, sizeof out, "term.h5");
  write_file(ini, "[time]\nt_end = 100\nadaptive = 0\ndt_max = 5e-3\n"
                  "[output]\nsnapshot_every = 1000000\n");
  char *args[] = {"run", ini, TINY, "--out", out, "--quiet", NULL};
  pid_t pid = spawn(args, NULL);
  assert_true(wait_rows(out, 2) >= 2);
  /* the file of a running run is neither overwritten (even with --force)
   * nor continued */
  result r;
  char *again[] = {"run", ini, TINY, "--out", out, "--quiet", "--force", NULL};
  collect_tag(spawn_tag(again, NULL, "again"), &r, "again");
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "in use"));
  char *cont[] = {"run", "--restart", out, NULL};
  collect_tag(spawn_tag(cont, NULL, "again"), &r, "again");
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "in use"));
  assert_int_equal(kill(pid, SIGTERM), 0);
  collect(pid, &r);
  printf("# SIGTERM -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 128 + SIGTERM);
  assert_non_null(strstr(r.err, "--restart"));
  ves_io *io = open_ro(out);
  long R = ves_io_rows(io);
  ves_io_snapinfo si;
  assert_string_equal(ves_io_get_info(io)->status, "stopped");
  assert_int_equal(ves_io_snapshots(io), 2); /* t = 0 and the state at the signal */
  assert_int_equal(ves_io_read_snapshot(io, 1, NULL, NULL, NULL, &si), VES_OK);
  assert_int_equal(si.state.nstep, R); /* nothing lost: a restart continues from here */
  ves_io_close(&io);
  unlink(ini), rm_run(out);
}

/* ---- SIGKILL mid-run --------------------------------------------------------- */

static void test_sigkill(void **state) {
  (void)state;
  char ini[128], out[128];
  tmp_path(ini, sizeof ini, "long.ini");
  tmp_path(out, sizeof out, "killed.h5");
  /* many small constant steps: the run is far from done when killed; the
   * only snapshot is the initial one, so the restart below recomputes every
   * step the killed run had completed */
  write_file(ini, "[time]\nt_end = 100\nadaptive = 0\ndt_max = 5e-3\n"
                  "[output]\nsnapshot_every = 1000000\n");
  char *args[] = {"run", ini, TINY, "--out", out, "--quiet", NULL};
  pid_t pid = spawn(args, NULL);
  /* at least 5 completed steps, read from the file as it grows */
  long rows = wait_rows(out, 5);
  assert_int_equal(kill(pid, SIGKILL), 0);
  result r;
  collect(pid, &r);
  assert_int_equal(r.code, 128 + SIGKILL);
  assert_true(rows >= 5);

  /* the file opens and holds every completed step */
  ves_io *io = open_ro(out);
  long R = ves_io_rows(io);
  printf("# killed after >= %ld steps: the file holds %ld steps, %d snapshots, status %s\n", rows,
         R, ves_io_snapshots(io), ves_io_get_info(io)->status);
  assert_true(R >= rows);
  assert_string_equal(ves_io_get_info(io)->status, "running");
  double *step = series(io, "step"), *t = series(io, "t"), *E = series(io, "E");
  for (long i = 0; i < R; i++) {
    assert_true(step[i] == (double)(i + 1));
    assert_true(fabs(t[i] - 5e-3 * (i + 1)) < 1e-12); /* constant steps */
    double prev = i ? E[i - 1] : ves_io_get_info(io)->E0;
    assert_true(isfinite(E[i]) && E[i] <= prev + 1e-10 * fabs(prev)); /* the integrator's test */
  }
  assert_int_equal(ves_io_snapshots(io), 1);
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot(io, 0, NULL, NULL, NULL, &si), VES_OK);
  assert_true(si.state.nstep == 0 && si.state.t == 0.0);
  ves_io_close(&io);
  run(&r, "info", out, NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "status = running\n"));

  /* continued from its last snapshot (t = 0), it recomputes the R steps
   * exactly as the killed run had them */
  char copy[128], cmd[512];
  tmp_path(copy, sizeof copy, "killed_copy.h5");
  snprintf(cmd, sizeof cmd, "cp %s %s", out, copy);
  assert_int_equal(system(cmd), 0);
  char max[32];
  snprintf(max, sizeof max, "%ld", R);
  run(&r, "run", "--restart", out, "--max-steps", max, "--quiet", NULL);
  if (r.code) fail_msg("restart of the killed run: exit %d: %s", r.code, r.err);
  ves_io *a = open_ro(copy), *b = open_ro(out);
  assert_int_equal(ves_io_rows(b), R);
  same_series(a, b, R);
  ves_io_close(&a), ves_io_close(&b);
  free(step), free(t), free(E);
  unlink(ini), rm_run(out), rm_run(copy);
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_cli_restart")) return 1;
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_restart_bitwise),
      cmocka_unit_test(test_restart_bitwise_freeze2),
      cmocka_unit_test(test_restart_after_reset),
      cmocka_unit_test(test_restart_after_remesh),
      cmocka_unit_test(test_reset_and_remesh_same_step),
      cmocka_unit_test(test_flow_at_nodes),
      cmocka_unit_test(test_restart_set),
      cmocka_unit_test(test_sigterm),
      cmocka_unit_test(test_sigkill),
  };
  // clang-format on
  return cmocka_run_group_tests_name("cli_restart", tests, setup_all, teardown_all);
}
