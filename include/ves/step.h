/* vesica — one time step as a generic constrained nonlinear program
 * (DESIGN.md §3, paper Eq. 11): given y^n and dt,
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

/* The dissipation matrix K(y^n) over the free dofs, in the same structure
 * (for the explicit Euler backend and preconditioning). */
const double *ves_step_K(const ves_step *s);
/* dt E(y) alone and its gradient (the Euler backend's force). */
ves_status ves_step_eval_energy_grad(ves_step *s, const double *x, double *E, double *gE);

/* The gradient flow at y^n: K ydot = -grad E - sum_i sigma_i grad c_i with
 * J ydot = 0 (forward Euler's velocity, the dt -> 0 limit of the step).
 * ydot[nvar] (may be NULL) the velocity of the free dofs (R0 per t*),
 * sigma[ncon] the constraint forces (tension, pressure) per unit time that
 * the spectra below take. Requires ves_step_set (dt only scales the
 * evaluation). Allocates and factorizes [K J^T; J 0]. Returns VES_OK,
 * VES_ERR_ARG, errors of the evaluation or the factorization, VES_ERR_ALLOC. */
ves_status ves_step_flow(ves_step *s, double *ydot, double *sigma);

/* The stiffness of the explicit step at y^n: the largest eigenvalue mu_max
 * (units 1/t*) of K^-1 (Hess E + sum_i sigma_i Hess c_i) on the tangent space
 * {v : J v = 0} of the held constraints, sigma[ncon] the constraint forces
 * per unit time (a step's multipliers divided by its dt; NULL when ncon = 0).
 * Forward Euler on K ydot = -grad E - sum sigma_i grad c_i, J ydot = 0 is
 * linearly stable near y^n for dt <= 2 / mu_max (the iteration matrix is I -
 * dt K^-1 A on that space; at a state out of equilibrium this is its frozen
 * linearization). Lanczos in the K inner product from a fixed start, at most
 * `iters` (>= 2) steps with full reorthogonalization: mu_max from below;
 * *resid (may be NULL) is its Ritz residual relative to mu_max, a bound on
 * the error when the top eigenvalue is separated. Requires ves_step_set (its
 * dt and targets only select the held constraints); allocates and factorizes
 * [K J^T; J 0] (an analysis, not part of a step). Returns VES_OK,
 * VES_ERR_ARG, errors of the Hessian assembly or the factorization,
 * VES_ERR_NOCONV (a zero start vector or LAPACK's dstev failed), VES_ERR_ALLOC. */
ves_status ves_step_stiffness(ves_step *s, const double *sigma, int iters, double *mu_max,
                              double *resid);

/* The slow end of the same spectrum: the eigenvalues mu of A v = mu K v on
 * {v : J v = 0} (A = Hess E + sum_i sigma_i Hess c_i at y^n, as above) that
 * lie just above mu_lo. The linearized flow K ydot = -A (y - y*) decays
 * along an eigenvector as exp(-mu t): mu < 0 is an unstable direction (a
 * state near a saddle of E on the constraint set grows away from it at the
 * rate -mu), mu ~ 0 a neutral one (a rigid translation of the vesicle in the
 * box). Shift and invert: Lanczos on P (A - mu_lo K)^-1 K, at most `iters`
 * steps; mu[nwant] (ascending, the nwant lowest found above mu_lo; NAN
 * where fewer were found), err[nwant] (may be NULL) their Ritz error bounds
 * (1/t*, good when the eigenvalue is separated); vec[nwant * nvar] (may be
 * NULL) the Ritz vectors, in the order of mu, K-normalized (v^T K v = 1;
 * NAN where mu is); *nbelow (may be NULL) the
 * exact number of eigenvalues below mu_lo (the inertia of [A - mu_lo K,
 * J^T; J 0] from MUMPS). mu_lo must not be an eigenvalue (a singular
 * factorization: VES_ERR_SINGULAR). Allocates and factorizes (an analysis,
 * not part of a step). Returns VES_OK, VES_ERR_ARG (nwant < 1 or > iters or
 * above the tangent dimension, iters < 2, mu_lo not finite, sigma NULL with
 * constraints), errors of the assembly or the factorization, VES_ERR_NOCONV
 * (dstev failed), VES_ERR_ALLOC. */
ves_status ves_step_modes(ves_step *s, const double *sigma, double mu_lo, int iters, int nwant,
                          double *mu, double *err, double *vec, int *nbelow);

/* The curvatures of the three functionals along a direction v[nvar] (free
 * dofs) at y^n: curv = (v^T Hess E v, v^T Hess A v, v^T Hess V v), units of
 * E, A, V per |v|^2. For a K-normalized mode of ves_step_modes, mu = curv[0]
 * + sigma_A curv[1] + sigma_V curv[2] over the held constraints: which of
 * them makes mu what it is. Allocates (an analysis); VES_ERR_ARG, errors of
 * the assembly, VES_ERR_ALLOC. */
ves_status ves_step_curvatures(ves_step *s, const double *v, double curv[3]);

/* The model, y^n and parameters of the current step. */
ves_model *ves_step_model(ves_step *s);
const ves_step_params *ves_step_get_params(const ves_step *s);

#endif
