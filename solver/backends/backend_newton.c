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
 * fixed point is still the exact KKT point), accelerated by Anderson mixing
 * of its last NEWTON_AA_DEPTH steps (anderson()). A fresh matrix is built
 * when the chord stalls: no descent, a line search that had to cut the step,
 * or a residual that did not halve over the last NEWTON_STALL_WINDOW
 * iterations (fewer since the build: the Newton step of a fresh matrix must
 * halve it at once). Measured at eps 0.01 (bench/RESULTS.md): after the
 * Newton step the plain chord often stalled at ~1e-3 of the start residual
 * and a second matrix was built in most steps; the accelerated chord gets
 * through that in 2-4 more iterations (~1/15 of a build each). Close to the
 * tolerance a step the merit function cannot judge is judged by the
 * residual (tail_step).
 *
 * freeze_hessian = 2 keeps the factorization across steps as well: a step
 * starts with the last one (K(y^m) + dt_m Hess E(y^m) + ..., m < n) as its
 * chord matrix unless the step is marked fresh (ves_step_params.fresh: a
 * restart point, a retried step), its dt differs from dt_m by more than
 * NEWTON_REUSE_DT (the stiff modes, dt Hess E, would then contract at
 * |1 - dt/dt_m| only), or the constraints held differ. The same stall rules
 * rebuild it. At small dt the matrix of a step is within a few percent of
 * the previous step's: one assembly (Hessian + K's share + factorization,
 * ~10x a chord iteration at eps 0.01) serves several steps.
 *
 * Inexact chord solves: with a frozen Hessian the iteration is a chord
 * method, which converges linearly whatever the accuracy of its direction
 * (its residual g + J^T lam and c are recomputed exactly, and so is its
 * fixed point), so single precision factors (opt->factor_single) are
 * refined only to |b - A x| <= NEWTON_SOLVE_TOL |b| (inexact Newton with
 * forcing term NEWTON_SOLVE_TOL, far below the chord's own contraction,
 * 0.05-0.3 a step at eps 0.01). The single precision solve alone is
 * within 1e-5..2e-4 on the KKT matrices at eps 0.01, so the refinement's
 * second MUMPS solve and product are skipped: half a solve's cost
 * (bench/RESULTS.md, session 23). freeze_hessian = 0 (Newton proper)
 * refines to VES_LDL_REFINE_TOL, keeping its quadratic convergence, and so
 * does a chord iteration whose error could hide under the rounding floor (solve_tol).
 *
 * Inertia correction memory (as Ipopt's): after a corrected factorization
 * with delta, the next one that needs a correction starts at delta/10
 * instead of NEWTON_DELTA0 (each rung of the ladder is a factorization:
 * measured on an eps 0.02 oblate step at dt* 0.3, 7 factorizations for
 * delta = 0, 1e-3, ..., 100). The memory is forgotten with the matrix.
 * Within a step, a build after one that needed delta_b starts its ladder at
 * delta_b/3 instead of 0 (0 again once delta_b/3 < NEWTON_DELTA0), and the
 * ladder climbs x100 instead of x10 while more than NEWTON_NEG_JUMP extra
 * negative pivots remain: at eps 0.01 and dt* ~0.8 the step Hessian has
 * 5-50 directions of negative curvature (the spurious modes of issue 22)
 * and each rung is a factorization (~5 s there).
 * Across steps, the ladder of a step's first build climbs from the
 * correction the previous step's first build needed (delta = 0 is still
 * tried first): in the bud phase of the prolate C0 run at eps 0.01 the first
 * builds of consecutive steps needed 1, 10, 10, 100, 10, 10, each after the
 * rungs 0, 1e-3, 1e-2, 0.1, ... (6 factorizations of ~4 s, one thread, for 10;
 * bench/RESULTS.md, session 21). The hint is forgotten at a fresh step (a
 * restart point or a retry), so a restart stays bit for bit.
 *
 * Build limit (opt->max_builds, [solver] max_builds; 0, the default, = none):
 * an attempt that would build more matrices returns VES_MAXITER and the
 * integrator retries at dt/2. A failing attempt is a damped Newton run that
 * builds a matrix nearly every iteration until max_iter (measured: 23-38
 * builds in 40 iterations, 190-390 s at eps 0.02-0.04), but accepted
 * attempts built up to 29 (the eps 0.02 prolate, bench/RESULTS.md session
 * 19): no limit separates the two, and any limit changes some trajectories,
 * so it is off by default. Only with a frozen Hessian (freeze_hessian 0
 * builds at every iteration, and max_iter bounds it). bench_robust and the
 * robustness studies set 0 explicitly: their single large steps are meant
 * to run long (dt* 100: 30 builds).
 *
 * Correction limit (opt->max_correction, [solver] max_correction; 0, the
 * default, = none): a matrix whose ladder would go beyond this delta
 * returns VES_MAXITER before factorizing that rung, and the integrator
 * retries at dt/2; the limit itself is the ladder's last rung (a rung
 * beyond it is cut to it once), so the attempt is given up only when a
 * correction of max_correction does not suffice. The correction measures
 * how far the step is beyond the time of its fastest unstable mode: H +
 * delta K is positive definite (on the constraints' null space) once delta
 * > -(1 + dt mu_min), mu_min the most negative eigenvalue of Hess E against
 * K, so delta ~ 10 means dt ~ 10x that time, and a chord on (1 + delta) K +
 * dt Hess E contracts the viscous modes by only ~delta/(1 + delta) an
 * iteration. Traced in the prolate C0 run at eps 0.01 (NEWTON_TRACE,
 * session 37): the attempt at dt* 0.041 that was retried (step 19) needed
 * delta 100 at the predictor (20 extra negative pivots at 0, 7 at 10) and
 * then 3.3e3, 1.1e3, 370; the accepted steps before it (17, 18: 72 and 96
 * s) needed up to 33 and 11 in 20 factorizations each, against one matrix
 * at delta 0 for the steps at dt* 0.02 before them. Off by default: near
 * rest large steps meet the spurious modes above (5-50 negative directions
 * at dt* ~0.8) and still converge in a few builds, and the robustness
 * studies' single steps at dt* 100 are meant to run long.
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
 * when both vanish (an equilibrium without tension).
 *
 * Built with -DNEWTON_TRACE (make OPT="-O2 -g -DNEWTON_TRACE") the solve
 * prints each iteration (residual / S, violation, fresh matrix, step
 * length, acceleration, second-order correction) and each factorization's
 * rung (delta, negative pivots) to stderr. */
#include <float.h>
#include <math.h>
#ifdef NEWTON_TRACE
#include <stdio.h>
#endif
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "backends/backend_kkt_impl.h"
#include "ves/backend.h"
#include "core/clock_impl.h"

#define NEWTON_ARMIJO 1e-4 /* sufficient decrease of the merit function */
#define NEWTON_MAX_LS 40   /* backtracking halvings */
#ifndef NEWTON_DELTA0      /* overridable for measurements (bench/RESULTS.md, session 38) */
#define NEWTON_DELTA0 1e-3 /* first inertia correction, units of K */
#endif
#define NEWTON_DELTA_MAX 1e6  /* give up beyond this correction */
#define NEWTON_NEG_JUMP 8     /* more extra negative pivots than this: the next delta x100 */
#define NEWTON_STALL 0.5      /* frozen: refresh when |res| fell by less than this ... */
#define NEWTON_STALL_WINDOW 3 /* ... over this many iterations (fewer since the build) */
#define NEWTON_TAIL 1e3       /* the tail: |res| within this factor of the tolerance */
#define NEWTON_FNOISE 1e2     /* merit values closer than this many eps_mach |phi| are equal */
#define NEWTON_REUSE_DT 1.25  /* freeze 2: reuse while dt / dt_m is within [1/this, this] */
#define NEWTON_AA_DEPTH 5     /* Anderson acceleration of the chord: steps remembered */
#define NEWTON_AA_GROW 10.0   /* an accelerated step longer than this many chord steps is refused */
#define NEWTON_SOLVE_TOL 1e-3 /* frozen: the KKT solves' relative residual (single precision) */
#define NEWTON_FLOOR_FRAC 1e-2 /* at the floor: refine a direction above this of the step */

typedef struct {
  ves_backend_options opt; /* copied */
  kkt_system kkt;          /* KKT structure, values, factorization */
  int nvar;                /* free dofs */
  double *g;               /* nvar grad f at x */
  double *J;               /* KKT_NROWS nvar Jacobian at x */
  double *r;               /* nvar g + J^T lam */
  double *sol;             /* nvar + KKT_NROWS right-hand side / solution */
  double *soc;             /* nvar + KKT_NROWS second-order correction */
  double *xt;              /* nvar trial point */
  double noise;            /* eps_mach (|H| |x|)_inf at the last assembly */
  int have_factor;         /* the KKT factorization holds a usable chord matrix */
  double dt_factor;        /* the dt of the step whose matrix it is */
  int ncon_factor;         /* the constraints held in it */
  double delta_last;       /* the last inertia correction (0: none since the matrix was fresh) */
  double delta_build;      /* the correction of the last build (0: none was needed) */
  double delta_hint;       /* the correction the last step's first build needed (0: none) */
  int at_floor;            /* a loose direction's error would hide under the floor (solve_tol) */
  double *xn;              /* the step's start x^n (ves_step_x0): the displacement's origin */
  /* Anderson acceleration of the chord iteration (columns of nvar + KKT_NROWS) */
  double *aa_du;       /* NEWTON_AA_DEPTH differences of the iterates u = (x, lam) */
  double *aa_dg;       /* NEWTON_AA_DEPTH differences of their chord steps */
  double *aa_q;        /* NEWTON_AA_DEPTH orthonormalized aa_dg (x part), workspace */
  double *aa_u, *aa_g; /* the previous iterate and its chord step */
  double *aa_p;        /* the accelerated step */
  int aa_n;            /* columns held (0: none; the newest at (aa_n - 1)) */
  int aa_prev;         /* aa_u, aa_g hold the previous iterate of the same matrix */
} newton_state;

static void newton_destroy(void **state) {
  if (!state || !*state) return;
  newton_state *w = *state;
  kkt_destroy(&w->kkt);
  free(w->g), free(w->J), free(w->r), free(w->sol), free(w->soc), free(w->xt), free(w->xn);
  free(w->aa_du), free(w->aa_dg), free(w->aa_q), free(w->aa_u), free(w->aa_g), free(w->aa_p);
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
  ves_status st = kkt_create(s, opt->factor_single, &w->kkt);
  if (st != VES_OK) {
    free(w);
    return st;
  }
  const size_t nv = (size_t)w->nvar, na = nv + KKT_NROWS;
  w->g = malloc(nv * sizeof *w->g);
  w->J = calloc(KKT_NROWS * nv, sizeof *w->J);
  w->r = malloc(nv * sizeof *w->r);
  w->sol = malloc(na * sizeof *w->sol);
  w->soc = malloc(na * sizeof *w->soc);
  w->xt = malloc(nv * sizeof *w->xt);
  w->xn = malloc(nv * sizeof *w->xn);
  w->aa_du = malloc(NEWTON_AA_DEPTH * na * sizeof *w->aa_du);
  w->aa_dg = malloc(NEWTON_AA_DEPTH * na * sizeof *w->aa_dg);
  w->aa_q = malloc(NEWTON_AA_DEPTH * nv * sizeof *w->aa_q);
  w->aa_u = malloc(na * sizeof *w->aa_u);
  w->aa_g = malloc(na * sizeof *w->aa_g);
  w->aa_p = malloc(na * sizeof *w->aa_p);
  *state = w;
  if (!w->g || !w->J || !w->r || !w->sol || !w->soc || !w->xt || !w->xn || !w->aa_du || !w->aa_dg ||
      !w->aa_q || !w->aa_u || !w->aa_g || !w->aa_p) {
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
 * with the inertia correction: exactly KKT_NROWS negative pivots. A rung
 * of the ladder adds (delta - the last rung's delta) K in place. */
static ves_status assemble_factor(newton_state *w, ves_step *s, const double *x, const double *lam,
                                  int ncon, ves_backend_stats *stt) {
  double *H = w->kkt.val; /* the first nh values */
  w->have_factor = 0;     /* the values are overwritten from here on */
  /* a matrix factored in single precision is formed in it (step.h) */
  VES_CALL(w->opt.factor_single ? ves_step_eval_hess_single(s, x, 1.0, lam, H)
                                : ves_step_eval_hess(s, x, 1.0, lam, H));
  stt->h_evals++;
  w->noise = ves_step_hess_floor(s, x, H, w->xt); /* the residual's floor, w->xt scratch */
  kkt_fill_rows(&w->kkt, w->J, ncon);
  const double *K = NULL;              /* assembled only for a correction (ves_step_K) */
  const int first = stt->h_evals == 1; /* the step's first build */
  const double d0 = fmax(fmax(NEWTON_DELTA0, w->delta_last / 10), first ? w->delta_hint : 0);
  /* the ladder's first rung: delta = 0, unless the last build needed a
   * correction, whose third is tried first (the iterate moved little since;
   * measured at eps 0.01, dt* 0.8: 19 factorizations in 7 builds, a build
   * needing delta 1..10 after one that needed 1..10) */
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
    ves_status st = kkt_factor(&w->kkt);
    stt->factorizations++;
#ifdef NEWTON_TRACE
    fprintf(stderr, "newton   factor delta %.1e: %s, %d negative pivots\n", delta,
            ves_status_str(st), w->kkt.neg);
#endif
    if (st == VES_OK && w->kkt.neg == KKT_NROWS) {
      if (delta > 0) w->delta_last = delta;
      w->delta_build = delta;
      if (first) w->delta_hint = delta;
      w->have_factor = 1, w->ncon_factor = ncon;
      w->dt_factor = ves_step_get_params(s)->dt;
      return VES_OK;
    }
    if (st != VES_OK && st != VES_ERR_SINGULAR) return st; /* not an inertia problem */
    /* the next rung: x10, or x100 when many directions are still negative
     * (measured: 50 extra negative pivots at delta 0 needed delta 1e3) */
    const int extra = st == VES_OK ? w->kkt.neg - KKT_NROWS : 0;
    delta = delta == 0 ? d0 : (extra > NEWTON_NEG_JUMP ? 100 : 10) * delta;
    /* the limit itself is the last rung: a matrix that needs no more than
     * max_correction is not given up for the ladder's grid (which had made
     * a limit of 10 mean 3.3 after the rungs 0.033, 0.33, 3.3: RESULTS,
     * session 38) */
    if (lim > 0 && in < lim && delta > lim) delta = lim;
  }
}

/* The KKT solves' refinement target: NEWTON_SOLVE_TOL for the chord (a
 * frozen Hessian), VES_LDL_REFINE_TOL for Newton proper (the header) and
 * for a chord direction whose error could hide under the rounding floor
 * (w->at_floor, set by floor_direction). */
static double solve_tol(const newton_state *w) {
  return w->opt.freeze_hessian && !w->at_floor ? NEWTON_SOLVE_TOL : VES_LDL_REFINE_TOL;
}

/* Whether the chord direction dx (solved to NEWTON_SOLVE_TOL) must be solved
 * again refined: when the convergence test is the rounding floor N (N >
 * tol S), a residual below N is accepted whatever error the direction
 * carried, and that error, ~NEWTON_SOLVE_TOL |dx| (measured 2.5e-3 |dx|:
 * test_step's dt 1e-6 step, tol 1e-11, converged after one chord
 * iteration), stays in the answer. It is negligible against the step's
 * displacement |x + dx - x^n| when |dx| is below NEWTON_FLOOR_FRAC of it
 * (an error <= ~2.5e-5 of the displacement), as for the corrections after
 * a good predictor; a direction that carries the step (the first from x^n,
 * a poor predictor) is refined. Session 24 refined every solve at the
 * floor, which at eps 0.01 is nearly every solve of the oblate relaxation
 * and cost it ~11% (bench/RESULTS.md, session 25). */
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

/* Anderson acceleration (type II, depth NEWTON_AA_DEPTH) of the chord
 * iteration u <- u + g(u), g the step the frozen matrix gives at u: with
 * dU, dG the differences of the last iterates and their steps,
 *   gamma = argmin |g - dG gamma|_2 (x part),  p = g - (dU + dG) gamma.
 * For a linear residual this is GMRES on the frozen-matrix-preconditioned
 * system (Walker & Ni 2011): the chord's linear rate ||I - M0^-1 M|| becomes
 * a Krylov one, at no extra evaluation. The least squares by modified
 * Gram-Schmidt in fixed loops (deterministic: no BLAS threads); a column
 * that is nearly dependent on the newer ones ends the history there.
 * u = (x, lam) and g = (dx, dlam) over na = nvar + KKT_NROWS. Writes p into
 * w->aa_p and returns 1, or 0 when no history is held (p = g then). */
static int anderson(newton_state *w, const double *x, const double *lam, const double *g) {
  const int nv = w->nvar, na = nv + KKT_NROWS;
  if (w->aa_prev) {                   /* a new column: the differences to the previous iterate */
    if (w->aa_n == NEWTON_AA_DEPTH) { /* drop the oldest */
      memmove(w->aa_du, w->aa_du + na, (size_t)(NEWTON_AA_DEPTH - 1) * na * sizeof *w->aa_du);
      memmove(w->aa_dg, w->aa_dg + na, (size_t)(NEWTON_AA_DEPTH - 1) * na * sizeof *w->aa_dg);
      w->aa_n--;
    }
    double *du = w->aa_du + (size_t)w->aa_n * na, *dg = w->aa_dg + (size_t)w->aa_n * na;
    for (int j = 0; j < nv; j++) du[j] = x[j] - w->aa_u[j];
    for (int i = 0; i < KKT_NROWS; i++) du[nv + i] = lam[i] - w->aa_u[nv + i];
    for (int j = 0; j < na; j++) dg[j] = g[j] - w->aa_g[j];
    w->aa_n++;
  }
  memcpy(w->aa_u, x, (size_t)nv * sizeof *x);
  memcpy(w->aa_u + nv, lam, KKT_NROWS * sizeof *lam);
  memcpy(w->aa_g, g, (size_t)na * sizeof *g);
  w->aa_prev = 1;
  memcpy(w->aa_p, g, (size_t)na * sizeof *g);
  if (w->aa_n == 0) return 0;
  /* QR of the dG columns (x part), newest first; R upper triangular */
  double R[NEWTON_AA_DEPTH][NEWTON_AA_DEPTH] = {{0}}, rhs[NEWTON_AA_DEPTH], gam[NEWTON_AA_DEPTH];
  int m = 0;
  for (int c = w->aa_n - 1; c >= 0; c--, m++) {
    double *q = w->aa_q + (size_t)m * nv;
    const double *dg = w->aa_dg + (size_t)c * na;
    double n0 = 0;
    for (int j = 0; j < nv; j++) q[j] = dg[j], n0 += dg[j] * dg[j];
    for (int i = 0; i < m; i++) {
      const double *qi = w->aa_q + (size_t)i * nv;
      double d = 0;
      for (int j = 0; j < nv; j++) d += qi[j] * q[j];
      R[i][m] = d;
      for (int j = 0; j < nv; j++) q[j] -= d * qi[j];
    }
    double nn = 0;
    for (int j = 0; j < nv; j++) nn += q[j] * q[j];
    if (!(nn > 1e-20 * n0) || n0 == 0) break; /* dependent: the older columns go too */
    R[m][m] = sqrt(nn);
    for (int j = 0; j < nv; j++) q[j] /= R[m][m];
  }
  if (m < w->aa_n) { /* keep the m newest columns */
    const int drop = w->aa_n - m;
    memmove(w->aa_du, w->aa_du + (size_t)drop * na, (size_t)m * na * sizeof *w->aa_du);
    memmove(w->aa_dg, w->aa_dg + (size_t)drop * na, (size_t)m * na * sizeof *w->aa_dg);
    w->aa_n = m;
  }
  if (m == 0) return 0;
  for (int i = 0; i < m; i++) {
    const double *qi = w->aa_q + (size_t)i * nv;
    double d = 0;
    for (int j = 0; j < nv; j++) d += qi[j] * g[j];
    rhs[i] = d;
  }
  for (int i = m - 1; i >= 0; i--) { /* R gam = Q^T g */
    double d = rhs[i];
    for (int k = i + 1; k < m; k++) d -= R[i][k] * gam[k];
    gam[i] = d / R[i][i];
  }
  double gn = 0, pn = 0;
  for (int i = 0; i < m; i++) { /* column i of the QR is history column aa_n - 1 - i */
    const size_t c = (size_t)(w->aa_n - 1 - i) * na;
    for (int j = 0; j < na; j++) w->aa_p[j] -= gam[i] * (w->aa_du[c + j] + w->aa_dg[c + j]);
  }
  for (int j = 0; j < nv; j++) gn += g[j] * g[j], pn += w->aa_p[j] * w->aa_p[j];
  if (!(pn <= NEWTON_AA_GROW * NEWTON_AA_GROW * gn)) { /* a wild extrapolation: plain chord */
    memcpy(w->aa_p, g, (size_t)na * sizeof *g);
    w->aa_n = 0;
    return 0;
  }
  return 1;
}

/* The tail of a chord iteration: within NEWTON_TAIL of the tolerance the
 * merit function's changes are at the rounding of f (dt E summed over all
 * points), its directional derivative carries that noise, and a stale
 * matrix's step can be refused as "no descent" although it converges; a
 * rebuild for the last digits cost a whole Hessian and factorization
 * (measured at eps 0.01: one of the two of a step). There the full step
 * (dx, dlam) is judged by the KKT residual instead: taken when it falls by
 * NEWTON_STALL. *ok = 1: x, lam, f, c and w->g, w->J are at the new point;
 * 0: unchanged (w->g, w->J re-evaluated at x). */
static ves_status tail_step(newton_state *w, ves_step *s, double *x, double *lam, const double *dx,
                            const double *dlam, int ncon, double res, double *f, double *c, int *ok,
                            ves_backend_stats *stt) {
  const int nv = w->nvar;
  double ft, ct[KKT_NROWS] = {0, 0};
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
      memset(w->soc, 0, (size_t)(nv + KKT_NROWS) * sizeof *w->soc);
      for (int i = 0; i < ncon; i++) w->soc[nv + i] = -ct[i];
      VES_CALL(kkt_solve_tol(&w->kkt, w->soc, solve_tol(w)));
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

/* Newton's iteration on the step's KKT conditions (the header's method).
 * Still ~150 lines: one loop whose iterations share the iterate, the
 * multipliers, the merit parameter, the stall window and the freshness of
 * the matrix, and leave it from six places (converged, limit, rebuild,
 * tail step, no descent, error); the parts with a meaning of their own
 * (assemble_factor, anderson, residual, merit_slope, line_search,
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
  /* the last step's matrix as this one's chord matrix (freeze 2) */
  const int reuse = w->opt.freeze_hessian >= 2 && w->have_factor && !par->fresh &&
                    w->ncon_factor == ncon && par->dt <= NEWTON_REUSE_DT * w->dt_factor &&
                    w->dt_factor <= NEWTON_REUSE_DT * par->dt;
  if (!reuse) w->have_factor = 0, w->noise = 0, w->delta_last = 0, w->delta_build = 0;
  if (par->fresh) w->delta_hint = 0; /* a restart point or a retry: as a new run */
  w->aa_n = 0, w->aa_prev = 0;       /* a new step: a new residual */
  VES_CHECK(nv == ves_step_nvar(s), VES_ERR_ARG);
  VES_CHECK(ncon == 0 || lambda, VES_ERR_ARG);
  double tgt[KKT_NROWS] = {1, 1}, lam[KKT_NROWS] = {0, 0}, c[KKT_NROWS] = {0, 0},
         ct[KKT_NROWS] = {0, 0};
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
     * eps_mach (|H| |x|)_inf (measured plateau: 0.3 of this bound) */
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
        stt->h_evals >= w->opt.max_builds) { /* a damped attempt that wanders: give it up */
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
    for (int i = 0; i < KKT_NROWS; i++) w->sol[nv + i] = i < ncon ? -c[i] : 0.0;
    if ((st = kkt_solve_tol(&w->kkt, w->sol, solve_tol(w))) != VES_OK) break;
    if (floor_direction(w, x, w->sol, res, scale)) { /* again, refined */
      w->at_floor = 1;
      for (int j = 0; j < nv; j++) w->sol[j] = -w->r[j];
      for (int i = 0; i < KKT_NROWS; i++) w->sol[nv + i] = i < ncon ? -c[i] : 0.0;
      if ((st = kkt_solve_tol(&w->kkt, w->sol, solve_tol(w))) != VES_OK) break;
    }
    const double *dx = w->sol, *dlam = w->sol + nv;
    int accel = 0;
    if (built_now) { /* a new matrix: a new iteration map */
      w->aa_n = 0, w->aa_prev = 0;
      res_win[0] = res, nwin = 1;
    }
    if (w->opt.freeze_hessian) { /* the chord: accelerated when it has a history */
      accel = anderson(w, x, lam, w->sol);
      dx = w->aa_p, dlam = w->aa_p + nv;
    }
    /* merit parameter and directional derivative of phi along dx (with the
     * current J: exact even when the matrix is frozen) */
    double lmax = 0;
    for (int i = 0; i < ncon; i++) lmax = fmax(lmax, fabs(lam[i] + dlam[i]));
    mu = fmax(mu, 2 * lmax);
    double D = merit_slope(w, dx, c, mu, ncon);
    if (D >= 0 && accel) { /* the accelerated step is no descent: the plain chord step */
      w->aa_n = 0;
      memcpy(w->aa_p, w->sol, (size_t)(nv + KKT_NROWS) * sizeof *w->aa_p);
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
     * strict test rejects every step of a converging iteration (measured:
     * problems/mode2.ini at dt* = 0.04, 28 iterations and two halvings). */
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
#ifdef NEWTON_TRACE
    fprintf(
        stderr, "newton it %2d dt %.3e res/S %.3e viol %.1e built %d h %d a %.3g accel %d soc %d\n",
        stt->iterations, par->dt, res / scale, viol, built_now, stt->h_evals, a, accel, used_soc);
#endif
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
