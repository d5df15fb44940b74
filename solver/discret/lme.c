/* vesica — local max-ent (LME) basis functions, gradients, Hessians in 2D:
 * the dual Newton iteration for lambda(X) and the closed-form derivatives
 * below (docs/design.md, "Discretization"). */

/* Notation. X the evaluation point, X_a the m neighbours, d_a = X - X_a,
 * beta_a = gamma / h_a^2 with h_a supplied by the caller (the mean Delaunay
 * edge length at node a, computed by the geometry module).
 *
 *   f_a(X, lambda) = -beta_a |d_a|^2 + lambda . d_a,
 *   Z = sum_a exp(f_a),  p_a = exp(f_a) / Z.
 *
 * The dual. lambda(X) minimizes the convex log Z(lambda), whose gradient is
 * r = sum_a p_a d_a and Hessian J = sum_a p_a d_a (x) d_a - r (x) r (the
 * covariance of the d_a under p). At the minimum r = 0: sum_a p_a X_a = X.
 * Newton: dlambda = -J^{-1} r from the caller's guess (warm start) or 0.
 * Every evaluation uses the log-sum-exp shift exp(f_a - max_b f_b); r and J
 * are accumulated in long double and J in centred form sum p (d-r)(x)(d-r).
 * Safeguards: (i) if J is ill-conditioned (smallest eigenvalue below
 * LME_RCOND_REG times its trace) it is regularized to J + mu I, a
 * Levenberg step that turns into steepest descent when J vanishes;
 * (ii) the step is capped so that no exponent changes by more than
 * LME_STEP_CAP (|dlambda| max_a |d_a| <= LME_STEP_CAP); (iii) Armijo
 * backtracking on log Z (sufficient decrease 1e-4, halving). When the
 * predicted decrease -r.dlambda is below the rounding level of log Z the
 * Armijo test is meaningless; the step is then accepted if it does not
 * increase |r| (near the minimum Newton is quadratically convergent).
 * Convergence: |r| <= newton_tol * h_loc, h_loc = min_a sqrt(gamma / beta_a).
 * Iterations from lambda = 0: ~3-4 at interior points of a
 * perturbed lattice, 1 on a regular hex lattice; 1e-3 h from the hull ~11
 * (each step advances lambda . n by O(1/h) in the exponential tail).
 *
 * Failure modes. Fewer than 3 neighbours, NULL pointers, nder outside
 * {0,1,2}, non-positive beta or invalid parameters -> VES_ERR_ARG. All
 * neighbours collinear (the uniformly weighted covariance of the X_a is
 * singular) -> VES_ERR_ARG before any iteration. X strictly outside the
 * convex hull of the neighbours: lambda diverges; detected when
 * |lambda| max_a |d_a| exceeds LME_LAMBDA_MAX (legitimate points, even 1e-12 h
 * from the hull, stay below ~200) or the line search stalls
 * -> VES_ERR_NOCONV (after ~35 iterations). X on the hull (or
 * numerically on it): Newton may reach |r| <= tol with lambda -> infinity and J
 * singular in the normal direction; a converged J with smallest/largest
 * eigenvalue below LME_RCOND_MIN
 * -> VES_ERR_ARG. Iteration limit reached -> VES_ERR_NOCONV.
 *
 * Derivatives (node-wise beta; docs/design.md, "Discretization").
 * Implicit differentiation of r(X, lambda(X)) = 0 with dr/dX|_lambda =
 * I - J_beta (at r = 0) and dr/dlambda = J gives
 *   dlambda/dX = J^{-1} (J_beta - I),
 *   J_beta = 2 sum_b beta_b p_b d_b (x) d_b,  r_beta = 2 sum_b beta_b p_b d_b.
 * With v_a = J^{-1} d_a, M_a = 2 beta_a d_a - (J_beta - I) v_a and
 * g_a = r_beta - M_a (= grad log p_a):
 *   grad p_a = p_a g_a.
 * Differentiating g_a once more, using sum_b p_b d_b (x) g_b = -I (from
 * d r / dX = 0), sum_b p_b M_b = r_beta and sum_b p_b (d_a . v_b) M_b = v_a:
 *   grad g_a = (2 (sum_b beta_b p_b - beta_a) + r_beta . v_a) I
 *            - sum_b p_b (1 + d_a . v_b) M_b (x) M_b
 *            + r_beta (x) v_a + v_a (x) r_beta + r_beta (x) r_beta,
 *   Hess p_a = p_a [g_a (x) g_a + grad g_a],
 * (checked by finite differences in tests/test_lme.c). It is O(m): with d_a . v_b = v_a . d_b,
 *   sum_b p_b (1 + d_a . v_b) M_b (x) M_b = S + v_a,R T_R + v_a,Z T_Z,
 *   S = sum_b p_b M_b (x) M_b,  T_k = sum_b p_b d_b,k M_b (x) M_b,
 * so the sums over b are formed once and each node costs O(1).
 *
 * Precision. Near the hull (distance delta) the terms above are
 * O(1/(delta h)) and cancel to O(1/h^2). The derivative algebra is therefore
 * done in long double, with the weights renormalized (sum p = 1) and the d_a
 * re-centred on their p-mean (so sum p d = 0 and J = sum p d (x) d hold to
 * ~1e-19); in plain double the affine-reproduction error of the Hessians is
 * ~1e-10 at 1e-3 h from the hull, with this treatment ~1e-12. */
#include "ves/lme.h"

#include <float.h>
#include <math.h>
#include <stddef.h>

/* Levenberg regularization threshold: smallest eigenvalue of J relative to
 * its trace below which J + mu I (mu = LME_RCOND_REG tr J) is used. */
#define LME_RCOND_REG 1e-13
/* A converged J whose eigenvalue ratio is below this is declared singular
 * (X on the hull or a degenerate neighbourhood). At a distance delta from a
 * straight hull edge the ratio is ~0.8 delta/h, so points within
 * ~1e-10 h of the hull are rejected; exactly on it the ratio is ~1e-14.
 * Closer than ~1e-6 h the Hessians lose accuracy anyway (~1e-10 / h^2). */
#define LME_RCOND_MIN 1e-10
/* Largest change of any exponent f_a in one Newton step. */
#define LME_STEP_CAP 30.0
/* |lambda| max|d_a| beyond which lambda is considered divergent. */
#define LME_LAMBDA_MAX 1e3
/* Armijo sufficient-decrease constant and maximal number of halvings. */
#define LME_ARMIJO 1e-4
#define LME_MAX_HALVINGS 60

/* Neighbours whose derivative quantities are kept between the two passes
 * over them (ves_lme_eval; 144 bytes each on the stack); more are recomputed. */
#define LME_KEEP 256

/* Accumulators and the derivative algebra run in extended precision. */
typedef long double xreal;

/* Scratch layout in work (doubles): q[m] = -beta_a |d_a|^2, p[m], d[2m]. */
int ves_lme_work_size(int m) { return m > 0 ? 4 * m : 0; }

/* Defaults: gamma = 0.6 and tol0 = 1e-6, the same values as the problem
 * file's [geometry] gamma and support_tol (test_config checks that they
 * agree), newton_tol = 1e-14, max_iter = 100. */
void ves_lme_params_default(ves_lme_params *par) {
  if (!par) return;
  par->gamma = 0.6;
  par->tol0 = 1e-6;
  par->newton_tol = 1e-14;
  par->max_iter = 100;
}

/* r_a = h sqrt(-ln(tol0) / gamma): where beta_a |X - X_a|^2 = -ln tol0. */
double ves_lme_radius(const ves_lme_params *par, double h) {
  if (!par || !(par->gamma > 0) || !(par->tol0 > 0 && par->tol0 < 1)) return NAN;
  return h * sqrt(-log(par->tol0) / par->gamma);
}

/* Smallest/largest eigenvalue ratio of the symmetric PSD 2x2 [a b; b c]. */
static double sym2_rcond(double a, double b, double c) {
  double t = 0.5 * (a + c), s = hypot(0.5 * (a - c), b); /* eigen = t -+ s */
  if (!(t + s > 0)) return 0.0;
  double det = a * c - b * b;                  /* lmin lmax = det */
  double lmin = det > 0 ? det / (t + s) : 0.0; /* stable smallest eigenvalue */
  return lmin / (t + s);
}

/* log Z(lambda) with p_a, r = sum p_a d_a and J = sum p_a (d_a-r)(x)(d_a-r). */
static double lme_dual(int m, const double *q, const double *d, const double lam[2], double *p,
                       double r[2], xreal J[3]) {
  double fmax = -HUGE_VAL;
  for (int a = 0; a < m; a++) {
    p[a] = q[a] + lam[0] * d[2 * a] + lam[1] * d[2 * a + 1]; /* f_a */
    if (p[a] > fmax) fmax = p[a];
  }
  xreal Z = 0, r0 = 0, r1 = 0;
  for (int a = 0; a < m; a++) {
    p[a] = exp(p[a] - fmax); /* shifted weight, <= 1 */
    Z += p[a];
  }
  double iZ = (double)(1.0L / Z);
  for (int a = 0; a < m; a++) {
    p[a] *= iZ; /* p_a = w_a / Z */
    r0 += p[a] * (xreal)d[2 * a];
    r1 += p[a] * (xreal)d[2 * a + 1];
  }
  r[0] = (double)r0;
  r[1] = (double)r1;
  J[0] = J[1] = J[2] = 0;
  for (int a = 0; a < m; a++) {
    xreal e0 = d[2 * a] - r0, e1 = d[2 * a + 1] - r1; /* d_a - r */
    J[0] += p[a] * e0 * e0;
    J[1] += p[a] * e0 * e1;
    J[2] += p[a] * e1 * e1;
  }
  return fmax + (double)logl(Z); /* log Z = fmax + log sum exp(f - fmax) */
}

/* Newton for lambda: argmin log Z, safeguarded (see the file header). */
static ves_status lme_newton(const ves_lme_params *par, int m, const double *q, const double *d,
                             double dmax, double tol, double lam[2], double *p, double r[2],
                             xreal J[3], int *iters) {
  double lz = lme_dual(m, q, d, lam, p, r, J);
  double rn = hypot(r[0], r[1]);
  int it = 0;
  while (!(rn <= tol)) {
    if (it >= par->max_iter || !isfinite(lz)) break;
    double J0 = (double)J[0], J1 = (double)J[1], J2 = (double)J[2];
    double tr = J0 + J2;
    double mu = sym2_rcond(J0, J1, J2) < LME_RCOND_REG
                    ? LME_RCOND_REG * tr
                    : 0.0; /* Levenberg shift for an ill-conditioned J */
    double a = J0 + mu, b = J1, c = J2 + mu;
    double det = a * c - b * b;
    double s0 = -(c * r[0] - b * r[1]) / det; /* s = -(J + mu I)^{-1} r */
    double s1 = -(a * r[1] - b * r[0]) / det;
    if (!(det > 0) || !isfinite(s0) || !isfinite(s1)) {
      s0 = -r[0] / (dmax * dmax); /* steepest descent if J vanished */
      s1 = -r[1] / (dmax * dmax);
    }
    double sn = hypot(s0, s1) * dmax;
    if (sn > LME_STEP_CAP) { /* cap the change of any exponent */
      s0 *= LME_STEP_CAP / sn;
      s1 *= LME_STEP_CAP / sn;
    }
    double slope = r[0] * s0 + r[1] * s1;               /* d log Z along s, < 0 */
    double noise = 64 * DBL_EPSILON * (fabs(lz) + 1.0); /* rounding of log Z */
    double t = 1.0, lt[2], rt[2], lzt = lz;
    xreal Jt[3];
    int ok = 0;
    for (int k = 0; k < LME_MAX_HALVINGS; k++, t *= 0.5) {
      lt[0] = lam[0] + t * s0;
      lt[1] = lam[1] + t * s1;
      lzt = lme_dual(m, q, d, lt, p, rt, Jt);
      if (-t * slope <= noise) { /* below rounding: accept if |r| not up */
        ok = hypot(rt[0], rt[1]) <= rn;
        break;
      }
      if (lzt <= lz + LME_ARMIJO * t * slope) { /* Armijo */
        ok = 1;
        break;
      }
    }
    if (!ok) { /* line search stalled: restore p, r, J at lam and stop */
      lz = lme_dual(m, q, d, lam, p, r, J);
      break;
    }
    lam[0] = lt[0];
    lam[1] = lt[1];
    lz = lzt;
    r[0] = rt[0];
    r[1] = rt[1];
    J[0] = Jt[0];
    J[1] = Jt[1];
    J[2] = Jt[2];
    rn = hypot(r[0], r[1]);
    it++;
    if (hypot(lam[0], lam[1]) * dmax > LME_LAMBDA_MAX) break; /* diverging */
  }
  *iters = it;
  return rn <= tol ? VES_OK : VES_ERR_NOCONV;
}

/* Moments shared by all nodes in the derivative pass (extended precision). */
typedef struct {
  xreal ip;    /* 1 / sum_b p_b */
  xreal c[2];  /* sum_b P_b d_b (the Newton residual r) */
  xreal Ji[3]; /* J^{-1}: (RR, RZ, ZZ) */
  xreal rb[2]; /* r_beta = 2 sum_b beta_b P_b e_b */
  xreal B[3];  /* J_beta - I: (RR, RZ, ZZ) */
} lme_moments;

/* Per-node quantities of the derivative formulas. */
typedef struct {
  xreal P;    /* p_a, renormalized */
  xreal e[2]; /* e_a = d_a - r */
  xreal v[2]; /* v_a = J^{-1} e_a */
  xreal M[2]; /* M_a = 2 beta_a e_a - (J_beta - I) v_a */
  xreal g[2]; /* g_a = r_beta - M_a = grad log p_a */
} lme_node;

/* v_a = J^{-1} e_a, M_a = 2 beta_a e_a - (J_beta - I) v_a, g_a = r_beta - M_a,
 * in extended precision: kept between the two derivative passes in a stack
 * buffer of LME_KEEP nodes (the caller's work holds doubles only), recomputed
 * beyond it. */
static void lme_node_eval(const lme_moments *mo, double p, const double d[2], double beta,
                          lme_node *n) {
  n->P = p * mo->ip;
  n->e[0] = d[0] - mo->c[0];
  n->e[1] = d[1] - mo->c[1];
  n->v[0] = mo->Ji[0] * n->e[0] + mo->Ji[1] * n->e[1];
  n->v[1] = mo->Ji[1] * n->e[0] + mo->Ji[2] * n->e[1];
  n->M[0] = 2 * (xreal)beta * n->e[0] - (mo->B[0] * n->v[0] + mo->B[1] * n->v[1]);
  n->M[1] = 2 * (xreal)beta * n->e[1] - (mo->B[1] * n->v[0] + mo->B[2] * n->v[1]);
  n->g[0] = mo->rb[0] - n->M[0];
  n->g[1] = mo->rb[1] - n->M[1];
}

/* The offsets d_a = X - X_a and q_a = -beta_a |d_a|^2 (d[2m], q[m]), with
 * *dmax = max |d_a| and *bmax = max beta_a; VES_ERR_ARG for a non-finite
 * offset or beta_a <= 0, neighbours that all coincide with X, or collinear
 * ones (no 2D hull: the uniform covariance of the X_a singular). */
static ves_status lme_offsets(const double X[2], int m, const double *xa, const double *beta,
                              double *q, double *d, double *dmax_out, double *bmax_out) {
  /* d_a = X - X_a, q_a = -beta_a |d_a|^2; moments of the X_a. */
  double bmax = 0.0, dmax = 0.0, m0 = 0, m1 = 0;
  for (int a = 0; a < m; a++) {
    VES_CHECK(beta[a] > 0 && isfinite(beta[a]), VES_ERR_ARG);
    d[2 * a] = X[0] - xa[2 * a];
    d[2 * a + 1] = X[1] - xa[2 * a + 1];
    VES_CHECK(isfinite(d[2 * a]) && isfinite(d[2 * a + 1]), VES_ERR_ARG);
    double dd = d[2 * a] * d[2 * a] + d[2 * a + 1] * d[2 * a + 1];
    q[a] = -beta[a] * dd;
    if (beta[a] > bmax) bmax = beta[a];
    if (dd > dmax) dmax = dd;
    m0 += d[2 * a];
    m1 += d[2 * a + 1];
  }
  dmax = sqrt(dmax);
  VES_CHECK(dmax > 0, VES_ERR_ARG); /* all neighbours coincide with X */
  m0 /= m;                          /* uniform mean of the d_a */
  m1 /= m;
  double u00 = 0, u01 = 0, u11 = 0; /* uniform covariance of the X_a */
  for (int a = 0; a < m; a++) {
    double e0 = d[2 * a] - m0, e1 = d[2 * a + 1] - m1;
    u00 += e0 * e0;
    u01 += e0 * e1;
    u11 += e1 * e1;
  }
  VES_CHECK(sym2_rcond(u00, u01, u11) > 1e3 * DBL_EPSILON,
            VES_ERR_ARG); /* collinear neighbours: no 2D hull */
  *dmax_out = dmax, *bmax_out = bmax;
  return VES_OK;
}

/* Rows 1-2 (nder >= 1: grad p_a = p_a g_a) and 3-5 (nder = 2: Hess p_a =
 * p_a [g_a g_a^T + grad g_a]) of tab from the unnormalized weights p (sum
 * 1/ip) and the centre c = sum P d of the normalized ones (extended
 * precision, see ves_lme_eval). */
static void lme_derivatives(int m, const double *p, const double *d, const double *beta, xreal ip,
                            xreal c0, xreal c1, int nder, double *tab) {
  lme_moments mo = {.ip = ip, .c = {c0, c1}};
  xreal j00 = 0, j01 = 0, j11 = 0, jb00 = 0, jb01 = 0, jb11 = 0, sb = 0;
  for (int a = 0; a < m; a++) {
    xreal P = p[a] * ip, e0 = d[2 * a] - c0, e1 = d[2 * a + 1] - c1;
    xreal bp = (xreal)beta[a] * P;
    j00 += P * e0 * e0; /* J = sum P e (x) e */
    j01 += P * e0 * e1;
    j11 += P * e1 * e1;
    sb += bp;            /* sum beta P */
    mo.rb[0] += bp * e0; /* r_beta / 2 */
    mo.rb[1] += bp * e1;
    jb00 += bp * e0 * e0; /* J_beta / 2 */
    jb01 += bp * e0 * e1;
    jb11 += bp * e1 * e1;
  }
  xreal det = j00 * j11 - j01 * j01;
  mo.Ji[0] = j11 / det; /* J^{-1} */
  mo.Ji[1] = -j01 / det;
  mo.Ji[2] = j00 / det;
  mo.rb[0] *= 2; /* r_beta */
  mo.rb[1] *= 2;
  mo.B[0] = 2 * jb00 - 1; /* J_beta - I */
  mo.B[1] = 2 * jb01;
  mo.B[2] = 2 * jb11 - 1;

  /* The node quantities of this pass are kept (on the stack, in extended
   * precision) for the Hessian pass when m <= LME_KEEP, else recomputed; the
   * sums S, T_R, T_Z run in scalars, which the compiler can hold in registers
   * (the same operations in the same order either way). */
  lme_node keep[LME_KEEP], tmp;
  xreal S0 = 0, S1 = 0, S2 = 0, TR0 = 0, TR1 = 0, TR2 = 0, TZ0 = 0, TZ1 = 0, TZ2 = 0;
  for (int a = 0; a < m; a++) {
    lme_node *n = m <= LME_KEEP ? keep + a : &tmp;
    lme_node_eval(&mo, p[a], d + 2 * a, beta[a], n);
    tab[m + a] = (double)(n->P * n->g[0]);     /* dp/dR = p g_R */
    tab[2 * m + a] = (double)(n->P * n->g[1]); /* dp/dZ = p g_Z */
    if (nder < 2) continue;
    const xreal pm0 = n->P * n->M[0] * n->M[0], pm1 = n->P * n->M[0] * n->M[1],
                pm2 = n->P * n->M[1] * n->M[1]; /* p M (x) M */
    S0 += pm0;                                  /* S = sum p M (x) M */
    TR0 += pm0 * n->e[0];                       /* T_R = sum p e_R M (x) M */
    TZ0 += pm0 * n->e[1];                       /* T_Z = sum p e_Z M (x) M */
    S1 += pm1;
    TR1 += pm1 * n->e[0];
    TZ1 += pm1 * n->e[1];
    S2 += pm2;
    TR2 += pm2 * n->e[0];
    TZ2 += pm2 * n->e[1];
  }
  if (nder < 2) return;

  const xreal rb0 = mo.rb[0], rb1 = mo.rb[1], rb0x2 = 2 * rb0, rb1x2 = 2 * rb1;
  const xreal rr00 = rb0 * rb0, rr01 = rb0 * rb1, rr11 = rb1 * rb1; /* r_b r_b^T */
  for (int a = 0; a < m; a++) {
    const lme_node *n = m <= LME_KEEP ? keep + a : &tmp;
    if (m > LME_KEEP) lme_node_eval(&mo, p[a], d + 2 * a, beta[a], &tmp);
    const xreal *v = n->v, *g = n->g;
    xreal dI = 2 * (sb - beta[a]) + rb0 * v[0] + rb1 * v[1]; /* I coeff. */
    /* grad g_a = dI I - (S + v_R T_R + v_Z T_Z) + r_b v^T + v r_b^T + r_b r_b^T
     */
    xreal h00 = dI - (S0 + v[0] * TR0 + v[1] * TZ0) + rb0x2 * v[0] + rr00;
    xreal h01 = -(S1 + v[0] * TR1 + v[1] * TZ1) + rb0 * v[1] + v[0] * rb1 + rr01;
    xreal h11 = dI - (S2 + v[0] * TR2 + v[1] * TZ2) + rb1x2 * v[1] + rr11;
    tab[3 * m + a] = (double)(n->P * (g[0] * g[0] + h00)); /* d2p/dR2 */
    tab[4 * m + a] = (double)(n->P * (g[0] * g[1] + h01)); /* d2p/dRdZ */
    tab[5 * m + a] = (double)(n->P * (g[1] * g[1] + h11)); /* d2p/dZ2 */
  }
}

/* p_a, grad p_a = p_a g_a and Hess p_a = p_a [g_a g_a^T + grad g_a] at X. */
ves_status ves_lme_eval(const ves_lme_params *par, const double X[2], int m, const double *xa,
                        const double *beta, double lambda[2], int nder, double *tab, double *work,
                        ves_lme_info *info) {
  VES_CHECK(par && X && xa && beta && lambda && tab && work, VES_ERR_ARG);
  VES_CHECK(m >= 3 && nder >= 0 && nder <= 2, VES_ERR_ARG);
  VES_CHECK(par->gamma > 0 && par->newton_tol > 0 && par->max_iter >= 1, VES_ERR_ARG);
  VES_CHECK(isfinite(X[0]) && isfinite(X[1]), VES_ERR_ARG);
  if (!(isfinite(lambda[0]) && isfinite(lambda[1])))
    lambda[0] = lambda[1] = 0.0; /* a useless guess is replaced by 0 */
  double *q = work, *p = work + m, *d = work + 2 * m;
  double dmax = 0, bmax = 0;
  VES_CALL(lme_offsets(X, m, xa, beta, q, d, &dmax, &bmax));

  double hloc = sqrt(par->gamma / bmax); /* h_loc = min_a sqrt(gamma/beta_a) */
  double r[2];
  xreal Jx[3];
  int iters = 0;
  const int warm = lambda[0] != 0.0 || lambda[1] != 0.0;
  ves_status st = lme_newton(par, m, q, d, dmax, par->newton_tol * hloc, lambda, p, r, Jx, &iters);
  if (st == VES_ERR_NOCONV && warm) {
    /* a guess from another point can start far out (|lambda| dmax above
     * LME_LAMBDA_MAX at once, as at a node set made by a reset, where the
     * previous point is unrelated): again from lambda = 0 */
    int more = 0;
    lambda[0] = lambda[1] = 0.0;
    st = lme_newton(par, m, q, d, dmax, par->newton_tol * hloc, lambda, p, r, Jx, &more);
    iters += more;
  }
  if (info) {
    info->iterations = iters;
    info->residual = hypot(r[0], r[1]);
  }
  if (st != VES_OK) return st;
  double rc = sym2_rcond((double)Jx[0], (double)Jx[1], (double)Jx[2]);
  VES_CHECK(rc >= LME_RCOND_MIN, VES_ERR_ARG); /* X (numerically) on the hull */

  /* The derivative algebra below uses, in extended precision, the weights
   * P_a = p_a / sum_b p_b and the centred offsets e_a = d_a - sum_b P_b d_b,
   * so that sum P = 1, sum P e = 0 and J = sum P e (x) e hold to ~1e-19
   * relative. The formulas assume exactly these identities; near the hull
   * (distance delta) their terms are O(1/(delta h)) and cancel to O(1/h^2),
   * so the Newton residual r (<= newton_tol h) or a normalization error of
   * 1e-16 would otherwise be amplified by h/delta to 1e-10 and worse. The
   * shift of d by r changes the derivatives only at the level to which
   * lambda is known anyway (|J^{-1} r|). */
  xreal sp = 0, c0 = 0, c1 = 0;
  for (int a = 0; a < m; a++) {
    sp += p[a];                   /* sum p (1 up to rounding) */
    c0 += p[a] * (xreal)d[2 * a]; /* sum p d = r */
    c1 += p[a] * (xreal)d[2 * a + 1];
  }
  xreal ip = 1 / sp;
  c0 *= ip;
  c1 *= ip;
  for (int a = 0; a < m; a++) tab[a] = (double)(p[a] * ip); /* row 0: p_a */
  if (nder == 0) return VES_OK;

  lme_derivatives(m, p, d, beta, ip, c0, c1, nder, tab);
  return VES_OK;
}
