/* vesica — Lagrange-Newton backend: Newton's method on the first-order
 * conditions of the step problem (paper Sec. 3.2), Lagrangian L = f + lam^T c,
 *
 *   [ H  J^T ] [ dx   ]     [ g + J^T lam ]
 *   [ J  0   ] [ dlam ] = - [ c           ],   H = Hess_x L,
 *
 * factorized by MUMPS (LDL^T, symmetric indefinite; analysis once in create).
 *
 * Globalization: inertia check (the KKT matrix must have exactly ncon negative
 * eigenvalues, i.e. H positive definite on the null space of J; otherwise
 * H + delta K with delta = 1e-3, 1e-2, ... — K is the dissipation metric, so the
 * correction is a larger viscosity); backtracking line search on the l1 merit
 * phi = f + mu sum |c_i|, mu = 2 max |lam| (nondecreasing within a step),
 * Armijo constant 1e-4, a second-order correction when the full step is
 * rejected (Maratos effect), VES_ERR_DOMAIN at a trial point = step too long
 * (halve).
 *
 * Frozen Hessian (opt->freeze_hessian, the paper's practice): H (and J in the
 * matrix) assembled and factorized once at the start of the step; every
 * iteration recomputes only g, c and J for the residual (a chord method, whose
 * fixed point is still the exact KKT point). A fresh matrix is built when the
 * chord step stalls: no descent, a line search that had to cut the step, or a
 * residual that fell by less than half.
 *
 * Convergence (both):
 *   |g + J^T lam|_inf <= max(tol * S, N),  S = max(|g(x_start)|_inf, |J^T lam|_inf),
 *   |c_i| <= ctol * target_i  (A0, V_target),
 * N = eps_mach (|H| |x|)_inf the rounding floor: x holds absolute positions
 * (~1) to eps_mach, so g = K (x - x0) + ... carries an error of that size
 * whatever the iteration does; for small dt it exceeds tol * S (measured on
 * the test problem at dt = 1e-3: plateau 4.4e-14 = 1.1e-9 S, N = 1.5e-13).
 * S is the size of the forces in the step: at x_start = x0, g = dt grad E(y^n)
 * (the viscous term vanishes), and the tension term J^T lam balances it at the
 * solution; relative to S the criterion means the same for any dt (an
 * absolute floor max(1, .) would make small steps converge vacuously). S = 1
 * when both vanish (an equilibrium without tension). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "backend_kkt_impl.h"
#include "ves/backend.h"
#include "clock_impl.h"

#define NEWTON_ARMIJO 1e-4     /* sufficient decrease of the merit function */
#define NEWTON_MAX_LS 40       /* backtracking halvings */
#define NEWTON_DELTA0 1e-3     /* first inertia correction, units of K */
#define NEWTON_DELTA_MAX 1e6   /* give up beyond this correction */
#define NEWTON_STALL 0.5       /* frozen: refresh when |res| fell by less than this */
#define NEWTON_FNOISE 1e2      /* merit values closer than this many eps_mach |phi| are equal */

typedef struct {
  ves_backend_options opt; /* copied */
  kkt_system kkt;          /* KKT structure, values, factorization */
  int nvar;                /* free dofs */
  double *H;               /* nh Hessian values */
  double *g;               /* nvar grad f at x */
  double *J;               /* KKT_NROWS nvar Jacobian at x */
  double *r;               /* nvar g + J^T lam */
  double *sol;             /* nvar + KKT_NROWS right-hand side / solution */
  double *soc;             /* nvar + KKT_NROWS second-order correction */
  double *xt;              /* nvar trial point */
  double noise;            /* eps_mach (|H| |x|)_inf at the last assembly */
} newton_state;

static void newton_destroy(void **state) {
  if (!state || !*state) return;
  newton_state *w = *state;
  kkt_destroy(&w->kkt);
  free(w->H), free(w->g), free(w->J), free(w->r), free(w->sol), free(w->soc), free(w->xt);
  free(w);
  *state = NULL;
}

static ves_status newton_create(const ves_backend_options *opt, ves_step *s, void **state) {
  VES_CHECK(state, VES_ERR_ARG);
  *state = NULL;
  VES_CHECK(opt && s, VES_ERR_ARG);
  VES_CHECK(opt->tol > 0 && opt->ctol > 0 && opt->max_iter > 0, VES_ERR_ARG);
  newton_state *w = calloc(1, sizeof *w);
  if (!w) return VES_ERR_ALLOC;
  w->opt = *opt;
  w->nvar = ves_step_nvar(s);
  ves_status st = kkt_create(s, &w->kkt);
  if (st != VES_OK) {
    free(w);
    return st;
  }
  const size_t nv = (size_t)w->nvar, na = nv + KKT_NROWS;
  w->H = malloc((size_t)w->kkt.nh * sizeof *w->H);
  w->g = malloc(nv * sizeof *w->g);
  w->J = calloc(KKT_NROWS * nv, sizeof *w->J);
  w->r = malloc(nv * sizeof *w->r);
  w->sol = malloc(na * sizeof *w->sol);
  w->soc = malloc(na * sizeof *w->soc);
  w->xt = malloc(nv * sizeof *w->xt);
  *state = w;
  if (!w->H || !w->g || !w->J || !w->r || !w->sol || !w->soc || !w->xt) {
    newton_destroy(state);
    return VES_ERR_ALLOC;
  }
  return VES_OK;
}

static double norm_inf(int n, const double *v) {
  double m = 0;
  for (int i = 0; i < n; i++) m = fmax(m, fabs(v[i]));
  return m;
}

/* Assemble H at (x, lam), fill and factorize the KKT matrix with the inertia
 * correction: exactly KKT_NROWS negative pivots. */
static ves_status assemble_factor(newton_state *w, ves_step *s, const double *x,
                                  const double *lam, int ncon, ves_backend_stats *stt) {
  VES_CALL(ves_step_eval_hess(s, x, 1.0, lam, w->H));
  stt->h_evals++;
  /* rounding floor of the residual: eps_mach (|H| |x|)_inf, w->xt as scratch */
  double *acc = w->xt;
  memset(acc, 0, (size_t)w->nvar * sizeof *acc);
  for (int t = 0; t < w->kkt.nh; t++) {
    const int i = w->kkt.irow[t], j = w->kkt.jcol[t];
    acc[i] += fabs(w->H[t] * x[j]);
    if (i != j) acc[j] += fabs(w->H[t] * x[i]); /* the mirrored upper entry */
  }
  w->noise = DBL_EPSILON * norm_inf(w->nvar, acc);
  const double *K = ves_step_K(s);
  for (double delta = 0; delta <= NEWTON_DELTA_MAX;
       delta = delta == 0 ? NEWTON_DELTA0 : 10 * delta) {
    kkt_fill(&w->kkt, w->H, delta, K, w->J, ncon);
    ves_status st = kkt_factor(&w->kkt);
    if (st == VES_OK && w->kkt.neg == KKT_NROWS) return VES_OK;
    if (st != VES_OK && st != VES_ERR_SINGULAR) return st; /* not an inertia problem */
  }
  return VES_ERR_SINGULAR;
}

/* Values at x: f and c (one model pass). */
static ves_status eval_fc(ves_step *s, const double *x, double *f, double *c,
                          ves_backend_stats *stt) {
  stt->f_evals++;
  VES_CALL(ves_step_eval_f(s, x, f));
  return ves_step_eval_c(s, x, c);
}

/* Gradients at x: g and J (one model pass, values from the cache). */
static ves_status eval_gJ(newton_state *w, ves_step *s, const double *x,
                          ves_backend_stats *stt) {
  stt->g_evals++;
  VES_CALL(ves_step_eval_grad(s, x, w->g));
  return ves_step_eval_jac(s, x, w->J);
}

static double l1(int n, const double *c) {
  double a = 0;
  for (int i = 0; i < n; i++) a += fabs(c[i]);
  return a;
}

static ves_status newton_solve(void *state, ves_step *s, double *x, double *lambda,
                               ves_backend_stats *stt) {
  VES_CHECK(state && s && x && stt, VES_ERR_ARG);
  memset(stt, 0, sizeof *stt);
  const double t0 = ves_wall_seconds();
  newton_state *w = state;
  w->noise = 0;
  const ves_step_params *par = ves_step_get_params(s);
  VES_CHECK(par, VES_ERR_ARG); /* ves_step_set not called */
  const int nv = w->nvar, ncon = ves_step_ncon(s);
  VES_CHECK(nv == ves_step_nvar(s), VES_ERR_ARG);
  VES_CHECK(ncon == 0 || lambda, VES_ERR_ARG);
  double tgt[KKT_NROWS] = {1, 1}, lam[KKT_NROWS] = {0, 0}, c[KKT_NROWS] = {0, 0},
         ct[KKT_NROWS] = {0, 0};
  {
    int k = 0;
    if (par->hold_area) tgt[k++] = par->A0;
    if (par->hold_volume) tgt[k++] = par->V_target;
  }
  for (int i = 0; i < ncon; i++) lam[i] = lambda[i];

  double f, ft, mu = 0;
  ves_status st = eval_fc(s, x, &f, c, stt);
  if (st == VES_OK) st = eval_gJ(w, s, x, stt);
  const double gscale = norm_inf(nv, w->g);
  int fresh = 1;            /* build the matrix at the next iteration */
  double res_prev = INFINITY;
  ves_status result = VES_ERR_NOCONV;
  while (st == VES_OK) {
    /* residual r = g + J^T lam and the convergence test */
    memcpy(w->r, w->g, (size_t)nv * sizeof *w->r);
    double jl = 0;
    for (int i = 0; i < ncon; i++)
      for (int j = 0; j < nv; j++) w->r[j] += lam[i] * w->J[(size_t)i * nv + j];
    if (ncon) {
      for (int j = 0; j < nv; j++) jl = fmax(jl, fabs(w->r[j] - w->g[j]));
    }
    double scale = fmax(gscale, jl), res = norm_inf(nv, w->r), viol = 0;
    if (scale == 0) scale = 1;
    /* the residual is not resolved below the rounding of x itself: x is
     * stored to eps_mach |x| absolute, and H magnifies that to
     * eps_mach (|H| |x|)_inf (measured plateau: 0.3 of this bound) */
    const double floor_res = w->noise > 0 ? w->noise : 0.0;
    for (int i = 0; i < ncon; i++) viol = fmax(viol, fabs(c[i]) / tgt[i]);
    stt->violation = viol;
    if (res <= fmax(w->opt.tol * scale, floor_res) && viol <= w->opt.ctol) {
      result = VES_OK;
      break;
    }
    if (stt->iterations >= w->opt.max_iter) {
      result = VES_MAXITER;
      break;
    }
    if (w->opt.freeze_hessian && !fresh && res > NEWTON_STALL * res_prev) fresh = 1;
    res_prev = res;
    int built_now = 0;
    if (fresh || !w->opt.freeze_hessian) {
      if ((st = assemble_factor(w, s, x, lam, ncon, stt)) != VES_OK) break;
      fresh = 0, built_now = 1;
    }
    /* Newton direction: [H J^T; J 0][dx; dlam] = -[r; c] */
    for (int j = 0; j < nv; j++) w->sol[j] = -w->r[j];
    for (int i = 0; i < KKT_NROWS; i++) w->sol[nv + i] = i < ncon ? -c[i] : 0.0;
    if ((st = kkt_solve(&w->kkt, w->sol)) != VES_OK) break;
    const double *dx = w->sol, *dlam = w->sol + nv;
    /* merit parameter and directional derivative of phi along dx (with the
     * current J: exact even when the matrix is frozen) */
    double lmax = 0;
    for (int i = 0; i < ncon; i++) lmax = fmax(lmax, fabs(lam[i] + dlam[i]));
    mu = fmax(mu, 2 * lmax);
    double D = 0;
    for (int j = 0; j < nv; j++) D += w->g[j] * dx[j];
    for (int i = 0; i < ncon; i++) {
      double jd = 0;
      for (int j = 0; j < nv; j++) jd += w->J[(size_t)i * nv + j] * dx[j];
      D += mu * (c[i] > 0 ? jd : c[i] < 0 ? -jd : fabs(jd));
    }
    if (D >= 0 && !built_now) { /* a stale matrix gave no descent: rebuild */
      fresh = 1;
      continue;
    }
    const double phi0 = f + mu * l1(ncon, c), Dm = fmin(D, 0);
    /* Armijo with a rounding allowance (as Ipopt's line search): f holds
     * dt E ~ dt 2 pi k, summed over all points, so near the solution the
     * predicted decrease a D falls below the rounding of f itself and a
     * strict test rejects every step of a converging iteration (measured:
     * problems/mode2.ini at dt* = 0.04, 28 iterations and two halvings). */
    const double fnoise = NEWTON_FNOISE * DBL_EPSILON * fabs(phi0);
    /* backtracking on phi; DOMAIN = too long */
    double a = 1;
    int accepted = 0, used_soc = 0;
    for (int ls = 0; ls < NEWTON_MAX_LS && !accepted; ls++, a *= 0.5) {
      for (int j = 0; j < nv; j++) w->xt[j] = x[j] + a * dx[j];
      ves_status e = eval_fc(s, w->xt, &ft, ct, stt);
      if (e == VES_ERR_DOMAIN) continue;
      if (e != VES_OK) {
        st = e;
        break;
      }
      if (ft + mu * l1(ncon, ct) <= phi0 + NEWTON_ARMIJO * a * Dm + fnoise) {
        accepted = 1;
        break;
      }
      if (ls == 0 && ncon > 0) {
        /* second-order correction: [H J^T; J 0][p; q] = [0; -c(x + dx)] */
        memset(w->soc, 0, (size_t)(nv + KKT_NROWS) * sizeof *w->soc);
        for (int i = 0; i < ncon; i++) w->soc[nv + i] = -ct[i];
        if ((e = kkt_solve(&w->kkt, w->soc)) != VES_OK) {
          st = e;
          break;
        }
        for (int j = 0; j < nv; j++) w->xt[j] = x[j] + dx[j] + w->soc[j];
        e = eval_fc(s, w->xt, &ft, ct, stt);
        if (e != VES_OK && e != VES_ERR_DOMAIN) {
          st = e;
          break;
        }
        if (e == VES_OK && ft + mu * l1(ncon, ct) <= phi0 + NEWTON_ARMIJO * Dm + fnoise) {
          accepted = used_soc = 1;
          break;
        }
      }
    }
    if (st != VES_OK) break;
    if (!accepted) {
      if (!built_now) { /* a stale matrix: rebuild and retry */
        fresh = 1;
        continue;
      }
      result = VES_ERR_NOCONV;
      break;
    }
    if (a < 1) fresh = 1; /* the step had to be cut: a frozen matrix is stale */
    memcpy(x, w->xt, (size_t)nv * sizeof *x);
    for (int i = 0; i < ncon; i++) lam[i] += (used_soc ? 1.0 : a) * dlam[i];
    f = ft;
    memcpy(c, ct, sizeof c);
    stt->iterations++;
    st = eval_gJ(w, s, x, stt);
  }
  if (st != VES_OK) result = st == VES_ERR_SINGULAR ? VES_ERR_SOLVER : st; /* no usable KKT matrix */
  for (int i = 0; i < ncon; i++) lambda[i] = lam[i];
  stt->solver_status = (int)result;
  stt->seconds = ves_wall_seconds() - t0;
  return result;
}

const ves_backend_type ves_backend_newton = {"newton", newton_create, newton_solve,
                                             newton_destroy};
