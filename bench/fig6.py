#!/usr/bin/python3
"""
vesica bench: the paper's Fig. 6 (a prolate vesicle deflated at constant area while its
spontaneous curvature rises: elongation and pearling) from the run of problems/pearling.ini, in
the paper's layout, and the numbers that describe it.

Usage: /usr/bin/python3 bench/fig6.py RUN.h5 [FIGDIR [NSHOT]]
  RUN.h5 is the run (bench/paper.sh: OUT/fig6.h5; a run still being written can be read from a
  copy, or with HDF5_USE_FILE_LOCKING=FALSE); its working files go to a folder RUN.fig6/ beside
  it. FIGDIR (default bench/figures/paper) gets fig6_epsE.png (RUN_pearls.png for a run
  without a C0 ramp, e.g. problems/prolate_c0.ini's Fig. 5 right, titled by its protocol):
  top, the nodes y(X_a) coloured by phi at NSHOT (default 6) snapshots (those nearest t* = 0,
  half and end of the C0 ramp, and equal steps in t* from there to the last; the meridian plane
  mirrored to r < 0, as the paper shows it) with each snapshot's phi = 0 curve in black
  (python/vesica.py's Snapshot.interface, on the triangles in use at it), axes r/R0 and z/R0
  fitted to the curves, one colour bar for phi; bottom, E* = E/k against t* with C0 R0 and 10 v
  (v the phase field's reduced volume) on a second axis fitted to them, the resets (grey ticks)
  and remeshings (red dashes) marked, the legend below the axes.
Prints Markdown tables: the shape along the run (per snapshot: t*, step, nodes, E*, C0 R0, v,
the length along the axis, the pieces of the inside on the axis, the number of pearls, their
radii and the neck radii between them, the fastest node of the flow), and the remeshings (what each changed). Needs h5py and
numpy (Debian python3-h5py) and gnuplot.

The shape: phi = 0 on the snapshot's triangles (the mesh of the reference in use: /mesh or the
last remeshing before the snapshot; phi linear on each triangle, the snapshot's positions x). Its
outer radius profile rho(z) = the largest R of the phi = 0 curve in bins of z (width eps/4).
A pearl is a local maximum of rho(z) that rises at least eps/2 above the lower of the two minima
beside it (the neck, or the end of the shape); a neck is the minimum of rho between two adjacent
pearls. Pieces on the axis: the intervals of z where phi > 0 on the axis (more than one: the
vesicle has pinched into several).
"""
import os
import subprocess
import sys

import h5py
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "python"))
from fig7 import segments  # noqa: E402  (phi = 0 segments on triangles)
import vesica  # noqa: E402  (the reader: a snapshot's phi = 0 curves, its .interface)


def triangles_for(f, step):
    """the triangles of the reference in use after accepted step `step`"""
    tri = f["mesh/triangles"][()]
    if "remeshes" in f:
        g = f["remeshes"]
        for k in range(int(g.attrs["count"])):
            if int(g[str(k)].attrs["step"]) <= step:
                tri = g[f"{k}/triangles"][()]
    return tri


def profile(segs, eps):
    """rho(z): the largest R of the phi = 0 segments' points in z bins of width eps/4"""
    t = np.linspace(0, 1, 9)
    p = (segs[:, None, 0] + t[None, :, None] * (segs[:, None, 1] - segs[:, None, 0])).reshape(-1, 2)
    p = p[p[:, 0] >= 0]
    w = eps / 4
    z0 = p[:, 1].min()
    b = np.floor((p[:, 1] - z0) / w).astype(int)
    rho = np.full(b.max() + 1, np.nan)
    np.fmax.at(rho, b, p[:, 0])
    z = z0 + (np.arange(len(rho)) + 0.5) * w
    ok = ~np.isnan(rho)
    return z[ok], rho[ok]


def pearls(z, rho, eps):
    """pearls (z, radius) and necks (z, radius) of the profile: local maxima standing at least
    eps/2 above the lower of the minima beside them; necks the minima between adjacent pearls"""
    rr = np.concatenate([[0.0], rho, [0.0]])  # the shape closes on the axis at both ends
    zz = np.concatenate([[z[0]], z, [z[-1]]])
    mx = [i for i in range(1, len(rr) - 1) if rr[i] >= rr[i - 1] and rr[i] > rr[i + 1]]
    keep = True
    while keep and len(mx) > 1:  # drop the least prominent maximum until all stand eps/2 out
        keep = False
        prom = []
        for j, i in enumerate(mx):
            lo = rr[mx[j - 1]:i + 1].min() if j > 0 else 0.0
            hi = rr[i:mx[j + 1] + 1].min() if j + 1 < len(mx) else 0.0
            prom.append(rr[i] - max(lo, hi))
        j = int(np.argmin(prom))
        if prom[j] < eps / 2:
            # merge: keep the higher of it and its neighbour
            mx.pop(j)
            keep = True
    P = [(zz[i], rr[i]) for i in mx]
    N = []
    for a, b in zip(mx[:-1], mx[1:]):
        k = a + int(np.argmin(rr[a:b + 1]))
        N.append((zz[k], rr[k]))
    return P, N


def axis_pieces(x, phi, eps):
    """the intervals of z where phi > 0 on the axis (nodes with R < eps/10), sorted by z"""
    m = x[:, 0] < eps / 10
    zs, ph = x[m, 1], phi[m]
    o = np.argsort(zs)
    zs, ph = zs[o], ph[o]
    inside = ph > 0
    return int(np.sum(inside[1:] & ~inside[:-1]) + (1 if len(inside) and inside[0] else 0))


def main():
    if len(sys.argv) < 2:
        sys.exit("usage: fig6.py RUN.h5 [FIGDIR [NSHOT]]")
    path = sys.argv[1]
    figdir = sys.argv[2] if len(sys.argv) > 2 else "bench/figures/paper"
    nshot = int(sys.argv[3]) if len(sys.argv) > 3 else 6
    f = vesica._open(path)  # with the reader's flags: vesica.load opens it again
    eps = float(f["parameters"].attrs["geometry.epsilon"])
    run = vesica.load(path)
    ser = run.series  # row i holds step i, row 0 the initial state (either format)
    t, E, V, c0 = (np.asarray(ser[k]) for k in ("t", "E", "V", "c0"))
    A = np.asarray(ser["A"])
    recon = np.asarray(ser["reconnections"])
    v = V / (4 * np.pi / 3 * (A / (4 * np.pi)) ** 1.5)
    nsnap = int(f["snapshots"].attrs["count"])
    st = [f[f"snapshots/{k}"].attrs for k in range(nsnap)]
    ts = np.array([a["t"] for a in st])
    steps = np.array([int(a["step"]) for a in st])
    tmp = os.path.splitext(path)[0] + ".fig6"
    os.makedirs(tmp, exist_ok=True)
    print(f"eps {eps}; {len(t) - 1} steps to t* {t[-1]:.4g}; {nsnap} snapshots; "
          f"{int(recon[-1]) if len(recon) else 0} resets")
    print()
    print("| t* | step | nodes | E* | C0 R0 | v | length (z extent) | pieces on the axis | pearls | "
          "pearl radii (from the top) | neck radii | max flow (R0 per t*) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    shape = []
    for k in range(nsnap):
        g = f[f"snapshots/{k}"]
        x, phi = g["x"][()], g["phi"][()]
        segs = segments(x, phi, triangles_for(f, steps[k]))
        z, rho = profile(segs, eps)
        P, N = pearls(z, rho, eps)
        pc = axis_pieces(x, phi, eps)
        a = st[k]
        vk = a["V"] / (4 * np.pi / 3 * (a["A"] / (4 * np.pi)) ** 1.5)
        # the fastest node of the flow over the last step (absent at t* = 0 and in files
        # before 2026-12-05): how far from rest
        vmax = (f"{np.hypot(*g['velocity'][()].T).max():.3g}" if "velocity" in g else "—")
        shape.append((k, ts[k], steps[k], len(x), a["E"], a["c0"], vk, z.max() - z.min(), pc, P, N,
                      vmax))
    rows = sorted(set(np.linspace(0, nsnap - 1, min(nsnap, 16)).round().astype(int)))
    for k, tk, sk, n, Ek, ck, vk, L, pc, P, N, vmax in (shape[i] for i in rows):
        pr = ", ".join(f"{r:.3f}" for _, r in P[::-1])
        nr = ", ".join(f"{r:.3f}" for _, r in N[::-1])
        print(f"| {tk:.4g} | {sk} | {n} | {Ek:.3f} | {ck:.3f} | {vk:.4f} | {L:.3f} | {pc} | {len(P)} | "
              f"{pr} | {nr or '—'} | {vmax} |")
    # the remeshings
    print()
    if "remeshes" in f and int(f["remeshes"].attrs["count"]) > 0:
        print("| remeshing | step | t* | nodes | E* before -> projected -> corrected | dA/A | dV/V | "
              "correction max abs(delta)/h (its.) | A, V residual | interface moved max / mean | s |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for k in range(int(f["remeshes"].attrs["count"])):
            a = f[f"remeshes/{k}"].attrs
            s = int(a["step"])
            print(f"| {k + 1} | {s} | {t[s]:.4g} | {int(a['n_old'])} -> {int(a['n_new'])} | "
                  f"{a['E_old']:.4f} -> {a['E_proj']:.4f} -> {a['E']:.4f} | {a['dA']:.1e} | {a['dV']:.1e} | "
                  f"{a['corr_max']:.1e} ({int(a['corr_iter'])}) | {a['res_A']:.0e}, {a['res_V']:.0e} | "
                  f"{a['disp_max']:.1e} / {a['disp_mean']:.1e} | {a['seconds']:.1f} |")
    else:
        print("no remeshing")
    # the figure: nodes coloured by phi at nshot snapshots, E* (and C0 R0, v) against t*
    ramp = float(f["parameters"].attrs["protocol.c0_ramp_end"])
    if 0 < ramp < ts[-1] and nshot >= 4:  # three in the ramps, the rest after them
        want = np.concatenate([np.linspace(ts[0], ramp, 3), np.linspace(ramp, ts[-1], nshot - 2)[1:]])
    else:
        want = np.linspace(ts[0], ts[-1], nshot)
    pick = sorted(set(int(np.argmin(np.abs(ts - w))) for w in want))
    rlim, zlim = 0.0, 0.0
    for k in pick:
        g = f[f"snapshots/{k}"]
        x, phi = g["x"][()], g["phi"][()]
        np.savetxt(os.path.join(tmp, f"nodes_{k}.txt"),
                   np.column_stack([np.concatenate([x[:, 0], -x[:, 0]]), np.concatenate([x[:, 1], x[:, 1]]),
                                    np.concatenate([phi, phi])]), fmt="%.6g")
        with open(os.path.join(tmp, f"curve_{k}.txt"), "w") as o:  # its pieces apart by a blank line
            for piece in run.snapshots[k].interface:
                for r_, z_ in piece:
                    o.write(f"{r_:.6g} {z_:.6g}\n")
                o.write("\n")
                rlim = max(rlim, np.abs(piece[:, 0]).max())
                zlim = max(zlim, np.abs(piece[:, 1]).max())
    # the view: the curves and 0.3 R0 around them (the diffuse layer: ~2.7 eps at eps 0.08)
    rlim, zlim = np.ceil((rlim + 0.3) * 10) / 10, np.ceil((zlim + 0.3) * 10) / 10
    ev = np.column_stack([t, E, c0, v])
    np.savetxt(os.path.join(tmp, "series.txt"), ev)
    marks = []
    for i in range(1, len(recon)):
        if recon[i] > recon[i - 1]:
            marks.append(f"set arrow from {t[i]},graph 0 to {t[i]},graph 0.04 nohead lc rgb '#888888'")
    if "remeshes" in f:
        for k in range(int(f["remeshes"].attrs["count"])):
            s = int(f[f"remeshes/{k}"].attrs["step"])
            marks.append(f"set arrow from {t[s]},graph 0 to {t[s]},graph 1 nohead dt 2 lc rgb '#d62728'")
    os.makedirs(figdir, exist_ok=True)
    if ramp > 0:  # the C0 ramp of problems/pearling.ini: Fig. 6
        png = os.path.join(figdir, f"fig6_eps{eps:g}.png")
        par = f["parameters"].attrs
        what = (f"Fig. 6 at eps {eps}: v {float(par['shape.reduced_volume']):g} -> {v[-1]:.2f} at "
                f"constant area, C_0 R_0 {float(par['material.c0']):g} -> "
                f"{float(par['protocol.c0_ramp_to']):g}")
    else:  # any other run (e.g. problems/prolate_c0.ini, Fig. 5 right): named by its file
        png = os.path.join(figdir, f"{os.path.splitext(os.path.basename(path))[0]}_pearls.png")
        par = f["parameters"].attrs
        what = (f"eps {eps}, v {float(par['shape.reduced_volume']):g}: C_0 R_0 "
                f"{float(par['material.c0']):g} -> {float(par['protocol.c0_after']):g} "
                f"at t* {float(par['protocol.c0_time']):g}")
    # the shape panels side by side at equal scale, the last with the colour bar; below them the
    # series, its right axis fitted to C0 R0 and 10 v
    w = 0.92 / len(pick)
    y2max = 1.08 * max(np.nanmax(c0), np.nanmax(10 * v))
    g = ["set terminal pngcairo size 1600,1050 font ',11'", f"set output '{png}'",
         f"set multiplot title '{what} ({len(t)} steps)' . \"\\n\" . 'the nodes coloured by "
         "{/Symbol f}; black: {/Symbol f} = 0'",
         "set palette defined (-1 '#3060c0', 0 '#a0a0a0', 1 '#c03030'); set cbrange [-1:1]",
         "set cblabel '{/Symbol f} at the nodes'; set cbtics 0.5",
         "set size ratio -1; unset key; set tics font ',9'; set xlabel 'r / R_0'"]
    for j, k in enumerate(pick):
        last = j == len(pick) - 1
        g += [f"set origin {j * w},0.40; set size {w + (0.08 if last else 0)},0.54",
              "set colorbox" if last else "unset colorbox",
              "set ylabel 'z / R_0'" if j == 0 else "unset ylabel",
              f"set xrange [-{rlim}:{rlim}]; set yrange [-{zlim}:{zlim}]",
              f"set title 't* = {ts[k]:.3g}, C_0 R_0 = {st[k]['c0']:.2f}'",
              f"plot '{tmp}/nodes_{k}.txt' u 1:2:3 w p pt 7 ps 0.12 lc palette, "
              f"'{tmp}/curve_{k}.txt' u 1:2 w l lw 1.5 lc rgb 'black', "
              f"'{tmp}/curve_{k}.txt' u (-$1):2 w l lw 1.5 lc rgb 'black'"]
    g += ["unset colorbox; set size ratio 0; set tics font ',10'; set origin 0,0; set size 1,0.40",
          "unset title; set format x '%g'; set xlabel 't* = t k / ({/Symbol m} R_0^3)'",
          "set ylabel 'E* = E / k'",
          "set y2label 'C_0 R_0, 10 v'; set ytics nomirror; set y2tics",
          f"set xrange [{t[0]:.6g}:{t[-1]:.6g}]; set yrange [0:*]; set y2range [0:{y2max:.3g}]",
          "set key below horizontal"] + marks
    g.append(f"plot '{tmp}/series.txt' u 1:2 w l lw 2 lc rgb 'black' t 'E*', "
             f"'' u 1:3 axes x1y2 w l lw 1.5 lc rgb '#1f77b4' t 'C_0 R_0 (right axis)', "
             f"'' u 1:($4*10) axes x1y2 w l lw 1.5 lc rgb '#2ca02c' t '10 v (right axis)', "
             "NaN w l dt 2 lc rgb '#d62728' t 'remeshing', "
             "NaN w l lc rgb '#888888' t 'reset (tick at the bottom)'")
    g.append("unset multiplot")
    subprocess.run(["gnuplot"], input="\n".join(g) + "\n", text=True, check=True)
    print()
    print(f"figure: {png}")


if __name__ == "__main__":
    main()
