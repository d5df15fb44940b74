#!/usr/bin/env python3
"""Writes data/cup.txt: the generating curve of a cup (stomatocyte-like) vesicle,
the boundary of the set within distance w of a circular arc of radius rho about
the origin from the north pole to polar angle tm: outer arc, rounded rim,
inner arc, ending on the axis at (0, rho - w). Points from the north pole to the
south pole, R >= 0; vesica scales the curve to area 4 pi.
Usage: python3 data/make_cup.py [rho w tm] > data/cup.txt"""
import math, sys
rho, w, tm = (float(a) for a in sys.argv[1:4]) if len(sys.argv) > 3 else (1.0, 0.34, 2.3)
pts = []
n = 120
for k in range(n + 1):                      # outer arc, north pole -> rim
    t = tm * k / n
    pts.append(((rho + w) * math.sin(t), (rho + w) * math.cos(t)))
C = (rho * math.sin(tm), rho * math.cos(tm))
for k in range(1, 40):                      # rim: half circle of radius w about C
    a = tm + math.pi * k / 40               # direction angle measured like t
    pts.append((C[0] + w * math.sin(a), C[1] + w * math.cos(a)))
for k in range(n, -1, -1):                  # inner arc, rim -> axis
    t = tm * k / n
    pts.append(((rho - w) * math.sin(t), (rho - w) * math.cos(t)))
pts[0] = (0.0, pts[0][1]); pts[-1] = (0.0, pts[-1][1])
# sharp area and volume (polygon of revolution) for the header
A = V = 0.0
for (r0, z0), (r1, z1) in zip(pts, pts[1:]):
    l = math.hypot(r1 - r0, z1 - z0)
    A += math.pi * (r0 + r1) * l
    V += math.pi * (r0 * r0 + r0 * r1 + r1 * r1) / 3 * (z0 - z1)
R0 = math.sqrt(A / (4 * math.pi))
print(f"# cup: rho = {rho}, w = {w}, tm = {tm}; reduced volume ~ {V / (4 * math.pi / 3 * R0**3):.4f}")
for r, z in pts:
    print(f"{r:.12f} {z:.12f}")
