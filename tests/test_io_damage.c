/* vesica — tests of the output module on failing writes and damaged files:
 * a write that fails (a full disk), a file cut short, its salvage, and the
 * damaged files the fuzzer found (absurd end addresses, foreign types, bad
 * layouts and attributes). */
#include "io_test_impl.h"

static char self[4096]; /* this program, re-executed for the child of test_write_failure */

/* A write that fails: the room check sees the limit first; a write past
 * it fails with the cause recorded (strerror(EFBIG)), and the process
 * closes the file and exits without crashing. */
static void test_write_failure(void **state) {
  (void)state;
  fake f;
  char path[128], out[128], cmd[4096 + 512];
  ves_io *io = fake_file(&f, "full.h5", path, sizeof path);
  double y[8] = {0}, phi[4] = {0};
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s0), VES_OK);
  assert_int_equal(ves_io_room(io, 1, 100), VES_OK); /* no limit here */
  assert_null(ves_io_error(io));
  ves_io_close(&io);
  free(f.problem);
  path_in(out, sizeof out, "full.out");
  snprintf(cmd, sizeof cmd, "%s --write-fail %s > %s 2>&1", self, path, out);
  int rc = system(cmd);
  char text[1024] = "";
  FILE *fo = fopen(out, "r");
  size_t k = fo ? fread(text, 1, sizeof text - 1, fo) : 0;
  text[k] = 0;
  if (fo) fclose(fo);
  printf("# child exit %d:\n%s", WIFEXITED(rc) ? WEXITSTATUS(rc) : 128 + WTERMSIG(rc), text);
  assert_true(WIFEXITED(rc) && WEXITSTATUS(rc) == 0); /* not 139 */
  assert_non_null(strstr(text, "room: file size limit reached"));
  char want[128];
  snprintf(want, sizeof want, "append: input/output error: %s\n", strerror(EFBIG));
  assert_non_null(strstr(text, want));
}

/* A file cut short (a copy interrupted, a full disk) is named damaged and
 * truncated, not "in use by a running vesica", writable or not. */
static void test_truncated(void **state) {
  (void)state;
  fake f;
  char path[128], err[512] = "";
  ves_io *io = fake_file(&f, "cut.h5", path, sizeof path);
  double y[8] = {0}, phi[4] = {0};
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s0), VES_OK);
  ves_io_close(&io);
  free(f.problem);
  struct stat sb;
  assert_int_equal(stat(path, &sb), 0);
  assert_int_equal(truncate(path, sb.st_size / 2), 0);
  for (int w = 0; w < 2; w++) {
    assert_int_equal(ves_io_open(path, w, &io, err, sizeof err), VES_ERR_IO);
    printf("# cut to half, writable %d: %s\n", w, err);
    assert_non_null(strstr(err, "damaged: truncated file"));
    assert_null(strstr(err, "in use"));
  }
}

/* Kept whole (89 lines): one scenario whose checks build on each other. */
static void test_salvage(void **state) {
  (void)state;
  fake f;
  char path[128], cut[160], out[192], err[512] = "";
  ves_io *io = fake_file(&f, "salv.h5", path, sizeof path);
  double y[8], x[8], phi[4] = {1, 0.5, -0.25, -1};
  for (long i = 0; i <= 6; i++) {
    if (i % 3 == 0) {
      for (int j = 0; j < 8; j++) y[j] = f.X[j] + 0.01 * (double)i, x[j] = y[j] + 1e-3;
      ves_io_snapinfo si = snap_of(i);
      assert_int_equal(ves_io_snapshot(io, y, x, phi, &si), VES_OK);
    }
    if (i < 6) {
      ves_io_row r = row_of(i);
      assert_int_equal(ves_io_append(io, &r), VES_OK);
    }
  }
  ves_io_close(&io);
  free(f.problem);
  snprintf(out, sizeof out, "%s.salvage", path);
  ves_io_salvaged s;
  assert_int_equal(ves_io_salvage(path, out, &s, err, sizeof err), VES_ERR_ARG);
  assert_non_null(strstr(err, "not cut short"));
  assert_int_equal(ves_io_cut_short(path, NULL, NULL), 0);
  long fsize;
  char *bytes = file_bytes(path, &fsize);
  snprintf(cut, sizeof cut, "%s.cut", path);
  int kept[3] = {0}, refused = 0;
  for (long c = 500; c < fsize; c += 2500) {
    write_prefix(cut, bytes, c);
    long long size = 0, stored = 0;
    assert_int_equal(ves_io_cut_short(cut, &size, &stored), 1);
    assert_true(size == c && stored == fsize);
    ves_status st = ves_io_salvage(cut, out, &s, err, sizeof err);
    if (st != VES_OK) {
      if (st != VES_ERR_IO) fail_msg("cut at %ld: %s (%s)", c, ves_status_str(st), err);
      assert_int_equal(access(out, F_OK), -1);
      refused++;
      continue;
    }
    assert_true(s.snapshot >= 0 && s.snapshot <= 2 && s.snapshots == 3);
    assert_int_equal(s.rows, 3 * s.snapshot);
    kept[s.snapshot]++;
    check_index(out, s.snapshot + 1); /* the index of the snapshots kept */
    assert_int_equal(ves_io_open(out, 1, &io, err, sizeof err), VES_OK);
    assert_int_equal(ves_io_snapshots(io), s.snapshot + 1);
    check_rows(io, s.rows);
    double y1[8], x1[8], phi1[4];
    ves_io_snapinfo si1, want = snap_of(s.rows);
    assert_int_equal(ves_io_read_snapshot(io, s.snapshot, y1, x1, phi1, &si1), VES_OK);
    for (int j = 0; j < 8; j++) y[j] = f.X[j] + 0.01 * (double)s.rows, x[j] = y[j] + 1e-3;
    assert_memory_equal(y, y1, sizeof y), assert_memory_equal(x, x1, sizeof x);
    assert_memory_equal(phi, phi1, sizeof phi);
    assert_memory_equal(&want.state, &si1.state, sizeof want.state);
    ves_io_row r = row_of(s.rows); /* it continues */
    assert_int_equal(ves_io_append(io, &r), VES_OK);
    ves_io_close(&io);
    if (kept[0] + kept[1] + kept[2] == 1) { /* an existing output is not replaced */
      assert_int_equal(ves_io_salvage(cut, out, &s, err, sizeof err), VES_ERR_IO);
      assert_non_null(strstr(err, "must not exist"));
    }
    remove(out);
  }
  printf("# %ld cuts: snapshot 0 kept %d times, 1 %d, 2 %d; %d refused\n", (fsize + 2000) / 2500,
         kept[0], kept[1], kept[2], refused);
  assert_true(kept[1] + kept[2] >= 1); /* the end cut off keeps a later snapshot */
  assert_true(kept[0] + kept[1] + kept[2] > refused);
  free(bytes);
  remove(cut);
  /* snapshots without checksums (an older writer): refused, nothing written */
  char plain[128];
  fake g;
  io = fake_file(&g, "plain.h5", plain, sizeof plain);
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, x, phi, &s0), VES_OK);
  ves_io_close(&io);
  free(g.problem);
  hid_t h = H5Fopen(plain, H5F_ACC_RDWR, H5P_DEFAULT);
  assert_true(h >= 0);
  assert_true(H5Adelete_by_name(h, "snapshots/0", "checksum", H5P_DEFAULT) >= 0);
  H5Fclose(h);
  struct stat sb;
  assert_int_equal(stat(plain, &sb), 0);
  assert_int_equal(truncate(plain, sb.st_size - 1), 0);
  snprintf(out, sizeof out, "%s.salvage", plain);
  assert_int_equal(ves_io_salvage(plain, out, &s, err, sizeof err), VES_ERR_IO);
  printf("# no checksums: %s\n", err);
  assert_non_null(strstr(err, "carry no checksums"));
  assert_int_equal(access(out, F_OK), -1);
}

/* A superblock recording an end far beyond the file (the salvage allocated
 * it) is refused before anything is allocated or written. */
static void test_salvage_huge_end(void **state) {
  (void)state;
  char path[128];
  long size;
  unsigned char *b = fake_bytes("huge.h5", path, sizeof path, 1, &size);
  assert_true(b[8] == 0 || b[8] == 1); /* superblock version: its end of file at 40 or 44 */
  const long long huge = 1LL << 45;    /* 32 TiB, below the 2^50 ves_io_cut_short accepts */
  for (int i = 0; i < 8; i++) b[(b[8] == 0 ? 40 : 44) + i] = (unsigned char)(huge >> (8 * i));
  put_bytes(path, b, size);
  long long got = 0, stored = 0;
  assert_int_equal(ves_io_cut_short(path, &got, &stored), 1);
  assert_true(stored == huge && got == size);
  salvage_refused(path, "superblock records 35184372088832 bytes");
}

/* Data whose HDF5 type is not one this module writes is refused unread,
 * without a crash: a damaged float type (bit offset 7 in a 64-bit double)
 * sends HDF5 1.10.8's conversion (H5T__conv_f_f) far past its buffers:
 * such a file opened, and `vesica run --restart` crashed (SIGSEGV)
 * appending its first series row. Here every double of the file so
 * damaged, then a snapshot's y replaced by a valid but foreign float type. */
static void test_foreign_types(void **state) {
  (void)state;
  char path[128], copy[160], err[512] = "";
  long size;
  unsigned char *b = fake_bytes("types.h5", path, sizeof path, 1, &size);
  /* the datatype message of an IEEE little-endian double (version 1, class
   * 1; size 8; bit offset 0, precision 64; exponent at 52, 11 bits;
   * mantissa at 0, 52 bits; bias 1023): its bit offset set to 7 */
  static const unsigned char f64[20] = {0x11, 0x20, 0x3f, 0,  8, 0,    0,    0,    0, 0,
                                        0x40, 0,    0x34, 11, 0, 0x34, 0xff, 0x03, 0, 0};
  int found = 0;
  for (long i = 0; i + 20 <= size; i++)
    if (!memcmp(b + i, f64, sizeof f64)) b[i + 8] = 7, found++;
  assert_true(found >= 10);
  snprintf(copy, sizeof copy, "%s.damaged", path);
  put_bytes(copy, b, size);
  ves_io *io = NULL;
  for (int w = 0; w < 2; w++) {
    assert_int_equal(ves_io_open(copy, w, &io, err, sizeof err), VES_ERR_CONFIG);
    assert_non_null(strstr(err, "not a vesica output file"));
    assert_null(io);
  }
  printf("# %d doubles' types damaged: %s\n", found, err);
  /* a valid float type that is not ours (a 32-bit float) in a snapshot */
  const double y[8] = {0, 1, 2, 3, 4, 5, 6, 7};
  hid_t h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  assert_true(h >= 0 && H5Ldelete(h, "snapshots/0/y", H5P_DEFAULT) >= 0);
  hsize_t dims[2] = {4, 2};
  hid_t sp = H5Screate_simple(2, dims, NULL);
  hid_t d =
      H5Dcreate2(h, "snapshots/0/y", H5T_IEEE_F32LE, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  assert_true(d >= 0 && H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, y) >= 0);
  H5Dclose(d), H5Sclose(sp), H5Fclose(h);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  double y1[8];
  assert_int_equal(ves_io_read_snapshot(io, 0, y1, NULL, NULL, NULL), VES_ERR_IO);
  /* x is ours, but a read verifies the snapshot whole (its checksum covers y) */
  assert_int_equal(ves_io_read_snapshot(io, 0, NULL, y1, NULL, NULL), VES_ERR_IO);
  assert_non_null(strstr(ves_io_corruption(io), "/snapshots/0/y: does not read"));
  ves_io_close(&io);
}

/* A salvage copies only what reads whole: a contiguous dataset whose
 * layout records more stored bytes than its data holds crashed HDF5's
 * H5Ocopy (SIGSEGV); snapshot 0's y so damaged in a file cut short, the
 * salvage refuses (every snapshot stands on snapshot 0) without a crash. */
static void test_salvage_bad_layout(void **state) {
  (void)state;
  char path[128];
  long size;
  unsigned char *b = fake_bytes("layout.h5", path, sizeof path, 2, &size);
  hid_t h = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
  hid_t d = H5Dopen2(h, "snapshots/0/y", H5P_DEFAULT);
  const haddr_t at = H5Dget_offset(d);
  H5Dclose(d), H5Fclose(h);
  /* its layout message: version 3, contiguous, address, size 64 */
  unsigned char msg[18] = {3, 1};
  for (int i = 0; i < 8; i++) msg[2 + i] = (unsigned char)(at >> (8 * i));
  msg[10] = 64;
  int found = 0;
  for (long i = 0; i + 18 <= size; i++)
    if (!memcmp(b + i, msg, sizeof msg)) b[i + 12] = 7, found++; /* size 64 + 7 << 16 */
  assert_int_equal(found, 1);
  put_bytes(path, b, size - 100);
  salvage_refused(path, "cannot be copied whole");
}

/* A salvage with a damaged attribute message in /parameters (a string
 * type of size 0 and an unknown padding): iterating the attributes
 * (H5Aiterate2) crashed in HDF5 1.10.8 (SIGSEGV in H5A__close); they are
 * first decoded one by one (io.c attrs_decode), and the salvage refuses. */
static void test_salvage_bad_attribute(void **state) {
  (void)state;
  char path[128];
  long size;
  unsigned char *b = fake_bytes("attr.h5", path, sizeof path, 1, &size);
  /* the attribute geometry.quadrature: its name, then (8-byte aligned) its
   * datatype message, a fixed string (class 3, version 1: 0x13) */
  static const char name[] = "geometry.quadrature";
  int found = 0;
  for (long i = 0; i + 40 <= size && !found; i++)
    if (!memcmp(b + i, name, sizeof name))
      for (long j = i + (long)sizeof name; j < i + 32 && !found; j++)
        if (b[j] == 0x13) b[j + 1] = 8, b[j + 4] = 0, found = 1; /* padding 8, size 0 */
  assert_true(found);
  put_bytes(path, b, size - 100);
  salvage_refused(path, "cannot be copied whole");
}

int main(int argc, char **argv) {
  if (argc == 3 && !strcmp(argv[1], "--write-fail")) return write_fail_child(argv[2]);
  snprintf(self, sizeof self, "%s", argv[0]);
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_write_failure),
      cmocka_unit_test(test_truncated),
      cmocka_unit_test(test_salvage),
      cmocka_unit_test(test_salvage_huge_end),
      cmocka_unit_test(test_foreign_types),
      cmocka_unit_test(test_salvage_bad_layout),
      cmocka_unit_test(test_salvage_bad_attribute),
  };
  // clang-format on
  return cmocka_run_group_tests_name("io_damage", tests, setup_all, teardown_all);
}
