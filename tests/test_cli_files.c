/* vesica — tests of the program's output files (build/vesica, run as a
 * child process): nothing is overwritten without --force and inputs never; a
 * full disk exits 3 with the state saved and restartable elsewhere; a torn
 * last write restarts from the last complete snapshot. Run from the
 * repository root (make test does; the full-disk case needs root). */
#include "cli_test_impl.h"

/* Kept whole (91 lines): one scenario whose checks build on each other. */
static void test_no_overwrite(void **state) {
  (void)state;
  char ini[128], out[128], xdmf[128], tsv[128], cmd[512];
  tmp_path(ini, sizeof ini, "ow.ini");
  tmp_path(out, sizeof out, "ow.h5");
  tmp_path(xdmf, sizeof xdmf, "ow.xdmf");
  tmp_path(tsv, sizeof tsv, "ow.tsv");
  const char *text = "[time]\nt_end = 1\nadaptive = 0\n";
  write_file(ini, text);
  result r;
  run(&r, "run", ini, TINY, "--out", out, "--quiet", "--max-steps", "2", NULL);
  if (r.code) fail_msg("run: exit %d: %s", r.code, r.err);
  const long size = file_size(out);
  /* an existing run: refused, named, untouched */
  run(&r, "run", ini, TINY, "--out", out, "--quiet", "--max-steps", "1", NULL);
  printf("# again -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "exists; --force overwrites it"));
  assert_non_null(strstr(r.err, "--restart"));
  assert_int_equal(file_size(out), size);
  /* the XDMF file alone, and an existing --series file: refused too */
  rename(out, tsv);
  run(&r, "run", ini, TINY, "--out", out, "--quiet", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, xdmf));
  rename(tsv, out);
  write_file(tsv, "keep\n");
  run(&r, "run", ini, TINY, "--out", out, "--series", tsv, "--force", "--quiet", "--max-steps", "1",
      NULL);
  assert_int_equal(r.code, 0); /* --force: out, xdmf and the series overwritten */
  assert_true(file_size(tsv) > 5);
  unlink(tsv);
  /* the problem file as --out or --series: refused even with --force */
  const char *frag = "is the input file";
  run(&r, "run", ini, TINY, "--out", ini, "--force", "--quiet", NULL);
  printf("# --out = the problem file -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, frag));
  run(&r, "run", ini, TINY, "--out", out, "--series", ini, "--force", "--quiet", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, frag));
  char got[256] = "";
  slurp(ini, got, sizeof got);
  assert_string_equal(got, text); /* untouched */
  /* plot: existing figures refused without --force; --outdir a/b/c created */
  char dir[160], png[256];
  snprintf(dir, sizeof dir, "%s/a/b/c", tmpdir);
  run(&r, "plot", out, "--outdir", dir, NULL);
  if (r.code) fail_msg("plot --outdir a/b/c: exit %d: %s", r.code, r.err);
  snprintf(png, sizeof png, "%s/ow_energy.png", dir);
  assert_true(file_size(png) > 0);
  run(&r, "plot", out, "--outdir", dir, NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "exists; --force"));
  run(&r, "plot", out, "--outdir", dir, "--force", NULL);
  assert_int_equal(r.code, 0);
  /* a PNG write that fails (file-size limit: gnuplot exits 0 and leaves a
   * truncated file): exit 3, the figure named, no figure or part left */
  char dir2[160];
  snprintf(dir2, sizeof dir2, "%s/full", tmpdir);
  char *pargs[] = {"plot", out, "--outdir", dir2, NULL};
  /* the script (27.7 KiB with the flow's arrows) fits, the snapshots'
   * figure (~60 KiB) does not */
  run_limited(&r, 30 * 1024, pargs);
  printf("# plot into a 30 KiB file-size limit -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 3);
  assert_non_null(strstr(r.err, "incomplete"));
  assert_int_equal(files_in(dir2), 0);
  rmdir(dir2);
  /* spectrum --vectors: an existing file refused, the input never, and a
   * write that fails exits 3 and leaves nothing */
  write_file(tsv, "keep\n");
  run(&r, "spectrum", out, "--modes", "2", "--lanczos", "10", "--vectors", tsv, NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, "exists; --force"));
  run(&r, "spectrum", out, "--modes", "2", "--lanczos", "10", "--vectors", out, "--force", NULL);
  assert_int_equal(r.code, 2);
  assert_non_null(strstr(r.err, frag));
  unlink(tsv);
  char *sargs[] = {"spectrum", out, "--modes", "2", "--lanczos", "10", "--vectors", tsv, NULL};
  run_limited(&r, 16 * 1024, sargs);
  printf("# spectrum --vectors into a 16 KiB file-size limit -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 3); /* an output that cannot be written, as plot's */
  assert_non_null(strstr(r.err, "cannot write"));
  assert_false(exists(tsv));
  snprintf(cmd, sizeof cmd, "%s.part", tsv);
  assert_false(exists(cmd));
  snprintf(cmd, sizeof cmd, "rm -rf %s/a", tmpdir);
  assert_int_equal(system(cmd), 0);
  unlink(ini), unlink(out), unlink(xdmf);
}

static void test_full_disk(void **state) {
  (void)state;
  char out[256];
  /* the file-size limit (ulimit -f): 400 KiB hold the header, the first
   * snapshot, the first chunk of every series and a few steps (340 KiB
   * until the snapshots held the flow: then the room check refused step 1) */
  tmp_path(out, sizeof out, "full.h5");
  fsize_limit = 400 * 1024;
  expect_full(out, "file size limit reached");
  rm_run(out);
  /* a real full disk: a 440 KiB tmpfs (needs root) */
  char mnt[128];
  tmp_path(mnt, sizeof mnt, "tmpfs");
  assert_int_equal(mkdir(mnt, 0755), 0);
  if (mount("tmpfs", mnt, "tmpfs", 0, "size=440k") != 0) {
    printf("# tmpfs: not mounted (%s): the file-size limit stands in\n", strerror(errno));
  } else {
    snprintf(out, sizeof out, "%s/full.h5", mnt);
    expect_full(out, "no space left on device");
    umount(mnt);
  }
  rmdir(mnt);
}

/* Copies of a small run's file (written in two parts: a run and its
 * restart) cut at 21 offsets, 12 spread over the file and 9 inside and
 * after the data of its last snapshot: `--restart` of each
 * either salvages it (the damaged file kept as .damaged) and finishes the
 * run from the last snapshot whose data the cut left whole — the final
 * state and the series then bit for bit those of the uninterrupted run, no
 * silent wrong state — or refuses with exit 3 and the cause; never a crash
 * and never "in use by a running vesica?".
 * Kept whole (100 lines): one scenario whose checks build on each other. */
static void test_torn_file(void **state) {
  (void)state;
  enum { SPREAD = 12, LAST = 9, CUTS = SPREAD + LAST };
  char ini[128], full[128], cut[CUTS][128], xdmf[128];
  tmp_path(ini, sizeof ini, "torn.ini");
  tmp_path(full, sizeof full, "torn.h5");
  write_file(ini, "[time]\nt_end = 100\nadaptive = 0\ndt_max = 5e-3\n"
                  "[output]\nsnapshot_every = 1\n");
  result r;
  /* coarser than TINY (215 nodes): 20 restarts, each a setup and <= 4 steps;
   * stopped at step 2 and continued, as a full disk's file would be (its
   * status and setup time rewritten) */
  run(&r, "run", ini, TINY, "--set", "geometry.h_band=0.9", "--set", "geometry.h_far=0.4", "--out",
      full, "--max-steps", "2", "--quiet", NULL);
  if (r.code) fail_msg("the run: exit %d: %s", r.code, r.err);
  run(&r, "run", "--restart", full, "--max-steps", "4", "--quiet", NULL);
  if (r.code) fail_msg("its restart: exit %d: %s", r.code, r.err);
  /* the uninterrupted run: snapshots at steps 0 to 4 */
  ves_io *io = open_ro(full);
  const int S = ves_io_snapshots(io), n = ves_io_get_info(io)->n;
  assert_int_equal(S, 5);
  double *y0 = malloc(2 * (size_t)n * sizeof *y0), *y1 = malloc(2 * (size_t)n * sizeof *y1);
  assert_true(y0 && y1);
  assert_int_equal(ves_io_read_snapshot(io, S - 1, y0, NULL, NULL, NULL), VES_OK);
  ves_io_close(&io);
  hid_t h = H5Fopen(full, H5F_ACC_RDONLY, H5P_DEFAULT);
  assert_true(h >= 0);
  long lo[5], hi[5];
  for (int k = 0; k < S; k++) snapshot_bytes(h, k, &lo[k], &hi[k]);
  H5Fclose(h);
  const long size = file_size(full);
  long at[CUTS];
  for (int i = 0; i < SPREAD; i++) at[i] = size * (i + 1) / (SPREAD + 1);
  for (int i = 0; i < LAST; i++) /* from the start of its data to the last byte */
    at[SPREAD + i] = lo[S - 1] + (size - 1 - lo[S - 1]) * i / (LAST - 1);
  int resumed = 0, last_cases = 0;
  for (int i = 0; i < CUTS; i += 2) { /* two restarts at a time */
    pid_t pid[2];
    char tag[2][16];
    for (int j = 0; j < 2 && i + j < CUTS; j++) {
      char name[32];
      snprintf(name, sizeof name, "torn%d.h5", i + j);
      tmp_path(cut[i + j], sizeof cut[0], name);
      copy_cut(full, cut[i + j], at[i + j]);
      char *args[] = {"run", "--restart", cut[i + j], "--max-steps", "4", NULL};
      snprintf(tag[j], sizeof tag[j], "torn%d", j);
      pid[j] = spawn_tag(args, NULL, tag[j]);
    }
    for (int j = 0; j < 2 && i + j < CUTS; j++) {
      const int c = i + j;
      collect_tag(pid[j], &r, tag[j]);
      /* the last snapshot whose data lie wholly before the cut */
      int whole = -1;
      while (whole + 1 < S && hi[whole + 1] <= at[c]) whole++;
      const char *from = strstr(r.err, "from snapshot ");
      const int K = from ? atoi(from + strlen("from snapshot ")) : -1;
      printf("# cut at %6ld of %ld bytes (last whole snapshot %2d) -> exit %d, resumed from %d\n",
             at[c], size, whole, r.code, K);
      char damaged[160], x[160];
      snprintf(damaged, sizeof damaged, "%s.damaged", cut[c]);
      if (r.code == 3) { /* refused: the cause named, the file left as it was */
        if (!strstr(r.err, "cut short") || !strstr(r.err, "cannot be salvaged") ||
            strstr(r.err, "in use"))
          fail_msg("cut at %ld: exit 3 with '%s'", at[c], r.err);
        assert_int_equal(file_size(cut[c]), at[c]);
        assert_false(exists(damaged));
      } else {
        if (r.code != 0 || K < 0 || K > whole)
          fail_msg("cut at %ld (snapshot %d whole): exit %d, resumed from %d: %s", at[c], whole,
                   r.code, K, r.err);
        /* 5 e-16 relative is not good enough here: the trajectory is the
         * uninterrupted one bit for bit (restarts are, test_restart_bitwise) */
        ves_io *a = open_ro(full), *b = open_ro(cut[c]);
        assert_int_equal(ves_io_rows(b), 4);
        same_series(a, b, 4);
        assert_int_equal(ves_io_read_snapshot(b, ves_io_snapshots(b) - 1, y1, NULL, NULL, NULL),
                         VES_OK);
        assert_memory_equal(y0, y1, 2 * (size_t)n * sizeof *y0);
        ves_io_close(&a), ves_io_close(&b);
        assert_int_equal(file_size(damaged), at[c]); /* the damaged file kept */
        resumed++;
      }
      /* cut inside the last snapshot's data: it resumes from the one before */
      if (at[c] >= lo[S - 1] && at[c] < hi[S - 1]) {
        last_cases++;
        if (K != S - 2) fail_msg("cut at %ld inside the last snapshot: resumed from %d", at[c], K);
      }
      unlink(cut[c]), unlink(damaged);
      snprintf(x, sizeof x, "%.*s.xdmf", (int)strlen(cut[c]) - 3, cut[c]);
      unlink(x);
    }
  }
  printf("# %d of %d cut copies resumed, %d cut inside the last snapshot\n", resumed, CUTS,
         last_cases);
  assert_true(last_cases >= 3);
  assert_true(resumed >= CUTS / 2); /* the cuts past the header's first blocks */
  free(y0), free(y1);
  unlink(ini), unlink(full);
  unlink(tmp_path(xdmf, sizeof xdmf, "torn.xdmf"));
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_cli_files")) return 1;
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_full_disk),
      cmocka_unit_test(test_torn_file),
      cmocka_unit_test(test_no_overwrite),
  };
  // clang-format on
  return cmocka_run_group_tests_name("cli_files", tests, setup_all, teardown_all);
}
