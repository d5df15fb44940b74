/* vesica — tests of the reset of the reference configuration
 * (solver/time/reconnect.c, paper Sec. 3.3): the push-forward of grad phi0 and
 * Hess phi0 against finite differences of the composed field phi0 o y^-1
 * (analytic and discrete), invariance of E, A, V and of their variations
 * along motions both discrete spaces contain, a chain of two resets, and the
 * next time step with and without a reset. */
#include "reconnect_test_impl.h"

/* ------------------------------------------------------------------------ */
/* Push-forward: analytic                                                    */
/* ------------------------------------------------------------------------ */

/* An analytic phi0 and motion y (not affine, with shear), with derivatives. */
static void phi0_an(const double X[2], double pd[6]) {
  const double R = X[0], Z = X[1], u = 1.3 * R + 0.4 * Z, s = sin(u), c = cos(u);
  pd[0] = s + R * R * Z;
  pd[1] = 1.3 * c + 2 * R * Z, pd[2] = 0.4 * c + R * R;
  pd[3] = -1.69 * s + 2 * Z, pd[4] = -0.52 * s + 2 * R, pd[5] = -0.16 * s;
}

/* y = (R + 0.3 R sin Z + 0.1 Z^2, Z + 0.2 R^2 + 0.1 sin(R Z)): y[2], F[4], G[6]. */
static void map_an(const double X[2], double y[2], double F[4], double G[6]) {
  const double R = X[0], Z = X[1], sZ = sin(Z), cZ = cos(Z), s = sin(R * Z), c = cos(R * Z);
  y[0] = R + 0.3 * R * sZ + 0.1 * Z * Z;
  y[1] = Z + 0.2 * R * R + 0.1 * s;
  if (!F) return;
  F[0] = 1 + 0.3 * sZ, F[1] = 0.3 * R * cZ + 0.2 * Z;
  F[2] = 0.4 * R + 0.1 * Z * c, F[3] = 1 + 0.1 * R * c;
  G[0] = 0, G[1] = 0.3 * cZ, G[2] = -0.3 * R * sZ + 0.2;
  G[3] = 0.4 - 0.1 * Z * Z * s, G[4] = 0.1 * (c - R * Z * s), G[5] = -0.1 * R * R * s;
}

/* phi(x) = phi0(y^-1(x)): Newton on y(X) = x from X0, to rounding. */
static double phi_composed_an(const double x[2], const double X0[2]) {
  double X[2] = {X0[0], X0[1]}, y[2], F[4], G[6], pd[6];
  for (int it = 0; it < 30; it++) {
    map_an(X, y, F, G);
    const double r0 = x[0] - y[0], r1 = x[1] - y[1], J = F[0] * F[3] - F[1] * F[2];
    X[0] += (F[3] * r0 - F[1] * r1) / J, X[1] += (-F[2] * r0 + F[0] * r1) / J;
    if (hypot(r0, r1) < 1e-16) break;
  }
  phi0_an(X, pd);
  return pd[0];
}

/* Central differences of phi at x with step d: value, gradient, Hessian
 * (phi_rr, phi_rz, phi_zz) from the 3 x 3 stencil; truncation O(d^2). */
static void fd_derivs(double (*phi)(const double *, const void *), const void *ctx,
                      const double x[2], double d, double out[6]) {
  double v[3][3];
  for (int i = -1; i <= 1; i++)
    for (int j = -1; j <= 1; j++) {
      const double xi[2] = {x[0] + i * d, x[1] + j * d};
      v[i + 1][j + 1] = phi(xi, ctx);
    }
  out[0] = v[1][1];
  out[1] = (v[2][1] - v[0][1]) / (2 * d), out[2] = (v[1][2] - v[1][0]) / (2 * d);
  out[3] = (v[2][1] - 2 * v[1][1] + v[0][1]) / (d * d);
  out[4] = (v[2][2] - v[2][0] - v[0][2] + v[0][0]) / (4 * d * d);
  out[5] = (v[1][2] - 2 * v[1][1] + v[1][0]) / (d * d);
}

static double phi_an_cb(const double *x, const void *ctx) {
  return phi_composed_an(x, (const double *)ctx);
}

/* Largest |a_k - b_k| over the gradient (k = 1, 2) and the Hessian (3..5),
 * each relative to the largest entry of b in that group. */
static void rel_errs(const double a[6], const double b[6], double *eg, double *eh) {
  const double sg = fmax(fabs(b[1]), fabs(b[2])),
               sh = fmax(fabs(b[3]), fmax(fabs(b[4]), fabs(b[5])));
  *eg = fmax(fabs(a[1] - b[1]), fabs(a[2] - b[2])) / sg;
  *eh = fmax(fabs(a[3] - b[3]), fmax(fabs(a[4] - b[4]), fabs(a[5] - b[5]))) / sh;
}

/* ves_reconnect_push_forward against central differences (step 1e-4) of the
 * analytic phi0 o y^-1 at 5 points where F is far from I (|F - I| ~ 0.3-0.5)
 * and the G term is large: FD truncation ~1e-8 relative, rounding ~1e-9, so
 * 1e-6 is far below what a wrong term gives (the G term alone is 10-60% of
 * the Hessian, printed). Also: F = I, G = 0 gives the data back unchanged, and
 * a folded F is VES_ERR_DOMAIN. */
static void test_push_forward_analytic(void **state) {
  (void)state;
  const double pts[5][2] = {{0.5, 0.3}, {1.2, -0.7}, {0.9, 1.1}, {1.6, 0.4}, {0.3, -1.3}};
  double worst_g = 0, worst_h = 0;
  for (int k = 0; k < 5; k++) {
    double y[2], F[4], G[6], pd[6], pf[6], fd[6], G0[6] = {0}, p0[6];
    map_an(pts[k], y, F, G);
    phi0_an(pts[k], pd);
    assert_int_equal(ves_reconnect_push_forward(F, G, pd, pf), VES_OK);
    assert_int_equal(ves_reconnect_push_forward(F, G0, pd, p0), VES_OK);
    fd_derivs(phi_an_cb, pts[k], y, 1e-4, fd);
    double eg, eh, gterm, dummy;
    rel_errs(pf, fd, &eg, &eh);
    rel_errs(p0, pf, &dummy, &gterm);
    printf("# analytic point (%.1f, %.1f): det F = %.3f; grad rel err %.1e, Hess rel err %.1e "
           "(G term %.0f%% of the Hessian)\n",
           pts[k][0], pts[k][1], F[0] * F[3] - F[1] * F[2], eg, eh, 100 * gterm);
    assert_true(pf[0] == pd[0]); /* phi0 is a material property */
    assert_true(gterm > 0.05);   /* the test sees the G term */
    worst_g = fmax(worst_g, eg), worst_h = fmax(worst_h, eh);
  }
  assert_true(worst_g <= 1e-6);
  assert_true(worst_h <= 1e-6);
  /* identity: unchanged to rounding (F^-1 = I exactly, one product each) */
  const double I[4] = {1, 0, 0, 1}, Z6[6] = {0}, pd[6] = {0.3, -1.2, 2.5, 4.0, -0.7, 1.9};
  double out[6];
  assert_int_equal(ves_reconnect_push_forward(I, Z6, pd, out), VES_OK);
  for (int j = 0; j < 6; j++) assert_true(out[j] == pd[j]);
  const double Ff[4] = {1, 0.5, 2, 1}; /* det = 0 */
  out[0] = 42;
  assert_int_equal(ves_reconnect_push_forward(Ff, Z6, pd, out), VES_ERR_DOMAIN);
  assert_true(out[0] == 42);
}

/* ------------------------------------------------------------------------ */
/* The discrete composed field                                               */
/* ------------------------------------------------------------------------ */

/* Independent evaluation of the old discrete fields at any point X: the LME
 * basis on the setup's nodes (real + ghost) through ves_geom_search and
 * ves_lme_eval, not through the tables of ves_quad. */
typedef struct {
  const ves_nodes *nodes;
  const double *y;     /* 2n nodal positions of the motion */
  const double *phi0c; /* n coefficients of phi0 */
  ves_geom_search *search;
  double *xe, *beta; /* extended nodes and their beta */
  int ne;
  const double *X0; /* material point near which to invert y */
  /* the neighbour set in use (lme_ctx_fix): the truncated basis is smooth
   * only on a fixed set (a node entering the support at beta|d|^2 = -ln tol0
   * makes a jump ~1e-7 that differences of step 1e-3 would amplify by 1e6) */
  int m, idx[512];
  double xa[1024], beta_m[512];
} lme_ctx;

static void lme_ctx_init(lme_ctx *c, const ves_nodes *nodes, const double *y, const double *phi0c) {
  c->nodes = nodes, c->y = y, c->phi0c = phi0c;
  c->ne = nodes->n + nodes->ng;
  c->xe = xmalloc(2 * (size_t)c->ne);
  c->beta = xmalloc((size_t)c->ne);
  double *rad = xmalloc((size_t)c->ne);
  ves_nodes_extended(nodes, c->xe);
  for (int a = 0; a < c->ne; a++) {
    const double h = nodes->h[a < nodes->n ? a : nodes->ghost_of[a - nodes->n]];
    rad[a] = ves_lme_radius(&P->lme, h);
    c->beta[a] = P->lme.gamma / (h * h);
  }
  assert_int_equal(ves_geom_search_create(c->ne, c->xe, rad, &c->search), VES_OK);
  free(rad);
}

static void lme_ctx_free(lme_ctx *c) {
  ves_geom_search_destroy(&c->search);
  free(c->xe), free(c->beta);
}

/* Fix the neighbour set to that of X (as the tables do at a point). */
static void lme_ctx_fix(lme_ctx *c, const double X[2]) {
  assert_int_equal(ves_geom_search_query(c->search, X, 512, c->idx, &c->m), VES_OK);
  assert_true(c->m <= 512);
  for (int k = 0; k < c->m; k++) {
    c->xa[2 * k] = c->xe[2 * c->idx[k]], c->xa[2 * k + 1] = c->xe[2 * c->idx[k] + 1];
    c->beta_m[k] = c->beta[c->idx[k]];
  }
}

/* At X, on the fixed neighbour set: y(X) (2), F (4) and phi0_h(X). */
static void lme_fields(const lme_ctx *c, const double X[2], double y[2], double F[4], double *phi) {
  const int m = c->m, *idx = c->idx;
  double tab[6 * 512], work[4 * 512], lam[2] = {0, 0};
  assert_int_equal(ves_lme_eval(&P->lme, X, m, c->xa, c->beta_m, lam, 1, tab, work, NULL), VES_OK);
  const int n = c->nodes->n;
  memset(y, 0, 2 * sizeof *y), memset(F, 0, 4 * sizeof *F), *phi = 0;
  for (int k = 0; k < m; k++) {
    const int ghost = idx[k] >= n, a = ghost ? c->nodes->ghost_of[idx[k] - n] : idx[k];
    const double yr = ghost ? -c->y[2 * a] : c->y[2 * a], yz = c->y[2 * a + 1];
    y[0] += tab[k] * yr, y[1] += tab[k] * yz;
    F[0] += tab[m + k] * yr, F[1] += tab[2 * m + k] * yr;
    F[2] += tab[m + k] * yz, F[3] += tab[2 * m + k] * yz;
    *phi += tab[k] * c->phi0c[a];
  }
}

/* phi_h(x) = phi0_h(y_h^-1(x)), Newton from c->X0 to |y(X) - x| <= 1e-15. */
static double phi_composed_h(const double *x, const void *ctx) {
  const lme_ctx *c = ctx;
  double X[2] = {c->X0[0], c->X0[1]}, y[2], F[4], phi = 0;
  for (int it = 0; it < 20; it++) {
    lme_fields(c, X, y, F, &phi);
    const double r0 = x[0] - y[0], r1 = x[1] - y[1], J = F[0] * F[3] - F[1] * F[2];
    if (hypot(r0, r1) <= 1e-15) return phi;
    X[0] += (F[3] * r0 - F[1] * r1) / J, X[1] += (-F[2] * r0 + F[0] * r1) / J;
  }
  fail_msg("inversion of y_h did not converge at (%g, %g)", x[0], x[1]);
  return phi;
}

/* The point data of the reset model at its points Xh' = y_h(Xh) against
 * central differences of the composed discrete field phi0_h o y_h^-1 (the
 * old basis on the neighbour set of Xh, evaluated independently of the
 * tables; y_h inverted by Newton) at 24 points: 16 in the interface band
 * (|phi0| < 0.9) and 8 near the axis (R < 0.15). Steps 2e-3 and 1e-3 with
 * Richardson extrapolation: the plain step-1e-3 error is the O(d^2)
 * truncation (measured 2e-5 for both gradient and Hessian, relative to the
 * largest entry at the point), the extrapolated one is what remains (measured
 * below: 4e-10 and 3e-9). Bounds 1e-8 and 1e-7: far below the G term, at least 1.7e-2 of the
 * Hessian at every point tested (printed), which a wrong second-derivative
 * term would miss. Also: phi0 at the points is unchanged, the new points are
 * y_h(Xh) and the new weights w det F. */
static void test_composed_field_fd(void **state) {
  (void)state;
  ves_reconnect *r = reset(P->su->model, P->yd);
  const ves_quad *q0 = P->su->quad, *q1 = ves_reconnect_quad(r);
  const int nq = q0->nq;
  double *pd0 = xmalloc(6 * (size_t)nq), *pd1 = xmalloc(6 * (size_t)nq);
  ves_model_point_data(P->su->model, pd0);
  ves_model_point_data(ves_reconnect_model(r), pd1);
  lme_ctx c;
  lme_ctx_init(&c, P->su->nodes, P->yd, P->su->phi0c);
  int nband = 0, naxis = 0;
  double worst_g = 0, worst_h = 0, worst_g1 = 0, worst_h1 = 0, gterm_min = INFINITY, pos_err = 0,
         w_err = 0;
  for (int al = 0; al < nq && (nband < 16 || naxis < 8); al++) {
    const double *Xh = q0->x + 2 * al;
    if (fabs(pd0[6 * al]) < 0.9 && al % 37 == 0 && nband < 16)
      nband++; /* every 37th band point */
    else if (Xh[0] < 0.15 && al % 11 == 0 && naxis < 8)
      naxis++; /* every 11th point near the axis */
    else
      continue;
    double y[2], F[4], phi, fd[6], mo[12];
    lme_ctx_fix(&c, Xh);
    lme_fields(&c, Xh, y, F, &phi);
    /* the new point is y_h(Xh), its weight w det F, phi0 kept */
    pos_err = fmax(pos_err, hypot(q1->x[2 * al] - y[0], q1->x[2 * al + 1] - y[1]));
    w_err = fmax(w_err, fabs(q1->w[al] / (q0->w[al] * (F[0] * F[3] - F[1] * F[2])) - 1));
    assert_true(pd1[6 * al] == pd0[6 * al]);
    c.X0 = Xh;
    double fd2[6], eg, eh, eg1, eh1, gterm, dummy, p0[6];
    fd_derivs(phi_composed_h, &c, q1->x + 2 * al, 2e-3, fd);
    fd_derivs(phi_composed_h, &c, q1->x + 2 * al, 1e-3, fd2);
    rel_errs(pd1 + 6 * al, fd2, &eg1, &eh1);
    worst_g1 = fmax(worst_g1, eg1), worst_h1 = fmax(worst_h1, eh1);
    for (int j = 0; j < 6; j++) fd[j] = (4 * fd2[j] - fd[j]) / 3; /* Richardson: O(d^4) */
    rel_errs(pd1 + 6 * al, fd, &eg, &eh);
    /* the same push-forward without the G term */
    ves_quad_motion(q0, P->yd, al, 2, mo);
    const double Fq[4] = {mo[1], mo[2], mo[7], mo[8]}, G0[6] = {0};
    assert_int_equal(ves_reconnect_push_forward(Fq, G0, pd0 + 6 * al, p0), VES_OK);
    rel_errs(p0, pd1 + 6 * al, &dummy, &gterm);
    worst_g = fmax(worst_g, eg), worst_h = fmax(worst_h, eh);
    gterm_min = fmin(gterm_min, gterm);
  }
  printf("# discrete composed field at %d band + %d axis points: grad rel err %.1e, Hess rel err "
         "%.1e (step 1e-3: %.1e, %.1e); G term >= %.1e of the Hessian; |Xh' - y_h(Xh)| <= %.1e, "
         "|w'/(w det F) - 1| <= %.1e\n",
         nband, naxis, worst_g, worst_h, worst_g1, worst_h1, gterm_min, pos_err, w_err);
  assert_int_equal(nband, 16);
  assert_int_equal(naxis, 8);
  assert_true(worst_g <= 1e-8);
  assert_true(worst_h <= 1e-7);
  /* positions and weights: the tables and the independent LME evaluation
   * differ by rounding (sums in another order, Newton warm starts) */
  assert_true(pos_err <= 1e-13);
  assert_true(w_err <= 1e-12);
  lme_ctx_free(&c);
  free(pd0), free(pd1);
  ves_reconnect_destroy(&r);
  assert_null(r);
}

/* ------------------------------------------------------------------------ */
/* Invariance                                                                */
/* ------------------------------------------------------------------------ */

/* E, A, V at the reset state; their gradients, Hessians and K along a motion
 * that is affine in the current configuration, dy^a = (al r_a, be z_a + ga)
 * (r odd, z even: both spaces contain it, the old one as A y(X) + b, the new
 * one as A X' + b, so E, A, V agree along the whole line y + t dy, and so do
 * all their derivatives and the dissipation of that velocity field).
 * Measured at the state of smooth_motion(AMP): the values agree to 4e-16, and the
 * directional derivatives to 1e-14. The reset's residual is the affine
 * reproduction of the new basis (F' - I ~ 1e-14 at the points, measured
 * below) and rounding of sums over ~1e4 points: 1e-12 for values,
 * 1e-10 for the directional derivatives (they cancel between nodes). */
static void test_invariance(void **state) {
  (void)state;
  ves_model *m0 = P->su->model;
  double c0, d0, c1, d1, v0[3], v1[3];
  assert_int_equal(ves_reconnect_distortion(m0, P->yd, &c0, &d0), VES_OK);
  ves_reconnect *r = reset(m0, P->yd);
  ves_model *m1 = ves_reconnect_model(r);
  ves_reconnect_info info;
  ves_reconnect_get_info(r, &info);
  assert_int_equal(ves_reconnect_distortion(m1, P->yd, &c1, &d1), VES_OK);
  eav(m0, P->yd, v0);
  eav(m1, P->yd, v1);
  printf("# reset at cond F = %.3f, det F >= %.3f (%.2f s, tables %.2f s, m = %.1f, h' in "
         "[%.4f, %.4f]); after: cond - 1 = %.1e, det - 1 = %.1e\n",
         c0, d0, info.seconds, info.qinfo.seconds, info.qinfo.m_mean, info.h_min, info.h_max,
         c1 - 1, d1 - 1);
  printf("# E* %.12f A %.12f V %.12f; relative change %.1e %.1e %.1e\n", v0[0], v0[1], v0[2],
         v1[0] / v0[0] - 1, v1[1] / v0[1] - 1, v1[2] / v0[2] - 1);
  assert_true(info.cond_max == c0 && info.det_min == d0);
  assert_true(d0 < 0.8 && c0 > 1.5);                           /* strongly deformed, with shear */
  assert_true(fabs(c1 - 1) <= 1e-12 && fabs(d1 - 1) <= 1e-12); /* y' = identity */
  for (int k = 0; k < 3; k++) assert_true(fabs(v1[k] / v0[k] - 1) <= 1e-12);
  double *yr = xmalloc(2 * (size_t)P->n); /* the new reference is y */
  ves_model_reference(m1, yr);
  assert_memory_equal(yr, P->yd, 2 * (size_t)P->n * sizeof *yr);
  free(yr);

  /* variations along dy = (0.3 r, -0.2 z + 0.1) */
  const int n2 = 2 * P->n;
  const ves_pattern *p0 = ves_model_pattern(m0), *p1 = ves_model_pattern(m1);
  const size_t l0 = 4 * (size_t)p0->ptr[P->n], l1 = 4 * (size_t)p1->ptr[P->n];
  double *dy = xmalloc(n2), *g0 = xmalloc(3 * (size_t)n2), *g1 = xmalloc(3 * (size_t)n2);
  double *b0 = xmalloc(l0), *b1 = xmalloc(l1), *yt = xmalloc(n2);
  for (int a = 0; a < P->n; a++)
    dy[2 * a] = 0.3 * P->yd[2 * a], dy[2 * a + 1] = -0.2 * P->yd[2 * a + 1] + 0.1;
  assert_int_equal(ves_model_eval(m0, P->yd, 7, v0, v0 + 1, v0 + 2, g0, g0 + n2, g0 + 2 * n2),
                   VES_OK);
  assert_int_equal(ves_model_eval(m1, P->yd, 7, v1, v1 + 1, v1 + 2, g1, g1 + n2, g1 + 2 * n2),
                   VES_OK);
  const char *name[3] = {"E", "A", "V"};
  double worst = 0;
  for (int k = 0; k < 3; k++) {
    long double s0 = 0, s1 = 0;
    for (int i = 0; i < n2; i++) s0 += g0[k * n2 + i] * dy[i], s1 += g1[k * n2 + i] * dy[i];
    const double cw[3] = {k == 0, k == 1, k == 2};
    assert_int_equal(ves_model_hessian(m0, P->yd, cw[0], cw[1], cw[2], b0), VES_OK);
    assert_int_equal(ves_model_hessian(m1, P->yd, cw[0], cw[1], cw[2], b1), VES_OK);
    const double h0 = blk_quad(p0, b0, dy), h1 = blk_quad(p1, b1, dy);
    const double e1 = fabs((double)(s1 - s0)) / fabs((double)s0), e2 = fabs(h1 - h0) / fabs(h0);
    printf("# %s along dy: first variation %.6e (rel change %.1e), second %.6e (%.1e)\n", name[k],
           (double)s0, e1, h0, e2);
    worst = fmax(worst, fmax(e1, e2));
  }
  assert_int_equal(ves_model_dissipation(m0, P->yd, b0), VES_OK);
  assert_int_equal(ves_model_dissipation(m1, P->yd, b1), VES_OK);
  const double k0 = blk_quad(p0, b0, dy), k1 = blk_quad(p1, b1, dy);
  printf("# dy^T K dy = %.6e, rel change %.1e\n", k0, fabs(k1 - k0) / k0);
  worst = fmax(worst, fabs(k1 - k0) / k0);
  /* finite motion along the line: y + 0.1 dy */
  for (int i = 0; i < n2; i++) yt[i] = P->yd[i] + 0.1 * dy[i];
  eav(m0, yt, v0);
  eav(m1, yt, v1);
  printf("# at y + 0.1 dy: E, A, V rel change %.1e %.1e %.1e\n", v1[0] / v0[0] - 1,
         v1[1] / v0[1] - 1, v1[2] / v0[2] - 1);
  for (int k = 0; k < 3; k++) assert_true(fabs(v1[k] / v0[k] - 1) <= 1e-12);
  assert_true(worst <= 1e-10);
  free(dy), free(g0), free(g1), free(b0), free(b1), free(yt);
  ves_reconnect_destroy(&r);
}

/* A reset near the identity (smooth_motion() with amplitude 2e-4: cond F = 1.002).
 * E, A, V are preserved as at yd (1e-12, as above). The new spacings are not
 * the old ones moved: where the nodes sit on nearly co-circular quadruples
 * (the interface-aligned band layers) Delaunay edges flip under the tiny
 * motion, and h'_a jumps (measured 7e-3), so the basis and the gradients
 * change at O(1e-3) (measured 2.0e-3 for E) however small the motion: the
 * reset is not continuous in y at the level of the discretization. Asserted
 * (5x margins): the jump exists and stays below 3.5e-2 in h, 1e-2 in grad E.
 * With y = X exactly the reset reproduces the old model (same triangulation),
 * as the similarity test shows for y = 2X. */
static void test_near_identity(void **state) {
  (void)state;
  double *y = xmalloc(2 * (size_t)P->n), v0[3], v1[3], c, d, rel[3];
  smooth_motion(P->su->nodes, P->X, 2e-4, y);
  assert_int_equal(ves_reconnect_distortion(P->su->model, y, &c, &d), VES_OK);
  ves_reconnect *r = reset(P->su->model, y);
  const ves_nodes *nn = ves_reconnect_nodes(r);
  double hj = 0;
  for (int a = 0; a < P->n; a++) hj = fmax(hj, fabs(nn->h[a] / P->su->nodes->h[a] - 1));
  eav(P->su->model, y, v0);
  eav(ves_reconnect_model(r), y, v1);
  grad_diff(P->su->model, ves_reconnect_model(r), y, rel);
  printf("# near identity (cond %.4f, det %.4f): max |h'/h - 1| = %.1e; E, A, V rel change %.1e "
         "%.1e %.1e; gradients of E, A, V differ by %.1e %.1e %.1e\n",
         c, d, hj, v1[0] / v0[0] - 1, v1[1] / v0[1] - 1, v1[2] / v0[2] - 1, rel[0], rel[1], rel[2]);
  for (int k = 0; k < 3; k++) assert_true(fabs(v1[k] / v0[k] - 1) <= 1e-12);
  assert_true(hj > 1e-4 && hj <= 3.5e-2);
  assert_true(rel[0] <= 1e-2);
  ves_reconnect_destroy(&r);
  free(y);
}

/* Two resets in a row: reset at yd, deform further from there (the same
 * smooth motion applied to the new reference positions), reset again; the
 * first reference object is destroyed before the second model is used (it
 * must own or copy all it needs). E, A, V preserved at each reset as above. */
static void test_chain(void **state) {
  (void)state;
  ves_reconnect *r1 = reset(P->su->model, P->yd);
  double *y2 = xmalloc(2 * (size_t)P->n), v1[3], v2[3], c, d;
  smooth_motion(ves_reconnect_nodes(r1), P->yd, 0.5 * AMP, y2);
  assert_int_equal(ves_reconnect_distortion(ves_reconnect_model(r1), y2, &c, &d), VES_OK);
  eav(ves_reconnect_model(r1), y2, v1);
  ves_reconnect *r2 = reset(ves_reconnect_model(r1), y2);
  ves_reconnect_destroy(&r1);
  double c2, d2;
  assert_int_equal(ves_reconnect_distortion(ves_reconnect_model(r2), y2, &c2, &d2), VES_OK);
  eav(ves_reconnect_model(r2), y2, v2);
  /* the cumulative motion from the setup's reference, for the record */
  double ct, dt_;
  assert_int_equal(ves_reconnect_distortion(P->su->model, y2, &ct, &dt_), VES_OK);
  printf("# second reset at cond %.3f, det %.3f relative to the first (%.3f, %.3f from the "
         "start): E, A, V rel change %.1e %.1e %.1e\n",
         c, d, ct, dt_, v2[0] / v1[0] - 1, v2[1] / v1[1] - 1, v2[2] / v1[2] - 1);
  assert_true(c > 1.2); /* a real second deformation */
  for (int k = 0; k < 3; k++) assert_true(fabs(v2[k] / v1[k] - 1) <= 1e-12); /* as above */
  assert_true(fabs(c2 - 1) <= 1e-12 && fabs(d2 - 1) <= 1e-12);
  ves_reconnect_destroy(&r2);
  free(y2);
}

/* ------------------------------------------------------------------------ */
/* The next step                                                             */
/* ------------------------------------------------------------------------ */

/* At a similarity y = 2X (F = 2I, G = 0) the new basis is the old one
 * rescaled, p'_a(2X) = p_a(X) (h'_a = 2 h_a to rounding: the same Delaunay
 * triangulation of exactly scaled points), so both discrete spaces are the
 * same and the step after the reset is the step without it: measured 1.2e-13
 * in the nodal values (5e-11 of the step). Asserted: 1e-8 of the step (the
 * Newton tolerance is 1e-9 relative) and E, A, V after the step to 1e-12. */
static void test_next_step_similarity(void **state) {
  (void)state;
  const int n2 = 2 * P->n;
  double *y = xmalloc(n2), *ya = xmalloc(n2), *yb = xmalloc(n2), v[3], va[3], vb[3], la[2], lb[2];
  for (int i = 0; i < n2; i++) y[i] = 2 * P->X[i];
  ves_model *m0 = P->su->model;
  ves_reconnect *r = reset(m0, y);
  ves_model *m1 = ves_reconnect_model(r);
  const ves_nodes *nn = ves_reconnect_nodes(r);
  double herr = 0;
  for (int a = 0; a < P->n; a++) herr = fmax(herr, fabs(nn->h[a] / (2 * P->su->nodes->h[a]) - 1));
  assert_true(herr <= 1e-14); /* the same triangulation; sums in another order */
  eav(m0, y, v);
  ves_backend_stats sa, sb;
  newton_step(m0, y, 1e-2, v[1], v[2], ya, la, &sa);
  newton_step(m1, y, 1e-2, v[1], v[2], yb, lb, &sb);
  eav(m0, ya, va);
  eav(m1, yb, vb);
  const step_diff sd = compare_steps(m0, m1, y, ya, yb);
  printf("# similarity y = 2X, dt = 1e-2: h'/2h - 1 <= %.1e; %d / %d Newton iterations; E* %.10f "
         "-> %.10f / %.10f; nodes: max |ya - yb| = %.1e of a step %.1e; lambda (%.6e, %.6e) / "
         "(%.6e, %.6e)\n",
         herr, sa.iterations, sb.iterations, v[0], va[0], vb[0], sd.node_max, sd.node_step, la[0],
         la[1], lb[0], lb[1]);
  assert_true(sd.node_step > 1e-3); /* a visible step */
  assert_true(sd.node_max <= 1e-8 * sd.node_step);
  for (int k = 0; k < 3; k++) assert_true(fabs(vb[k] / va[k] - 1) <= 1e-12);
  ves_reconnect_destroy(&r);
  free(y), free(ya), free(yb);
}

/* At the strongly deformed state yd the new basis p'_a differs from p_a o y^-1
 * (and h'_a from the pushed-forward spacing: the Delaunay edges of the moved
 * nodes flip), so the step after the reset is a step in a different
 * discrete space, and the nodal values — coefficients of a smoothing basis,
 * not positions of material points — differ (measured 3.8e-4 of a 2.8e-3
 * step). What must agree is the motion of the material (measured at the
 * quadrature points: 3.4e-4 in L2 of the step's own motion, max 1.6e-3) and
 * the energy after the step (3.4e-5 of the decrement); A and V are held
 * (1e-10, the constraint tolerance). The gradients of E, A, V at the reset
 * state differ by 13%, 4%, 2% (printed): the forces on the nodes are those of
 * another basis. Asserted with 10-30x margins: L2 1e-2, pointwise 2e-2,
 * energy 1e-3 of the decrement; an error in the weights, the points or the
 * push-forward shows at O(1) (E, A, V invariance above). */

static void test_next_step_deformed(void **state) {
  (void)state;
  ves_model *m0 = P->su->model;
  ves_reconnect *r = reset(m0, P->yd);
  ves_model *m1 = ves_reconnect_model(r);
  double rel[3];
  grad_diff(m0, m1, P->yd, rel);
  printf("# deformed: gradients of E, A, V at the reset state differ by %.1e %.1e %.1e\n", rel[0],
         rel[1], rel[2]);
  check_next_step(m0, P->yd, m1, P->yd, "deformed");
  ves_reconnect_destroy(&r);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0);
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_push_forward_analytic),
      cmocka_unit_test(test_composed_field_fd),
      cmocka_unit_test(test_invariance),
      cmocka_unit_test(test_near_identity),
      cmocka_unit_test(test_chain),
      cmocka_unit_test(test_next_step_similarity),
      cmocka_unit_test(test_next_step_deformed),
  };
  // clang-format on
  return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
