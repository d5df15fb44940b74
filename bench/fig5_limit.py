#!/usr/bin/python3
"""
vesica bench: sharp-interface energies of the limit shapes of Fig. 5 right: which end
state does the spontaneous-curvature model prefer at the paper's C0 R0 = 10, v = 0.8?
Usage: /usr/bin/python3 bench/fig5_limit.py [C0] [v]        (defaults 10 and 0.8; no dependencies)

Normalization (docs/design.md, "The model"): E* = (1/2) int (H - C0)^2 dA, H = (c1 + c2)/2, lengths in R0, so
A = 4 pi and V = v 4 pi/3. A sphere of radius R: E* = 2 pi (1 - C0 R)^2 (zero at R = 1/C0); a
cylinder of radius rho: E* per unit length pi rho (1/(2 rho) - C0)^2 (zero at rho = 1/(2 C0)).

Shapes compared, each holding A and V exactly; necks are ideal (zero area and energy) and the tube's
end caps are left out (together a sphere of radius rho: E* 2 pi (1 - C0 rho)^2 = pi/2 at
rho = 1/(2 C0), small beside the differences below):
  - two spheres r1 >= r2 joined by a neck (the paper's description of its end state);
  - a sphere with a cylindrical tube of radius rho (the tethers of our runs at eps 0.04 / 0.02);
  - a sphere with N small spheres of radius 1/C0 (zero energy each) holding the excess area.
"""
import math
import sys


def bisect(f, a, b, n=200):
    fa = f(a)
    for _ in range(n):
        m = 0.5 * (a + b)
        fm = f(m)
        if (fm > 0) == (fa > 0):
            a, fa = m, fm
        else:
            b = m
    return 0.5 * (a + b)


def main():
    c0 = float(sys.argv[1]) if len(sys.argv) > 1 else 10.0
    v = float(sys.argv[2]) if len(sys.argv) > 2 else 0.8
    sphere = lambda r: 2 * math.pi * (1 - c0 * r) ** 2
    print(f"C0 R0 = {c0:g}, v = {v:g}, A = 4 pi (E* = (1/2) int (H - C0)^2 dA)")
    print("| shape | radii | E* |")
    print("|---|---|---|")
    # two spheres: r1^2 + r2^2 = 1, r1^3 + r2^3 = v (r2 <= 1/sqrt 2 <= r1)
    r2 = bisect(lambda r: (1 - r * r) ** 1.5 + r ** 3 - v, 1e-9, 1 / math.sqrt(2))
    r1 = math.sqrt(1 - r2 * r2)
    print(f"| two spheres + neck | {r1:.4f}, {r2:.4f} | {sphere(r1) + sphere(r2):.2f} "
          f"({sphere(r1):.2f} + {sphere(r2):.2f}) |")
    # sphere R + tube (rho, L): R^2 + rho L / 2 = 1, R^3 + (3/4) rho^2 L = v
    for rho in sorted({0.5 / c0, 0.07, 0.1, 0.2}):
        R = bisect(lambda R: R ** 3 + 1.5 * rho * (1 - R * R) - v, 0.5, 1.0)
        L = 2 * (1 - R * R) / rho
        tube = math.pi * rho * L * (0.5 / rho - c0) ** 2
        print(f"| sphere + tube rho {rho:.3g}, length {L:.2f} | {R:.4f} | {sphere(R) + tube:.2f} "
              f"({sphere(R):.2f} + {tube:.2f}) |")
    # sphere R + N spheres of radius s = 1/C0: R^2 + N s^2 = 1, R^3 + N s^3 = v
    s = 1 / c0
    R = bisect(lambda R: R ** 3 + (1 - R * R) * s - v, 0.5, 1.0)
    n = (1 - R * R) / (s * s)
    print(f"| sphere + {n:.1f} spheres of radius {s:.3g} | {R:.4f} | {sphere(R):.2f} |")


if __name__ == "__main__":
    main()
