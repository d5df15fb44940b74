/* vesica — local densities of energy, area, volume and dissipation at one
 * quadrature point, with analytic gradients and Hessians in the 11 local
 * kinematic variables q = (r, F, G) (docs/design.md, "Discretization").
 *
 * Notation. F = F-tilde, F_iI = dy_i/dX_I (spatial i in {r,z}, material I in
 * {R,Z}); H = F^-1 indexed H_Ii (material, spatial); J = det F; G_nJK =
 * d2 y_n / dX_J dX_K; p_I = d_I phi0, S_IJ = d_IJ phi0 (point data). Repeated
 * indices are summed. Derivatives "d/dF_kK" are written for an index pair
 * alpha = (k, K) stored at q[1 + 2k + K].
 *
 * Formulas (paper Sec. 2.1, Eqs. 2-7; Appendix A; Appendix B.3-B.4):
 *   g_i   = p_I H_Ii                          (grad phi, Eq. 2)
 *   M_JK  = H_Ji H_Ki                         (M = H H^T, material, symmetric)
 *   c_I   = d_i H_Ii = -H_In G_nJK H_Ji H_Ki  (Eq. 4 with Sec. 2.1's d_j F^-1)
 *   Lap   = S_IJ M_IJ + p_I c_I + g_r / r     (Eq. 4 + hoop term, App. A)
 *         = S:M - g_n m_n + g_r / r,   m_n = G_n : M
 *   W     = eps Lap + C1,  C1 = (phi0/eps + sqrt2 C0)(1 - phi0^2)
 *   e_E   = W^2 J r                           (Eq. 5, App. B.4)
 *   e_A   = [(eps/2) g.g + C2] J r,  C2 = (phi0^2 - 1)^2 / (4 eps)   (Eq. 7)
 *   e_V   = (1/2)(1 + phi0) J r               (Eq. 6)
 *   (1/2) qdot^T D qdot = [mu |sym L|^2 + mu (rdot/r)^2
 *                          + (lambda/2)(tr L + rdot/r)^2] r J,  L = Fdot H
 *                                             (Eq. 8, App. A)
 *
 * Derivation route (instead of the nodal chain rules of App. B; exact to
 * rounding, checked against finite differences in tests/test_model_local.c).
 * Everything follows from dH_Ii/dF_kK = -H_Ik H_Ki (App. B.2):
 *   dg_i/dF_kK       = -g_k H_Ki
 *   d2g_i/dF_kK dF_lL = g_k H_Kl H_Li + g_l H_Lk H_Ki
 *   dM_JK/dF_kL      = -(H_Jk M_LK + H_Kk M_JL)
 *   for a fixed symmetric T and phi_T = T:M, with Q = H^T T H (spatial):
 *   dphi_T/dF_kK     = -2 Q_ki H_Ki
 *   d2phi_T/dF_kK dF_lL = 2 [Q_kl M_KL + (HQ)_Kl H_Lk + (HQ)_Lk H_Kl]
 * Lap is linear in G and in 1/r, so with T = S - g_n G_n (frozen) and
 * w = (1/r - m_r, -m_z):
 *   dLap/dF   = dphi_T/dF + w_i dg_i/dF
 *   d2Lap/dF2 = d2phi_T/dF2 + w_i d2g_i/dF2 - sum_n (dg_n (x) dm_n + dm_n (x) dg_n)
 *   dLap/dr = -g_r/r^2,  d2Lap/dr2 = 2 g_r/r^3,  d2Lap/dr dF = -(dg_r/dF)/r^2
 *   dLap/dG_nJK = -mult_JK g_n M_JK   (mult = 1 for RR, ZZ; 2 for RZ)
 *   d2Lap/dG_nJK dF = -mult_JK (dg_n/dF M_JK + g_n dM_JK/dF),  d2Lap/dG2 = 0.
 * Every density is f(q) * P with P = J r, dJ/dF = cofactor(F) and
 * d2J/dF_rR dF_zZ = 1, d2J/dF_rZ dF_zR = -1, so one product rule
 *   d(fP) = P df + f dP,  d2(fP) = P d2f + f d2P + df (x) dP + dP (x) df
 * finishes all three, with f = W^2 (df = 2W eps dLap, d2f = 2 eps^2 dLap (x)
 * dLap + 2 W eps d2Lap), f = (eps/2) g.g + C2, f = (1 + phi0)/2.
 * D = r J B^T K B with B the 5 x 5 map qdot -> (L_rr, L_rz, L_zr, L_zz,
 * rdot/r), written as five rank-one terms.
 * Cost (hand count, gcc -O2, one core): e_E with its full Hessian ~1,500 flops,
 * ~0.24 us a call (4e6 calls/s); value and gradient ~0.05 us; D ~0.05 us. */
#include "model/model_impl.h"

#include <string.h>

#define SQRT2 1.41421356237309504880168872420969808

/* Kinematics shared by all densities. */
typedef struct {
  double r;       /* current radius (> 0) */
  double J;       /* det F (> 0) */
  double F[2][2]; /* F[i][I] */
  double H[2][2]; /* F^-1 as H[I][i] */
} kin;

/* J = det F, H = F^-1 = adj(F)/J; VES_ERR_DOMAIN unless J > 0 and r > 0. */
static ves_status kin_eval(const double *q, kin *k) {
  const double a = q[VES_Q_FRR], b = q[VES_Q_FRZ], c = q[VES_Q_FZR], d = q[VES_Q_FZZ];
  const double J = a * d - b * c;
  if (!(J > 0.0) || !(q[VES_Q_R] > 0.0)) return VES_ERR_DOMAIN;
  const double iJ = 1.0 / J;
  k->r = q[VES_Q_R];
  k->J = J;
  k->F[0][0] = a;
  k->F[0][1] = b;
  k->F[1][0] = c;
  k->F[1][1] = d;
  k->H[0][0] = d * iJ;  /* H_Rr */
  k->H[0][1] = -b * iJ; /* H_Rz */
  k->H[1][0] = -c * iJ; /* H_Zr */
  k->H[1][1] = a * iJ;  /* H_Zz */
  return VES_OK;
}

/* Q = H^T T H (Q_ij = H_Ii T_IJ H_Jj), T symmetric 2 x 2. */
static void congruence(const double H[2][2], const double T[2][2], double Q[2][2]) {
  double TH[2][2]; /* TH_Ij = T_IJ H_Jj */
  for (int I = 0; I < 2; I++)
    for (int j = 0; j < 2; j++) TH[I][j] = T[I][0] * H[0][j] + T[I][1] * H[1][j];
  Q[0][0] = H[0][0] * TH[0][0] + H[1][0] * TH[1][0];
  Q[0][1] = H[0][0] * TH[0][1] + H[1][0] * TH[1][1];
  Q[1][1] = H[0][1] * TH[0][1] + H[1][1] * TH[1][1];
  Q[1][0] = Q[0][1];
}

/* dphi_T/dF_kK = -2 Q_ki H_Ki for phi_T = T:M, Q = H^T T H (4 entries). */
static void dphi(const double H[2][2], const double Q[2][2], double out[4]) {
  for (int k = 0; k < 2; k++)
    for (int K = 0; K < 2; K++) out[2 * k + K] = -2.0 * (Q[k][0] * H[K][0] + Q[k][1] * H[K][1]);
}

/* Lap = S:M - g_n m_n + g_r / r (Eq. 4 + App. A); when dl != NULL its
 * gradient dl[VES_NQ]; when d2l != NULL (requires dl) the upper triangle of
 * its Hessian d2l[VES_NQ^2] (lower triangle set to zero). G = q + 5. */
static double lap_eval(const ves_model_point *pt, const kin *k, const double *G, double *dl,
                       double *d2l) {
  const double(*H)[2] = k->H;
  const double S[2][2] = {{pt->ddphi0[0], pt->ddphi0[1]}, {pt->ddphi0[1], pt->ddphi0[2]}};
  const double Gm[2][2][2] = {{{G[0], G[1]}, {G[1], G[2]}}, {{G[3], G[4]}, {G[4], G[5]}}};
  const double pR = pt->dphi0[0], pZ = pt->dphi0[1];
  const double g[2] = {pR * H[0][0] + pZ * H[1][0], /* g_i = p_I H_Ii */
                       pR * H[0][1] + pZ * H[1][1]};
  double M[2][2]; /* M_JK = H_Ji H_Ki */
  M[0][0] = H[0][0] * H[0][0] + H[0][1] * H[0][1];
  M[0][1] = H[0][0] * H[1][0] + H[0][1] * H[1][1];
  M[1][1] = H[1][0] * H[1][0] + H[1][1] * H[1][1];
  M[1][0] = M[0][1];
  double m[2]; /* m_n = G_n : M */
  for (int n = 0; n < 2; n++)
    m[n] = Gm[n][0][0] * M[0][0] + 2.0 * Gm[n][0][1] * M[0][1] + Gm[n][1][1] * M[1][1];
  const double ir = 1.0 / k->r;
  const double lap = S[0][0] * M[0][0] + 2.0 * S[0][1] * M[0][1] + S[1][1] * M[1][1] - g[0] * m[0] -
                     g[1] * m[1] + g[0] * ir;
  if (!dl) return lap;

  /* First derivatives. */
  double T[2][2]; /* T = S - g_n G_n (g frozen) */
  for (int I = 0; I < 2; I++)
    for (int J = 0; J < 2; J++) T[I][J] = S[I][J] - g[0] * Gm[0][I][J] - g[1] * Gm[1][I][J];
  double QT[2][2], Qn[2][2][2];
  congruence(H, T, QT);
  congruence(H, Gm[0], Qn[0]);
  congruence(H, Gm[1], Qn[1]);
  double dphiT[4], Dm[2][4], Dg[2][4];
  dphi(H, QT, dphiT);
  dphi(H, Qn[0], Dm[0]);
  dphi(H, Qn[1], Dm[1]);
  const double w[2] = {ir - m[0], -m[1]};
  const double Hw[2] = {H[0][0] * w[0] + H[0][1] * w[1], H[1][0] * w[0] + H[1][1] * w[1]};
  for (int a = 0; a < 4; a++) {
    const int kk = a >> 1, K = a & 1;
    Dg[0][a] = -g[kk] * H[K][0]; /* dg_i/dF_kK = -g_k H_Ki */
    Dg[1][a] = -g[kk] * H[K][1];
    dl[1 + a] = dphiT[a] - g[kk] * Hw[K];
  }
  dl[VES_Q_R] = -g[0] * ir * ir;
  static const int cJ[3] = {0, 0, 1}, cK[3] = {0, 1, 1};
  static const double mult[3] = {1.0, 2.0, 1.0};
  for (int n = 0; n < 2; n++)
    for (int c = 0; c < 3; c++) dl[5 + 3 * n + c] = -mult[c] * g[n] * M[cJ[c]][cK[c]];
  if (!d2l) return lap;

  /* Second derivatives (upper triangle). */
  memset(d2l, 0, sizeof(double) * VES_NQ * VES_NQ);
  d2l[0] = 2.0 * g[0] * ir * ir * ir;
  for (int a = 0; a < 4; a++) d2l[1 + a] = -Dg[0][a] * ir * ir;
  double HQ[2][2]; /* (H Q_T)_Kl */
  for (int K = 0; K < 2; K++)
    for (int l = 0; l < 2; l++) HQ[K][l] = H[K][0] * QT[0][l] + H[K][1] * QT[1][l];
  for (int a = 0; a < 4; a++) {
    const int kk = a >> 1, K = a & 1;
    for (int b = a; b < 4; b++) {
      const int l = b >> 1, L = b & 1;
      double v =
          2.0 * (QT[kk][l] * M[K][L] + HQ[K][l] * H[L][kk] + HQ[L][kk] * H[K][l]); /* d2phi_T */
      v += g[kk] * H[K][l] * Hw[L] + g[l] * H[L][kk] * Hw[K];                      /* w.d2g */
      v -= Dg[0][a] * Dm[0][b] + Dm[0][a] * Dg[0][b] + Dg[1][a] * Dm[1][b] + Dm[1][a] * Dg[1][b];
      d2l[(1 + a) * VES_NQ + 1 + b] = v;
    }
  }
  double DM[3][4]; /* dM_JK/dF_kL = -(H_Jk M_LK + H_Kk M_JL) */
  for (int c = 0; c < 3; c++)
    for (int a = 0; a < 4; a++) {
      const int kk = a >> 1, L = a & 1, J = cJ[c], K = cK[c];
      DM[c][a] = -(H[J][kk] * M[L][K] + H[K][kk] * M[J][L]);
    }
  for (int a = 0; a < 4; a++)
    for (int n = 0; n < 2; n++)
      for (int c = 0; c < 3; c++)
        d2l[(1 + a) * VES_NQ + 5 + 3 * n + c] =
            -mult[c] * (Dg[n][a] * M[cJ[c]][cK[c]] + g[n] * DM[c][a]);
  return lap;
}

/* e = f P with P = J r: value, gradient and (full, exactly symmetric) Hessian
 * by the product rule. df == NULL means f constant; d2f holds an upper
 * triangle (may be NULL when f is constant or hess is NULL). */
static void times_jr(const kin *k, double f, const double *df, const double *d2f, double *e,
                     double *grad, double *hess) {
  const double r = k->r, J = k->J;
  const double a = k->F[0][0], b = k->F[0][1], c = k->F[1][0], d = k->F[1][1];
  const double cof[4] = {d, -c, -b, a}; /* dJ/dF = cofactor of F */
  /* dP/dq: dP/dr = J, dP/dF = r cof(F) (nonzero for q[0..4] only). */
  const double dP[5] = {J, r * cof[0], r * cof[1], r * cof[2], r * cof[3]};
  const double P = J * r;
  *e = f * P;
  if (grad) {
    for (int i = 0; i < VES_NQ; i++) grad[i] = df ? P * df[i] : 0.0;
    for (int i = 0; i < 5; i++) grad[i] += f * dP[i];
  }
  if (!hess) return;
  for (int i = 0; i < VES_NQ; i++)
    for (int j = i; j < VES_NQ; j++) {
      double v = 0.0;
      if (df) {
        v = P * d2f[i * VES_NQ + j];
        if (i < 5) v += dP[i] * df[j];
        if (j < 5) v += df[i] * dP[j];
      }
      hess[i * VES_NQ + j] = v;
    }
  /* f d2P: d2P/dr dF = cof(F), d2P/dF_rR dF_zZ = r, d2P/dF_rZ dF_zR = -r */
  for (int j = 1; j < 5; j++) hess[j] += f * cof[j - 1];
  hess[VES_Q_FRR * VES_NQ + VES_Q_FZZ] += f * r;
  hess[VES_Q_FRZ * VES_NQ + VES_Q_FZR] -= f * r;
  for (int i = 0; i < VES_NQ; i++)
    for (int j = i + 1; j < VES_NQ; j++) hess[j * VES_NQ + i] = hess[i * VES_NQ + j];
}

ves_status ves_model_local_energy_ex(const ves_model_local_par *par, const ves_model_point *pt,
                                     const double q[VES_NQ], double *e, double *grad, double *hess,
                                     double *W, double *lap) {
  kin k;
  VES_CALL(kin_eval(q, &k));
  const double eps = par->eps, phi0 = pt->phi0;
  const double C1 = (phi0 / eps + SQRT2 * par->C0) * (1.0 - phi0 * phi0);
  double dl[VES_NQ], d2l[VES_NQ * VES_NQ];
  const int need1 = grad || hess;
  const double L = lap_eval(pt, &k, q + 5, need1 ? dl : NULL, hess ? d2l : NULL);
  const double w = eps * L + C1; /* W */
  if (W) *W = w;
  if (lap) *lap = L;
  if (!need1) {
    times_jr(&k, w * w, NULL, NULL, e, NULL, NULL);
    return VES_OK;
  }
  double df[VES_NQ]; /* d(W^2) = 2 W eps dLap */
  const double s = 2.0 * w * eps;
  for (int i = 0; i < VES_NQ; i++) df[i] = s * dl[i];
  if (hess) { /* d2(W^2) = 2 eps^2 dLap (x) dLap + 2 W eps d2Lap (upper) */
    const double s2 = 2.0 * eps * eps;
    for (int i = 0; i < VES_NQ; i++)
      for (int j = i; j < VES_NQ; j++)
        d2l[i * VES_NQ + j] = s2 * dl[i] * dl[j] + s * d2l[i * VES_NQ + j];
  }
  times_jr(&k, w * w, df, hess ? d2l : NULL, e, grad, hess);
  return VES_OK;
}

ves_status ves_model_local_energy(const ves_model_local_par *par, const ves_model_point *pt,
                                  const double q[VES_NQ], double *e, double *grad, double *hess) {
  return ves_model_local_energy_ex(par, pt, q, e, grad, hess, NULL, NULL);
}

ves_status ves_model_local_area(const ves_model_local_par *par, const ves_model_point *pt,
                                const double q[VES_NQ], double *e, double *grad, double *hess) {
  kin k;
  VES_CALL(kin_eval(q, &k));
  const double(*H)[2] = k.H;
  const double eps = par->eps, phi0 = pt->phi0;
  const double pR = pt->dphi0[0], pZ = pt->dphi0[1];
  const double g[2] = {pR * H[0][0] + pZ * H[1][0], pR * H[0][1] + pZ * H[1][1]};
  const double C2 = 0.25 / eps * (phi0 * phi0 - 1.0) * (phi0 * phi0 - 1.0);
  const double f = 0.5 * eps * (g[0] * g[0] + g[1] * g[1]) + C2;
  if (!grad && !hess) {
    times_jr(&k, f, NULL, NULL, e, NULL, NULL);
    return VES_OK;
  }
  /* d|g|^2/dF_kK = -2 g_k (Hg)_K;
   * d2|g|^2/dF_kK dF_lL = 2 g_k g_l M_KL + 2 [g_k H_Kl (Hg)_L + g_l H_Lk (Hg)_K] */
  const double Hg[2] = {H[0][0] * g[0] + H[0][1] * g[1], H[1][0] * g[0] + H[1][1] * g[1]};
  double df[VES_NQ] = {0.0}, d2f[VES_NQ * VES_NQ];
  for (int a = 0; a < 4; a++) df[1 + a] = -eps * g[a >> 1] * Hg[a & 1];
  if (hess) {
    double M[2][2];
    M[0][0] = H[0][0] * H[0][0] + H[0][1] * H[0][1];
    M[0][1] = H[0][0] * H[1][0] + H[0][1] * H[1][1];
    M[1][1] = H[1][0] * H[1][0] + H[1][1] * H[1][1];
    M[1][0] = M[0][1];
    memset(d2f, 0, sizeof d2f);
    for (int a = 0; a < 4; a++) {
      const int kk = a >> 1, K = a & 1;
      for (int b = a; b < 4; b++) {
        const int l = b >> 1, L = b & 1;
        d2f[(1 + a) * VES_NQ + 1 + b] =
            eps * (g[kk] * g[l] * M[K][L] + g[kk] * H[K][l] * Hg[L] + g[l] * H[L][kk] * Hg[K]);
      }
    }
  }
  times_jr(&k, f, df, hess ? d2f : NULL, e, grad, hess);
  return VES_OK;
}

ves_status ves_model_local_volume(const ves_model_local_par *par, const ves_model_point *pt,
                                  const double q[VES_NQ], double *e, double *grad, double *hess) {
  (void)par;
  kin k;
  VES_CALL(kin_eval(q, &k));
  times_jr(&k, 0.5 * (1.0 + pt->phi0), NULL, NULL, e, grad, hess);
  return VES_OK;
}

ves_status ves_model_local_dissip(const ves_model_local_par *par, const double q[VES_NQ],
                                  double D[VES_NQD * VES_NQD]) {
  kin k;
  VES_CALL(kin_eval(q, &k));
  const double(*H)[2] = k.H;
  /* Rows of B: l = B qdot, l = (L_rr, L_rz, L_zr, L_zz, rdot/r) with
   * L_ij = Fdot_iI H_Ij; then (1/2) l^T K l = mu [L_rr^2 + L_zz^2 + s^2
   * + (L_rz + L_zr)^2 / 2] + (lambda/2)(L_rr + L_zz + s)^2, and
   * K = 2 mu (e0 e0^T + e3 e3^T + e4 e4^T) + mu (e1 + e2)(e1 + e2)^T
   *     + lambda (e0 + e3 + e4)(e0 + e3 + e4)^T. */
  const double b0[5] = {0.0, H[0][0], H[1][0], 0.0, 0.0};         /* L_rr */
  const double b3[5] = {0.0, 0.0, 0.0, H[0][1], H[1][1]};         /* L_zz */
  const double b4[5] = {1.0 / k.r, 0.0, 0.0, 0.0, 0.0};           /* rdot / r */
  const double cs[5] = {0.0, H[0][1], H[1][1], H[0][0], H[1][0]}; /* L_rz + L_zr */
  double t[5];                                                    /* tr L + rdot/r */
  for (int i = 0; i < 5; i++) t[i] = b0[i] + b3[i] + b4[i];
  const double rJ = k.r * k.J;
  const double m2 = 2.0 * par->mu * rJ, m1 = par->mu * rJ, la = par->lambda * rJ;
  for (int i = 0; i < 5; i++)
    for (int j = i; j < 5; j++) {
      const double v = m2 * (b0[i] * b0[j] + b3[i] * b3[j] + b4[i] * b4[j]) + m1 * cs[i] * cs[j] +
                       la * t[i] * t[j];
      D[i * 5 + j] = v;
      D[j * 5 + i] = v;
    }
  return VES_OK;
}
