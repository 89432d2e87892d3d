#!/usr/bin/env python3
"""Writes the second test curve of the feed-planning part: the fan-shaped contour as a cubic NURBS.

Source: ../../../shared/data/curves/fan_shape_2d_waypoints.csv (89 waypoints, closed, from
github cgmannes/2-dimensional-trajectory-planning spline_toolpath.m, commit 5574aa0), whose original use is a closed
C2 cubic spline through the waypoints, chord-length parametrised. This script builds exactly that spline (periodic
second-derivative system, solved by Gaussian elimination) and writes it as a degree-3 NURBS: each spline segment is
a cubic Bezier (control points P_i, P_i + h_i D_i / 3, P_{i+1} - h_i D_{i+1} / 3, P_{i+1}), the interior knots have
multiplicity 3 (the B-spline form of a piecewise Bezier curve; the curve stays C2 because the spline is), all weights
1, knots normalised to [0, 1]. Four lobes, each with two tight turns (radii down to about 1 mm) between straighter
flanks: several high-curvature zones, as Chen et al. 2016 asks of its examples.

Usage: python3 generate.py [WAYPOINTS_CSV]   (writes fan_nurbs_control_points.csv, fan_nurbs_knots.csv here)
"""
import math
import os
import sys

here = os.path.dirname(os.path.abspath(__file__))
src = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "../../../shared/data/curves/fan_shape_2d_waypoints.csv")

pts = []
for line in open(src):
    line = line.strip()
    if not line or line.startswith("#") or line.startswith("index"):
        continue
    _, x, y = line.split(",")
    pts.append((float(x), float(y)))
if pts[0] == pts[-1]:
    pts = pts[:-1]  # closed: the last waypoint repeats the first
n = len(pts)
h = [math.dist(pts[i], pts[(i + 1) % n]) for i in range(n)]


def solve(a, b):
    """Dense Gaussian elimination with partial pivoting."""
    m = len(b)
    a = [row[:] + [b[i]] for i, row in enumerate(a)]
    for c in range(m):
        p = max(range(c, m), key=lambda r: abs(a[r][c]))
        a[c], a[p] = a[p], a[c]
        for r in range(c + 1, m):
            f = a[r][c] / a[c][c]
            if f:
                for k in range(c, m + 1):
                    a[r][k] -= f * a[c][k]
    x = [0.0] * m
    for r in range(m - 1, -1, -1):
        x[r] = (a[r][m] - sum(a[r][k] * x[k] for k in range(r + 1, m))) / a[r][r]
    return x


# Periodic cubic spline: h_{i-1} M_{i-1} + 2 (h_{i-1} + h_i) M_i + h_i M_{i+1} = 6 (slope_i - slope_{i-1}).
A = [[0.0] * n for _ in range(n)]
for i in range(n):
    A[i][(i - 1) % n] += h[i - 1]
    A[i][i] += 2 * (h[i - 1] + h[i])
    A[i][(i + 1) % n] += h[i]
M = []
for d in range(2):
    slope = [(pts[(i + 1) % n][d] - pts[i][d]) / h[i] for i in range(n)]
    M.append(solve(A, [6 * (slope[i] - slope[i - 1]) for i in range(n)]))

cps = []
for i in range(n):
    j = (i + 1) % n
    p0, p1 = pts[i], pts[j]
    d0 = [(p1[d] - p0[d]) / h[i] - h[i] * (2 * M[d][i] + M[d][j]) / 6 for d in range(2)]
    d1 = [(p1[d] - p0[d]) / h[i] + h[i] * (M[d][i] + 2 * M[d][j]) / 6 for d in range(2)]
    if i == 0:
        cps.append(p0)
    cps.append(tuple(p0[d] + h[i] * d0[d] / 3 for d in range(2)))
    cps.append(tuple(p1[d] - h[i] * d1[d] / 3 for d in range(2)))
    cps.append(p1)
total = sum(h)
t = [0.0]
for i in range(n):
    t.append(t[-1] + h[i])
knots = [0.0] * 4 + [x / total for x in t[1:-1] for _ in range(3)] + [1.0] * 4
assert len(knots) == len(cps) + 4

head = ("# Fan-shaped contour as a cubic NURBS (degree 3, {} control points, weights 1): the closed C2 cubic spline\n"
        "# through the {} waypoints of ../../../shared/data/curves/fan_shape_2d_waypoints.csv (github\n"
        "# cgmannes/2-dimensional-trajectory-planning, commit 5574aa0), chord-length parametrised; written by generate.py; mm\n")
with open(os.path.join(here, "fan_nurbs_control_points.csv"), "w") as f:
    f.write(head.format(len(cps), n))
    f.write("index,x,y,z,weight\n")
    for i, (x, y) in enumerate(cps):
        f.write(f"{i},{x:.9f},{y:.9f},0.000,1\n")
with open(os.path.join(here, "fan_nurbs_knots.csv"), "w") as f:
    f.write(head.format(len(cps), n).replace("cubic NURBS", "cubic NURBS knot vector", 1))
    f.write("index,knot\n")
    for i, k in enumerate(knots):
        f.write(f"{i},{k:.12f}\n")
print(f"{len(cps)} control points, {len(knots)} knots, chord length through the waypoints {total:.4f} mm")
