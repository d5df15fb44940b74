/* vesica — tests of the local densities (energy, area, volume, dissipation)
 * and their analytic derivatives in the local kinematic variables. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
/* cmocka needs the four headers above first */
#include <cmocka.h>

#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model/model_impl.h"

#define NQ VES_NQ
#define EPS 0.04 /* interface width of the random states (brief: eps = 0.04) */

/* Deterministic uniform numbers in [0, 1) (xorshift64*). */
static double urand(uint64_t *s) {
  *s ^= *s >> 12;
  *s ^= *s << 25;
  *s ^= *s >> 27;
  return (double)((*s * 2685821657736338717ULL) >> 11) * 0x1.0p-53;
}

/* Uniform in [-1, 1). */
static double srand1(uint64_t *s) { return 2.0 * urand(s) - 1.0; }

/* A random state: F = I + P with |P_iI| <= 0.4 and det F >= 0.5, G_nJK in
 * [-5, 5], r log-uniform in [1e-2, 2], phi0 in (-1, 1), |grad phi0| <= 1/eps,
 * |d2 phi0| entries <= 1/eps^2. */
static void random_state(uint64_t *s, double q[NQ], ves_model_point *pt) {
  do {
    for (int a = 0; a < 4; a++) q[1 + a] = (a == 0 || a == 3 ? 1.0 : 0.0) + 0.4 * srand1(s);
  } while (q[1] * q[4] - q[2] * q[3] < 0.5);
  for (int c = 0; c < 6; c++) q[5 + c] = 5.0 * srand1(s);
  q[0] = exp(log(1e-2) + urand(s) * (log(2.0) - log(1e-2)));
  pt->phi0 = 0.999 * srand1(s);
  const double th = 6.283185307179586 * urand(s), mag = urand(s) / EPS;
  pt->dphi0[0] = mag * cos(th);
  pt->dphi0[1] = mag * sin(th);
  for (int c = 0; c < 3; c++) pt->ddphi0[c] = srand1(s) / (EPS * EPS);
}

/* Scale of each variable for the finite-difference step and the error norm:
 * r for r (the density varies on the scale r through 1/r), 1 for F (F ~ I),
 * max(1, |G|) for G. */
static void var_scale(const double q[NQ], double sc[NQ]) {
  sc[0] = q[0];
  for (int a = 1; a < 5; a++) sc[a] = 1.0;
  for (int c = 5; c < NQ; c++) sc[c] = fmax(1.0, fabs(q[c]));
}

typedef struct {
  double grad;     /* worst scaled gradient error (2-norm, relative) */
  double hess;     /* worst scaled Hessian error (Frobenius, relative) */
  double hess_col; /* worst scaled Hessian column error, relative to the column */
  double asym;     /* worst |H_ij - H_ji| / max |H| */
} fd_report;

/* Central differences of fn at (pt, q): gradient from values, Hessian from
 * gradients, step h_k = delta * sc_k. In the scaled variables u_k = q_k/sc_k
 * the densities vary on scales O(1), so the truncation error is
 * O(delta^2 * |u-derivative 3|) ~ 1e-10 and the rounding error
 * O(1e-16 / delta) ~ 1e-11 relative for delta = 1e-5 (cancellation in W
 * can cost one or two more digits): a 1e-6 bound leaves a wide margin while
 * any wrong term (an O(1) relative error in one entry) fails it. */
static void fd_check(ves_model_local_fn *fn, const ves_model_local_par *par,
                     const ves_model_point *pt, const double q[NQ], fd_report *rep) {
  const double delta = 1e-5;
  double e, g[NQ], H[NQ * NQ], sc[NQ];
  assert_int_equal(fn(par, pt, q, &e, g, H), VES_OK);
  var_scale(q, sc);
  double gerr = 0.0, gnorm = 0.0, herr = 0.0, hnorm = 0.0, colw = 0.0, hmax = 0.0;
  for (int k = 0; k < NQ; k++) {
    double qp[NQ], qm[NQ], ep, em, gp[NQ], gm[NQ];
    memcpy(qp, q, sizeof qp);
    memcpy(qm, q, sizeof qm);
    const double h = delta * sc[k];
    qp[k] += h;
    qm[k] -= h;
    assert_int_equal(fn(par, pt, qp, &ep, gp, NULL), VES_OK);
    assert_int_equal(fn(par, pt, qm, &em, gm, NULL), VES_OK);
    const double gfd = (ep - em) / (2.0 * h);
    gerr += pow(sc[k] * (gfd - g[k]), 2);
    gnorm += pow(sc[k] * g[k], 2);
    double cerr = 0.0, cnorm = 0.0;
    for (int i = 0; i < NQ; i++) {
      const double hfd = (gp[i] - gm[i]) / (2.0 * h);
      const double d = sc[i] * sc[k] * (hfd - H[i * NQ + k]);
      const double v = sc[i] * sc[k] * H[i * NQ + k];
      cerr += d * d;
      cnorm += v * v;
      hmax = fmax(hmax, fabs(H[i * NQ + k]));
    }
    herr += cerr;
    hnorm += cnorm;
    /* columns that vanish identically (area and volume in G) are compared
       absolutely against 1e-12 of the whole matrix */
    colw = fmax(colw, sqrt(cerr) / fmax(sqrt(cnorm), 1e-12));
  }
  double asym = 0.0;
  for (int i = 0; i < NQ; i++)
    for (int j = 0; j < NQ; j++) asym = fmax(asym, fabs(H[i * NQ + j] - H[j * NQ + i]));
  rep->grad = fmax(rep->grad, sqrt(gerr / gnorm));
  rep->hess = fmax(rep->hess, sqrt(herr / hnorm));
  rep->hess_col = fmax(rep->hess_col, colw);
  rep->asym = fmax(rep->asym, hmax > 0 ? asym / hmax : 0.0);
}

/* FD checks of one density over 40 random states (20 per C0 in {0, 1.5}). */
static void fd_density(ves_model_local_fn *fn, const char *name, uint64_t seed) {
  fd_report rep = {0};
  for (int t = 0; t < 40; t++) {
    ves_model_local_par par = {EPS, t < 20 ? 0.0 : 1.5, 1.0, 10.0};
    ves_model_point pt;
    double q[NQ];
    random_state(&seed, q, &pt);
    fd_check(fn, &par, &pt, q, &rep);
  }
  printf("  %-7s FD: grad %.2e  hess %.2e  worst column %.2e  asym %.1e\n", name, rep.grad,
         rep.hess, rep.hess_col, rep.asym);
  assert_true(rep.grad <= 1e-6);
  assert_true(rep.hess <= 1e-6);
  assert_true(rep.hess_col <= 1e-6);
  assert_true(rep.asym == 0.0); /* filled from one triangle: symmetric bit for bit */
}

static void test_fd_energy(void **state) {
  (void)state;
  fd_density(ves_model_local_energy, "energy", 1001);
}

static void test_fd_area(void **state) {
  (void)state;
  fd_density(ves_model_local_area, "area", 2002);
}

static void test_fd_volume(void **state) {
  (void)state;
  fd_density(ves_model_local_volume, "volume", 3003);
}

/* NULL gradient/Hessian pointers give the same value; the gradient does not
 * depend on whether the Hessian is asked for (same arithmetic: bitwise). */
static void test_optional_outputs(void **state) {
  (void)state;
  uint64_t seed = 77;
  ves_model_local_fn *fns[3] = {ves_model_local_energy, ves_model_local_area,
                                ves_model_local_volume};
  for (int t = 0; t < 5; t++) {
    ves_model_local_par par = {EPS, 1.5, 1.0, 10.0};
    ves_model_point pt;
    double q[NQ];
    random_state(&seed, q, &pt);
    for (int f = 0; f < 3; f++) {
      double e0, e1, e2, e3, g1[NQ], g2[NQ], H2[NQ * NQ], H3[NQ * NQ];
      assert_int_equal(fns[f](&par, &pt, q, &e0, NULL, NULL), VES_OK);
      assert_int_equal(fns[f](&par, &pt, q, &e1, g1, NULL), VES_OK);
      assert_int_equal(fns[f](&par, &pt, q, &e2, g2, H2), VES_OK);
      assert_int_equal(fns[f](&par, &pt, q, &e3, NULL, H3), VES_OK);
      assert_true(e0 == e1 && e1 == e2 && e2 == e3);
      assert_memory_equal(g1, g2, sizeof g1);
      assert_memory_equal(H2, H3, sizeof H2);
    }
    double e, W, lap, ew;
    assert_int_equal(ves_model_local_energy_ex(&par, &pt, q, &ew, NULL, NULL, &W, &lap), VES_OK);
    assert_int_equal(ves_model_local_energy(&par, &pt, q, &e, NULL, NULL), VES_OK);
    assert_true(e == ew);
    /* e_E = W^2 det F r, one rounding per product */
    const double J = q[1] * q[4] - q[2] * q[3];
    assert_true(fabs(e - W * W * J * q[0]) <= 1e-15 * e);
  }
}

/* C1 = (phi0/eps + sqrt2 C0)(1 - phi0^2), C2 = (phi0^2 - 1)^2 / (4 eps). */
static double c1_of(const ves_model_local_par *p, double phi0) {
  return (phi0 / p->eps + sqrt(2.0) * p->C0) * (1.0 - phi0 * phi0);
}
static double c2_of(const ves_model_local_par *p, double phi0) {
  return (phi0 * phi0 - 1.0) * (phi0 * phi0 - 1.0) / (4.0 * p->eps);
}

/* At F = I, G = 0: Lap = phi0_RR + phi0_ZZ + phi0_R / r, the reference
 * densities, and the G-derivative of Lap (the c_I term of Eq. 4):
 * dLap/dG_nJK = -mult_JK phi0_n delta_JK, i.e. -p_n for G_nRR and G_nZZ and 0
 * for G_nRZ; dLap/dr = -p_R/r^2. With G != 0 (the map y = X + G:XX/2 at
 * X = 0): Lap = tr S - p_n (G_nRR + G_nZZ) + p_R / r. */
static void test_identity_state(void **state) {
  (void)state;
  uint64_t seed = 4242;
  for (int t = 0; t < 20; t++) {
    ves_model_local_par par = {EPS, t % 2 ? 1.5 : 0.0, 1.0, 10.0};
    ves_model_point pt;
    double q[NQ];
    random_state(&seed, q, &pt);
    double Gsave[6];
    memcpy(Gsave, q + 5, sizeof Gsave);
    q[1] = q[4] = 1.0;
    q[2] = q[3] = 0.0;
    memset(q + 5, 0, 6 * sizeof(double));
    const double r = q[0], *p = pt.dphi0, *S = pt.ddphi0;
    const double lap0 = S[0] + S[2] + p[0] / r;
    /* magnitude of the summed terms: the result is exact to a few ulp of it */
    const double mag = fabs(S[0]) + fabs(S[2]) + fabs(p[0] / r);
    double e, g[NQ], W, lap;
    assert_int_equal(ves_model_local_energy_ex(&par, &pt, q, &e, g, NULL, &W, &lap), VES_OK);
    assert_true(fabs(lap - lap0) <= 4e-16 * mag);
    const double W0 = par.eps * lap0 + c1_of(&par, pt.phi0);
    /* W = eps Lap + C1: Lap's few ulp of mag, C1's few ulp */
    const double C1 = c1_of(&par, pt.phi0);
    assert_true(fabs(W - W0) <= 2e-15 * (par.eps * mag + fabs(C1)));
    /* dE/dG = 2 W eps r dLap/dG at F = I (P = r); |p| <= 1/eps bounds the
       entries by |s|/eps, each a product of a few roundings */
    const double s = 2.0 * W * par.eps * r;
    const double dG[6] = {-p[0], 0.0, -p[0], -p[1], 0.0, -p[1]};
    for (int c = 0; c < 6; c++) assert_true(fabs(g[5 + c] - s * dG[c]) <= 1e-14 * fabs(s) / EPS);
    /* dE/dr = 2 W eps r dLap/dr + W^2 (dP/dr = det F = 1) */
    assert_true(fabs(g[0] - (s * (-p[0] / (r * r)) + W * W)) <=
                1e-14 * (fabs(s * p[0] / (r * r)) + W * W));

    double eA, eV;
    assert_int_equal(ves_model_local_area(&par, &pt, q, &eA, NULL, NULL), VES_OK);
    const double eA0 = (0.5 * par.eps * (p[0] * p[0] + p[1] * p[1]) + c2_of(&par, pt.phi0)) * r;
    assert_true(fabs(eA - eA0) <= 1e-15 * eA0);
    assert_int_equal(ves_model_local_volume(&par, &pt, q, &eV, NULL, NULL), VES_OK);
    assert_true(fabs(eV - 0.5 * (1.0 + pt.phi0) * r) <= 1e-16 * r);

    /* F = I with G: Lap = tr S - p_n tr G_n + p_R / r */
    memcpy(q + 5, Gsave, sizeof Gsave);
    assert_int_equal(ves_model_local_energy_ex(&par, &pt, q, &e, NULL, NULL, NULL, &lap), VES_OK);
    const double lapG = S[0] + S[2] - p[0] * (q[5] + q[7]) - p[1] * (q[8] + q[10]) + p[0] / r;
    const double magG =
        mag + fabs(p[0]) * (fabs(q[5]) + fabs(q[7])) + fabs(p[1]) * (fabs(q[8]) + fabs(q[10]));
    assert_true(fabs(lap - lapG) <= 1e-15 * magG);
  }
}

/* Uniform dilation y = s X about the axis (F = s I, G = 0, r = s R): H = I/s,
 * grad phi = grad phi0 / s, and every term of Lap carries two inverse lengths,
 * so Lap = lap0 / s^2 with lap0 = phi0_RR + phi0_ZZ + phi0_R / R; det F r =
 * s^3 R, hence e_V = s^3 e_V(R), e_A = [eps |p|^2 / (2 s^2) + C2] s^3 R and
 * e_E = (eps lap0 / s^2 + C1)^2 s^3 R. Compared to a few ulp. */
static void test_dilation(void **state) {
  (void)state;
  uint64_t seed = 999;
  for (int t = 0; t < 20; t++) {
    ves_model_local_par par = {EPS, t % 2 ? 1.5 : 0.0, 1.0, 10.0};
    ves_model_point pt;
    double q[NQ];
    random_state(&seed, q, &pt);
    const double sd = 0.5 + 1.5 * urand(&seed), R = q[0];
    q[0] = sd * R;
    q[1] = q[4] = sd;
    q[2] = q[3] = 0.0;
    memset(q + 5, 0, 6 * sizeof(double));
    const double *p = pt.dphi0, *S = pt.ddphi0;
    const double lap0 = S[0] + S[2] + p[0] / R;
    const double mag = (fabs(S[0]) + fabs(S[2]) + fabs(p[0] / R)) / (sd * sd);
    double e, W, lap, eA, eV;
    assert_int_equal(ves_model_local_energy_ex(&par, &pt, q, &e, NULL, NULL, &W, &lap), VES_OK);
    assert_true(fabs(lap - lap0 / (sd * sd)) <= 1e-15 * mag);
    const double W0 = par.eps * lap0 / (sd * sd) + c1_of(&par, pt.phi0);
    const double s3R = sd * sd * sd * R;
    /* e_E: W carries the rounding of Lap times eps plus C1's */
    const double dW = 1e-15 * (par.eps * mag + fabs(c1_of(&par, pt.phi0)));
    assert_true(fabs(e - W0 * W0 * s3R) <= 2.0 * fabs(W0) * dW * s3R + 1e-15 * W0 * W0 * s3R);
    assert_int_equal(ves_model_local_area(&par, &pt, q, &eA, NULL, NULL), VES_OK);
    const double eA0 =
        (0.5 * par.eps * (p[0] * p[0] + p[1] * p[1]) / (sd * sd) + c2_of(&par, pt.phi0)) * s3R;
    assert_true(fabs(eA - eA0) <= 1e-15 * eA0);
    assert_int_equal(ves_model_local_volume(&par, &pt, q, &eV, NULL, NULL), VES_OK);
    assert_true(fabs(eV - 0.5 * (1.0 + pt.phi0) * s3R) <= 1e-15 * s3R);
  }
}

/* Independent check of the formula for Lap itself (not only of its
 * derivatives): take the quadratic map y(X) = y0 + F X + G:XX/2 and the
 * quadratic phi0(X) = phi0 + p.X + X.S.X/2 around X = 0, push phi0 forward by
 * inverting y with Newton, and take the axisymmetric Laplacian of phi in (r, z)
 * by fourth-order central differences of step h = 1e-3: phi_rr + phi_zz +
 * phi_r / r. Measured: the error falls as h^4 (4.6e-4, 2.6e-5, 1.6e-6 at
 * h = 2e-2, 1e-2, 5e-3) to 2.5e-9 at h = 1e-3, where rounding is
 * O(1e-16 * 30/12 / h^2) ~ 3e-10; bound 1e-7 relative to the size of the
 * terms. A wrong sign or factor in c_I or the hoop term gives O(1). */
static double phi_at(const double F[4], const double G[6], const ves_model_point *pt,
                     const double y0[2], const double y[2]) {
  double X[2] = {0.0, 0.0};
  for (int it = 0; it < 50; it++) {
    double res[2], A[4];
    for (int n = 0; n < 2; n++) {
      const double *g = G + 3 * n;
      res[n] = y0[n] + F[2 * n] * X[0] + F[2 * n + 1] * X[1] +
               0.5 * (g[0] * X[0] * X[0] + 2.0 * g[1] * X[0] * X[1] + g[2] * X[1] * X[1]) - y[n];
      A[2 * n] = F[2 * n] + g[0] * X[0] + g[1] * X[1];
      A[2 * n + 1] = F[2 * n + 1] + g[1] * X[0] + g[2] * X[1];
    }
    const double dA = A[0] * A[3] - A[1] * A[2];
    const double dx0 = (A[3] * res[0] - A[1] * res[1]) / dA;
    const double dx1 = (-A[2] * res[0] + A[0] * res[1]) / dA;
    X[0] -= dx0;
    X[1] -= dx1;
    if (fabs(dx0) + fabs(dx1) < 1e-17) break;
  }
  const double *p = pt->dphi0, *S = pt->ddphi0;
  return pt->phi0 + p[0] * X[0] + p[1] * X[1] +
         0.5 * (S[0] * X[0] * X[0] + 2.0 * S[1] * X[0] * X[1] + S[2] * X[1] * X[1]);
}

static void test_lap_pushforward(void **state) {
  (void)state;
  uint64_t seed = 31337;
  double worst = 0.0;
  for (int t = 0; t < 20; t++) {
    double q[NQ];
    do {
      for (int a = 0; a < 4; a++) q[1 + a] = (a == 0 || a == 3 ? 1.0 : 0.0) + 0.4 * srand1(&seed);
    } while (q[1] * q[4] - q[2] * q[3] < 0.5);
    for (int c = 0; c < 6; c++) q[5 + c] = srand1(&seed);
    q[0] = 0.3 + urand(&seed);
    ves_model_point pt = {0.3 * srand1(&seed),
                          {srand1(&seed), srand1(&seed)},
                          {srand1(&seed), srand1(&seed), srand1(&seed)}};
    ves_model_local_par par = {EPS, 0.0, 1.0, 10.0};
    double e, lap;
    assert_int_equal(ves_model_local_energy_ex(&par, &pt, q, &e, NULL, NULL, NULL, &lap), VES_OK);
    const double y0[2] = {q[0], 0.1};
    const double h = 1e-3;
    /* fourth-order central stencils along r and z */
    double fr[5], fz[5];
    for (int i = 0; i < 5; i++) {
      const double yr[2] = {y0[0] + (i - 2) * h, y0[1]};
      const double yz[2] = {y0[0], y0[1] + (i - 2) * h};
      fr[i] = phi_at(q + 1, q + 5, &pt, y0, yr);
      fz[i] = phi_at(q + 1, q + 5, &pt, y0, yz);
    }
    const double prr =
        (-fr[4] + 16.0 * fr[3] - 30.0 * fr[2] + 16.0 * fr[1] - fr[0]) / (12.0 * h * h);
    const double pzz =
        (-fz[4] + 16.0 * fz[3] - 30.0 * fz[2] + 16.0 * fz[1] - fz[0]) / (12.0 * h * h);
    const double pr = (-fr[4] + 8.0 * fr[3] - 8.0 * fr[1] + fr[0]) / (12.0 * h);
    const double lapfd = prr + pzz + pr / q[0];
    const double mag = fabs(prr) + fabs(pzz) + fabs(pr / q[0]) + 1.0;
    worst = fmax(worst, fabs(lap - lapfd) / mag);
  }
  printf("  Lap vs FD Laplacian of the pushed-forward phi: %.2e\n", worst);
  assert_true(worst <= 1e-7);
}

/* Independent implementation of (1/2) qdot^T D qdot from the definitions of
 * Appendix A: L = Fdot F^-1, |d|^2 = |sym L|^2 + (rdot/r)^2,
 * div v = tr L + rdot/r, times r det F. */
static double diss_ref(const ves_model_local_par *par, const double q[NQ], const double qd[5]) {
  const double J = q[1] * q[4] - q[2] * q[3];
  const double Fi[2][2] = {{q[4] / J, -q[2] / J}, {-q[3] / J, q[1] / J}}; /* (F^-1)_Ij */
  const double Fd[2][2] = {{qd[1], qd[2]}, {qd[3], qd[4]}};
  double L[2][2];
  for (int i = 0; i < 2; i++)
    for (int j = 0; j < 2; j++) L[i][j] = Fd[i][0] * Fi[0][j] + Fd[i][1] * Fi[1][j];
  double d2 = 0.0;
  for (int i = 0; i < 2; i++)
    for (int j = 0; j < 2; j++) d2 += 0.25 * pow(L[i][j] + L[j][i], 2);
  const double s = qd[0] / q[0];
  d2 += s * s;
  const double dv = L[0][0] + L[1][1] + s;
  return (par->mu * d2 + 0.5 * par->lambda * dv * dv) * q[0] * J;
}

static double quad_form(const double D[25], const double x[5]) {
  double v = 0.0;
  for (int i = 0; i < 5; i++)
    for (int j = 0; j < 5; j++) v += x[i] * D[5 * i + j] * x[j];
  return 0.5 * v;
}

/* D: symmetric; equal to the second differences of the independent quadratic
 * form (exact for a quadratic at any step, so only rounding: 1e-12 of the
 * largest entry); positive semidefinite with exactly one null direction for
 * mu > 0, the local spin Fdot = Omega F, rdot = 0 (|sym L| = 0, div v = 0:
 * the 5 local rates are independent, so this direction cannot be excluded
 * locally; a rigid rotation of the whole body in the (r,z) plane is not a
 * null direction because it carries rdot = omega z != 0, checked below);
 * positive definite on the complement; translation gives zero; uniform
 * dilation gives |d|^2 = 3a^2 and div v = 3a. */
static void test_dissip(void **state) {
  (void)state;
  uint64_t seed = 555;
  double worst_fd = 0.0, worst_null = 0.0, min_pos = INFINITY;
  for (int t = 0; t < 40; t++) {
    ves_model_local_par par = {EPS, 0.0, 0.5 + urand(&seed),
                               t % 4 == 3 ? 0.0 : 100.0 * urand(&seed)};
    ves_model_point pt;
    double q[NQ], D[25];
    random_state(&seed, q, &pt);
    assert_int_equal(ves_model_local_dissip(&par, q, D), VES_OK);
    double dmax = 0.0;
    for (int i = 0; i < 25; i++) dmax = fmax(dmax, fabs(D[i]));
    for (int i = 0; i < 5; i++)
      for (int j = 0; j < 5; j++) assert_true(D[5 * i + j] == D[5 * j + i]);
    /* second differences of the reference quadratic form, step h_k = scale */
    const double sc[5] = {q[0], 1.0, 1.0, 1.0, 1.0};
    for (int i = 0; i < 5; i++)
      for (int j = 0; j < 5; j++) {
        double x[4][5] = {{0}};
        const double si[4] = {1, 1, -1, -1}, sj[4] = {1, -1, 1, -1};
        double v = 0.0;
        for (int c = 0; c < 4; c++) {
          x[c][i] += si[c] * sc[i];
          x[c][j] += sj[c] * sc[j];
          v += si[c] * sj[c] * diss_ref(&par, q, x[c]);
        }
        v /= 4.0 * sc[i] * sc[j];
        worst_fd = fmax(worst_fd, fabs(v - D[5 * i + j]) / dmax);
      }
    /* eigenvalues */
    double A[25], ev[5];
    memcpy(A, D, sizeof A);
    assert_int_equal(LAPACKE_dsyev(LAPACK_ROW_MAJOR, 'V', 'U', 5, A, 5, ev), 0);
    /* eigenvalue 0 is the spin: |ev[0]| at rounding of the largest */
    worst_null = fmax(worst_null, fabs(ev[0]) / ev[4]);
    assert_true(fabs(ev[0]) <= 1e-13 * ev[4]);
    const double spin[5] = {0.0, q[3], q[4], -q[1], -q[2]}; /* Omega F, Omega = [0 1; -1 0] */
    assert_true(fabs(quad_form(D, spin)) <=
                1e-13 * ev[4] * (q[1] * q[1] + q[2] * q[2] + q[3] * q[3] + q[4] * q[4]));
    if (par.lambda > 0.0) { /* lambda = 0 leaves only mu: still one null direction */
      min_pos = fmin(min_pos, ev[1] / ev[4]);
      assert_true(ev[1] > 1e-8 * ev[4]);
    } else {
      assert_true(ev[1] > 1e-8 * ev[4]);
    }
    /* Cholesky of D + spin spin^T (lifts the single null direction): PD */
    double C[25];
    memcpy(C, D, sizeof C);
    for (int i = 0; i < 5; i++)
      for (int j = 0; j < 5; j++) C[5 * i + j] += ev[4] * spin[i] * spin[j];
    assert_int_equal(LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'U', 5, C, 5), 0);

    const double J = q[1] * q[4] - q[2] * q[3], r = q[0];
    /* translation in z: no rates at all in the local variables */
    const double zero[5] = {0};
    assert_true(quad_form(D, zero) == 0.0);
    /* uniform dilation rate */
    const double a = srand1(&seed);
    const double dil[5] = {a * r, a * q[1], a * q[2], a * q[3], a * q[4]};
    const double vdil = (par.mu * 3.0 * a * a + 0.5 * par.lambda * 9.0 * a * a) * r * J;
    assert_true(fabs(quad_form(D, dil) - vdil) <= 1e-13 * vdil);
    /* rigid rotation v = omega (z, -r) seen at height z0: Fdot = omega Omega F,
       rdot = omega z0, so |d|^2 = (omega z0 / r)^2 = div v^2 */
    const double om = srand1(&seed), z0 = srand1(&seed);
    const double rot[5] = {om * z0, om * q[3], om * q[4], -om * q[1], -om * q[2]};
    const double s = om * z0 / r;
    const double vrot = (par.mu + 0.5 * par.lambda) * s * s * r * J;
    assert_true(fabs(quad_form(D, rot) - vrot) <= 1e-12 * (vrot + ev[4] * om * om));
    assert_true(quad_form(D, rot) > 0.0);
  }
  printf("  dissip: FD %.2e  null/max eig %.2e  min other/max eig %.2e\n", worst_fd, worst_null,
         min_pos);
  assert_true(worst_fd <= 1e-12);
}

/* det F <= 0, r <= 0 and NaNs are VES_ERR_DOMAIN, outputs untouched. */
static void test_domain_errors(void **state) {
  (void)state;
  ves_model_local_par par = {EPS, 1.5, 1.0, 10.0};
  ves_model_point pt = {0.2, {3.0, -1.0}, {10.0, 2.0, -5.0}};
  const double good[NQ] = {0.5, 1.0, 0.1, -0.2, 0.9, 1, 2, 3, 4, 5, 6};
  ves_model_local_fn *fns[3] = {ves_model_local_energy, ves_model_local_area,
                                ves_model_local_volume};
  for (int c = 0; c < 7; c++) {
    double q[NQ];
    memcpy(q, good, sizeof q);
    switch (c) {
    case 0:
      q[0] = 0.0;
      break; /* r = 0 (on the axis) */
    case 1:
      q[0] = -1e-3;
      break; /* r < 0 */
    case 2:
      q[1] = 0.1;
      q[4] = 0.2;
      q[2] = 0.1;
      q[3] = 0.2;
      break; /* det F = 0 */
    case 3:
      q[1] = -1.0;
      break; /* det F < 0 */
    case 4:
      q[0] = NAN;
      break;
    case 5:
      q[4] = NAN;
      break;
    case 6:
      q[2] = 1.0;
      q[3] = 1.0;
      q[1] = 0.5;
      q[4] = 0.5;
      break; /* det F = -0.75 */
    }
    for (int f = 0; f < 3; f++) {
      double e = 42.0, g[NQ], H[NQ * NQ];
      g[0] = 42.0;
      H[0] = 42.0;
      assert_int_equal(fns[f](&par, &pt, q, &e, g, H), VES_ERR_DOMAIN);
      assert_true(e == 42.0 && g[0] == 42.0 && H[0] == 42.0);
    }
    double D[25];
    D[0] = 42.0;
    assert_int_equal(ves_model_local_dissip(&par, q, D), VES_ERR_DOMAIN);
    assert_true(D[0] == 42.0);
    double e, W = 42.0, lap = 42.0;
    assert_int_equal(ves_model_local_energy_ex(&par, &pt, q, &e, NULL, NULL, &W, &lap),
                     VES_ERR_DOMAIN);
    assert_true(W == 42.0 && lap == 42.0);
  }
  double e;
  assert_int_equal(ves_model_local_energy(&par, &pt, good, &e, NULL, NULL), VES_OK);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_fd_energy),       cmocka_unit_test(test_fd_area),
      cmocka_unit_test(test_fd_volume),       cmocka_unit_test(test_optional_outputs),
      cmocka_unit_test(test_identity_state),  cmocka_unit_test(test_dilation),
      cmocka_unit_test(test_lap_pushforward), cmocka_unit_test(test_dissip),
      cmocka_unit_test(test_domain_errors),
  };
  // clang-format on
  return cmocka_run_group_tests(tests, NULL, NULL);
}
