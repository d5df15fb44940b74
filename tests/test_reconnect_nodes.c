/* vesica — tests of the reset of the reference configuration
 * (solver/time/reconnect.c): new nodes at the motion of the old ones, the
 * carried state, the distortion measure on affine motions, the reset policy,
 * the drift reset, the new quadrature and model constructors, the restore
 * of a stored reference, and the error paths. */
#include "reconnect_test_impl.h"

/* ------------------------------------------------------------------------ */
/* New nodes at the motion of the old ones                                   */
/* ------------------------------------------------------------------------ */

/* VES_RESET_NODES_MOTION: X'_a = y(X_a). Checked: z(X_a) of the non-wall
 * nodes against the even-field path (ves_quad_field on a point set at the
 * nodes; the motion goes through ves_quad_motion) to 1e-13
 * (rounding of a sum of ~20 terms of size 2); axis nodes at r = 0 exactly, every other r > 0; wall
 * nodes at y^a; the shift max |y^a - y(X_a)| / h_a the same in both modes, and 0 to rounding
 * (1e-12) on a stretch y = (1.2 R, 0.9 Z + 0.05), which the basis reproduces exactly. E, A, V are
 * preserved as with the paper's nodes (1e-12), and the next step agrees with the step without a
 * reset as test_next_step_deformed requires of the paper's nodes (same bounds). */
static void test_motion_nodes(void **state) {
  (void)state;
  const int n = P->n, n2 = 2 * n;
  const ves_nodes *n0 = P->su->nodes;
  ves_model *m0 = P->su->model;
  ves_reconnect *rc = reset(m0, P->yd), *r = NULL;
  assert_int_equal(ves_reconnect_create(m0, P->yd, VES_RESET_NODES_MOTION, &r), VES_OK);
  ves_reconnect_info ic, im;
  ves_reconnect_get_info(rc, &ic);
  ves_reconnect_get_info(r, &im);
  const ves_nodes *nn = ves_reconnect_nodes(r);
  double *zc = xmalloc(n), *zx = xmalloc(n), ez = 0;
  for (int a = 0; a < n; a++) zc[a] = P->yd[2 * a + 1];
  ves_quad *pq = NULL;
  double *fz = xmalloc(6 * n);
  assert_int_equal(ves_quad_create_at_nodes(n0, &pq), VES_OK);
  assert_int_equal(ves_quad_tables(pq, n0, &P->lme, NULL), VES_OK);
  ves_quad_field(pq, zc, 0, fz); /* z is even in R: ghosts carry their node's value */
  for (int a = 0; a < n; a++) zx[a] = fz[6 * a];
  ves_quad_destroy(&pq);
  free(fz);
  int wall = 0, axis = 0;
  for (int a = 0; a < n; a++) {
    if (n0->flag[a] & VES_NODE_WALL) {
      assert_true(nn->x[2 * a] == P->yd[2 * a] && nn->x[2 * a + 1] == P->yd[2 * a + 1]);
      wall++;
      continue;
    }
    if (n0->flag[a] & VES_NODE_AXIS)
      assert_true(nn->x[2 * a] == 0.0), axis++;
    else
      assert_true(nn->x[2 * a] > 0.0);
    ez = fmax(ez, fabs(nn->x[2 * a + 1] - zx[a]));
  }
  printf("# motion nodes at yd: shift max |y^a - y(X_a)|/h_a = %.3e (paper's nodes: %.3e), "
         "%d mirrored / %d; z(X_a) vs the field path %.1e (%d wall, %d axis nodes)\n",
         im.shift_max, ic.shift_max, im.mirrored, ic.mirrored, ez, wall, axis);
  assert_true(ez <= 1e-13);
  assert_true(im.shift_max == ic.shift_max && im.shift_max > 0);
  assert_true(wall > 0 && axis > 0);

  /* invariance: y on the old model, the new nodes on the new one */
  ves_model *m1 = ves_reconnect_model(r);
  double v0[3], v1[3];
  eav(m0, P->yd, v0);
  eav(m1, nn->x, v1);
  printf("# motion nodes: E, A, V relative change %.1e %.1e %.1e\n", v1[0] / v0[0] - 1,
         v1[1] / v0[1] - 1, v1[2] / v0[2] - 1);
  for (int k = 0; k < 3; k++) assert_true(fabs(v1[k] / v0[k] - 1) <= 1e-12);

  /* the next step, as test_next_step_deformed */
  check_next_step(m0, P->yd, m1, nn->x, "motion nodes");
  ves_reconnect_destroy(&r);
  ves_reconnect_destroy(&rc);

  /* a stretch: y(X_a) = y^a to rounding */
  double *ys = xmalloc(n2);
  for (int a = 0; a < n; a++)
    ys[2 * a] = 1.2 * P->X[2 * a], ys[2 * a + 1] = 0.9 * P->X[2 * a + 1] + 0.05;
  assert_int_equal(ves_reconnect_create(m0, ys, VES_RESET_NODES_MOTION, &r), VES_OK);
  ves_reconnect_get_info(r, &im);
  printf("# stretch: shift %.1e\n", im.shift_max);
  assert_true(im.shift_max <= 1e-12);
  ves_reconnect_destroy(&r);
  free(zc), free(zx), free(ys);
}

/* ves_reconnect_carry (the predictor's y^{n-1} onto the new reference), in
 * both modes: carrying y itself gives the reset's new nodes bit for bit (the
 * same computation); a second state z = y + (a R, d Z + e) (odd in R, even
 * in Z, as the ghosts require: the basis reproduces it) is carried to the
 * new nodes plus the same map of the old ones to rounding (1e-13: sums of
 * ~20 terms of size 2), wall nodes at z^a, axis nodes at r = 0 exactly; with
 * the paper's nodes zn = z. Errors: NULL, a bad mode, non-finite z. */
static void test_carry(void **state) {
  (void)state;
  const int n = P->n;
  const ves_nodes *n0 = P->su->nodes;
  ves_model *m0 = P->su->model;
  double *z = xmalloc(2 * n), *zn = xmalloc(2 * n);
  for (int a = 0; a < n; a++) /* the wall nodes' z^a moves too: the carry keeps it */
    z[2 * a] = P->yd[2 * a] + 0.03 * P->X[2 * a],
          z[2 * a + 1] = P->yd[2 * a + 1] - 0.02 * P->X[2 * a + 1] + 0.01;
  for (int mode = 0; mode < 2; mode++) {
    const ves_reset_nodes where = mode ? VES_RESET_NODES_MOTION : VES_RESET_NODES_COEF;
    ves_reconnect *r = NULL;
    assert_int_equal(ves_reconnect_create(m0, P->yd, where, &r), VES_OK);
    const ves_nodes *nn = ves_reconnect_nodes(r);
    assert_int_equal(ves_reconnect_carry(m0, P->yd, where, P->yd, zn), VES_OK);
    assert_memory_equal(zn, nn->x, 2 * (size_t)n * sizeof *zn);
    assert_int_equal(ves_reconnect_carry(m0, P->yd, where, z, zn), VES_OK);
    double err = 0;
    for (int a = 0; a < n; a++) {
      if (n0->flag[a] & VES_NODE_WALL) {
        assert_true(zn[2 * a] == z[2 * a] && zn[2 * a + 1] == z[2 * a + 1]);
        continue;
      }
      if (n0->flag[a] & VES_NODE_AXIS) assert_true(zn[2 * a] == 0.0);
      if (!mode) {
        assert_true(zn[2 * a] == z[2 * a] && zn[2 * a + 1] == z[2 * a + 1]);
        continue;
      }
      err = fmax(err, fabs(zn[2 * a] - (nn->x[2 * a] + 0.03 * P->X[2 * a])));
      err = fmax(err, fabs(zn[2 * a + 1] - (nn->x[2 * a + 1] - 0.02 * P->X[2 * a + 1] + 0.01)));
    }
    printf("# carry (%s): max |zn - (new node + map of the old)| = %.1e\n",
           mode ? "motion" : "coefficients", err);
    assert_true(err <= 1e-13);
    ves_reconnect_destroy(&r);
  }
  assert_int_equal(ves_reconnect_carry(NULL, P->yd, VES_RESET_NODES_COEF, z, zn), VES_ERR_ARG);
  assert_int_equal(ves_reconnect_carry(m0, P->yd, (ves_reset_nodes)7, z, zn), VES_ERR_ARG);
  z[5] = NAN;
  assert_int_equal(ves_reconnect_carry(m0, P->yd, VES_RESET_NODES_MOTION, z, zn), VES_ERR_ARG);
  free(z), free(zn);
}

/* ------------------------------------------------------------------------ */
/* Distortion, policy, constructors, errors                                  */
/* ------------------------------------------------------------------------ */

/* Exact values on affine motions. A stretch y = (a R, d Z + e) is odd/even
 * as the ghosts require, so the LME reproduces it at every point: cond =
 * max(a/d, d/a), det = a d, to rounding (1e-13). A shear or a rotation is not
 * (the ghosts carry (-r, z), not the affine image of (-R, Z)), so per point
 * the exact values hold where no ghost is a neighbour: shear
 * y = (R + s Z, Z): cond = ((4 + s^2)^(1/2) + s)^2 / 4, det = 1; rotation by
 * 0.4 with a stretch 1.5: cond = 1.5, det = 1.5. Also ves_quad_motion at
 * y = X: r = R, z = Z, F = I, G = 0 at every point (ghost signs). */
static void test_distortion_affine(void **state) {
  (void)state;
  ves_model *m = P->su->model;
  const ves_quad *q = P->su->quad;
  const int n2 = 2 * P->n, nq = q->nq;
  double *y = xmalloc(n2), *cond = xmalloc((size_t)nq), *det = xmalloc((size_t)nq), c, d;
  double err = 0;
  for (int al = 0; al < nq; al++) {
    double mo[12];
    ves_quad_motion(q, P->X, al, 2, mo);
    const double ref[12] = {q->x[2 * al], 1, 0, 0, 0, 0, q->x[2 * al + 1], 0, 1, 0, 0, 0};
    for (int j = 0; j < 12; j++) err = fmax(err, fabs(mo[j] - ref[j]) * (j % 6 >= 3 ? 0.01 : 1));
  }
  printf("# motion at y = X: max error %.1e (second derivatives scaled by h^2 ~ 0.01)\n", err);
  assert_true(err <= 1e-12); /* affine reproduction of the tables */
  assert_int_equal(ves_reconnect_distortion(m, P->X, &c, &d), VES_OK);
  assert_true(fabs(c - 1) <= 1e-12 && fabs(d - 1) <= 1e-12);

  const double st[3][3] = {{1.2, 0.8, 0.1}, {0.7, 1.0, -0.3}, {1.5, 1.5, 0.0}};
  for (int k = 0; k < 3; k++) {
    for (int a = 0; a < P->n; a++)
      y[2 * a] = st[k][0] * P->X[2 * a], y[2 * a + 1] = st[k][1] * P->X[2 * a + 1] + st[k][2];
    assert_int_equal(ves_reconnect_distortion(m, y, &c, &d), VES_OK);
    const double ce = fmax(st[k][0] / st[k][1], st[k][1] / st[k][0]), de = st[k][0] * st[k][1];
    printf("# stretch (%.1f, %.1f): cond %.15f (exact %.15f), det %.15f (exact %.15f)\n", st[k][0],
           st[k][1], c, ce, d, de);
    assert_true(fabs(c - ce) <= 1e-13 * ce && fabs(d - de) <= 1e-13 * de);
  }
  /* shear and rotation, per point away from the ghosts */
  const double s = 0.5, th = 0.4, sc = 1.5;
  for (int kind = 0; kind < 2; kind++) {
    for (int a = 0; a < P->n; a++) {
      const double R = P->X[2 * a], Z = P->X[2 * a + 1];
      if (kind == 0)
        y[2 * a] = R + s * Z, y[2 * a + 1] = Z;
      else
        y[2 * a] = sc * (cos(th) * R - sin(th) * Z),
              y[2 * a + 1] = sc * (sin(th) * R + cos(th) * Z);
    }
    const double ce = kind == 0 ? pow(sqrt(4 + s * s) + s, 2) / 4 : 1.0, de = kind ? sc * sc : 1;
    assert_int_equal(ves_reconnect_distortion_points(m, y, cond, det), VES_OK);
    int cnt = 0;
    double ec = 0, ed = 0;
    for (int al = 0; al < nq; al++) {
      int ghost = 0;
      for (int t = q->ptr[al]; t < q->ptr[al + 1]; t++) ghost |= q->mirror[t];
      if (ghost) continue;
      cnt++;
      ec = fmax(ec, fabs(cond[al] - ce) / ce), ed = fmax(ed, fabs(det[al] - de) / de);
    }
    printf("# %s: %d of %d points without ghost neighbours: cond rel err %.1e (exact %.6f), det "
           "rel err %.1e\n",
           kind ? "rotation x 1.5" : "shear 0.5", cnt, nq, ec, ce, ed);
    assert_true(cnt > nq / 2);
    assert_true(ec <= 1e-12 && ed <= 1e-12);
    /* the scalar measure agrees with the per-point maximum and minimum */
    double cm = 1, dm = INFINITY;
    for (int al = 0; al < nq; al++) cm = fmax(cm, cond[al]), dm = fmin(dm, det[al]);
    assert_int_equal(ves_reconnect_distortion(m, y, &c, &d), VES_OK);
    assert_true(c == cm && d == dm);
  }
  /* a fold: y_z = -Z: det = -1, cond = +inf */
  for (int a = 0; a < P->n; a++) y[2 * a] = P->X[2 * a], y[2 * a + 1] = -P->X[2 * a + 1];
  assert_int_equal(ves_reconnect_distortion(m, y, &c, &d), VES_OK);
  assert_true(isinf(c) && fabs(d + 1) <= 1e-12);
  free(y), free(cond), free(det);
}

/* The policy: count, cond and det criteria each trigger alone. */
static void test_due(void **state) {
  (void)state;
  ves_model *m = P->su->model;
  ves_reconnect_params par;
  ves_reconnect_params_default(&par);
  assert_int_equal(par.every, 0);
  int due = -1;
  double c, d;
  /* at the reference: nothing due */
  assert_int_equal(ves_reconnect_due(&par, m, P->X, 1000, &due, &c, &d), VES_OK);
  assert_int_equal(due, 0);
  /* yd (cond 1.875, det 0.696): not due by default (every criterion off) */
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, 5, &due, &c, &d), VES_OK);
  assert_int_equal(due, 0);
  par.cond_max = 2, par.det_min = 0.5; /* not due at the reasoned thresholds either */
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, 5, &due, &c, &d), VES_OK);
  assert_int_equal(due, 0);
  par.det_min = 0;
  par.cond_max = 1.8; /* cond alone */
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, 5, &due, &c, &d), VES_OK);
  assert_int_equal(due, 1);
  par.cond_max = 0, par.det_min = 0.7; /* det alone */
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, 5, &due, &c, &d), VES_OK);
  assert_int_equal(due, 1);
  par.det_min = 0, par.every = 20; /* count alone: no distortion measured */
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, 19, &due, &c, &d), VES_OK);
  assert_true(due == 0 && c == 1 && d == 1);
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, 20, &due, NULL, NULL), VES_OK);
  assert_int_equal(due, 1);
  /* bad parameters */
  par.every = -1;
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, 5, &due, NULL, NULL), VES_ERR_ARG);
  par.every = 0, par.cond_max = 0.5;
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, 5, &due, NULL, NULL), VES_ERR_ARG);
  par.cond_max = 0, par.det_min = 1.0;
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, 5, &due, NULL, NULL), VES_ERR_ARG);
  par.det_min = NAN;
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, 5, &due, NULL, NULL), VES_ERR_ARG);
  ves_reconnect_params_default(&par);
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, -1, &due, NULL, NULL), VES_ERR_ARG);
  assert_int_equal(ves_reconnect_due(NULL, m, P->yd, 0, &due, NULL, NULL), VES_ERR_ARG);
  assert_int_equal(ves_reconnect_due(&par, m, P->yd, 0, NULL, NULL, NULL), VES_ERR_ARG);
}

/* The drift damping across a reset: the new model keeps the parameter and
 * builds S on the NEW nodes. A model with drift 0.5 and one without, both
 * reset at the deformed state: E, A, V of the new models bitwise equal (S
 * is in K only); on the affine motion dy = (0.3 r, -0.2 z + 0.1) of the new
 * reference the two K agree to rounding (S vanishes on motions affine in
 * the new reference: a stale S on the old nodes would not, since dy is not
 * affine in X there), and on a random motion the damped K is larger.
 * 1e-12 of dy^T K dy: sums of ~1e5 products of either sign. */
static void test_drift_reset(void **state) {
  (void)state;
  ves_model *m0 = P->su->model, *md = NULL;
  const ves_quad *q = P->su->quad;
  const int n2 = 2 * P->n;
  ves_model_params par;
  ves_model_get_params(m0, &par);
  assert_true(par.drift == 0);
  par.drift = 0.5;
  double *pd = xmalloc(6 * (size_t)q->nq);
  ves_model_point_data(m0, pd);
  assert_int_equal(ves_model_create_points(P->su->nodes, q, pd, &par, &md), VES_OK);
  ves_reconnect *r0 = reset(m0, P->yd), *rd = reset(md, P->yd);
  ves_model *m1 = ves_reconnect_model(r0), *m1d = ves_reconnect_model(rd);
  ves_model_params p1;
  ves_model_get_params(m1d, &p1);
  assert_true(p1.drift == 0.5);
  double v1[3], v1d[3];
  eav(m1, P->yd, v1);
  eav(m1d, P->yd, v1d);
  assert_memory_equal(v1, v1d, sizeof v1);
  const ves_pattern *pa = ves_model_pattern(m1), *pb = ves_model_pattern(m1d);
  double *ba = xmalloc(4 * (size_t)pa->ptr[P->n]), *bb = xmalloc(4 * (size_t)pb->ptr[P->n]);
  double *dy = xmalloc(n2);
  assert_int_equal(ves_model_dissipation(m1, P->yd, ba), VES_OK);
  assert_int_equal(ves_model_dissipation(m1d, P->yd, bb), VES_OK);
  for (int a = 0; a < P->n; a++)
    dy[2 * a] = 0.3 * P->yd[2 * a], dy[2 * a + 1] = -0.2 * P->yd[2 * a + 1] + 0.1;
  const double ka = blk_quad(pa, ba, dy), kb = blk_quad(pb, bb, dy);
  unsigned long rng = 12345; /* a deterministic pseudo-random motion in [-1, 1) */
  for (int i = 0; i < n2; i++)
    rng = rng * 6364136223846793005UL + 1442695040888963407UL,
    dy[i] = (double)(rng >> 11) * 0x1.0p-52 - 1;
  for (int a = 0; a < P->n; a++)
    if (P->su->nodes->flag[a] & (VES_NODE_AXIS | VES_NODE_WALL)) dy[2 * a] = 0;
  const double ra = blk_quad(pa, ba, dy), rb = blk_quad(pb, bb, dy);
  printf("# after the reset: affine dy^T K dy %.12e (undamped %.12e, rel diff %.1e); random "
         "%.6e (undamped %.6e)\n",
         kb, ka, fabs(kb - ka) / ka, rb, ra);
  assert_true(fabs(kb - ka) <= 1e-12 * ka);
  assert_true(rb > ra * (1 + 1e-3));
  ves_reconnect_destroy(&r0), ves_reconnect_destroy(&rd);
  ves_model_destroy(&md);
  free(pd), free(ba), free(bb), free(dy);
}

/* ves_model_create_points from a model's own point data, nodes and
 * quadrature rebuilds the same model: E, A, V and gradients bitwise equal
 * (the same point data and the same assembly). ves_quad_create_points copies
 * what it is given; with ntri = 0 it is an evaluation-only point set the
 * model refuses. Error paths of both. */
static void test_constructors(void **state) {
  (void)state;
  ves_model *m0 = P->su->model, *m1 = NULL;
  const ves_quad *q = P->su->quad;
  const int nq = q->nq, n2 = 2 * P->n;
  double *pd = xmalloc(6 * (size_t)nq), *g0 = xmalloc(3 * (size_t)n2),
         *g1 = xmalloc(3 * (size_t)n2);
  double v0[3], v1[3];
  ves_model_params par;
  ves_model_get_params(m0, &par);
  assert_true(par.eps == P->cfg.epsilon && par.c0 == P->cfg.c0);
  assert_ptr_equal(ves_model_nodes(m0), P->su->nodes);
  assert_ptr_equal(ves_model_quad(m0), P->su->quad);
  ves_model_point_data(m0, pd);
  assert_int_equal(ves_model_create_points(P->su->nodes, q, pd, &par, &m1), VES_OK);
  assert_int_equal(ves_model_eval(m0, P->yd, 7, v0, v0 + 1, v0 + 2, g0, g0 + n2, g0 + 2 * n2),
                   VES_OK);
  assert_int_equal(ves_model_eval(m1, P->yd, 7, v1, v1 + 1, v1 + 2, g1, g1 + n2, g1 + 2 * n2),
                   VES_OK);
  assert_memory_equal(v0, v1, sizeof v0);
  assert_memory_equal(g0, g1, 3 * (size_t)n2 * sizeof *g0);
  ves_model_destroy(&m1);

  /* a copy of the quadrature, then tables: the same tables */
  ves_quad *qc = NULL, *qe = (ves_quad *)1;
  assert_int_equal(ves_quad_create_points(nq, q->x, q->w, q->ntri, q->tri, &qc), VES_OK);
  assert_true(qc->nq == nq && qc->ntri == q->ntri && qc->tab == NULL);
  assert_int_equal(ves_quad_tables(qc, P->su->nodes, &P->lme, NULL), VES_OK);
  assert_memory_equal(qc->ptr, q->ptr, ((size_t)nq + 1) * sizeof *q->ptr);
  assert_memory_equal(qc->tab, q->tab, 6 * (size_t)q->ptr[nq] * sizeof *q->tab);
  ves_quad_destroy(&qc);
  /* evaluation-only point set: tables yes, a model no */
  assert_int_equal(ves_quad_create_points(5, q->x, q->w, 0, NULL, &qc), VES_OK);
  assert_int_equal(ves_quad_tables(qc, P->su->nodes, &P->lme, NULL), VES_OK);
  assert_int_equal(ves_model_create_points(P->su->nodes, qc, pd, &par, &m1), VES_ERR_ARG);
  assert_null(m1);
  ves_quad_destroy(&qc);
  /* errors */
  double wbad[6] = {1, 1, 1, 0, 1, 1}, xnan[12];
  memcpy(xnan, q->x, sizeof xnan);
  xnan[3] = NAN;
  const int tbad[3] = {0, -1, 2};
  assert_int_equal(ves_quad_create_points(0, q->x, q->w, 0, NULL, &qe), VES_ERR_ARG);
  assert_null(qe);
  assert_int_equal(ves_quad_create_points(6, q->x, wbad, 1, q->tri, &qe), VES_ERR_ARG);
  assert_int_equal(ves_quad_create_points(6, xnan, q->w, 1, q->tri, &qe), VES_ERR_ARG);
  assert_int_equal(ves_quad_create_points(6, q->x, q->w, 1, tbad, &qe), VES_ERR_ARG);
  assert_int_equal(ves_quad_create_points(7, q->x, q->w, 1, q->tri, &qe), VES_ERR_ARG);
  assert_int_equal(ves_quad_create_points(6, q->x, q->w, 1, NULL, &qe), VES_ERR_ARG);
  assert_int_equal(ves_quad_create_points(6, q->x, q->w, 1, q->tri, NULL), VES_ERR_ARG);
  pd[6 * 10 + 4] = INFINITY;
  m1 = (ves_model *)1;
  assert_int_equal(ves_model_create_points(P->su->nodes, q, pd, &par, &m1), VES_ERR_ARG);
  assert_null(m1);
  assert_int_equal(ves_model_create_points(P->su->nodes, q, NULL, &par, &m1), VES_ERR_ARG);
  par.eps = 0;
  ves_model_point_data(m0, pd);
  assert_int_equal(ves_model_create_points(P->su->nodes, q, pd, &par, &m1), VES_ERR_ARG);
  free(pd), free(g0), free(g1);
}

/* ves_reconnect_restore from what a reset stores (nodes, spacings, points,
 * weights, point data): the same tables and the same model, bit for bit
 * (values and gradients of E, A, V at a further deformed state), then a
 * second reset from each gives the same new reference. Errors: a wrong
 * point count, h <= 0, r < 0. */
static void test_restore(void **state) {
  (void)state;
  const int n = P->n, n2 = 2 * n;
  ves_reconnect *r1 = NULL, *rr = NULL;
  assert_int_equal(ves_reconnect_create(P->su->model, P->yd, VES_RESET_NODES_MOTION, &r1), VES_OK);
  const ves_nodes *nd = ves_reconnect_nodes(r1);
  const ves_quad *q = ves_reconnect_quad(r1);
  const int nq = q->nq;
  double *pd = xmalloc(6 * (size_t)nq);
  ves_model_point_data(ves_reconnect_model_const(r1), pd);
  assert_int_equal(ves_reconnect_restore(P->su->model, nd->x, nd->h, nq, q->x, q->w, pd, &rr),
                   VES_OK);
  const ves_quad *qr = ves_reconnect_quad(rr);
  assert_memory_equal(ves_reconnect_nodes(rr)->x, nd->x, (size_t)n2 * sizeof *nd->x);
  assert_memory_equal(ves_reconnect_nodes(rr)->h, nd->h, (size_t)n * sizeof *nd->h);
  assert_memory_equal(qr->ptr, q->ptr, ((size_t)nq + 1) * sizeof *q->ptr);
  assert_memory_equal(qr->nbr, q->nbr, (size_t)q->ptr[nq] * sizeof *q->nbr);
  assert_memory_equal(qr->tab, q->tab, 6 * (size_t)q->ptr[nq] * sizeof *q->tab);
  /* a further motion on the new reference: the same model */
  double *y2 = xmalloc((size_t)n2), *g1 = xmalloc(3 * (size_t)n2), *g2 = xmalloc(3 * (size_t)n2);
  double v1[3], v2[3];
  smooth_motion(nd, nd->x, 0.5 * AMP, y2);
  assert_int_equal(
      ves_model_eval(ves_reconnect_model(r1), y2, 7, v1, v1 + 1, v1 + 2, g1, g1 + n2, g1 + 2 * n2),
      VES_OK);
  assert_int_equal(
      ves_model_eval(ves_reconnect_model(rr), y2, 7, v2, v2 + 1, v2 + 2, g2, g2 + n2, g2 + 2 * n2),
      VES_OK);
  assert_memory_equal(v1, v2, sizeof v1);
  assert_memory_equal(g1, g2, 3 * (size_t)n2 * sizeof *g1);
  /* and the next reset from either */
  ves_reconnect *s1 = NULL, *s2 = NULL;
  assert_int_equal(ves_reconnect_create(ves_reconnect_model(r1), y2, VES_RESET_NODES_MOTION, &s1),
                   VES_OK);
  assert_int_equal(ves_reconnect_create(ves_reconnect_model(rr), y2, VES_RESET_NODES_MOTION, &s2),
                   VES_OK);
  assert_memory_equal(ves_reconnect_nodes(s1)->h, ves_reconnect_nodes(s2)->h,
                      (size_t)n * sizeof(double));
  assert_memory_equal(ves_reconnect_quad(s1)->tab, ves_reconnect_quad(s2)->tab,
                      6 * (size_t)ves_reconnect_quad(s1)->ptr[nq] * sizeof(double));
  printf("# restored reference: %d nodes, %d points, tables and model identical; E* %.12g\n", n, nq,
         v2[0] / P->cfg.k);
  ves_reconnect_destroy(&s1), ves_reconnect_destroy(&s2);
  ves_reconnect_destroy(&rr);
  /* errors */
  double *h = xmalloc((size_t)n), *x = xmalloc((size_t)n2);
  memcpy(h, nd->h, (size_t)n * sizeof *h);
  memcpy(x, nd->x, (size_t)n2 * sizeof *x);
  rr = (ves_reconnect *)1;
  assert_int_equal(ves_reconnect_restore(P->su->model, x, h, nq - 1, q->x, q->w, pd, &rr),
                   VES_ERR_ARG);
  assert_null(rr);
  h[7] = 0;
  assert_int_equal(ves_reconnect_restore(P->su->model, x, h, nq, q->x, q->w, pd, &rr), VES_ERR_ARG);
  h[7] = nd->h[7];
  int a = 0;
  while (nd->flag[a] & VES_NODE_AXIS) a++;
  x[2 * a] = -x[2 * a];
  assert_int_equal(ves_reconnect_restore(P->su->model, x, h, nq, q->x, q->w, pd, &rr), VES_ERR_ARG);
  ves_reconnect_destroy(&r1);
  free(pd), free(y2), free(g1), free(g2), free(h), free(x);
}

/* Error paths of the reset and the distortion measure.
 * Kept whole (100 lines): one scenario whose checks build on each other. */
static void test_errors(void **state) {
  (void)state;
  ves_model *m = P->su->model;
  const int n2 = 2 * P->n;
  double *y = xmalloc(n2), c, d;
  ves_reconnect *r = (ves_reconnect *)1;
  /* arguments */
  assert_int_equal(ves_reconnect_create(NULL, P->yd, VES_RESET_NODES_COEF, &r), VES_ERR_ARG);
  assert_null(r);
  assert_int_equal(ves_reconnect_create(m, NULL, VES_RESET_NODES_COEF, &r), VES_ERR_ARG);
  assert_int_equal(ves_reconnect_create(m, P->yd, VES_RESET_NODES_COEF, NULL), VES_ERR_ARG);
  assert_int_equal(ves_reconnect_create(m, P->yd, (ves_reset_nodes)2, &r), VES_ERR_ARG);
  assert_null(r);
  memcpy(y, P->yd, n2 * sizeof *y);
  y[7] = NAN;
  assert_int_equal(ves_reconnect_create(m, y, VES_RESET_NODES_COEF, &r), VES_ERR_ARG);
  assert_int_equal(ves_reconnect_distortion(m, y, &c, &d), VES_ERR_ARG);
  assert_int_equal(ves_reconnect_distortion_points(m, y, NULL, NULL), VES_ERR_ARG);
  assert_int_equal(ves_reconnect_distortion(NULL, P->yd, &c, &d), VES_ERR_ARG);
  assert_int_equal(ves_reconnect_distortion_points(m, NULL, NULL, NULL), VES_ERR_ARG);
  /* an axis node off the axis */
  memcpy(y, P->yd, n2 * sizeof *y);
  int axis = -1;
  for (int a = 0; a < P->n && axis < 0; a++)
    if ((P->su->nodes->flag[a] & VES_NODE_AXIS) && !(P->su->nodes->flag[a] & VES_NODE_WALL))
      axis = a;
  assert_true(axis >= 0);
  y[2 * axis] = 1e-3;
  assert_int_equal(ves_reconnect_create(m, y, VES_RESET_NODES_COEF, &r), VES_ERR_ARG);
  assert_null(r);
  /* a fold (y_z = -Z): det F = -1 at every point */
  for (int a = 0; a < P->n; a++) y[2 * a] = P->X[2 * a], y[2 * a + 1] = -P->X[2 * a + 1];
  assert_int_equal(ves_reconnect_create(m, y, VES_RESET_NODES_COEF, &r), VES_ERR_DOMAIN);
  /* a node pushed through the axis: its points keep r > 0 and det F > 0
   * (the basis is smooth); the node is mirrored (it and its ghost swap
   * roles: the same point set), and E, A, V are preserved as by any reset */
  memcpy(y, P->X, n2 * sizeof *y);
  int near = -1;
  for (int a = 0; a < P->n && near < 0; a++)
    if (!(P->su->nodes->flag[a] & (VES_NODE_AXIS | VES_NODE_WALL)) && P->X[2 * a] > 0 &&
        P->X[2 * a] < 0.06 && fabs(P->X[2 * a + 1]) < 1.0)
      near = a;
  assert_true(near >= 0);
  y[2 * near] = -0.25 * P->X[2 * near];
  double dmin, rmin = INFINITY;
  assert_int_equal(ves_reconnect_distortion(m, y, NULL, &dmin), VES_OK);
  for (int al = 0; al < P->su->quad->nq; al++) {
    double mo[12];
    ves_quad_motion(P->su->quad, y, al, 0, mo);
    rmin = fmin(rmin, mo[0]);
  }
  ves_status st = ves_reconnect_create(m, y, VES_RESET_NODES_COEF, &r);
  printf("# node %d at R = %.4f moved to r = %.4f: det F >= %.3f, r >= %.1e at the points, reset: "
         "%s\n",
         near, P->X[2 * near], y[2 * near], dmin, rmin, ves_status_str(st));
  assert_true(dmin > 0 && rmin > 0); /* an admissible motion */
  assert_int_equal(st, VES_OK);
  {
    ves_reconnect_info info;
    ves_reconnect_get_info(r, &info);
    assert_int_equal(info.mirrored, 1);
    const double *xn = ves_reconnect_nodes(r)->x;
    assert_true(xn[2 * near] == -y[2 * near] && xn[2 * near + 1] == y[2 * near + 1]);
    for (int a = 0; a < P->n; a++)
      if (a != near) assert_true(xn[2 * a] == y[2 * a] && xn[2 * a + 1] == y[2 * a + 1]);
    double v0[3], v1[3];
    eav(m, y, v0);
    eav(ves_reconnect_model(r), xn, v1);
    printf("# mirrored node: E, A, V relative change %.1e %.1e %.1e\n", v1[0] / v0[0] - 1,
           v1[1] / v0[1] - 1, v1[2] / v0[2] - 1);
    for (int k = 0; k < 3; k++) assert_true(fabs(v1[k] / v0[k] - 1) <= 1e-12); /* as a reset */
    ves_reconnect_destroy(&r);
  }
  /* a node on the axis itself (on its own ghost): refused */
  y[2 * near] = 0.0;
  assert_int_equal(ves_reconnect_create(m, y, VES_RESET_NODES_COEF, &r), VES_ERR_DOMAIN);
  assert_null(r);
  /* two nodes at the same place, the map still admissible at the points */
  memcpy(y, P->X, n2 * sizeof *y);
  int a0 = -1, b0 = -1;
  for (int a = 0; a < P->n && a0 < 0; a++)
    if (!(P->su->nodes->flag[a] & (VES_NODE_AXIS | VES_NODE_WALL)) && P->X[2 * a] > 1.3) a0 = a;
  assert_true(a0 >= 0);
  double best = INFINITY;
  for (int b = 0; b < P->n; b++) {
    const double dd = hypot(P->X[2 * b] - P->X[2 * a0], P->X[2 * b + 1] - P->X[2 * a0 + 1]);
    if (b != a0 && !(P->su->nodes->flag[b] & (VES_NODE_AXIS | VES_NODE_WALL)) && dd < best)
      best = dd, b0 = b;
  }
  y[2 * a0] = P->X[2 * b0], y[2 * a0 + 1] = P->X[2 * b0 + 1];
  assert_int_equal(ves_reconnect_distortion(m, y, NULL, &dmin), VES_OK);
  st = ves_reconnect_create(m, y, VES_RESET_NODES_COEF, &r);
  printf("# node %d moved onto node %d (%.4f away): det F >= %.3f, reset: %s\n", a0, b0, best, dmin,
         ves_status_str(st));
  assert_true(dmin > 0);
  assert_int_equal(st, VES_ERR_GEOM);
  ves_reconnect_destroy(&r); /* accepts NULL */
  ves_reconnect_destroy(NULL);
  free(y);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0);
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_drift_reset),
      cmocka_unit_test(test_motion_nodes),
      cmocka_unit_test(test_carry),
      cmocka_unit_test(test_distortion_affine),
      cmocka_unit_test(test_due),
      cmocka_unit_test(test_constructors),
      cmocka_unit_test(test_restore),
      cmocka_unit_test(test_errors),
  };
  // clang-format on
  return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
