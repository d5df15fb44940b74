#!/usr/bin/python3
"""
vesica bench: the paper's Fig. 7 (kinetic effects of deflation) from the three runs of
problems/deflate_{slow,medium,fast}.ini, in the paper's layout, and the numbers that compare them.

Usage: /usr/bin/python3 bench/fig7.py DIR [FIGDIR [VESICA]]
  DIR holds fig7_{slow,medium,fast}.h5 and fig7_*.done (bench/paper.sh's layout); its working
  files go to DIR/fig7_plot/. FIGDIR (default bench/figures/paper) gets fig7_epsE.png: top left
  V/V0 against t*, bottom left E* = E/k against t* (time axes from the first step to the
  last), right the phi = 0 curves at the energy's maximum (A fast, B medium, C slow; the end of
  each ramp) and at the end of the runs, with the sharp equilibrium D at the final shapes'
  reduced volume, in r/R0 and z/R0 fitted to the curves. VESICA (default build/vesica) runs
  `vesica check` on each of those shapes.
Prints Markdown tables: per rate the ramp's end, E* max and its t*, E* final, the final
interface's max distance from the other rates' and its up-down asymmetry; per shape (at the
maximum, at the end, D) the run's E*, the sharp E* of its phi = 0 curve and that shape's energy
as a phase field with the equilibrium profile at the runs' eps, distances to the run's final
shape and to D, the profile's width against the equilibrium one; then the sharp equilibria
(bench/sharp_axi.py, oblate/discocyte and prolate branches, continued from v = 0.9). Needs h5py
and numpy (Debian python3-h5py) and gnuplot.

The interface: phi = 0 on the snapshot's triangles (/mesh/triangles on the snapshot's positions
x, phi linear on each triangle), kept where R >= 0 (the ghosts mirror the axis). Distances between
two curves: the symmetric Hausdorff distance between the polylines (every point of one to the
nearest segment of the other, both ways), in R0 = sqrt(A0 / 4 pi).
"""
import os
import subprocess
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import sharp_axi  # noqa: E402

RATES = (("fast", 14.0), ("medium", 2.8), ("slow", 0.56))
V_FINAL = 0.72  # V/V0 at the ramp's end (the problem files' volume_final)


def segments(x, phi, tri):
    """phi = 0 segments (m, 2, 2) of phi linear on the triangles, on the side R >= 0"""
    segs = []
    p = phi[tri]  # (ntri, 3)
    P = x[tri]  # (ntri, 3, 2)
    for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        # the vertex a alone on its side: the segment crosses edges a-b and a-c
        m = (np.sign(p[:, a]) != np.sign(p[:, b])) & (np.sign(p[:, a]) != np.sign(p[:, c])) & (p[:, a] != 0)
        m &= np.sign(p[:, b]) == np.sign(p[:, c])
        if not m.any():
            continue
        ta = p[m, a] / (p[m, a] - p[m, b])
        tc = p[m, a] / (p[m, a] - p[m, c])
        q1 = P[m, a] + ta[:, None] * (P[m, b] - P[m, a])
        q2 = P[m, a] + tc[:, None] * (P[m, c] - P[m, a])
        segs.append(np.stack([q1, q2], axis=1))
    s = np.concatenate(segs)
    return s[(s[:, 0, 0] >= 0) | (s[:, 1, 0] >= 0)]


def seg_dist(pts, segs):
    """distance of each point to the nearest of the segments"""
    a = segs[:, 0]
    d = segs[:, 1] - a
    dd = np.maximum((d * d).sum(1), 1e-300)
    out = np.empty(len(pts))
    for i0 in range(0, len(pts), 256):
        q = pts[i0:i0 + 256, None, :] - a[None]
        t = np.clip((q * d[None]).sum(2) / dd[None], 0, 1)
        r = q - t[..., None] * d[None]
        out[i0:i0 + 256] = np.sqrt((r * r).sum(2)).min(1)
    return out


def dense(segs, n=4):
    """points along the segments (n + 1 a segment), for the distance of a curve to another"""
    t = np.linspace(0, 1, n + 1)
    return (segs[:, None, 0] + t[None, :, None] * (segs[:, None, 1] - segs[:, None, 0])).reshape(-1, 2)


def hausdorff(s1, s2):
    return max(seg_dist(dense(s1), s2).max(), seg_dist(dense(s2), s1).max())


def polyline_segs(r, z):
    p = np.column_stack([r, z])
    return np.stack([p[:-1], p[1:]], axis=1)


def smooth_curve(segs, K=30, n=801):
    """the interface as a smooth generating curve from north to south pole: the points of the
    phi = 0 segments ordered by their polar angle alpha about the centre (0, zc) (a star-shaped
    interface), their arc length s taken on a polar fit rho(alpha) = sum_{k<40} c_k cos(k alpha),
    then r(s) = sum_{k=1..K} b_k sin(k pi s/L), z(s) = sum_{k<=K} d_k cos(k pi s/L) by least
    squares (smooth on the axis), each point's s then moved to its nearest point of the fit and
    the fit repeated (4 times); (r, z) at n equal parameter steps and the points' max distance
    from the fitted curve"""
    p = dense(segs)
    p = p[p[:, 0] >= 0]
    zc = 0.5 * (p[:, 1].max() + p[:, 1].min())
    rho = np.hypot(p[:, 0], p[:, 1] - zc)
    al = np.arctan2(p[:, 0], p[:, 1] - zc)  # 0 north, pi south
    c = np.linalg.lstsq(np.cos(np.outer(al, np.arange(40))), rho, rcond=None)[0]
    a = np.linspace(0, np.pi, 8001)
    ro = np.cos(np.outer(a, np.arange(40))) @ c
    S = np.concatenate([[0], np.cumsum(np.hypot(np.diff(ro * np.sin(a)), np.diff(ro * np.cos(a))))])
    L = S[-1]
    sp = np.interp(al, a, S) * np.pi / L
    k = np.arange(1, K + 1)
    k0 = np.arange(K + 1)
    uf = np.linspace(0, np.pi, 8001)
    for _ in range(4):  # parameter correction: each point's s to its nearest point of the fit
        br = np.linalg.lstsq(np.sin(np.outer(sp, k)), p[:, 0], rcond=None)[0]
        dz = np.linalg.lstsq(np.cos(np.outer(sp, k0)), p[:, 1], rcond=None)[0]
        cf = np.column_stack([np.sin(np.outer(uf, k)) @ br, np.cos(np.outer(uf, k0)) @ dz])
        for i0 in range(0, len(p), 512):
            d2 = ((p[i0:i0 + 512, None, :] - cf[None]) ** 2).sum(2)
            sp[i0:i0 + 512] = uf[d2.argmin(1)]
    res = seg_dist(p, np.stack([cf[:-1], cf[1:]], axis=1)).max()
    u = np.linspace(0, np.pi, n)
    r, z = np.sin(np.outer(u, k)) @ br, np.cos(np.outer(u, np.arange(K + 1))) @ dz
    r[0] = r[-1] = 0.0
    return r, z, res


def check(vesica, pts_file, eps, bands=(3, 2)):
    """vesica check of a curve at eps: the phase-field energy of that shape with the equilibrium
    profile, the sharp energy of its generating curve, the phase field's reduced volume, and the
    band used (the first of bands that fits the curve's curvature: the runs' band 4 at eps 0.08
    does not fit their rims; one band for all shapes keeps them comparable)"""
    for band in bands:
        ini = f"{pts_file}.band{band}.ini"
        with open(ini, "w") as o:
            o.write(f"[geometry]\nepsilon = {eps}\nband = {band}\n[shape]\ntype = curve\n"
                    f"points = {os.path.basename(pts_file)}\n")
        out = subprocess.run([vesica, "check", ini], capture_output=True, text=True)
        if out.returncode == 0:
            kv = dict(ln.split(" = ", 1) for ln in out.stdout.splitlines() if " = " in ln)
            return float(kv["energy"]), float(kv["energy_sharp"]), float(kv["reduced_volume"]), band
    return None


class Run:
    def __init__(self, path):
        f = h5py.File(path, "r")
        self.tri = f["mesh/triangles"][()]
        self.count = int(f["snapshots"].attrs["count"])
        self.times = np.array([f[f"snapshots/{k}"].attrs["t"] for k in range(self.count)])
        self.f = f

    def interface(self, k):
        g = self.f[f"snapshots/{k}"]
        return segments(g["x"][()], g["phi"][()], self.tri)

    def first_at(self, t):
        """the first snapshot at or after t"""
        k = int(np.searchsorted(self.times, t - 1e-12))
        return min(k, self.count - 1)


def series(f):
    """the run's /series as columns step, t, V/V0, E (full precision, whole across restarts)"""
    g = f["series"]
    V0 = f["snapshots/0"].attrs["V"]
    return np.column_stack([g["step"][()], g["t"][()], g["V"][()] / V0, g["E"][()]])


def sharp(v_target, K=16, n=13):
    """sharp equilibria at v_target, continued from the v = 0.9 spheroids (sharp_axi.py)"""
    d = sharp_axi.Disc(K)
    out = {}
    for name, (aeq, cpol) in (("oblate", (1.182923, 0.643176)), ("prolate", (0.643176, 1.182923))):
        a = sharp_axi.spheroid_coeffs(aeq, cpol, K)
        lam = 0.0
        for v in np.linspace(0.9, v_target, n):
            a, lam, info = sharp_axi.solve(d, a, v, lam)
        sd = sharp_axi.shape_dims(d, a)
        out[name] = dict(E=info["E"], v=info["v"], res=info["res"], index=info.get("index"),
                         r=sd["r"], z=sd["z"] - 0.5 * (sd["z"][0] + sd["z"][-1]))
    return out


def width(run, k, eps):
    """the interface profile's width against the equilibrium one: phi = tanh(d / w) at the nodes
    with |phi| < 0.9 (d the distance to the phi = 0 curve, R > 0.05), median of w / (sqrt2 eps) on
    the inside (phi > 0) and on the outside"""
    g = run.f[f"snapshots/{k}"]
    x, phi = g["x"][()], g["phi"][()]
    m = (np.abs(phi) < 0.9) & (x[:, 0] > 0.05)
    d = seg_dist(x[m], run.interface(k)) * np.sign(phi[m])
    w = d / np.arctanh(phi[m]) / (np.sqrt(2) * eps)
    return np.median(w[phi[m] > 0]), np.median(w[phi[m] < 0])


def main():
    if len(sys.argv) < 2:
        sys.exit("usage: fig7.py DIR [FIGDIR] [VESICA]")
    d = sys.argv[1]
    figdir = sys.argv[2] if len(sys.argv) > 2 else "bench/figures/paper"
    vesica = sys.argv[3] if len(sys.argv) > 3 else "build/vesica"
    runs, ser = {}, {}
    for name, rate in RATES:
        h5 = os.path.join(d, f"fig7_{name}.h5")
        if os.path.exists(h5) and os.path.exists(os.path.join(d, f"fig7_{name}.done")):
            runs[name] = Run(h5)
            ser[name] = series(runs[name].f)
    if not runs:
        sys.exit("fig7.py: no finished fig7 run in " + d)
    first = next(iter(runs.values())).f
    eps = float(first["parameters"].attrs["geometry.epsilon"])
    s0 = first["snapshots/0"].attrs
    v0 = s0["V"] / (4 * np.pi / 3 * (s0["A"] / (4 * np.pi)) ** 1.5)
    tmp = os.path.join(d, "fig7_plot")
    os.makedirs(tmp, exist_ok=True)
    final = {n: r.interface(r.count - 1) for n, r in runs.items()}
    rampend = {}
    print(f"eps {eps}; the phase field's v(0) = {v0:.6f}, final v = {v0 * V_FINAL:.6f}")
    print()
    print("| rate | ramp end t* | steps | E* max (t*) | E* at the snapshot nearest the max (t*) | E* final (t*) "
          "| final phi = 0: max distance to the other rates' | z-centroid | up-down asymmetry |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, rate in RATES:
        if name not in runs:
            print(f"| {name} | not run | | | | | | | |")
            continue
        r, s = runs[name], ser[name]
        te = (1 - V_FINAL) / rate
        im = int(np.argmax(s[:, 3]))
        k = r.first_at(s[im, 1])  # the snapshot at the energy's maximum (the paper's instant)
        rampend[name] = (k, r.times[k], r.interface(k))
        fs = final[name]
        others = [hausdorff(fs, final[o]) for o in final if o != name]
        pts = dense(fs)
        zc = 0.5 * (pts[:, 1].max() + pts[:, 1].min())
        mirror = fs.copy()
        mirror[:, :, 1] = 2 * zc - mirror[:, :, 1]
        print(f"| {name} | {te:.4g} | {int(s[-1, 0])} | {s[im, 3]:.4f} ({s[im, 1]:.4g}) | "
              f"{r.f[f'snapshots/{k}'].attrs['E']:.4f} ({r.times[k]:.4g}) | {s[-1, 3]:.4f} ({s[-1, 1]:.4g}) | "
              f"{max(others) if others else float('nan'):.2e} | {zc:+.1e} | {hausdorff(fs, mirror):.1e} |")
    # the shapes: each phi = 0 curve as a smooth generating curve, its sharp energy and the phase
    # field's energy of that shape with the equilibrium profile (vesica check at the runs' eps)
    print()
    print("| state | t* | E* of the run | E* sharp of its phi = 0 shape | E* of that shape as a phase "
          "field (check, band) | that phase field's v | fit residual | distance to the run's final phi = 0 "
          "| to D (z-centred) | profile width / equilibrium: inside, outside |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    rows, vfin = [], []
    for name in runs:
        r = runs[name]
        for tag, k in (("max", rampend[name][0]), ("final", r.count - 1)):
            rr, zz, res = smooth_curve(r.interface(k))
            fn = os.path.join(tmp, f"{name}_{k}.txt")
            np.savetxt(fn, np.column_stack([rr, zz]), fmt="%.12f")
            c = check(vesica, fn, eps)
            wi, wo = width(r, k, eps)
            rows.append((name, tag, k, r.times[k], r.f[f"snapshots/{k}"].attrs["E"], c, res, rr, zz, wi, wo))
    # D: the sharp discocyte at the final shapes' reduced volume (and at 0.9 x 0.72)
    vols = []
    for row in rows:
        if row[1] == "final":
            rr, zz = row[7], row[8]
            A = 2 * np.pi * np.sum(0.5 * (rr[1:] + rr[:-1]) * np.hypot(np.diff(rr), np.diff(zz)))
            V = np.pi * np.sum(0.5 * (rr[1:] ** 2 + rr[:-1] ** 2) * -np.diff(zz))
            vols.append(V / (4 * np.pi / 3 * (A / (4 * np.pi)) ** 1.5))
    vD = float(np.mean(vols))
    shD = sharp(vD)
    sh72 = sharp(0.9 * V_FINAL)
    eq = shD["oblate"]
    eqsegs = polyline_segs(eq["r"], eq["z"])
    fnD = os.path.join(tmp, "D.txt")
    rD, zD = eq["r"][::5], eq["z"][::5]  # pole (t = 0, the lower) to pole
    rD[0] = rD[-1] = 0.0
    np.savetxt(fnD, np.column_stack([rD, zD])[::-1], fmt="%.12f")  # north to south
    cD = check(vesica, fnD, eps)
    for name, tag, k, t, E, c, res, rr, zz, wi, wo in rows:
        sg = polyline_segs(rr, zz - 0.5 * (zz.max() + zz.min()))
        cs = f"{c[1]:.4f} | {c[0]:.4f} ({c[3]}) | {c[2]:.4f}" if c else "— | check refused | —"
        print(f"| {name}, {tag} | {t:.4g} | {E:.4f} | {cs} | {res:.1e} | "
              f"{hausdorff(runs[name].interface(k), final[name]):.1e} | {hausdorff(sg, eqsegs):.1e} | "
              f"{wi:.3f}, {wo:.3f} |")
    cs = f"{cD[1]:.4f} | {cD[0]:.4f} ({cD[3]}) | {cD[2]:.4f}" if cD else "— | check refused | —"
    print(f"| D: sharp discocyte at the final shapes' v {vD:.4f} | — | — | {eq['E']:.4f} (sharp_axi) / {cs} | — | — | 0 | — |")
    print()
    print(f"sharp equilibria (bench/sharp_axi.py, K 16, continued from the v = 0.9 spheroids): at v {vD:.4f}"
          f" oblate/discocyte {shD['oblate']['E']:.6f} (negative curvatures {shD['oblate']['index']}),"
          f" prolate {shD['prolate']['E']:.6f} ({shD['prolate']['index']}); at v {0.9 * V_FINAL:.3f}"
          f" (0.9 x 0.72) oblate/discocyte {sh72['oblate']['E']:.6f} ({sh72['oblate']['index']}),"
          f" prolate {sh72['prolate']['E']:.6f} ({sh72['prolate']['index']})")
    # the figure's data and gnuplot
    os.makedirs(figdir, exist_ok=True)
    for name in runs:
        s = ser[name]
        np.savetxt(os.path.join(tmp, f"{name}.series"), s[:, 1:])
        for tag, segs in (("ramp", rampend[name][2]), ("final", final[name])):
            with open(os.path.join(tmp, f"{name}.{tag}"), "w") as o:
                for sg in segs:
                    o.write(f"{sg[0, 0]} {sg[0, 1]}\n{sg[1, 0]} {sg[1, 1]}\n\n")
    np.savetxt(os.path.join(tmp, "D.curve"), np.column_stack([eq["r"], eq["z"]]))
    png = os.path.join(figdir, f"fig7_eps{eps:g}.png")
    col = {"fast": "#d62728", "medium": "#2ca02c", "slow": "#1f77b4"}
    lab = {"fast": "A", "medium": "B", "slow": "C"}
    # the axes fitted to the data: time from the first step to the last, the shapes' box from
    # their curves (and D's) with 0.05 R0 around
    tmax = max(ser[n][-1, 1] for n in runs)
    tmin = min(ser[n][ser[n][:, 1] > 0, 1][0] for n in runs)  # the first step (log axis: not t = 0)
    pts = np.concatenate([dense(rampend[n][2]) for n in runs] + [dense(final[n]) for n in runs]
                         + [np.column_stack([eq["r"], eq["z"]])])
    rmax = np.ceil((pts[:, 0].max() + 0.05) * 10) / 10
    zmax = np.ceil((np.abs(pts[:, 1]).max() + 0.05) * 10) / 10
    g = [f"set terminal pngcairo size 1500,900 font ',11'", f"set output '{png}'",
         f"set multiplot title 'Fig. 7 at eps {eps}: deflation to V/V_0 = {V_FINAL} at three rates'",
         "set size 0.5,0.46; set origin 0,0.48", "set xlabel 't* = t k / ({/Symbol m} R_0^3)'",
         "set ylabel 'V / V_0'",
         f"set logscale x; set format x '10^{{%L}}'; set xrange [{tmin:.3g}:{tmax:.3g}]",
         "set offsets 0, 0, graph 0.05, graph 0.05; set key bottom left",
         "plot " + ", ".join(f"'{tmp}/{n}.series' u 1:2 w l lw 2 lc rgb '{col[n]}' t '{n} ({lab[n]})'"
                             for n in runs),
         "set size 0.5,0.46; set origin 0,0; set ylabel 'E* = E / k'; set key top left",
         "set offsets 0, 0, graph 0.25, graph 0.05",  # room above the peaks for the legend
         "plot " + ", ".join(f"'{tmp}/{n}.series' u 1:3 w lp pt 7 ps 0.4 lw 2 lc rgb '{col[n]}' t '{n}'"
                             for n in runs) + f", {eq['E']} w l dt 2 lc rgb 'black' t 'D sharp ({eq['E']:.3f})'"
         + (f", {cD[0]} w l dt 3 lc rgb 'black' t 'D as a phase field at eps {eps} ({cD[0]:.3f})'" if cD else ""),
         "unset logscale x; set format x '%g'; set offsets 0, 0, 0, 0",
         f"set size 0.5,0.94; set origin 0.5,0; set xrange [0:{rmax:g}]; set yrange [-{zmax:g}:{zmax:g}]",
         "set size ratio -1; set xlabel 'r / R_0'; set ylabel 'z / R_0'; set key below maxrows 4",
         f'set title "{{/Symbol f}} = 0 at the energy maximum (A, B, C) and at the end (dotted);\\n'
         f'D: the sharp discocyte at v {vD:.4f}"',
         "plot " + ", ".join(f"'{tmp}/{n}.ramp' w l lw 2 lc rgb '{col[n]}' t '{lab[n]}: {n}, E* max, t* {rampend[n][1]:.3g}', "
                             f"'{tmp}/{n}.final' w l dt 3 lw 2 lc rgb '{col[n]}' t '{n}, end'" for n in runs)
         + f", '{tmp}/D.curve' w l lw 1 lc rgb 'black' t 'D (sharp, z-centred)'",
         "unset multiplot"]
    subprocess.run(["gnuplot"], input="\n".join(g) + "\n", text=True, check=True)
    print()
    print(f"figure: {png}")


if __name__ == "__main__":
    main()
