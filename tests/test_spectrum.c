/* vesica — tests of the linearized-flow analysis (spectrum.h): the flow's
 * constraint forces against forward Euler's first step, the stiffness
 * against Euler's observed stability limit, the modes, their Ritz vectors
 * and curvature shares against a dense solve of the same pencil, and the
 * analysis of a simulation's state (ves_spectrum_create) against these. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lapacke.h>

#include "ves/integrate.h"
#include "ves/setup.h"
#include "ves/spectrum.h"
#include "vesicle_impl.h"

/* Forward Euler with constant dt from the initial state, n steps; returns
 * the number of steps at which E rose (energy check off) and the first
 * step's constraint forces sigma = lambda / dt. */
static int euler_rises(ves_setup *s, double dt, int n, double *sigma) {
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  ip.t_end = 1.0, ip.adaptive = 0, ip.dt_initial = ip.dt_max = ip.dt_min = dt;
  ip.check_energy = 0;
  ves_backend_options bo;
  ves_backend_options_default(&bo);
  bo.factor_single = 0; /* the forces are compared with the spectrum's (double) to rounding */
  ves_sim *sim = NULL;
  if (ves_sim_create(s->model, ves_backend_find("euler"), &bo, &ip, &sim) != VES_OK)
    fail_msg("euler sim");
  double Eprev;
  ves_sim_initial(sim, &Eprev, NULL, NULL);
  ves_step_report rep;
  int rises = 0;
  for (int k = 0; k < n; k++) {
    if (ves_sim_step(sim, &rep) != VES_OK) break; /* an explosion leaves the domain */
    if (k == 0 && sigma) sigma[0] = rep.lambda[0] / dt, sigma[1] = rep.lambda[1] / dt;
    rises += rep.E > Eprev;
    Eprev = rep.E;
  }
  ves_sim_state st;
  ves_sim_get_state(sim, &st, NULL);
  if (st.nstep < n) rises += n - (int)st.nstep; /* steps that failed count as rises */
  ves_sim_destroy(&sim);
  return rises;
}

/* ves_spectrum_stiffness predicts forward Euler's stability limit 2 / mu_max:
 * 40 steps at 0.7 of it never raise E (every mode decays: (1 - 1.4)^2 < 1),
 * 40 steps at 1.5 of it do (the top mode grows 2x a step, 2^40 = 1e12 from
 * whatever the start holds of it). The start state: y^0, the forces from a
 * tiny first Euler step. */
static void test_euler_stiffness(void **state) {
  (void)state;
  ves_setup *s = small_setup();
  double sigma[2], mu, res;
  (void)euler_rises(s, 1e-7, 1, sigma);
  ves_step *st = NULL;
  assert_int_equal(ves_step_create(s->model, &st), VES_OK);
  double *y = malloc(2 * (size_t)s->nodes->n * sizeof *y);
  ves_model_reference(s->model, y);
  double A0, V0;
  assert_int_equal(ves_model_eval(s->model, y, VES_F_A | VES_F_V, NULL, &A0, &V0, NULL, NULL, NULL),
                   VES_OK);
  ves_step_params par = {.dt = 1, .hold_area = 1, .A0 = A0, .hold_volume = 1, .V_target = V0};
  assert_int_equal(ves_step_set(st, y, &par), VES_OK);
  assert_int_equal(ves_spectrum_stiffness(st, sigma, 60, &mu, &res), VES_OK);
  const double lim = 2 / mu;
  printf("# sigma %.6g %.6g; mu_max %.6e (Ritz residual %.1e): FE limit dt* %.4e\n", sigma[0],
         sigma[1], mu, res, lim);
  assert_true(mu > 0 && res < 1e-2); /* the top Ritz value has converged to 1% */
  const int below = euler_rises(s, 0.7 * lim, 40, NULL),
            above = euler_rises(s, 1.5 * lim, 40, NULL);
  printf("# 40 FE steps at 0.7 x the limit: E rose %d times; at 1.5 x: %d times\n", below, above);
  assert_int_equal(below, 0);
  assert_true(above > 0);
  /* arguments */
  assert_int_equal(ves_spectrum_stiffness(st, sigma, 1, &mu, NULL), VES_ERR_ARG);
  assert_int_equal(ves_spectrum_stiffness(st, NULL, 60, &mu, NULL), VES_ERR_ARG);
  assert_int_equal(ves_spectrum_stiffness(NULL, sigma, 60, &mu, NULL), VES_ERR_ARG);
  free(y);
  ves_step_destroy(&st);
  ves_setup_destroy(&s);
}

/* Dense n x n symmetric matrix (column-major) from lower triplets. */
static double *dense_sym(const ves_pattern *p, const double *v) {
  const int n = p->nfree;
  double *D = calloc((size_t)n * n, sizeof *D);
  assert_non_null(D);
  for (int t = 0; t < p->nnz; t++) {
    D[(size_t)p->jcol[t] * n + p->irow[t]] += v[t];
    if (p->irow[t] != p->jcol[t]) D[(size_t)p->irow[t] * n + p->jcol[t]] += v[t];
  }
  return D;
}

/* Q^T D Q for the Householder Q of J^T = Q R (n x m): its trailing
 * (n - m) x (n - m) block is D on the null space of J, in an orthonormal basis. */
static void project_dense(int n, int m, double *QR, const double *tau, double *D) {
  assert_int_equal(LAPACKE_dormqr(LAPACK_COL_MAJOR, 'L', 'T', n, n, m, QR, n, tau, D, n), 0);
  assert_int_equal(LAPACKE_dormqr(LAPACK_COL_MAJOR, 'R', 'N', n, n, m, QR, n, tau, D, n), 0);
}

/* ves_spectrum_modes and ves_spectrum_stiffness against a dense solve of the same
 * pencil A v = mu K v on {J v = 0} (A = Hess E + sigma_i Hess c_i from the
 * step Hessian: (H - K) / dt with lambda = dt sigma; the null space by
 * Householder; LAPACK dsygv), at the small vesicle's y^0 with the flow's
 * constraint forces there (ves_spectrum_flow, checked against Euler's first
 * step): the lowest eigenvalues above mu_lo agree with dense to 1e-7 of
 * the spectrum's scale mu_max (both are double precision solves of the same
 * matrices; Lanczos with full reorthogonalization on well-separated extreme
 * eigenvalues converges to rounding within 60 steps, and its own error bound
 * must cover the difference too), the inertia count below mu_lo is exact,
 * and mu_max matches the dense top eigenvalue to 1e-6 (asserted earlier
 * Ritz residual level).
 * Kept whole (137 lines): one scenario whose checks build on each other. */
static void test_flow_spectrum(void **state) {
  (void)state;
  ves_setup *s = small_setup();
  double sigma[2];
  (void)euler_rises(s, 1e-7, 1, sigma);
  ves_step *st = NULL;
  assert_int_equal(ves_step_create(s->model, &st), VES_OK);
  double *y = malloc(2 * (size_t)s->nodes->n * sizeof *y);
  assert_non_null(y);
  ves_model_reference(s->model, y);
  double A0, V0;
  assert_int_equal(ves_model_eval(s->model, y, VES_F_A | VES_F_V, NULL, &A0, &V0, NULL, NULL, NULL),
                   VES_OK);
  const double dt = 0.5;
  ves_step_params par = {.dt = dt, .hold_area = 1, .A0 = A0, .hold_volume = 1, .V_target = V0};
  assert_int_equal(ves_step_set(st, y, &par), VES_OK);
  /* ves_spectrum_flow solves the system of Euler's step at y^0: the same forces
   * to rounding (1e-10 relative: one factorization each of the same matrix) */
  double sf[2];
  assert_int_equal(ves_spectrum_flow(st, NULL, sf), VES_OK);
  printf("# flow forces at y^0: sigma %.12e %.12e (Euler's first step %.12e %.12e)\n", sf[0], sf[1],
         sigma[0], sigma[1]);
  for (int i = 0; i < 2; i++) assert_true(fabs(sf[i] - sigma[i]) <= 1e-10 * fabs(sigma[i]));
  assert_int_equal(ves_spectrum_flow(st, NULL, NULL), VES_ERR_ARG);
  /* the dense pencil on the null space of J */
  const ves_pattern *p = ves_model_pattern(s->model);
  const int n = p->nfree, m = 2, nt = n - m;
  double *H = malloc((size_t)p->nnz * sizeof *H), *x0 = malloc((size_t)n * sizeof *x0);
  double *J = malloc((size_t)m * n * sizeof *J), tau[2];
  assert_true(H && x0 && J);
  ves_step_x0(st, x0);
  const double lam[2] = {dt * sigma[0], dt * sigma[1]};
  assert_int_equal(ves_step_eval_hess(st, x0, 1.0, lam, H), VES_OK);
  const double *K = ves_step_K(st);
  for (int t = 0; t < p->nnz; t++) H[t] = (H[t] - K[t]) / dt; /* A */
  double *Ad = dense_sym(p, H), *Kd = dense_sym(p, K);
  assert_int_equal(ves_step_eval_jac(st, x0, J), VES_OK); /* row-major m x n = J^T col-major */
  assert_int_equal(LAPACKE_dgeqrf(LAPACK_COL_MAJOR, n, m, J, n, tau), 0);
  project_dense(n, m, J, tau, Ad);
  project_dense(n, m, J, tau, Kd);
  double *At = malloc((size_t)nt * nt * sizeof *At), *Kt = malloc((size_t)nt * nt * sizeof *Kt);
  double *w = malloc((size_t)nt * sizeof *w);
  assert_true(At && Kt && w);
  for (int j = 0; j < nt; j++)
    for (int i = 0; i < nt; i++) {
      At[(size_t)j * nt + i] = Ad[(size_t)(j + m) * n + (i + m)];
      Kt[(size_t)j * nt + i] = Kd[(size_t)(j + m) * n + (i + m)];
    }
  assert_int_equal(LAPACKE_dsygv(LAPACK_COL_MAJOR, 1, 'N', 'L', nt, At, nt, Kt, nt, w), 0);
  const double scale = w[nt - 1];
  printf("# dense pencil (%d tangent dofs): mu = %.8e %.8e %.8e %.8e %.8e ... %.6e\n", nt, w[0],
         w[1], w[2], w[3], w[4], scale);
  /* the top: ves_spectrum_stiffness */
  double mu_max, res;
  assert_int_equal(ves_spectrum_stiffness(st, sigma, 60, &mu_max, &res), VES_OK);
  printf("# stiffness: mu_max %.8e (dense %.8e, Ritz residual %.1e)\n", mu_max, scale, res);
  assert_true(fabs(mu_max - scale) <= 1e-6 * scale);
  /* the bottom from below all (nbelow 0), and from between w[2] and w[3] (3) */
  /* (shift and invert converges fast for the eigenvalues nearest mu_lo: the
   * bottom of this spectrum is a cluster, -0.048 -0.047 -0.030 -0.027 ...) */
  const double los[2] = {w[0] - 0.1 * (w[1] - w[0]), 0.5 * (w[2] + w[3])};
  const int below[2] = {0, 3};
  double *vec = malloc(3 * (size_t)n * sizeof *vec), *Kv = malloc((size_t)n * sizeof *Kv);
  double *Av = malloc((size_t)n * sizeof *Av), *J2 = malloc((size_t)m * n * sizeof *J2);
  assert_true(vec && Kv && Av && J2);
  assert_int_equal(ves_step_eval_jac(st, x0, J2), VES_OK);
  for (int c = 0; c < 2; c++) {
    double mu[3], err[3];
    int nb = -1;
    assert_int_equal(ves_spectrum_modes(st, sigma, los[c], 60, 3, mu, err, vec, &nb), VES_OK);
    printf("# modes above %.6g: %d below; mu = %.8e %.8e %.8e (error bounds %.1e %.1e %.1e)\n",
           los[c], nb, mu[0], mu[1], mu[2], err[0], err[1], err[2]);
    assert_int_equal(nb, below[c]);
    for (int j = 0; j < 3; j++) {
      const double d = fabs(mu[j] - w[below[c] + j]);
      assert_true(d <= 1e-7 * scale);
      assert_true(d <= 10 * err[j] + 1e-12 * scale); /* the bound is honest */
      /* the Ritz vector: tangent (J v = 0 to rounding of the K-solves,
       * 1e-12 of |J| |v|), K-normalized (1e-12), and an eigenvector: the
       * tangent part of (A - mu K) v, relative to |K v| mu_max, below the
       * eigenvalue's own accuracy (1e-7 of mu_max, above) */
      const double *v = vec + (size_t)j * n;
      double vKv = 0, jn[2] = {0, 0}, jv[2] = {0, 0}, vn = 0, kn = 0, rn = 0;
      ves_pattern_symv(p, K, v, Kv);
      ves_pattern_symv(p, H, v, Av);
      for (int i = 0; i < n; i++) {
        vKv += v[i] * Kv[i], vn += v[i] * v[i], kn += Kv[i] * Kv[i];
        Av[i] -= mu[j] * Kv[i]; /* r = (A - mu K) v */
        for (int q = 0; q < m; q++)
          jv[q] += J2[(size_t)q * n + i] * v[i],
              jn[q] += J2[(size_t)q * n + i] * J2[(size_t)q * n + i];
      }
      /* remove r's component in the range of J^T: r - J^T (J J^T)^-1 J r */
      double G[3] = {0, 0, 0}, g[2] = {0, 0};
      for (int i = 0; i < n; i++) {
        G[0] += J2[i] * J2[i], G[1] += J2[i] * J2[n + i], G[2] += J2[n + i] * J2[n + i];
        g[0] += J2[i] * Av[i], g[1] += J2[n + i] * Av[i];
      }
      const double det = G[0] * G[2] - G[1] * G[1];
      const double c0 = (G[2] * g[0] - G[1] * g[1]) / det, c1 = (G[0] * g[1] - G[1] * g[0]) / det;
      for (int i = 0; i < n; i++) {
        const double ri = Av[i] - c0 * J2[i] - c1 * J2[n + i];
        rn += ri * ri;
      }
      const double rel = sqrt(rn / kn) / scale;
      printf("#   vector %d: v^T K v - 1 = %.1e, |J v| / (|J| |v|) = %.1e %.1e, tangent "
             "residual / (|K v| mu_max) = %.1e\n",
             j + 1, vKv - 1, fabs(jv[0]) / sqrt(jn[0] * vn), fabs(jv[1]) / sqrt(jn[1] * vn), rel);
      /* mu = v^T A v split over the functionals (ves_spectrum_curvatures): the
       * same number from three separate assemblies (rounding of sums over
       * ~1e5 terms: 1e-9 of mu_max) */
      double cv[3];
      assert_int_equal(ves_spectrum_curvatures(st, v, cv), VES_OK);
      const double split = cv[0] + sigma[0] * cv[1] + sigma[1] * cv[2];
      printf("#   vector %d: E'' %.6e + sigma_A A'' %.6e + sigma_V V'' %.6e = %.9e (mu %.9e)\n",
             j + 1, cv[0], sigma[0] * cv[1], sigma[1] * cv[2], split, mu[j]);
      assert_true(fabs(split - mu[j]) <= 1e-9 * scale);
      assert_true(fabs(vKv - 1) <= 1e-11); /* measured <= 1.5e-13 */
      for (int q = 0; q < m; q++) assert_true(fabs(jv[q]) <= 1e-12 * sqrt(jn[q] * vn));
      assert_true(rel <= 1e-7);
    }
  }
  /* arguments */
  double mu1;
  assert_int_equal(ves_spectrum_modes(st, sigma, 0, 60, 0, &mu1, NULL, NULL, NULL), VES_ERR_ARG);
  assert_int_equal(ves_spectrum_modes(st, sigma, 0, 1, 1, &mu1, NULL, NULL, NULL), VES_ERR_ARG);
  assert_int_equal(ves_spectrum_modes(st, NULL, 0, 60, 1, &mu1, NULL, NULL, NULL), VES_ERR_ARG);
  assert_int_equal(ves_spectrum_modes(st, sigma, NAN, 60, 1, &mu1, NULL, NULL, NULL), VES_ERR_ARG);
  assert_int_equal(ves_spectrum_modes(NULL, sigma, 0, 60, 1, &mu1, NULL, NULL, NULL), VES_ERR_ARG);
  double cv3[3];
  assert_int_equal(ves_spectrum_curvatures(st, NULL, cv3), VES_ERR_ARG);
  assert_int_equal(ves_spectrum_curvatures(NULL, vec, cv3), VES_ERR_ARG);
  free(y), free(H), free(x0), free(J), free(Ad), free(Kd), free(At), free(Kt), free(w);
  free(vec), free(Kv), free(Av), free(J2);
  ves_step_destroy(&st);
  ves_setup_destroy(&s);
}

/* ves_spectrum_create, the analysis vesica spectrum prints, against the
 * functions it is built from, called on a step problem set at the same
 * state, for each choice of held constraints (both; the area alone; the
 * volume alone: its force must land in sigma[1] and its share in from[2]).
 * The same solves of the same matrices in the same order: equal to 1e-12
 * relative (bit for bit is expected; the margin only allows a reordered
 * sum). Then what it adds: the shares of mu sum to mu (1e-9 of mu_max, as
 * in test_flow_spectrum, plus the Ritz bound), the material at the nodes of the unmoved initial
 * state is the nodes themselves (LME reproduces affine functions: 1e-12),
 * so the drift's K-norm vanishes to rounding, the mode shares lie in [0, 1],
 * and u is each mode's vector spread over the nodes. Bad arguments: VES_ERR_ARG.
 * Kept whole (95 lines): one scenario whose checks build on each other. */
static void test_analysis(void **state) {
  (void)state;
  ves_setup *s = small_setup();
  ves_integrate_params ip;
  ves_integrate_params_default(&ip);
  ves_sim *sim = make_sim(s, "newton", &ip);
  const ves_pattern *pat = ves_model_pattern(s->model);
  const int n = s->nodes->n, nv = pat->nfree, nm = 2, lz = 40;
  const int held[3][2] = {{1, 1}, {1, 0}, {0, 1}};
  double *vec = malloc((size_t)nm * nv * sizeof *vec);
  assert_non_null(vec);
  for (int c = 0; c < 3; c++) {
    const ves_spectrum_params p = {.hold_area = held[c][0],
                                   .hold_volume = held[c][1],
                                   .above = -1,
                                   .modes = nm,
                                   .lanczos = lz};
    ves_spectrum *sp = NULL;
    assert_int_equal(ves_spectrum_create(sim, &p, &sp), VES_OK);
    assert_non_null(sp);
    assert_int_equal(sp->n, n);
    assert_int_equal(sp->nvar, nv);
    /* the same, function by function */
    ves_sim_state ss;
    ves_sim_get_state(sim, &ss, NULL);
    ves_step_params par = {.dt = ss.dt,
                           .hold_area = held[c][0],
                           .A0 = ss.A0,
                           .hold_volume = held[c][1],
                           .V_target = ss.V};
    ves_step *st = NULL;
    assert_int_equal(ves_step_create(s->model, &st), VES_OK);
    assert_int_equal(ves_step_set(st, ves_sim_y(sim), &par), VES_OK);
    double sg[2] = {0, 0}, mu_max, res, mu[3], err[3];
    int below;
    assert_int_equal(ves_spectrum_flow(st, NULL, sg), VES_OK);
    const double sA = held[c][0] ? sg[0] : 0.0, sV = held[c][1] ? sg[held[c][0]] : 0.0;
    printf("# held (%d, %d): sigma %.9e %.9e (create %.9e %.9e)\n", held[c][0], held[c][1], sA, sV,
           sp->sigma[0], sp->sigma[1]);
    assert_true(fabs(sp->sigma[0] - sA) <= 1e-12 * fabs(sA));
    assert_true(fabs(sp->sigma[1] - sV) <= 1e-12 * fabs(sV));
    assert_true(held[c][0] ? sA != 0 : sp->sigma[0] == 0);
    assert_true(held[c][1] ? sV != 0 : sp->sigma[1] == 0);
    assert_int_equal(ves_spectrum_stiffness(st, sg, lz, &mu_max, &res), VES_OK);
    assert_true(fabs(sp->mu_max - mu_max) <= 1e-12 * mu_max);
    assert_int_equal(ves_spectrum_modes(st, sg, -1, lz, nm, mu, err, vec, &below), VES_OK);
    assert_int_equal(sp->below, below);
    for (int j = 0; j < nm; j++) {
      const ves_spectrum_mode *q = sp->mode + j;
      printf("#   mu_%d %.9e (direct %.9e): E'' %.4e sA A'' %.4e sV V'' %.4e; band %.3f axis "
             "%.3f material %.3e\n",
             j + 1, sp->mu[j], mu[j], q->from[0], q->from[1], q->from[2], q->band, q->axis,
             q->material);
      assert_true(fabs(sp->mu[j] - mu[j]) <= 1e-12 * mu_max);
      /* the Ritz value and its vector's Rayleigh quotient both approximate
       * mu within the Ritz bound (plus the rounding of test_flow_spectrum) */
      assert_true(fabs(q->from[0] + q->from[1] + q->from[2] - mu[j]) <=
                  1e-9 * mu_max + 10 * sp->mu_err[j]);
      if (!held[c][0]) assert_true(q->from[1] == 0);
      if (!held[c][1]) assert_true(q->from[2] == 0);
      assert_true(q->band >= 0 && q->band <= 1 && q->axis >= 0 && q->axis <= 1);
      assert_true(q->material > 0 && isfinite(q->drift));
      for (int i = 0; i < 2 * n; i++) {
        const int k = pat->dof[i];
        assert_true(sp->u[(size_t)j * 2 * n + i] == (k >= 0 ? sp->vec[(size_t)j * nv + k] : 0.0));
      }
    }
    double xerr = 0;
    for (int i = 0; i < 2 * n; i++) xerr = fmax(xerr, fabs(sp->x[i] - s->nodes->x[i]));
    printf("#   max |y(X_a) - X_a| %.1e, drift K-norm %.1e\n", xerr, sp->drift_K_norm);
    assert_true(xerr <= 1e-12);
    assert_true(sp->drift_K_norm <= 1e-10); /* sqrt of K-weighted squares of ~1e-13 */
    ves_step_destroy(&st);
    ves_spectrum_destroy(&sp);
    assert_null(sp);
  }
  /* arguments */
  ves_spectrum *sp = NULL;
  ves_spectrum_params bad = {
      .hold_area = 1, .hold_volume = 1, .above = -1, .modes = 5, .lanczos = 4};
  assert_int_equal(ves_spectrum_create(sim, &bad, &sp), VES_ERR_ARG); /* modes > lanczos */
  assert_null(sp);
  bad.modes = 2, bad.above = NAN;
  assert_int_equal(ves_spectrum_create(sim, &bad, &sp), VES_ERR_ARG);
  bad.above = 0, bad.lanczos = 1, bad.modes = 1;
  assert_int_equal(ves_spectrum_create(sim, &bad, &sp), VES_ERR_ARG);
  bad.lanczos = 4;
  assert_int_equal(ves_spectrum_create(NULL, &bad, &sp), VES_ERR_ARG);
  assert_int_equal(ves_spectrum_create(sim, NULL, &sp), VES_ERR_ARG);
  assert_int_equal(ves_spectrum_create(sim, &bad, NULL), VES_ERR_ARG);
  ves_spectrum_destroy(NULL);
  free(vec);
  ves_sim_destroy(&sim);
  ves_setup_destroy(&s);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_euler_stiffness),
      cmocka_unit_test(test_flow_spectrum),
      cmocka_unit_test(test_analysis),
  };
  // clang-format on
  return cmocka_run_group_tests_name("spectrum", tests, NULL, NULL);
}
