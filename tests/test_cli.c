/* vesica — tests of the program (build/vesica, run as a child process):
 * every problem file passes `check`; malformed input of every kind exits with
 * code 2, a message naming the cause and no output left behind; help,
 * spectrum, the progress line, the series, a numerical failure, the size
 * estimate of a setup; other tools read the output. Run from the repository
 * root (make test does); the program is found next to this test's folder. */
#include "cli_test_impl.h"

/* Every problems/NAME.ini at its own resolution, two checks at a time (the
 * setup is mostly single-threaded), against the values stored when the
 * problem files last changed (data/check_reference.tsv; regenerate a row
 * with vesica check when a problem file or the discretization changes on
 * purpose). Tolerances: the node count exactly (the node generation is
 * deterministic: a fixed seed, CGAL's exact predicates); E* to 1e-8
 * relative (printed to 1e-9 absolute, E* ~ 6-30; the sums over ~1e5
 * quadrature points and the L2 projection's refined solve vary with the
 * thread count and BLAS kernels at ~1e-12, while any change of the
 * discretization moves E* by more than 1e-5: a node spacing 1% coarser
 * changes it by ~1e-4 at these resolutions, docs/results.md, "Convergence
 * in ε and h"); the area and
 * volume ratios and the reduced volume to 1e-10 (printed to 1e-12 and
 * 1e-9; the same sums). */
static void test_problem_files_check(void **state) {
  (void)state;
  DIR *d = opendir("problems");
  if (!d) fail_msg("run from the repository root: no problems/ folder here");
  char paths[64][PATH_MAX];
  int count = 0;
  struct dirent *e;
  while ((e = readdir(d)) && count < 64) {
    size_t l = strlen(e->d_name);
    if (l > 4 && !strcmp(e->d_name + l - 4, ".ini")) {
      snprintf(paths[count], sizeof paths[0], "problems/%.*s", (int)(PATH_MAX - 16), e->d_name);
      char text[4096] = ""; /* study files (a [study] section) are for vesica study */
      slurp(paths[count], text, sizeof text);
      if (!strstr(text, "\n[study]") && strncmp(text, "[study]", 7)) {
        /* each problem file states its resolution (docs/manual.md, [geometry]) */
        if (!strstr(text, "\nresolution = ")) fail_msg("%s: no resolution line", paths[count]);
        count++;
      }
    }
  }
  closedir(d);
  for (int i = 0; i < count; i += 2) {
    pid_t pid[2];
    char tag[2][16];
    for (int j = 0; j < 2 && i + j < count; j++) {
      char *args[] = {"check", paths[i + j], NULL};
      snprintf(tag[j], sizeof tag[j], "check%d", j);
      pid[j] = spawn_tag(args, NULL, tag[j]);
    }
    for (int j = 0; j < 2 && i + j < count; j++) {
      result r;
      collect_tag(pid[j], &r, tag[j]);
      const char *keys[] = {
          "nodes = ", "energy = ", "area_ratio = ", "volume_ratio = ", "reduced_volume = "};
      const double tol[] = {0, 1e-8, 1e-10, 1e-10, 1e-10}; /* energy relative, the rest absolute */
      char val[5][32];
      double got[5], want[5];
      for (int k = 0; k < 5; k++) {
        value_of(r.out, keys[k], val[k], sizeof val[k]);
        got[k] = strtod(val[k], NULL);
      }
      printf("# check\t%s\t%s\t%s\t%s\t%s\t%s\t(exit %d)\n", paths[i + j], val[0], val[1], val[2],
             val[3], val[4], r.code);
      if (r.code != 0) fail_msg("vesica check %s: exit %d: %s", paths[i + j], r.code, r.err);
      if (stored_check(paths[i + j], want))
        fail_msg("%s: no stored values in data/check_reference.tsv", paths[i + j]);
      for (int k = 0; k < 5; k++) {
        const double err = k == 1 ? fabs(got[k] / want[k] - 1) : fabs(got[k] - want[k]);
        if (!(err <= tol[k]))
          fail_msg("vesica check %s: %s%s, stored %.12g (difference %.2e > %.0e)", paths[i + j],
                   keys[k], val[k], want[k], err, tol[k]);
      }
    }
  }
  assert_true(count >= 8); /* sphere, oblate, prolate, cup, prolate_c0, 3 deflations */
}

/* Kept whole (154 lines): one scenario whose checks build on each other. */
static void test_malformed_input(void **state) {
  (void)state;
  char ini[128];
  tmp_path(ini, sizeof ini, "bad.ini");
  int cases = 0;
#define BAD(text, frag1, frag2) (expect_bad_run(text, NULL, 0, frag1, frag2), cases++)
#define BADX(text, frag1, frag2, ...)                                                              \
  do {                                                                                             \
    const char *x_[] = {__VA_ARGS__};                                                              \
    expect_bad_run(text, x_, (int)(sizeof x_ / sizeof x_[0]), frag1, frag2);                       \
    cases++;                                                                                       \
  } while (0)
  /* the problem file itself: the message names the file, the key, the reason */
  BAD("[geometri]\nepsilon = 0.1\n", "[geometri]: unknown section", ini);
  BAD("[geometry]\nepsilom = 0.1\n", "epsilom: unknown key", ini);
  BAD("[geometry]\nepsilon = abc\n", "epsilon", "not a number");
  BAD("[geometry]\nepsilon = 0.9\n", "epsilon", "out of range");
  BAD("[shape]\nmode = 2.5\n", "mode", "not an integer");
  BAD("[shape]\ntype = spheroid\nreduced_volume = 1.2\n", "reduced_volume", "out of range");
  BAD("[geometry]\nepsilon = 0.3\n", "epsilon", "too large for the box");
  BAD("[geometry]\nbox_r = 0.5\n", "box_r", "do not fit");
  BAD("[shape]\ntype = spheroid\n[geometry]\nbox_z = 0.85\n", "box_z = 0.85", "does not fit");
  BAD("[time]\ndt_initial = 1\ndt_max = 0.1\n", "dt_initial", "dt_min, dt_max");
  BAD("[solver]\nbackend = cg\n", "backend", "ipopt|nlopt|newton|euler");
  BAD("[protocol]\nvolume_rate = -1\nvolume_final = 0.8\n[constraints]\nvolume = 0\n",
      "volume_rate", "volume = 1");
  BAD("[protocol]\nvolume_rate = -1\nvolume_final = 1.2\n", "volume_final", "below 1");
  BAD("[protocol]\nc0_after = 5\n", "c0_after", "c0_time");
  BAD("[protocol]\nc0_time = 5\nc0_after = 2\n[time]\nt_end = 1\n", "c0_time", "t_end");
  BAD("[protocol]\nc0_until = 0.5\n", "c0_until", "c0_time");
  /* a band too wide for the shape's curvature is bad input, found in the setup */
  BAD("[shape]\ntype = spheroid\nreduced_volume = 0.8\norientation = prolate\n"
      "[geometry]\nepsilon = 0.08\nband = 5.5\nbox_z = 2.5\n",
      "band*epsilon = 0.44", "radius of curvature");
  BAD("epsilon = 0.1\n[geometry]\n", "epsilon", "outside a section");
  BAD("[geometry\nepsilon = 0.1\n", ini, "line 1: '[geometry': a section header needs a");
  BAD("[geometry]\nepsilon = 0.1\nepsilon = 0.2\n", "line 3", "duplicate key");
  BAD("[time]\nt_end = 1\n[time]\n", "line 3: [time]", "duplicate section");
  BAD("[shape]\ntype = curve\n", "points", "needs a points file");
  BAD("[shape]\ntype = curve\npoints = nowhere.txt\n", "nowhere.txt", "cannot open");
  /* the syntax, through the program: the line and the cause */
  BAD("[geometry]\nEPSILON = 0.02\nepsilon = 0.03\n", "line 3: [geometry] epsilon",
      "duplicate key (first at line 2)");
  BAD("[geometry]\nepsilon 0.02\n", "line 2: 'epsilon 0.02'", "expected key = value");
  BAD("[geometry]\n= 0.02\n", "line 2: '= 0.02'", "not a key name");
  BAD("[]\n", "line 1: '[]'", "not a section name");
  BAD("\n\n[geometry]\nepsilon = abc\n", "line 4: [geometry] epsilon = 'abc'", "not a number");
  BAD("[shape]\nnope = 1\n", "line 2: [shape] nope", "unknown key");
  BAD("\xef\xbb\xbf[geometry]\nepsilon = 0.9\n", "line 2: [geometry] epsilon = '0.9'",
      "out of range");
  BAD("[geometry]\r\nepsilon = 2e\r\n", "line 2: [geometry] epsilon = '2e'", "not a number");
  BAD("[geometry]\nepsilon = 0.1 0.2\n", "epsilon = '0.1 0.2'", "not a number");
  BAD("[geometry]\nepsilon =\n", "line 2: [geometry] epsilon = ''", "no value");
  /* values: out of range, not a number, not an integer, not a choice */
  BAD("[time]\nt_end = -1\n", "[time] t_end = '-1'", "out of range");
  BAD("[time]\nt_end = 0\n", "[time] t_end = '0'", "out of range");
  BAD("[time]\ndt_min = 0\n", "[time] dt_min = '0'", "out of range");
  BAD("[time]\nadaptive = 2\n", "[time] adaptive = '2'", "out of range");
  BAD("[time]\nadaptive = yes\n", "[time] adaptive = 'yes'", "not a number");
  BAD("[material]\nk = 0\n", "[material] k = '0'", "out of range");
  BAD("[material]\nk = -1\n", "[material] k = '-1'", "out of range");
  BAD("[material]\nmu = nan\n", "[material] mu = 'nan'", "not a number");
  BAD("[geometry]\nepsilon = inf\n", "epsilon = 'inf'", "not a number");
  BAD("[geometry]\nepsilon = 1e400\n", "epsilon = '1e400'", "not a number");
  BAD("[geometry]\nepsilon = 0x10\n", "epsilon = '0x10'", "out of range");
  BAD("[geometry]\nh_band = -0.5\n", "[geometry] h_band = '-0.5'", "out of range");
  BAD("[shape]\ntype = cube\n", "[shape] type = 'cube'", "sphere|spheroid|discocyte|curve");
  BAD("[shape]\norientation = sideways\n", "orientation = 'sideways'", "oblate|prolate");
  BAD("[shape]\ndelta = 2\n", "[shape] delta = '2'", "out of range");
  BAD("[output]\nsnapshot_every = 0\n", "snapshot_every = '0'", "out of range");
  BAD("[output]\nsnapshot_every = 1.5\n", "snapshot_every = '1.5'", "not an integer");
  BAD("[solver]\ntol = 0\n", "[solver] tol = '0'", "out of range");
  BAD("[solver]\nmax_iter = -3\n", "[solver] max_iter = '-3'", "out of range");
  BAD("[solver]\nfreeze_hessian = 7\n", "freeze_hessian = '7'", "out of range");
  BAD("[reconnect]\nevery = -1\n", "[reconnect] every = '-1'", "out of range");
  BAD("[reconnect]\nnodes = random\n", "nodes = 'random'", "coefficients|motion");
  BAD("[constraints]\nvolume = 2\n", "[constraints] volume = '2'", "out of range");
  /* curves the shape cannot use: named before any setup (a self-crossing
   * curve would otherwise run with band_layers = 0 and a wrong area) */
  char cross[160], north[160];
  snprintf(cross, sizeof cross, "%s/cross.txt", tmpdir);
  snprintf(north, sizeof north, "%s/north.txt", tmpdir);
  write_file(cross, "0 1\n1 0\n1 1\n0.3 -0.5\n0 -1\n");
  write_file(north, "0 -1\n0.7 -0.7\n1 0\n0.7 0.7\n0 1\n");
  BAD("[shape]\ntype = curve\npoints = cross.txt\n[geometry]\nband_layers = 0\n", "cross.txt",
      "crosses itself");
  BAD("[shape]\ntype = curve\npoints = cross.txt\n", "cross.txt", "crosses itself");
  BAD("[shape]\ntype = curve\npoints = north.txt\n", "north.txt",
      "from the north pole (the larger Z) to the south pole");
  unlink(cross), unlink(north);
  /* arguments */
  BAD(NULL, "usage", NULL);
  BADX(NULL, "/nonexistent/problem.ini", "cannot open", "/nonexistent/problem.ini");
  BADX(NULL, tmpdir, "is a folder, not a problem file", tmpdir); /* no DIR.h5 run */
  BADX("[geometry]\n", "--backend 'cg'", "not one of", "--backend", "cg");
  BADX("[geometry]\n", "--set", "section.key=value", "--set", "geometry.epsilon");
  BADX("[geometry]\n", "[geometry] nope", "unknown key", "--set", "geometry.nope=1");
  BADX("[geometry]\n", "--set", "out of range", "--set", "geometry.epsilon=-1");
  BADX("[geometry]\n", "--max-steps '0'", "positive integer", "--max-steps", "0");
  BADX("[geometry]\n", "--frobnicate", "unknown option", "--frobnicate");
  BADX("[geometry]\n", "--restart", "no CONFIG.ini", "--restart", "x.h5");
  printf("# %d malformed runs\n", cases);
  assert_true(cases >= 60); /* each exit 2, the cause named, no output left */

  /* --out into a missing folder: named, exit 2 */
  write_file(ini, "[geometry]\n");
  result r;
  run(&r, "run", ini, "--out", "/nonexistent/folder/x.h5", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "/nonexistent/folder"));
  assert_non_null(strstr(r.err, "does not exist"));
  cases++;

  /* files that are not output files: info, plot and restart refuse them */
  char h5[128], text[128];
  tmp_path(text, sizeof text, "text.h5");
  write_file(text, "not hdf5\n");
  tmp_path(h5, sizeof h5, "foreign.h5");
  hid_t f = H5Fcreate(h5, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  assert_true(f >= 0);
  H5Fclose(f);
  struct {
    const char *cmd, *file, *frag;
  } files[] = {
      {"info", "/nonexistent.h5", "cannot open"}, {"info", text, "not an HDF5 file"},
      {"info", h5, "not a vesica output file"},   {"plot", "/nonexistent.h5", "cannot open"},
      {"plot", text, "not an HDF5 file"},         {"run", text, "not an HDF5 file"},
      {"run", h5, "not a vesica output file"}};
  for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
    if (!strcmp(files[i].cmd, "run"))
      run(&r, "run", "--restart", files[i].file, NULL);
    else
      run(&r, files[i].cmd, files[i].file, NULL);
    printf("# %s %s -> %d: %s", files[i].cmd, files[i].file, r.code, r.err);
    assert_int_equal(r.code, 2);
    assert_non_null(strstr(r.err, files[i].frag));
    assert_non_null(strstr(r.err, files[i].file));
    cases++;
  }
  /* commands */
  run(&r, "frobnicate", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "unknown command 'frobnicate'"));
  run(&r, "check", ini, "--phi0", "exact", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "--phi0"));
  run(&r, "plot", text, "--times", "1,x", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "--times"));
  cases += 3;
  printf("# %d malformed inputs in all\n", cases);
  assert_true(cases >= 80);
  unlink(ini), unlink(text), unlink(h5);
}

/* ---- --help on every command ---------------------------------------------- */

static void test_help(void **state) {
  (void)state;
  const char *cmds[] = {"run", "check", "info", "plot", "keys", "spectrum"};
  result r;
  for (size_t i = 0; i < sizeof cmds / sizeof cmds[0]; i++) {
    run(&r, cmds[i], "--help", NULL);
    assert_int_equal(r.code, 0);
    assert_non_null(strstr(r.out, "usage: vesica"));
  }
  run(&r, "--help", NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "info FILE.h5"));
  assert_non_null(strstr(r.out, "130/143")); /* every exit code */
  run(&r, "help", NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "info FILE.h5"));
  run(&r, "help", "info", NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "usage: vesica info"));
  assert_non_null(strstr(r.out, "references")); /* every key info prints */
  run(&r, "help", "nope", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "unknown command 'nope'"));
}

/* vesica spectrum on a run with resets, at a snapshot behind the last
 * reset (its reference rebuilt from the file) and at the last one. The two
 * halves of the answer come from different computations and must agree: the
 * count below a shift (the factorization's inertia) and the eigenvalues
 * Lanczos finds above it. The Ritz values of the lowest eigenvalues are
 * upper bounds (mu_j <= mu_j^Ritz, interlacing), so with the shift just
 * above a first call's mu_2^Ritz at least 2 lie below it, the lowest found
 * lies above it, and when exactly 2 lie below, that one is mu_3 <=
 * mu_3^Ritz of the first call. fe_dt_limit is 2 / mu_max. Bad options
 * exit 2.
 * Kept whole (138 lines): one scenario whose checks build on each other. */
static void test_spectrum(void **state) {
  (void)state;
  char ini[128], h5[128];
  tmp_path(ini, sizeof ini, "spec.ini");
  tmp_path(h5, sizeof h5, "spec.h5");
  write_file(ini, "[time]\nt_end = 0.02\nadaptive = 0\n[output]\nsnapshot_every = 1\n"
                  "[reconnect]\nevery = 2\nnodes = motion\n");
  result r;
  run(&r, "run", ini, TINY, "--out", h5, "--quiet", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  const char *snaps[] = {"3", "-1"}; /* step 3 (one reset behind it), the last (step 4) */
  char tsv[128];
  tmp_path(tsv, sizeof tsv, "modes.tsv");
  for (int c = 0; c < 2; c++) {
    run(&r, "spectrum", h5, "--snapshot", snaps[c], "--modes", "4", "--lanczos", "60", "--vectors",
        tsv, "--force", NULL);
    if (r.code) fail_msg("spectrum: exit %d: %s", r.code, r.err);
    printf("# spectrum --snapshot %s:\n%s", snaps[c], r.out);
    /* where the modes live: shares in [0, 1]; mu's parts add up to mu: they
     * are the Rayleigh quotient x^T A x of the Ritz vector, which differs
     * from the shift-and-invert Ritz value by second order in the Ritz
     * residual, well inside the first-order bound mu_i_error (measured:
     * 0.05-0.1 of it for the unconverged pairs here, 1e-9 of mu_max for
     * the converged one) */
    for (int j = 1; j <= 4; j++) {
      char key[64];
      const char *parts[] = {"band", "axis", "material", "from_E", "from_A", "from_V", "drift"};
      double v[7];
      for (int q = 0; q < 7; q++) {
        snprintf(key, sizeof key, "mu_%d_%s", j, parts[q]);
        v[q] = key_value(r.out, key);
        assert_true(isfinite(v[q]));
      }
      snprintf(key, sizeof key, "mu_%d", j);
      const double mu = key_value(r.out, key);
      assert_true(v[0] >= 0 && v[0] <= 1 && v[1] >= 0 && v[1] <= 1 && v[2] > 0);
      assert_true(fabs(v[6]) <= 1 + 1e-12); /* a cosine */
      snprintf(key, sizeof key, "mu_%d_error", j);
      const double bound = key_value(r.out, key) + 1e-9 * key_value(r.out, "mu_max");
      assert_true(fabs(v[3] + v[4] + v[5] - mu) <= bound);
    }
    const double share = key_value(r.out, "drift_in_modes");
    assert_true(share >= 0 && share <= 1 + 1e-12 && key_value(r.out, "drift_K_norm") > 0);
    /* the file: 4 comment lines, then one row a node of 5 + 4 x 4 numbers */
    FILE *f = fopen(tsv, "r");
    assert_non_null(f);
    char line[4096];
    int rows = 0, comments = 0;
    while (fgets(line, sizeof line, f)) {
      if (line[0] == '#') {
        comments++;
        continue;
      }
      int cols = 0;
      for (char *tok = strtok(line, " \n"); tok; tok = strtok(NULL, " \n")) {
        char *end;
        const double x = strtod(tok, &end);
        assert_true(end != tok && isfinite(x));
        cols++;
      }
      assert_int_equal(cols, 5 + 4 * 4);
      rows++;
    }
    fclose(f);
    assert_int_equal(comments, 4);
    assert_int_equal(rows, (int)key_value(r.out, "nodes"));
    const double mu2 = key_value(r.out, "mu_2"), mu3 = key_value(r.out, "mu_3");
    const double mu_max = key_value(r.out, "mu_max"), lim = key_value(r.out, "fe_dt_limit");
    assert_true(key_value(r.out, "reconnections") == (c == 0 ? 1 : 2));
    assert_true(key_value(r.out, "below") == 0); /* --above -1 lies below all here */
    assert_true(mu_max > 0 && fabs(lim * mu_max - 2) < 1e-5);
    assert_true(isfinite(mu2) && isfinite(mu3) && mu3 > mu2);
    assert_true(key_value(r.out, "dissipation") > 0);
    char above[64];
    const double shift = mu2 + 1e-9 * fabs(mu2);
    snprintf(above, sizeof above, "%.17g", shift);
    run(&r, "spectrum", h5, "--snapshot", snaps[c], "--above", above, "--modes", "1", "--lanczos",
        "60", NULL);
    if (r.code) fail_msg("spectrum --above: exit %d: %s", r.code, r.err);
    const double m1 = key_value(r.out, "mu_1"), nb = key_value(r.out, "below");
    printf("# --above %s: below %g, mu_1 %.9e (mu_3^Ritz before %.9e)\n", above, nb, m1, mu3);
    assert_true(nb >= 2 && m1 > shift);
    if (nb == 2) assert_true(m1 <= mu3 + 1e-9 * fabs(mu3));
  }
  /* bad input */
  const char *bad[][3] = {{"--snapshot", "99", "holds"},
                          {"--modes", "0", "--modes"},
                          {"--above", "x", "--above"},
                          {"--lanczos", "1", "--lanczos"},
                          {"--frobnicate", "1", "unknown option"}};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    run(&r, "spectrum", h5, bad[i][0], bad[i][1], NULL);
    assert_int_equal(r.code, 2);
    assert_non_null(strstr(r.err, bad[i][2]));
  }
  /* info: the sharp interface the nodes show (level_set.c ves_level_set_eval,
   * tested exactly in test_level_set). At t = 0 its area and volume are the
   * shape's sharp ones (vesica check) up to the piecewise-linear
   * interpolation of phi at h = 0.14 (measured 0.2% and 0.4%, asserted 1%: the phase
   * field's own A and V differ from them by 2.5% and 13% at eps 0.2), and 4
   * small steps move its reduced volume by far less than 1e-3 */
  run(&r, "check", ini, TINY, NULL);
  assert_int_equal(r.code, 0);
  const double a_sh = key_value(r.out, "area_sharp"), v_sh = key_value(r.out, "volume_sharp");
  run(&r, "info", h5, NULL);
  assert_int_equal(r.code, 0);
  const double ai = key_value(r.out, "interface_area_initial");
  const double voli = key_value(r.out, "interface_volume_initial");
  printf("# info: interface area %.6f (sharp %.6f), volume %.6f (sharp %.6f), v %.6f -> %.6f\n", ai,
         a_sh, voli, v_sh, key_value(r.out, "interface_reduced_volume_initial"),
         key_value(r.out, "interface_reduced_volume_final"));
  assert_true(fabs(ai / a_sh - 1) <= 0.01 && fabs(voli / v_sh - 1) <= 0.01);
  const double vi = key_value(r.out, "interface_reduced_volume_initial");
  assert_true(fabs(key_value(r.out, "interface_reduced_volume_final") - vi) <= 1e-3);
  assert_true(key_value(r.out, "node_triangles_inverted_initial") == 0);
  assert_true(key_value(r.out, "node_triangles_inverted_final") == 0);
  /* the largest drift over the snapshots: at least the final one (it is in
   * the max), and small over 4 small steps (the same 1e-3 as v above; the
   * drift of A_I, V_I separately, so a bound of 1e-2 on each) */
  const double daf = fabs(key_value(r.out, "interface_area_final") / ai - 1);
  const double dvf = fabs(key_value(r.out, "interface_volume_final") / voli - 1);
  const double dam = key_value(r.out, "interface_area_drift_max");
  const double dvm = key_value(r.out, "interface_volume_drift_max");
  printf("# info: interface drift max: area %.3e (final %.3e), volume %.3e (final %.3e)\n", dam,
         daf, dvm, dvf);
  /* daf, dvf from values printed to 9 digits: off by up to 1e-8 */
  assert_true(dam >= daf - 1e-8 && dvm >= dvf - 1e-8);
  assert_true(dam <= 1e-2 && dvm <= 1e-2);
  assert_true(key_value(r.out, "node_triangles_inverted_max") == 0);
  run(&r, "spectrum", ini, NULL); /* not an HDF5 file */
  assert_int_equal(r.code, 2);
  run(&r, "spectrum", h5, "--vectors", "/nonexistent-dir/m.tsv", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "does not exist"));
  unlink(ini), unlink(h5), unlink(tsv);
  char xdmf[128];
  unlink(tmp_path(xdmf, sizeof xdmf, "spec.xdmf"));
}

/* ---- the progress line -------------------------------------------------------- */

/* The progress line's ETA: one value with constant steps (0 s at t_end);
 * with adaptive steps below dt_max a range lo-hi from the relative step
 * dt/t (cli_loop.c cli_eta_steps; the estimator alone: test_eta.c). */
static void test_progress_eta(void **state) {
  (void)state;
  char ini[128], out[128];
  tmp_path(ini, sizeof ini, "eta.ini");
  tmp_path(out, sizeof out, "eta.h5");
  result r;
  write_file(ini, "[time]\nt_end = 0.1\nadaptive = 0\n"); /* 20 steps of 5e-3 */
  run(&r, "run", ini, TINY, "--out", out, NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  printf("# constant steps:\n%s", r.err);
  const char *l10 = strstr(r.err, "step 10 "), *l20 = strstr(r.err, "step 20 ");
  assert_non_null(l10);
  assert_non_null(l20);
  long a = -1, b = -1;
  const char *e = strstr(l10, "ETA ");
  assert_true(e && e < l20);
  assert_int_equal(sscanf(e, "ETA %ld s\n", &a), 1); /* one value */
  const char *nl = strchr(e, '\n');
  assert_true(a >= 0 && nl && !memchr(e, '-', (size_t)(nl - e)));
  assert_non_null(strstr(l20, "ETA 0 s\n")); /* t_end reached */
  /* adaptive, dt growing at most 1.2x a step from 5e-3: at step 10 dt <=
   * 0.031 and t <= 0.2, so 26+ steps are left at that dt, 1 at dt_max = 10 */
  write_file(ini, "[time]\nt_end = 1\ndt_max = 10\ngrowth_max = 1.2\n");
  run(&r, "run", ini, TINY, "--out", out, "--max-steps", "12", "--force", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  printf("# adaptive steps:\n%s", r.err);
  l10 = strstr(r.err, "step 10 ");
  assert_non_null(l10);
  e = strstr(l10, "ETA ");
  assert_non_null(e);
  /* --max-steps 12 leaves 2 steps: 1 to 2, a range or (rounded to the
   * same second) one value; not 1 to 26+ steps */
  b = -1;
  assert_true(sscanf(e, "ETA %ld-%ld s", &a, &b) >= 1);
  assert_true(0 <= a && (b == -1 || a <= b));
  /* a step with retries says what its rejected attempts were and cost:
   * adaptive Euler grows dt until a step raises E (test_integrate.c) */
  write_file(ini, "[time]\nt_end = 1\ndt_max = 1\n");
  run(&r, "run", ini, TINY, "--backend", "euler", "--out", out, "--max-steps", "30", "--force",
      NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  /* at step 10 dt* is far below dt_max = 1 (20 steps left at it, 1 at
   * dt_max): an estimate from dt/t all the same, never "unknown" */
  l10 = strstr(r.err, "step 10 ");
  assert_non_null(l10);
  assert_true(strncmp(strstr(l10, "ETA "), "ETA unknown", 11) != 0);
  e = strstr(r.err, "attempt(s) rejected from dt* ");
  if (!e) fail_msg("no line for the rejected attempts:\n%s", r.err);
  if (!e) return; /* (fail_msg does not return; for the compiler's flow analysis) */
  printf("# euler: %.*s\n", (int)strcspn(e, "\n"), e);
  assert_non_null(strstr(e, "(last: step rejected; in all "));
  /* summed over the attempts: euler factorizes once an attempt */
  const char *ls = e;
  while (ls > r.err && ls[-1] != '\n') ls--;
  int attempts = 0, its = 0, hs = 0, fs = 0;
  assert_int_equal(sscanf(ls, "step %*d: %d attempt(s)", &attempts), 1);
  assert_int_equal(sscanf(strstr(e, "in all "),
                          "in all %d iterations, %d Hessians, %d factorizations", &its, &hs, &fs),
                   3);
  assert_true(attempts >= 1 && fs == attempts);
  unlink(ini), rm_run(out);
}

/* --series: one header line naming the columns of vesica info --series
 * (no comment mark), the row of the initial state (step 0, t = 0), then one
 * row per accepted step whose step, t and E are the file's series (to the
 * 12 printed digits: 1e-11 relative covers the rounding), its retries and
 * factorizations the file's too (adaptive Euler grows dt until a step
 * raises E and is retried, as in test_progress_eta). The whole text against
 * info's: tests/test_series_tsv.py.
 * Kept whole (84 lines): one scenario whose checks build on each other. */
static void test_series(void **state) {
  (void)state;
  char ini[128], out[128], tsv[128];
  tmp_path(ini, sizeof ini, "ser.ini");
  tmp_path(out, sizeof out, "ser.h5");
  tmp_path(tsv, sizeof tsv, "ser.tsv");
  write_file(ini, "[time]\nt_end = 1\ndt_max = 1\n");
  result r;
  run(&r, "run", ini, TINY, "--backend", "euler", "--out", out, "--max-steps", "30", "--series",
      tsv, "--quiet", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  ves_io *io = NULL;
  char err[256];
  assert_int_equal(ves_io_open(out, 0, &io, err, sizeof err), VES_OK);
  const long R = ves_io_rows(io);
  double *t = series(io, "t"), *E = series(io, "E"), *fac = series(io, "factorizations");
  double *ret = series(io, "retries");
  FILE *f = fopen(tsv, "r");
  assert_non_null(f);
  char line[2048], head[2048] = "";
  int nhead = 0, rows = 0, retried = 0;
  assert_non_null(fgets(head, sizeof head, f));
  nhead = tsv_fields(head);
  while (fgets(line, sizeof line, f)) {
    assert_int_equal(tsv_fields(line), nhead);
    long step;
    double tt, dt, e;
    assert_int_equal(sscanf(line, "%ld\t%lf\t%lf\t%lf", &step, &tt, &dt, &e), 4);
    assert_true(step == rows && rows <= R);
    if (rows == 0) { /* the initial state */
      assert_true(tt == 0 && dt == 0);
      rows++;
      continue;
    }
    assert_true(fabs(tt / t[rows - 1] - 1) <= 1e-11 && fabs(e / E[rows - 1] - 1) <= 1e-11);
    /* retries (column 18) and factorizations (21, the last) as in the file */
    const char *c = line;
    double v[21];
    for (int k = 0; k < 21; k++) {
      v[k] = strtod(c, NULL);
      c = strchr(c, '\t');
      if (k < 20) assert_non_null(c), c++;
    }
    assert_true(v[17] == ret[rows - 1] && v[20] == fac[rows - 1] && v[20] >= 1);
    retried += v[17] > 0;
    rows++;
  }
  fclose(f);
  printf("# series: %d columns named, %d rows (file %ld), %d with retries\n", nhead, rows, R,
         retried);
  assert_int_equal(nhead, 21);
  assert_int_equal(strncmp(head, "step\tt\tdt\tE\tA\tV\tV_target\t", 25), 0);
  assert_non_null(strstr(head, "\treconnections\tfactorizations\n"));
  assert_int_equal(rows, R + 1);
  assert_true(retried > 0);
  free(ret);
  /* vesica info --series N: the file's last N rows, step first, the values to the 12
   * digits printed (%.12g: 1e-11 relative covers its rounding) */
  run(&r, "info", out, "--series", "2", NULL);
  if (r.code) fail_msg("info --series: exit %d: %s", r.code, r.err);
  char *l1 = strchr(r.out, '\n'), *l2 = l1 ? strchr(l1 + 1, '\n') : NULL;
  assert_non_null(l2);
  assert_int_equal(strncmp(r.out, "# step\tt\tdt\tE\t", sizeof "# step\tt\tdt\tE\t" - 1), 0);
  assert_int_equal((int)strlen(l2 + 1), (int)strcspn(l2 + 1, "\n") + 1); /* 3 lines in all */
  long s1, s2;
  double t2, e2;
  assert_int_equal(sscanf(l1 + 1, "%ld", &s1), 1);
  assert_int_equal(sscanf(l2 + 1, "%ld\t%lf\t%*f\t%lf", &s2, &t2, &e2), 3);
  assert_true(s1 == R - 1 && s2 == R);
  assert_true(fabs(t2 / t[R - 1] - 1) <= 1e-11 && fabs(e2 / E[R - 1] - 1) <= 1e-11);
  run(&r, "info", out, "--series", "0", NULL); /* every row: the header, t = 0, the R steps */
  int lines = 0;
  for (const char *c = r.out; *c; c++) lines += *c == '\n';
  assert_int_equal(lines, R + 2);
  assert_int_equal(strncmp(strchr(r.out, '\n') + 1, "0\t0\t0\t", 6), 0);
  run(&r, "info", out, "--series", "-1", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "not an integer"));
  /* the summary's count of factorizations: the column's sum */
  double fsum = 0;
  for (long k = 0; k < R; k++) fsum += fac[k];
  run(&r, "info", out, NULL);
  assert_true(key_value(r.out, "kkt_factorizations") == fsum);
  free(t), free(E), free(fac);
  ves_io_close(&io);
  unlink(ini), rm_run(out), unlink(tsv);
}

/* ---- numerical failure: exit 3, the file kept with the last good state ---- */

static void test_numerical_failure(void **state) {
  (void)state;
  char ini[128], out[128];
  tmp_path(ini, sizeof ini, "fail.ini");
  tmp_path(out, sizeof out, "fail.h5");
  /* one Newton iteration to tol = 1e-14 fails at every dt (as in
   * test_integrate.c's forced failure) */
  write_file(ini, "[solver]\nmax_iter = 1\ntol = 1e-14\n[time]\nt_end = 0.5\ndt_min = 1e-3\n");
  result r;
  run(&r, "run", ini, TINY, "--out", out, "--quiet", NULL);
  printf("# forced failure -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 3);
  assert_non_null(strstr(r.err, "no acceptable step"));
  assert_non_null(strstr(r.err, "the last attempt hit solver.max_iter")); /* the limit's key */
  assert_non_null(strstr(r.err, out));
  ves_io *io = open_ro(out);
  assert_string_equal(ves_io_get_info(io)->status, "failed");
  assert_int_equal(ves_io_rows(io), 0);
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot(io, ves_io_snapshots(io) - 1, NULL, NULL, NULL, &si),
                   VES_OK);
  assert_true(si.state.nstep == 0 && si.state.t == 0.0); /* the last good state */
  ves_io_close(&io);
  /* the correction limit named as such: one step of dt* 1000 (no halving:
   * dt_min), whose matrix needs an inertia correction (the spurious modes
   * at such a dt), against a limit of 1e-9 K */
  write_file(ini, "[time]\nt_end = 2000\ndt_min = 1000\ndt_max = 1000\n"
                  "[solver]\nmax_correction = 1e-9\n");
  run(&r, "run", ini, TINY, "--set", "time.dt_initial=1000", "--out", out, "--quiet", "--force",
      NULL);
  printf("# the correction limit -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 3);
  assert_non_null(strstr(r.err, "the last attempt hit solver.max_correction"));
  unlink(ini), rm_run(out);
}

/* A large problem is announced with its estimated size and cost before the
 * setup (here one refused right after, by the box check); one beyond the
 * machine's memory is refused with the estimate, nothing built. */
static void test_setup_estimate(void **state) {
  (void)state;
  char ini[128];
  tmp_path(ini, sizeof ini, "big.ini");
  write_file(ini, "[shape]\ntype = spheroid\nreduced_volume = 0.6\norientation = prolate\n"
                  "[geometry]\nepsilon = 0.02\nband = 20\nbox_z = 3\n");
  result r;
  run(&r, "check", ini, NULL);
  printf("# %s", r.err);
  assert_int_equal(r.code, 2);
  const char *l = strstr(r.err, "vesica check: setting up about ");
  assert_non_null(l);
  long n = strtol(l + strlen("vesica check: setting up about "), NULL, 10);
  /* the estimate's formula (cli_common.c) for this shape, whose meridian is
   * 5.479 R0: 1.27 L rho (2 band eps / h0^2 + (1/h0 - 1/h_far) / slope) =
   * 69,372 (computed independently); 10% either way */
  assert_true(n > 62000 && n < 77000);
  assert_true(strstr(r.err, "does not fit") > l); /* the line comes first */
  /* with resets the peak is EST_RESET = 2.1x the steps' (a reset's tables) */
  const double gb = estimate_gb(l, "GB peak memory in a run, ");
  run(&r, "check", ini, "--set", "reconnect.every=20", NULL);
  assert_int_equal(r.code, 2);
  const double gb_reset = estimate_gb(r.err, "GB peak memory in a run (with its resets), ");
  printf("# peak estimate %.1f GB, with resets %.1f GB\n", gb, gb_reset);
  assert_true(fabs(gb_reset / gb - 2.1) < 0.02); /* both printed to 0.1 GB of ~10 */
  /* with remeshings the same figure, said to hold for the initial node set */
  run(&r, "check", ini, "--set", "remesh.every=50", NULL);
  assert_int_equal(r.code, 2);
  const double gb_remesh = estimate_gb(
      r.err, "GB peak memory in a run (with its resets, for this node set: a remeshing that adds "
             "nodes raises it in proportion), ");
  assert_true(gb_remesh == gb_reset);
  const double have = (double)sysconf(_SC_PHYS_PAGES) * (double)sysconf(_SC_PAGESIZE);
  if (have < 1e12) { /* ~6e6 nodes, ~1 TB: refused on any smaller machine */
    run(&r, "check", ini, "--set", "geometry.box_z=4", "--set", "geometry.epsilon=1e-4", NULL);
    printf("# %s", r.err);
    assert_int_equal(r.code, 2);
    assert_non_null(strstr(r.err, "would need about"));
    assert_non_null(strstr(r.err, "coarsen the problem"));
  }
  unlink(ini);
}

/* meshio reads the XDMF file and h5py the HDF5 file of a run whose name
 * holds XML's special characters, a space and a UTF-8 letter, in a folder
 * whose name holds ':' (tests/xdmf_check.py: the times, triangles and phi
 * meshio sees are the file's snapshots; units and description on every
 * object). Names the XDMF file could not refer to (':', '|', a leading
 * space, a control character, a byte that is not UTF-8: an output name
 * with ':' would break its data items) are refused with exit 2 and
 * nothing written, for a new run and for a restart. */
static void test_external_readers(void **state) {
  (void)state;
  char ini[128], dir[128], out[256], xdmf[256];
  tmp_path(ini, sizeof ini, "ext.ini");
  tmp_path(dir, sizeof dir, "d:ir");
  write_file(ini, "[time]\nt_end = 100\nadaptive = 0\ndt_max = 5e-3\n"
                  "[output]\nsnapshot_every = 1\n");
  assert_int_equal(mkdir(dir, 0755), 0);
  snprintf(out, sizeof out, "%s/r&<x> \"q\" \xc3\xa9.h5", dir);
  snprintf(xdmf, sizeof xdmf, "%s/r&<x> \"q\" \xc3\xa9.xdmf", dir);
  result r;
  run(&r, "run", ini, TINY, "--set", "geometry.h_band=0.9", "--set", "geometry.h_far=0.4", "--out",
      out, "--max-steps", "2", "--quiet", NULL);
  if (r.code) fail_msg("the run: exit %d: %s", r.code, r.err);
  char *py[] = {"/usr/bin/python3", "tests/xdmf_check.py", xdmf, NULL};
  run_prog(&r, py[0], py);
  printf("# %s%s", r.out, r.err);
  if (r.code)
    fail_msg("xdmf_check.py: exit %d (python3-meshio and python3-h5py come with make deps): %s%s",
             r.code, r.out, r.err);
  const char *bad[] = {"a:b.h5", "a|b.h5", " lead.h5", "c\x01.h5", "\xff.h5"};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
    char p[160], x[160];
    snprintf(p, sizeof p, "%s/%s", tmpdir, bad[i]);
    run(&r, "run", ini, "--out", p, "--quiet", NULL);
    printf("# --out '%s' -> %d: %s", bad[i], r.code, r.err);
    assert_int_equal(r.code, 2);
    assert_non_null(strstr(r.err, "could not refer to it"));
    snprintf(x, sizeof x, "%.*s.xdmf", (int)strlen(p) - 3, p);
    assert_false(exists(p));
    assert_false(exists(x));
  }
  char moved[160];
  tmp_path(moved, sizeof moved, "x:y.h5");
  assert_int_equal(rename(out, moved), 0);
  run(&r, "run", "--restart", moved, NULL);
  printf("# --restart x:y.h5 -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "rename the file"));
  unlink(moved), unlink(xdmf), unlink(ini);
  snprintf(xdmf, sizeof xdmf, "%s/r&<x> \"q\" \xc3\xa9_last.xmf", dir); /* meshio.read's file */
  unlink(xdmf);
  assert_int_equal(rmdir(dir), 0);
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_cli")) return 1;
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_help),
      cmocka_unit_test(test_malformed_input),
      cmocka_unit_test(test_spectrum),
      cmocka_unit_test(test_progress_eta),
      cmocka_unit_test(test_series),
      cmocka_unit_test(test_numerical_failure),
      cmocka_unit_test(test_problem_files_check),
      cmocka_unit_test(test_external_readers),
      cmocka_unit_test(test_setup_estimate),
  };
  // clang-format on
  return cmocka_run_group_tests_name("cli", tests, setup_all, teardown_all);
}
