/* vesica — tests of a run whose disk another program fills (build/vesica,
 * run as a child process, writing into a small tmpfs that `dd` fills at
 * several moments of the run): the run exits 3 with one line saying what
 * the file keeps; the file opens in place and as a copy elsewhere, holds
 * every snapshot that completed, bit for bit those of an uninterrupted run,
 * and continues with --restart to that run's end, bit for bit. Run from the
 * repository root (make test does); needs root for the tmpfs (skipped
 * otherwise). */
#include "cli_test_impl.h"

enum { STEPS = 10 }; /* the run's --max-steps: a fill comes before its end */

static char mnt[128]; /* the tmpfs */

/* A 3 MiB tmpfs at mnt: a TINY run's file (~25 KiB a snapshot) has room
 * for all its steps; dd fills it. 0, or -1 when it cannot be mounted
 * (not root). */
static int mount_small(void) {
  tmp_path(mnt, sizeof mnt, "tmpfs");
  if (mkdir(mnt, 0755) != 0 && errno != EEXIST) return -1;
  if (mount("tmpfs", mnt, "tmpfs", 0, "size=3m") != 0) {
    rmdir(mnt);
    return -1;
  }
  return 0;
}

static void unmount_small(void) {
  umount(mnt);
  rmdir(mnt);
}

/* Fill the tmpfs from another process: dd writes zeros until the disk is full. */
static void fill(const char *path) {
  char cmd[512];
  snprintf(cmd, sizeof cmd, "dd if=/dev/zero of=%s bs=64k >/dev/null 2>&1", path);
  assert_int_not_equal(system(cmd), -1); /* dd exits 1: no space left */
}

/* The number in "kept N complete snapshot" of a message, -1 when absent. */
static int kept_of(const char *err) {
  const char *p = strstr(err, "kept ");
  return p && strstr(p, " complete snapshot") ? atoi(p + 5) : -1;
}

static int lines_of(const char *text) {
  int n = 0;
  for (const char *c = text; *c; c++) n += *c == '\n';
  return n;
}

/* Snapshots 0..S-1 of b are those of a, bit for bit (y, x, phi, the state). */
static void same_snapshots(ves_io *a, ves_io *b, int S) {
  const int n = ves_io_get_info(a)->n;
  double *va = malloc(5 * (size_t)n * sizeof *va), *vb = malloc(5 * (size_t)n * sizeof *vb);
  assert_true(va && vb);
  for (int k = 0; k < S; k++) {
    ves_io_snapinfo sa, sb;
    assert_int_equal(ves_io_read_snapshot(a, k, va, va + 2 * n, va + 4 * n, &sa), VES_OK);
    assert_int_equal(ves_io_read_snapshot(b, k, vb, vb + 2 * n, vb + 4 * n, &sb), VES_OK);
    if (memcmp(va, vb, 5 * (size_t)n * sizeof *va) || memcmp(&sa.state, &sb.state, sizeof sa.state))
      fail_msg("snapshot %d differs from the uninterrupted run's", k);
  }
  free(va), free(vb);
}

/* The disk filled once the run has written `after` steps (a snapshot every
 * `every` steps): exit 3 with one line naming what it keeps; the file, in
 * place and copied elsewhere, opens with vesica info, keeps every snapshot
 * complete at the fill as the uninterrupted run `full` has them, and
 * continues to the end, bit for bit that run when it kept one of its
 * snapshots (a run stopped between them saves its state as one more). */
static void fill_after(const char *ini, const char *full, long after, int every) {
  char out[256], filler[256], copy[128], cmd[640];
  snprintf(out, sizeof out, "%s/disk.h5", mnt);
  snprintf(filler, sizeof filler, "%s/filler", mnt);
  char max[16];
  snprintf(max, sizeof max, "%d", STEPS);
  char *args[] = {"run", (char *)ini, TINY, "--out", out, "--quiet", "--max-steps", max, NULL};
  pid_t pid = spawn_tag(args, NULL, "disk");
  const long rows = wait_rows(out, after);
  fill(filler);
  result r;
  collect_tag(pid, &r, "disk");
  printf("# every %d, filled after %ld steps (%ld written) -> %d: %s", every, after, rows, r.code,
         r.err);
  assert_true(rows >= after);
  assert_int_equal(r.code, 3);
  assert_int_equal(lines_of(r.err), 1); /* one line, never a second that contradicts it */
  const int N = kept_of(r.err);
  if (N < 1 + after / every || !strstr(r.err, "--restart") || strstr(r.err, "half-way"))
    fail_msg("filled after %ld steps: '%s'", after, r.err);
  /* in place, the disk still full: it opens, with the snapshots it names */
  char *info[] = {"info", out, NULL};
  collect_tag(spawn_tag(info, NULL, "info"), &r, "info");
  if (r.code) fail_msg("vesica info in place: exit %d: %s", r.code, r.err);
  ves_io *a = open_ro(full), *b = open_ro(out);
  assert_int_equal(ves_io_snapshots(b), N);
  assert_string_equal(ves_io_get_info(b)->status, "failed");
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot(b, N - 1, NULL, NULL, NULL, &si), VES_OK);
  const long last = si.state.nstep;     /* the run's state at its stop, or its last snapshot */
  const int shared = last % every == 0; /* the uninterrupted run has it too */
  assert_true(last >= after && ves_io_rows(b) >= last);
  same_snapshots(a, b, shared ? N : N - 1);
  same_series(a, b, last);
  ves_io_close(&a), ves_io_close(&b);
  /* space freed, the file copied to a normal folder: info, and --restart
   * to the end of the uninterrupted run */
  unlink(filler);
  tmp_path(copy, sizeof copy, "disk_copy.h5");
  snprintf(cmd, sizeof cmd, "cp %s %s", out, copy);
  assert_int_equal(system(cmd), 0);
  char *info2[] = {"info", copy, NULL};
  collect_tag(spawn_tag(info2, NULL, "info"), &r, "info");
  if (r.code) fail_msg("vesica info of the copy: exit %d: %s", r.code, r.err);
  run(&r, "run", "--restart", copy, "--max-steps", max, "--quiet", NULL);
  if (r.code) fail_msg("--restart of the copy: exit %d: %s", r.code, r.err);
  if (shared) {
    assert_int_equal(same_runs(full, copy), STEPS);
  } else {
    b = open_ro(copy);
    assert_int_equal(ves_io_rows(b), STEPS);
    ves_io_close(&b);
  }
  rm_run(copy), rm_run(out);
}

/* The uninterrupted run of ini (STEPS steps) into full. */
static void run_full(const char *ini, const char *full) {
  char max[16];
  snprintf(max, sizeof max, "%d", STEPS);
  result r;
  run(&r, "run", ini, TINY, "--out", full, "--quiet", "--max-steps", max, NULL);
  if (r.code) fail_msg("the uninterrupted run: exit %d: %s", r.code, r.err);
}

/* A TINY run into the tmpfs, dd filling it after the 1st, 3rd and 6th
 * steps with a snapshot every step (the XDMF file rewritten at each: its
 * write meets the full disk first), and after the 5th with one every 4
 * steps (the reservation before a step meets it: the run stops
 * there and saves its state). */
static void test_filled_mid_run(void **state) {
  (void)state;
  if (geteuid() != 0 || mount_small() != 0) {
    printf("# skipped: a tmpfs needs root\n");
    skip();
  }
  char ini[128], full[128];
  tmp_path(ini, sizeof ini, "disk.ini");
  tmp_path(full, sizeof full, "disk_full.h5");
  const int every[] = {1, 4};
  const long after[][3] = {{1, 3, 6}, {5, 0, 0}};
  for (int j = 0; j < 2; j++) {
    char text[256];
    snprintf(text, sizeof text,
             "[time]\nt_end = 100\nadaptive = 0\ndt_max = 5e-3\n[output]\nsnapshot_every = %d\n",
             every[j]);
    write_file(ini, text);
    run_full(ini, full);
    for (int i = 0; i < 3 && after[j][i] > 0; i++) fill_after(ini, full, after[j][i], every[j]);
    rm_run(full);
  }
  unlink(ini);
  unmount_small();
}

/* The disk full before the run writes its header: exit 3 (a write that
 * fails, docs/manual.md "Exit codes"), one line, nothing left behind. */
static void test_full_before_header(void **state) {
  (void)state;
  if (geteuid() != 0 || mount_small() != 0) {
    printf("# skipped: a tmpfs needs root\n");
    skip();
  }
  char ini[128], out[256], xdmf[256], filler[256];
  tmp_path(ini, sizeof ini, "disk0.ini");
  write_file(ini, "[time]\nt_end = 100\nadaptive = 0\ndt_max = 5e-3\n");
  snprintf(out, sizeof out, "%s/disk0.h5", mnt);
  snprintf(xdmf, sizeof xdmf, "%s/disk0.xdmf", mnt);
  snprintf(filler, sizeof filler, "%s/filler", mnt);
  fill(filler);
  result r;
  run(&r, "run", ini, TINY, "--out", out, "--quiet", NULL);
  printf("# a full disk before the header -> %d: %s", r.code, r.err);
  assert_int_equal(r.code, 3);
  assert_int_equal(lines_of(r.err), 1);
  assert_non_null(strstr(r.err, "nothing kept"));
  assert_false(exists(out));
  assert_false(exists(xdmf));
  unlink(filler), unlink(ini);
  unmount_small();
}

/* A file whose superblock records an end of file before its last snapshot
 * (what a flush stopped half-way leaves: HDF5 refuses to read it, and
 * closing it after a writable open would cut it there): --restart
 * salvages every snapshot, the damaged file kept, and continues bit for
 * bit as the uninterrupted run. */
static void test_end_behind(void **state) {
  (void)state;
  char ini[128], full[128], part[128], damaged[160];
  tmp_path(ini, sizeof ini, "behind.ini");
  tmp_path(full, sizeof full, "behind_full.h5");
  tmp_path(part, sizeof part, "behind.h5");
  snprintf(damaged, sizeof damaged, "%s.damaged", part);
  write_file(ini, "[time]\nt_end = 100\nadaptive = 0\ndt_max = 5e-3\n"
                  "[output]\nsnapshot_every = 1\n");
  result r;
  run(&r, "run", ini, TINY, "--out", full, "--quiet", "--max-steps", "6", NULL);
  if (r.code) fail_msg("the uninterrupted run: exit %d: %s", r.code, r.err);
  run(&r, "run", ini, TINY, "--out", part, "--quiet", "--max-steps", "4", NULL);
  if (r.code) fail_msg("the run to step 4: exit %d: %s", r.code, r.err);
  hid_t h = H5Fopen(part, H5F_ACC_RDONLY, H5P_DEFAULT);
  assert_true(h >= 0);
  long lo, hi;
  snapshot_bytes(h, 4, &lo, &hi);
  H5Fclose(h);
  /* the end of file address of the version 0 superblock (bytes 40..47) */
  FILE *f = fopen(part, "r+b");
  assert_non_null(f);
  unsigned char eoa[8];
  for (int i = 0; i < 8; i++) eoa[i] = (unsigned char)((unsigned long)lo >> (8 * i));
  assert_int_equal(fseek(f, 40, SEEK_SET), 0);
  assert_int_equal(fwrite(eoa, 1, 8, f), 8);
  fclose(f);
  const long size = file_size(part);
  char *info[] = {"info", part, NULL};
  collect_tag(spawn_tag(info, NULL, "info"), &r, "info");
  printf("# end of file recorded at %ld of %ld bytes: info -> %d: %s", lo, size, r.code, r.err);
  assert_int_not_equal(r.code, 0); /* HDF5 refuses it */
  run(&r, "run", "--restart", part, "--max-steps", "6", NULL);
  printf("# --restart -> %d: %s", r.code, r.err);
  if (r.code || !strstr(r.err, "damaged") || !strstr(r.err, "salvaged snapshots 0..4 of 5"))
    fail_msg("--restart of a file whose end is behind: exit %d: %s", r.code, r.err);
  assert_int_equal(file_size(damaged), size); /* kept whole */
  assert_int_equal(same_runs(full, part), 6);
  rm_run(full), rm_run(part), unlink(damaged), unlink(ini);
}

/* The tmpfs unmounted even after a failed test, then the scratch folder removed. */
static int teardown(void **state) {
  if (mnt[0]) umount(mnt), rmdir(mnt);
  return teardown_all(state);
}

int main(int argc, char **argv) {
  (void)argc;
  if (cli_find_vesica(argv[0], "test_cli_disk")) return 1;
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_full_before_header),
      cmocka_unit_test(test_filled_mid_run),
      cmocka_unit_test(test_end_behind),
  };
  // clang-format on
  return cmocka_run_group_tests_name("cli_disk", tests, setup_all, teardown);
}
