/* vesica — the linearized flow at a state (an analysis above the step
 * problem, not part of it; docs/design.md, "Analysis"): the gradient flow K ydot = -grad E -
 * sum_i sigma_i grad c_i on the held constraints' tangent space, the
 * spectrum of its linearization A v = mu K v (A = Hess E + sum_i sigma_i
 * Hess c_i) by Lanczos in the K inner product, the stiffness mu_max of the
 * explicit step, the Ritz vectors and how the functionals share each mu;
 * and, on a simulation's state, the whole analysis `vesica spectrum`
 * prints (dissipation, where each mode lives, its cosine with the drift of
 * the coefficients). Every KKT matrix here is a step problem's (kkt.h). */
#ifndef VES_SPECTRUM_H
#define VES_SPECTRUM_H

#include "ves/integrate.h"
#include "ves/status.h"
#include "ves/step.h"

/* ---- on a step problem set at y^n (ves_step_set) ----------------------- */

/* The gradient flow at y^n: K ydot = -grad E - sum_i sigma_i grad c_i with
 * J ydot = 0 (forward Euler's velocity, the dt -> 0 limit of the step).
 * ydot[nvar] (may be NULL) the velocity of the free dofs (R0 per t*),
 * sigma[ncon] the constraint forces (tension, pressure) per unit time that
 * the spectra below take. Requires ves_step_set (dt only scales the
 * evaluation). Allocates and factorizes [K J^T; J 0]. Returns VES_OK,
 * VES_ERR_ARG, errors of the evaluation or the factorization, VES_ERR_ALLOC. */
ves_status ves_spectrum_flow(ves_step *s, double *ydot, double *sigma);

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
ves_status ves_spectrum_stiffness(ves_step *s, const double *sigma, int iters, double *mu_max,
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
 * NAN where mu is); *nbelow (may be NULL) the exact number of eigenvalues
 * below mu_lo (the inertia of the KKT matrix of A - mu_lo K from MUMPS).
 * mu_lo must not be an eigenvalue (a singular factorization:
 * VES_ERR_SINGULAR). Allocates and factorizes (an analysis, not part of a
 * step). Returns VES_OK, VES_ERR_ARG (nwant < 1 or > iters or above the
 * tangent dimension, iters < 2, mu_lo not finite, sigma NULL with
 * constraints), errors of the assembly or the factorization, VES_ERR_NOCONV
 * (dstev failed), VES_ERR_ALLOC. */
ves_status ves_spectrum_modes(ves_step *s, const double *sigma, double mu_lo, int iters, int nwant,
                              double *mu, double *err, double *vec, int *nbelow);

/* The curvatures of the three functionals along a direction v[nvar] (free
 * dofs) at y^n: curv = (v^T Hess E v, v^T Hess A v, v^T Hess V v), units of
 * E, A, V per |v|^2. For a K-normalized mode of ves_spectrum_modes, mu =
 * curv[0] + sigma_A curv[1] + sigma_V curv[2] over the held constraints:
 * which of them makes mu what it is. Allocates (an analysis); VES_ERR_ARG,
 * errors of the assembly, VES_ERR_ALLOC. */
ves_status ves_spectrum_curvatures(ves_step *s, const double *v, double curv[3]);

/* ---- the analysis of a simulation's state (vesica spectrum) ------------- */

/* What to compute. */
typedef struct {
  int hold_area;   /* 1: the area is a held constraint (as in the run) */
  int hold_volume; /* 1: the volume is */
  double above;    /* the modes are the eigenvalues just above this (1/t*) */
  int modes;       /* how many (>= 1, <= lanczos) */
  int lanczos;     /* Lanczos steps of each spectrum (>= 2) */
} ves_spectrum_params;

/* Where a mode lives and what makes its eigenvalue. */
typedef struct {
  double peak[2];  /* material position of the node with the largest |u_a| (R0) */
  double peak_phi; /* phi there */
  double band;     /* share of sum_a |u_a|^2 on nodes with |phi_a| < 0.9 */
  double axis;     /* share on nodes within 2 h_a of the axis */
  double material; /* |du| / |u| over the nodes (du: the motion u gives at the nodes) */
  double from[3];  /* mu's parts: v^T Hess E v, sigma_A v^T Hess A v, sigma_V v^T Hess V v
                      (model units: 1/t*; 0 for a free constraint, NAN where mu is) */
  double drift;    /* K-cosine with the drift y^a - y(X_a) of the coefficients */
} ves_spectrum_mode;

/* The linearized flow at a state (plain data, model units: energies and
 * the constraint forces scale with k, the program prints them over k). */
typedef struct {
  int n;               /* real nodes */
  int nvar;            /* free dofs */
  int nmodes;          /* modes asked for (params.modes) */
  double sigma[2];     /* constraint forces of the flow: area, volume (0 when not held) */
  double dissipation;  /* -dE/dt of the flow: ydot^T K ydot */
  double ydot_max;     /* largest nodal speed |ydot_a| over the free components (R0/t*) */
  double mu_max;       /* stiffness (ves_spectrum_stiffness, 1/t*) */
  double mu_max_resid; /* its Ritz residual relative to mu_max */
  int below;           /* eigenvalues below params.above (exact: the inertia) */
  double *mu;          /* nmodes eigenvalues just above params.above, ascending (NAN: not found) */
  double *mu_err;      /* nmodes their Ritz error bounds */
  ves_spectrum_mode *mode; /* nmodes where each lives */
  double drift_K_norm;     /* sqrt(d^T K d), d = y^a - y(X_a) over the free dofs */
  double drift_in_modes;   /* sum of the squared drift cosines: the share of d in the modes */
  double *vec;             /* nmodes * nvar the K-normalized modes over the free dofs */
  double *x;               /* 2n material positions y(X_a) at the nodes (R0) */
  double *phi;             /* n phi at the nodes */
  double *u;               /* nmodes * 2n each mode's coefficients per node (r, z; fixed ones 0) */
  double *du;              /* nmodes * 2n the motion each gives at the nodes */
} ves_spectrum;

/* The analysis at the simulation's current state (ves_sim_y, with dt, A0
 * and V of ves_sim_get_state as the step's): the flow, its stiffness, the
 * modes above p->above and where they live. sim is borrowed (its point set
 * at the nodes is built on first use, as by ves_sim_node_material); *out is
 * the caller's, freed with ves_spectrum_destroy. VES_ERR_ARG (modes < 1 or
 * more than lanczos, lanczos < 2, above not finite), the errors of the
 * functions above and of the node evaluations, VES_ERR_ALLOC. */
ves_status ves_spectrum_create(ves_sim *sim, const ves_spectrum_params *p, ves_spectrum **out);
void ves_spectrum_destroy(ves_spectrum **s);

#endif
