/* vesica — private: the local densities of the model at one quadrature point
 * (energy, area, volume, dissipation) as functions of the 11 local kinematic
 * variables q, with their analytic gradients and Hessians (docs/design.md,
 * "Discretization"; derivation in solver/model/model_local.c). */
#ifndef VES_MODEL_IMPL_H
#define VES_MODEL_IMPL_H

#include "ves/status.h"

/* Position of each local kinematic variable in q[VES_NQ]. All are linear in
 * the nodal positions: q = B_alpha y. F is F-tilde, F_iI = d y_i / d X_I
 * (i in {r, z} spatial, I in {R, Z} material); G_iJK = d2 y_i / dX_J dX_K. */
enum {
  VES_Q_R = 0,     /* r, current radius of the point (units R0, > 0) */
  VES_Q_FRR = 1,   /* F_rR = dr/dR */
  VES_Q_FRZ = 2,   /* F_rZ = dr/dZ */
  VES_Q_FZR = 3,   /* F_zR = dz/dR */
  VES_Q_FZZ = 4,   /* F_zZ = dz/dZ */
  VES_Q_GRRR = 5,  /* G_rRR = d2r/dR2   (units 1/R0) */
  VES_Q_GRRZ = 6,  /* G_rRZ = d2r/dRdZ */
  VES_Q_GRZZ = 7,  /* G_rZZ = d2r/dZ2 */
  VES_Q_GZRR = 8,  /* G_zRR = d2z/dR2 */
  VES_Q_GZRZ = 9,  /* G_zRZ = d2z/dRdZ */
  VES_Q_GZZZ = 10, /* G_zZZ = d2z/dZ2 */
  VES_NQ = 11      /* number of local kinematic variables */
};

/* Position of each velocity variable in qdot[VES_NQD] (the time derivatives
 * of the first five entries of q). */
enum {
  VES_QD_R = 0,   /* rdot (units R0 / time) */
  VES_QD_FRR = 1, /* Fdot_rR (units 1 / time) */
  VES_QD_FRZ = 2, /* Fdot_rZ */
  VES_QD_FZR = 3, /* Fdot_zR */
  VES_QD_FZZ = 4, /* Fdot_zZ */
  VES_NQD = 5     /* number of velocity variables */
};

/* Fixed data of one quadrature point (set per reference configuration). */
typedef struct {
  double phi0;      /* reference phase field phi0 (dimensionless, ~ +1 inside,
                       -1 outside) */
  double dphi0[2];  /* reference gradient (phi0_R, phi0_Z), units 1/R0 */
  double ddphi0[3]; /* reference Hessian (phi0_RR, phi0_RZ, phi0_ZZ),
                       units 1/R0^2 */
} ves_model_point;

/* Physical parameters the local densities need (dimensionless units of
 * docs/design.md, "The model": lengths in R0, time in mu R0^3 / k). */
typedef struct {
  double eps;    /* interface width eps, units R0 (> 0; paper: 0.01) */
  double C0;     /* spontaneous curvature C0, units 1/R0 */
  double mu;     /* shear viscosity mu (1 in the units above; >= 0) */
  double lambda; /* bulk (penalty) viscosity lambda, same units as mu
                    (lambda / mu >= 10 in use; >= -2 mu / 3 for D >= 0) */
} ves_model_local_par;

/* Common signature of the three densities e(q) below, each per unit
 * reference area dR dZ and without the prefactors (f_E, f_A, 2 pi) and the
 * quadrature weight:
 *   par   parameters                                              borrowed
 *   pt    point data                                              borrowed
 *   q     the VES_NQ local kinematic variables                    borrowed
 *   e     out: the density value (never NULL)
 *   grad  out: de/dq, VES_NQ entries; NULL when not needed
 *   hess  out: d2e/dq2, VES_NQ x VES_NQ row-major, exactly symmetric;
 *         NULL when not needed
 * Returns VES_OK, or VES_ERR_DOMAIN when det F <= 0 or r <= 0 (or either is
 * NaN); then no output is written. No allocation, no side effects. */
typedef ves_status ves_model_local_fn(const ves_model_local_par *par, const ves_model_point *pt,
                                      const double q[VES_NQ], double *e, double *grad,
                                      double *hess);

/* Energy density e_E = W^2 det F r (paper Eq. 5, Appendix B.4), with
 * W = eps Lap + (phi0/eps + sqrt(2) C0)(1 - phi0^2) and Lap the pushed-
 * forward axisymmetric Laplacian of phi (Eq. 4 and Appendix A). */
ves_status ves_model_local_energy(const ves_model_local_par *par, const ves_model_point *pt,
                                  const double q[VES_NQ], double *e, double *grad, double *hess);

/* As ves_model_local_energy, also returning W (units 1/R0) and
 * Lap = Delta phi (units 1/R0^2) for diagnostics; W and lap may each be
 * NULL. */
ves_status ves_model_local_energy_ex(const ves_model_local_par *par, const ves_model_point *pt,
                                     const double q[VES_NQ], double *e, double *grad, double *hess,
                                     double *W, double *lap);

/* Area density e_A = [(eps/2)|grad phi|^2 + (phi0^2 - 1)^2 / (4 eps)] det F r
 * (paper Eq. 7), grad phi = grad phi0 F^-1. Independent of G. */
ves_status ves_model_local_area(const ves_model_local_par *par, const ves_model_point *pt,
                                const double q[VES_NQ], double *e, double *grad, double *hess);

/* Volume density e_V = (1/2)(1 + phi0) det F r (paper Eq. 6: V = int e_V
 * including the Vol(Omega) term). par is unused and may be NULL. */
ves_status ves_model_local_volume(const ves_model_local_par *par, const ves_model_point *pt,
                                  const double q[VES_NQ], double *e, double *grad, double *hess);

/* Dissipation matrix: the symmetric VES_NQD x VES_NQD matrix D(q), row-major,
 * with (1/2) qdot^T D qdot = [mu |d|^2 + (lambda/2)(div v)^2] r det F
 * (paper Eq. 8 and Appendix A): |d|^2 = |sym(Fdot F^-1)|^2 + (rdot/r)^2,
 * div v = tr(Fdot F^-1) + rdot/r. Only q[0..4] are read. D is positive
 * semidefinite for mu > 0, lambda > -2mu/3, with exactly one null direction:
 * the local spin Fdot = Omega F (Omega antisymmetric), rdot = 0.
 * Returns VES_OK or VES_ERR_DOMAIN (D not written). */
ves_status ves_model_local_dissip(const ves_model_local_par *par, const double q[VES_NQ],
                                  double D[VES_NQD * VES_NQD]);

#endif
