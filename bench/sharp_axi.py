#!/usr/bin/python3
"""
vesica bench: sharp-interface Helfrich (spontaneous curvature C0, no ADE) axisymmetric equilibria
at fixed reduced volume, an independent check of the phase-field energies (docs/results.md,
"Accuracy against the sharp-interface references").
Usage: /usr/bin/python3 bench/sharp_axi.py [V] [K] [C0]   (V = 0.9, K = 16: converged to ~13 digits;
C0 in 1/R0, default 0)
Prints E* of the oblate and the prolate equilibria (sphere E* = 2 pi at C0 = 0) and their R_eq and
half-height at A = 4 pi. numpy only (Debian python3-numpy).
Normalization: E* = (1/2) int (H - C0)^2 dA, H = (c1+c2)/2 (sphere at C0 = 0 -> 2*pi), the sharp
limit of vesica's phase-field energy (docs/design.md); H > 0 on a sphere.
C0 breaks the scale invariance: the shape is computed at arc length L and scaled by s = sqrt(4 pi/A)
to A = 4 pi, where (1/2) int H^2 dA is unchanged, int H dA is s times its value and the area 4 pi.

Generating curve in arc length s = L t, t in [0,1] (pole -> pole), L fixed (scale-free problem):
    psi(t) = pi t + sum_{k} a_k sin(k pi t)
(tangent angle; r' = cos psi, z' = sin psi). Up-down symmetry psi(1-t) = pi - psi(t) <=> only even k
(closure r(1)=0 then holds exactly). Odd k may be switched on (closure becomes a constraint).
r(t) = L int_0^t cos psi : computed spectrally (cos psi is even, 2-periodic -> cosine series via FFT,
integrated exactly to a sine series). Integrals over [0,1] by Gauss-Legendre (integrands analytic).
Stationary point of E* subject to v = v0 found by Newton on the KKT system; gradient by complex step,
Hessian by central differences of complex-step gradients.
"""
import numpy as np, sys

L = np.pi


class Disc:
    def __init__(self, K, M=None, Q=None, sym=True, C0=0.0):
        self.sym = sym
        self.C0 = C0
        self.ks = np.arange(2, K + 1, 2) if sym else np.arange(1, K + 1)
        self.K = K
        self.M = M if M else max(256, 16 * K)       # FFT points on full period [0,2)
        self.Q = Q if Q else max(128, 6 * K)        # Gauss-Legendre nodes on [0,1]
        x, w = np.polynomial.legendre.leggauss(self.Q)
        self.tq = 0.5 * (x + 1); self.wq = 0.5 * w
        self.tu = 2.0 * np.arange(self.M) / self.M
        self.n = np.arange(1, self.M // 2)
        self.Sq = np.sin(np.pi * np.outer(self.tq, self.n)) / (np.pi * self.n)  # r basis at GL nodes
        self.Su = np.sin(np.pi * np.outer(self.tu, self.ks))
        self.Bq = np.sin(np.pi * np.outer(self.tq, self.ks))
        self.Dq = np.pi * self.ks * np.cos(np.pi * np.outer(self.tq, self.ks))
        # real cosine-transform matrix (no complex FFT: keeps complex-step derivatives exact)
        Cmat = (2.0 / self.M) * np.cos(np.pi * np.outer(self.n, self.tu))
        self.R = L * (self.Sq @ Cmat)

    def geom(self, a):
        """returns psi, psi_s, r at GL nodes, plus closure residual (mean of cos psi)"""
        psiu = np.pi * self.tu + self.Su @ a
        f = np.cos(psiu)
        r = self.R @ f
        psi = np.pi * self.tq + self.Bq @ a
        psis = (np.pi + self.Dq @ a) / L
        return psi, psis, r, np.mean(f)

    def funcs(self, a):
        psi, psis, r, c0 = self.geom(a)
        sp = np.sin(psi)
        H2 = (psis + sp / r) ** 2
        E = 0.25 * np.pi * L * np.sum(self.wq * r * H2)
        A = 2 * np.pi * L * np.sum(self.wq * r)
        if self.C0 != 0:  # at A = 4 pi: - C0 s int H dA + (C0^2 / 2) 4 pi
            IH = np.pi * L * np.sum(self.wq * r * (psis + sp / r))
            E = E - self.C0 * np.sqrt(4 * np.pi / A) * IH + 2 * np.pi * self.C0 ** 2
        V = np.pi * L * np.sum(self.wq * r * r * sp)
        v = V / (4 * np.pi / 3 * (A / (4 * np.pi)) ** 1.5)
        return E, v, c0, A, V


def cgrad(fun, x, h=1e-30):
    """complex-step gradient of a vector-valued function (returns list of arrays)"""
    n = len(x)
    out = None
    for j in range(n):
        xc = x.astype(complex); xc[j] += 1j * h
        vals = fun(xc)
        if out is None:
            out = [np.zeros(n) for _ in vals]
        for i, val in enumerate(vals):
            out[i][j] = np.imag(val) / h
    return out


def solve(d, a0, v0, lam0=0.0, tol=1e-13, maxit=40, verbose=False):
    """Newton on KKT: grad E - lam grad v (- mu grad c0) = 0, v = v0 (, c0 = 0)"""
    a = a0.copy(); lam = lam0; mu = 0.0
    n = len(a)
    fun = lambda x: d.funcs(x)[:3]
    for it in range(maxit):
        gE, gv, gc = cgrad(fun, a)
        E, v, c0 = [np.real(t) for t in fun(a)]
        res = np.concatenate([gE - lam * gv - mu * gc, [v - v0]] + ([] if d.sym else [[c0]]))
        nr = np.linalg.norm(res)
        if verbose:
            print(f"  it {it:2d} |res|={nr:.3e} E={E:.15f} v={v:.15f}", flush=True)
        if nr < tol:
            break
        delta = 1e-6
        HE = np.zeros((n, n)); Hv = np.zeros((n, n)); Hc = np.zeros((n, n))
        for j in range(n):
            ap = a.copy(); ap[j] += delta
            am = a.copy(); am[j] -= delta
            gp = cgrad(fun, ap); gm = cgrad(fun, am)
            HE[:, j] = (gp[0] - gm[0]) / (2 * delta)
            Hv[:, j] = (gp[1] - gm[1]) / (2 * delta)
            Hc[:, j] = (gp[2] - gm[2]) / (2 * delta)
        Hl = HE - lam * Hv - mu * Hc
        Hl = 0.5 * (Hl + Hl.T)
        if d.sym:
            J = np.zeros((n + 1, n + 1))
            J[:n, :n] = Hl; J[:n, n] = -gv; J[n, :n] = gv
        else:
            J = np.zeros((n + 2, n + 2))
            J[:n, :n] = Hl; J[:n, n] = -gv; J[:n, n + 1] = -gc
            J[n, :n] = gv; J[n + 1, :n] = gc
        step = np.linalg.solve(J, -res)
        a = a + step[:n]; lam += step[n]
        if not d.sym:
            mu += step[n + 1]
    # Hessian of Lagrangian projected on tangent space of constraint -> index (number of neg. eigenvalues)
    info = dict(E=E, v=v, lam=lam, res=nr, it=it)
    try:
        Q_, _ = np.linalg.qr(np.column_stack([gv] + ([] if d.sym else [gc])), mode='complete')
        T = Q_[:, (1 if d.sym else 2):]
        ev = np.linalg.eigvalsh(T.T @ Hl @ T)
        info['index'] = int(np.sum(ev < -1e-8)); info['mineig'] = ev[0]
    except Exception:
        pass
    return a, lam, info


def shape_dims(d, a, Ngrid=4001):
    """equatorial radius, half-height, max radius, rescaled to A = 4 pi (R0=1)"""
    E, v, c0, A, V = [np.real(t) for t in d.funcs(a)]
    scale = np.sqrt(4 * np.pi / A)
    t = np.linspace(0, 1, Ngrid)
    psiu = np.pi * d.tu + d.Su @ a
    C = np.fft.fft(np.cos(psiu)) / d.M; M = d.M
    c = np.real(C[1:M // 2] + C[M - 1:M // 2:-1])
    Cs = np.fft.fft(np.sin(psiu)) / d.M
    # z(t) = L int_0^t sin psi : sin psi is odd 2-periodic plus ... (psi - pi t is odd, sin(pi t + f) is odd) -> sine series
    s_ = Cs[1:M // 2] - Cs[M - 1:M // 2:-1]   # sin psi = sum b_n sin(n pi t), b_n = i (C_n - C_-n)
    b = np.real(1j * s_)
    n = d.n
    r = L * (np.sin(np.pi * np.outer(t, n)) / (np.pi * n)) @ c
    z = L * ((1 - np.cos(np.pi * np.outer(t, n))) / (np.pi * n)) @ b
    Req = r[Ngrid // 2] * scale
    rmax = r.max() * scale
    H = z[-1] * scale                 # pole-to-pole height
    # height at the axis vs max height (dimple?)
    return dict(Req=Req, rmax=rmax, half_height=H / 2, z_span=(z.max() - z.min()) * scale / 2, r=r * scale, z=z * scale)


# ---------- spheroid -> psi(t) samples -> sine coefficients ----------
def spheroid_coeffs(aeq, cpol, K, sym=True, Nth=4096):
    """psi(s) of the ellipse r = aeq sin th, z = -cpol cos th, arc length rescaled to L; returns a_k and scale"""
    th = np.pi * np.arange(Nth) / Nth  # for spectral arclength
    # ds/dth is pi-periodic even; integrate via FFT over [0, pi)
    g = lambda th: np.sqrt(aeq ** 2 * np.cos(th) ** 2 + cpol ** 2 * np.sin(th) ** 2)
    G = np.fft.rfft(g(th)) / Nth
    g0 = np.real(G[0]); m = np.arange(1, len(G))
    def s_of(th):  # int_0^th g
        # g = g0 + sum 2 Re(G_m e^{i 2 m th})
        return g0 * th + np.sum(2 * np.real(G[1:, None] * (np.exp(2j * np.outer(m, th)) - 1) / (2j * m[:, None])), axis=0)
    def g_of(th):
        return g(th)
    Stot = g0 * np.pi
    # uniform t grid on [0,1]
    Mh = 4 * K + 64
    t = np.arange(Mh + 1) / Mh
    starget = t * Stot
    thv = np.pi * t.copy()
    for _ in range(50):
        dth = (s_of(thv) - starget) / g_of(thv)
        thv -= dth
        if np.max(np.abs(dth)) < 1e-15:
            break
    psi = np.arctan2(cpol * np.sin(thv), aeq * np.cos(thv))
    psi[0] = 0.0; psi[-1] = np.pi
    f = psi - np.pi * t
    ks = np.arange(2, K + 1, 2) if sym else np.arange(1, K + 1)
    # a_k = 2 int_0^1 f sin(k pi t) dt, trapezoid (integrand even/periodic -> spectral)
    w = np.ones(Mh + 1) / Mh; w[0] = w[-1] = 0.5 / Mh
    a = 2 * (np.sin(np.pi * np.outer(ks, t)) * f) @ w
    return a


def spheroid_energy_exact(a, c):
    """Independent closed-form-ish check: E* = (1/8) int (c1+c2)^2 dA by 1D quadrature in theta (GL, many nodes)."""
    x, w = np.polynomial.legendre.leggauss(2000)
    th = 0.5 * np.pi * (x + 1); w = 0.5 * np.pi * w
    r = a * np.sin(th); rp = a * np.cos(th); zp = c * np.sin(th); rpp = -a * np.sin(th); zpp = c * np.cos(th)
    ds = np.sqrt(rp ** 2 + zp ** 2)
    k1 = (rp * zpp - zp * rpp) / ds ** 3
    k2 = zp / (r * ds)
    dA = 2 * np.pi * r * ds
    A = np.sum(w * dA)
    return np.sum(w * (k1 + k2) ** 2 * dA) / 8, A


if __name__ == "__main__":
    v0 = float(sys.argv[1]) if len(sys.argv) > 1 else 0.9
    K = int(sys.argv[2]) if len(sys.argv) > 2 else 16
    d = Disc(K, C0=float(sys.argv[3]) if len(sys.argv) > 3 else 0.0)
    # start: the v = 0.9 spheroids (Newton reaches v0 from them for v0 near 0.9)
    for name, (aeq, cpol) in (("oblate", (1.182923, 0.643176)), ("prolate", (0.643176, 1.182923))):
        a, lam, info = solve(d, spheroid_coeffs(aeq, cpol, K), v0)
        sd = shape_dims(d, a)
        print(f"{name} v={info['v']:.12f} E*={info['E']:.12f} R_eq={sd['Req']:.9f} "
              f"half_height={sd['half_height']:.9f} residual={info['res']:.1e} "
              f"negative_curvatures={info.get('index')}")
