/* vesica — what the tests of the reference reset share: a small vesicle with
 * a deformed state, a reset helper, one Newton step and the comparison of the
 * next step with and without a reset. Included by test_reconnect.c and
 * test_reconnect_nodes.c, each a cmocka program. */
#ifndef VES_RECONNECT_TEST_IMPL_H
#define VES_RECONNECT_TEST_IMPL_H

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

static inline double *xmalloc(size_t n) {
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

static inline int group_setup(void **state) {
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

static inline int group_teardown(void **state) {
  (void)state;
  if (!P) return 0;
  ves_setup_destroy(&P->su);
  free(P->X), free(P->yd);
  free(P);
  P = NULL;
  return 0;
}

static inline ves_reconnect *reset(const ves_model *m, const double *y) {
  ves_reconnect *r = NULL;
  ves_status st = ves_reconnect_create(m, y, VES_RESET_NODES_COEF, &r);
  if (st != VES_OK) fail_msg("reset: %s", ves_status_str(st));
  return r;
}

static inline void eav(ves_model *m, const double *y, double v[3]) {
  assert_int_equal(
      ves_model_eval(m, y, VES_F_E | VES_F_A | VES_F_V, v, v + 1, v + 2, NULL, NULL, NULL), VES_OK);
}

/* Full quadratic form v^T M v of block values blk (lower blocks, all dofs). */
static inline double blk_quad(const ves_pattern *pat, const double *blk, const double *v) {
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

/* One Newton VTI step (dt, area and volume held at A0, V0) from yn on model
 * m; ynew (2n), multipliers lam[2], statistics. */
static inline void newton_step(ves_model *m, const double *yn, double dt, double A0, double V0,
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

static inline step_diff compare_steps(ves_model *m0, ves_model *m1, const double *y,
                                      const double *ya, const double *yb) {
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

/* One step of dt = 1e-2 from y0 on m0 (no reset) and from y1 on m1 (after a
 * reset at y0; y1 = the new reference nodes), compared and asserted as the
 * comment above says; label prefixes the printed lines. */
static inline void check_next_step(ves_model *m0, const double *y0, ves_model *m1, const double *y1,
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

/* Relative 2-norm difference of the gradients of E, A, V of two models at y
 * over the free dofs: rel[3]. */
static inline void grad_diff(ves_model *m0, ves_model *m1, const double *y, double rel[3]) {
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

#endif
