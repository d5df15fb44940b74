/* vesica — tests of what the program prints for scripts (build/vesica, run
 * as a child process): `keys KEY` (one key's row, an unknown key refused
 * naming the closest), `check --print-config` (every key's effective value
 * as a problem file, a fixed point), the verdict line of `spectrum`, the
 * progress line's ETA and the run's closing line (finished, stopped at
 * --max-steps, interrupted), --series refused with --restart. Run from the
 * repository root (make test does). */
#include "cli_test_impl.h"

#include "app/cli_impl.h"

/* The line of text that starts with prefix (its newline cut), into buf;
 * 0 when there is none. */
static int line_of(const char *text, const char *prefix, char *buf, size_t len) {
  for (const char *p = text; p && *p; p = strchr(p, '\n') ? strchr(p, '\n') + 1 : NULL)
    if (!strncmp(p, prefix, strlen(prefix))) {
      snprintf(buf, len, "%.*s", (int)strcspn(p, "\n"), p);
      return 1;
    }
  return 0;
}

/* ---- vesica keys KEY ---------------------------------------------------- */

/* `keys section.key` and `keys key`: the table's header and that key's row,
 * the same text as in the full table; an unknown key exits 2 naming the
 * closest; two operands or an option other than --study exit 2. */
static void test_keys_one(void **state) {
  (void)state;
  result all, r;
  run(&all, "keys", NULL);
  assert_int_equal(all.code, 0);
  char row[1024], head[512], want[2048];
  assert_true(line_of(all.out, "| time | dt_max |", row, sizeof row));
  const char *nl = strchr(all.out, '\n');
  assert_non_null(nl);
  nl = strchr(nl + 1, '\n'); /* the header: two lines */
  assert_non_null(nl);
  snprintf(head, sizeof head, "%.*s", (int)(nl + 1 - all.out), all.out);
  snprintf(want, sizeof want, "%s%s\n", head, row);
  run(&r, "keys", "time.dt_max", NULL);
  assert_int_equal(r.code, 0);
  assert_string_equal(r.out, want);
  run(&r, "keys", "dt_max", NULL); /* a bare key: the one section that has it */
  assert_int_equal(r.code, 0);
  assert_string_equal(r.out, want);
  run(&r, "keys", "time.dtmax", NULL);
  printf("# keys time.dtmax -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 2);
  assert_string_equal(r.out, "");
  assert_non_null(strstr(r.err, "'time.dtmax': not a problem-file key"));
  assert_non_null(strstr(r.err, "the closest: time.dt_max"));
  run(&r, "keys", "time.dt_max", "time.t_end", NULL);
  assert_int_equal(r.code, 2);
  run(&r, "keys", "--studies", NULL);
  assert_int_equal(r.code, 2);
}

/* ---- vesica check --print-config ---------------------------------------- */

/* The effective problem of a file and --set overrides: every key with the
 * value in force (an override's, the file's, a default's) as a problem
 * file; saved as .ini it is accepted by check, which prints the same
 * derived quantities as the original command line, and its own
 * --print-config is the same text (a fixed point). Nothing is built:
 * --print-config of a problem too large for the machine prints. */
static void test_print_config(void **state) {
  (void)state;
  char ini[128], eff[128];
  tmp_path(ini, sizeof ini, "pc.ini");
  tmp_path(eff, sizeof eff, "pc_eff.ini");
  write_file(ini, "[time]\nt_end = 0.5\n[material]\nc0 = 0.25\n");
  result r, again, c1, c2;
  run(&r, "check", ini, TINY, "--set", "time.dt_max=0.125", "--print-config", NULL);
  if (r.code) fail_msg("check --print-config: exit %d: %s", r.code, r.err);
  printf("# check --print-config:\n%s", r.out);
  /* every key of `vesica keys` once, under its section */
  result keys;
  run(&keys, "keys", NULL);
  int nkeys = 0;
  for (const char *p = strstr(keys.out, "\n| "); p; p = strstr(p + 1, "\n| ")) {
    char sec[64], key[64], pat[160];
    if (sscanf(p, "\n| %63s | %63s |", sec, key) != 2 || !strcmp(sec, "section")) continue;
    snprintf(pat, sizeof pat, "\n%s = ", key);
    char head[80];
    snprintf(head, sizeof head, "[%s]\n", sec);
    const char *s = strstr(r.out, head), *k = s ? strstr(s, pat) : NULL,
               *next = s ? strstr(s + 1, "\n[") : NULL;
    if (!k || (next && k > next)) fail_msg("--print-config: no %s in [%s]", key, sec);
    nkeys++;
  }
  assert_true(nkeys > 50);
  /* the override, the file's values, a default */
  assert_non_null(strstr(r.out, "\ndt_max = 0.125\n"));
  assert_non_null(strstr(r.out, "\nt_end = 0.5\n"));
  assert_non_null(strstr(r.out, "\nc0 = 0.25\n"));
  assert_non_null(strstr(r.out, "\nepsilon = 0.2\n")); /* TINY's --set */
  write_file(eff, r.out);
  run(&again, "check", eff, "--print-config", NULL);
  assert_int_equal(again.code, 0);
  assert_string_equal(again.out, r.out); /* a fixed point */
  /* the same problem: check prints the same quantities (timings aside) */
  run(&c1, "check", ini, TINY, "--set", "time.dt_max=0.125", NULL);
  run(&c2, "check", eff, NULL);
  assert_int_equal(c1.code, 0);
  assert_int_equal(c2.code, 0);
  const char *keys_same[] = {"nodes", "quadrature_points", "energy", "area", "volume", "c0"};
  for (int i = 0; i < 6; i++) {
    char a[128], b[128], k[64];
    snprintf(k, sizeof k, "%s = ", keys_same[i]);
    value_of(c1.out, k, a, sizeof a);
    value_of(c2.out, k, b, sizeof b);
    assert_string_equal(a, b);
  }
  /* bad input: refused as check refuses it, nothing on stdout */
  run(&r, "check", ini, "--set", "time.dt_max=-1", "--print-config", NULL);
  assert_int_equal(r.code, 2);
  assert_string_equal(r.out, "");
  /* nothing is built: a problem of ~4e6 nodes, which check refuses beyond
   * the machine's memory (~700 GB), prints */
  run(&r, "check", ini, "--set", "geometry.epsilon=0.01", "--set", "geometry.h_band=0.05", "--set",
      "geometry.h_far=0.05", "--set", "geometry.box_r=50", "--set", "geometry.box_z=50",
      "--print-config", NULL);
  assert_int_equal(r.code, 0);
  assert_non_null(strstr(r.out, "\nbox_r = 50\n"));
  unlink(ini), unlink(eff);
}

/* ---- the verdict of vesica spectrum --------------------------------------- */

/* The verdict from synthetic spectra: stable, an exact count, a lower bound
 * when every mode found is below -1e-3, undetermined with eigenvalues below
 * an --above higher than -1e-3 or no mode found. */
static void test_verdict_cases(void **state) {
  (void)state;
  char v[320];
  const double stable[] = {-2e-4, 0.5, 1.0};
  assert_int_equal(cli_spectrum_verdict(v, sizeof v, -1, 0, 3, stable), 0);
  assert_string_equal(v, "verdict: stable (no mode below -1e-3; lowest mu_1 = -2.000e-04)");
  const double two[] = {-0.05, -0.002, -5e-4};
  assert_int_equal(cli_spectrum_verdict(v, sizeof v, -1, 1, 3, two), 3);
  assert_non_null(strstr(v, "verdict: 3 unstable modes (below -1e-3; 1 below --above -1"));
  const double one[] = {-0.0011, 0.2};
  assert_int_equal(cli_spectrum_verdict(v, sizeof v, -1, 0, 2, one), 1);
  assert_non_null(strstr(v, "verdict: 1 unstable mode (")); /* exactly at the edge: -1.1e-3 */
  const double all[] = {-0.09, -0.08};
  assert_int_equal(cli_spectrum_verdict(v, sizeof v, -1, 0, 2, all), 2);
  assert_non_null(strstr(v, "verdict: at least 2 unstable modes"));
  assert_int_equal(cli_spectrum_verdict(v, sizeof v, 0.5, 4, 3, stable), -1);
  assert_non_null(strstr(v, "verdict: undetermined (4 eigenvalue(s) below --above 0.5"));
  const double none[] = {NAN, NAN};
  assert_int_equal(cli_spectrum_verdict(v, sizeof v, -1, 0, 2, none), -1);
  assert_non_null(strstr(v, "raise --lanczos"));
}

/* The verdict of a real spectrum: the last line of stdout, after every
 * key = value line, its count that of mu_i < -1e-3 and `below`. */
static void test_spectrum_verdict(void **state) {
  (void)state;
  char ini[128], h5[128];
  tmp_path(ini, sizeof ini, "sv.ini");
  tmp_path(h5, sizeof h5, "sv.h5");
  write_file(ini, "[time]\nt_end = 0.01\nadaptive = 0\n");
  result r;
  run(&r, "run", ini, TINY, "--out", h5, "--quiet", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  const char *aboves[] = {"-1", "-1e-6"};
  for (int c = 0; c < 2; c++) {
    run(&r, "spectrum", h5, "--above", aboves[c], "--modes", "4", "--lanczos", "40", NULL);
    if (r.code) fail_msg("spectrum: exit %d: %s", r.code, r.err);
    const size_t n = strlen(r.out);
    assert_true(n > 0 && r.out[n - 1] == '\n');
    const char *last = r.out + n - 1;
    while (last > r.out && last[-1] != '\n') last--;
    printf("# spectrum --above %s: %s", aboves[c], last);
    assert_int_equal(strncmp(last, "verdict: ", 9), 0);
    assert_non_null(strstr(r.out, "\nseconds = ")); /* the key = value lines stay */
    const int below = (int)key_value(r.out, "below");
    const double above = key_value(r.out, "above");
    int count = below, all_found = 1;
    for (int j = 1; j <= 4; j++) {
      char k[32];
      snprintf(k, sizeof k, "mu_%d", j);
      const double mu = key_value(r.out, k);
      if (mu < -1e-3)
        count++;
      else
        all_found = 0;
    }
    if (above > -1e-3 && below > 0) {
      assert_non_null(strstr(last, "undetermined"));
    } else if (count == 0) {
      assert_non_null(strstr(last, "verdict: stable (no mode below -1e-3; lowest mu_1 = "));
    } else {
      char want[64];
      snprintf(want, sizeof want, "%s%d unstable mode", all_found ? "at least " : "", count);
      assert_non_null(strstr(last, want));
    }
  }
  unlink(ini), rm_run(h5);
}

/* ---- the progress line and the closing line ----------------------------- */

/* The ETA of adaptive steps far below dt_max (adaptive Euler, dt_max 1: a
 * range over 10x of the linear bounds) is a range lo-hi in seconds on every
 * progress line, never "unknown"; the closing line of a run stopped by
 * --max-steps names it, the step, t*, E* (info's energy_final) and the
 * steps; one that reaches t_end says finished. */
static void test_progress_and_end(void **state) {
  (void)state;
  char ini[128], out[128];
  tmp_path(ini, sizeof ini, "pe.ini");
  tmp_path(out, sizeof out, "pe.h5");
  write_file(ini, "[time]\nt_end = 1\ndt_max = 1\n");
  result r, info;
  run(&r, "run", ini, TINY, "--backend", "euler", "--out", out, "--max-steps", "30", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  printf("# adaptive euler:\n%s", r.err);
  int lines = 0;
  for (const char *p = strstr(r.err, "step "); p; p = strstr(p + 1, "\nstep ")) {
    const char *e = strstr(p, "ETA ");
    if (!e || e > strchr(p + 1, '\n')) continue; /* a retry's line */
    double a, b;
    char unit[8];
    assert_true(strncmp(e + 4, "unknown", 7) != 0);
    const int k = sscanf(e, "ETA %lf-%lf %7s", &a, &b, unit);
    assert_true(k == 3 || sscanf(e, "ETA %lf %7s", &a, unit) == 2);
    lines++;
  }
  assert_int_equal(lines, 3); /* steps 10, 20, 30 (not a terminal: every 10th) */
  run(&info, "info", out, NULL);
  char E[64], want[256];
  value_of(info.out, "energy_final = ", E, sizeof E);
  char line[512];
  assert_true(
      line_of(r.err, "vesica run: stopped at --max-steps at step 30, t* = ", line, sizeof line));
  snprintf(want, sizeof want, ", E* = %.9g: 30 steps, ", strtod(E, NULL));
  assert_non_null(strstr(line, want));
  assert_non_null(strstr(line, "; wrote "));
  write_file(ini, "[time]\nt_end = 0.02\nadaptive = 0\n");
  run(&r, "run", ini, TINY, "--out", out, "--force", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  assert_true(line_of(r.err, "vesica run: finished (t_end reached) at step 4, t* = 0.02, E* = ",
                      line, sizeof line));
  run(&r, "run", ini, TINY, "--out", out, "--force", "--quiet", NULL); /* --quiet: none */
  assert_int_equal(r.code, 0);
  assert_string_equal(r.err, "");
  unlink(ini), rm_run(out);
}

/* A run stopped by SIGINT says so in its closing line, even with --quiet:
 * interrupted, where, and how to continue. */
static void test_interrupted(void **state) {
  (void)state;
  char ini[128], out[128];
  tmp_path(ini, sizeof ini, "int.ini");
  tmp_path(out, sizeof out, "int.h5");
  write_file(ini, "[time]\nt_end = 100\nadaptive = 0\ndt_max = 5e-3\n");
  char *args[] = {"run", ini, TINY, "--out", out, "--quiet", NULL};
  pid_t pid = spawn_tag(args, NULL, "int");
  assert_true(wait_rows(out, 2) >= 2);
  assert_int_equal(kill(pid, SIGINT), 0);
  result r;
  collect_tag(pid, &r, "int");
  printf("# interrupted -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 130);
  char line[512], tail[PATH_MAX + 64];
  assert_true(line_of(r.err, "vesica run: interrupted by signal 2 at step ", line, sizeof line));
  snprintf(tail, sizeof tail, "; continue with vesica run --restart %s", out);
  assert_non_null(strstr(line, tail));
  unlink(ini), rm_run(out);
}

/* --series with --restart: refused (exit 2, no text written), pointing to
 * vesica info FILE.h5 --series 0 for every row: a continued text would
 * repeat the steps after the last snapshot. */
static void test_restart_series(void **state) {
  (void)state;
  char ini[128], out[128], tsv[128], want[PATH_MAX + 64];
  tmp_path(ini, sizeof ini, "rs.ini");
  tmp_path(out, sizeof out, "rs.h5");
  tmp_path(tsv, sizeof tsv, "rs.tsv");
  write_file(ini, "[time]\nt_end = 1\nadaptive = 0\n");
  result r;
  run(&r, "run", ini, TINY, "--out", out, "--quiet", "--max-steps", "1", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  run(&r, "run", "--restart", out, "--series", tsv, "--quiet", NULL);
  printf("# --restart --series -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 2);
  snprintf(want, sizeof want, "vesica info %s --series 0", out);
  assert_non_null(strstr(r.err, want));
  assert_false(exists(tsv));
  unlink(ini), rm_run(out);
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_cli_print")) return 1;
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_keys_one),         cmocka_unit_test(test_print_config),
      cmocka_unit_test(test_verdict_cases),    cmocka_unit_test(test_spectrum_verdict),
      cmocka_unit_test(test_progress_and_end), cmocka_unit_test(test_interrupted),
      cmocka_unit_test(test_restart_series),
  };
  return cmocka_run_group_tests_name("cli_print", tests, setup_all, teardown_all);
}
