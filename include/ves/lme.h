/* vesica — local maximum-entropy (LME) approximants in 2D (the meridian plane).
 *
 * p_a(X) = exp(-beta_a |X - X_a|^2 + lambda . (X - X_a)) / Z(X, lambda),
 * with lambda(X) the minimizer of log Z (so that sum_a p_a (X - X_a) = 0:
 * exact reproduction of affine functions). beta_a = gamma / h_a^2 is node-wise.
 * See solver/discret/lme.c for the derivative formulas in use and the Newton safeguard
 * (docs/design.md, "Discretization"). */
#ifndef VES_LME_H
#define VES_LME_H

#include "ves/status.h"

/* Parameters of the approximants. */
typedef struct {
  double gamma;      /* aspect ratio gamma, beta_a = gamma / h_a^2 (default 0.6, the
                        problem file's; paper: 0.8) */
  double tol0;       /* support truncation: node a is a neighbour of X when
                        beta_a |X - X_a|^2 <= -ln(tol0) (default 1e-6) */
  double newton_tol; /* convergence: |sum_a p_a (X - X_a)| <= newton_tol * h_loc,
                        h_loc = min_a 1/sqrt(beta_a/gamma) (default 1e-14) */
  int max_iter;      /* Newton iteration limit (default 100) */
} ves_lme_params;

/* Per-call diagnostics. */
typedef struct {
  int iterations;  /* Newton iterations taken */
  double residual; /* final |sum_a p_a (X - X_a)| */
} ves_lme_info;

/* Fill *par with the defaults above. */
void ves_lme_params_default(ves_lme_params *par);

/* Support radius of a node of spacing h: h sqrt(-ln(tol0) / gamma). */
double ves_lme_radius(const ves_lme_params *par, double h);

/* Number of doubles of scratch space ves_lme_eval needs for m neighbours. */
int ves_lme_work_size(int m);

/* Evaluate the m basis functions that are non-zero at X and their derivatives.
 *   X[2]      evaluation point (R, Z)                                  borrowed
 *   m         number of neighbours (>= 3, not all collinear with X)
 *   xa[2m]    neighbour coordinates, interleaved (R_a, Z_a)            borrowed
 *   beta[m]   beta_a = gamma / h_a^2                                   borrowed
 *   lambda[2] in: initial guess (0,0 if none; non-finite -> 0; a guess from
 *             which Newton fails is dropped for 0, once); out: the
 *             converged lambda(X) (the last iterate if Newton failed)
 *   nder      0: values; 1: + gradients; 2: + Hessians
 *   tab       output, row-major 6 x m (only the first 1, 3 or 6 rows are
 *             written for nder = 0, 1, 2):
 *             tab[0m+a] = p_a, tab[1m+a] = dp_a/dR, tab[2m+a] = dp_a/dZ,
 *             tab[3m+a] = d2p_a/dR2, tab[4m+a] = d2p_a/dRdZ, tab[5m+a] = d2p_a/dZ2
 *   work      scratch of ves_lme_work_size(m) doubles                  borrowed
 *   info      diagnostics, may be NULL
 * No allocation; thread-safe for distinct work arrays.
 * Returns VES_OK;
 *   VES_ERR_ARG     NULL pointer, m < 3, nder not in {0,1,2}, beta_a <= 0,
 *                   invalid par, collinear neighbours, or X on the hull of
 *                   the neighbours (J singular after convergence: within
 *                   ~1e-10 h of it);
 *   VES_ERR_NOCONV  X outside the hull (lambda diverges), or newton_tol not
 *                   reached in max_iter iterations.
 * X must lie strictly inside the convex hull of the neighbours. */
ves_status ves_lme_eval(const ves_lme_params *par, const double X[2], int m, const double *xa,
                        const double *beta, double lambda[2], int nder, double *tab, double *work,
                        ves_lme_info *info);

#endif
