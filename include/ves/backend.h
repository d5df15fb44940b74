/* vesica — the solvers of one step problem, behind one small table
 * {name, create, solve, destroy} (docs/design.md, "Backends"):
 *   ipopt   Ipopt 3.11 (MUMPS inside), exact sparse Hessian of the Lagrangian
 *   nlopt   NLopt 2.7 augmented Lagrangian around a gradient-based optimizer
 *   newton  Lagrange-Newton on the KKT system, MUMPS, optional frozen Hessian,
 *           line search on a merit function
 *   euler   explicit forward Euler on K ydot = -grad E + sum sigma grad c,
 *           grad c^T ydot = 0 (not an NLP solve: the paper's comparison) */
#ifndef VES_BACKEND_H
#define VES_BACKEND_H

#include "ves/status.h"
#include "ves/step.h"

/* Options common to all backends (each documents which it honours). The
 * defaults (ves_backend_options_default) are the problem file's [solver]
 * keys' (vesica keys lists them). */
typedef struct {
  double tol;            /* optimality / KKT residual tolerance (relative; [solver] tol) */
  double ctol;           /* constraint violation tolerance, relative to A0, V ([solver] ctol) */
  int max_iter;          /* iteration limit per step ([solver] max_iter) */
  int max_builds;        /* newton with a frozen Hessian: matrix builds per step, then
                            VES_MAXITER ([solver] max_builds; 0 = no limit) */
  double max_correction; /* newton: the largest inertia correction delta (H + delta K)
                            a matrix may need, then VES_MAXITER ([solver]
                            max_correction; 0 = no limit) */
  int freeze_hessian;    /* newton: 0 = a fresh Hessian every iteration; 1 = assembled
                            once per step, rebuilt when the chord stalls (paper);
                            2 = also kept across steps (backend_newton.c) */
  int factor_single;     /* newton, euler: the KKT factorization in single precision, each
                            solve refined in double (ldl.h; [solver] factor_precision) */
  int verbose;           /* 0 quiet; > 0 lets the solver print (ipopt print_level) */
} ves_backend_options;

/* Statistics of one solve, the same for every backend. */
typedef struct {
  int iterations;     /* outer iterations (Newton steps, Ipopt iterations, ...) */
  int f_evals;        /* objective evaluations */
  int g_evals;        /* gradient evaluations */
  int h_evals;        /* Hessian assemblies */
  int factorizations; /* newton, euler: KKT factorizations (inertia corrections included) */
  double violation;   /* final max |c_i| / target_i */
  double seconds;     /* wall time */
  int solver_status;  /* the backend's own code (Ipopt ApplicationReturnStatus, nlopt_result) */
  int limit;          /* a VES_MAXITER return: the limit that ended the solve (ves_backend_limit) */
} ves_backend_stats;

/* Which limit ended a solve that returned VES_MAXITER (ves_backend_stats.limit),
 * each a problem-file key: the retry line names it. */
typedef enum {
  VES_LIMIT_NONE = 0,  /* the solve did not stop at a limit */
  VES_LIMIT_ITER,      /* [solver] max_iter (Ipopt's max_iter, nlopt's evaluation budget) */
  VES_LIMIT_BUILDS,    /* [solver] max_builds (newton with a frozen Hessian) */
  VES_LIMIT_CORRECTION /* [solver] max_correction (newton) */
} ves_backend_limit;

/* The problem-file key of a limit ("solver.max_iter", ...; "" for VES_LIMIT_NONE). */
const char *ves_backend_limit_key(int limit);

typedef struct {
  const char *name;
  /* state for a step problem s (borrowed); *state taken by the caller */
  ves_status (*create)(const ves_backend_options *opt, ves_step *s, void **state);
  /* x: in, the start (usually x0); out, the solution. lambda[ncon]: in, the
   * previous multipliers (warm start); out, the new ones (for Ipopt the
   * Lagrangian is f + lambda^T c). Returns VES_OK when converged, VES_MAXITER
   * when the limit was hit, VES_ERR_DOMAIN / VES_ERR_NOCONV / VES_ERR_SOLVER
   * on failure (the integrator then halves dt). */
  ves_status (*solve)(void *state, ves_step *s, double *x, double *lambda, ves_backend_stats *st);
  void (*destroy)(void **state);
  int ignores_start;    /* 1: solve computes x from x0 whatever x holds (the explicit euler
                           step): the integrator's predictor is not evaluated for it */
  int hard_by_hessians; /* 1: the step controller's iteration rule (time.iter_target)
                           counts the solve's Hessians, not its iterations: nlopt's
                           iterations are AUGLAG's outer ones, 10-20 a step where
                           newton needs 4-8, and each of its Hessians a metric for
                           a whole L-BFGS phase, its Newton-like unit */
} ves_backend_type;

/* The defaults: tol 1e-9, ctol 1e-10, max_iter 40, max_builds 0,
 * max_correction 0, freeze_hessian 1, factor_single 1, verbose 0 (the
 * problem file's [solver] defaults). */
void ves_backend_options_default(ves_backend_options *opt);

/* The table entry for a name ("ipopt", "nlopt", "newton", "euler"), or NULL. */
const ves_backend_type *ves_backend_find(const char *name);

extern const ves_backend_type ves_backend_ipopt, ves_backend_nlopt, ves_backend_newton,
    ves_backend_euler;

#endif
