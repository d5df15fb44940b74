/* vesica — tests of the LME basis: consistency, derivatives, axis, errors. */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ves/lme.h"

/* A node set: n nodes at x[2a], x[2a+1] with local spacing h[a]. */
typedef struct {
  int n;
  double *x;
  double *h;
} nodeset;

/* A neighbourhood of an evaluation point, gathered by brute force. */
typedef struct {
  int m;
  double xa[2 * 512];
  double beta[512];
  double f[512]; /* nodal values of a test field (ghost test) */
  double tab[6 * 512];
  double work[4 * 512];
} hood;

/* Deterministic uniform numbers in [0, 1) (xorshift64*). */
static double urand(uint64_t *s) {
  *s ^= *s >> 12;
  *s ^= *s << 25;
  *s ^= *s >> 27;
  return (double)((*s * 2685821657736338717ULL) >> 11) * 0x1.0p-53;
}

static void nodeset_add(nodeset *ns, double R, double Z, double h) {
  ns->x[2 * ns->n] = R;
  ns->x[2 * ns->n + 1] = Z;
  ns->h[ns->n] = h;
  ns->n++;
}

static void nodeset_alloc(nodeset *ns, int cap) {
  ns->n = 0;
  ns->x = malloc(2 * (size_t)cap * sizeof(double));
  ns->h = malloc((size_t)cap * sizeof(double));
  assert_non_null(ns->x);
  assert_non_null(ns->h);
}

static void nodeset_free(nodeset *ns) {
  free(ns->x);
  free(ns->h);
}

/* Hex lattice of spacing h, columns at R = k (sqrt3/2) h (k = -K..K), rows at
 * Z = j h (+ h/2 on odd columns), |Z| <= L: mirror-symmetric about R = 0 with
 * a column of nodes on the axis (docs/design.md, "Discretization"). */
static void hex_lattice(nodeset *ns, double h, int K, double L) {
  nodeset_alloc(ns, (2 * K + 1) * (int)(2 * L / h + 3));
  for (int k = -K; k <= K; k++) {
    double R = k * (sqrt(3.0) / 2) * h, off = (abs(k) % 2) ? 0.5 * h : 0.0;
    for (int j = -(int)(L / h) - 1; j <= (int)(L / h) + 1; j++) {
      double Z = j * h + off;
      if (fabs(Z) <= L) nodeset_add(ns, R, Z, h);
    }
  }
}

/* Local spacing of the graded set: h(R) = ln3/(2n) (1 + 2R), 0.034 .. 0.103
 * for n = 16 (a factor 3 across the box). */
static double graded_h(double R, int n) { return log(3.0) / (2.0 * n) * (1 + 2 * R); }

/* Graded, randomly perturbed node set in the box [0,1]^2: columns at
 * R_i = (3^{i/n} - 1)/2, in each column Z_j = j/n_i with n_i = round(1/h);
 * interior nodes perturbed by up to 0.15 h in both directions, edge nodes
 * along their edge only, corners fixed, so the hull is exactly the box. */
static void graded_box(nodeset *ns, int n, uint64_t seed) {
  nodeset_alloc(ns, 4 * n * n * 4);
  for (int i = 0; i <= n; i++) {
    double R = 0.5 * (pow(3.0, (double)i / n) - 1.0);
    if (i == n) R = 1.0;
    int ni = (int)lround(1.0 / graded_h(R, n));
    for (int j = 0; j <= ni; j++) {
      double Z = (double)j / ni, hR = graded_h(R, n), Ra = R, Za = Z;
      int edgeR = (i == 0 || i == n), edgeZ = (j == 0 || j == ni);
      double u1 = 2 * urand(&seed) - 1, u2 = 2 * urand(&seed) - 1;
      if (!edgeR) Ra += 0.15 * hR * u1;
      if (!edgeZ) Za += 0.15 * hR * u2;
      nodeset_add(ns, Ra, Za, graded_h(Ra, n));
    }
  }
}

/* Gather the nodes whose support (radius ves_lme_radius(h_a)) contains X. */
static void gather(const nodeset *ns, const ves_lme_params *par, const double X[2], hood *H,
                   const double *fnode) {
  H->m = 0;
  for (int a = 0; a < ns->n; a++) {
    double dR = X[0] - ns->x[2 * a], dZ = X[1] - ns->x[2 * a + 1];
    double ra = ves_lme_radius(par, ns->h[a]);
    if (dR * dR + dZ * dZ > ra * ra) continue;
    assert_true(H->m < 512);
    H->xa[2 * H->m] = ns->x[2 * a];
    H->xa[2 * H->m + 1] = ns->x[2 * a + 1];
    H->beta[H->m] = par->gamma / (ns->h[a] * ns->h[a]);
    H->f[H->m] = fnode ? fnode[a] : 0.0;
    H->m++;
  }
}

/* Worst consistency errors over a set of points. */
typedef struct {
  double pu[3];  /* |sum p - 1|, |sum grad p|, |sum Hess p| */
  double rep[3]; /* |sum p X_a - X|, |sum grad p (x) X_a - I|,
                    |sum Hess p X_a| */
  double pmin;   /* smallest p_a */
  int it_max, npts;
  double it_sum;
} consist;

static void consist_init(consist *c) {
  memset(c, 0, sizeof *c);
  c->pmin = 1.0;
}

static double maxd(double a, double b) { return a > b ? a : b; }

/* Evaluate at X (nder = 2, lambda from 0) and fold the errors into c. The
 * sums are accumulated in long double so that they measure the basis, not
 * the summation in the test. */
static void check_point(const ves_lme_params *par, const nodeset *ns, const double X[2], hood *H,
                        consist *c) {
  gather(ns, par, X, H, NULL);
  double lam[2] = {0, 0};
  ves_lme_info info;
  ves_status st = ves_lme_eval(par, X, H->m, H->xa, H->beta, lam, 2, H->tab, H->work, &info);
  if (st != VES_OK)
    print_error("point (%.17g, %.17g): m = %d, status %s, it %d, |r| %g\n", X[0], X[1], H->m,
                ves_status_str(st), info.iterations, info.residual);
  assert_int_equal(st, VES_OK);
  int m = H->m;
  long double s[6] = {0}, x[2] = {0}, gx[4] = {0}, hx[6] = {0};
  for (int a = 0; a < m; a++) {
    long double Ra = H->xa[2 * a], Za = H->xa[2 * a + 1];
    for (int k = 0; k < 6; k++) s[k] += H->tab[k * m + a];
    x[0] += H->tab[a] * Ra;
    x[1] += H->tab[a] * Za;
    gx[0] += H->tab[m + a] * Ra;     /* d/dR sum p R_a = 1 */
    gx[1] += H->tab[m + a] * Za;     /* d/dR sum p Z_a = 0 */
    gx[2] += H->tab[2 * m + a] * Ra; /* d/dZ sum p R_a = 0 */
    gx[3] += H->tab[2 * m + a] * Za; /* d/dZ sum p Z_a = 1 */
    for (int k = 0; k < 3; k++) {
      hx[k] += H->tab[(3 + k) * m + a] * Ra;
      hx[3 + k] += H->tab[(3 + k) * m + a] * Za;
    }
    if (H->tab[a] < c->pmin) c->pmin = H->tab[a];
  }
  c->pu[0] = maxd(c->pu[0], fabsl(s[0] - 1));
  c->pu[1] = maxd(c->pu[1], maxd(fabsl(s[1]), fabsl(s[2])));
  c->pu[2] = maxd(c->pu[2], maxd(fabsl(s[3]), maxd(fabsl(s[4]), fabsl(s[5]))));
  c->rep[0] = maxd(c->rep[0], maxd(fabsl(x[0] - X[0]), fabsl(x[1] - X[1])));
  c->rep[1] = maxd(
      c->rep[1], maxd(maxd(fabsl(gx[0] - 1), fabsl(gx[1])), maxd(fabsl(gx[2]), fabsl(gx[3] - 1))));
  for (int k = 0; k < 6; k++) c->rep[2] = maxd(c->rep[2], fabsl(hx[k]));
  if (info.iterations > c->it_max) c->it_max = info.iterations;
  c->it_sum += info.iterations;
  c->npts++;
}

static void consist_report(const char *what, const consist *c) {
  printf("  %-26s pts %3d  PU %.1e %.1e %.1e  affine %.1e %.1e %.1e  "
         "Newton mean %.2f max %d\n",
         what, c->npts, c->pu[0], c->pu[1], c->pu[2], c->rep[0], c->rep[1], c->rep[2],
         c->it_sum / c->npts, c->it_max);
}

/* Partition of unity and affine reproduction (values, gradients, Hessians):
 * the dual is solved to |r| <= 1e-14 h, so the value identities hold to
 * ~1e-16; the derivative identities are algebraic consequences of r = 0 and
 * of J = sum p d d^T evaluated with the same p, so they hold to rounding
 * amplified by cond(J) (<= ~1e3 at 1e-3 h from the hull) times the entry
 * size (|Hess p| ~ 1/h^2 ~ 1e3): ~1e-12. 1e-10 (absolute, coordinates O(1))
 * leaves a margin of ~100 while still catching any O(h) formula error. */
static void assert_consist(const consist *c) {
  for (int k = 0; k < 3; k++) {
    assert_true(c->pu[k] <= 1e-10);
    assert_true(c->rep[k] <= 1e-10);
  }
  assert_true(c->pmin >= 0.0); /* p_a = exp(.)/Z >= 0 by construction */
}

/* The defaults with the paper's gamma = 0.8, the value these tests' bounds
 * are set for (the default is the problem file's 0.6). */
static void paper_params(ves_lme_params *par) {
  ves_lme_params_default(par);
  par->gamma = 0.8;
}

static void test_params(void **state) {
  (void)state;
  ves_lme_params par;
  ves_lme_params_default(&par);
  /* the problem file's [geometry] gamma and support_tol (test_config checks
   * the two agree for every key) */
  assert_true(par.gamma == 0.6 && par.tol0 == 1e-6);
  assert_true(par.newton_tol == 1e-14 && par.max_iter == 100);
  /* r = h sqrt(ln(1e6)/0.6) = 4.7985...h; exact formula, so 1e-15 relative */
  assert_true(fabs(ves_lme_radius(&par, 2.0) - 2.0 * sqrt(log(1e6) / 0.6)) <= 1e-15 * 10.0);
  assert_true(ves_lme_work_size(70) >= 4 * 70); /* q, p, d[2] per node */
  assert_int_equal(ves_lme_work_size(0), 0);
}

static void test_consistency_hex(void **state) {
  (void)state;
  ves_lme_params par;
  paper_params(&par);
  nodeset ns;
  hex_lattice(&ns, 0.1, 14, 1.0);
  hood *H = malloc(sizeof *H);
  assert_non_null(H);
  consist c;
  consist_init(&c);
  uint64_t seed = 12345;
  int msum = 0;
  for (int k = 0; k < 200; k++) {
    double X[2] = {-0.5 + urand(&seed), -0.5 + urand(&seed)};
    check_point(&par, &ns, X, H, &c);
    msum += H->m;
  }
  printf("  hex lattice h = 0.1: mean m = %.1f\n", (double)msum / 200);
  consist_report("hex interior", &c);
  assert_consist(&c);
  /* docs/design.md, "Discretization": ~3 Newton iterations (<= 6) at interior points; 10 allows
   * for the points that fall close to a node. */
  assert_true(c.it_max <= 10);
  free(H);
  nodeset_free(&ns);
}

/* Wide supports (gamma = 0.15: m ~ 330 neighbours, more than ves_lme_eval
 * keeps between its passes, so the node quantities are recomputed): the same
 * consistency as with the default supports. */
static void test_consistency_wide(void **state) {
  (void)state;
  ves_lme_params par;
  paper_params(&par);
  par.gamma = 0.15;
  nodeset ns;
  hex_lattice(&ns, 0.1, 22, 1.6);
  hood *H = malloc(sizeof *H);
  assert_non_null(H);
  consist c;
  consist_init(&c);
  uint64_t seed = 321;
  int mmin = 512;
  for (int k = 0; k < 40; k++) {
    double X[2] = {-0.3 + 0.6 * urand(&seed), -0.3 + 0.6 * urand(&seed)};
    check_point(&par, &ns, X, H, &c);
    if (H->m < mmin) mmin = H->m;
  }
  printf("  hex lattice h = 0.1, gamma 0.15: m >= %d\n", mmin);
  consist_report("hex wide", &c);
  assert_true(mmin > 256);
  assert_consist(&c);
  free(H);
  nodeset_free(&ns);
}

static void test_consistency_graded(void **state) {
  (void)state;
  ves_lme_params par;
  paper_params(&par);
  const int n = 16;
  nodeset ns;
  graded_box(&ns, n, 777);
  hood *H = malloc(sizeof *H);
  assert_non_null(H);
  uint64_t seed = 4242;

  consist ci;
  consist_init(&ci);
  for (int k = 0; k < 300; k++) { /* interior: [0.15, 0.85]^2 */
    double X[2] = {0.15 + 0.7 * urand(&seed), 0.15 + 0.7 * urand(&seed)};
    check_point(&par, &ns, X, H, &ci);
  }
  consist_report("graded interior", &ci);
  assert_consist(&ci);
  assert_true(ci.it_max <= 10); /* as in the hex test */

  /* Within 1e-3 h of each of the four edges (h the local spacing). */
  consist cb;
  consist_init(&cb);
  for (int k = 0; k < 60; k++) {
    double t = 0.05 + 0.9 * urand(&seed), X[2];
    switch (k % 4) {
    case 0:
      X[0] = t, X[1] = 1e-3 * graded_h(t, n);
      break;
    case 1:
      X[0] = t, X[1] = 1 - 1e-3 * graded_h(t, n);
      break;
    case 2:
      X[0] = 1e-3 * graded_h(0, n), X[1] = t;
      break;
    default:
      X[0] = 1 - 1e-3 * graded_h(1, n), X[1] = t;
      break;
    }
    check_point(&par, &ns, X, H, &cb);
  }
  consist_report("graded 1e-3 h from edges", &cb);
  assert_consist(&cb);

  /* Near the four corners: 1e-3 h from both edges, and 1e-3 h from one edge
   * and 0.3 h from the other. */
  consist cc;
  consist_init(&cc);
  for (int k = 0; k < 4; k++) {
    double cR = k & 1, cZ = (k >> 1) & 1, h = graded_h(cR, n);
    double sR = cR ? -1 : 1, sZ = cZ ? -1 : 1;
    double X1[2] = {cR + sR * 1e-3 * h, cZ + sZ * 1e-3 * h};
    double X2[2] = {cR + sR * 1e-3 * h, cZ + sZ * 0.3 * h};
    double X3[2] = {cR + sR * 0.3 * h, cZ + sZ * 1e-3 * h};
    check_point(&par, &ns, X1, H, &cc);
    check_point(&par, &ns, X2, H, &cc);
    check_point(&par, &ns, X3, H, &cc);
  }
  consist_report("graded near corners", &cc);
  assert_consist(&cc);
  free(H);
  nodeset_free(&ns);
}

/* Relative error in the max norm over the neighbours:
 * max_a |fd_a - an_a| / max_a |an_a|. */
static double relerr(int m, const double *fd, const double *an) {
  double e = 0, s = 0;
  for (int a = 0; a < m; a++) {
    e = maxd(e, fabs(fd[a] - an[a]));
    s = maxd(s, fabs(an[a]));
  }
  return e / s;
}

/* Gradients and Hessians against central differences of p and grad p with
 * the neighbour set (and node-wise beta) held fixed. */
static double fd_check(const ves_lme_params *par, const nodeset *ns, const double X[2], double step,
                       hood *H) {
  gather(ns, par, X, H, NULL);
  int m = H->m;
  double *an = malloc(6 * (size_t)m * sizeof(double));
  double *tp = malloc(6 * (size_t)m * sizeof(double));
  double *tm = malloc(6 * (size_t)m * sizeof(double));
  double *fd = malloc((size_t)m * sizeof(double));
  assert_true(an && tp && tm && fd);
  double lam[2] = {0, 0};
  assert_int_equal(ves_lme_eval(par, X, m, H->xa, H->beta, lam, 2, an, H->work, NULL), VES_OK);
  double worst = 0;
  for (int k = 0; k < 2; k++) {
    double Xp[2] = {X[0], X[1]}, Xm[2] = {X[0], X[1]};
    Xp[k] += step;
    Xm[k] -= step;
    double lp[2] = {lam[0], lam[1]}, lm[2] = {lam[0], lam[1]};
    assert_int_equal(ves_lme_eval(par, Xp, m, H->xa, H->beta, lp, 1, tp, H->work, NULL), VES_OK);
    assert_int_equal(ves_lme_eval(par, Xm, m, H->xa, H->beta, lm, 1, tm, H->work, NULL), VES_OK);
    /* grad p, component k */
    for (int a = 0; a < m; a++) fd[a] = (tp[a] - tm[a]) / (2 * step);
    worst = maxd(worst, relerr(m, fd, an + (1 + k) * m));
    /* d/dX_k of dp/dR and of dp/dZ: rows (RR, RZ) for k = 0, (RZ, ZZ) k = 1 */
    for (int l = 0; l < 2; l++) {
      for (int a = 0; a < m; a++) fd[a] = (tp[(1 + l) * m + a] - tm[(1 + l) * m + a]) / (2 * step);
      worst = maxd(worst, relerr(m, fd, an + (3 + k + l) * m));
    }
  }
  free(an);
  free(tp);
  free(tm);
  free(fd);
  return worst;
}

static void test_derivatives_fd(void **state) {
  (void)state;
  ves_lme_params par;
  paper_params(&par);
  const int n = 16;
  nodeset ns;
  graded_box(&ns, n, 99);
  hood *H = malloc(sizeof *H);
  assert_non_null(H);
  uint64_t seed = 2024;
  double wi = 0, wb = 0;
  for (int k = 0; k < 40; k++) {
    double X[2] = {0.15 + 0.7 * urand(&seed), 0.15 + 0.7 * urand(&seed)};
    /* step 1e-4 h: truncation O((1e-4)^2 h^2 |p'''|/|p'|) ~ 1e-8, rounding
     * ~ 1e-16 / 1e-4 plus the Newton error 1e-14 / 1e-4 ~ 1e-10 relative. */
    wi = maxd(wi, fd_check(&par, &ns, X, 1e-4 * graded_h(X[0], n), H));
  }
  for (int k = 0; k < 8; k++) {
    /* 0.05 h from an edge the derivatives vary on the scale 0.05 h: step
     * 1e-6 h keeps the truncation ~ (1e-6/0.05)^2 ~ 4e-10, rounding ~ 1e-8. */
    double t = 0.1 + 0.8 * urand(&seed), X[2];
    switch (k % 4) {
    case 0:
      X[0] = t, X[1] = 0.05 * graded_h(t, n);
      break;
    case 1:
      X[0] = t, X[1] = 1 - 0.05 * graded_h(t, n);
      break;
    case 2:
      X[0] = 0.05 * graded_h(0, n), X[1] = t;
      break;
    default:
      X[0] = 1 - 0.05 * graded_h(1, n), X[1] = t;
      break;
    }
    wb = maxd(wb, fd_check(&par, &ns, X, 1e-6 * graded_h(X[0], n), H));
  }
  /* The published uniform-beta gradient grad p_a = -p_a J^{-1} d_a, on the
   * same graded set, for contrast: the FD test must be able to reject it. */
  double wu = 0;
  for (int k = 0; k < 10; k++) {
    double X[2] = {0.15 + 0.7 * urand(&seed), 0.15 + 0.7 * urand(&seed)};
    gather(&ns, &par, X, H, NULL);
    int m = H->m;
    double lam[2] = {0, 0}, J[3] = {0, 0, 0};
    assert_int_equal(ves_lme_eval(&par, X, m, H->xa, H->beta, lam, 1, H->tab, H->work, NULL),
                     VES_OK);
    for (int a = 0; a < m; a++) {
      double d0 = X[0] - H->xa[2 * a], d1 = X[1] - H->xa[2 * a + 1];
      J[0] += H->tab[a] * d0 * d0;
      J[1] += H->tab[a] * d0 * d1;
      J[2] += H->tab[a] * d1 * d1;
    }
    double det = J[0] * J[2] - J[1] * J[1], *gu = H->work; /* m doubles */
    for (int a = 0; a < m; a++) {
      double d0 = X[0] - H->xa[2 * a], d1 = X[1] - H->xa[2 * a + 1];
      gu[a] = -H->tab[a] * (J[2] * d0 - J[1] * d1) / det; /* -p (J^-1 d)_R */
    }
    wu = maxd(wu, relerr(m, gu, H->tab + m));
  }
  printf("  FD check (max-norm relative): interior %.1e, 0.05 h from edges "
         "%.1e; uniform-beta gradient off by %.1e\n",
         wi, wb, wu);
  assert_true(wu >= 1e-3); /* node-wise beta matters at the 1e-1 level */
  /* Required by the design: 1e-6 relative, well above the FD error budget
   * above and far below the error of a wrong formula (the uniform-beta
   * gradient is off by the amount printed above on this graded set). */
  assert_true(wi <= 1e-6);
  assert_true(wb <= 1e-6);
  free(H);
  nodeset_free(&ns);
}

/* Mirror ghosts: with the node set symmetric about R = 0, an even nodal
 * field has a vanishing R-derivative on the axis and an odd field a
 * vanishing value there. */
static void test_ghost_axis(void **state) {
  (void)state;
  ves_lme_params par;
  paper_params(&par);
  const double h = 0.1;
  nodeset ns;
  hex_lattice(&ns, h, 12, 1.0);
  double *fe = malloc((size_t)ns.n * sizeof(double));
  double *fo = malloc((size_t)ns.n * sizeof(double));
  assert_true(fe && fo);
  double fe_max = 0, fo_max = 0;
  for (int a = 0; a < ns.n; a++) {
    double R = fabs(ns.x[2 * a]), Z = ns.x[2 * a + 1];
    double s = ns.x[2 * a] < 0 ? -1.0 : 1.0;
    fe[a] = cos(R) + Z * Z;  /* even: the mirror gets the same value */
    fo[a] = s * R * (1 + Z); /* odd: the mirror gets the opposite value */
    fe_max = maxd(fe_max, fabs(fe[a]));
    fo_max = maxd(fo_max, fabs(fo[a]));
  }
  hood *H = malloc(sizeof *H), *H2 = malloc(sizeof *H2);
  assert_true(H && H2);
  double e_even = 0, e_odd = 0, lamR = 0;
  for (int k = 0; k <= 40; k++) {
    double X[2] = {0.0, -0.5 + k * 0.025}; /* on the axis, on and off nodes */
    gather(&ns, &par, X, H, fe);
    gather(&ns, &par, X, H2, fo);
    double lam[2] = {0, 0};
    assert_int_equal(ves_lme_eval(&par, X, H->m, H->xa, H->beta, lam, 2, H->tab, H->work, NULL),
                     VES_OK);
    long double dRu = 0, u = 0;
    for (int a = 0; a < H->m; a++) {
      dRu += H->tab[H->m + a] * H->f[a];
      u += H->tab[a] * H2->f[a];
    }
    e_even = maxd(e_even, fabsl(dRu) * h / fe_max);
    e_odd = maxd(e_odd, fabsl(u) / fo_max);
    lamR = maxd(lamR, fabs(lam[0]) * h);
  }
  printf("  axis: |du/dR| h / max|f| (even) %.1e, |u| / max|f| (odd) %.1e, "
         "|lambda_R| h %.1e\n",
         e_even, e_odd, lamR);
  /* Symmetric neighbourhoods make the pairwise contributions cancel
   * exactly up to the order of summation: rounding ~ m eps ~ 1e-14. */
  assert_true(e_even <= 1e-12);
  assert_true(e_odd <= 1e-12);
  free(H);
  free(H2);
  free(fe);
  free(fo);
  nodeset_free(&ns);
}

/* A warm start from a nearby point's lambda gives the same table in no more
 * iterations; nder = 0 and 1 write only the first 1 and 3 rows. */
static void test_warm_start_rows(void **state) {
  (void)state;
  ves_lme_params par;
  paper_params(&par);
  nodeset ns;
  graded_box(&ns, 16, 31);
  hood *H = malloc(sizeof *H);
  assert_non_null(H);
  double X[2] = {0.4123, 0.5456}, h = graded_h(X[0], 16);
  gather(&ns, &par, X, H, NULL);
  int m = H->m;
  double *t2 = malloc(6 * (size_t)m * sizeof(double));
  assert_non_null(t2);
  double lam[2] = {0, 0};
  ves_lme_info icold, iwarm;
  assert_int_equal(ves_lme_eval(&par, X, m, H->xa, H->beta, lam, 2, H->tab, H->work, &icold),
                   VES_OK);
  assert_true(icold.residual <= par.newton_tol * h); /* the stated criterion */
  /* warm: lambda of a point 0.1 h away */
  double Xn[2] = {X[0] + 0.1 * h, X[1] - 0.05 * h}, lw[2] = {0, 0};
  assert_int_equal(ves_lme_eval(&par, Xn, m, H->xa, H->beta, lw, 0, t2, H->work, NULL), VES_OK);
  assert_int_equal(ves_lme_eval(&par, X, m, H->xa, H->beta, lw, 2, t2, H->work, &iwarm), VES_OK);
  printf("  Newton iterations: cold %d, warm (from 0.1 h away) %d\n", icold.iterations,
         iwarm.iterations);
  assert_true(iwarm.iterations <= icold.iterations);
  /* both solves reach |r| <= 1e-14 h; p depends on lambda through
   * dp = p d . dlambda with |dlambda| <= |J^{-1}| |r| ~ 1e-14 / h: 1e-12
   * relative bounds the difference of every row. */
  for (int k = 0; k < 6; k++) assert_true(relerr(m, t2 + k * m, H->tab + k * m) <= 1e-12);
  /* a wild guess (|lambda| dmax ~ 1e4, above the divergence bound: what a
   * previous, unrelated point can leave) is dropped for 0 after its Newton
   * fails: the cold result, bit for bit (the same iteration from 0) */
  double lfar[2] = {3e3 / h, -2e3 / h};
  assert_int_equal(ves_lme_eval(&par, X, m, H->xa, H->beta, lfar, 2, t2, H->work, NULL), VES_OK);
  assert_memory_equal(t2, H->tab, 6 * (size_t)m * sizeof(double));
  /* a non-finite guess is replaced by 0: the cold result, bit for bit */
  double lnan[2] = {NAN, 1.0};
  assert_int_equal(ves_lme_eval(&par, X, m, H->xa, H->beta, lnan, 2, t2, H->work, NULL), VES_OK);
  for (int k = 0; k < 6 * m; k++) assert_true(t2[k] == H->tab[k]);
  /* row-writing contract: untouched rows keep their sentinel; the written
   * rows are bit-identical (same inputs, same operations) */
  for (int k = 0; k < 6 * m; k++) t2[k] = -7.0;
  lam[0] = lam[1] = 0;
  ves_lme_eval(&par, X, m, H->xa, H->beta, lam, 1, t2, H->work, NULL);
  for (int k = 0; k < 3 * m; k++) assert_true(t2[k] == H->tab[k]);
  for (int k = 3 * m; k < 6 * m; k++) assert_true(t2[k] == -7.0);
  for (int k = 0; k < 6 * m; k++) t2[k] = -7.0;
  lam[0] = lam[1] = 0;
  ves_lme_eval(&par, X, m, H->xa, H->beta, lam, 0, t2, H->work, NULL);
  for (int k = 0; k < m; k++) assert_true(t2[k] == H->tab[k]);
  for (int k = m; k < 6 * m; k++) assert_true(t2[k] == -7.0);
  free(t2);
  free(H);
  nodeset_free(&ns);
}

static void test_errors(void **state) {
  (void)state;
  ves_lme_params par;
  paper_params(&par);
  double tab[6 * 64], work[4 * 64], lam[2] = {0, 0};
  double xa[6] = {0, 0, 1, 0, 0, 1}, beta[3] = {1, 1, 1};
  double X[2] = {0.2, 0.2};
  /* a valid call first, so each failure below is due to its one change */
  assert_int_equal(ves_lme_eval(&par, X, 3, xa, beta, lam, 2, tab, work, NULL), VES_OK);
  lam[0] = lam[1] = 0;
  assert_int_equal(ves_lme_eval(&par, X, 2, xa, beta, lam, 0, tab, work, NULL),
                   VES_ERR_ARG); /* m < 3 */
  assert_int_equal(ves_lme_eval(NULL, X, 3, xa, beta, lam, 0, tab, work, NULL), VES_ERR_ARG);
  assert_int_equal(ves_lme_eval(&par, NULL, 3, xa, beta, lam, 0, tab, work, NULL), VES_ERR_ARG);
  assert_int_equal(ves_lme_eval(&par, X, 3, NULL, beta, lam, 0, tab, work, NULL), VES_ERR_ARG);
  assert_int_equal(ves_lme_eval(&par, X, 3, xa, NULL, lam, 0, tab, work, NULL), VES_ERR_ARG);
  assert_int_equal(ves_lme_eval(&par, X, 3, xa, beta, NULL, 0, tab, work, NULL), VES_ERR_ARG);
  assert_int_equal(ves_lme_eval(&par, X, 3, xa, beta, lam, 0, NULL, work, NULL), VES_ERR_ARG);
  assert_int_equal(ves_lme_eval(&par, X, 3, xa, beta, lam, 0, tab, NULL, NULL), VES_ERR_ARG);
  assert_int_equal(ves_lme_eval(&par, X, 3, xa, beta, lam, 3, tab, work, NULL),
                   VES_ERR_ARG); /* nder = 3 */
  assert_int_equal(ves_lme_eval(&par, X, 3, xa, beta, lam, -1, tab, work, NULL), VES_ERR_ARG);
  double bneg[3] = {1, -1, 1};
  assert_int_equal(ves_lme_eval(&par, X, 3, xa, bneg, lam, 0, tab, work, NULL),
                   VES_ERR_ARG); /* beta <= 0 */
  ves_lme_params bad = par;
  bad.max_iter = 0;
  assert_int_equal(ves_lme_eval(&bad, X, 3, xa, beta, lam, 0, tab, work, NULL), VES_ERR_ARG);
  double Xnan[2] = {NAN, 0};
  assert_int_equal(ves_lme_eval(&par, Xnan, 3, xa, beta, lam, 0, tab, work, NULL), VES_ERR_ARG);

  /* collinear neighbourhood, X on the line: no 2D hull */
  double xl[10] = {-0.2, 0, -0.1, 0, 0, 0, 0.1, 0, 0.2, 0}, bl[5] = {80, 80, 80, 80, 80};
  double Xl[2] = {0.05, 0};
  lam[0] = lam[1] = 0;
  assert_int_equal(ves_lme_eval(&par, Xl, 5, xl, bl, lam, 0, tab, work, NULL), VES_ERR_ARG);

  /* X outside the hull of a real neighbourhood: lambda diverges */
  nodeset ns;
  graded_box(&ns, 16, 5);
  hood *H = malloc(sizeof *H);
  assert_non_null(H);
  double Xo[2] = {-0.01, 0.5};
  gather(&ns, &par, Xo, H, NULL);
  assert_true(H->m >= 3);
  ves_lme_info info;
  lam[0] = lam[1] = 0;
  assert_int_equal(ves_lme_eval(&par, Xo, H->m, H->xa, H->beta, lam, 2, H->tab, H->work, &info),
                   VES_ERR_NOCONV);
  printf("  outside the hull: NOCONV after %d iterations\n", info.iterations);

  /* X exactly on the hull (an edge of the box): J singular -> VES_ERR_ARG */
  double Xe[2] = {0.5, 0.0};
  gather(&ns, &par, Xe, H, NULL);
  lam[0] = lam[1] = 0;
  ves_status st = ves_lme_eval(&par, Xe, H->m, H->xa, H->beta, lam, 2, H->tab, H->work, &info);
  printf("  on the hull: %s after %d iterations\n", ves_status_str(st), info.iterations);
  assert_int_equal(st, VES_ERR_ARG);

  /* iteration limit: one Newton step cannot converge 1e-3 h from an edge */
  double Xb[2] = {0.5, 1e-3 * graded_h(0.5, 16)};
  gather(&ns, &par, Xb, H, NULL);
  ves_lme_params one = par;
  one.max_iter = 1;
  lam[0] = lam[1] = 0;
  assert_int_equal(ves_lme_eval(&one, Xb, H->m, H->xa, H->beta, lam, 0, H->tab, H->work, &info),
                   VES_ERR_NOCONV);
  assert_int_equal(info.iterations, 1);
  free(H);
  nodeset_free(&ns);
}

int main(void) {
  setvbuf(stdout, NULL, _IOLBF, 0); /* keep output in order with cmocka's stderr */
  // clang-format off
  const struct CMUnitTest tests[] = {
      cmocka_unit_test(test_params),
      cmocka_unit_test(test_consistency_hex),
      cmocka_unit_test(test_consistency_wide),
      cmocka_unit_test(test_consistency_graded),
      cmocka_unit_test(test_derivatives_fd),
      cmocka_unit_test(test_ghost_axis),
      cmocka_unit_test(test_warm_start_rows),
      cmocka_unit_test(test_errors),
  };
  // clang-format on
  return cmocka_run_group_tests(tests, NULL, NULL);
}
