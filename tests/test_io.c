/* vesica — tests of the output module: the HDF5 layout written and read back
 * bit for bit, truncation and continuation, a file left by a writer killed
 * in the middle of an append or a snapshot, every refusal of a foreign file,
 * phi at the nodes against the exact profile, the restart chain at the
 * library level (state -> snapshot -> file -> state -> the same steps), the
 * self-describing attributes, a file of the previous layout and the snapshot
 * index. */
#include "io_test_impl.h"

/* Kept whole (110 lines): one scenario whose checks build on each other. */
static void test_roundtrip(void **state) {
  (void)state;
  fake f;
  char path[128], err[512] = "";
  ves_io *io = fake_file(&f, "rt.h5", path, sizeof path);
  double y[8], x[8], phi[4] = {1, 0.5, -0.25, -1};
  for (long i = 0; i < 3; i++) {
    ves_io_row r = row_of(i);
    assert_int_equal(ves_io_append(io, &r), VES_OK);
  }
  for (int k = 0; k < 2; k++) {
    for (int j = 0; j < 8; j++) y[j] = f.X[j] * (1 + 0.125 * k) + 1.0 / 3, x[j] = y[j] - 0.0625;
    ves_io_snapinfo si = snap_of(k * 3);
    assert_int_equal(ves_io_snapshot(io, y, x, phi, &si), VES_OK);
  }
  assert_int_equal(ves_io_set_status(io, "finished"), VES_OK);
  ves_io_close(&io);
  assert_null(io);
  check_index(path, 2);

  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  const ves_io_info *in = ves_io_get_info(io);
  assert_int_equal(in->format_version, VES_IO_FORMAT);
  assert_string_equal(in->version, "9.9.9");
  assert_string_equal(in->backend, "newton");
  assert_string_equal(in->status, "finished");
  assert_string_equal(in->problem, f.problem);
  assert_string_equal(in->source, "/somewhere/p.ini");
  assert_int_equal(in->n, 4);
  assert_int_equal(in->ntri, 2);
  assert_true(in->E0 == 7.5 && in->A0 == 12.5 && in->V0 == 4.25 && in->setup_seconds == 1.25);
  check_rows(io, 3);
  assert_int_equal(ves_io_snapshots(io), 2);
  double y2[8], x2[8], phi2[4], X2[8];
  int tri2[6];
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot(io, 1, y2, x2, phi2, &si), VES_OK);
  assert_memory_equal(y, y2, sizeof y);
  assert_memory_equal(x, x2, sizeof x);
  assert_memory_equal(phi, phi2, sizeof phi);
  ves_io_snapinfo want = snap_of(3);
  assert_memory_equal(&want.state, &si.state, sizeof si.state); /* every field, bit for bit */
  assert_true(si.wall_seconds == want.wall_seconds && si.rows == 3 && si.reconnections == 0);
  assert_int_equal(ves_io_read_mesh(io, X2, tri2), VES_OK);
  assert_memory_equal(f.X, X2, sizeof X2);
  assert_memory_equal(f.tri, tri2, sizeof tri2);
  /* the stored problem text gives back the identical configuration */
  ves_config back;
  assert_int_equal(ves_config_load_text(in->problem, in->source, &back, err, sizeof err), VES_OK);
  for (int i = 0; i < ves_config_count(); i++) {
    ves_config_entry a, b;
    ves_config_entry_get(&f.cfg, i, &a);
    ves_config_entry_get(&back, i, &b);
    assert_true(a.real == b.real && a.integer == b.integer);
    if (a.text) assert_string_equal(a.text, b.text);
  }
  /* misuse */
  assert_int_equal(ves_io_read_series(io, "nope", y2), VES_ERR_ARG);
  assert_int_equal(ves_io_read_snapshot(io, 2, y2, NULL, NULL, NULL), VES_ERR_ARG);
  ves_io_row r = row_of(0);
  assert_int_equal(ves_io_append(io, &r), VES_ERR_ARG); /* read-only */
  ves_io_close(&io);

  /* typed parameters, read with plain HDF5 */
  hid_t h = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
  assert_true(h >= 0);
  hid_t g = H5Gopen2(h, "parameters", H5P_DEFAULT);
  double eps = 0;
  int every = 0;
  hid_t a = H5Aopen(g, "geometry.epsilon", H5P_DEFAULT);
  assert_true(H5Aread(a, H5T_NATIVE_DOUBLE, &eps) >= 0 && eps == f.cfg.epsilon);
  hid_t t = H5Aget_type(a);
  assert_int_equal(H5Tget_class(t), H5T_FLOAT);
  H5Tclose(t), H5Aclose(a);
  a = H5Aopen(g, "output.snapshot_every", H5P_DEFAULT);
  t = H5Aget_type(a);
  assert_int_equal(H5Tget_class(t), H5T_INTEGER);
  assert_true(H5Aread(a, H5T_NATIVE_INT, &every) >= 0 && every == f.cfg.snapshot_every);
  H5Tclose(t), H5Aclose(a);
  a = H5Aopen(g, "solver.backend", H5P_DEFAULT);
  t = H5Aget_type(a);
  assert_int_equal(H5Tget_class(t), H5T_STRING);
  H5Tclose(t), H5Aclose(a);
  H5Gclose(g), H5Fclose(h);

  /* the XDMF file beside it: both collections, every snapshot */
  char xpath[160], text[16384];
  ves_io_xdmf_path(path, xpath, sizeof xpath);
  assert_string_equal(xpath + strlen(xpath) - 8, "/rt.xdmf");
  FILE *xf = fopen(xpath, "r");
  assert_non_null(xf);
  size_t len = fread(text, 1, sizeof text - 1, xf);
  text[len] = 0;
  fclose(xf);
  assert_non_null(strstr(text, "CollectionType=\"Temporal\""));
  assert_non_null(strstr(text, "rt.h5:/snapshots/1/x")); /* the material, not y^a */
  assert_null(strstr(text, "/snapshots/1/y"));
  assert_non_null(strstr(text, "rt.h5:/snapshots/1/phi"));
  assert_non_null(strstr(text, "rt.h5:/mesh/triangles"));
  assert_non_null(strstr(text, "TopologyType=\"Polyvertex\""));
  assert_null(strstr(text, "/snapshots/2/"));
  /* four time stamps (two collections, two snapshots), exact in %.17g */
  const char *p = text;
  double times[4];
  int nt = 0;
  while (nt < 4 && (p = strstr(p, "<Time Value=\""))) times[nt++] = strtod(p += 13, NULL);
  assert_int_equal(nt, 4);
  assert_null(strstr(p, "<Time Value=\"")); /* and no more */
  assert_true(times[0] == 0.0 && times[1] == snap_of(3).state.t && times[3] == times[1]);
  free(f.problem);
}

/* Reopened for writing: rows dropped after a snapshot, appends and
 * snapshots continue the numbering. */
static void test_truncate_continue(void **state) {
  (void)state;
  fake f;
  char path[128], err[512] = "";
  ves_io *io = fake_file(&f, "tc.h5", path, sizeof path);
  double y[8] = {0}, phi[4] = {0};
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s0), VES_OK);
  for (long i = 0; i < 5; i++) {
    ves_io_row r = row_of(i);
    assert_int_equal(ves_io_append(io, &r), VES_OK);
  }
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_OK);
  check_rows(io, 5);
  assert_int_equal(ves_io_truncate(io, 2), VES_OK);
  check_rows(io, 2);
  assert_int_equal(ves_io_truncate(io, 3), VES_ERR_ARG); /* cannot grow */
  ves_io_row r = row_of(2);
  assert_int_equal(ves_io_append(io, &r), VES_OK);
  ves_io_snapinfo s3 = snap_of(3);
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s3), VES_OK);
  assert_int_equal(ves_io_snapshots(io), 2);
  ves_io_close(&io);
  check_index(path, 2);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  check_rows(io, 3);
  ves_io_snapinfo si;
  assert_int_equal(ves_io_read_snapshot(io, 1, NULL, NULL, NULL, &si), VES_OK);
  assert_int_equal(si.state.nstep, 3);
  ves_io_close(&io);
  free(f.problem);
}

/* References (resets): written and read back bit for bit, counted, the
 * point count checked, truncated, and the next one written in place. */
static void test_references(void **state) {
  (void)state;
  fake f;
  char path[128], err[512] = "";
  ves_io *io = fake_file(&f, "ref.h5", path, sizeof path);
  assert_int_equal(ves_io_references(io), 0);
  enum { NQ = 12 };
  double x[8], h[4], xq[2 * NQ], wq[NQ], pd[6 * NQ];
  for (int k = 0; k < 3; k++) {
    for (int i = 0; i < 8; i++) x[i] = f.X[i] + 0.01 * k;
    for (int i = 0; i < 4; i++) h[i] = 0.1 + i + k;
    for (int i = 0; i < 2 * NQ; i++) xq[i] = i / 7.0 + k;
    for (int i = 0; i < NQ; i++) wq[i] = 1.0 / (i + 3 + k);
    for (int i = 0; i < 6 * NQ; i++) pd[i] = sin(i + k);
    ves_io_reference ref = {
        .step = 10 * (k + 1), .nq = NQ, .x = x, .h = h, .xq = xq, .wq = wq, .pd = pd};
    assert_int_equal(ves_io_write_reference(io, &ref), VES_OK);
    assert_int_equal(ves_io_references(io), k + 1);
  }
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_references(io), 3);
  double bx[8], bh[4], bxq[2 * NQ], bwq[NQ], bpd[6 * NQ];
  ves_io_reference_buf b = {.nq = NQ, .x = bx, .h = bh, .xq = bxq, .wq = bwq, .pd = bpd};
  assert_int_equal(ves_io_read_reference(io, 2, &b), VES_OK);
  assert_int_equal(b.step, 30);
  assert_memory_equal(bx, x, sizeof x);
  assert_memory_equal(bh, h, sizeof h);
  assert_memory_equal(bxq, xq, sizeof xq);
  assert_memory_equal(bwq, wq, sizeof wq);
  assert_memory_equal(bpd, pd, sizeof pd);
  assert_int_equal(ves_io_read_reference(io, 3, &b), VES_ERR_ARG);
  b.nq = NQ - 1; /* not the file's */
  assert_int_equal(ves_io_read_reference(io, 0, &b), VES_ERR_IO);
  assert_int_equal(ves_io_truncate_references(io, 1), VES_ERR_ARG); /* read-only */
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_truncate_references(io, 4), VES_ERR_ARG); /* cannot grow */
  assert_int_equal(ves_io_truncate_references(io, 1), VES_OK);
  assert_int_equal(ves_io_references(io), 1);
  ves_io_reference ref = {.step = 99, .nq = NQ, .x = x, .h = h, .xq = xq, .wq = wq, .pd = pd};
  assert_int_equal(ves_io_write_reference(io, &ref), VES_OK);
  assert_int_equal(ves_io_references(io), 2);
  b.nq = NQ;
  assert_int_equal(ves_io_read_reference(io, 1, &b), VES_OK);
  assert_int_equal(b.step, 99);
  ves_io_close(&io);
  free(f.problem);
}

/* A writer killed in the middle: one series a row longer than the others,
 * and a snapshot group written but not counted. The reader sees the
 * complete rows and snapshots; the next snapshot replaces the stray group. */
static void test_killed_writer(void **state) {
  (void)state;
  fake f;
  char path[128], err[512] = "";
  ves_io *io = fake_file(&f, "kw.h5", path, sizeof path);
  double y[8] = {0}, phi[4] = {0};
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s0), VES_OK);
  for (long i = 0; i < 2; i++) {
    ves_io_row r = row_of(i);
    assert_int_equal(ves_io_append(io, &r), VES_OK);
  }
  ves_io_close(&io);
  hid_t h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  assert_true(h >= 0);
  hid_t d = H5Dopen2(h, "series/E", H5P_DEFAULT);
  hsize_t three = 3;
  assert_true(H5Dset_extent(d, &three) >= 0);
  H5Dclose(d);
  hid_t g = H5Gcreate2(h, "snapshots/1", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  assert_true(g >= 0);
  H5Gclose(g), H5Fclose(h);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  check_rows(io, 2); /* the shortest series */
  ves_io_close(&io);
  /* every series extended, "step" (written last) not yet written: its fill
   * value 0 marks the row incomplete */
  h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  g = H5Gopen2(h, "series", H5P_DEFAULT);
  H5G_info_t gi;
  assert_true(H5Gget_info(g, &gi) >= 0 && gi.nlinks == 21);
  for (hsize_t i = 0; i < gi.nlinks; i++) {
    char name[64];
    assert_true(H5Lget_name_by_idx(g, ".", H5_INDEX_NAME, H5_ITER_INC, i, name, sizeof name,
                                   H5P_DEFAULT) > 0);
    d = H5Dopen2(g, name, H5P_DEFAULT);
    assert_true(H5Dset_extent(d, &three) >= 0);
    H5Dclose(d);
  }
  H5Gclose(g), H5Fclose(h);

  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_OK);
  check_rows(io, 2);
  assert_int_equal(ves_io_snapshots(io), 1);
  ves_io_snapinfo s2 = snap_of(2);
  y[3] = 0.75;
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &s2), VES_OK);
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  double y2[8];
  ves_io_snapinfo si;
  assert_int_equal(ves_io_snapshots(io), 2);
  assert_int_equal(ves_io_read_snapshot(io, 1, y2, NULL, NULL, &si), VES_OK);
  assert_true(y2[3] == 0.75 && si.state.nstep == 2);
  ves_io_close(&io);
  free(f.problem);
}

/* Every file that is not ours is refused with the reason, naming it. */
static void test_refusals(void **state) {
  (void)state;
  char path[128], err[512];
  ves_io *io = NULL;
  path_in(path, sizeof path, "missing.h5");
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_ERR_IO);
  assert_non_null(strstr(err, "cannot open"));
  assert_non_null(strstr(err, path));
  path_in(path, sizeof path, "text.h5");
  FILE *t = fopen(path, "w");
  fputs("plain text\n", t);
  fclose(t);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_ERR_IO);
  assert_non_null(strstr(err, "not an HDF5 file"));
  path_in(path, sizeof path, "foreign.h5");
  hid_t h = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
  H5Fclose(h);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "not a vesica output file"));
  /* ours, but from a future version */
  fake f;
  fake_init(&f);
  path_in(path, sizeof path, "future.h5");
  assert_int_equal(ves_io_create(path, &f.h, &io, err, sizeof err), VES_OK);
  ves_io_close(&io);
  h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  int v = 99;
  hid_t a = H5Aopen(h, "format_version", H5P_DEFAULT);
  H5Awrite(a, H5T_NATIVE_INT, &v);
  H5Aclose(a), H5Fclose(h);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "format_version 99"));
  assert_null(io);
  /* format 1 (no snapshot x): read, x given as y; not continued */
  path_in(path, sizeof path, "format1.h5");
  assert_int_equal(ves_io_create(path, &f.h, &io, err, sizeof err), VES_OK);
  double y[8], x[8], phi[4] = {0};
  for (int j = 0; j < 8; j++) y[j] = j + 0.5, x[j] = -j;
  ves_io_snapinfo s0 = snap_of(0);
  assert_int_equal(ves_io_snapshot(io, y, x, phi, &s0), VES_OK);
  ves_io_close(&io);
  h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  v = 1;
  a = H5Aopen(h, "format_version", H5P_DEFAULT);
  H5Awrite(a, H5T_NATIVE_INT, &v);
  H5Aclose(a);
  assert_true(H5Ldelete(h, "snapshots/0/x", H5P_DEFAULT) >= 0);
  H5Fclose(h);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_get_info(io)->format_version, 1);
  assert_int_equal(ves_io_read_snapshot(io, 0, NULL, x, NULL, NULL), VES_OK);
  assert_memory_equal(x, y, sizeof y);
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_ERR_CONFIG);
  assert_non_null(strstr(err, "format_version 1"));
  assert_non_null(strstr(err, "read-only"));
  assert_null(io);
  /* cannot create */
  assert_int_equal(ves_io_create("/nonexistent/dir/x.h5", &f.h, &io, err, sizeof err), VES_ERR_IO);
  assert_non_null(strstr(err, "/nonexistent/dir/x.h5"));
  assert_null(io);
  free(f.problem);
}

/* The material at the nodes (ves_sim_node_material), what the snapshots
 * hold. Sphere of radius 1, eps 0.2 (300 nodes), newton, dt 5e-3.
 *  - t = 0: x = X (the motion is the identity, reproduced by LME to its
 *    Newton tolerance 1e-14 h: bound 1e-12), axis r = 0 and wall nodes
 *    exactly; phi against the exact profile tanh((1 - |X|)/(sqrt2 eps)) to
 *    1e-3 (the least-squares fit at h = 0.7 eps: measured 2.9e-4, 2.2e-4 at
 *    the wall nodes, moved 1e-3 h inwards), and against the setup's own
 *    field sum_b p_b(X_a) phi0c_b to 1e-10 (a refit of that field gives
 *    back phi0c to the projection's 1e-12); with those coefficients given
 *    (ves_sim_set_phi0_coefficients), that field itself;
 *  - after 2 steps: phi bit for bit the same (no reset: the same material),
 *    x moved, axis and walls as above;
 *  - a reset after 2 steps with nodes at y(X_a): x as after the same 2
 *    steps without it (the new nodes are where the material went; LME's
 *    identity to 1e-12), phi carried over bit for bit; with nodes at y^a,
 *    other material: phi refitted on the new reference, within 1e-2 of the
 *    values at t = 0 (the node sets differ by the coefficients' shift, a
 *    small fraction of eps on this smooth motion; measured below).
 * Kept whole (109 lines): one scenario whose checks build on each other. */
static void test_node_material(void **state) {
  (void)state;
  ves_setup *s = tiny_setup(0);
  const ves_nodes *nd = s->nodes;
  const int n = nd->n;
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  ip.t_end = 1, ip.dt_initial = 5e-3, ip.dE_target = 0.05;
  const ves_backend_type *bk = ves_backend_find("newton");
  double *x = malloc(2 * (size_t)n * sizeof *x), *x2 = malloc(2 * (size_t)n * sizeof *x2);
  double *phi = malloc((size_t)n * sizeof *phi), *phi2 = malloc((size_t)n * sizeof *phi2);
  double *f = malloc(6 * (size_t)n * sizeof *f);
  ves_sim *sim = NULL;
  ves_step_report rep;
  assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &sim), VES_OK);
  assert_int_equal(ves_sim_node_material(sim, x, phi), VES_OK);
  ves_quad *pq = NULL;
  assert_int_equal(ves_quad_create_at_nodes(nd, &pq), VES_OK);
  assert_int_equal(ves_quad_tables(pq, nd, &s->quad->lme, NULL), VES_OK);
  ves_quad_field(pq, s->phi0c, 0, f);
  ves_quad_destroy(&pq);
  int walls = 0, axis = 0;
  double ex = 0, worst = 0, worst_wall = 0, efit = 0;
  for (int a = 0; a < n; a++) {
    double R = nd->x[2 * a], Z = nd->x[2 * a + 1];
    double exact = tanh((1 - sqrt(R * R + Z * Z)) / (M_SQRT2 * 0.2)), e = fabs(phi[a] - exact);
    worst = fmax(worst, e);
    efit = fmax(efit, fabs(phi[a] - f[6 * a]));
    ex = fmax(ex, hypot(x[2 * a] - R, x[2 * a + 1] - Z));
    if (nd->flag[a] & VES_NODE_WALL) {
      walls++, worst_wall = fmax(worst_wall, e);
      assert_true(x[2 * a] == R && x[2 * a + 1] == Z);
    }
    if (nd->flag[a] & VES_NODE_AXIS) axis++, assert_true(x[2 * a] == 0.0);
  }
  printf("# %d nodes (%d wall, %d axis): t = 0: max |x - X| = %.1e; max |phi - phi0| = %.2e "
         "(wall %.2e); against the setup's field %.1e\n",
         n, walls, axis, ex, worst, worst_wall, efit);
  assert_true(ex < 1e-12);
  assert_true(worst < 1e-3);
  assert_true(walls > 0 && axis > 0 && worst_wall < 1e-3);
  assert_true(efit < 1e-10);
  for (int i = 0; i < 2; i++) assert_int_equal(ves_sim_step(sim, &rep), VES_OK);
  assert_int_equal(ves_sim_node_material(sim, x2, phi2), VES_OK);
  assert_memory_equal(phi, phi2, (size_t)n * sizeof *phi);
  double moved = 0;
  for (int a = 0; a < n; a++) {
    moved = fmax(moved, hypot(x2[2 * a] - x[2 * a], x2[2 * a + 1] - x[2 * a + 1]));
    if (nd->flag[a] & VES_NODE_WALL) assert_true(x2[2 * a] == x[2 * a]);
    if (nd->flag[a] & VES_NODE_AXIS) assert_true(x2[2 * a] == 0.0);
  }
  printf("# after 2 steps: the material at the nodes moved up to %.2e R0\n", moved);
  assert_true(moved > 1e-6);
  ves_sim_destroy(&sim);

  /* with the setup's coefficients given (as vesica run does): phi is their
   * field at the nodes, bit for bit (no refit), within the refit's 1e-12 of
   * the refitted values above (bound 1e-10, as efit); refused when NULL,
   * non-finite, or after a reset (below) */
  assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &sim), VES_OK);
  assert_int_equal(ves_sim_set_phi0_coefficients(NULL, s->phi0c), VES_ERR_ARG);
  assert_int_equal(ves_sim_set_phi0_coefficients(sim, NULL), VES_ERR_ARG);
  const double keep = s->phi0c[n / 2];
  s->phi0c[n / 2] = NAN;
  assert_int_equal(ves_sim_set_phi0_coefficients(sim, s->phi0c), VES_ERR_ARG);
  s->phi0c[n / 2] = keep;
  assert_int_equal(ves_sim_set_phi0_coefficients(sim, s->phi0c), VES_OK);
  assert_int_equal(ves_sim_node_material(sim, NULL, phi2), VES_OK);
  double dref = 0;
  for (int a = 0; a < n; a++) {
    assert_true(phi2[a] == f[6 * a]);
    dref = fmax(dref, fabs(phi2[a] - phi[a]));
  }
  printf("# with the setup's coefficients: max |phi - phi(refit)| = %.1e\n", dref);
  assert_true(dref < 1e-10);
  ves_sim_destroy(&sim);

  /* a reset after 2 steps: x (against x2, the same 2 steps without a reset)
   * and phi (carried or refitted) */
  for (int mode = 0; mode < 2; mode++) {
    ip.reconnect_every = 2;
    ip.reconnect_nodes = mode ? VES_RESET_NODES_COEF : VES_RESET_NODES_MOTION;
    assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &sim), VES_OK);
    for (int i = 0; i < 2; i++) assert_int_equal(ves_sim_step(sim, &rep), VES_OK);
    assert_int_equal(ves_sim_reconnections(sim), 1);
    assert_int_equal(ves_sim_set_phi0_coefficients(sim, s->phi0c), VES_ERR_ARG); /* a reset's */
    double *phir = mode ? phi2 : x; /* x is free scratch here (2n >= n) */
    assert_int_equal(ves_sim_node_material(sim, f, phir), VES_OK);
    double dx = 0, dphi = 0;
    for (int a = 0; a < n; a++) {
      dx = fmax(dx, hypot(f[2 * a] - x2[2 * a], f[2 * a + 1] - x2[2 * a + 1]));
      dphi = fmax(dphi, fabs(phir[a] - phi[a]));
    }
    printf("# reset, nodes at %s: max |x - x(no reset)| = %.2e, max |phi - phi(t = 0)| = %.2e\n",
           mode ? "y^a" : "y(X_a)", dx, dphi);
    if (mode == 0) {
      assert_true(dx < 1e-12); /* the nodes are where the material went */
      assert_memory_equal(phi, phir, (size_t)n * sizeof *phi);
    } else {
      assert_true(dx > 0); /* new nodes at the coefficients: other material */
      assert_true(dphi > 0 && dphi < 1e-2);
    }
    ves_sim_destroy(&sim);
  }
  free(x), free(x2), free(phi), free(phi2), free(f);
  ves_setup_destroy(&s);
}

/* The restart chain through the library: 4 steps straight, or 2 steps, a
 * snapshot (with the predictor's y^{n-1}), a fresh simulation set from the
 * file and 2 more steps: the same positions, energy, time and next step,
 * bit for bit.
 * Kept whole (92 lines): one scenario whose checks build on each other. */
static void test_restart_chain(void **state) {
  (void)state;
  ves_setup *s = tiny_setup(1);
  int n = s->nodes->n;
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  ip.t_end = 1, ip.dt_initial = 5e-3, ip.dE_target = 0.05;
  const ves_backend_type *bk = ves_backend_find("newton");
  ves_sim *a = NULL, *b = NULL;
  ves_step_report rep;
  assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &a), VES_OK);
  for (int i = 0; i < 4; i++) assert_int_equal(ves_sim_step(a, &rep), VES_OK);
  ves_sim_state sa;
  double *ya = malloc(2 * (size_t)n * sizeof *ya), *yb = malloc(2 * (size_t)n * sizeof *yb);
  double *phi = calloc((size_t)n, sizeof *phi);
  ves_sim_get_state(a, &sa, ya);
  ves_sim_destroy(&a);

  assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &b), VES_OK);
  for (int i = 0; i < 2; i++) assert_int_equal(ves_sim_step(b, &rep), VES_OK);
  ves_io_snapinfo si = {.rows = 2};
  ves_sim_get_state(b, &si.state, yb);
  /* the predictor's y^{n-1} goes with the state (a default run has one) */
  double *ypb = malloc(2 * (size_t)n * sizeof *ypb), *ypr = malloc(2 * (size_t)n * sizeof *ypr);
  assert_true(si.state.dt_prev > 0 && ves_sim_y_prev(b));
  memcpy(ypb, ves_sim_y_prev(b), 2 * (size_t)n * sizeof *ypb);
  si.y_prev = ypb;
  ves_sim_destroy(&b);
  char path[128], err[512] = "";
  path_in(path, sizeof path, "chain.h5");
  char *problem;
  ves_config cfg;
  ves_config_default(&cfg);
  assert_int_equal(ves_config_to_text(&cfg, &problem), VES_OK);
  ves_io_header h = {.version = "t",
                     .backend = "newton",
                     .problem = problem,
                     .source = "",
                     .cfg = &cfg,
                     .n = n,
                     .X = s->nodes->x,
                     .ntri = s->quad->ntri,
                     .tri = s->quad->tri,
                     .E0 = 1,
                     .A0 = 1,
                     .V0 = 1};
  ves_io *io = NULL;
  assert_int_equal(ves_io_create(path, &h, &io, err, sizeof err), VES_OK);
  si.y_prev = NULL; /* a held y^{n-1} must be given */
  assert_int_equal(ves_io_snapshot(io, yb, yb, phi, &si), VES_ERR_ARG);
  si.y_prev = ypb;
  assert_int_equal(ves_io_snapshot(io, yb, yb, phi, &si), VES_OK);
  ves_io_close(&io);
  memset(yb, 0, 2 * (size_t)n * sizeof *yb);

  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  ves_io_snapinfo back;
  assert_int_equal(ves_io_read_snapshot(io, 0, yb, NULL, NULL, &back), VES_OK);
  assert_true(back.state.dt_prev == si.state.dt_prev && !back.y_prev);
  assert_int_equal(ves_io_read_snapshot_prev(io, 0, n, ypr), VES_OK);
  assert_memory_equal(ypr, ypb, 2 * (size_t)n * sizeof *ypr);
  ves_io_close(&io);
  assert_int_equal(ves_sim_create(s->model, bk, &bo, &ip, &b), VES_OK);
  /* dt_prev > 0 without y^{n-1} is refused */
  assert_int_equal(ves_sim_set_state(b, &back.state, yb, NULL), VES_ERR_ARG);
  assert_int_equal(ves_sim_set_state(b, &back.state, yb, ypr), VES_OK);
  ves_sim_state chk;
  ves_sim_get_state(b, &chk, NULL);
  assert_memory_equal(&chk, &back.state, sizeof chk);
  for (int i = 0; i < 2; i++) assert_int_equal(ves_sim_step(b, &rep), VES_OK);
  ves_sim_state sb;
  ves_sim_get_state(b, &sb, yb);
  printf("# straight: t %.6g E %.12g; restarted: t %.6g E %.12g\n", sa.t, sa.E, sb.t, sb.E);
  assert_memory_equal(ya, yb, 2 * (size_t)n * sizeof *ya);
  assert_memory_equal(&sa, &sb, sizeof sa);

  /* bad states are refused and leave the simulation as it was */
  ves_sim_state bad = sb;
  bad.dt = 0;
  assert_int_equal(ves_sim_set_state(b, &bad, yb, ypr), VES_ERR_ARG);
  bad = sb, bad.E = NAN;
  assert_int_equal(ves_sim_set_state(b, &bad, yb, ypr), VES_ERR_ARG);
  yb[0] = INFINITY;
  assert_int_equal(ves_sim_set_state(b, &sb, yb, ypr), VES_ERR_ARG);
  ves_sim_get_state(b, &chk, NULL);
  assert_memory_equal(&chk, &sb, sizeof chk);
  ves_sim_destroy(&b);
  free(ya), free(yb), free(phi), free(problem), free(ypb), free(ypr);
  ves_setup_destroy(&s);
}

/* Self-describing output: units and description on every group and
 * dataset of a file with series, snapshots and references; the root names
 * the program, version, problem and where the format is described. */
static void test_self_describing(void **state) {
  (void)state;
  fake f;
  char path[128];
  ves_io *io = fake_file(&f, "desc.h5", path, sizeof path);
  ves_io_row r = row_of(0);
  assert_int_equal(ves_io_append(io, &r), VES_OK);
  double y[8], x[8], phi[4] = {1, 0.5, -0.25, -1};
  for (int j = 0; j < 8; j++) y[j] = x[j] = f.X[j];
  ves_io_snapinfo si = snap_of(1);
  assert_int_equal(ves_io_snapshot(io, y, x, phi, &si), VES_OK);
  enum { NQ = 3 };
  double h[4] = {0.1, 0.1, 0.1, 0.1}, xq[2 * NQ] = {0}, wq[NQ] = {1, 1, 1}, pd[6 * NQ] = {0};
  ves_io_reference ref = {.step = 1, .nq = NQ, .x = x, .h = h, .xq = xq, .wq = wq, .pd = pd};
  assert_int_equal(ves_io_write_reference(io, &ref), VES_OK);
  ves_io_close(&io);
  hid_t h5 = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
  assert_true(h5 >= 0);
  int count = 0;
  assert_true(H5Ovisit(h5, H5_INDEX_NAME, H5_ITER_INC, described, &count) >= 0);
  /* root, parameters, mesh + 3, series + 21, snapshots + 0 + 3 + interface + its one piece,
   * snapshot_index, references + 0 + 5, provenance + 0 */
  assert_int_equal(count, 1 + 1 + 4 + 22 + 7 + 1 + 7 + 2);
  const char *root[] = {"program", "version",        "problem",
                        "source",  "format_version", "format_description"};
  for (size_t i = 0; i < sizeof root / sizeof root[0]; i++)
    if (H5Aexists(h5, root[i]) <= 0) fail_msg("root: no attribute %s", root[i]);
  /* the status codes as an enumeration: every value with its name */
  hid_t a = H5Aopen_by_name(h5, "series/status", "codes", H5P_DEFAULT, H5P_DEFAULT);
  assert_true(a >= 0);
  hid_t t = H5Aget_type(a);
  assert_int_equal(H5Tget_class(t), H5T_ENUM);
  assert_int_equal(H5Tget_nmembers(t), 14); /* VES_STATUS_LIST */
  char name[32];
  int v = VES_ERR_IO;
  assert_true(H5Tenum_nameof(t, &v, name, sizeof name) >= 0);
  assert_string_equal(name, "VES_ERR_IO");
  v = VES_MAXITER;
  assert_true(H5Tenum_nameof(t, &v, name, sizeof name) >= 0);
  assert_string_equal(name, "VES_MAXITER");
  H5Tclose(t), H5Aclose(a);
  H5Fclose(h5);
  /* and the file still reads */
  char err[512] = "";
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_snapshots(io), 1);
  ves_io_close(&io);
  unlink(path);
  free(f.problem);
}

/* A file of an older writer, without the series column "factorizations"
 * (added on 2026-12-05 within format_version 2): it opens and continues
 * without the column (appends, snapshots), reads it as -1 and summarizes it
 * as not recorded; its checksums, written without the column, hold, so a
 * copy cut short is salvaged, and the salvaged file lacks the column too. */
static void test_older_file(void **state) {
  (void)state;
  fake f;
  char path[128], cut[160], out[192], err[512] = "";
  ves_io *io = fake_file(&f, "old.h5", path, sizeof path);
  ves_io_close(&io);
  hid_t h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
  assert_true(h >= 0 && H5Ldelete(h, "series/factorizations", H5P_DEFAULT) >= 0);
  H5Fclose(h);
  ves_io_summary sum;
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_summarize(io, 0, &sum), VES_OK);
  assert_true(sum.steps == 0 && sum.factorizations == -1); /* not recorded, even without rows */
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_OK);
  double y[8], x[8], phi[4] = {1, 0.5, -0.25, -1};
  for (int j = 0; j < 8; j++) y[j] = f.X[j], x[j] = y[j] + 1e-3;
  for (long i = 0; i <= 6; i++) {
    if (i % 3 == 0) {
      ves_io_snapinfo si = snap_of(i);
      assert_int_equal(ves_io_snapshot(io, y, x, phi, &si), VES_OK);
    }
    ves_io_row r = row_of(i);
    if (i < 6) assert_int_equal(ves_io_append(io, &r), VES_OK);
  }
  assert_int_equal(ves_io_truncate(io, 6), VES_OK);
  ves_io_close(&io);
  assert_int_equal(ves_io_open(path, 0, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_rows(io), 6);
  double v[6], it[6];
  assert_int_equal(ves_io_read_series(io, "factorizations", v), VES_OK);
  assert_int_equal(ves_io_read_series(io, "iterations", it), VES_OK);
  for (int i = 0; i < 6; i++) assert_true(v[i] == -1 && it[i] == row_of(i).iterations);
  assert_int_equal(ves_io_summarize(io, 0, &sum), VES_OK);
  assert_true(sum.factorizations == -1 && sum.iterations == 3 + 4 + 5 + 6 + 7 + 8);
  ves_io_close(&io);
  /* cut short at every 997th byte: some copy keeps a later snapshot, whose
   * series checksum (without the column) held */
  long fsize;
  char *bytes = file_bytes(path, &fsize);
  snprintf(cut, sizeof cut, "%s.cut", path);
  snprintf(out, sizeof out, "%s.salvage", path);
  int later = 0;
  for (long c = 500; c < fsize; c += 997) {
    write_prefix(cut, bytes, c);
    ves_io_salvaged s;
    if (ves_io_salvage(cut, out, &s, err, sizeof err) != VES_OK) continue;
    later += s.snapshot > 0;
    assert_int_equal(ves_io_open(out, 1, &io, err, sizeof err), VES_OK);
    assert_int_equal(ves_io_rows(io), s.rows);
    ves_io_row r = row_of(s.rows); /* it continues, still without the column */
    assert_int_equal(ves_io_append(io, &r), VES_OK);
    double w[7];
    assert_int_equal(ves_io_read_series(io, "factorizations", w), VES_OK);
    for (long i = 0; i <= s.rows; i++) assert_true(w[i] == -1);
    ves_io_close(&io);
    h = H5Fopen(out, H5F_ACC_RDONLY, H5P_DEFAULT);
    assert_true(h >= 0 && H5Lexists(h, "series/factorizations", H5P_DEFAULT) == 0);
    H5Fclose(h);
    remove(out);
  }
  printf("# an older file cut short: %d salvaged copies kept a later snapshot\n", later);
  assert_true(later > 0);
  free(bytes);
  remove(cut), remove(path);
  free(f.problem);
}

/* The snapshot index kept equal to the snapshots: rebuilt at the next
 * snapshot of a file without one (an older writer's) or with a row missing
 * (cut between a snapshot and its row), and shortened with the snapshots
 * (a restart from an earlier one). */
static void test_snapshot_index(void **state) {
  (void)state;
  fake f;
  char path[128], err[512] = "";
  ves_io *io = fake_file(&f, "index.h5", path, sizeof path);
  double y[8] = {0}, phi[4] = {0};
  int k = 0;
  for (; k < 3; k++) {
    ves_io_snapinfo si = snap_of(2 * k);
    assert_int_equal(ves_io_snapshot(io, y, y, phi, &si), VES_OK);
  }
  ves_io_close(&io);
  check_index(path, 3);
  for (int damage = 0; damage < 2; damage++) {
    hid_t h = H5Fopen(path, H5F_ACC_RDWR, H5P_DEFAULT);
    assert_true(h >= 0);
    if (damage == 0) { /* no index at all */
      assert_true(H5Ldelete(h, "snapshot_index", H5P_DEFAULT) >= 0);
    } else { /* the last row missing */
      hid_t d = H5Dopen2(h, "snapshot_index", H5P_DEFAULT);
      hsize_t one = 1;
      assert_true(d >= 0 && H5Dset_extent(d, &one) >= 0);
      H5Dclose(d);
    }
    H5Fclose(h);
    assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_OK);
    ves_io_snapinfo si = snap_of(2 * k++);
    assert_int_equal(ves_io_snapshot(io, y, y, phi, &si), VES_OK);
    ves_io_close(&io);
    check_index(path, k);
  }
  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_OK);
  assert_int_equal(ves_io_truncate_snapshots(io, 2), VES_OK);
  ves_io_close(&io);
  check_index(path, 2);
  assert_int_equal(ves_io_open(path, 1, &io, err, sizeof err), VES_OK);
  ves_io_snapinfo si = snap_of(7); /* a later state in place of snapshot 2 */
  assert_int_equal(ves_io_snapshot(io, y, y, phi, &si), VES_OK);
  ves_io_close(&io);
  check_index(path, 3);
  remove(path);
  free(f.problem);
}

int main(int argc, char **argv) {
  (void)argc, (void)argv;
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_roundtrip),
      cmocka_unit_test(test_truncate_continue),
      cmocka_unit_test(test_killed_writer),
      cmocka_unit_test(test_references),
      cmocka_unit_test(test_refusals),
      cmocka_unit_test(test_node_material),
      cmocka_unit_test(test_restart_chain),
      cmocka_unit_test(test_self_describing),
      cmocka_unit_test(test_older_file),
      cmocka_unit_test(test_snapshot_index),
  };
  // clang-format on
  return cmocka_run_group_tests_name("io", tests, setup_all, teardown_all);
}
