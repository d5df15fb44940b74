/* vesica — tests of the reset of the reference configuration
 * (solver/time/reconnect.c, paper Sec. 3.3): the push-forward of grad phi0 and
 * Hess phi0 against finite differences of the composed field phi0 o y^-1
 * (analytic and discrete), invariance of E, A, V and of their variations
 * along motions both discrete spaces contain, a chain of two resets, the
 * next time step with and without a reset, the distortion measure on affine
 * motions, the reset policy, the new quadrature and model constructors, and
 * the error paths. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
/* cmocka needs the four headers above first */
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ves/backend.h"
#include "ves/reconnect.h"
#include "ves/setup.h"
#include "ves/step.h"
#include "app/problem.h"
#include "vesicle_impl.h"

/* ------------------------------------------------------------------------ */
/* The problem                                                               */
/* ------------------------------------------------------------------------ */

static double *xmalloc(size_t n) {
  double *p = malloc((n ? n : 1) * sizeof *p);
  assert_non_null(p);
  return p;
}

/* A small out-of-equilibrium vesicle: the unit sphere with a P2 bump of 0.15,
 * eps = 0.15, band 3 eps, in a 1.9 x 1.9 box, L2-projected phi0 (983 nodes,
 * 11310 points). yd: smooth_motion() (vesicle_impl.h) with amplitude AMP,
 * which gives min det F = 0.696 and max cond F = 1.875 (a visible shear). */
typedef struct {
  ves_config cfg;     /* its configuration */
  ves_setup *su;      /* shape, nodes, quadrature, phi0 coefficients, model */
  ves_lme_params lme; /* the LME parameters of the setup's tables */
  int n;              /* real nodes */
  double *X;          /* 2n reference positions */
  double *yd;         /* 2n the deformed state */
} problem;

static problem *P;
#define AMP 0.07

static int group_setup(void **state) {
  (void)state;
  P = calloc(1, sizeof *P);
  if (!P) return -1;
  char err[512] = "";
  /* the paper's E (no stabilization): the reset's identities are its own
   * (E_s is measured from the reference and drops to 0 at a reset; the time
   * loop's test_reconnect_stabilized checks that) */
  if (bump_config("shape.delta=0.15", "geometry.stabilization=0", &P->cfg, err, sizeof err) !=
      VES_OK) {
    fprintf(stderr, "config: %s\n", err);
    return -1;
  }
  if (ves_problem_setup_create(&P->cfg, VES_PHI0_L2, &P->su, err, sizeof err) != VES_OK) {
    fprintf(stderr, "setup: %s\n", err);
    return -1;
  }
  P->lme = P->su->quad->lme; /* the setup's (config gamma, support_tol) */
  P->n = P->su->nodes->n;
  P->X = malloc(2 * (size_t)P->n * sizeof *P->X);
  P->yd = malloc(2 * (size_t)P->n * sizeof *P->yd);
  if (!P->X || !P->yd) return -1;
  ves_model_reference(P->su->model, P->X);
  smooth_motion(P->su->nodes, P->X, AMP, P->yd);
  printf("# problem: %d nodes, %d points\n", P->n, P->su->quad->nq);
  return 0;
}

static int group_teardown(void **state) {
  (void)state;
  if (!P) return 0;
  ves_setup_destroy(&P->su);
  free(P->X), free(P->yd);
  free(P);
  P = NULL;
  return 0;
}

static ves_reconnect *reset(const ves_model *m, const double *y) {
  ves_reconnect *r = NULL;
  ves_status st = ves_reconnect_create(m, y, VES_RESET_NODES_COEF, &r);
  if (st != VES_OK) fail_msg("reset: %s", ves_status_str(st));
  return r;
}

static void eav(ves_model *m, const double *y, double v[3]) {
  assert_int_equal(
      ves_model_eval(m, y, VES_F_E | VES_F_A | VES_F_V, v, v + 1, v + 2, NULL, NULL, NULL), VES_OK);
}

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

/* Full quadratic form v^T M v of block values blk (lower blocks, all dofs). */
static double blk_quad(const ves_pattern *pat, const double *blk, const double *v) {
  long double s = 0;
  for (int a = 0; a < pat->n; a++)
    for (int t = pat->ptr[a]; t < pat->ptr[a + 1]; t++) {
      const int b = pat->col[t];
      const double *B = blk + 4 * (size_t)t;
      const double va[2] = {v[2 * a], v[2 * a + 1]}, vb[2] = {v[2 * b], v[2 * b + 1]};
      const double x =
          va[0] * (B[0] * vb[0] + B[1] * vb[1]) + va[1] * (B[2] * vb[0] + B[3] * vb[1]);
      s += b == a ? x : 2 * x;
    }
  return (double)s;
}

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

/* Relative 2-norm difference of the gradients of E, A, V of two models at y
 * over the free dofs: rel[3]. */
static void grad_diff(ves_model *m0, ves_model *m1, const double *y, double rel[3]) {
  const int n2 = 2 * P->n;
  const ves_pattern *pat = ves_model_pattern(m0);
  double *g0 = xmalloc(3 * (size_t)n2), *g1 = xmalloc(3 * (size_t)n2), v[3];
  assert_int_equal(ves_model_eval(m0, y, 7, v, v + 1, v + 2, g0, g0 + n2, g0 + 2 * n2), VES_OK);
  assert_int_equal(ves_model_eval(m1, y, 7, v, v + 1, v + 2, g1, g1 + n2, g1 + 2 * n2), VES_OK);
  for (int k = 0; k < 3; k++) {
    double num = 0, den = 0;
    for (int i = 0; i < n2; i++)
      if (pat->dof[i] >= 0) {
        const double a = g0[k * n2 + i], b = g1[k * n2 + i];
        num += (a - b) * (a - b), den += a * a;
      }
    rel[k] = sqrt(num / den);
  }
  free(g0), free(g1);
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

/* One Newton VTI step (dt, area and volume held at A0, V0) from yn on model
 * m; ynew (2n), multipliers lam[2], statistics. */
static void newton_step(ves_model *m, const double *yn, double dt, double A0, double V0,
                        double *ynew, double lam[2], ves_backend_stats *bs) {
  ves_step *s = NULL;
  void *bst = NULL;
  ves_backend_options o;
  ves_backend_options_default(&o);
  o.freeze_hessian = 1; /* one Hessian per step: the test's cost */
  assert_int_equal(ves_step_create(m, &s), VES_OK);
  ves_step_params sp = {.dt = dt, .hold_area = 1, .A0 = A0, .hold_volume = 1, .V_target = V0};
  assert_int_equal(ves_step_set(s, yn, &sp), VES_OK);
  assert_int_equal(ves_backend_newton.create(&o, s, &bst), VES_OK);
  double *x = xmalloc((size_t)ves_step_nvar(s));
  ves_step_x0(s, x);
  lam[0] = lam[1] = 0;
  assert_int_equal(ves_backend_newton.solve(bst, s, x, lam, bs), VES_OK);
  ves_step_expand(s, x, ynew);
  ves_backend_newton.destroy(&bst);
  ves_step_destroy(&s);
  free(x);
}

/* Differences between the step without reset (model m0, result ya) and with
 * it (m1, yb) from the same y: nodal values, and the motion of the material
 * points y(Xh) (old tables for ya, new tables at the moved points for yb),
 * in max norm and L2 (weights w) relative to the step's own motion. */
typedef struct {
  double node_max, node_step;    /* max |ya - yb|, max |ya - y| over the nodes */
  double pt_max, pt_step, pt_l2; /* same at the points; L2 ratio */
} step_diff;

static step_diff compare_steps(ves_model *m0, ves_model *m1, const double *y, const double *ya,
                               const double *yb) {
  step_diff sd = {0, 0, 0, 0, 0};
  for (int i = 0; i < 2 * P->n; i++) {
    sd.node_max = fmax(sd.node_max, fabs(ya[i] - yb[i]));
    sd.node_step = fmax(sd.node_step, fabs(ya[i] - y[i]));
  }
  const ves_quad *q0 = ves_model_quad(m0), *q1 = ves_model_quad(m1);
  long double d2 = 0, u2 = 0;
  for (int al = 0; al < q0->nq; al++) {
    double ma[12], mb[12], mn[12];
    ves_quad_motion(q0, ya, al, 0, ma);
    ves_quad_motion(q1, yb, al, 0, mb);
    ves_quad_motion(q0, y, al, 0, mn);
    const double e = hypot(ma[0] - mb[0], ma[6] - mb[6]), u = hypot(ma[0] - mn[0], ma[6] - mn[6]);
    sd.pt_max = fmax(sd.pt_max, e), sd.pt_step = fmax(sd.pt_step, u);
    d2 += q0->w[al] * e * e, u2 += q0->w[al] * u * u;
  }
  sd.pt_l2 = (double)sqrtl(d2 / u2);
  return sd;
}

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
/* One step of dt = 1e-2 from y0 on m0 (no reset) and from y1 on m1 (after a
 * reset at y0; y1 = the new reference nodes), compared and asserted as the
 * comment above says; label prefixes the printed lines. */
static void check_next_step(ves_model *m0, const double *y0, ves_model *m1, const double *y1,
                            const char *label) {
  const int n2 = 2 * P->n;
  double *ya = xmalloc(n2), *yb = xmalloc(n2), v[3], va[3], vb[3], la[2], lb[2];
  eav(m0, y0, v);
  ves_backend_stats sa, sb;
  newton_step(m0, y0, 1e-2, v[1], v[2], ya, la, &sa);
  newton_step(m1, y1, 1e-2, v[1], v[2], yb, lb, &sb);
  eav(m0, ya, va);
  eav(m1, yb, vb);
  const step_diff sd = compare_steps(m0, m1, y0, ya, yb);
  const double dE = fabs(vb[0] - va[0]) / (v[0] - va[0]);
  printf("# %s, dt = 1e-2: %d / %d Newton iterations; E* %.10f -> %.10f / %.10f (difference "
         "%.1e of the decrement); A/A0 - 1 %.1e / %.1e, V/V0 - 1 %.1e / %.1e\n",
         label, sa.iterations, sb.iterations, v[0], va[0], vb[0], dE, va[1] / v[1] - 1,
         vb[1] / v[1] - 1, va[2] / v[2] - 1, vb[2] / v[2] - 1);
  printf("# %s: nodal values: max |ya - yb| = %.1e of a step %.1e; material points: max %.1e of "
         "a motion %.1e, L2 %.1e; lambda (%.6e, %.6e) / (%.6e, %.6e)\n",
         label, sd.node_max, sd.node_step, sd.pt_max, sd.pt_step, sd.pt_l2, la[0], la[1], lb[0],
         lb[1]);
  assert_true(va[0] < v[0] && vb[0] < v[0]); /* both decrease the energy */
  assert_true(dE <= 1e-3);
  for (int k = 1; k < 3; k++)
    assert_true(fabs(va[k] / v[k] - 1) <= 1e-10 && fabs(vb[k] / v[k] - 1) <= 1e-10);
  assert_true(sd.pt_l2 <= 1e-2);
  assert_true(sd.pt_max <= 2e-2 * sd.pt_step);
  free(ya), free(yb);
}

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
      cmocka_unit_test(test_push_forward_analytic),
      cmocka_unit_test(test_composed_field_fd),
      cmocka_unit_test(test_invariance),
      cmocka_unit_test(test_drift_reset),
      cmocka_unit_test(test_near_identity),
      cmocka_unit_test(test_chain),
      cmocka_unit_test(test_next_step_similarity),
      cmocka_unit_test(test_next_step_deformed),
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
