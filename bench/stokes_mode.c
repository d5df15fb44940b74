/* bench/stokes_mode.c -- independent prediction of the relaxation rate of a
 * slightly perturbed, bending-only spherical vesicle (vesica's hydrodynamic
 * time-scale check). Self-contained: shares no code with vesica's model.
 * It stays one file of ~2,100 lines on purpose: an independent reference
 * that compiles with one command, reads from top to bottom with its
 * derivation inline, and cannot pick up vesica's code or headers by
 * accident.
 *
 * Build: gcc -std=c11 -O2 -Wall -Wextra -Werror -o /tmp/stokes_mode \
 *            bench/stokes_mode.c -ldmumps_seq -llapacke -lopenblas -lm
 * Run:   OPENBLAS_NUM_THREADS=1 /tmp/stokes_mode   (about 1 minute, one core)
 *        options: --only ABCD (sections), --nmax N (finest mesh of section C,
 *        default 64), --nverify N (B, default 32), --nbig N (D uses N and 2N,
 *        default 16), --nq n (n x n collapsed Gauss rule per triangle, 5),
 *        --kout K (override the outer radial cell factor; checks mesh
 *        independence).
 *        Inextensible membrane (section 4): --membrane inextensible (default
 *        free) switches A-D to the locally inextensible membrane and adds
 *        sections S (stability of the tension discretization, --nstab N,
 *        default 32) and E (free vs inextensible, box 3, meshes nmax/4..nmax);
 *        about 2.5 minutes in all, each section < 40 s. --tension p1|p2
 *        (multiplier space, default p1; p2 is unstable, kept for section S),
 *        --area auto|fixed|free (l = 0 tension, see 4(d)). --only takes
 *        any of ABCDSE.
 *
 * Units: k = mu = R = 1, time t* = t k/(mu R^3). Setting: sphere r = 1,
 * membrane with bending energy only (no tension, no surface incompressibility,
 * C0 = 0, area and volume free), ONE fluid of viscosity mu inside and out.
 *
 * 1. ENERGY AND FORCE.  E = (k/2) \oint H^2 dA, H = (c1+c2)/2; for the sphere
 *    H = 1/R, E = (k/2) R^-2 4 pi R^2 = 2 pi k.  Standard Helfrich
 *    (kappa/2)\oint (2H)^2 = 2 kappa \oint H^2 equals it for kappa = k/4.
 *    First variation under x -> x + psi n (n outward, H = div_s(n)/2):
 *    delta(dA) = 2H psi dA, delta H = -(Lap_s psi + (c1^2+c2^2) psi)/2, so
 *      delta \oint H^2 dA = -\oint [Lap_s H + 2H(H^2 - K)] psi dA,
 *    and the normal force density exerted on the fluid is
 *      f_n = -deltaE/delta psi = (k/2) [Lap_s H + 2H(H^2 - K)].
 *    Linearization at the sphere: for a normal displacement psi = a P_l(cos th),
 *    Lap_s P_l = -L P_l / R^2 (L = l(l+1)), delta H = (L-2) a P_l/(2R^2), and
 *    H^2 - K = ((c1-c2)/2)^2 = O(a^2), hence
 *      f_n = (k/2) Lap_s(delta H) = -(k/4) L(L-2) a P_l / R^4 = -kappa L(L-2) a P_l / R^4.
 *    The sphere is a critical point of E (scale invariance), so the quadratic
 *    energy is E2 = -(1/2) \oint f_n psi dA = (kappa/2) L(L-2) (a/R)^2 \oint P_l^2 dOmega
 *      = 2 pi kappa L(L-2) delta^2/(2l+1) = pi k L(L-2) delta^2 / (2(2l+1)),
 *    delta = a/R (for r = 1 + delta P_l the normal displacement is delta P_l to
 *    first order).  [Same as the Helfrich/Milner-Safran spectrum
 *    (kappa/2)(l-1)l(l+1)(l+2)|u_lm|^2 with sigma = 0, since (l-1)(l+2) = L-2.]
 *    Checked numerically in section A4 on the exact surface r = 1 + delta P_l
 *    (principal curvatures of the surface of revolution, Gauss quadrature):
 *    E2 to O(delta^2), f_l/delta to O(delta^2), and the virtual-work identity
 *    dE/d delta = -\oint f_n (dx/d delta . n) dA at finite delta.
 *
 * 2. MOBILITY, UNBOUNDED SPACE.  M_l = P_l-component of the normal velocity
 *    produced by the normal force density P_l(cos th) n on the sphere;
 *    s_l = M_l kappa L(L-2)/R^4 (d delta/dt = -s_l delta), energy rate 2 s_l.
 *    (a) Lamb-type solution, for the compressible fluid too.  Stress
 *    sigma = 2 mu d + lam (div u) I; equilibrium mu Lap u + (mu+lam) grad div u = 0
 *    (lam -> inf: Stokes, -lam div u -> p).  With p = r^n P_l a solid
 *    harmonic, u = al r^2 grad p + be x p gives Lap u = [(4n+2) al + 2 be] grad p,
 *    div u = [2n al + (n+3) be] p, so it solves the equations if
 *    mu[(4n+2)al + 2be] = -(mu+lam)[2n al + (n+3)be]; together with u = grad(r^n P_l)
 *    this gives two regular interior (n = l) and two decaying exterior
 *    (n = -l-1) fields (radial parts r^{l+1}, r^{l-1}; r^{-l}, r^{-l-2}).
 *    Interface r = 1: continuous velocity (u_r, u_th), continuous tangential
 *    traction mu(du_th/dr - u_th/r + (1/r) du_r/dth), normal traction jump
 *    [sigma_rr] = -P_l.  4x4 system (lamb_solve).  Closed forms (mu = R = 1):
 *      incompressible   M_l = 2 L / ((2l-1)(2l+1)(2l+3))   (M_2 = 4/35, M_3 = 8/105)
 *      lam/mu finite    M_l = [(lam+3)D + 3 lam + 7] / (2 (lam+2)(2l+1) D),  D = (2l-1)(2l+3)
 *    (b) Stokeslet / Kelvin integral.  u(x) = \oint G(x-y) f(y) dA_y,
 *    G = [(3-4nu) I/r + r r^T/r^3] / (16 pi mu (1-nu)), nu = lam/(2(lam+mu))
 *    (nu = 1/2: Oseen tensor).  For x, y on the unit sphere, x.(x-y) = r^2/2 and
 *    y.(x-y) = -r^2/2, so n_x.G.n_y = [(3-4nu)(1/r - r/2) - r/4]/(16 pi mu (1-nu)),
 *    a function of cos(gamma) = x.y only.  With 1/r = sum P_n(cos gamma) and
 *    r = sum -4/((2n-1)(2n+3)) P_n(cos gamma) (generating function / Legendre
 *    expansion of |x-y| at r< = r> = 1) and Funk-Hecke
 *    (\oint P_n(x.y) P_l(y) dA_y = 4 pi/(2l+1) P_l(x) delta_nl):
 *      M_l = [(3-4nu)(D+2) + 1] / (4 mu (1-nu)(2l+1) D),
 *    identical to (a) (nu = 1/2: (D+3)/(2(2l+1)D) = 2L/((2l-1)(2l+1)(2l+3))).
 *    Both are checked against a direct numerical quadrature of the full 3-D
 *    tensor over the sphere (section A2): geodesic polar coordinates centred
 *    at the target remove the weak singularity (sin(gamma)/r = cos(gamma/2)),
 *    Gauss in gamma, trapezoid in the periodic angle, Gauss in cos(th) for the
 *    projection; it also shows the response is a pure P_l (the sphere's
 *    single-layer operator is diagonal in l).
 *    (c) Drop check: inside viscosity lv mu in (a), normal force
 *    -gamma (l-1)(l+2) a/R^2 (tension plus Laplace-pressure perturbation):
 *    rate = M_2 * 4 gamma reproduces 40(lv+1)/((2lv+3)(19lv+16)) gamma/(mu R)
 *    for every lv tried (0.01..100), in particular 16/35 at lv = 1 (A3).
 *    Rates, incompressible unbounded: s_l = k L^2 (L-2) / (2 mu R^3 (2l-1)(2l+1)(2l+3)):
 *      s_2 = 24/35 = 0.685714, s_3 = 16/7 = 2.285714; lam/mu = 100: 0.691877, 2.307190.
 *
 * 3. FINITE ELEMENTS IN THE BOX.  Meridian domain [0,Rb] x [-Rb,Rb]; the
 *    common factor 2 pi is dropped from every integral.  Weak form: find u with
 *    u = 0 on the walls (or given data), u_rho = 0 on the axis (u_z free:
 *    symmetry), such that for all admissible w
 *      \int [2 mu d(u):d(w) + lam div u div w] rho drho dz = \int_Gamma f.w rho ds,
 *    d:d = d_rr^2 + d_zz^2 + 2 d_rz^2 + (u_rho/rho)^2 (hoop strain),
 *    div u = du_rho/drho + u_rho/rho + du_z/dz; f = P_l(cos th) n on the circle
 *    Gamma (rho = sin th, ds = dth): a line integral.  Three discretizations:
 *      TH     Taylor-Hood P2-P1, incompressible: -\int p div w rho, -\int q div u rho;
 *      THmix  the same with -(1/lam)\int p q rho (p = -lam div u): the exact
 *             lam/mu = 100 problem in a form stable uniformly in lam;
 *      P2pen  pure P2 velocity with the penalty term (SPD).
 *    The pressure is P1, continuous inside and outside the sphere but
 *    DISCONTINUOUS across it (vertices on Gamma carry two pressures): the
 *    pressure jumps by the normal force, and a continuous P1 pressure would
 *    cost accuracy; it also makes the discrete inside volume exactly conserved
 *    in TH (u_0 = 0 to round-off).  TH pins one wall pressure (the constant).
 *    Mesh: structured, 7 mapped blocks (inner half-square, three ring blocks
 *    square -> circle, three outer blocks circle -> top wall / side wall /
 *    bottom wall, geometrically graded outwards, arc breakpoints at the box
 *    corner directions), transfinite interpolation, each quad split into two
 *    6-node triangles whose nodes come from the map (isoparametric, curved:
 *    the circle is represented to O(h^3) and is a union of element edges).
 *    N = cells per eighth of the circle (quarter of the half circle).
 *    Quadrature: collapsed Gauss n x n on triangles, 8 Gauss points per arc edge.
 *    Sparse direct solve: MUMPS (SYM = 1 for P2pen, SYM = 2 otherwise); all
 *    load vectors P_2..P_8 share one factorization.
 *    Output functional: u_m = (2m+1)/2 \int_0^pi u.n P_m sin th dth evaluated
 *    as (2m+1)/2 b_m.U with b_m the load vector of P_m: for m = l this is the
 *    energy (compliance) functional and converges at O(h^4) for P2.
 *    Coupling: in the box the P_l force excites other P_m; the table gives
 *    u_m/u_l and the decay rate of the coupled linear dynamics
 *    da_m/dt = -sum_n M_mn kappa L_n(L_n - 2) a_n (m, n = 2..8; modes 0, 1 have
 *    no stiffness and are slaved).
 *    Verification (section B): the exact unbounded solution of 2(a) (for lam =
 *    inf and lam/mu = 100) imposed as Dirichlet data on the box-3 walls with the
 *    membrane force inside: the FE functional must converge to the analytic
 *    M_l and the velocity to the exact field (observed: L2 error O(h^3), u_l
 *    error O(h^4)). Section D extrapolates the box sequence 3..48 to an
 *    infinite box and recovers the analytic M_l.
 *
 * 4. INEXTENSIBLE MEMBRANE (--membrane inextensible).  Same bending force,
 *    plus the constraint of local surface incompressibility div_s u = 0 on
 *    r = 1, enforced by a tension field sigma (Lagrange multiplier; zero base
 *    tension, i.e. the linearization about the tensionless sphere of
 *    Milner-Safran / Seifert).
 *    (a) Surface divergence.  On a surface of revolution with meridian tangent
 *    t and azimuthal e_phi, div_s u = t.(du/ds) + e_phi.(du/dphi)/rho =
 *    t.du/ds + u_rho/rho (d e_rho/dphi = e_phi).  On the unit sphere, u =
 *    u_n n + u_th e_th, dn/dth = e_th, de_th/dth = -n:  t.du/ds = u_n + du_th/dth,
 *    u_rho/rho = u_n + u_th cot th, so div_s u = 2 u_n + (1/sin th) d/dth(sin th u_th).
 *    For u_r = U P_l, u_th = V dP_l/dth: div_s u = (2U - L V) P_l.
 *    The weak term \int sigma div_s w dA = -\int w.(grad_s sigma) dA + \int 2 sigma w_n dA
 *    (unit sphere), so in  a(u,w) + \int sigma div_s w = \int f.w  the
 *    membrane exerts the extra force grad_s sigma - 2 sigma n: sigma is the
 *    physical tension perturbation (tangential Sig dP_l/dth, normal -2 Sig P_l).
 *    (b) Unbounded, equal viscosities.  From the Lamb solution of 2(a), the
 *    sphere's mobility for a force (f_n P_l n + f_t grad_s P_l), d = (2l+1)(4L-3):
 *      U = L (2 f_n + 3 f_t)/d,   V = (3 f_n + (2L+3) f_t)/d
 *    (symmetric: G_nt = L G_tn, L = |grad_s P_l|^2/|P_l|^2).  With f_n = 1 - 2 Sig,
 *    f_t = Sig, the constraint 2U = L V gives f_n = (2L-3) f_t, hence
 *      Sig_l = 1/(2L-1),   M_l = U = L/((2l+1)(2L-1)) = 1/Z_l,
 *      Z_l = (2l+1)(2l^2+2l-1)/(l(l+1)),
 *    and s_l = M_l kappa L(L-2) = kappa (l-1)(l+2) l(l+1)/(mu R^3 Z_l): the
 *    Milner-Safran / Seifert rate at zero tension.  Ratio to the free membrane
 *    (4L-3)/(4L-2): 21/22 (l=2), 45/46 (l=3).  Compressible fluid (lam/mu), from
 *    the same 5x5 system solved symbolically:
 *      M_l = L[(lam+3)^2 L + lam + 2] / ((2l+1)(lam+2) Q),  Sig_l = [(lam+5)L - 2]/Q,
 *      Q = lam L(2L-1) + 6L^2 + 2L - 4   (-> the incompressible values as lam -> inf).
 *    Section A6 checks lamb_solve_mem (5x5, numeric) against these.
 *    (c) Discretization.  sigma is continuous P1 on the arc vertices (the
 *    trace of the P2 velocity is quadratic on each arc edge: a 1-D Taylor-Hood
 *    pair).  B_ij = \int psi_i div_s(phi_j) rho ds evaluated on the discrete
 *    (isoparametric) arc as \int psi_i [rho (dX.dphi_j)/|dX| + (phi_j e_rho)|dX|] dt,
 *    exact for rigid translations; symmetric saddle point (MUMPS SYM = 2).
 *    Stability (section S): the generalized eigenvalues of the tension Schur
 *    complement S = B A^-1 B^T against the tension mass (squared inf-sup
 *    ratios) converge under refinement for P1 (THmix box 3: 0.012747 (l = 0),
 *    0.40656, 0.62819, 0.88201, ... with smooth eigenvectors l = 1, 2, 3, ...;
 *    unbounded incompressible values, from (b) with f_n = -2 Sig, f_t = Sig:
 *    L(2L-1)/((2l+1)(4L-3)) = 0.400, 0.629, 0.876 for l = 1, 2, 3), and
 *    lam_max h stays constant (order-1 operator).  Continuous P2 on all arc nodes
 *    (equal order) is NOT stable: eigenvalues ~ 0.022 h with oscillating
 *    eigenvectors (no Legendre content below l = 16); with it the velocity
 *    still converges but the tension does not (section B, --tension p2).
 *    With P1, section B shows u_l O(h^4), velocity L2 O(h^3), nodal tension O(h^2).
 *    (d) The l = 0 tension.  A uniform tension only acts through the total area
 *    change, 2 \oint u_n dA.  In TH the inside volume is conserved exactly, which
 *    fixes the total area to O(h^4): the uniform tension is then nearly
 *    redundant with the inside pressure (S has an l = 0 eigenvalue 5e-9 (N = 4)
 *    ... 1.5e-13 (N = 32), section S) and is ill-determined (sig_0 = O(1), non-convergent, although
 * the velocity is unaffected).  --area auto therefore removes it for TH: the multiplier space is
 * {sigma: \oint sigma dA = 0}, imposed with one scalar multiplier c (the discrete constraint
 * becomes div_s u = -c; c is reported as "div resid" in section B and is < 1e-9).  For THmix /
 * P2pen (compressible fluid) the total area is a real constraint and is kept (--area fixed;
 *    --area free would let the area change uniformly: in box 3 it changes M_2
 *    by 3e-7 and M_3 not at all).
 *
 * Sections: A analytic checks; B verification; C box 3 mesh convergence
 * (TH, P2pen, THmix); D box size -> unbounded; with --membrane inextensible
 * also S (stability of the tension multiplier) and E (free vs inextensible).
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <time.h>
#include <dmumps_c.h>
#include <lapacke.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define LMAX_OUT 8 /* Legendre components computed on the sphere: 0..LMAX_OUT */

static double now_sec(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void *xmalloc(size_t n) {
  void *p = malloc(n ? n : 1);
  if (!p) {
    fprintf(stderr, "out of memory (%zu bytes)\n", n);
    exit(2);
  }
  return p;
}
static void *xcalloc(size_t n, size_t s) {
  void *p = calloc(n ? n : 1, s ? s : 1);
  if (!p) {
    fprintf(stderr, "out of memory\n");
    exit(2);
  }
  return p;
}

/* ------------------------------------------------------------------------- */
/* Legendre polynomials and Gauss-Legendre rules                              */
/* ------------------------------------------------------------------------- */

/* P_n(x), P_n'(x), P_n''(x) for n = 0..nmax (arrays of nmax+1) */
static void legendre_all(int nmax, double x, double *P, double *dP, double *d2P) {
  P[0] = 1.0;
  dP[0] = 0.0;
  d2P[0] = 0.0;
  if (nmax >= 1) {
    P[1] = x;
    dP[1] = 1.0;
    d2P[1] = 0.0;
  }
  for (int n = 1; n < nmax; n++) {
    P[n + 1] = ((2 * n + 1) * x * P[n] - n * P[n - 1]) / (n + 1);
    dP[n + 1] = dP[n - 1] + (2 * n + 1) * P[n];
    d2P[n + 1] = d2P[n - 1] + (2 * n + 1) * dP[n];
  }
}

static double legendre(int l, double x) {
  double p0 = 1.0, p1 = x;
  if (l == 0) return 1.0;
  for (int n = 1; n < l; n++) {
    double p2 = ((2 * n + 1) * x * p1 - n * p0) / (n + 1);
    p0 = p1;
    p1 = p2;
  }
  return p1;
}

/* dP_l/dx */
static double dlegendre(int l, double x) {
  double P[64], dP[64], d2P[64];
  legendre_all(l, x, P, dP, d2P);
  return dP[l];
}

/* n-point Gauss-Legendre rule on [-1, 1] */
static void gauleg(int n, double *x, double *w) {
  for (int i = 0; i < n; i++) {
    double z = cos(M_PI * (i + 0.75) / (n + 0.5)), z1, pp = 1.0;
    for (int it = 0; it < 100; it++) {
      double p1 = 1.0, p2 = 0.0;
      for (int j = 0; j < n; j++) {
        double p3 = p2;
        p2 = p1;
        p1 = ((2.0 * j + 1.0) * z * p2 - j * p3) / (j + 1.0);
      }
      pp = n * (z * p1 - p2) / (z * z - 1.0);
      z1 = z;
      z = z1 - p1 / pp;
      if (fabs(z - z1) < 1e-15) break;
    }
    x[i] = z;
    w[i] = 2.0 / ((1.0 - z * z) * pp * pp);
  }
}

/* ------------------------------------------------------------------------- */
/* Part A: analytic (Lamb-type) solution, unbounded space                     */
/* ------------------------------------------------------------------------- */

/* One material: shear viscosity mu, bulk (penalty) coefficient lam; inc = 1
 * means incompressible (lam -> infinity, Stokes with pressure). */
typedef struct {
  double mu, lam;
  int inc;
} Fluid;

/* Axisymmetric poloidal fields of angular degree l:
 *   u_r = U(r) P_l(cos th),  u_th = V(r) d/dth P_l(cos th),
 *   isotropic stress (lam div u, or -p) = S(r) P_l(cos th).
 * type 1: u = grad(r^n P_l)                     (div u = 0)
 * type 2: u = al r^2 grad(p) + be x p,  p = r^n P_l, with
 *         mu[(4n+2) al + 2 be] = 1   (so mu lap u = grad p per unit p)
 *         2n al + (n+3) be = -1/(lam+mu)   (so mu lap u + (mu+lam) grad div u = 0)
 * n = l (interior, regular at 0) or n = -l-1 (exterior, decaying). */
static void lamb_term(int type, double n, Fluid f, double r, double *U, double *dU, double *V,
                      double *dV, double *S) {
  if (type == 1) {
    *U = n * pow(r, n - 1);
    *dU = n * (n - 1) * pow(r, n - 2);
    *V = pow(r, n - 1);
    *dV = (n - 1) * pow(r, n - 2);
    *S = 0.0;
    return;
  }
  double e = f.inc ? 0.0 : -1.0 / (f.lam + f.mu);
  double a11 = f.mu * (4 * n + 2), a12 = 2 * f.mu, a21 = 2 * n, a22 = n + 3;
  double det = a11 * a22 - a12 * a21;
  double al = (a22 - a12 * e) / det, be = (a11 * e - a21) / det;
  double c = al * n + be;
  *U = c * pow(r, n + 1);
  *dU = c * (n + 1) * pow(r, n);
  *V = al * pow(r, n + 1);
  *dV = al * (n + 1) * pow(r, n);
  *S = (f.inc ? -1.0 : -f.lam / (f.lam + f.mu)) * pow(r, n);
}

typedef struct {
  int l;
  Fluid fin, fout;
  double c[4];
  double M;
  int inext;
  double Sig;
} Lamb;

/* Unit sphere carrying the normal force density F P_l(cos th) n (F = 1),
 * fluid fin inside and fout outside; continuity of velocity and of the
 * tangential traction, jump of the normal traction:
 *   [U] = 0, [V] = 0, [mu (V' - V/r + U/r)] = 0, [S + 2 mu U'] = -F. */
static Lamb lamb_solve(int l, Fluid fin, Fluid fout) {
  Lamb L;
  L.l = l;
  L.fin = fin;
  L.fout = fout;
  double A[16], b[4] = {0, 0, 0, -1.0};
  for (int k = 0; k < 4; k++) {
    int type = (k % 2) + 1, out = k >= 2;
    double n = out ? -(double)l - 1.0 : (double)l, U, dU, V, dV, S;
    Fluid f = out ? fout : fin;
    lamb_term(type, n, f, 1.0, &U, &dU, &V, &dV, &S);
    double sg = out ? 1.0 : -1.0;
    A[0 * 4 + k] = sg * U;
    A[1 * 4 + k] = sg * V;
    A[2 * 4 + k] = sg * f.mu * (dV - V + U);
    A[3 * 4 + k] = sg * (S + 2 * f.mu * dU);
  }
  lapack_int ipiv[4];
  lapack_int info = LAPACKE_dgesv(LAPACK_ROW_MAJOR, 4, 1, A, 4, ipiv, b, 1);
  if (info != 0) {
    fprintf(stderr, "lamb_solve: dgesv info %d\n", (int)info);
    exit(2);
  }
  memcpy(L.c, b, sizeof b);
  double M = 0.0;
  for (int k = 0; k < 2; k++) {
    double U, dU, V, dV, S;
    lamb_term(k + 1, (double)l, fin, 1.0, &U, &dU, &V, &dV, &S);
    M += L.c[k] * U;
  }
  L.M = M;
  L.inext = 0;
  L.Sig = 0.0;
  return L;
}

/* The same with an INEXTENSIBLE membrane (header, section 4): fifth unknown the
 * tension perturbation Sig P_l(cos th); the membrane force on the fluid gains
 * grad_s(sigma) - 2 sigma n, i.e. tangential Sig dP_l/dth, normal -2 Sig P_l, and
 * the surface divergence 2 u_r + (1/sin th) d/dth(sin th u_th) = (2U - L V) P_l
 * must vanish:
 *   [U] = 0, [V] = 0, [mu (V' - V/r + U/r)] + Sig = 0, [S + 2 mu U'] - 2 Sig = -F,
 *   2 U - L V = 0  (interior branch, r = 1). */
static Lamb lamb_solve_mem(int l, Fluid fin, Fluid fout, int inext) {
  if (!inext) return lamb_solve(l, fin, fout);
  Lamb L;
  L.l = l;
  L.fin = fin;
  L.fout = fout;
  L.inext = 1;
  double A[25], b[5] = {0, 0, 0, -1.0, 0}, LL = l * (l + 1.0);
  memset(A, 0, sizeof A);
  for (int k = 0; k < 4; k++) {
    int type = (k % 2) + 1, out = k >= 2;
    double n = out ? -(double)l - 1.0 : (double)l, U, dU, V, dV, S;
    Fluid f = out ? fout : fin;
    lamb_term(type, n, f, 1.0, &U, &dU, &V, &dV, &S);
    double sg = out ? 1.0 : -1.0;
    A[0 * 5 + k] = sg * U;
    A[1 * 5 + k] = sg * V;
    A[2 * 5 + k] = sg * f.mu * (dV - V + U);
    A[3 * 5 + k] = sg * (S + 2 * f.mu * dU);
    A[4 * 5 + k] = out ? 0.0 : 2.0 * U - LL * V;
  }
  A[2 * 5 + 4] = 1.0;
  A[3 * 5 + 4] = -2.0;
  lapack_int ipiv[5];
  lapack_int info = LAPACKE_dgesv(LAPACK_ROW_MAJOR, 5, 1, A, 5, ipiv, b, 1);
  if (info != 0) {
    fprintf(stderr, "lamb_solve_mem: dgesv info %d\n", (int)info);
    exit(2);
  }
  memcpy(L.c, b, 4 * sizeof(double));
  L.Sig = b[4];
  double M = 0.0;
  for (int k = 0; k < 2; k++) {
    double U, dU, V, dV, S;
    lamb_term(k + 1, (double)l, fin, 1.0, &U, &dU, &V, &dV, &S);
    M += L.c[k] * U;
  }
  L.M = M;
  return L;
}

/* Exact velocity (u_rho, u_z) at meridian point (rho, z); side 0 = inside
 * branch, 1 = outside branch (chosen by the caller, not by |x|). */
static void lamb_field(const Lamb *L, int side, double rho, double z, double *ur, double *uz) {
  double r = hypot(rho, z);
  if (r < 1e-300) {
    *ur = 0;
    *uz = 0;
    return;
  }
  double ct = z / r, st = rho / r;
  double Uc = 0, Vc = 0;
  for (int k = 0; k < 2; k++) {
    int kk = side ? k + 2 : k;
    double n = side ? -(double)L->l - 1.0 : (double)L->l, U, dU, V, dV, S;
    lamb_term(k + 1, n, side ? L->fout : L->fin, r, &U, &dU, &V, &dV, &S);
    Uc += L->c[kk] * U;
    Vc += L->c[kk] * V;
  }
  double Pl = legendre(L->l, ct);
  double dPdth = -st * dlegendre(L->l, ct);
  double u_r = Uc * Pl, u_t = Vc * dPdth;
  *ur = u_r * st + u_t * ct;
  *uz = u_r * ct - u_t * st;
}

/* closed forms (derived in the header) */
static double M_closed_inc(int l) {
  double L = l * (l + 1.0);
  return 2.0 * L / ((2.0 * l - 1) * (2.0 * l + 1) * (2.0 * l + 3));
}
static double M_closed_comp(int l, double lam) /* mu = 1 */
{
  double D = (2.0 * l - 1) * (2.0 * l + 3);
  return ((lam + 3.0) * D + 3.0 * lam + 7.0) / (2.0 * (lam + 2.0) * (2.0 * l + 1) * D);
}
/* inextensible membrane (header, section 4): M_l = 1/Z_l (Milner-Safran / Seifert) */
static double M_closed_inext(int l) {
  double L = l * (l + 1.0);
  return L / ((2.0 * l + 1) * (2.0 * L - 1));
}
static double M_closed_inext_comp(int l, double lam) /* mu = 1 */
{
  double L = l * (l + 1.0);
  return L * ((lam + 3) * (lam + 3) * L + lam + 2) /
         ((2.0 * l + 1) * (lam + 2) * (lam * L * (2 * L - 1) + 6 * L * L + 2 * L - 4));
}
static double
Sig_closed_inext(int l, double lam) /* tension amplitude per unit normal force; lam = inf ok */
{
  double L = l * (l + 1.0);
  if (isinf(lam)) return 1.0 / (2 * L - 1);
  return ((lam + 5) * L - 2) / (lam * L * (2 * L - 1) + 6 * L * L + 2 * L - 4);
}

/* Direct quadrature of the Kelvin (nu < 1/2) / Oseen (nu = 1/2) tensor over
 * the unit sphere: u(x) = \oint G(x - y) f(y) dA_y,
 *   G = [(3 - 4 nu) I / r + r r^T / r^3] / (16 pi mu (1 - nu)),
 * f = P_l(cos th_y) n_y.  The 1/r singularity is removed by geodesic polar
 * coordinates (gam, psi) centred at the target x: dA = sin(gam) dgam dpsi and
 * sin(gam)/r = cos(gam/2).  Gauss in gam, trapezoid in psi (periodic).
 * Returns u_l = (2l+1)/2 \int u_n P_l dcos(th); *dev = max over the targets
 * of |u_n - u_l P_l| / |u_l| (0 if the response is a pure P_l). */
static double kelvin_quadrature(int l, double nu, int nth, int ng, int nps, double *dev) {
  double *xt = xmalloc(sizeof(double) * nth), *wt = xmalloc(sizeof(double) * nth);
  double *xg = xmalloc(sizeof(double) * ng), *wg = xmalloc(sizeof(double) * ng);
  double *un = xmalloc(sizeof(double) * nth);
  gauleg(nth, xt, wt);
  gauleg(ng, xg, wg);
  double C = 1.0 / (16.0 * M_PI * (1.0 - nu));
  double ul = 0.0;
  for (int i = 0; i < nth; i++) {
    double c0 = xt[i], s0 = sqrt(1.0 - c0 * c0);
    double x[3] = {s0, 0.0, c0}, e1[3] = {c0, 0.0, -s0}, e2[3] = {0.0, 1.0, 0.0};
    double sum = 0.0;
    for (int g = 0; g < ng; g++) {
      double gam = 0.5 * M_PI * (xg[g] + 1.0), wgam = 0.5 * M_PI * wg[g];
      double cg = cos(gam), sg = sin(gam);
      for (int p = 0; p < nps; p++) {
        double psi = 2.0 * M_PI * p / nps, wpsi = 2.0 * M_PI / nps;
        double cp = cos(psi), sp = sin(psi), y[3], rv[3];
        for (int d = 0; d < 3; d++) {
          y[d] = cg * x[d] + sg * (cp * e1[d] + sp * e2[d]);
          rv[d] = x[d] - y[d];
        }
        double r = sqrt(rv[0] * rv[0] + rv[1] * rv[1] + rv[2] * rv[2]);
        double fy = legendre(l, y[2]);
        double rf = (rv[0] * y[0] + rv[1] * y[1] + rv[2] * y[2]) * fy;
        double xr = rv[0] * x[0] + rv[1] * x[1] + rv[2] * x[2];
        double xy = x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
        /* x . G f * sin(gam), written with sin(gam)/r and sin(gam)/r^3 */
        double sr = sg / r;
        double val = C * ((3.0 - 4.0 * nu) * xy * fy * sr + xr * rf * sr / (r * r));
        sum += val * wgam * wpsi;
      }
    }
    un[i] = sum;
    ul += 0.5 * (2 * l + 1) * wt[i] * sum * legendre(l, c0);
  }
  double md = 0.0;
  for (int i = 0; i < nth; i++) {
    double d = fabs(un[i] - ul * legendre(l, xt[i])) / fabs(ul);
    if (d > md) md = d;
  }
  *dev = md;
  free(xt);
  free(wt);
  free(xg);
  free(wg);
  free(un);
  return ul;
}

/* Surface r(th) = 1 + delta P_l(cos th): meridian geometry, principal
 * curvatures with the sphere's c = +1 (outward normal n = (-z', rho')/s'). */
static void shape_geom(int l, double delta, double th, double *rho, double *sp, double *H,
                       double *K, double *rn) {
  double P[64], dP[64], d2P[64], c = cos(th), s = sin(th);
  legendre_all(l, c, P, dP, d2P);
  double r = 1.0 + delta * P[l];
  double r1 = -delta * s * dP[l];
  double r2 = delta * (s * s * d2P[l] - c * dP[l]);
  double R = r * s, R1 = r1 * s + r * c, R2 = r2 * s + 2 * r1 * c - r * s;
  double Z1 = r1 * c - r * s, Z2 = r2 * c - 2 * r1 * s - r * c;
  double S = sqrt(R1 * R1 + Z1 * Z1);
  double c1 = (R2 * Z1 - Z2 * R1) / (S * S * S);
  double c2 = -Z1 / (S * R);
  *rho = R;
  *sp = S;
  *H = 0.5 * (c1 + c2);
  *K = c1 * c2;
  /* r_hat . n  (radial unit vector dotted with the outward normal) */
  if (rn) *rn = (s * (-Z1) + c * R1) / S;
}

/* E/k = (1/2) \oint H^2 dA = pi \int_0^pi H^2 rho s' dth */
static double shape_energy(int l, double delta) {
  int n = 200;
  double x[200], w[200], E = 0.0;
  gauleg(n, x, w);
  for (int i = 0; i < n; i++) {
    double th = 0.5 * M_PI * (x[i] + 1.0), rho, sp, H, K;
    shape_geom(l, delta, th, &rho, &sp, &H, &K, NULL);
    E += 0.5 * M_PI * w[i] * M_PI * H * H * rho * sp;
  }
  return E;
}

/* Normal force density on the fluid (per unit area, outward positive):
 *   f_n = (k/2) [ Lap_s H + 2 H (H^2 - K) ]     (k = 1)
 * Lap_s H = (1/(rho s')) d/dth (rho/s' dH/dth), derivatives by central
 * differences of the analytic H(th). */
static double shape_force(int l, double delta, double th) {
  const double h = 2e-3;
  double g[2];
  for (int j = 0; j < 2; j++) {
    double t = th + (j ? 0.5 : -0.5) * h, rho, sp, H, K, Hp, Hm;
    shape_geom(l, delta, t, &rho, &sp, &H, &K, NULL);
    double a1, a2, a3, a4;
    shape_geom(l, delta, t + 0.5 * h, &a1, &a2, &Hp, &a3, NULL);
    shape_geom(l, delta, t - 0.5 * h, &a1, &a2, &Hm, &a4, NULL);
    g[j] = rho / sp * (Hp - Hm) / h;
  }
  double rho, sp, H, K;
  shape_geom(l, delta, th, &rho, &sp, &H, &K, NULL);
  double lap = (g[1] - g[0]) / h / (rho * sp);
  return 0.5 * (lap + 2.0 * H * (H * H - K));
}

/* P_l component of f_n: (2l+1)/2 \int_0^pi f_n P_l(cos th) sin th dth, and the
 * virtual work -\oint f_n (dx/ddelta . n) dA = -2 pi \int f_n P_l (r_hat.n) rho s' dth */
static void shape_force_moments(int l, double delta, double *fl, double *vw) {
  int n = 120;
  double x[120], w[120], a = 0.0, b = 0.0;
  gauleg(n, x, w);
  for (int i = 0; i < n; i++) {
    double th = 0.5 * M_PI * (x[i] + 1.0), wt = 0.5 * M_PI * w[i];
    double f = shape_force(l, delta, th), rho, sp, H, K, rn;
    shape_geom(l, delta, th, &rho, &sp, &H, &K, &rn);
    double P = legendre(l, cos(th));
    a += wt * 0.5 * (2 * l + 1) * f * P * sin(th);
    b += -wt * 2.0 * M_PI * f * P * rn * rho * sp;
  }
  *fl = a;
  *vw = b;
}

/* ------------------------------------------------------------------------- */
/* Part B: structured, circle-conforming, isoparametric P2 mesh               */
/* ------------------------------------------------------------------------- */

enum { F_AXIS = 1, F_WALL = 2, F_ARC = 4, F_VERT = 8 };

typedef struct {
  int nn;
  double *x;           /* 2*nn: (rho, z) */
  unsigned char *flag; /* F_* bits */
  int ne;
  int *en;             /* 6*ne: vertices 0,1,2 then mid(01), mid(12), mid(20) */
  unsigned char *side; /* 0 inside the sphere, 1 outside */
  int narc;            /* arc nodes ordered by theta: vertex, mid, vertex, ... */
  int *arc;
  double Rb, Zb, hmax;
  int N;
} Mesh;

typedef struct {
  int type;
  double p0[2], p1[2], th0, th1;
} Curve;
typedef struct {
  Curve b, t, l, r;
  int ns, nt;
  double beta;
  int side;
} Block;

static void curve_eval(const Curve *c, double s, double *x) {
  if (c->type == 0) {
    x[0] = c->p0[0] + s * (c->p1[0] - c->p0[0]);
    x[1] = c->p0[1] + s * (c->p1[1] - c->p0[1]);
  } else {
    double th = c->th0 + s * (c->th1 - c->th0);
    x[0] = sin(th);
    x[1] = cos(th);
  }
}

static Curve cline(double a0, double a1, double b0, double b1) {
  Curve c;
  memset(&c, 0, sizeof c);
  c.type = 0;
  c.p0[0] = a0;
  c.p0[1] = a1;
  c.p1[0] = b0;
  c.p1[1] = b1;
  return c;
}
static Curve carc(double t0, double t1) {
  Curve c;
  memset(&c, 0, sizeof c);
  c.type = 1;
  c.th0 = t0;
  c.th1 = t1;
  return c;
}

/* transfinite interpolation, t graded by (exp(beta t) - 1)/(exp(beta) - 1) */
static void block_map(const Block *B, double s, double t, double *x) {
  if (B->beta > 0) t = (exp(B->beta * t) - 1.0) / (exp(B->beta) - 1.0);
  double xb[2], xt[2], xl[2], xr[2], c00[2], c10[2], c01[2], c11[2];
  curve_eval(&B->b, s, xb);
  curve_eval(&B->t, s, xt);
  curve_eval(&B->l, t, xl);
  curve_eval(&B->r, t, xr);
  curve_eval(&B->b, 0, c00);
  curve_eval(&B->b, 1, c10);
  curve_eval(&B->t, 0, c01);
  curve_eval(&B->t, 1, c11);
  for (int d = 0; d < 2; d++)
    x[d] =
        (1 - t) * xb[d] + t * xt[d] + (1 - s) * xl[d] + s * xr[d] -
        ((1 - s) * (1 - t) * c00[d] + s * (1 - t) * c10[d] + (1 - s) * t * c01[d] + s * t * c11[d]);
}

static const double *g_sortx;
static int cmp_x(const void *a, const void *b) {
  double xa = g_sortx[2 * *(const int *)a], xb = g_sortx[2 * *(const int *)b];
  return (xa > xb) - (xa < xb);
}
static const double *g_sortth;
static int cmp_th(const void *a, const void *b) {
  double xa = g_sortth[*(const int *)a], xb = g_sortth[*(const int *)b];
  return (xa > xb) - (xa < xb);
}

/* Square box Rb = Zb.  N = cells on a quarter of the half circle (even).
 * Blocks: inner half-square [0,a]x[-a,a]; three inner ring blocks square ->
 * circle; three outer blocks circle -> box (top wall, side wall, bottom wall),
 * radially graded; arc breakpoints at th = pi/4, 3pi/4 (box corners).
 * Kept whole (214 lines): one computation over shared buffers with one exit. */
static Mesh mesh_build(double Rb, int N, int Kout) {
  const double a = 0.5, q = M_PI / 4, q3 = 3 * M_PI / 4;
  const double sq = sqrt(0.5);
  double beta = log(4.0 * Rb / M_PI);
  if (beta < 0) beta = 0;
  int min_ = N / 2 > 0 ? N / 2 : 1, mout = Kout * N / 2;
  Block B[7];
  memset(B, 0, sizeof B);
  /* center */
  B[0].b = cline(0, -a, a, -a);
  B[0].t = cline(0, a, a, a);
  B[0].l = cline(0, -a, 0, a);
  B[0].r = cline(a, -a, a, a);
  B[0].ns = N;
  B[0].nt = 2 * N;
  B[0].side = 0;
  /* inner top */
  B[1].b = cline(0, a, a, a);
  B[1].t = carc(0, q);
  B[1].l = cline(0, a, 0, 1);
  B[1].r = cline(a, a, sq, sq);
  B[1].ns = N;
  B[1].nt = min_;
  B[1].side = 0;
  /* inner right */
  B[2].b = cline(a, a, a, -a);
  B[2].t = carc(q, q3);
  B[2].l = cline(a, a, sq, sq);
  B[2].r = cline(a, -a, sq, -sq);
  B[2].ns = 2 * N;
  B[2].nt = min_;
  B[2].side = 0;
  /* inner bottom */
  B[3].b = cline(a, -a, 0, -a);
  B[3].t = carc(q3, M_PI);
  B[3].l = cline(a, -a, sq, -sq);
  B[3].r = cline(0, -a, 0, -1);
  B[3].ns = N;
  B[3].nt = min_;
  B[3].side = 0;
  /* outer top */
  B[4].b = carc(0, q);
  B[4].t = cline(0, Rb, Rb, Rb);
  B[4].l = cline(0, 1, 0, Rb);
  B[4].r = cline(sq, sq, Rb, Rb);
  B[4].ns = N;
  B[4].nt = mout;
  B[4].side = 1;
  B[4].beta = beta;
  /* outer right */
  B[5].b = carc(q, q3);
  B[5].t = cline(Rb, Rb, Rb, -Rb);
  B[5].l = cline(sq, sq, Rb, Rb);
  B[5].r = cline(sq, -sq, Rb, -Rb);
  B[5].ns = 2 * N;
  B[5].nt = mout;
  B[5].side = 1;
  B[5].beta = beta;
  /* outer bottom */
  B[6].b = carc(q3, M_PI);
  B[6].t = cline(Rb, -Rb, 0, -Rb);
  B[6].l = cline(sq, -sq, Rb, -Rb);
  B[6].r = cline(0, -1, 0, -Rb);
  B[6].ns = N;
  B[6].nt = mout;
  B[6].side = 1;
  B[6].beta = beta;

  int np = 0, ne = 0;
  for (int k = 0; k < 7; k++) {
    np += (2 * B[k].ns + 1) * (2 * B[k].nt + 1);
    ne += 2 * B[k].ns * B[k].nt;
  }
  double *px = xmalloc(sizeof(double) * 2 * np);
  unsigned char *pv = xmalloc((size_t)np);
  int off = 0;
  int boff[7];
  for (int k = 0; k < 7; k++) {
    boff[k] = off;
    int ni = 2 * B[k].ns + 1, nj = 2 * B[k].nt + 1;
    for (int j = 0; j < nj; j++)
      for (int i = 0; i < ni; i++) {
        block_map(&B[k], (double)i / (ni - 1), (double)j / (nj - 1), px + 2 * off);
        pv[off] = (i % 2 == 0 && j % 2 == 0);
        off++;
      }
  }
  /* merge coincident points */
  int *ord = xmalloc(sizeof(int) * np), *gid = xmalloc(sizeof(int) * np);
  for (int i = 0; i < np; i++) {
    ord[i] = i;
    gid[i] = -1;
  }
  g_sortx = px;
  qsort(ord, (size_t)np, sizeof(int), cmp_x);
  const double tol = 1e-9;
  int nn = 0;
  for (int ii = 0; ii < np; ii++) {
    int i = ord[ii];
    if (gid[i] >= 0) continue;
    gid[i] = nn;
    for (int jj = ii + 1; jj < np && px[2 * ord[jj]] - px[2 * i] < tol; jj++) {
      int j = ord[jj];
      if (gid[j] < 0 && fabs(px[2 * j + 1] - px[2 * i + 1]) < tol) gid[j] = nn;
    }
    nn++;
  }
  Mesh M;
  memset(&M, 0, sizeof M);
  M.nn = nn;
  M.Rb = Rb;
  M.Zb = Rb;
  M.N = N;
  M.x = xmalloc(sizeof(double) * 2 * nn);
  M.flag = xcalloc((size_t)nn, 1);
  for (int i = 0; i < np; i++) {
    int g = gid[i];
    M.x[2 * g] = px[2 * i];
    M.x[2 * g + 1] = px[2 * i + 1];
    if (pv[i]) M.flag[g] |= F_VERT;
  }
  for (int g = 0; g < nn; g++) {
    double *x = M.x + 2 * g;
    if (fabs(x[0]) < 1e-9) {
      x[0] = 0.0;
      M.flag[g] |= F_AXIS;
    }
    if (fabs(x[0] - Rb) < 1e-9) {
      x[0] = Rb;
      M.flag[g] |= F_WALL;
    }
    if (fabs(fabs(x[1]) - Rb) < 1e-9) {
      x[1] = x[1] > 0 ? Rb : -Rb;
      M.flag[g] |= F_WALL;
    }
    double r = hypot(x[0], x[1]);
    if (fabs(r - 1.0) < 1e-9) {
      x[0] /= r;
      x[1] /= r;
      M.flag[g] |= F_ARC;
    }
  }
  /* elements */
  M.ne = ne;
  M.en = xmalloc(sizeof(int) * 6 * ne);
  M.side = xmalloc((size_t)ne);
  int e = 0;
  double hmax = 0.0;
  for (int k = 0; k < 7; k++) {
    int ni = 2 * B[k].ns + 1;
#define LID(i, j) gid[boff[k] + (j)*ni + (i)]
    for (int cj = 0; cj < B[k].nt; cj++)
      for (int ci = 0; ci < B[k].ns; ci++) {
        int i = 2 * ci, j = 2 * cj;
        int v00 = LID(i, j), v10 = LID(i + 2, j), v11 = LID(i + 2, j + 2), v01 = LID(i, j + 2);
        int m0 = LID(i + 1, j), m1 = LID(i + 2, j + 1), m2 = LID(i + 1, j + 2), m3 = LID(i, j + 1);
        int cc = LID(i + 1, j + 1);
        int T[2][6] = {{v00, v10, v11, m0, m1, cc}, {v00, v11, v01, cc, m2, m3}};
        for (int t = 0; t < 2; t++) {
          int *en = M.en + 6 * e;
          memcpy(en, T[t], sizeof(int) * 6);
          const double *A0 = M.x + 2 * en[0], *A1 = M.x + 2 * en[1], *A2 = M.x + 2 * en[2];
          double det = (A1[0] - A0[0]) * (A2[1] - A0[1]) - (A1[1] - A0[1]) * (A2[0] - A0[0]);
          if (det < 0) { /* swap vertices 1,2 and mids 3,5 */
            int tmp = en[1];
            en[1] = en[2];
            en[2] = tmp;
            tmp = en[3];
            en[3] = en[5];
            en[5] = tmp;
          }
          for (int v = 0; v < 3; v++) {
            const double *p = M.x + 2 * en[v], *qq = M.x + 2 * en[(v + 1) % 3];
            double h = hypot(p[0] - qq[0], p[1] - qq[1]);
            if (h > hmax) hmax = h;
          }
          M.side[e] = (unsigned char)B[k].side;
          e++;
        }
      }
#undef LID
  }
  M.hmax = hmax;
  /* arc nodes sorted by theta */
  int na = 0;
  for (int g = 0; g < nn; g++)
    if (M.flag[g] & F_ARC) na++;
  M.narc = na;
  M.arc = xmalloc(sizeof(int) * na);
  double *th = xmalloc(sizeof(double) * nn);
  na = 0;
  for (int g = 0; g < nn; g++)
    if (M.flag[g] & F_ARC) {
      M.arc[na++] = g;
      th[g] = atan2(M.x[2 * g], M.x[2 * g + 1]);
    }
  g_sortth = th;
  qsort(M.arc, (size_t)na, sizeof(int), cmp_th);
  free(th);
  if (na % 2 != 1) {
    fprintf(stderr, "mesh: bad arc node count %d\n", na);
    exit(2);
  }
  for (int i = 0; i < na; i++)
    if (!!(M.flag[M.arc[i]] & F_VERT) != (i % 2 == 0)) {
      fprintf(stderr, "mesh: arc vertex/mid alternation broken\n");
      exit(2);
    }
  free(px);
  free(pv);
  free(ord);
  free(gid);
  return M;
}

static void mesh_free(Mesh *M) {
  free(M->x);
  free(M->flag);
  free(M->en);
  free(M->side);
  free(M->arc);
  memset(M, 0, sizeof *M);
}

/* ------------------------------------------------------------------------- */
/* Part C: axisymmetric FE (P2 velocity; P1 pressure discontinuous across the */
/* membrane) and MUMPS                                                        */
/* ------------------------------------------------------------------------- */

enum { FORM_TH = 0, FORM_PEN = 1, FORM_MIX = 2 };
static const char *form_name[3] = {"TH", "P2pen", "THmix"};

/* isoparametric P2 at reference (xi, eta) */
static void p2_eval(const Mesh *M, const int *en, double xi, double eta, double *N, double dN[6][2],
                    double *detJ, double *X) {
  double L1 = 1 - xi - eta, L2 = xi, L3 = eta;
  double dL[3][2] = {{-1, -1}, {1, 0}, {0, 1}};
  double Lv[3] = {L1, L2, L3};
  double dr[6][2];
  for (int k = 0; k < 3; k++) {
    N[k] = Lv[k] * (2 * Lv[k] - 1);
    dr[k][0] = (4 * Lv[k] - 1) * dL[k][0];
    dr[k][1] = (4 * Lv[k] - 1) * dL[k][1];
  }
  for (int k = 0; k < 3; k++) {
    int a = k, b = (k + 1) % 3;
    N[3 + k] = 4 * Lv[a] * Lv[b];
    dr[3 + k][0] = 4 * (Lv[a] * dL[b][0] + Lv[b] * dL[a][0]);
    dr[3 + k][1] = 4 * (Lv[a] * dL[b][1] + Lv[b] * dL[a][1]);
  }
  double J[2][2] = {{0, 0}, {0, 0}};
  X[0] = X[1] = 0;
  for (int k = 0; k < 6; k++) {
    const double *p = M->x + 2 * en[k];
    X[0] += N[k] * p[0];
    X[1] += N[k] * p[1];
    for (int d = 0; d < 2; d++) {
      J[d][0] += p[d] * dr[k][0];
      J[d][1] += p[d] * dr[k][1];
    }
  }
  double det = J[0][0] * J[1][1] - J[0][1] * J[1][0];
  double Ji[2][2] = {{J[1][1] / det, -J[0][1] / det}, {-J[1][0] / det, J[0][0] / det}};
  for (int k = 0; k < 6; k++) {
    dN[k][0] = dr[k][0] * Ji[0][0] + dr[k][1] * Ji[1][0];
    dN[k][1] = dr[k][0] * Ji[0][1] + dr[k][1] * Ji[1][1];
  }
  *detJ = det;
}

/* collapsed (Duffy) Gauss rule on the reference triangle */
static int g_nq = 5;
static int tri_rule(double *xi, double *eta, double *w) {
  double x[16], ww[16];
  gauleg(g_nq, x, ww);
  int n = 0;
  for (int i = 0; i < g_nq; i++)
    for (int j = 0; j < g_nq; j++) {
      double u = 0.5 * (x[i] + 1), v = 0.5 * (x[j] + 1);
      xi[n] = u;
      eta[n] = v * (1 - u);
      w[n] = 0.25 * ww[i] * ww[j] * (1 - u);
      n++;
    }
  return n;
}

/* Load vector of the membrane force density P_m(cos th) n on the unit circle,
 * b_i = \int_Gamma f . phi_i rho ds (the common factor 2 pi dropped from all
 * integrals), along the quadratic arc edges. Full velocity numbering. */
static void arc_load(const Mesh *M, int m, double *b) {
  double gx[8], gw[8];
  gauleg(8, gx, gw);
  memset(b, 0, sizeof(double) * 2 * M->nn);
  for (int e = 0; e + 2 < M->narc; e += 2) {
    int n3[3] = {M->arc[e], M->arc[e + 1], M->arc[e + 2]};
    for (int q = 0; q < 8; q++) {
      double t = 0.5 * (gx[q] + 1), w = 0.5 * gw[q];
      double phi[3] = {(1 - t) * (1 - 2 * t), 4 * t * (1 - t), t * (2 * t - 1)};
      double dphi[3] = {4 * t - 3, 4 - 8 * t, 4 * t - 1};
      double X[2] = {0, 0}, dX[2] = {0, 0};
      for (int k = 0; k < 3; k++)
        for (int d = 0; d < 2; d++) {
          X[d] += phi[k] * M->x[2 * n3[k] + d];
          dX[d] += dphi[k] * M->x[2 * n3[k] + d];
        }
      double r = hypot(X[0], X[1]), ds = hypot(dX[0], dX[1]);
      double nrm[2] = {X[0] / r, X[1] / r};
      double f = legendre(m, X[1] / r);
      for (int k = 0; k < 3; k++)
        for (int d = 0; d < 2; d++) b[2 * n3[k] + d] += w * ds * X[0] * f * nrm[d] * phi[k];
    }
  }
}

/* Membrane: inext = 0 free (bending force only); inext = 1 locally
 * inextensible, tension multiplier of degree tdeg (1: continuous P1 on the arc
 * vertices, 2: continuous P2 on all arc nodes); area_free = 1 removes the l = 0
 * (uniform) tension from the multiplier space, i.e. the total area may change
 * (header, section 4). Trailing members zero = the free membrane. */
typedef struct {
  int form;
  double mu, lam;
  int inext, tdeg, area_free;
} Form;

/* number of tension unknowns on the arc and the tension dof of arc position a
 * (-1: none) */
static int tension_count(const Mesh *M, int tdeg) {
  return tdeg == 2 ? M->narc : (M->narc + 1) / 2;
}

/* Arc edge j (arc positions 2j, 2j+1, 2j+2): local constraint matrix
 *   Bl[i][2k+d] = \int psi_i (div_s phi_k e_d) rho ds,
 *   div_s v = t.dv/ds + v_rho/rho  (surface divergence of an axisymmetric field
 *   on the surface of revolution; on the unit sphere it equals
 *   2 v_n + (1/sin th) d/dth(sin th v_th)),
 * computed on the discrete (isoparametric quadratic) arc as
 *   \int psi_i [rho (dX . dv)/|dX| + v_rho |dX|] dt  (no 1/rho singularity),
 * and ml[i] = \int psi_i rho ds (tension mass, for the l = 0 treatment).
 * td[i] = tension dofs, returns their number (2 for P1, 3 for P2). */
static int arc_tension_edge(const Mesh *M, int j, int tdeg, double Bl[3][6], double ml[3],
                            int td[3]) {
  double gx[8], gw[8];
  gauleg(8, gx, gw);
  int n3[3] = {M->arc[2 * j], M->arc[2 * j + 1], M->arc[2 * j + 2]};
  int nt = tdeg == 2 ? 3 : 2;
  if (tdeg == 2) {
    td[0] = 2 * j;
    td[1] = 2 * j + 1;
    td[2] = 2 * j + 2;
  } else {
    td[0] = j;
    td[1] = j + 1;
    td[2] = -1;
  }
  memset(Bl, 0, sizeof(double) * 18);
  memset(ml, 0, sizeof(double) * 3);
  for (int q = 0; q < 8; q++) {
    double t = 0.5 * (gx[q] + 1), w = 0.5 * gw[q];
    double phi[3] = {(1 - t) * (1 - 2 * t), 4 * t * (1 - t), t * (2 * t - 1)};
    double dphi[3] = {4 * t - 3, 4 - 8 * t, 4 * t - 1};
    double psi[3];
    if (tdeg == 2)
      memcpy(psi, phi, sizeof psi);
    else {
      psi[0] = 1 - t;
      psi[1] = t;
      psi[2] = 0;
    }
    double X[2] = {0, 0}, dX[2] = {0, 0};
    for (int k = 0; k < 3; k++)
      for (int d = 0; d < 2; d++) {
        X[d] += phi[k] * M->x[2 * n3[k] + d];
        dX[d] += dphi[k] * M->x[2 * n3[k] + d];
      }
    double ds = hypot(dX[0], dX[1]);
    for (int i = 0; i < nt; i++) {
      ml[i] += w * psi[i] * X[0] * ds;
      for (int k = 0; k < 3; k++)
        for (int d = 0; d < 2; d++)
          Bl[i][2 * k + d] +=
              w * psi[i] * (X[0] * dX[d] * dphi[k] / ds + (d == 0 ? phi[k] * ds : 0.0));
    }
  }
  return nt;
}

/* Legendre components sig_m = (2m+1)/2 \int sigma P_m sin th dth, m = 0..lmax, of a
 * tension field given by its dofs, and the relative L2 (sin th dth) norm of the
 * remainder sigma - sum_m sig_m P_m (a measure of non-smooth content) */
static void tension_components(const Mesh *M, int tdeg, const double *sg, int lmax, double *comp,
                               double *resid) {
  double gx[8], gw[8], P[64], dP[64], d2P[64];
  gauleg(8, gx, gw);
  for (int m = 0; m <= lmax; m++) comp[m] = 0;
  for (int pass = 0; pass < 2; pass++) {
    double num = 0, den = 0;
    for (int j = 0; 2 * j + 2 < M->narc; j++) {
      int n3[3] = {M->arc[2 * j], M->arc[2 * j + 1], M->arc[2 * j + 2]};
      for (int q = 0; q < 8; q++) {
        double t = 0.5 * (gx[q] + 1), w = 0.5 * gw[q];
        double phi[3] = {(1 - t) * (1 - 2 * t), 4 * t * (1 - t), t * (2 * t - 1)};
        double dphi[3] = {4 * t - 3, 4 - 8 * t, 4 * t - 1};
        double X[2] = {0, 0}, dX[2] = {0, 0};
        for (int k = 0; k < 3; k++)
          for (int d = 0; d < 2; d++) {
            X[d] += phi[k] * M->x[2 * n3[k] + d];
            dX[d] += dphi[k] * M->x[2 * n3[k] + d];
          }
        double sv = tdeg == 2 ? phi[0] * sg[2 * j] + phi[1] * sg[2 * j + 1] + phi[2] * sg[2 * j + 2]
                              : (1 - t) * sg[j] + t * sg[j + 1];
        double wt = w * X[0] * hypot(dX[0], dX[1]);
        legendre_all(lmax, X[1] / hypot(X[0], X[1]), P, dP, d2P);
        if (pass == 0) {
          for (int m = 0; m <= lmax; m++) comp[m] += 0.5 * (2 * m + 1) * wt * sv * P[m];
        } else {
          double sm = 0;
          for (int m = 0; m <= lmax; m++) sm += comp[m] * P[m];
          num += wt * (sv - sm) * (sv - sm);
          den += wt * sv * sv;
        }
      }
    }
    if (pass == 1 && resid) *resid = den > 0 ? sqrt(num / den) : 0.0;
  }
}

typedef struct {
  int nunk, nvel, npres;
  double t_asm, t_solve;
  long long nnz;
} SolveInfo;

/* Solve for nrhs right-hand sides: load col c = membrane force P_{loads[c]}
 * (loads[c] < 0: none) plus bext[c] (a load vector in the full velocity
 * numbering, or NULL); Dirichlet data gD[c] (full velocity vector, walls and
 * axis) or NULL for no-slip. Output U[c]: full velocity vector (2 nn); Sg[c]
 * (if Sg and Sg[c]): the tension dofs (inextensible membrane). */
static int fe_solve_ext(const Mesh *M, Form F, int nrhs, const int *loads, double **gD,
                        double **bext, double **U, double **Sg, SolveInfo *info);
/* Kept whole (216 lines): one computation over shared buffers with one exit. */
static int fe_solve_ext(const Mesh *M, Form F, int nrhs, const int *loads, double **gD,
                        double **bext, double **U, double **Sg, SolveInfo *info) {
  double t0 = now_sec();
  int nn = M->nn, nv = 2 * nn;
  int *eq = xmalloc(sizeof(int) * nv);
  int nf = 0;
  for (int i = 0; i < nn; i++) {
    int fl = M->flag[i];
    eq[2 * i] = (fl & (F_WALL | F_AXIS)) ? -1 : nf++;
    eq[2 * i + 1] = (fl & F_WALL) ? -1 : nf++;
  }
  int nvf = nf;
  int haveP = F.form != FORM_PEN;
  int *pid = NULL, npres = 0;
  if (haveP) {
    pid = xmalloc(sizeof(int) * 2 * nn);
    for (int i = 0; i < 2 * nn; i++) pid[i] = -1;
    for (int e = 0; e < M->ne; e++)
      for (int k = 0; k < 3; k++) {
        int key = M->side[e] * nn + M->en[6 * e + k];
        if (pid[key] < 0) pid[key] = npres++;
      }
  }
  int *peq = NULL;
  if (haveP) {
    peq = xmalloc(sizeof(int) * (npres > 0 ? npres : 1));
    int pinned = -1;
    if (F.form == FORM_TH) { /* pin one outside pressure at a wall vertex */
      for (int i = 0; i < nn && pinned < 0; i++)
        if ((M->flag[i] & F_WALL) && (M->flag[i] & F_VERT) && pid[nn + i] >= 0)
          pinned = pid[nn + i];
    }
    for (int p = 0; p < npres; p++) peq[p] = (p == pinned) ? -1 : nf++;
  }
  /* tension multiplier on the arc (inextensible membrane), then the scalar
   * multiplier of the zero-mean condition when the l = 0 tension is removed */
  int ntens = F.inext ? tension_count(M, F.tdeg) : 0, t0eq = nf, ceq = -1;
  nf += ntens;
  if (F.inext && F.area_free) ceq = nf++;
  int n = nf;
  int nloc = haveP ? 15 : 12;
  long long cap =
      (long long)M->ne * nloc * (nloc + 1) / 2 + (long long)(M->narc / 2) * 21 + ntens + 16;
  MUMPS_INT *irn = xmalloc(sizeof(MUMPS_INT) * cap), *jcn = xmalloc(sizeof(MUMPS_INT) * cap);
  double *av = xmalloc(sizeof(double) * cap);
  long long nnz = 0;
  double *rhs = xcalloc((size_t)n * nrhs, sizeof(double));
  double xi[256], eta[256], wq[256];
  int nq = tri_rule(xi, eta, wq);
  double lampen = F.form == FORM_PEN ? F.lam : 0.0;
  for (int e = 0; e < M->ne; e++) {
    const int *en = M->en + 6 * e;
    double K[15][15];
    memset(K, 0, sizeof K);
    for (int q = 0; q < nq; q++) {
      double Nf[6], dN[6][2], det, X[2];
      p2_eval(M, en, xi[q], eta[q], Nf, dN, &det, X);
      double rho = X[0], w = wq[q] * fabs(det) * rho;
      double ev[12][4], dv[12];
      for (int k = 0; k < 6; k++) {
        ev[2 * k][0] = dN[k][0];
        ev[2 * k][1] = 0;
        ev[2 * k][2] = 0.5 * dN[k][1];
        ev[2 * k][3] = Nf[k] / rho;
        dv[2 * k] = dN[k][0] + Nf[k] / rho;
        ev[2 * k + 1][0] = 0;
        ev[2 * k + 1][1] = dN[k][1];
        ev[2 * k + 1][2] = 0.5 * dN[k][0];
        ev[2 * k + 1][3] = 0;
        dv[2 * k + 1] = dN[k][1];
      }
      for (int a = 0; a < 12; a++)
        for (int b = a; b < 12; b++) {
          double v = 2 * F.mu *
                         (ev[a][0] * ev[b][0] + ev[a][1] * ev[b][1] + 2 * ev[a][2] * ev[b][2] +
                          ev[a][3] * ev[b][3]) +
                     lampen * dv[a] * dv[b];
          K[a][b] += w * v;
        }
      if (haveP) {
        double Lb[3] = {1 - xi[q] - eta[q], xi[q], eta[q]};
        for (int p = 0; p < 3; p++) {
          for (int a = 0; a < 12; a++) K[a][12 + p] += -w * Lb[p] * dv[a];
          if (F.form == FORM_MIX)
            for (int r = p; r < 3; r++) K[12 + p][12 + r] += -w * Lb[p] * Lb[r] / F.lam;
        }
      }
    }
    for (int a = 0; a < nloc; a++)
      for (int b = 0; b < a; b++) K[a][b] = K[b][a];
    int g[15], gfull[15];
    for (int k = 0; k < 6; k++) {
      gfull[2 * k] = 2 * en[k];
      gfull[2 * k + 1] = 2 * en[k] + 1;
      g[2 * k] = eq[2 * en[k]];
      g[2 * k + 1] = eq[2 * en[k] + 1];
    }
    if (haveP)
      for (int p = 0; p < 3; p++) {
        gfull[12 + p] = -1;
        g[12 + p] = peq[pid[M->side[e] * nn + en[p]]];
      }
    for (int a = 0; a < nloc; a++) {
      if (g[a] < 0) continue;
      for (int b = a; b < nloc; b++) {
        if (g[b] < 0) continue;
        int i = g[a], j = g[b];
        if (i > j) {
          int t = i;
          i = j;
          j = t;
        }
        irn[nnz] = i + 1;
        jcn[nnz] = j + 1;
        av[nnz] = K[a][b];
        nnz++;
      }
      /* Dirichlet lift */
      for (int b = 0; b < 12; b++) {
        if (g[b] >= 0) continue;
        for (int c = 0; c < nrhs; c++)
          if (gD && gD[c]) rhs[(size_t)c * n + g[a]] -= K[a][b] * gD[c][gfull[b]];
      }
    }
  }
  if (F.inext) {
    for (int j = 0; 2 * j + 2 < M->narc; j++) {
      double Bl[3][6], ml[3];
      int td[3];
      int nt = arc_tension_edge(M, j, F.tdeg, Bl, ml, td);
      for (int i = 0; i < nt; i++) {
        int ti = t0eq + td[i];
        for (int k = 0; k < 3; k++)
          for (int d = 0; d < 2; d++) {
            int full = 2 * M->arc[2 * j + k] + d, gv = eq[full];
            if (gv >= 0) {
              irn[nnz] = gv + 1;
              jcn[nnz] = ti + 1;
              av[nnz] = Bl[i][2 * k + d];
              nnz++;
            } else {
              for (int c = 0; c < nrhs; c++)
                if (gD && gD[c]) rhs[(size_t)c * n + ti] -= Bl[i][2 * k + d] * gD[c][full];
            }
          }
        if (ceq >= 0) {
          irn[nnz] = ti + 1;
          jcn[nnz] = ceq + 1;
          av[nnz] = ml[i];
          nnz++;
        }
      }
    }
  }
  double *bl = xmalloc(sizeof(double) * nv);
  for (int c = 0; c < nrhs; c++) {
    if (loads[c] >= 0) {
      arc_load(M, loads[c], bl);
      for (int i = 0; i < nv; i++)
        if (eq[i] >= 0) rhs[(size_t)c * n + eq[i]] += bl[i];
    }
    if (bext && bext[c])
      for (int i = 0; i < nv; i++)
        if (eq[i] >= 0) rhs[(size_t)c * n + eq[i]] += bext[c][i];
  }
  free(bl);
  double t1 = now_sec();
  DMUMPS_STRUC_C id;
  memset(&id, 0, sizeof id);
  id.job = -1;
  id.par = 1;
  id.sym = (F.form == FORM_PEN && !F.inext) ? 1 : 2;
  id.comm_fortran = -987654;
  dmumps_c(&id);
  id.icntl[0] = -1;
  id.icntl[1] = -1;
  id.icntl[2] = -1;
  id.icntl[3] = 0;
  id.icntl[13] = 60;
  id.n = n;
  id.nnz = nnz;
  id.irn = irn;
  id.jcn = jcn;
  id.a = av;
  id.rhs = rhs;
  id.nrhs = nrhs;
  id.lrhs = n;
  id.job = 6;
  dmumps_c(&id);
  int ok = id.infog[0] >= 0;
  if (!ok) fprintf(stderr, "MUMPS error INFOG(1)=%d INFOG(2)=%d\n", id.infog[0], id.infog[1]);
  id.job = -2;
  dmumps_c(&id);
  double t2 = now_sec();
  for (int c = 0; c < nrhs; c++)
    for (int i = 0; i < nv; i++)
      U[c][i] = eq[i] >= 0 ? rhs[(size_t)c * n + eq[i]] : (gD && gD[c] ? gD[c][i] : 0.0);
  if (Sg)
    for (int c = 0; c < nrhs; c++)
      if (Sg[c])
        for (int i = 0; i < ntens; i++) Sg[c][i] = rhs[(size_t)c * n + t0eq + i];
  info->nunk = n;
  info->nvel = nvf;
  info->npres = haveP ? npres : 0;
  info->t_asm = t1 - t0;
  info->t_solve = t2 - t1;
  info->nnz = nnz;
  free(eq);
  free(pid);
  free(peq);
  free(irn);
  free(jcn);
  free(av);
  free(rhs);
  return ok;
}

/* Legendre components of the normal velocity on the sphere:
 * u_m = (2m+1)/2 \int_0^pi u.n P_m sin th dth = (2m+1)/2 * (b_m . U) */
static void sphere_components(const Mesh *M, const double *U, double *um) {

  double *b = xmalloc(sizeof(double) * 2 * M->nn);
  for (int m = 0; m <= LMAX_OUT; m++) {
    arc_load(M, m, b);
    double s = 0;
    for (int i = 0; i < 2 * M->nn; i++) s += b[i] * U[i];
    um[m] = 0.5 * (2 * m + 1) * s;
  }
  free(b);
}

/* relative weighted L2 error of the velocity against the exact Lamb field */
static double l2_error(const Mesh *M, const double *U, const Lamb *L) {
  double xi[256], eta[256], wq[256], num = 0, den = 0;
  int nq = tri_rule(xi, eta, wq);
  for (int e = 0; e < M->ne; e++) {
    const int *en = M->en + 6 * e;
    for (int q = 0; q < nq; q++) {
      double Nf[6], dN[6][2], det, X[2], uh[2] = {0, 0}, ue[2];
      p2_eval(M, en, xi[q], eta[q], Nf, dN, &det, X);
      for (int k = 0; k < 6; k++) {
        uh[0] += Nf[k] * U[2 * en[k]];
        uh[1] += Nf[k] * U[2 * en[k] + 1];
      }
      lamb_field(L, M->side[e], X[0], X[1], &ue[0], &ue[1]);
      double w = wq[q] * fabs(det) * X[0];
      num += w * ((uh[0] - ue[0]) * (uh[0] - ue[0]) + (uh[1] - ue[1]) * (uh[1] - ue[1]));
      den += w * (ue[0] * ue[0] + ue[1] * ue[1]);
    }
  }
  return sqrt(num / den);
}

/* ------------------------------------------------------------------------- */
/* Part D: driver                                                             */
/* ------------------------------------------------------------------------- */

static const double KAPPA = 0.25; /* kappa = k/4, k = 1 */

static double stiff(int l) /* kappa L (L-2), the normal-force stiffness of mode l */
{
  double L = l * (l + 1.0);
  return KAPPA * L * (L - 2.0);
}

static int g_kout = 0; /* override of the outer radial cell count factor (0: automatic) */
/* membrane model: --membrane free|inextensible, --tension p1|p2, --area auto|fixed|free */
static int g_inext = 0, g_tdeg = 1, g_area = -1;

static Form make_form(int form, double lam) {
  Form F;
  memset(&F, 0, sizeof F);
  F.form = form;
  F.mu = 1.0;
  F.lam = lam;
  F.inext = g_inext;
  F.tdeg = g_tdeg;
  /* auto: TH conserves the inside volume exactly, which already fixes the
   * total area to O(h^4); the l = 0 tension is then (nearly) redundant with
   * the inside pressure and is removed. THmix / P2pen: total area fixed. */
  F.area_free = g_area >= 0 ? g_area : (form == FORM_TH);
  return F;
}
static double M_unbounded(int inext, int form, int l) {
  if (inext) return form == FORM_TH ? M_closed_inext(l) : M_closed_inext_comp(l, 100.0);
  return form == FORM_TH ? M_closed_inc(l) : M_closed_comp(l, 100.0);
}
static int kout_for(double Rb) {
  if (g_kout > 0) return g_kout;
  double beta = log(4.0 * Rb / M_PI);
  double Lout = 0.5 * ((Rb - 1.0) + (Rb * sqrt(2.0) - 1.0));
  double r = Lout * beta / ((exp(beta) - 1.0) * (M_PI / 4.0));
  int k = (int)lround(2.0 * r);
  return k < 2 ? 2 : k;
}

static double order3(double a, double b, double c) /* observed order from 3 values, ratio 2 */
{
  double d1 = a - b, d2 = b - c;
  if (d1 == 0 || d2 == 0 || d1 / d2 <= 0) return NAN;
  return log(fabs(d1 / d2)) / log(2.0);
}

/* Kept whole (100 lines): one computation over shared buffers with one exit. */
static void section_analytic(void) {
  printf("\n## A. Analytic mobility, unbounded space (R = mu = k = 1, kappa = k/4)\n\n");
  Fluid inc = {1.0, 0.0, 1}, c100 = {1.0, 100.0, 0};
  printf("A1. Lamb solution (4x4 interface system) vs closed forms\n");
  printf("  M_l(inc) = 2L/((2l-1)(2l+1)(2l+3)),  M_l(lam) = [(lam+3)D + 3lam + "
         "7]/(2(lam+2)(2l+1)D), D = (2l-1)(2l+3)\n");
  printf("  %2s %14s %14s %10s %14s %14s %10s\n", "l", "Lamb inc", "closed inc", "diff",
         "Lamb lam=100", "closed lam=100", "diff");
  for (int l = 2; l <= 6; l++) {
    Lamb a = lamb_solve(l, inc, inc), b = lamb_solve(l, c100, c100);
    printf("  %2d %14.10f %14.10f %10.2e %14.10f %14.10f %10.2e\n", l, a.M, M_closed_inc(l),
           a.M - M_closed_inc(l), b.M, M_closed_comp(l, 100.0), b.M - M_closed_comp(l, 100.0));
  }
  printf("\nA2. Direct quadrature of the Oseen / Kelvin tensor over the sphere (polar coordinates "
         "about the target)\n");
  printf("  %2s %8s %6s %16s %16s %10s %12s\n", "l", "lam/mu", "nodes", "quadrature", "closed form",
         "rel diff", "non-P_l part");
  int res[2][3] = {{12, 24, 32}, {24, 48, 64}};
  for (int l = 2; l <= 3; l++)
    for (int k = 0; k < 2; k++) {
      double lam = k ? 100.0 : INFINITY;
      double nu = k ? lam / (2 * (lam + 1.0)) : 0.5;
      double exact = k ? M_closed_comp(l, lam) : M_closed_inc(l);
      for (int rr = 0; rr < 2; rr++) {
        double dev;
        double q = kelvin_quadrature(l, nu, res[rr][0], res[rr][1], res[rr][2], &dev);
        printf("  %2d %8s %6d %16.12f %16.12f %10.2e %12.2e\n", l, k ? "100" : "inf",
               res[rr][0] * res[rr][1] * res[rr][2], q, exact, q / exact - 1, dev);
      }
    }
  printf("\nA3. Drop with surface tension gamma, viscosity ratio lv (inside lv*mu), mode l = 2:\n");
  printf("  rate = M_2(lv) * gamma (l-1)(l+2)/R^2  vs  40(lv+1)/((2lv+3)(19lv+16)) gamma/(mu R)\n");
  printf("  %8s %16s %16s %10s\n", "lv", "Lamb", "formula", "rel diff");
  double lvs[5] = {0.01, 0.3, 1.0, 5.0, 100.0};
  for (int i = 0; i < 5; i++) {
    double lv = lvs[i];
    Fluid fi = {lv, 0, 1};
    Lamb a = lamb_solve(2, fi, inc);
    double rate = a.M * 4.0, f = 40 * (lv + 1) / ((2 * lv + 3) * (19 * lv + 16));
    printf("  %8.2f %16.12f %16.12f %10.2e\n", lv, rate, f, rate / f - 1);
  }
  printf("\nA4. Helfrich energy and force of r = 1 + delta P_l (exact axisymmetric geometry, "
         "quadrature)\n");
  printf("  E2 = (E(d)+E(-d)-2E(0))/(2 d^2) vs pi L(L-2)/(2(2l+1));  f_l/delta from the shape "
         "equation\n");
  printf("  f_n = (k/2)[Lap_s H + 2H(H^2-K)], (f_l(d)-f_l(-d))/(2d) vs -kappa L(L-2); virtual work "
         "check dE/dd = -oint f_n (dx/dd.n) dA\n");
  printf("  %2s %7s %16s %16s %10s %14s %14s %10s %12s\n", "l", "delta", "E2 numeric", "E2 formula",
         "rel diff", "f_l/d numeric", "-kappa L(L-2)", "rel diff", "virt.work");
  for (int l = 2; l <= 3; l++) {
    double L = l * (l + 1.0);
    double E0 = shape_energy(l, 0.0);
    double ds[2] = {0.02, 0.002};
    for (int k = 0; k < 2; k++) {
      double d = ds[k];
      double Ep = shape_energy(l, d), Em = shape_energy(l, -d);
      double E2 = (Ep + Em - 2 * E0) / (2 * d * d), E2f = M_PI * L * (L - 2) / (2 * (2 * l + 1));
      double fp, fm, vwp, vwm;
      shape_force_moments(l, d, &fp, &vwp);
      shape_force_moments(l, -d, &fm, &vwm);
      double fl = (fp - fm) / (2 * d);
      /* virtual work at delta = d: dE/dd (central difference) vs -oint f_n dx.n dA */
      double hh = 1e-4;
      double dEdd = (shape_energy(l, d + hh) - shape_energy(l, d - hh)) / (2 * hh);
      printf("  %2d %7.3f %16.12f %16.12f %10.2e %14.8f %14.8f %10.2e %12.2e\n", l, d, E2, E2f,
             E2 / E2f - 1, fl, -stiff(l), fl / -stiff(l) - 1, vwp / dEdd - 1);
    }
    printf("     sphere E(0)/k = %.15f (2 pi = %.15f); E(0.02)-2pi = %.10e, linearized %.10e\n", E0,
           2 * M_PI, shape_energy(l, 0.02) - 2 * M_PI,
           M_PI * L * (L - 2) * 0.02 * 0.02 / (2 * (2 * l + 1)));
  }
  printf("\nA5. Unbounded rates s_l = M_l kappa L(L-2) (amplitude), 2 s_l (energy E* - E*_inf)\n");
  printf("  %2s %8s %14s %14s %14s\n", "l", "lam/mu", "M_l", "s_l", "2 s_l");
  for (int l = 2; l <= 3; l++) {
    double Mi = M_closed_inc(l), Mc = M_closed_comp(l, 100.0);
    printf("  %2d %8s %14.10f %14.10f %14.10f\n", l, "inf", Mi, Mi * stiff(l), 2 * Mi * stiff(l));
    printf("  %2d %8s %14.10f %14.10f %14.10f\n", l, "100", Mc, Mc * stiff(l), 2 * Mc * stiff(l));
  }
  if (!g_inext) return;
  printf("\nA6. INEXTENSIBLE membrane (div_s u = 0 on r = 1, tension multiplier Sig P_l), Lamb 5x5 "
         "system vs closed forms\n");
  printf("  inc: M_l = 1/Z_l = L/((2l+1)(2L-1)), Sig_l = 1/(2L-1);  lam: M_l = L[(lam+3)^2 L + lam "
         "+ 2]/((2l+1)(lam+2)Q),\n");
  printf("  Sig_l = [(lam+5)L - 2]/Q, Q = lam L(2L-1) + 6L^2 + 2L - 4;  rate s_l = M_l kappa "
         "L(L-2) = kappa (l-1)(l+2)L/(mu Z_l)\n");
  printf("  %2s %6s %14s %14s %9s %12s %12s %9s %12s %12s %10s\n", "l", "lam/mu", "M_l Lamb",
         "M_l closed", "diff", "Sig Lamb", "Sig closed", "diff", "s_l", "2 s_l", "inext/free");
  for (int l = 1; l <= 6; l++)
    for (int k = 0; k < 2; k++) {
      Fluid f = k ? c100 : inc;
      Lamb a = lamb_solve_mem(l, f, f, 1);
      double Mc = k ? M_closed_inext_comp(l, 100.0) : M_closed_inext(l);
      double Sc = Sig_closed_inext(l, k ? 100.0 : INFINITY);
      double Mf = k ? M_closed_comp(l, 100.0) : M_closed_inc(l);
      printf("  %2d %6s %14.10f %14.10f %9.1e %12.9f %12.9f %9.1e %12.8f %12.8f %10.7f\n", l,
             k ? "100" : "inf", a.M, Mc, a.M - Mc, a.Sig, Sc, a.Sig - Sc, Mc * stiff(l),
             2 * Mc * stiff(l), Mc / Mf);
    }
  printf("  (l = 1 has zero stiffness; listed for the mobility only)\n");
}

/* B: solver verification against the exact unbounded solution imposed on the walls
 * Kept whole (90 lines): one computation over shared buffers with one exit. */
static void section_verify(int nmax) {
  printf("\n## B. Verification: exact unbounded Lamb solution imposed as Dirichlet data on the "
         "box-3 walls\n");
  printf("   (body: membrane force P_l n on r = 1; the FE functional u_l must converge to the "
         "unbounded M_l)\n");
  if (g_inext)
    printf("   membrane: INEXTENSIBLE, tension P%d on the arc, l = 0 tension %s; sig err = max "
           "nodal |sigma_h - Sig P_l| / Sig\n",
           g_tdeg,
           g_area < 0 ? "auto (removed for TH, kept otherwise)"
           : g_area   ? "removed"
                      : "kept");
  printf("\n");
  printf("  %-6s %5s %2s %4s %8s %8s %16s %12s %6s %12s %6s", "form", "lam", "l", "N", "h_max",
         "unknowns", "u_l (FE)", "err u_l", "order", "L2 rel err", "order");
  if (g_inext) printf(" %10s %6s %10s", "sig err", "order", "div resid");
  printf("\n");
  Fluid inc = {1.0, 0.0, 1}, c100 = {1.0, 100.0, 0};
  int forms[3] = {FORM_TH, FORM_PEN, FORM_MIX};
  for (int fi = 0; fi < 3; fi++) {
    Form F = make_form(forms[fi], forms[fi] == FORM_TH ? INFINITY : 100.0);
    Fluid fl = forms[fi] == FORM_TH ? inc : c100;
    Lamb La[2] = {lamb_solve_mem(2, fl, fl, g_inext), lamb_solve_mem(3, fl, fl, g_inext)};
    double eu[2][8], el[2][8], es[2][8];
    int k = 0;
    for (int N = 4; N <= nmax; N *= 2, k++) {
      Mesh M = mesh_build(3.0, N, kout_for(3.0));
      double *gD[2], *U[2], *Sg[2] = {NULL, NULL};
      int loads[2] = {2, 3}, nt = F.inext ? tension_count(&M, F.tdeg) : 0;
      for (int c = 0; c < 2; c++) {
        gD[c] = xcalloc((size_t)2 * M.nn, sizeof(double));
        U[c] = xmalloc(sizeof(double) * 2 * M.nn);
        if (nt) Sg[c] = xmalloc(sizeof(double) * nt);
        for (int i = 0; i < M.nn; i++)
          if (M.flag[i] & (F_WALL | F_AXIS))
            lamb_field(&La[c], 1, M.x[2 * i], M.x[2 * i + 1], &gD[c][2 * i], &gD[c][2 * i + 1]);
      }
      SolveInfo si;
      if (!fe_solve_ext(&M, F, 2, loads, gD, NULL, U, Sg, &si)) exit(3);
      for (int c = 0; c < 2; c++) {
        double um[LMAX_OUT + 1];
        sphere_components(&M, U[c], um);
        int l = loads[c];
        eu[c][k] = um[l] - La[c].M;
        el[c][k] = l2_error(&M, U[c], &La[c]);
        char o1[16] = "", o2[16] = "", o3[16] = "";
        if (k > 0) {
          snprintf(o1, sizeof o1, "%.2f", log(fabs(eu[c][k - 1] / eu[c][k])) / log(2.0));
          snprintf(o2, sizeof o2, "%.2f", log(el[c][k - 1] / el[c][k]) / log(2.0));
        }
        printf("  %-6s %5s %2d %4d %8.4f %8d %16.12f %12.3e %6s %12.3e %6s", form_name[F.form],
               F.form == FORM_TH ? "inf" : "100", l, N, M.hmax, si.nunk, um[l], eu[c][k], o1,
               el[c][k], o2);
        if (nt) {
          double e = 0;
          for (int i = 0; i < nt; i++) {
            int g = M.arc[F.tdeg == 2 ? i : 2 * i];
            double d = fabs(Sg[c][i] - La[c].Sig * legendre(l, M.x[2 * g + 1]));
            if (d > e) e = d;
          }
          es[c][k] = e / fabs(La[c].Sig);
          if (k > 0) snprintf(o3, sizeof o3, "%.2f", log(es[c][k - 1] / es[c][k]) / log(2.0));
          /* discrete constraint check: max_i |\int psi_i div_s u rho ds| / \int psi_i rho ds */
          double dr = 0, *rs = xcalloc((size_t)nt, sizeof(double)),
                 *ms = xcalloc((size_t)nt, sizeof(double));
          for (int j = 0; 2 * j + 2 < M.narc; j++) {
            double Bl[3][6], ml[3];
            int td[3], ntl = arc_tension_edge(&M, j, F.tdeg, Bl, ml, td);
            for (int i = 0; i < ntl; i++) {
              for (int kk = 0; kk < 3; kk++)
                for (int d = 0; d < 2; d++)
                  rs[td[i]] += Bl[i][2 * kk + d] * U[c][2 * M.arc[2 * j + kk] + d];
              ms[td[i]] += ml[i];
            }
          }
          for (int i = 0; i < nt; i++)
            if (fabs(rs[i]) / ms[i] > dr) dr = fabs(rs[i]) / ms[i];
          free(rs);
          free(ms);
          printf(" %10.3e %6s %10.1e", es[c][k], o3, dr);
        }
        printf("\n");
        free(gD[c]);
        free(U[c]);
        free(Sg[c]);
      }
      mesh_free(&M);
    }
  }
}

typedef struct {
  double mob[LMAX_OUT + 1][LMAX_OUT + 1]; /* mob[m][n]: u_m from unit P_n load, n = 2..LMAX_OUT */
  double sig[LMAX_OUT + 1][LMAX_OUT + 1]; /* inextensible: tension component m from unit P_n load */
  double sres[LMAX_OUT + 1]; /* inextensible: tension remainder beyond l = 16 (relative) */
  int nunk;
  double hmax, time;
} BoxResult;

static BoxResult box_run(double Rb, int N, Form F) {
  BoxResult R;
  memset(&R, 0, sizeof R);
  Mesh M = mesh_build(Rb, N, kout_for(Rb));
  int nr = LMAX_OUT - 1, loads[LMAX_OUT], nt = F.inext ? tension_count(&M, F.tdeg) : 0;
  double *U[LMAX_OUT], *Sg[LMAX_OUT];
  for (int c = 0; c < nr; c++) {
    loads[c] = c + 2;
    U[c] = xmalloc(sizeof(double) * 2 * M.nn);
    Sg[c] = nt ? xmalloc(sizeof(double) * nt) : NULL;
  }
  SolveInfo si;
  double t0 = now_sec();
  if (!fe_solve_ext(&M, F, nr, loads, NULL, NULL, U, Sg, &si)) exit(3);
  for (int c = 0; c < nr; c++) {
    double um[LMAX_OUT + 1];
    sphere_components(&M, U[c], um);
    for (int m = 0; m <= LMAX_OUT; m++) R.mob[m][c + 2] = um[m];
    if (nt) {
      double comp[17];
      tension_components(&M, F.tdeg, Sg[c], 16, comp, &R.sres[c + 2]);
      for (int m = 0; m <= LMAX_OUT; m++) R.sig[m][c + 2] = comp[m];
    }
    free(U[c]);
    free(Sg[c]);
  }
  R.time = now_sec() - t0;
  R.nunk = si.nunk;
  R.hmax = M.hmax;
  mesh_free(&M);
  return R;
}

/* decay rate of the coupled linear dynamics da_m/dt = -sum_n mob[m][n] stiff(n) a_n
 * (m, n = 2..LMAX_OUT; modes 0, 1 carry no stiffness and are slaved), returning
 * the eigenvalue whose eigenvector is dominated by mode l */
static double coupled_rate(const BoxResult *R, int l) {
  int n = LMAX_OUT - 1;
  double A[64], wr[8], wi[8], vr[64], vl[1];
  for (int i = 0; i < n; i++)
    for (int j = 0; j < n; j++) A[i * n + j] = R->mob[i + 2][j + 2] * stiff(j + 2);
  lapack_int info = LAPACKE_dgeev(LAPACK_ROW_MAJOR, 'N', 'V', n, A, n, wr, wi, vl, 1, vr, n);
  if (info != 0) return NAN;
  int best = -1;
  double bw = 0;
  for (int k = 0; k < n; k++) {
    double tot = 0;
    for (int i = 0; i < n; i++) tot += vr[i * n + k] * vr[i * n + k];
    double wgt = vr[(l - 2) * n + k] * vr[(l - 2) * n + k] / tot;
    if (wgt > bw) {
      bw = wgt;
      best = k;
    }
  }
  return best >= 0 ? wr[best] : NAN;
}

static void print_box_header(void) {
  printf("  %-6s %5s %5s %2s %4s %8s %8s %14s %12s %12s %10s %10s %10s %12s", "form", "box", "lam",
         "l", "N", "h_max", "unknowns", "M_l", "s_l", "2 s_l", "u_{l-2}/u_l", "u_{l+2}/u_l",
         "u_{l+4}/u_l", "coupled s");
  if (g_inext) printf(" %12s %10s %9s", "sig_l", "sig_0", "sig rem");
  printf("\n");
}

static void print_box_row(const char *fn, double Rb, const char *lam, int l, int N,
                          const BoxResult *R) {
  double Ml = R->mob[l][l];
  printf("  %-6s %5.1f %5s %2d %4d %8.4f %8d %14.10f %12.8f %12.8f %10.2e %10.2e %10.2e %12.8f", fn,
         Rb, lam, l, N, R->hmax, R->nunk, Ml, Ml * stiff(l), 2 * Ml * stiff(l),
         R->mob[l - 2][l] / Ml, R->mob[l + 2][l] / Ml,
         l + 4 <= LMAX_OUT ? R->mob[l + 4][l] / Ml : NAN, coupled_rate(R, l));
  if (g_inext) printf(" %12.9f %10.2e %9.1e", R->sig[l][l], R->sig[0][l], R->sres[l]);
  printf("\n");
}

static void section_box(int nmax) {
  printf("\n## C. Box R in [0,3], Z in [-3,3], no-slip walls: mesh convergence\n");
  printf("   M_l = u_l from the unit force P_l n; u_m = (2m+1)/2 int u_n P_m dcos(th); coupled s = "
         "decay rate of the\n");
  printf("   mode-l eigenvector of da_m/dt = -sum_n M_mn kappa L_n(L_n-2) a_n, m,n = 2..%d\n",
         LMAX_OUT);
  if (g_inext)
    printf("   membrane: INEXTENSIBLE, tension P%d; sig_m = (2m+1)/2 int sigma P_m dcos(th) per "
           "unit P_l force,\n"
           "   sig rem = relative L2 norm of sigma minus its l <= 16 Legendre part (spurious-mode "
           "indicator)\n",
           g_tdeg);
  printf("\n");
  int forms[3] = {FORM_TH, FORM_PEN, FORM_MIX};
  for (int fi = 0; fi < 3; fi++) {
    Form F = make_form(forms[fi], forms[fi] == FORM_TH ? INFINITY : 100.0);
    const char *lam = forms[fi] == FORM_TH ? "inf" : "100";
    print_box_header();
    double Mv[2][8];
    int Ns[8], k = 0;
    double tt = 0;
    BoxResult Rlast;
    memset(&Rlast, 0, sizeof Rlast);
    for (int N = 4; N <= nmax; N *= 2, k++) {
      BoxResult R = box_run(3.0, N, F);
      tt += R.time;
      for (int l = 2; l <= 3; l++) {
        print_box_row(form_name[F.form], 3.0, lam, l, N, &R);
        Mv[l - 2][k] = R.mob[l][l];
      }
      Ns[k] = N;
      Rlast = R;
    }
    for (int l = 2; l <= 3; l++) {
      printf("  %s lam=%s l=%d, N=%d, all components u_m/u_l, m = 0..%d:", form_name[F.form], lam,
             l, Ns[k - 1], LMAX_OUT);
      for (int m = 0; m <= LMAX_OUT; m++) printf(" %.3e", Rlast.mob[m][l] / Rlast.mob[l][l]);
      printf("\n");
    }
    /* reciprocity of the symmetric discrete operator: u_m[P_n]/(2m+1) = u_n[P_m]/(2n+1) */
    double rec = 0;
    for (int m = 2; m <= LMAX_OUT; m++)
      for (int nn = 2; nn <= LMAX_OUT; nn++) {
        double d = fabs(Rlast.mob[m][nn] / (2 * m + 1) - Rlast.mob[nn][m] / (2 * nn + 1));
        if (d > rec) rec = d;
      }
    printf("  reciprocity defect max |u_m[P_n]/(2m+1) - u_n[P_m]/(2n+1)| = %.1e\n", rec);
    for (int l = 2; l <= 3; l++) {
      printf("  %s lam=%s l=%d: successive differences", form_name[F.form], lam, l);
      for (int i = 1; i < k; i++) printf(" %.2e", Mv[l - 2][i] - Mv[l - 2][i - 1]);
      printf("; observed order");
      for (int i = 2; i < k; i++)
        printf(" %.2f", order3(Mv[l - 2][i - 2], Mv[l - 2][i - 1], Mv[l - 2][i]));
      if (k >= 3) {
        double p = order3(Mv[l - 2][k - 3], Mv[l - 2][k - 2], Mv[l - 2][k - 1]);
        if (isfinite(p) && p > 0.5) {
          double Mx = Mv[l - 2][k - 1] + (Mv[l - 2][k - 1] - Mv[l - 2][k - 2]) / (pow(2.0, p) - 1);
          printf("; Richardson M_l = %.10f (s_l %.8f)", Mx, Mx * stiff(l));
        }
      }
      printf("\n");
    }
    printf("  (N = %d..%d, total %.1f s)\n\n", Ns[0], Ns[k - 1], tt);
  }
}

static void section_bigbox(int N, int nbox, const double *boxes) {
  printf("\n## D. Box size: approach to the unbounded value (meshes N = %d and %d, Richardson with "
         "order 4)\n",
         N, 2 * N);
  printf("   gap = M_l(box) - M_l(unbounded analytic); p = local decay exponent "
         "log(gap1/gap2)/log(R2/R1)\n");
  if (g_inext)
    printf("   membrane: INEXTENSIBLE (tension P%d); analytic = closed form of section A6\n",
           g_tdeg);
  printf("\n");
  int forms[2] = {FORM_TH, FORM_MIX};
  for (int fi = 0; fi < 2; fi++) {
    Form F = make_form(forms[fi], forms[fi] == FORM_TH ? INFINITY : 100.0);
    const char *lam = forms[fi] == FORM_TH ? "inf" : "100";
    print_box_header();
    double Mr[2][16], dN[2][16];
    for (int b = 0; b < nbox; b++) {
      BoxResult R1 = box_run(boxes[b], N, F), R2 = box_run(boxes[b], 2 * N, F);
      for (int l = 2; l <= 3; l++) {
        print_box_row(form_name[F.form], boxes[b], lam, l, 2 * N, &R2);
        Mr[l - 2][b] = R2.mob[l][l] + (R2.mob[l][l] - R1.mob[l][l]) / 15.0;
        dN[l - 2][b] = R2.mob[l][l] - R1.mob[l][l];
      }
    }
    printf("\n  %5s %2s %16s %10s %14s %12s %8s %12s\n", "box", "l", "M_l (Richardson)",
           "M(2N)-M(N)", "s_l", "gap", "p", "gap*box^p");
    for (int l = 2; l <= 3; l++) {
      double Minf = M_unbounded(g_inext, forms[fi], l);
      double pth = l == 2 ? 3.0 : 5.0;
      for (int b = 0; b < nbox; b++) {
        double gap = Mr[l - 2][b] - Minf;
        char ps[16] = "";
        if (b > 0)
          snprintf(ps, sizeof ps, "%.2f",
                   log(fabs((Mr[l - 2][b - 1] - Minf) / gap)) / log(boxes[b] / boxes[b - 1]));
        printf("  %5.1f %2d %16.10f %10.1e %14.10f %12.3e %8s %12.4f\n", boxes[b], l, Mr[l - 2][b],
               dN[l - 2][b], Mr[l - 2][b] * stiff(l), gap, ps, gap * pow(boxes[b], pth));
      }
      /* extrapolation to an infinite box from the two largest boxes with gap ~ C box^-p */
      int b1 = nbox - 2, b2 = nbox - 1;
      double q = pow(boxes[b2] / boxes[b1], pth);
      double Mx = Mr[l - 2][b2] + (Mr[l - 2][b2] - Mr[l - 2][b1]) / (q - 1.0);
      /* and from two moderate boxes (6 and 12) */
      double q2 = pow(boxes[2] / boxes[1], pth);
      double Mx2 = Mr[l - 2][2] + (Mr[l - 2][2] - Mr[l - 2][1]) / (q2 - 1.0);
      printf("  %s lam=%s l=%d: box -> infinity with gap ~ box^-%.0f: from boxes %.0f,%.0f M = "
             "%.10f (analytic %.10f, diff %.1e);"
             " from boxes %.0f,%.0f M = %.10f (diff %.1e)\n",
             form_name[F.form], lam, l, pth, boxes[b1], boxes[b2], Mx, Minf, Mx - Minf, boxes[1],
             boxes[2], Mx2, Mx2 - Minf);
    }
    printf("\n");
  }
}

/* tension mass matrix (dense nt x nt): \int psi_i psi_j rho ds */
static void tension_mass(const Mesh *M, int tdeg, double *Ms) {
  int nt = tension_count(M, tdeg);
  double gx[8], gw[8];
  gauleg(8, gx, gw);
  memset(Ms, 0, sizeof(double) * (size_t)nt * nt);
  for (int j = 0; 2 * j + 2 < M->narc; j++) {
    int n3[3] = {M->arc[2 * j], M->arc[2 * j + 1], M->arc[2 * j + 2]};
    int td[3] = {tdeg == 2 ? 2 * j : j, tdeg == 2 ? 2 * j + 1 : j + 1, 2 * j + 2},
        ntl = tdeg == 2 ? 3 : 2;
    for (int q = 0; q < 8; q++) {
      double t = 0.5 * (gx[q] + 1), w = 0.5 * gw[q];
      double phi[3] = {(1 - t) * (1 - 2 * t), 4 * t * (1 - t), t * (2 * t - 1)};
      double dphi[3] = {4 * t - 3, 4 - 8 * t, 4 * t - 1};
      double psi[3] = {1 - t, t, 0};
      if (tdeg == 2) memcpy(psi, phi, sizeof psi);
      double X[2] = {0, 0}, dX[2] = {0, 0};
      for (int k = 0; k < 3; k++)
        for (int d = 0; d < 2; d++) {
          X[d] += phi[k] * M->x[2 * n3[k] + d];
          dX[d] += dphi[k] * M->x[2 * n3[k] + d];
        }
      double wt = w * X[0] * hypot(dX[0], dX[1]);
      for (int a = 0; a < ntl; a++)
        for (int b = 0; b < ntl; b++) Ms[(size_t)td[a] * nt + td[b]] += wt * psi[a] * psi[b];
    }
  }
}

/* S: discrete inf-sup / spurious-mode test of the velocity-tension pair.
 * S = B A^-1 B^T (A^-1: the Stokes solve of the form, with its pressure, no
 * tension), B_ij = \int psi_i div_s(phi_j) rho ds. The generalized eigenvalues
 * of S x = lambda M_sigma x (M_sigma: tension mass) are the squared inf-sup
 * ratios sup_v b(sigma,v)^2 / (a(v,v) |sigma|^2_L2) of the eigenvectors. A
 * stable pair: the lowest eigenvalues converge under refinement to those of the
 * continuous operator (smooth eigenvectors, dominant low l); a spurious tension
 * mode: an eigenvalue -> 0 with an oscillating eigenvector.
 * Kept whole (115 lines): one computation over shared buffers with one exit. */
static void section_stability(int nmax) {
  printf("\n## S. Stability of the tension discretization: spectrum of the tension Schur "
         "complement S = B A^-1 B^T\n");
  printf("   S x = lambda M_sigma x (L2 mass on the sphere); for the 6 lowest: lambda [dominant l "
         "of the eigenvector,\n");
  printf("   relative L2 remainder beyond l = 16]; lam_max*h (h = pi/(4N) arc edge) ~ const for an "
         "order-1 operator\n\n");
  int forms[2] = {FORM_MIX, FORM_TH};
  for (int fi = 0; fi < 2; fi++)
    for (int tdeg = 1; tdeg <= 2; tdeg++) {
      printf("  %-6s %4s %3s %4s %5s", "form", "lam", "sig", "N", "n_sig");
      for (int k = 0; k < 6; k++) printf("  lambda_%d [ l,    rem]", k + 1);
      printf(" %10s %9s %8s\n", "lam_max", "lmax*h", "asym");
      for (int N = 4; N <= nmax; N *= 2) {
        Mesh M = mesh_build(3.0, N, kout_for(3.0));
        Form F = make_form(forms[fi], forms[fi] == FORM_TH ? INFINITY : 100.0);
        F.inext = 0;
        int nt = tension_count(&M, tdeg), nv = 2 * M.nn;
        /* rows of B in the full velocity numbering (<= 5 nodes x 2 comps each) */
        int *ri = xmalloc(sizeof(int) * nt * 12), *rc = xcalloc((size_t)nt, sizeof(int));
        double *rv = xmalloc(sizeof(double) * nt * 12);
        for (int j = 0; 2 * j + 2 < M.narc; j++) {
          double Bl[3][6], ml[3];
          int td[3], ntl = arc_tension_edge(&M, j, tdeg, Bl, ml, td);
          for (int i = 0; i < ntl; i++)
            for (int k = 0; k < 3; k++)
              for (int d = 0; d < 2; d++) {
                int full = 2 * M.arc[2 * j + k] + d, r = td[i], m;
                for (m = 0; m < rc[r] && ri[r * 12 + m] != full; m++) {
                }
                if (m == rc[r]) {
                  ri[r * 12 + m] = full;
                  rv[r * 12 + m] = 0;
                  rc[r]++;
                }
                rv[r * 12 + m] += Bl[i][2 * k + d];
              }
        }
        double *S = xcalloc((size_t)nt * nt, sizeof(double));
        const int CH = 64;
        double *bx[64], *U[64];
        int loads[64];
        for (int c = 0; c < CH; c++) {
          bx[c] = xmalloc(sizeof(double) * nv);
          U[c] = xmalloc(sizeof(double) * nv);
          loads[c] = -1;
        }
        for (int j0 = 0; j0 < nt; j0 += CH) {
          int nc = nt - j0 < CH ? nt - j0 : CH;
          for (int c = 0; c < nc; c++) {
            memset(bx[c], 0, sizeof(double) * nv);
            for (int m = 0; m < rc[j0 + c]; m++)
              bx[c][ri[(j0 + c) * 12 + m]] = rv[(j0 + c) * 12 + m];
          }
          SolveInfo si;
          if (!fe_solve_ext(&M, F, nc, loads, NULL, bx, U, NULL, &si)) exit(3);
          for (int c = 0; c < nc; c++)
            for (int i = 0; i < nt; i++) {
              double v = 0;
              for (int m = 0; m < rc[i]; m++) v += rv[i * 12 + m] * U[c][ri[i * 12 + m]];
              S[(size_t)i * nt + j0 + c] = v;
            }
        }
        double asym = 0, smax = 0;
        for (int i = 0; i < nt; i++)
          for (int j = 0; j < nt; j++) {
            double a = S[(size_t)i * nt + j], b = S[(size_t)j * nt + i];
            if (fabs(a - b) > asym) asym = fabs(a - b);
            if (fabs(a) > smax) smax = fabs(a);
          }
        for (int i = 0; i < nt; i++)
          for (int j = 0; j < i; j++)
            S[(size_t)i * nt + j] = S[(size_t)j * nt + i] =
                0.5 * (S[(size_t)i * nt + j] + S[(size_t)j * nt + i]);
        double *Ms = xmalloc(sizeof(double) * (size_t)nt * nt), *ev = xmalloc(sizeof(double) * nt);
        tension_mass(&M, tdeg, Ms);
        lapack_int info = LAPACKE_dsygv(LAPACK_ROW_MAJOR, 1, 'V', 'U', nt, S, nt, Ms, nt, ev);
        printf("  %-6s %4s  P%d %4d %5d", form_name[F.form], F.form == FORM_TH ? "inf" : "100",
               tdeg, N, nt);
        if (info != 0)
          printf("  dsygv info %d", (int)info);
        else {
          double *x = xmalloc(sizeof(double) * nt);
          for (int k = 0; k < 6 && k < nt; k++) {
            for (int i = 0; i < nt; i++) x[i] = S[(size_t)i * nt + k];
            double comp[17], rem, best = -1;
            int lb = 0;
            tension_components(&M, tdeg, x, 16, comp, &rem);
            for (int m = 0; m <= 16; m++)
              if (comp[m] * comp[m] / (2 * m + 1) > best) {
                best = comp[m] * comp[m] / (2 * m + 1);
                lb = m;
              }
            printf("  %10.4e [%2d,%7.1e]", ev[k], lb, rem);
          }
          free(x);
          printf(" %10.3f %9.4f %8.1e", ev[nt - 1], ev[nt - 1] * M_PI / (4 * N), asym / smax);
        }
        printf("\n");
        fflush(stdout);
        for (int c = 0; c < CH; c++) {
          free(bx[c]);
          free(U[c]);
        }
        free(ri);
        free(rc);
        free(rv);
        free(S);
        free(Ms);
        free(ev);
        mesh_free(&M);
      }
      printf("\n");
    }
}

/* E: free vs inextensible membrane in box 3, lam = inf (TH) and 100 (THmix) */
static void section_compare(int nmax) {
  printf("\n## E. Free vs inextensible membrane, box 3 (R in [0,3], Z in [-3,3], no-slip), meshes "
         "N = %d, %d, %d\n",
         nmax / 4, nmax / 2, nmax);
  printf("   M_l: Richardson from the two finest meshes with the observed order (dM = M(N) - "
         "M(N/2) on the finest);\n");
  printf("   2s_l = 2 M_l kappa L(L-2) (energy rate); coupled 2s: modes 2..%d coupled by the box "
         "(finest mesh);\n",
         LMAX_OUT);
  printf("   tension P%d, l = 0 tension: %s\n\n", g_tdeg,
         g_area < 0 ? "auto"
         : g_area   ? "removed"
                    : "kept");
  printf("  %5s %2s %14s %9s %14s %9s %9s %11s %11s %11s %11s %9s %9s\n", "lam", "l", "M free",
         "dM", "M inext", "dM", "ratio", "2s free", "2s inext", "2s_c free", "2s_c inext",
         "unb free", "unb inx");
  int save = g_inext;
  int forms[2] = {FORM_TH, FORM_MIX};
  double Mx[2][2][2], dM[2][2][2], cs[2][2][2];
  for (int fi = 0; fi < 2; fi++) {
    for (int in = 0; in < 2; in++) {
      g_inext = in;
      Form F = make_form(forms[fi], forms[fi] == FORM_TH ? INFINITY : 100.0);
      BoxResult R[3];
      for (int k = 0; k < 3; k++) R[k] = box_run(3.0, nmax >> (2 - k), F);
      for (int l = 2; l <= 3; l++) {
        double a = R[0].mob[l][l], b = R[1].mob[l][l], c = R[2].mob[l][l], p = order3(a, b, c);
        if (!isfinite(p) || p < 2) p = 4;
        Mx[fi][in][l - 2] = c + (c - b) / (pow(2.0, p) - 1);
        dM[fi][in][l - 2] = c - b;
        cs[fi][in][l - 2] = coupled_rate(&R[2], l);
      }
    }
    for (int l = 2; l <= 3; l++) {
      double Mf = Mx[fi][0][l - 2], Mi = Mx[fi][1][l - 2];
      printf(
          "  %5s %2d %14.10f %9.1e %14.10f %9.1e %9.6f %11.7f %11.7f %11.7f %11.7f %9.6f %9.6f\n",
          forms[fi] == FORM_TH ? "inf" : "100", l, Mf, dM[fi][0][l - 2], Mi, dM[fi][1][l - 2],
          Mi / Mf, 2 * Mf * stiff(l), 2 * Mi * stiff(l), 2 * cs[fi][0][l - 2], 2 * cs[fi][1][l - 2],
          2 * M_unbounded(0, forms[fi], l) * stiff(l), 2 * M_unbounded(1, forms[fi], l) * stiff(l));
    }
  }
  g_inext = save;
  printf("\n  ratio inext/free: box 3 as above; unbounded (4L-3)/(4L-2) for lam = inf: l=2 %.6f, "
         "l=3 %.6f;"
         " lam = 100: l=2 %.6f, l=3 %.6f\n",
         M_closed_inext(2) / M_closed_inc(2), M_closed_inext(3) / M_closed_inc(3),
         M_closed_inext_comp(2, 100) / M_closed_comp(2, 100),
         M_closed_inext_comp(3, 100) / M_closed_comp(3, 100));
}

/* Kept whole (94 lines): the option parsing, the runs and the table they print, in order. */
int main(int argc, char **argv) {
  int nmax = 64, nverify = 32, nbig = 16, nstab = 32;
  int do_a = 1, do_b = 1, do_c = 1, do_d = 1, do_s = -1, do_e = -1;
  for (int i = 1; i < argc; i++) {
    if (!strcmp(argv[i], "--nmax") && i + 1 < argc)
      nmax = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--nverify") && i + 1 < argc)
      nverify = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--nbig") && i + 1 < argc)
      nbig = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--nq") && i + 1 < argc)
      g_nq = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--kout") && i + 1 < argc)
      g_kout = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--nstab") && i + 1 < argc)
      nstab = atoi(argv[++i]);
    else if (!strcmp(argv[i], "--membrane") && i + 1 < argc) {
      const char *s = argv[++i];
      if (!strcmp(s, "free"))
        g_inext = 0;
      else if (!strncmp(s, "inext", 5))
        g_inext = 1;
      else {
        fprintf(stderr, "--membrane free|inextensible\n");
        return 1;
      }
    } else if (!strcmp(argv[i], "--tension") && i + 1 < argc) {
      const char *s = argv[++i];
      if (!strcmp(s, "p1") || !strcmp(s, "P1"))
        g_tdeg = 1;
      else if (!strcmp(s, "p2") || !strcmp(s, "P2"))
        g_tdeg = 2;
      else {
        fprintf(stderr, "--tension p1|p2\n");
        return 1;
      }
    } else if (!strcmp(argv[i], "--area") && i + 1 < argc) {
      const char *s = argv[++i];
      if (!strcmp(s, "auto"))
        g_area = -1;
      else if (!strcmp(s, "fixed"))
        g_area = 0;
      else if (!strcmp(s, "free"))
        g_area = 1;
      else {
        fprintf(stderr, "--area auto|fixed|free\n");
        return 1;
      }
    } else if (!strcmp(argv[i], "--only") && i + 1 < argc) {
      const char *s = argv[++i];
      do_a = strchr(s, 'A') != NULL;
      do_b = strchr(s, 'B') != NULL;
      do_c = strchr(s, 'C') != NULL;
      do_d = strchr(s, 'D') != NULL;
      do_s = strchr(s, 'S') != NULL;
      do_e = strchr(s, 'E') != NULL;
    } else {
      fprintf(
          stderr,
          "usage: %s [--only ABCDSE] [--nmax N] [--nverify N] [--nbig N] [--nstab N] [--nq n] "
          "[--kout K]\n"
          "          [--membrane free|inextensible] [--tension p1|p2] [--area auto|fixed|free]\n",
          argv[0]);
      return 1;
    }
  }
  if (do_s < 0) do_s = g_inext;
  if (do_e < 0) do_e = g_inext;
  if (g_nq < 2 || g_nq > 16) g_nq = 5;
  double t0 = now_sec();
  printf("# stokes_mode: relaxation of P_l perturbations of a bending-only sphere (see the header "
         "of bench/stokes_mode.c)\n");
  printf("# units k = mu = R = 1 (kappa = k/4); s_l = M_l kappa L(L-2), L = l(l+1); triangle rule "
         "%dx%d collapsed Gauss\n",
         g_nq, g_nq);
  if (g_inext)
    printf("# membrane: INEXTENSIBLE (div_s u = 0 on r = 1), tension multiplier P%d on the arc, l "
           "= 0 tension %s\n",
           g_tdeg,
           g_area < 0 ? "auto (removed for TH, kept for THmix/P2pen)"
           : g_area   ? "removed (area free)"
                      : "kept (area fixed)");
  if (do_a) section_analytic();
  if (do_b) section_verify(nverify);
  if (do_c) section_box(nmax);
  if (do_d) {
    double boxes[6] = {3.0, 6.0, 12.0, 15.0, 24.0, 48.0};
    section_bigbox(nbig, 6, boxes);
  }
  if (do_s) section_stability(nstab);
  if (do_e) section_compare(nmax);
  printf("# total time %.1f s\n", now_sec() - t0);
  return 0;
}
