/* vesica — one time step as a generic constrained nonlinear program
 * (paper Eq. 11; docs/design.md, "The time step"): given y^n and dt,
 *
 *   minimize   f(x) = (1/2)(y - y^n)^T K(y^n) (y - y^n) + dt E(y)
 *   subject to c_A(x) = A(y) - A0 = 0            (when the area is held)
 *              c_V(x) = V(y) - V_target = 0      (when the volume is held)
 *
 * over the free degrees of freedom x of y (fixed ones keep their y^n values).
 * Every backend consumes exactly this object; it knows nothing of them. */
#ifndef VES_STEP_H
#define VES_STEP_H

#include "ves/model.h"
#include "ves/status.h"

/* What one step solves for. */
typedef struct {
  double dt;       /* time step (t* units) */
  int hold_area;   /* 1: constraint A(y) = A0 */
  double A0;       /* target area (units R0^2) */
  int hold_volume; /* 1: constraint V(y) = V_target */
  double V_target; /* target volume at t_{n+1} (units R0^3) */
  int fresh;       /* 1: the solver may carry nothing over from earlier steps (a
                      restart point: a run restarted from here repeats the next
                      steps bit for bit only if the original run started them
                      afresh too); 0: it may (the newton backend's factorization) */
} ves_step_params;

typedef struct ves_step ves_step;

/* Create for a model (borrowed: it must outlive the step). Workspaces are
 * allocated here, never in the evaluations. */
ves_status ves_step_create(ves_model *m, ves_step **out);
void ves_step_destroy(ves_step **s);

/* Start a step from y^n (2n full positions, copied): assembles K(y^n) and
 * stores the targets. */
ves_status ves_step_set(ves_step *s, const double *yn, const ves_step_params *par);

/* The largest step ratio dt / dt_prev of a BDF2 step: variable-step BDF2 is
 * zero-stable for ratios below 1 + sqrt 2. */
#define VES_BDF2_RATIO_MAX 2.4
/* Make the set step a BDF2 step (second order in dt) from the positions
 * y^{n-1} (2n, on the same reference) before the last accepted step and the
 * ratio w = dt / dt_prev of this step to that one, in (0, 2.4]:
 *   f(x) = (1/2)(y - y^a)^T K(y~) (y - y^a) + (dt / alpha) E(y),
 *   alpha = (1 + 2w)/(1 + w),  y^a = c y^n + (1 - c) y^{n-1},
 *   c = (1 + w)^2/(1 + 2w),    y~ = (1 + w) y^n - w y^{n-1},
 * whose stationarity is K(y~) (alpha/dt)(y - y^a) = -grad E - J^T lambda,
 * the variable-step BDF2 formula (docs/design.md, "The incremental
 * potential"). The start ves_step_x0 stays y^n; ves_step_get_params()->dt
 * becomes dt / alpha, the weight of E in f (the constraints' multipliers
 * scale with it). Called once after ves_step_set (VES_ERR_ARG otherwise),
 * before any evaluation; the next ves_step_set makes a backward Euler step
 * again. VES_ERR_DOMAIN when y~ or y^{n-1} is not admissible (det F <= 0 or
 * r <= 0 at a point): the step then stays as ves_step_set made it.
 * VES_ERR_ARG for a ratio outside (0, 2.4]. */
ves_status ves_step_set_history(ves_step *s, const double *yprev, double w);
/* 1 when the set step is a BDF2 step (ves_step_set_history). */
int ves_step_is_bdf2(const ves_step *s);
/* The same step with another dt in the objective f = (1/2) d^T K d + dt E:
 * y^n, K(y^n), the drift damping and the constraint targets are kept, the
 * cached evaluation is dropped. For a continuation in dt inside a backend
 * (nlopt's large steps), which must set the step's own dt back before it
 * returns. VES_ERR_ARG before ves_step_set or for dt not > 0 and finite. */
ves_status ves_step_set_dt(ves_step *s, double dt);

int ves_step_nvar(const ves_step *s); /* free dofs */
int ves_step_ncon(const ves_step *s); /* 0, 1 or 2: area first, then volume */

/* x0 = the free dofs of y^n. */
void ves_step_x0(const ves_step *s, double *x);
/* y (2n) from free dofs x, fixed dofs from y^n. */
void ves_step_expand(const ves_step *s, const double *x, double *y);

/* Evaluations at x (nvar). VES_ERR_DOMAIN when y leaves the admissible set
 * (det F <= 0 or r <= 0 at a point): backends must treat it as "cut the step". */
ves_status ves_step_eval_f(ves_step *s, const double *x, double *f);
ves_status ves_step_eval_grad(ves_step *s, const double *x, double *g); /* g[nvar] */
ves_status ves_step_eval_c(ves_step *s, const double *x, double *c);    /* c[ncon] */
ves_status ves_step_eval_jac(ves_step *s, const double *x, double *J); /* J[ncon*nvar], row-major */
/* f at the step's start x0 (y^n): dt E(y^n) for a backward Euler step; a
 * BDF2 step's f there also holds the dissipation from its anchor. */
ves_status ves_step_eval_f_start(ves_step *s, double *f);

/* E, A and V of the model at x (nvar), as ves_model_eval gives them (the same
 * sums, bit for bit): from the cache when the last evaluation was at x and
 * covered all three (both constraints held), else by a values-only model
 * pass. For the integrator at a converged step: the backend's last point is
 * nearly always its answer. */
ves_status ves_step_values(ves_step *s, const double *x, double *E, double *A, double *V);

/* 1: every evaluation of values at a new x computes the gradients in the same
 * model pass (about 3x a values-only pass, against 4x for a values pass and
 * a gradient pass at the same point); for a solver that asks for gradients
 * at almost every point whose value it asks for (newton: accepted full steps).
 * 0 (default): values alone. */
void ves_step_eager_gradients(ves_step *s, int on);

/* Hessian of the Lagrangian sigma_f (K + dt Hess E) + sum_i lambda_i Hess c_i
 * in a fixed sparsity: hess_nnz entries, lower triangle (row >= col), structure
 * from ves_step_hess_structure (0-based) and values from ves_step_eval_hess in
 * the same order. lambda may be NULL when ncon = 0. */
int ves_step_hess_nnz(const ves_step *s);
void ves_step_hess_structure(const ves_step *s, int *irow, int *jcol);
ves_status ves_step_eval_hess(ves_step *s, const double *x, double sigma_f, const double *lambda,
                              double *val);
/* As ves_step_eval_hess, each triangle's block matrix formed in single
 * precision (ves_model_hessian_step's single): for a matrix factored in
 * single precision, whose solves are refined against these values (the
 * newton backend's chord matrix; ~1e-6 of the terms' size, where the float
 * factorization itself perturbs by ~1e-7-1e-5). */
ves_status ves_step_eval_hess_single(ves_step *s, const double *x, double sigma_f,
                                     const double *lambda, double *val);
/* The rounding floor of a first-order residual with Hessian values val
 * (hess_nnz, the structure above, the lower triangle standing for both) at
 * x: eps_mach max_i sum_j |H_ij x_j|. x holds absolute positions to
 * eps_mach, and H magnifies that to this bound, below which no iteration
 * resolves the residual (backend_newton.c, backend_ipopt.c). acc: nvar
 * scratch. */
double ves_step_hess_floor(const ves_step *s, const double *x, const double *val, double *acc);

/* The dissipation matrix K(y^n) (+ the drift damping S) over the free dofs,
 * in the same structure (for the explicit Euler backend, inertia corrections
 * and preconditioning). Assembled at the first call after ves_step_set (the
 * objective and the Hessian use K(y^n) without it, point by point); NULL if
 * the step is not set or the assembly failed. */
const double *ves_step_K(ves_step *s);
/* dt E(y) alone and its gradient (the Euler backend's force). */
ves_status ves_step_eval_energy_grad(ves_step *s, const double *x, double *E, double *gE);

/* The parameters of the current step (NULL before ves_step_set). */
const ves_step_params *ves_step_get_params(const ves_step *s);

/* The model the step problem is built on (borrowed: the one given to
 * ves_step_create; NULL for a NULL s), for the analysis of the linearized
 * flow (spectrum.h), which needs its Hessian and pattern. The backends use
 * the step problem only. */
ves_model *ves_step_model(ves_step *s);

/* The targets of the held constraints, area first: tgt[k] = A0, then
 * V_target (both > 0: ves_step_set checks), the scale of the relative
 * violation |c_k| / tgt[k] every backend reports; tgt[k] = 1 past the held
 * ones. Returns their count (ves_step_ncon; 0 before ves_step_set). */
int ves_step_get_targets(const ves_step *s, double tgt[2]);

#endif
