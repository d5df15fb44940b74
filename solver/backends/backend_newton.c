/* vesica — the "newton" backend: Newton's method on the first-order
 * conditions of the step problem (paper Sec. 3.2), L = f + lam^T c,
 *
 *   [ H + delta K   J^T ] [ dx   ]     [ g + J^T lam ]
 *   [ J             0   ] [ dlam ] = - [ c           ],   H = Hess_x L,
 *
 * factorized by MUMPS (LDL^T, kkt.h). Inertia correction: the
 * matrix must have exactly VES_KKT_NROWS negative pivots (H positive definite on
 * null J), else delta K is added on a ladder delta = 0, NEWTON_DELTA0, x10
 * (K the dissipation metric: the correction is a larger viscosity). Line
 * search on the l1 merit f + mu sum |c_i| with a second-order correction.
 * With a frozen Hessian (freeze_hessian) the matrix of the step's start is
 * kept: a chord method, whose fixed point is still the exact KKT point,
 * accelerated by Anderson mixing (anderson_impl.h) and rebuilt when it
 * stalls; freeze_hessian 2 keeps it across steps of nearly equal dt.
 * Converged when |g + J^T lam|_inf <= max(tol S, N) and |c_i| <= ctol
 * target_i, S = max(|g(x_start)|_inf, |J^T lam|_inf) the step's force scale,
 * N = eps_mach (|H| |x|)_inf the rounding floor of the residual.
 * docs/design.md, "Backends"; docs/results.md, "The backends compared". */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "backends/anderson_impl.h"
#include "ves/kkt.h"
#include "ves/backend.h"
#include "core/clock_impl.h"

#define NEWTON_ARMIJO 1e-4     /* sufficient decrease of the merit function */
#define NEWTON_MAX_LS 40       /* backtracking halvings */
#define NEWTON_DELTA0 1e-3     /* first inertia correction, units of K */
#define NEWTON_DELTA_MAX 1e6   /* give up beyond this correction */
#define NEWTON_NEG_JUMP 8      /* more extra negative pivots than this: the next delta x100 */
#define NEWTON_STALL 0.5       /* frozen: refresh when |res| fell by less than this ... */
#define NEWTON_STALL_WINDOW 3  /* ... over this many iterations (fewer since the build) */
#define NEWTON_TAIL 1e3        /* the tail: |res| within this factor of the tolerance */
#define NEWTON_FNOISE 1e2      /* merit values closer than this many eps_mach |phi| are equal */
#define NEWTON_REUSE_DT 1.25   /* freeze 2: reuse while dt / dt_m is within [1/this, this] */
#define NEWTON_SOLVE_TOL 1e-3  /* frozen: the KKT solves' relative residual (single precision) */
#define NEWTON_FLOOR_FRAC 1e-2 /* at the floor: refine a direction above this of the step */

typedef struct {
  ves_backend_options opt; /* copied */
  ves_kkt kkt;             /* KKT structure, values, factorization */
  int nvar;                /* free dofs */
  double *g;               /* nvar grad f at x */
  double *J;               /* VES_KKT_NROWS nvar Jacobian at x */
  double *r;               /* nvar g + J^T lam */
  double *sol;             /* nvar + VES_KKT_NROWS right-hand side / solution */
  double *soc;             /* nvar + VES_KKT_NROWS second-order correction */
  double *xt;              /* nvar trial point */
  double noise;            /* eps_mach (|H| |x|)_inf at the last assembly */
  int have_factor;         /* the KKT factorization holds a usable chord matrix */
  double dt_factor;        /* the dt of the step whose matrix it is */
  int ncon_factor;         /* the constraints held in it */
  double delta_last;       /* the last inertia correction (0: none since the fresh matrix) */
  double delta_build;      /* the correction of the last build (0: none needed) */
  double delta_hint;       /* the correction the last step's first build needed (0: none) */
  int at_floor;            /* a loose direction's error would hide under the floor (solve_tol) */
  double *xn;              /* the step's start x^n (ves_step_x0): the displacement's origin */
  anderson aa;             /* the chord's acceleration, over u = (x, lam) */
} newton_state;

static void newton_destroy(void **state) {
  if (!state || !*state) return;
  newton_state *w = *state;
  ves_kkt_destroy(&w->kkt);
  free(w->g), free(w->J), free(w->r), free(w->sol), free(w->soc), free(w->xt), free(w->xn);
  anderson_destroy(&w->aa);
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
  ves_status st = ves_kkt_create(s, opt->factor_single, &w->kkt);
  if (st != VES_OK) {
    free(w);
    return st;
  }
  const size_t nv = (size_t)w->nvar, na = nv + VES_KKT_NROWS;
  w->g = malloc(nv * sizeof *w->g);
  w->J = calloc(VES_KKT_NROWS * nv, sizeof *w->J);
  w->r = malloc(nv * sizeof *w->r);
  w->sol = malloc(na * sizeof *w->sol);
  w->soc = malloc(na * sizeof *w->soc);
  w->xt = malloc(nv * sizeof *w->xt);
  w->xn = malloc(nv * sizeof *w->xn);
  *state = w;
  if (!w->g || !w->J || !w->r || !w->sol || !w->soc || !w->xt || !w->xn ||
      anderson_create((int)na, w->nvar, &w->aa) != VES_OK) {
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

/* Assemble H at (x, lam) into the KKT values' (1,1) block (no copy of its
 * own: at eps 0.01 the block has 1.5e7 entries), the rows, and factorize
 * with the inertia correction: exactly VES_KKT_NROWS negative pivots. A rung
 * of the ladder adds (delta - the last rung's delta) K in place. The ladder
 * remembers (as Ipopt's): after a corrected factorization with delta the
 * next correction starts at delta/10, a step's first build at the
 * correction the last step's first build needed (forgotten at a fresh
 * step, so a restart stays bit for bit), and it climbs x100 while more
 * than NEWTON_NEG_JUMP extra negative pivots remain: each rung is a
 * factorization (docs/results.md, "Robustness at large Δt"). The limit
 * opt->max_correction (0: none) gives the attempt up with VES_MAXITER, so
 * the integrator retries at dt/2; it is the ladder's last rung itself. */
static ves_status assemble_factor(newton_state *w, ves_step *s, const double *x, const double *lam,
                                  int ncon, ves_backend_stats *stt) {
  double *H = w->kkt.val; /* the first nh values */
  w->have_factor = 0;     /* the values are overwritten from here on */
  /* a matrix factored in single precision is formed in it (step.h) */
  VES_CALL(w->opt.factor_single ? ves_step_eval_hess_single(s, x, 1.0, lam, H)
                                : ves_step_eval_hess(s, x, 1.0, lam, H));
  stt->h_evals++;
  w->noise = ves_step_hess_floor(s, x, H, w->xt); /* the residual's floor, w->xt scratch */
  ves_kkt_fill_rows(&w->kkt, w->J, ncon);
  const double *K = NULL;              /* assembled only for a correction (ves_step_K) */
  const int first = stt->h_evals == 1; /* the step's first build */
  const double d0 = fmax(fmax(NEWTON_DELTA0, w->delta_last / 10), first ? w->delta_hint : 0);
  /* the ladder's first rung: delta = 0, unless the last build of the step
   * needed a correction, whose third is tried first (the iterate moved
   * little since: at eps 0.01, dt* 0.8, builds needing delta 1..10 follow
   * one another) */
  double delta = w->delta_build / 3 >= NEWTON_DELTA0 ? w->delta_build / 3 : 0, in = 0;
  const double lim = w->opt.max_correction;
  for (;;) {
    if (lim > 0 && delta > lim) {        /* before the ladder's end: the limit is named */
      stt->limit = VES_LIMIT_CORRECTION; /* a step far beyond its unstable modes' time */
      return VES_MAXITER;
    }
    if (delta > NEWTON_DELTA_MAX) return VES_ERR_SINGULAR;
    if (delta != in) { /* H + delta K: the difference to the last rung added */
      if (!K && !(K = ves_step_K(s))) return VES_ERR_ALLOC;
      for (int t = 0; t < w->kkt.nh; t++) H[t] += (delta - in) * K[t];
      in = delta;
    }
    ves_status st = ves_kkt_factor(&w->kkt);
    stt->factorizations++;
    if (st == VES_OK && w->kkt.neg == VES_KKT_NROWS) {
      if (delta > 0) w->delta_last = delta;
      w->delta_build = delta;
      if (first) w->delta_hint = delta;
      w->have_factor = 1, w->ncon_factor = ncon;
      w->dt_factor = ves_step_get_params(s)->dt;
      return VES_OK;
    }
    if (st != VES_OK && st != VES_ERR_SINGULAR) return st; /* not an inertia problem */
    /* the next rung: x10, or x100 when many directions are still negative
     * (50 extra negative pivots at delta 0 need delta ~1e3) */
    const int extra = st == VES_OK ? w->kkt.neg - VES_KKT_NROWS : 0;
    delta = delta == 0 ? d0 : (extra > NEWTON_NEG_JUMP ? 100 : 10) * delta;
    /* the limit itself is the last rung: a matrix that needs no more than
     * max_correction is not given up for the ladder's grid */
    if (lim > 0 && in < lim && delta > lim) delta = lim;
  }
}

/* The KKT solves' refinement target: NEWTON_SOLVE_TOL for the chord (a
 * frozen Hessian: it converges linearly whatever the accuracy of its
 * direction, since its residual is recomputed exactly, so a single
 * precision factor's solve is refined only that far, an inexact Newton
 * forcing term far below the chord's contraction; docs/results.md,
 * "Performance and its scaling"), VES_LDL_REFINE_TOL for Newton proper
 * (quadratic convergence) and for a chord direction whose error could hide
 * under the rounding floor (w->at_floor, set by floor_direction). */
static double solve_tol(const newton_state *w) {
  return w->opt.freeze_hessian && !w->at_floor ? NEWTON_SOLVE_TOL : VES_LDL_REFINE_TOL;
}

/* Whether the chord direction dx (solved to NEWTON_SOLVE_TOL) must be solved
 * again refined: when the convergence test is the rounding floor N (N >
 * tol S), a residual below N is accepted whatever error the direction
 * carried, and that error, ~NEWTON_SOLVE_TOL |dx| (2.5e-3 |dx| on
 * test_step's dt 1e-6 step, tol 1e-11, converged after one chord
 * iteration), stays in the answer. It is negligible against the step's
 * displacement |x + dx - x^n| when |dx| is below NEWTON_FLOOR_FRAC of it
 * (an error <= ~2.5e-5 of the displacement), as for the corrections after
 * a good predictor; a direction that carries the step (the first from x^n,
 * a poor predictor) is refined. Refining every solve at the floor costs
 * the eps 0.01 oblate relaxation ~11% (docs/results.md, "Performance and
 * its scaling"). */
static int floor_direction(const newton_state *w, const double *x, const double *dx, double res,
                           double scale) {
  if (!w->opt.freeze_hessian || w->noise <= w->opt.tol * scale || res <= w->opt.tol * scale)
    return 0;
  double d = 0, u = 0;
  for (int j = 0; j < w->nvar; j++) {
    d = fmax(d, fabs(dx[j]));
    u = fmax(u, fabs(x[j] + dx[j] - w->xn[j]));
  }
  return d > NEWTON_FLOOR_FRAC * u;
}

/* Values at x: f and c (one model pass). */
static ves_status eval_fc(ves_step *s, const double *x, double *f, double *c,
                          ves_backend_stats *stt) {
  stt->f_evals++;
  VES_CALL(ves_step_eval_f(s, x, f));
  return ves_step_eval_c(s, x, c);
}

/* Gradients at x: g and J (one model pass, values from the cache). */
static ves_status eval_gJ(newton_state *w, ves_step *s, const double *x, ves_backend_stats *stt) {
  stt->g_evals++;
  VES_CALL(ves_step_eval_grad(s, x, w->g));
  return ves_step_eval_jac(s, x, w->J);
}

static double l1(int n, const double *c) {
  double a = 0;
  for (int i = 0; i < n; i++) a += fabs(c[i]);
  return a;
}

/* The tail of a chord iteration: within NEWTON_TAIL of the tolerance the
 * merit function's changes are at the rounding of f (dt E summed over all
 * points), its directional derivative carries that noise, and a stale
 * matrix's step can be refused as "no descent" although it converges; a
 * rebuild for the last digits costs a whole Hessian and factorization
 * (at eps 0.01 one of the two of a step). There the full step
 * (dx, dlam) is judged by the KKT residual instead: taken when it falls by
 * NEWTON_STALL. *ok = 1: x, lam, f, c and w->g, w->J are at the new point;
 * 0: unchanged (w->g, w->J re-evaluated at x). */
static ves_status tail_step(newton_state *w, ves_step *s, double *x, double *lam, const double *dx,
                            const double *dlam, int ncon, double res, double *f, double *c, int *ok,
                            ves_backend_stats *stt) {
  const int nv = w->nvar;
  double ft, ct[VES_KKT_NROWS] = {0, 0};
  *ok = 0;
  for (int j = 0; j < nv; j++) w->xt[j] = x[j] + dx[j];
  ves_step_eager_gradients(s, 1);
  ves_status e = eval_fc(s, w->xt, &ft, ct, stt);
  ves_step_eager_gradients(s, 0);
  if (e == VES_ERR_DOMAIN) return VES_OK;
  VES_CALL(e);
  VES_CALL(eval_gJ(w, s, w->xt, stt));
  double rt = 0;
  for (int j = 0; j < nv; j++) {
    double r = w->g[j];
    for (int i = 0; i < ncon; i++) r += (lam[i] + dlam[i]) * w->J[(size_t)i * nv + j];
    rt = fmax(rt, fabs(r));
  }
  if (rt <= NEWTON_STALL * res) {
    memcpy(x, w->xt, (size_t)nv * sizeof *x);
    for (int i = 0; i < ncon; i++) lam[i] += dlam[i], c[i] = ct[i];
    *f = ft;
    *ok = 1;
    return VES_OK;
  }
  return eval_gJ(w, s, x, stt); /* back to x */
}

/* r = g + J^T lam into w->r; returns |r|_inf and *scale = max(gscale,
 * |J^T lam|_inf) (1 when both vanish): the convergence test's size. */
static double residual(newton_state *w, const double *lam, int ncon, double gscale, double *scale) {
  const int nv = w->nvar;
  memcpy(w->r, w->g, (size_t)nv * sizeof *w->r);
  double jl = 0;
  for (int i = 0; i < ncon; i++)
    for (int j = 0; j < nv; j++) w->r[j] += lam[i] * w->J[(size_t)i * nv + j];
  if (ncon) {
    for (int j = 0; j < nv; j++) jl = fmax(jl, fabs(w->r[j] - w->g[j]));
  }
  *scale = fmax(gscale, jl);
  if (*scale == 0) *scale = 1;
  return norm_inf(nv, w->r);
}

/* Directional derivative of the l1 merit function f + mu sum |c_i| along
 * dx, with the current g and J (exact even when the matrix is frozen). */
static double merit_slope(const newton_state *w, const double *dx, const double *c, double mu,
                          int ncon) {
  const int nv = w->nvar;
  double D = 0;
  for (int j = 0; j < nv; j++) D += w->g[j] * dx[j];
  for (int i = 0; i < ncon; i++) {
    double jd = 0;
    for (int j = 0; j < nv; j++) jd += w->J[(size_t)i * nv + j] * dx[j];
    D += mu * (c[i] > 0 ? jd : c[i] < 0 ? -jd : fabs(jd));
  }
  return D;
}

/* Backtracking on the merit function phi from x along dx (phi0 = phi(x),
 * Dm = min(slope, 0), fnoise its rounding allowance); VES_ERR_DOMAIN at a
 * trial point = too long: halve. At the full step a second-order correction
 * [H J^T; J 0][p; q] = [0; -c(x + dx)] is tried when it is rejected
 * (Maratos effect). *accepted: the trial w->xt (value *ft, constraints ct)
 * passed, at step length *a or, *used_soc, as x + dx + p. Returns VES_OK or
 * the first error that is not a domain error. */
static ves_status line_search(newton_state *w, ves_step *s, const double *x, const double *dx,
                              int ncon, double mu, double phi0, double Dm, double fnoise,
                              double *ft, double *ct, double *a, int *accepted, int *used_soc,
                              ves_backend_stats *stt) {
  const int nv = w->nvar;
  *a = 1, *accepted = 0, *used_soc = 0;
  for (int ls = 0; ls < NEWTON_MAX_LS; ls++, *a *= 0.5) {
    for (int j = 0; j < nv; j++) w->xt[j] = x[j] + *a * dx[j];
    /* the full step is usually taken: its gradients in the same model pass */
    ves_step_eager_gradients(s, ls == 0);
    ves_status e = eval_fc(s, w->xt, ft, ct, stt);
    ves_step_eager_gradients(s, 0);
    if (e == VES_ERR_DOMAIN) continue;
    VES_CALL(e);
    if (*ft + mu * l1(ncon, ct) <= phi0 + NEWTON_ARMIJO * *a * Dm + fnoise) {
      *accepted = 1;
      return VES_OK;
    }
    if (ls == 0 && ncon > 0) {
      memset(w->soc, 0, (size_t)(nv + VES_KKT_NROWS) * sizeof *w->soc);
      for (int i = 0; i < ncon; i++) w->soc[nv + i] = -ct[i];
      VES_CALL(ves_kkt_solve_tol(&w->kkt, w->soc, solve_tol(w)));
      for (int j = 0; j < nv; j++) w->xt[j] = x[j] + dx[j] + w->soc[j];
      e = eval_fc(s, w->xt, ft, ct, stt);
      if (e != VES_ERR_DOMAIN) VES_CALL(e);
      if (e == VES_OK && *ft + mu * l1(ncon, ct) <= phi0 + NEWTON_ARMIJO * Dm + fnoise) {
        *accepted = *used_soc = 1;
        return VES_OK;
      }
    }
  }
  return VES_OK;
}

/* Newton's iteration on the step's KKT conditions (the banner's method).
 * With a frozen Hessian a fresh matrix is built when the chord stalls: no
 * descent, a line search that had to cut the step, or a residual that did
 * not halve over the last NEWTON_STALL_WINDOW iterations (fewer since the
 * build). ~150 lines, kept whole: one loop whose iterations share the
 * iterate, the multipliers, the merit parameter, the stall window and the
 * freshness of the matrix, and leave it from six places (converged, limit,
 * rebuild, tail step, no descent, error); the parts with a meaning of their
 * own (assemble_factor, anderson_step, residual, merit_slope, line_search,
 * tail_step) are functions. */
static ves_status newton_solve(void *state, ves_step *s, double *x, double *lambda,
                               ves_backend_stats *stt) {
  VES_CHECK(state && s && x && stt, VES_ERR_ARG);
  memset(stt, 0, sizeof *stt);
  const double t0 = ves_wall_seconds();
  newton_state *w = state;
  const ves_step_params *par = ves_step_get_params(s);
  VES_CHECK(par, VES_ERR_ARG); /* ves_step_set not called */
  const int nv = w->nvar, ncon = ves_step_ncon(s);
  /* the last step's matrix as this one's chord matrix (freeze 2), unless
   * the step is fresh (a restart point, a retry), holds other constraints,
   * or its dt differs by more than NEWTON_REUSE_DT (the stiff modes, dt
   * Hess E, would contract at |1 - dt/dt_m| only): one assembly (~10x a
   * chord iteration at eps 0.01) serves several steps at small dt */
  const int reuse = w->opt.freeze_hessian >= 2 && w->have_factor && !par->fresh &&
                    w->ncon_factor == ncon && par->dt <= NEWTON_REUSE_DT * w->dt_factor &&
                    w->dt_factor <= NEWTON_REUSE_DT * par->dt;
  if (!reuse) w->have_factor = 0, w->noise = 0, w->delta_last = 0, w->delta_build = 0;
  if (par->fresh) w->delta_hint = 0; /* a restart point or a retry: as a new run */
  anderson_reset(&w->aa);            /* a new step: a new residual */
  VES_CHECK(nv == ves_step_nvar(s), VES_ERR_ARG);
  VES_CHECK(ncon == 0 || lambda, VES_ERR_ARG);
  double tgt[VES_KKT_NROWS] = {1, 1}, lam[VES_KKT_NROWS] = {0, 0}, c[VES_KKT_NROWS] = {0, 0},
         ct[VES_KKT_NROWS] = {0, 0};
  ves_step_get_targets(s, tgt);
  ves_step_x0(s, w->xn);
  for (int i = 0; i < ncon; i++) lam[i] = lambda[i];

  double f, ft, mu = 0;
  ves_status st = eval_fc(s, x, &f, c, stt);
  if (st == VES_OK) st = eval_gJ(w, s, x, stt);
  const double gscale = norm_inf(nv, w->g);
  int fresh = !reuse;                  /* build the matrix at the next iteration */
  double res_win[NEWTON_STALL_WINDOW]; /* residuals since the matrix was built, newest last */
  int nwin = 0;
  ves_status result = VES_ERR_NOCONV;
  while (st == VES_OK) {
    /* residual r = g + J^T lam and the convergence test */
    double scale, res = residual(w, lam, ncon, gscale, &scale), viol = 0;
    /* the residual is not resolved below the rounding of x itself: x is
     * stored to eps_mach |x| absolute, and H magnifies that to
     * eps_mach (|H| |x|)_inf (the residual's plateau is 0.3 of this bound) */
    const double floor_res = w->noise > 0 ? w->noise : 0.0;
    for (int i = 0; i < ncon; i++) viol = fmax(viol, fabs(c[i]) / tgt[i]);
    stt->violation = viol;
    if (res <= fmax(w->opt.tol * scale, floor_res) && viol <= w->opt.ctol) {
      result = VES_OK;
      break;
    }
    if (stt->iterations >= w->opt.max_iter) {
      result = VES_MAXITER, stt->limit = VES_LIMIT_ITER;
      break;
    }
    /* the chord stalls: the residual has not halved over the window (since the
     * build, at most NEWTON_STALL_WINDOW iterations back) */
    if (w->opt.freeze_hessian && !fresh && nwin > 0 && res > NEWTON_STALL * res_win[0]) fresh = 1;
    if (nwin == NEWTON_STALL_WINDOW) memmove(res_win, res_win + 1, --nwin * sizeof *res_win);
    res_win[nwin++] = res;
    int built_now = 0;
    if (w->opt.freeze_hessian && fresh && w->opt.max_builds > 0 &&
        stt->h_evals >= w->opt.max_builds) {
      /* opt->max_builds (0: none): a damped attempt that wanders builds a
       * matrix nearly every iteration; given up, the integrator retries at
       * dt/2. Accepted attempts build up to ~30 as well, so no limit
       * separates the two and it is off by default (docs/results.md,
       * "Robustness at large Δt"). */
      result = VES_MAXITER, stt->limit = VES_LIMIT_BUILDS;
      break;
    }
    if (fresh || !w->opt.freeze_hessian) {
      if ((st = assemble_factor(w, s, x, lam, ncon, stt)) != VES_OK) break;
      fresh = 0, built_now = 1;
    }
    /* Newton direction: [H J^T; J 0][dx; dlam] = -[r; c] */
    w->at_floor = 0;
    for (int j = 0; j < nv; j++) w->sol[j] = -w->r[j];
    for (int i = 0; i < VES_KKT_NROWS; i++) w->sol[nv + i] = i < ncon ? -c[i] : 0.0;
    if ((st = ves_kkt_solve_tol(&w->kkt, w->sol, solve_tol(w))) != VES_OK) break;
    if (floor_direction(w, x, w->sol, res, scale)) { /* again, refined */
      w->at_floor = 1;
      for (int j = 0; j < nv; j++) w->sol[j] = -w->r[j];
      for (int i = 0; i < VES_KKT_NROWS; i++) w->sol[nv + i] = i < ncon ? -c[i] : 0.0;
      if ((st = ves_kkt_solve_tol(&w->kkt, w->sol, solve_tol(w))) != VES_OK) break;
    }
    const double *dx = w->sol, *dlam = w->sol + nv;
    int accel = 0;
    if (built_now) { /* a new matrix: a new iteration map */
      anderson_reset(&w->aa);
      res_win[0] = res, nwin = 1;
    }
    if (w->opt.freeze_hessian) { /* the chord: accelerated when it has a history */
      accel = anderson_step(&w->aa, x, lam, w->sol);
      dx = w->aa.p, dlam = w->aa.p + nv;
    }
    /* merit parameter and directional derivative of phi along dx (with the
     * current J: exact even when the matrix is frozen) */
    double lmax = 0;
    for (int i = 0; i < ncon; i++) lmax = fmax(lmax, fabs(lam[i] + dlam[i]));
    mu = fmax(mu, 2 * lmax);
    double D = merit_slope(w, dx, c, mu, ncon);
    if (D >= 0 && accel) { /* the accelerated step is no descent: the plain chord step */
      anderson_plain(&w->aa, w->sol);
      accel = 0;
      D = merit_slope(w, dx, c, mu, ncon);
    }
    if (D >= 0 && !built_now) {                      /* a stale matrix gave no descent: rebuild */
      if (res <= NEWTON_TAIL * w->opt.tol * scale) { /* unless the tail converges */
        int ok = 0;
        if ((st = tail_step(w, s, x, lam, dx, dlam, ncon, res, &f, c, &ok, stt)) != VES_OK) break;
        if (ok) {
          stt->iterations++;
          continue;
        }
      }
      fresh = 1;
      continue;
    }
    const double phi0 = f + mu * l1(ncon, c), Dm = fmin(D, 0);
    /* Armijo with a rounding allowance (as Ipopt's line search): f holds
     * dt E ~ dt 2 pi k, summed over all points, so near the solution the
     * predicted decrease a D falls below the rounding of f itself and a
     * strict test rejects every step of a converging iteration
     * (problems/mode2.ini at dt* 0.04: 28 iterations and two halvings). */
    const double fnoise = NEWTON_FNOISE * DBL_EPSILON * fabs(phi0);
    double a = 1;
    int accepted = 0, used_soc = 0;
    st = line_search(w, s, x, dx, ncon, mu, phi0, Dm, fnoise, &ft, ct, &a, &accepted, &used_soc,
                     stt);
    if (st != VES_OK) break;
    if (!accepted) {
      if (!built_now) {                                /* a stale matrix: rebuild and retry */
        if (res <= NEWTON_TAIL * w->opt.tol * scale) { /* unless the tail converges */
          int ok = 0;
          if ((st = eval_gJ(w, s, x, stt)) != VES_OK) break; /* the trials moved the cache */
          if ((st = tail_step(w, s, x, lam, dx, dlam, ncon, res, &f, c, &ok, stt)) != VES_OK) break;
          if (ok) {
            stt->iterations++;
            continue;
          }
        }
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
  if (st != VES_OK)
    result = st == VES_ERR_SINGULAR ? VES_ERR_SOLVER : st; /* no usable KKT matrix */
  if (result != VES_OK) w->have_factor = 0; /* a failed attempt's matrix is not carried over */
  for (int i = 0; i < ncon; i++) lambda[i] = lam[i];
  stt->solver_status = (int)result;
  stt->seconds = ves_wall_seconds() - t0;
  return result;
}

const ves_backend_type ves_backend_newton = {
    "newton", newton_create, newton_solve, newton_destroy, 0, 0};
