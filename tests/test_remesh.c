/* vesica — tests of the full remeshing (solver/time/remesh.c): the interface
 * extracted from a state against the exact curve, a remesh of the unmoved
 * initial state against the initial setup, a remesh of a deformed state
 * (E, A, V against the old model's, constraints restored to rounding), the
 * rebuild of a remeshed reference from what a file stores (bit for bit),
 * the next time step on a remeshed reference, and the error paths. */
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
#include "ves/integrate.h"
#include "ves/remesh.h"
#include "ves/setup.h"
#include "ves/step.h"
#include "app/problem.h"
#include "vesicle_impl.h"

/* The problem: the unit sphere with a P2 bump of 0.15 (an oblate-prolate
 * perturbation, out of equilibrium), eps = 0.15, band 3 eps, in a 1.9 x 1.9
 * box (the problem of test_reconnect.c: ~1,000 nodes, ~11,000 points). */
typedef struct {
  ves_config cfg;
  ves_discret_params dp; /* its discretization */
  ves_setup *su;
  int n;
  double *X;          /* 2n reference positions */
  double *yd;         /* 2n a deformed state */
  double eav_seed[3]; /* E*, A, V of the same problem on the node set of another seed */
} problem;

static problem *P;
#define AMP 0.07

static int group_setup(void **state) {
  (void)state;
  P = calloc(1, sizeof *P);
  if (!P) return -1;
  char err[512] = "";
  /* the paper's E: E_s is measured from the reference and a remeshing makes a
   * new one, so the energy comparisons below are of E without it */
  if (bump_config("shape.delta=0.15", "geometry.stabilization=0", &P->cfg, err, sizeof err) !=
      VES_OK) {
    fprintf(stderr, "config: %s\n", err);
    return -1;
  }
  if (ves_problem_setup_create(&P->cfg, VES_PHI0_L2, &P->su, err, sizeof err) != VES_OK ||
      ves_problem_discret(&P->cfg, &P->dp, err, sizeof err) != VES_OK) {
    fprintf(stderr, "setup: %s\n", err);
    return -1;
  }
  P->n = P->su->nodes->n;
  P->X = malloc(2 * (size_t)P->n * sizeof *P->X);
  P->yd = malloc(2 * (size_t)P->n * sizeof *P->yd);
  if (!P->X || !P->yd) return -1;
  ves_model_reference(P->su->model, P->X);
  smooth_motion(P->su->nodes, P->X, AMP, P->yd);
  /* the resolution's yardstick: the same problem on another node set of the
   * same sizing (seed + 1) */
  ves_config c2 = P->cfg;
  c2.seed = P->cfg.seed + 1;
  ves_setup *s2 = NULL;
  if (ves_problem_setup_create(&c2, VES_PHI0_L2, &s2, err, sizeof err) != VES_OK) return -1;
  double *X2 = malloc(2 * (size_t)s2->nodes->n * sizeof *X2);
  if (!X2) return -1;
  ves_model_reference(s2->model, X2);
  if (ves_model_eval(s2->model, X2, VES_F_E | VES_F_A | VES_F_V, P->eav_seed, P->eav_seed + 1,
                     P->eav_seed + 2, NULL, NULL, NULL) != VES_OK)
    return -1;
  free(X2);
  printf("# problem: %d nodes, %d points; seed + 1: %d nodes\n", P->n, P->su->quad->nq,
         s2->nodes->n);
  ves_setup_destroy(&s2);
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

static void eav(ves_model *m, const double *y, double v[3]) {
  assert_int_equal(
      ves_model_eval(m, y, VES_F_E | VES_F_A | VES_F_V, v, v + 1, v + 2, NULL, NULL, NULL), VES_OK);
}

static void print_info(const char *what, const ves_remesh_info *in) {
  printf(
      "# %s: nodes %d -> %d, points %d -> %d, curve %d knots, %.4f long\n"
      "#   E* %.8f -> %.8f (dE* %+.3e), dA/A %+.3e, dV/V %+.3e before the correction\n"
      "#   correction: %d iterations, max |delta|/h %.3e, |delta| %.3e; residuals A %.1e V %.1e\n"
      "#   E* after %.8f; interface displacement max %.3e mean %.3e; %.2f s (interface %.2f, "
      "nodes %.2f, tables %.2f, projection %.2f, correction %.2f)\n",
      what, in->n_old, in->n_new, in->nq_old, in->nq_new, in->curve_points, in->curve_length,
      in->E_old, in->E_proj, in->dE, in->dA, in->dV, in->corr_iter, in->corr_max, in->corr_norm,
      in->res_A, in->res_V, in->E, in->disp_max, in->disp_mean, in->seconds, in->seconds_interface,
      in->seconds_nodes, in->seconds_tables, in->seconds_project, in->seconds_correct);
}

static ves_remesh *remesh(ves_model *m, const double *y, int hold_area, int hold_volume,
                          double A_target, double V_target) {
  ves_remesh_params par;
  ves_remesh_params_default(&par);
  par.hold_area = hold_area, par.A_target = A_target;
  par.hold_volume = hold_volume, par.V_target = V_target;
  ves_remesh *r = NULL;
  char err[512] = "";
  ves_status st = ves_remesh_create(&P->dp, m, y, &par, &r, err, sizeof err);
  if (st != VES_OK) fail_msg("remesh: %s: %s", ves_status_str(st), err);
  return r;
}

/* ------------------------------------------------------------------------ */

/* The interface of the initial state against the exact curve. */
static void test_interface(void **state) {
  (void)state;
  int np = 0, pieces = 0;
  double *pts = NULL;
  assert_int_equal(ves_remesh_interface(P->su->model, P->X, NULL, &np, &pts, &pieces), VES_OK);
  assert_int_equal(pieces, 1);
  assert_true(np > 20);
  assert_true(pts[0] == 0.0 && pts[2 * np - 2] == 0.0 && pts[1] > pts[2 * np - 1]);
  double dmax = 0;
  for (int i = 0; i < np; i++)
    dmax = fmax(dmax, fabs(ves_shape_distance(P->su->shape, pts + 2 * i)));
  printf("# interface: %d points, max distance from the exact curve %.3e (eps %.2f)\n", np, dmax,
         P->cfg.epsilon);
  free(pts);
}

/* E*, A, V of the same problem on two node sets of the same sizing (seeds
 * s and s + 1) differ by the discretization error's node-set part: the
 * change a remeshing may make (a new node set of the same sizing) is held
 * to that scale. Printed per quantity. */
static void seed_scale(double v[3]) {
  double E0[3];
  eav(P->su->model, P->X, E0);
  for (int i = 0; i < 3; i++) v[i] = fabs(P->eav_seed[i] - E0[i]);
  printf("# node-set scale (seed vs seed + 1): |dE*| %.3e, |dA| %.3e, |dV| %.3e\n", v[0], v[1],
         v[2]);
}

/* A remesh of the unmoved initial state reproduces the setup: the same node
 * count (the extracted curve is within ~1e-3 of the exact one, far below a
 * spacing, 0.075, so the node generation makes the same decisions), E*
 * within a tenth of the node-set scale, A and V restored to rounding, the
 * interface moved by less than 1% of eps. */
static void test_initial(void **state) {
  (void)state;
  ves_model *m = P->su->model;
  double v[3], sc[3];
  eav(m, P->X, v);
  seed_scale(sc);
  ves_remesh *r = remesh(m, P->X, 1, 1, v[1], v[2]);
  ves_remesh_info in;
  ves_remesh_get_info(r, &in);
  print_info("unmoved initial state", &in);
  assert_int_equal(in.n_old, P->n);
  /* the same sizing: the old points as they are, but for a cell or so
   * where the node generation's spread leaves one sparser than the sizing
   * (measured 1 of 1,885) */
  assert_true(in.proj_cells_refined <= in.nq_old / 6 / 100);
  assert_true(abs(in.n_new - in.n_old) <= in.n_old / 100);
  assert_true(fabs(in.E_proj - in.E_old) <= 0.1 * sc[0]);
  assert_true(fabs(in.dA) <= 1e-6 && fabs(in.dV) <= 1e-6); /* projection of phi alone */
  assert_true(in.res_A <= 1e-14 && in.res_V <= 1e-14);
  double w[3];
  eav(ves_remesh_model(r), ves_remesh_y(r), w); /* independently of the correction's own */
  assert_true(fabs(w[1] / v[1] - 1) <= 1e-14 && fabs(w[2] / v[2] - 1) <= 1e-14);
  assert_true(fabs(w[0] - v[0]) <= 0.1 * sc[0]);
  assert_true(in.disp_max <= 0.01 * P->cfg.epsilon);
  ves_remesh_destroy(&r);
}

/* A remesh of a deformed state (max cond F 1.9): E* within 4x the node-set
 * scale of the old model's (the scale is measured at rest; the deformed
 * state sits on a sheared basis, whose error is larger: measured 2.0x;
 * 4x = 1.7e-4 absolute, 2.2e-5 relative, still an order below the
 * relative E error of h_band = 0.5 eps, 3e-4 at eps 0.04, docs/results.md),
 * A and V restored to rounding by a correction far below a spacing, the
 * interface moved by less than 1% of eps. */
static void test_deformed(void **state) {
  (void)state;
  ves_model *m = P->su->model;
  double v[3], sc[3];
  eav(m, P->yd, v);
  seed_scale(sc);
  ves_remesh *r = remesh(m, P->yd, 1, 1, v[1], v[2]);
  ves_remesh_info in;
  ves_remesh_get_info(r, &in);
  print_info("deformed state", &in);
  assert_true(fabs(in.E_old - v[0]) == 0.0);
  assert_true(fabs(in.E_proj - in.E_old) <= 4 * sc[0]);
  assert_true(fabs(in.E - in.E_old) <= 4 * sc[0]);
  assert_true(in.res_A <= 1e-14 && in.res_V <= 1e-14);
  double w[3];
  eav(ves_remesh_model(r), ves_remesh_y(r), w);
  assert_true(fabs(w[1] / v[1] - 1) <= 1e-14 && fabs(w[2] / v[2] - 1) <= 1e-14);
  assert_true(in.corr_max <= 1e-3);
  assert_true(in.disp_max <= 0.01 * P->cfg.epsilon);
  /* the area alone held: V free, A restored */
  ves_remesh_destroy(&r);
  r = remesh(m, P->yd, 1, 0, v[1], 0.0);
  ves_remesh_get_info(r, &in);
  assert_true(in.res_A <= 1e-14 && in.res_V == 0.0);
  ves_remesh_destroy(&r);
}

/* The remeshed reference rebuilt from what a file stores (nodes, spacings,
 * flags, phi0 coefficients): the same tables and the same E, A, V and
 * gradients at the same positions, bit for bit. */
static void test_restore(void **state) {
  (void)state;
  ves_model *m = P->su->model;
  double v[3];
  eav(m, P->yd, v);
  ves_remesh *r = remesh(m, P->yd, 1, 1, v[1], v[2]), *q = NULL;
  const ves_nodes *nd = ves_remesh_nodes(r);
  const int n = nd->n;
  assert_int_equal(ves_remesh_restore(m, n, nd->x, nd->h, nd->flag, ves_remesh_phi0c(r), &q),
                   VES_OK);
  const ves_quad *a = ves_remesh_quad(r), *b = ves_remesh_quad(q);
  assert_int_equal(a->nq, b->nq);
  assert_int_equal(a->ptr[a->nq], b->ptr[b->nq]);
  assert_memory_equal(a->nbr, b->nbr, (size_t)a->ptr[a->nq] * sizeof *a->nbr);
  assert_memory_equal(a->tab, b->tab, 6 * (size_t)a->ptr[a->nq] * sizeof *a->tab);
  double *g1 = malloc(8 * (size_t)n * sizeof *g1);
  assert_non_null(g1);
  double e1[3], e2[3];
  assert_int_equal(ves_model_eval(ves_remesh_model(r), ves_remesh_y(r), 7, e1, e1 + 1, e1 + 2, g1,
                                  g1 + 2 * n, NULL),
                   VES_OK);
  assert_int_equal(ves_model_eval(ves_remesh_model(q), ves_remesh_y(r), 7, e2, e2 + 1, e2 + 2,
                                  g1 + 4 * n, g1 + 6 * n, NULL),
                   VES_OK);
  assert_memory_equal(e1, e2, sizeof e1);
  assert_memory_equal(g1, g1 + 4 * n, 4 * (size_t)n * sizeof *g1);
  free(g1);
  ves_remesh_destroy(&q);
  ves_remesh_destroy(&r);
}

/* The integrator with a remeshing every 2 steps: the node count changes,
 * the steps after it are accepted with A and V held, E falls. */
static void test_sim(void **state) {
  (void)state;
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  ip.t_end = 1, ip.dt_initial = 1e-3, ip.dt_max = 1e-3, ip.adaptive = 0;
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  ves_sim *sim = NULL;
  assert_int_equal(ves_sim_create(P->su->model, ves_backend_find("newton"), &bo, &ip, &sim),
                   VES_OK);
  ves_remesh_policy pol = {.every = 2};
  assert_int_equal(ves_sim_set_remesh(sim, &P->dp, &pol), VES_OK);
  double E0, A0, V0, Eprev;
  ves_sim_initial(sim, &E0, &A0, &V0);
  Eprev = E0;
  ves_step_report rep;
  for (int k = 1; k <= 5; k++) {
    assert_int_equal(ves_sim_step(sim, &rep), VES_OK);
    assert_int_equal(rep.remeshed, k % 2 == 0);
    assert_int_equal(rep.remesh_status, VES_OK);
    assert_true(fabs(rep.A / A0 - 1) <= 1e-9 && fabs(rep.V / V0 - 1) <= 1e-9); /* ctol 1e-10 */
    assert_true(rep.E <= Eprev + 1e-10 * fabs(Eprev));
    if (rep.remeshed) {
      printf("# step %d: remeshed %d -> %d nodes, dE* %+.2e, E* after %.8f\n", k, rep.remesh.n_old,
             rep.remesh.n_new, rep.remesh.dE, rep.remesh.E);
      assert_int_equal(ves_model_nodes(ves_sim_model(sim))->n, rep.remesh.n_new);
      assert_true(rep.remesh.res_A <= 1e-14 && rep.remesh.res_V <= 1e-14);
      /* the predictor's y^{n-1} carried onto the new nodes (test_carry) */
      assert_non_null(ves_sim_y_prev(sim));
      Eprev = rep.remesh.E;
    } else {
      Eprev = rep.E;
    }
  }
  assert_int_equal(ves_sim_remeshings(sim), 2);
  ves_sim_destroy(&sim);
}

/* A remeshing that fails (here every time: its keys ask for another box)
 * does not hold the resets back: with a reset and a remeshing both due
 * every 2 steps, the remeshing fails at step 2 and after every step from
 * then on (a failed one is tried again every max(1, every/4) steps), and
 * the resets are made at steps 2 and 4 all the same (a failed remeshing
 * must not leave the reference unrenewed). */
static void test_failed_remesh_resets(void **state) {
  (void)state;
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  ip.t_end = 1, ip.dt_initial = 1e-3, ip.dt_max = 1e-3, ip.adaptive = 0;
  ip.reconnect_every = 2;
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  ves_sim *sim = NULL;
  assert_int_equal(ves_sim_create(P->su->model, ves_backend_find("newton"), &bo, &ip, &sim),
                   VES_OK);
  ves_discret_params c2 = P->dp;
  c2.box_r = 2.5; /* not the model's box: ves_remesh_create refuses (test_errors) */
  ves_remesh_policy pol = {.every = 2};
  assert_int_equal(ves_sim_set_remesh(sim, &c2, &pol), VES_OK);
  ves_step_report rep;
  for (int k = 1; k <= 4; k++) {
    assert_int_equal(ves_sim_step(sim, &rep), VES_OK);
    assert_int_equal(rep.remeshed, 0);
    assert_int_equal(rep.remesh_status, k >= 2 ? VES_ERR_ARG : VES_OK);
    assert_int_equal(rep.reconnect_status, VES_OK);
    assert_int_equal(rep.reconnected, k % 2 == 0);
  }
  assert_int_equal(ves_sim_remeshings(sim), 0);
  assert_int_equal(ves_sim_reconnections(sim), 2);
  ves_sim_destroy(&sim);
  /* every 8 steps: due at step 8, then tried again every 8/4 = 2 steps */
  ip.reconnect_every = 0;
  assert_int_equal(ves_sim_create(P->su->model, ves_backend_find("newton"), &bo, &ip, &sim),
                   VES_OK);
  pol.every = 8;
  assert_int_equal(ves_sim_set_remesh(sim, &c2, &pol), VES_OK);
  for (int k = 1; k <= 12; k++) {
    assert_int_equal(ves_sim_step(sim, &rep), VES_OK);
    assert_int_equal(rep.remesh_status, k >= 8 && k % 2 == 0 ? VES_ERR_ARG : VES_OK);
  }
  ves_sim_destroy(&sim);
}

/* The carried y_prev (ves_remesh_params.y_prev): from the unmoved state
 * y = X with y_prev = X - (a R, d Z + e), whose displacement the basis
 * reproduces (odd r part a R, even z part), d_r / r = a and d_z = d z + e
 * are a constant and an affine field, which the L2 projection onto the new
 * basis keeps (to its 1e-12 tolerance), so y_prev' = y' - (a r', d z' + e)
 * with (r', z') the new nodes, at the free dofs (the fixed ones at y').
 * Measured 2.8e-11 (1.4e-9 of the displacement's 0.02): the projection's
 * relative residual 1e-12 times the mass matrix's conditioning; bound 1e-9
 * (a predictor's start needs far less). phi0' is the same bits with or
 * without a y_prev (field 0 of one projection), and no y_prev gives none. */
static void test_carry(void **state) {
  (void)state;
  ves_model *m = P->su->model;
  const int n0 = P->n;
  const double ca = 0.01, cd = -0.02, ce = 0.005;
  double v[3], *yp = malloc(2 * (size_t)n0 * sizeof *yp);
  assert_non_null(yp);
  eav(m, P->X, v);
  for (int a = 0; a < n0; a++)
    yp[2 * a] = P->X[2 * a] - ca * P->X[2 * a],
           yp[2 * a + 1] = P->X[2 * a + 1] - (cd * P->X[2 * a + 1] + ce);
  ves_remesh_params par;
  ves_remesh_params_default(&par);
  assert_null(par.y_prev);
  par.hold_area = 1, par.A_target = v[1], par.hold_volume = 1, par.V_target = v[2];
  ves_remesh *r0 = NULL, *r1 = NULL;
  char err[512] = "";
  assert_int_equal(ves_remesh_create(&P->dp, m, P->X, &par, &r0, err, sizeof err), VES_OK);
  par.y_prev = yp;
  assert_int_equal(ves_remesh_create(&P->dp, m, P->X, &par, &r1, err, sizeof err), VES_OK);
  assert_null(ves_remesh_y_prev(r0));
  const ves_nodes *nd = ves_remesh_nodes(r1);
  const int n = nd->n;
  assert_int_equal(ves_remesh_nodes(r0)->n, n);
  assert_memory_equal(ves_remesh_phi0c(r0), ves_remesh_phi0c(r1), (size_t)n * sizeof(double));
  assert_memory_equal(ves_remesh_y(r0), ves_remesh_y(r1), 2 * (size_t)n * sizeof(double));
  const double *y1 = ves_remesh_y(r1), *p1 = ves_remesh_y_prev(r1);
  assert_non_null(p1);
  double err_free = 0;
  int nfixed = 0;
  for (int a = 0; a < n; a++) {
    const double want[2] = {ca * nd->x[2 * a], cd * nd->x[2 * a + 1] + ce};
    for (int k = 0; k < 2; k++) {
      const int fixed = (nd->flag[a] & VES_NODE_WALL) || ((nd->flag[a] & VES_NODE_AXIS) && !k);
      if (fixed) {
        assert_true(p1[2 * a + k] == y1[2 * a + k]);
        nfixed++;
      } else
        err_free = fmax(err_free, fabs(y1[2 * a + k] - p1[2 * a + k] - want[k]));
    }
  }
  printf("# carried y_prev: max |(y' - y_prev') - (a r', d z' + e)| = %.1e (%d fixed dofs)\n",
         err_free, nfixed);
  assert_true(err_free <= 1e-9);
  assert_true(nfixed > 0);
  ves_remesh_destroy(&r0);
  ves_remesh_destroy(&r1);
  free(yp);
}

/* The error paths. */
static void test_errors(void **state) {
  (void)state;
  ves_model *m = P->su->model;
  ves_remesh_params par;
  ves_remesh_params_default(&par);
  ves_remesh *r = NULL;
  char err[256];
  assert_int_equal(ves_remesh_create(NULL, m, P->X, &par, &r, err, sizeof err), VES_ERR_ARG);
  assert_int_equal(ves_remesh_create(&P->dp, m, NULL, &par, &r, err, sizeof err), VES_ERR_ARG);
  ves_discret_params c2 = P->dp;
  c2.box_r = 2.5; /* not the model's box */
  assert_int_equal(ves_remesh_create(&c2, m, P->X, &par, &r, err, sizeof err), VES_ERR_ARG);
  assert_null(r);
  assert_non_null(strstr(err, "box"));
  double *y = malloc(2 * (size_t)P->n * sizeof *y);
  assert_non_null(y);
  memcpy(y, P->X, 2 * (size_t)P->n * sizeof *y);
  y[7] = NAN;
  assert_int_equal(ves_remesh_create(&P->dp, m, y, &par, &r, err, sizeof err), VES_ERR_ARG);
  int np;
  double *pts = NULL;
  assert_int_equal(ves_remesh_interface(m, y, NULL, &np, &pts, NULL), VES_ERR_ARG);
  /* no interface: phi = -1 everywhere */
  double *c = malloc((size_t)P->n * sizeof *c);
  assert_non_null(c);
  for (int a = 0; a < P->n; a++) c[a] = -1.0;
  assert_int_equal(ves_remesh_interface(m, P->X, c, &np, &pts, NULL), VES_ERR_GEOM);
  ves_model_params mp;
  ves_model_get_params(m, &mp);
  ves_model *m0 = NULL;
  assert_int_equal(ves_model_create(P->su->nodes, P->su->quad, c, &mp, &m0), VES_OK);
  assert_int_equal(ves_remesh_create(&P->dp, m0, P->X, &par, &r, err, sizeof err), VES_ERR_GEOM);
  assert_non_null(strstr(err, "interface"));
  ves_model_destroy(&m0);
  /* restore: a spacing <= 0 */
  const ves_nodes *nd = P->su->nodes;
  double *h = malloc((size_t)P->n * sizeof *h);
  assert_non_null(h);
  memcpy(h, nd->h, (size_t)P->n * sizeof *h);
  h[3] = 0;
  assert_int_equal(ves_remesh_restore(m, P->n, nd->x, h, nd->flag, P->su->phi0c, &r), VES_ERR_ARG);
  assert_int_equal(ves_remesh_restore(m, P->n, nd->x, nd->h, nd->flag, NULL, &r), VES_ERR_ARG);
  /* the policy */
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  ves_sim *sim = NULL;
  assert_int_equal(ves_sim_create(m, ves_backend_find("newton"), &bo, &ip, &sim), VES_OK);
  ves_remesh_policy pol = {.cond_max = 0.5};
  assert_int_equal(ves_sim_set_remesh(sim, &P->dp, &pol), VES_ERR_ARG);
  pol = (ves_remesh_policy){.det_min = 1.0};
  assert_int_equal(ves_sim_set_remesh(sim, &P->dp, &pol), VES_ERR_ARG);
  assert_int_equal(ves_sim_set_remesh(sim, NULL, NULL), VES_OK);
  ves_sim_destroy(&sim);
  free(y), free(c), free(h);
  ves_remesh_destroy(NULL);
}

/* A remeshing where the band layers fold: a prolate spheroid of v = 0.8
 * (poles' radius of curvature below band*eps = 0.45 at eps 0.15, band 3:
 * the setup refuses its layers, `vesica check` says so) set up without
 * layers, then remeshed by keys that ask for them, as a run's are when the
 * shape develops a neck or a thin tube after a layered setup (Fig. 6,
 * docs/results.md, "Resets and remeshing"). The remeshing fills the band without layers instead
 * of failing, and restores A and V to rounding. */
static void test_folded_layers(void **state) {
  (void)state;
  char err[512] = "";
  const char *set[] = {
      "geometry.epsilon=0.15",    "geometry.box_r=1.6",        "geometry.box_z=2.6",
      "geometry.band=3",          "geometry.band_layers=0",    "shape.type=spheroid",
      "shape.reduced_volume=0.8", "shape.orientation=prolate", "geometry.stabilization=0"};
  ves_config cfg;
  assert_int_equal(ves_config_load(NULL, 9, set, &cfg, err, sizeof err), VES_OK);
  ves_setup *su = NULL;
  if (ves_problem_setup_create(&cfg, VES_PHI0_L2, &su, err, sizeof err) != VES_OK)
    fail_msg("%s", err);
  ves_config layered = cfg;
  layered.band_layers = 1;
  const ves_discret_params dlayered = discret_of(&layered);
  ves_setup *refused = NULL;
  assert_int_equal(ves_problem_setup_create(&layered, VES_PHI0_L2, &refused, err, sizeof err),
                   VES_ERR_CONFIG); /* the premise: these layers fold on this shape */
  const int n = su->nodes->n;
  double *X = malloc(2 * (size_t)n * sizeof *X), v[3];
  assert_non_null(X);
  ves_model_reference(su->model, X);
  eav(su->model, X, v);
  ves_remesh_params par;
  ves_remesh_params_default(&par);
  par.hold_area = 1, par.A_target = v[1], par.hold_volume = 1, par.V_target = v[2];
  ves_remesh *r = NULL;
  ves_status st = ves_remesh_create(&dlayered, su->model, X, &par, &r, err, sizeof err);
  if (st != VES_OK) fail_msg("remesh: %s: %s", ves_status_str(st), err);
  ves_remesh_info in;
  ves_remesh_get_info(r, &in);
  print_info("prolate v 0.8 with folding band layers", &in);
  assert_int_equal(in.band_layers, 0);
  /* the same sizing without layers on the extracted curve: measured the same
   * node count and a relative change of E* of -2.8e-5; bounds 2% and 1e-3 (no second node
   * sample measured here for a scale, as test_initial has) */
  assert_true(abs(in.n_new - n) <= n / 50);
  assert_true(fabs(in.E_proj / in.E_old - 1) <= 1e-3);
  assert_true(in.res_A <= 1e-14 && in.res_V <= 1e-14);
  /* measured 2.3e-3 = 1.5% of eps (test_initial's near-sphere: < 1%): the
   * extracted curve is coarsest at the poles, whose radius of curvature
   * (0.087) is below eps */
  assert_true(in.disp_max <= 0.03 * cfg.epsilon);
  ves_remesh_destroy(&r);
  ves_setup_destroy(&su);
  free(X);
}

/* New nodes finer than the old points can carry: the remeshing's keys ask
 * for h_band = eps/3 on the unmoved state of a model made at eps/2, so its
 * points' density per new h^2 in the band is ~6 (the setup's ~14). The
 * thin cells' points are replaced by a finer rule on the old field, and the
 * projected field is the old one at the new points. (Where the projection
 * fails without this: the core of a thinning neck, old points stretched
 * ~4.5x along the axis at ~2 per new node, where the coefficients oscillate
 * by +-10 from node to node and E* jumps by 2.4%: Fig. 6 at eps 0.01,
 * docs/results.md, "Resets and remeshing". An isotropic density as here still fits: measured
 * max |new - old| 1.2e-5 without the refinement at eps/6.) */
static void test_thin_cells(void **state) {
  (void)state;
  ves_model *m = P->su->model;
  double v[3];
  eav(m, P->X, v);
  ves_discret_params fine = P->dp;
  fine.h_band = P->dp.h_band / 1.5;
  ves_remesh_params par;
  ves_remesh_params_default(&par);
  par.hold_area = 1, par.A_target = v[1], par.hold_volume = 1, par.V_target = v[2];
  ves_remesh *r = NULL;
  char err[512] = "";
  ves_status st = ves_remesh_create(&fine, m, P->X, &par, &r, err, sizeof err);
  if (st != VES_OK) fail_msg("remesh: %s: %s", ves_status_str(st), err);
  ves_remesh_info in;
  ves_remesh_get_info(r, &in);
  print_info("h_band eps/3 from eps/2", &in);
  printf("#   %d old cells refined (%d still thin), %d projection points\n", in.proj_cells_refined,
         in.proj_cells_capped, in.proj_points);
  /* the projected field against the old one at the new points (the state is
   * unmoved: a new point's position is the old field's argument) */
  const ves_quad *nq = ves_remesh_quad(r);
  ves_quad *at = NULL;
  assert_int_equal(ves_quad_create_points(nq->nq, nq->x, nq->w, 0, NULL, &at), VES_OK);
  assert_int_equal(ves_quad_tables(at, P->su->nodes, &P->su->quad->lme, NULL), VES_OK);
  double *fo = malloc(6 * (size_t)nq->nq * sizeof *fo);
  double *fn = malloc(6 * (size_t)nq->nq * sizeof *fn);
  assert_non_null(fo), assert_non_null(fn);
  ves_quad_field(at, P->su->phi0c, 0, fo);
  ves_quad_field(nq, ves_remesh_phi0c(r), 0, fn);
  double dmax = 0, d2 = 0, w2 = 0;
  for (int al = 0; al < nq->nq; al++) {
    const double d = fn[6 * (size_t)al] - fo[6 * (size_t)al];
    dmax = fmax(dmax, fabs(d)), d2 += nq->w[al] * d * d, w2 += nq->w[al];
  }
  printf("#   new field - old field at the new points: max %.3e, rms %.3e\n", dmax, sqrt(d2 / w2));
  free(fo), free(fn);
  ves_quad_destroy(&at);
  /* every band cell below half the setup's density, and no cell needs more
   * than the finest rule's 16x */
  assert_true(in.proj_cells_refined > 0 && in.proj_cells_capped == 0);
  assert_true(in.proj_points > in.nq_old);
  /* measured max 1.3e-5, rms 1.7e-6 (the best fit of a field of the old
   * basis on the new one); bounds ~10x */
  assert_true(dmax <= 1e-4 && sqrt(d2 / w2) <= 2e-5);
  /* measured |dE*| 3.2e-4 (5e-5 relative: the old field on the finer basis and
   * quadrature); bound 1e-4 relative, below the h_band = 0.5 eps
   * discretization error (3e-4, docs/results.md, "Convergence in ε and h") */
  assert_true(fabs(in.E_proj - in.E_old) <= 1e-4 * in.E_old);
  assert_true(fabs(in.dA) <= 1e-5 && fabs(in.dV) <= 1e-6);
  ves_remesh_destroy(&r);
}

int main(void) {
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_interface),
      cmocka_unit_test(test_initial),
      cmocka_unit_test(test_deformed),
      cmocka_unit_test(test_restore),
      cmocka_unit_test(test_sim),
      cmocka_unit_test(test_failed_remesh_resets),
      cmocka_unit_test(test_carry),
      cmocka_unit_test(test_errors),
      cmocka_unit_test(test_folded_layers),
      cmocka_unit_test(test_thin_cells),
  };
  // clang-format on
  return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
