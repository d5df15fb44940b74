/* vesica — tests of the step problem (solver/step/step.c) and of the newton and
 * euler backends: objective, gradient, constraint Jacobian and Hessian of the
 * Lagrangian against finite differences; the evaluation cache; one Newton
 * step (convergence, constraints, energy decrease, frozen vs fresh Hessian);
 * Euler as the dt -> 0 limit of the VTI step; the error paths. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
/* cmocka needs the four headers above first */
#include <cmocka.h>

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ves/backend.h"
#include "ves/setup.h"
#include "ves/step.h"
#include "app/problem.h"

/* ------------------------------------------------------------------------ */
/* The problem                                                               */
/* ------------------------------------------------------------------------ */

/* Deterministic uniform numbers in [0, 1) (xorshift64*). */
static double urand(uint64_t *s) {
  *s ^= *s >> 12;
  *s ^= *s << 25;
  *s ^= *s >> 27;
  return (double)((*s * 2685821657736338717ULL) >> 11) * 0x1.0p-53;
}

static double *xmalloc(size_t n) {
  double *p = malloc((n ? n : 1) * sizeof *p);
  assert_non_null(p);
  return p;
}

/* A small out-of-equilibrium vesicle: the unit sphere with a P2 perturbation
 * r = 1 + 0.1 P2(cos t) (a prolate-ish shape with curvature differences of
 * ~30%), eps = 0.12 in a 1.9 x 1.9 box, L2-projected phi0. */
typedef struct {
  ves_setup *su; /* setup (owns the model) */
  ves_model *m;  /* borrowed from su */
  ves_step *s;   /* the step problem */
  int n, nv;     /* real nodes, free dofs */
  double *yn;    /* 2n the state y^n = reference positions */
  double A0, V0; /* A, V at y^n */
  double E0;     /* E at y^n */
  double hmin;   /* smallest nodal spacing */
} problem;

static problem *P;

static int group_setup(void **state) {
  (void)state;
  P = calloc(1, sizeof *P);
  if (!P) return -1;
  ves_config cfg;
  char err[512] = "";
  const char *set[] = {"geometry.epsilon=0.12", "geometry.box_r=1.9", "geometry.box_z=1.9",
                       "shape.type=sphere",     "shape.mode=2",       "shape.delta=0.1"};
  if (ves_config_load(NULL, 6, set, &cfg, err, sizeof err) != VES_OK) {
    fprintf(stderr, "config: %s\n", err);
    return -1;
  }
  if (ves_problem_setup_create(&cfg, VES_PHI0_L2, &P->su, err, sizeof err) != VES_OK) {
    fprintf(stderr, "setup: %s\n", err);
    return -1;
  }
  P->m = P->su->model;
  P->n = P->su->nodes->n;
  P->yn = malloc(2 * (size_t)P->n * sizeof *P->yn);
  if (!P->yn) return -1;
  ves_model_reference(P->m, P->yn);
  if (ves_model_eval(P->m, P->yn, VES_F_E | VES_F_A | VES_F_V, &P->E0, &P->A0, &P->V0, NULL, NULL,
                     NULL) != VES_OK)
    return -1;
  P->hmin = INFINITY;
  for (int a = 0; a < P->n; a++) P->hmin = fmin(P->hmin, P->su->nodes->h[a]);
  if (ves_step_create(P->m, &P->s) != VES_OK) return -1;
  P->nv = ves_step_nvar(P->s);
  printf("# problem: %d nodes, %d free dofs, %d points; E* = %.6f, A = %.6f, V = %.6f, "
         "h_min = %.4f\n",
         P->n, P->nv, P->su->quad->nq, P->E0, P->A0, P->V0, P->hmin);
  return 0;
}

static int group_teardown(void **state) {
  (void)state;
  if (!P) return 0;
  ves_step_destroy(&P->s);
  ves_setup_destroy(&P->su);
  free(P->yn);
  free(P);
  P = NULL;
  return 0;
}

/* Set the step problem at y^n with dt and both constraints held. */
static void set_step(double dt, int hold_area, int hold_volume) {
  ves_step_params par = {dt, hold_area, P->A0, hold_volume, P->V0, 0};
  assert_int_equal(ves_step_set(P->s, P->yn, &par), VES_OK);
}

/* x = x0 + a smooth admissible motion of amplitude amp (free dofs): u_r odd
 * in R, u_z even, vanishing on the wall (as in test_model.c). */
static void perturbed_x(double amp, double *x) {
  const int n = P->n;
  const double LR = P->su->nodes->LR, LZ = P->su->nodes->LZ;
  double *y = xmalloc(2 * (size_t)n);
  for (int a = 0; a < n; a++) {
    const double R = P->yn[2 * a], Z = P->yn[2 * a + 1];
    const double w = (1 - (R / LR) * (R / LR)) * (1 - (Z / LZ) * (Z / LZ));
    y[2 * a] = R + amp * R * w * (1 + 0.5 * sin(3 * Z + 0.7) + 0.3 * cos(2 * R * R));
    y[2 * a + 1] = Z + amp * w * (sin(2.5 * Z + 0.3) + 0.5 * cos(3 * R * R - Z));
  }
  const ves_pattern *pat = ves_model_pattern(P->m);
  for (int i = 0; i < 2 * n; i++)
    if (pat->dof[i] >= 0) x[pat->dof[i]] = y[i];
  free(y);
}

/* ------------------------------------------------------------------------ */
/* The step problem                                                          */
/* ------------------------------------------------------------------------ */

/* At x = x0: f = dt E(y^n) exactly (d = 0), grad f = dt grad E, c = 0,
 * expand(x0) = y^n, and the sizes and structure are consistent. */
static void test_at_x0(void **state) {
  (void)state;
  const double dt = 1e-2;
  set_step(dt, 1, 1);
  assert_int_equal(ves_step_ncon(P->s), 2);
  assert_int_equal(ves_step_hess_nnz(P->s), ves_model_pattern(P->m)->nnz);
  assert_ptr_equal(ves_step_model(P->s), P->m);
  assert_true(ves_step_get_params(P->s)->dt == dt);
  const int nv = P->nv;
  double *x = xmalloc(nv), *g = xmalloc(nv), *gE = xmalloc(nv), *y = xmalloc(2 * (size_t)P->n);
  ves_step_x0(P->s, x);
  ves_step_expand(P->s, x, y);
  assert_memory_equal(y, P->yn, 2 * (size_t)P->n * sizeof *y);
  double f, c[2], Edt;
  assert_int_equal(ves_step_eval_f(P->s, x, &f), VES_OK);
  assert_int_equal(ves_step_eval_c(P->s, x, c), VES_OK);
  assert_int_equal(ves_step_eval_grad(P->s, x, g), VES_OK);
  assert_int_equal(ves_step_eval_energy_grad(P->s, x, &Edt, gE), VES_OK);
  printf("# at x0: f = %.15e, dt E = %.15e; c = (%.1e, %.1e)\n", f, dt * P->E0, c[0], c[1]);
  /* d = 0 exactly, so 0.5 d^T K d = 0 and f is the same double dt * E */
  assert_true(f == dt * P->E0);
  assert_true(Edt == f);
  assert_true(c[0] == 0 && c[1] == 0); /* same model pass as A0, V0 */
  /* K d = 0 exactly (dq = 0 at every point); g and gE are the same per-point
   * terms dt f_E w de/dq, rounded in another order (the factor dt before or
   * after the scatter): an entry sums ~1e2..1e3 such terms of either sign,
   * each off by an ulp, so 1e-12 of the largest entry bounds it */
  double gmax = 0, gdif = 0;
  for (int j = 0; j < nv; j++)
    gmax = fmax(gmax, fabs(gE[j])), gdif = fmax(gdif, fabs(g[j] - gE[j]));
  printf("# at x0: |grad f - dt grad E|_inf = %.2e of |dt grad E|_inf\n", gdif / gmax);
  assert_true(gdif <= 1e-12 * gmax);
  free(x), free(g), free(gE), free(y);
}

/* Central differences: gradient of f and rows of the constraint Jacobian on
 * 40 random free dofs at a perturbed x (amplitude 0.05: max |u| ~ 0.05, a
 * real deformation against the band spacing 0.06), dt = 1 so that both
 * terms of f matter (|K d| = 3.7 and |dt grad E| = 1.7, printed).
 * Step delta = 1e-4 h_min: test_model.c measured the noise floor of this
 * model's gradient checks there at ~2e-7 (truncation ~ (delta/h)^2, rounding
 * ~ 1e-16 |f| / (delta |g|)). Error per dof |fd - g| / max(|g|, 1e-2 |g|_sel,inf)
 * (the floor for entries that are nearly zero, e.g. far from the interface). */
static void test_gradient_jacobian_fd(void **state) {
  (void)state;
  const int nv = P->nv, NSEL = 40;
  const double dt = 1.0, delta = 1e-4 * P->hmin;
  set_step(dt, 1, 1);
  double *x = xmalloc(nv), *g = xmalloc(nv), *J = xmalloc(2 * (size_t)nv), *gE = xmalloc(nv);
  perturbed_x(0.05, x);
  assert_int_equal(ves_step_eval_grad(P->s, x, g), VES_OK);
  assert_int_equal(ves_step_eval_jac(P->s, x, J), VES_OK);
  assert_int_equal(ves_step_eval_energy_grad(P->s, x, NULL, gE), VES_OK);
  double kd = 0, ge = 0;
  for (int j = 0; j < nv; j++) kd = fmax(kd, fabs(g[j] - gE[j])), ge = fmax(ge, fabs(gE[j]));
  printf("# perturbed x: |K d|_inf = %.3e, |dt grad E|_inf = %.3e\n", kd, ge);
  assert_true(kd > 0.05 * ge && ge > 0.05 * kd); /* both terms matter */
  { /* the objective's K(y^n) d, summed point by point without a matrix, against
     * the assembled K (ves_step_K): the same per-point products B^T D B d,
     * regrouped (per triangle in the matrix), so they agree to rounding:
     * 1e-12 of the largest entry (the sums have ~1e2..1e3 terms of either
     * sign, ~1e-16 each), and f - dt E against (1/2) d^T K d likewise */
    const double *K = ves_step_K(P->s);
    assert_non_null(K);
    double *x0 = xmalloc(nv), *d = xmalloc(nv), *Kd = xmalloc(nv), f, Edt, dKd = 0, e = 0;
    ves_step_x0(P->s, x0);
    for (int j = 0; j < nv; j++) d[j] = x[j] - x0[j];
    ves_pattern_symv(ves_model_pattern(P->m), K, d, Kd);
    for (int j = 0; j < nv; j++) e = fmax(e, fabs(g[j] - gE[j] - Kd[j])), dKd += d[j] * Kd[j];
    assert_int_equal(ves_step_eval_f(P->s, x, &f), VES_OK);
    assert_int_equal(ves_step_eval_energy_grad(P->s, x, &Edt, NULL), VES_OK);
    printf("# K d without the matrix: |g - dt grad E - K d|_inf = %.2e of |K d|_inf; "
           "f - dt E - d^T K d / 2 = %.2e of it\n",
           e / kd, (f - Edt - 0.5 * dKd) / (0.5 * dKd));
    assert_true(e <= 1e-12 * fmax(kd, ge));
    assert_true(fabs(f - Edt - 0.5 * dKd) <= 1e-12 * (fabs(Edt) + 0.5 * dKd));
    free(x0), free(d), free(Kd);
  }

  uint64_t rng = 0x9E3779B97F4A7C15ULL;
  double err[3] = {0, 0, 0}, gmax[3] = {0, 0, 0};
  int sel[64];
  for (int k = 0; k < NSEL; k++) sel[k] = (int)(urand(&rng) * nv);
  for (int k = 0; k < NSEL; k++) {
    gmax[0] = fmax(gmax[0], fabs(g[sel[k]]));
    for (int i = 0; i < 2; i++) gmax[1 + i] = fmax(gmax[1 + i], fabs(J[(size_t)i * nv + sel[k]]));
  }
  for (int k = 0; k < NSEL; k++) {
    const int j = sel[k];
    const double xj = x[j];
    double fp, fm, cp[2], cm[2];
    x[j] = xj + delta;
    assert_int_equal(ves_step_eval_f(P->s, x, &fp), VES_OK);
    assert_int_equal(ves_step_eval_c(P->s, x, cp), VES_OK);
    x[j] = xj - delta;
    assert_int_equal(ves_step_eval_f(P->s, x, &fm), VES_OK);
    assert_int_equal(ves_step_eval_c(P->s, x, cm), VES_OK);
    x[j] = xj;
    double fd[3] = {(fp - fm) / (2 * delta), (cp[0] - cm[0]) / (2 * delta),
                    (cp[1] - cm[1]) / (2 * delta)};
    double an[3] = {g[j], J[j], J[(size_t)nv + j]};
    for (int q = 0; q < 3; q++)
      err[q] = fmax(err[q], fabs(fd[q] - an[q]) / fmax(fabs(an[q]), 1e-2 * gmax[q]));
  }
  printf("# FD (%d dofs, step %.1e): grad f %.2e, grad A %.2e, grad V %.2e (max rel error)\n", NSEL,
         delta, err[0], err[1], err[2]);
  for (int q = 0; q < 3; q++) assert_true(err[q] <= 1e-6);
  free(x), free(g), free(J), free(gE);
}

/* H(x, lambda) v against the central difference of the Lagrangian gradient
 * g + J^T lambda along a random v (|v|_inf = 1), lambda = (0.3, -0.5) and
 * sigma_f = 1; also sigma_f = 0 (constraint curvature alone). Step 1e-4 h_min
 * along v (test_model.c's direction check). Error |fd - Hv|_inf / |Hv|_inf. */
static void test_hessian_fd(void **state) {
  (void)state;
  const int nv = P->nv;
  const double dt = 1.0, delta = 1e-4 * P->hmin;
  set_step(dt, 1, 1);
  double *x = xmalloc(nv), *v = xmalloc(nv), *xp = xmalloc(nv), *gp = xmalloc(nv),
         *gm = xmalloc(nv), *J = xmalloc(2 * (size_t)nv), *H = xmalloc(ves_step_hess_nnz(P->s)),
         *Hv = xmalloc(nv);
  perturbed_x(0.05, x);
  uint64_t rng = 0xD1B54A32D192ED03ULL;
  for (int j = 0; j < nv; j++) v[j] = 2 * urand(&rng) - 1;
  const double lam[2] = {0.3, -0.5};
  const ves_pattern *pat = ves_model_pattern(P->m);
  for (int sf = 1; sf >= 0; sf--) {
    assert_int_equal(ves_step_eval_hess(P->s, x, sf, lam, H), VES_OK);
    ves_pattern_symv(pat, H, v, Hv);
    double *gs[2] = {gp, gm};
    for (int sgn = 0; sgn < 2; sgn++) {
      for (int j = 0; j < nv; j++) xp[j] = x[j] + (sgn ? -delta : delta) * v[j];
      assert_int_equal(ves_step_eval_grad(P->s, xp, gs[sgn]), VES_OK);
      assert_int_equal(ves_step_eval_jac(P->s, xp, J), VES_OK);
      for (int j = 0; j < nv; j++)
        gs[sgn][j] = sf * gs[sgn][j] + lam[0] * J[j] + lam[1] * J[(size_t)nv + j];
    }
    double emax = 0, hmax = 0;
    for (int j = 0; j < nv; j++) {
      emax = fmax(emax, fabs((gp[j] - gm[j]) / (2 * delta) - Hv[j]));
      hmax = fmax(hmax, fabs(Hv[j]));
    }
    printf("# Hessian of the Lagrangian (sigma_f = %d, lambda = (0.3, -0.5)) along v: rel "
           "error %.2e, |Hv| = %.3e\n",
           sf, emax / hmax, hmax);
    assert_true(hmax > 0 && emax <= 1e-6 * hmax);
    /* the rounding floor eps max_i (|H| |x|)_i, here by the pattern's own
     * symmetric product of |H| with |x| (xp, gp as scratch): the same sums
     * in another order, so to 1e-12 relative */
    const int nnz = ves_step_hess_nnz(P->s);
    double *aH = xmalloc(nnz), amax = 0;
    for (int t = 0; t < nnz; t++) aH[t] = fabs(H[t]);
    for (int j = 0; j < nv; j++) xp[j] = fabs(x[j]);
    ves_pattern_symv(pat, aH, xp, gp);
    for (int j = 0; j < nv; j++) amax = fmax(amax, gp[j]);
    const double fl = ves_step_hess_floor(P->s, x, H, gm);
    assert_true(fl > 0 && fabs(fl - DBL_EPSILON * amax) <= 1e-12 * fl);
    free(aH);
  }
  free(x), free(v), free(xp), free(gp), free(gm), free(J), free(H), free(Hv);
}

/* ves_step_eval_hess_single against ves_step_eval_hess at the perturbed x of
 * test_hessian_fd, sigma_f 1 and 0: each triangle's block entry is a sum of
 * K <= 36 float products of float-rounded factors, so its error is at most
 * (K + 2) u_s ~ 2.3e-6 of the sum of the terms' absolute values, which the
 * sums over triangles (in double) carry over. Measured: the largest entry
 * difference 6.7e-8 (sigma_f 1) and 3.0e-8 (0) of max |H|, Hv to 4.0e-8
 * and 1.9e-8 of |Hv|. Asserted: 1e-5 of max |H| entrywise and of |Hv|_inf
 * (the 2.3e-6 bound with room for rows whose terms cancel; a wrong entry
 * would be off by O(1)), and at least one entry must differ (the path is
 * single precision). */
static void test_hessian_single(void **state) {
  (void)state;
  const int nv = P->nv, nnz = ves_step_hess_nnz(P->s);
  set_step(1.0, 1, 1);
  double *x = xmalloc(nv), *v = xmalloc(nv), *Hd = xmalloc(nnz), *Hs = xmalloc(nnz),
         *yd = xmalloc(nv), *ys = xmalloc(nv);
  perturbed_x(0.05, x);
  uint64_t rng = 0x9E3779B97F4A7C15ULL;
  for (int j = 0; j < nv; j++) v[j] = 2 * urand(&rng) - 1;
  const double lam[2] = {0.3, -0.5};
  const ves_pattern *pat = ves_model_pattern(P->m);
  for (int sf = 1; sf >= 0; sf--) {
    assert_int_equal(ves_step_eval_hess(P->s, x, sf, lam, Hd), VES_OK);
    assert_int_equal(ves_step_eval_hess_single(P->s, x, sf, lam, Hs), VES_OK);
    double hmax = 0, dmax = 0, ymax = 0, dy = 0;
    for (int t = 0; t < nnz; t++)
      hmax = fmax(hmax, fabs(Hd[t])), dmax = fmax(dmax, fabs(Hs[t] - Hd[t]));
    ves_pattern_symv(pat, Hd, v, yd);
    ves_pattern_symv(pat, Hs, v, ys);
    for (int j = 0; j < nv; j++) ymax = fmax(ymax, fabs(yd[j])), dy = fmax(dy, fabs(ys[j] - yd[j]));
    printf("# single precision products (sigma_f = %d): max |Hs - H| = %.2e of max |H| = %.3e; "
           "|Hs v - H v| = %.2e of |Hv|\n",
           sf, dmax / hmax, hmax, dy / ymax);
    assert_true(hmax > 0 && dmax > 0 && dmax <= 1e-5 * hmax);
    assert_true(dy <= 1e-5 * ymax);
  }
  free(x), free(v), free(Hd), free(Hs), free(yd), free(ys);
}

static void eav(const double *x, double *E, double *A, double *V);

/* The cache is keyed by content: values at x, then at x changed in place
 * (same pointer), then back, agree with a fresh step object; the gradient
 * asked after the value at the same x is the same as asked first; and
 * ves_step_values hands out the model's own E, A, V from it or without it. */
static void test_cache(void **state) {
  (void)state;
  const int nv = P->nv;
  set_step(1e-2, 1, 1);
  ves_step *s2 = NULL;
  assert_int_equal(ves_step_create(P->m, &s2), VES_OK);
  ves_step_params par = {1e-2, 1, P->A0, 1, P->V0, 0};
  assert_int_equal(ves_step_set(s2, P->yn, &par), VES_OK);
  double *x = xmalloc(nv), *g1 = xmalloc(nv), *g2 = xmalloc(nv);
  perturbed_x(0.03, x);
  double f1, f2, f3, c1[2], c2[2];
  assert_int_equal(ves_step_eval_f(P->s, x, &f1), VES_OK);
  x[nv / 2] += 1e-3; /* in place */
  assert_int_equal(ves_step_eval_f(P->s, x, &f2), VES_OK);
  assert_int_equal(ves_step_eval_c(P->s, x, c1), VES_OK);
  assert_int_equal(ves_step_eval_grad(P->s, x, g1), VES_OK);
  assert_int_equal(ves_step_eval_grad(s2, x, g2), VES_OK); /* gradient first */
  assert_int_equal(ves_step_eval_f(s2, x, &f3), VES_OK);
  assert_int_equal(ves_step_eval_c(s2, x, c2), VES_OK);
  assert_true(f2 != f1);
  assert_true(f2 == f3 && c1[0] == c2[0] && c1[1] == c2[1]);
  assert_memory_equal(g1, g2, (size_t)nv * sizeof *g1);
  x[nv / 2] -= 1e-3;
  assert_int_equal(ves_step_eval_f(P->s, x, &f3), VES_OK);
  assert_true(f3 == f1);
  /* ves_step_values: the model's E, A, V bit for bit, from the cache at the
   * last point (both constraints held) and by a pass elsewhere; with one
   * constraint the cache lacks V and it evaluates all three */
  double Em, Am, Vm, Es, As, Vs;
  eav(x, &Em, &Am, &Vm);
  assert_int_equal(ves_step_values(P->s, x, &Es, &As, &Vs), VES_OK);
  assert_true(Es == Em && As == Am && Vs == Vm);
  x[nv / 3] += 1e-3; /* not the cached point */
  eav(x, &Em, &Am, &Vm);
  assert_int_equal(ves_step_values(P->s, x, &Es, &As, &Vs), VES_OK);
  assert_true(Es == Em && As == Am && Vs == Vm);
  par.hold_volume = 0;
  assert_int_equal(ves_step_set(s2, P->yn, &par), VES_OK);
  assert_int_equal(ves_step_eval_f(s2, x, &f3), VES_OK);
  assert_int_equal(ves_step_values(s2, x, &Es, &As, &Vs), VES_OK);
  assert_true(Es == Em && As == Am && Vs == Vm);
  assert_int_equal(ves_step_values(s2, x, &Es, &As, NULL), VES_ERR_ARG);
  ves_step_destroy(&s2);
  assert_null(s2);
  free(x), free(g1), free(g2);
}

/* ------------------------------------------------------------------------ */
/* Backends                                                                  */
/* ------------------------------------------------------------------------ */

/* Relative inf-norm difference |a - b| / |b| of two displacements from x0. */
static double rel_diff(int n, const double *a, const double *b, const double *x0) {
  double d = 0, m = 0;
  for (int j = 0; j < n; j++) d = fmax(d, fabs(a[j] - b[j])), m = fmax(m, fabs(b[j] - x0[j]));
  return d / m;
}

/* Run one backend on the current step from x0, lambda = 0; x, lambda out. */
static ves_status run_backend(const char *name, const ves_backend_options *opt, double *x,
                              double *lambda, ves_backend_stats *st) {
  const ves_backend_type *b = ves_backend_find(name);
  assert_non_null(b);
  void *state = NULL;
  assert_int_equal(b->create(opt, P->s, &state), VES_OK);
  ves_step_x0(P->s, x);
  lambda[0] = lambda[1] = 0;
  ves_status r = b->solve(state, P->s, x, lambda, st);
  b->destroy(&state);
  assert_null(state);
  return r;
}

/* E, A, V at the free dofs x. */
static void eav(const double *x, double *E, double *A, double *V) {
  double *y = xmalloc(2 * (size_t)P->n);
  ves_step_expand(P->s, x, y);
  assert_int_equal(ves_model_eval(P->m, y, VES_F_E | VES_F_A | VES_F_V, E, A, V, NULL, NULL, NULL),
                   VES_OK);
  free(y);
}

/* ves_step_set_dt: the same step with another dt (nlopt's continuation)
 * gives, at a point whose evaluation is cached at the first dt, f and grad f
 * of a step set afresh with the second dt, bit for bit (f = D + dt E, grad f
 * = K d + dt grad E formed by the model pass at that dt), and c unchanged;
 * set back, the first dt's values again. Bad dt refused. */
static void test_set_dt(void **state) {
  (void)state;
  const int nv = P->nv;
  set_step(1e-2, 1, 1);
  ves_step *s2 = NULL;
  assert_int_equal(ves_step_create(P->m, &s2), VES_OK);
  ves_step_params par = {10.0, 1, P->A0, 1, P->V0, 0};
  assert_int_equal(ves_step_set(s2, P->yn, &par), VES_OK);
  double *x = xmalloc(nv), *g1 = xmalloc(nv), *g2 = xmalloc(nv), *g0 = xmalloc(nv);
  perturbed_x(0.03, x);
  double f0, f1, f2, c0[2], c1[2];
  assert_int_equal(ves_step_eval_grad(P->s, x, g0), VES_OK); /* cached at dt 1e-2 */
  assert_int_equal(ves_step_eval_f(P->s, x, &f0), VES_OK);
  assert_int_equal(ves_step_eval_c(P->s, x, c0), VES_OK);
  assert_int_equal(ves_step_set_dt(P->s, 10.0), VES_OK);
  assert_true(ves_step_get_params(P->s)->dt == 10.0);
  assert_int_equal(ves_step_eval_f(P->s, x, &f1), VES_OK);
  assert_int_equal(ves_step_eval_grad(P->s, x, g1), VES_OK);
  assert_int_equal(ves_step_eval_c(P->s, x, c1), VES_OK);
  assert_int_equal(ves_step_eval_grad(s2, x, g2), VES_OK);
  assert_int_equal(ves_step_eval_f(s2, x, &f2), VES_OK);
  assert_true(f1 == f2 && f1 != f0);
  assert_memory_equal(g1, g2, (size_t)nv * sizeof *g1);
  assert_true(c1[0] == c0[0] && c1[1] == c0[1]);
  assert_int_equal(ves_step_set_dt(P->s, 1e-2), VES_OK);
  assert_int_equal(ves_step_eval_f(P->s, x, &f1), VES_OK);
  assert_int_equal(ves_step_eval_grad(P->s, x, g1), VES_OK);
  assert_true(f1 == f0);
  assert_memory_equal(g1, g0, (size_t)nv * sizeof *g1);
  assert_int_equal(ves_step_set_dt(P->s, 0.0), VES_ERR_ARG);
  assert_int_equal(ves_step_set_dt(P->s, NAN), VES_ERR_ARG);
  assert_int_equal(ves_step_set_dt(NULL, 1.0), VES_ERR_ARG);
  assert_true(ves_step_get_params(P->s)->dt == 1e-2);
  free(x), free(g0), free(g1), free(g2);
  ves_step_destroy(&s2);
}

/* One VTI step with the newton backend, both constraints held, from the
 * out-of-equilibrium y^n, dt = 1e-2 (paper Table 1's largest VTI step; the
 * forces move the nodes by 2.0e-4 in this step, 0.3% of the band spacing:
 * small, but far above the solver's resolution).
 * Converges; |A/A0 - 1|, |V/V0 - 1| <= 1e-10: ctol = 1e-10 is the backend's
 * stopping test on |c_i| / target_i and Newton converges quadratically, so the
 * final violation is far below it; 1e-10 of A0 ~ 13 is still ~1e6 ulps, well
 * above the rounding of the (extended-precision) sums. E(y^{n+1}) < E(y^n):
 * f(x^{n+1}) <= f(x0) = dt E(y^n) with the viscous term >= 0 (paper Sec. 3.2).
 * Frozen and fresh Hessian converge to the same KKT point: both stop at a
 * residual 1e-9 of the forces; the displacements agree to <= 1e-8 relative. */
static void test_newton_step(void **state) {
  (void)state;
  const int nv = P->nv;
  double *x0 = xmalloc(nv), *xa = xmalloc(nv), *xb = xmalloc(nv);
  ves_backend_options opt;
  ves_backend_options_default(&opt);
  const double dts[1] = {1e-2};
  for (int k = 0; k < 1; k++) {
    set_step(dts[k], 1, 1);
    ves_step_x0(P->s, x0);
    double la[2], lb[2], E, A, V;
    ves_backend_stats sa, sb;
    opt.freeze_hessian = 0;
    assert_int_equal(run_backend("newton", &opt, xa, la, &sa), VES_OK);
    opt.freeze_hessian = 1;
    assert_int_equal(run_backend("newton", &opt, xb, lb, &sb), VES_OK);
    eav(xa, &E, &A, &V);
    double umax = 0;
    for (int j = 0; j < nv; j++) umax = fmax(umax, fabs(xa[j] - x0[j]));
    const double rd = rel_diff(nv, xb, xa, x0);
    printf("# newton dt = %.0e: fresh %d it (f %d, g %d, h %d, %.2f s), frozen %d it (f %d, g "
           "%d, h %d, %.2f s); max |y - y^n| = %.2e; E* %.6f -> %.6f; A/A0-1 = %.1e, V/V0-1 = "
           "%.1e; lambda = (%.4e, %.4e); frozen vs fresh %.1e\n",
           dts[k], sa.iterations, sa.f_evals, sa.g_evals, sa.h_evals, sa.seconds, sb.iterations,
           sb.f_evals, sb.g_evals, sb.h_evals, sb.seconds, umax, P->E0, E, A / P->A0 - 1,
           V / P->V0 - 1, la[0], la[1], rd);
    assert_true(umax > 1e-4); /* visible motion (measured 2.0e-4) */
    assert_true(E < P->E0);   /* energy decrease */
    assert_true(fabs(A / P->A0 - 1) <= 1e-10);
    assert_true(fabs(V / P->V0 - 1) <= 1e-10);
    assert_true(sa.violation <= 1e-10 && sb.violation <= 1e-10);
    assert_true(rd <= 1e-8);
    assert_true(fabs(la[0] - lb[0]) <= 1e-6 * fabs(la[0]));
    assert_true(sb.h_evals <= sa.h_evals);
    assert_true(sa.iterations >= 1 && sa.iterations <= 10);
  }
  /* the volume alone (one constraint, in row 0): V held, A free to change */
  set_step(1e-2, 0, 1);
  assert_int_equal(ves_step_ncon(P->s), 1);
  double l1[2], E, A, V;
  ves_backend_stats s1;
  opt.freeze_hessian = 1;
  assert_int_equal(run_backend("newton", &opt, xa, l1, &s1), VES_OK);
  eav(xa, &E, &A, &V);
  printf("# newton dt = 1e-2, volume only: %d it (h %d); A/A0-1 = %.2e, V/V0-1 = %.1e, "
         "lambda_V = %.4e\n",
         s1.iterations, s1.h_evals, A / P->A0 - 1, V / P->V0 - 1, l1[0]);
  assert_true(fabs(V / P->V0 - 1) <= 1e-10);
  assert_true(fabs(A / P->A0 - 1) > 1e-8); /* the area moved: not held */
  assert_true(E < P->E0);
  free(x0), free(xa), free(xb);
}

/* Euler as the limit of VTI: (x_euler - x0)/dt and (x_newton - x0)/dt differ
 * by O(dt) (the VTI step is backward-Euler-like, first order). Measured for
 * dt = 1e-4, 1e-5, 1e-6: 9.3e-2, 9.8e-3, 9.9e-4 relative (inf-norm), i.e.
 * ~930 dt: the stiff modes relax at rates ~1e3, the scale of the explicit
 * stability limit. Checked: each decade divides the difference by 7..13
 * (linear, with margin) and the constant is O(1e3). Also Euler's statistics,
 * its multipliers (same convention as Newton's: they agree to O(dt)) and its
 * drift |c| = O(dt^2). */
static void test_euler_limit(void **state) {
  (void)state;
  const int nv = P->nv;
  double *x0 = xmalloc(nv), *xe = xmalloc(nv), *xn = xmalloc(nv);
  ves_backend_options opt;
  ves_backend_options_default(&opt);
  opt.tol = 1e-11;        /* the differences measured reach 1e-6 relative */
  opt.freeze_hessian = 1; /* one Hessian per solve: the test's cost */
  double diff[3], dts[3] = {1e-4, 1e-5, 1e-6};
  for (int k = 0; k < 3; k++) {
    set_step(dts[k], 1, 1);
    ves_step_x0(P->s, x0);
    double le[2], ln[2];
    ves_backend_stats se, sn;
    assert_int_equal(run_backend("euler", &opt, xe, le, &se), VES_OK);
    assert_int_equal(se.iterations, 1);
    assert_int_equal(se.g_evals, 1);
    assert_int_equal(se.h_evals, 0);
    assert_int_equal(run_backend("newton", &opt, xn, ln, &sn), VES_OK);
    diff[k] = rel_diff(nv, xe, xn, x0);
    printf("# dt = %.0e: |v_euler - v_newton| / |v_newton| = %.3e; newton %d it; euler "
           "drift %.1e; lambda/dt euler (%.5e, %.5e), newton (%.5e, %.5e)\n",
           dts[k], diff[k], sn.iterations, se.violation, le[0] / dts[k], le[1] / dts[k],
           ln[0] / dts[k], ln[1] / dts[k]);
    assert_true(fabs(le[0] - ln[0]) <= 1e-2 * fabs(ln[0])); /* measured 2e-5 at 1e-4 */
    /* second-order drift: measured 1.4e-4 dt^2 */
    assert_true(se.violation <= 1e-2 * dts[k] * dts[k]);
  }
  for (int k = 0; k < 3; k++) assert_true(diff[k] < 3e3 * dts[k]);
  for (int k = 0; k < 2; k++) assert_true(diff[k + 1] < diff[k] / 7 && diff[k + 1] > diff[k] / 13);
  free(x0), free(xe), free(xn);
}

/* ------------------------------------------------------------------------ */
/* Error paths                                                               */
/* ------------------------------------------------------------------------ */

/* Kept whole (90 lines): one scenario whose checks build on each other. */
static void test_errors(void **state) {
  (void)state;
  ves_step *s = NULL;
  assert_int_equal(ves_step_create(NULL, &s), VES_ERR_ARG);
  assert_int_equal(ves_step_create(P->m, NULL), VES_ERR_ARG);
  assert_int_equal(ves_step_create(P->m, &s), VES_OK);
  const int nv = ves_step_nvar(s);
  double *x = xmalloc(nv), *g = xmalloc(nv), f, c[2];
  /* before set: nothing evaluates */
  assert_null(ves_step_K(s));
  assert_null(ves_step_get_params(s));
  assert_int_equal(ves_step_ncon(s), 0);
  assert_int_equal(ves_step_eval_f(s, x, &f), VES_ERR_ARG);
  ves_step_params bad[] = {{0, 1, P->A0, 0, 0, 0},   {-1e-3, 0, 0, 0, 0, 0},
                           {NAN, 0, 0, 0, 0, 0},     {1e-3, 1, 0, 0, 0, 0},
                           {1e-3, 0, 0, 1, -1.0, 0}, {INFINITY, 0, 0, 0, 0, 0}};
  for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
    assert_int_equal(ves_step_set(s, P->yn, bad + i), VES_ERR_ARG);
  ves_step_params ok = {1e-3, 1, P->A0, 0, 0, 0};
  assert_int_equal(ves_step_set(NULL, P->yn, &ok), VES_ERR_ARG);
  assert_int_equal(ves_step_set(s, NULL, &ok), VES_ERR_ARG);
  assert_int_equal(ves_step_set(s, P->yn, NULL), VES_ERR_ARG);
  assert_int_equal(ves_step_set(s, P->yn, &ok), VES_OK);
  assert_int_equal(ves_step_ncon(s), 1);
  ves_step_x0(s, x);
  assert_int_equal(ves_step_eval_f(s, NULL, &f), VES_ERR_ARG);
  assert_int_equal(ves_step_eval_f(s, x, NULL), VES_ERR_ARG);
  assert_int_equal(ves_step_eval_grad(s, x, NULL), VES_ERR_ARG);
  assert_int_equal(ves_step_eval_c(s, x, NULL), VES_ERR_ARG);
  assert_int_equal(ves_step_eval_jac(s, x, NULL), VES_ERR_ARG);
  assert_int_equal(ves_step_eval_hess(s, x, 1.0, NULL, g), VES_ERR_ARG); /* ncon = 1 */
  assert_int_equal(ves_step_eval_f(NULL, x, &f), VES_ERR_ARG);
  assert_int_equal(ves_step_nvar(NULL), 0);
  /* a folded state (r < 0 everywhere) is outside the domain, and stays so
   * from the cache */
  for (int j = 0; j < nv; j++) g[j] = -x[j];
  assert_int_equal(ves_step_eval_f(s, g, &f), VES_ERR_DOMAIN);
  assert_int_equal(ves_step_eval_c(s, g, c), VES_ERR_DOMAIN);
  assert_int_equal(ves_step_eval_grad(s, g, x), VES_ERR_DOMAIN);
  /* backends: lookup, bad options, NULLs */
  assert_null(ves_backend_find("nosuch"));
  assert_null(ves_backend_find(NULL));
  const char *names[] = {"ipopt", "nlopt", "newton", "euler"};
  for (int i = 0; i < 4; i++) {
    const ves_backend_type *b = ves_backend_find(names[i]);
    assert_non_null(b);
    assert_string_equal(b->name, names[i]);
  }
  ves_backend_options opt;
  ves_backend_options_default(&opt);
  /* the problem file's [solver] defaults (test_config test_defaults_agree) */
  assert_true(opt.tol == 1e-9 && opt.ctol == 1e-10 && opt.max_iter == 40);
  const ves_backend_type *nb = ves_backend_find("newton"), *eb = ves_backend_find("euler");
  void *st = NULL;
  assert_int_equal(nb->create(NULL, s, &st), VES_ERR_ARG);
  assert_int_equal(nb->create(&opt, NULL, &st), VES_ERR_ARG);
  assert_int_equal(nb->create(&opt, s, NULL), VES_ERR_ARG);
  assert_int_equal(eb->create(&opt, NULL, &st), VES_ERR_ARG);
  ves_backend_options o2 = opt;
  o2.tol = 0;
  assert_int_equal(nb->create(&o2, s, &st), VES_ERR_ARG);
  o2 = opt, o2.max_iter = 0;
  assert_int_equal(nb->create(&o2, s, &st), VES_ERR_ARG);
  assert_null(st);
  /* iteration limit: one Newton step allowed, a tight tolerance */
  o2 = opt, o2.max_iter = 1, o2.tol = 1e-14;
  assert_int_equal(nb->create(&o2, s, &st), VES_OK);
  ves_backend_stats bs;
  double lam[2] = {0, 0};
  ves_step_x0(s, x);
  assert_int_equal(nb->solve(st, s, NULL, lam, &bs), VES_ERR_ARG);
  assert_int_equal(nb->solve(st, s, x, NULL, &bs), VES_ERR_ARG); /* ncon = 1 */
  assert_int_equal(nb->solve(st, s, x, lam, NULL), VES_ERR_ARG);
  assert_int_equal(nb->solve(st, s, x, lam, &bs), VES_MAXITER);
  assert_int_equal(bs.iterations, 1);
  assert_int_equal(bs.limit, VES_LIMIT_ITER);
  assert_string_equal(ves_backend_limit_key(bs.limit), "solver.max_iter");
  /* a start outside the domain */
  for (int j = 0; j < nv; j++) x[j] = -x[j];
  assert_int_equal(nb->solve(st, s, x, lam, &bs), VES_ERR_DOMAIN);
  nb->destroy(&st);
  assert_null(st);
  nb->destroy(NULL);
  eb->destroy(NULL);
  ves_step_destroy(&s);
  assert_null(s);
  ves_step_destroy(NULL);
  ves_step_destroy(&s);
  free(x), free(g);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0);
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_at_x0),       cmocka_unit_test(test_gradient_jacobian_fd),
      cmocka_unit_test(test_hessian_fd), cmocka_unit_test(test_hessian_single),  cmocka_unit_test(test_cache),
      cmocka_unit_test(test_newton_step), cmocka_unit_test(test_euler_limit),
      cmocka_unit_test(test_errors),      cmocka_unit_test(test_set_dt),
  };
  // clang-format on
  return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
