#!/usr/bin/python3
"""
vesica bench: how far a slowly creeping run is from rest (e.g. Fig. 5 right at eps 0.01).
Usage: /usr/bin/python3 bench/creep.py RUN.h5 [T_FROM] [T_WINDOW]
  RUN.h5    a run's file (read-only; HDF5_USE_FILE_LOCKING=FALSE lets it read a file a run
            still writes: the rows are flushed at every step)
  T_FROM    fit the rows with t* >= T_FROM (default: the last half of the run's t*)
  T_WINDOW  the window of the local rates (default 0.5)

Prints, from the file's /series (t*, E* = E/k):
  - the local rate -dE*/dt* over consecutive windows of T_WINDOW (a straight line fitted to the
    rows in each window), and the rate's decay time between windows;
  - the rest of the fall the last two windows imply (their rate times the rate's decay time);
  - the least-squares fit E*(t*) = E_inf + a exp(-(t* - t0)/tau) over the rows from t0 = T_FROM
    on, and from two later starts (1/3 and 1/2 of the way to the end): for each tau of a log
    grid E_inf and a are linear, the tau of the smallest residual is kept; the spread of E_inf
    over the starts says how well the tail pins it down.
The series' energy jumps at remeshings (|dE*| ~1e-2-1e-1 at eps 0.01) and the rows of retried
steps are in the data as they are: they show in the residual.
"""
import math
import sys

import h5py
import numpy as np


def fit_exp(t, e, tau):
    """E_inf, a and the rms residual of e = E_inf + a exp(-(t - t[0])/tau)."""
    A = np.vstack([np.ones_like(t), np.exp(-(t - t[0]) / tau)]).T
    (einf, a), *_ = np.linalg.lstsq(A, e, rcond=None)
    r = e - A @ np.array([einf, a])
    return einf, a, math.sqrt(float(np.mean(r * r)))


def main():
    if len(sys.argv) < 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        sys.exit(0 if len(sys.argv) > 1 else 2)
    with h5py.File(sys.argv[1], "r") as f:
        s = f["series"]
        t = np.array(s["t"][:], dtype=float)
        e = np.array(s["E"][:], dtype=float)
        k = float(f["parameters"].attrs["material.k"])
    e = e / k
    if t.size < 4:
        sys.exit(f"creep.py: {sys.argv[1]}: {t.size} rows, too few to fit")
    t_from = float(sys.argv[2]) if len(sys.argv) > 2 else 0.5 * t[-1]
    win = float(sys.argv[3]) if len(sys.argv) > 3 else 0.5
    print(f"{sys.argv[1]}: {t.size} rows, t* {t[0]:.4g} - {t[-1]:.4g}, E* {e[-1]:.6f} at the end")

    print(f"\nlocal rates (a line through the rows of each window of {win:g} t*, from the end back):")
    print("| t* window | rows | -dE*/dt* | decay time of the rate (t*) |")
    print("|---|---|---|---|")
    rows, hi = [], t[-1]
    while hi - win >= t[0] - 1e-12:
        m = (t >= hi - win) & (t <= hi)
        if m.sum() >= 3:
            rows.append((hi - win, hi, int(m.sum()), -np.polyfit(t[m], e[m], 1)[0]))
        hi -= win
    rows.reverse()
    prev, tau = None, None
    for lo, hi, n, rate in rows:
        tau = None  # the rate's decay time since the window before
        if prev and prev[1] > 0 and rate > 0 and rate < prev[1]:
            tau = (0.5 * (lo + hi) - prev[0]) / math.log(prev[1] / rate)
        print(f"| {lo:.3f} - {hi:.3f} | {n} | {rate:.4g} | {'—' if tau is None else f'{tau:.2f}'} |")
        prev = (0.5 * (lo + hi), rate)
    if tau is not None:  # the last window's rate, decaying as since the one before
        r = rows[-1][3]
        print(f"\nfrom the last two windows: the rate {r:.4g} decaying with tau {tau:.3g}, "
              f"E* still to fall {r * tau:.4f} (E_inf ~ {e[-1] - r * tau:.4f})")

    print("\nE*(t*) = E_inf + a exp(-(t* - t0)/tau), least squares over the rows from t0 on "
          "(later starts: how well the tail pins E_inf down):")
    print("| t0 | rows | tau | E_inf | a | rms residual | E* still to fall |")
    print("|---|---|---|---|---|---|---|")
    for frac in (0.0, 1.0 / 3.0, 0.5):
        t0 = t_from + frac * (t[-1] - t_from)
        m = t >= t0
        if m.sum() < 4:
            continue
        tt, ee = t[m], e[m]
        fits = [(tau,) + fit_exp(tt, ee, tau) for tau in np.geomspace(0.05, 50, 400)]
        tau, einf, a, res = min(fits, key=lambda r: r[3])
        edge = " (grid's end)" if tau in (fits[0][0], fits[-1][0]) else ""
        print(f"| {tt[0]:.3f} | {m.sum()} | {tau:.3g}{edge} | {einf:.4f} | {a:.4g} | {res:.2e} | "
              f"{e[-1] - einf:.4f} |")


if __name__ == "__main__":
    main()
