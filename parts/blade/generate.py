#!/usr/bin/env python3
"""Generates the five-axis blade contour (the predictive-compensation paper section 5: "a contour line of the blade" of an integral impeller,
compensated on a turning-milling centre with A and C; -31.43 % contour error after compensation).

The predictive-compensation paper gives neither the blade's section nor the tool, feed or tool orientation. The contour here is chosen once:

  Blade section: a NACA 4412 airfoil (camber m = 4 %, at p = 40 % of the chord, thickness t = 12 %), with the closed
  trailing edge of the 4-digit family's modified thickness law
      yt(x) = 5 t (0.2969 sqrt(x) - 0.1260 x - 0.3516 x^2 + 0.2843 x^3 - 0.1036 x^4)
      yc(x) = m / p^2 (2 p x - x^2)              (x < p)
            = m / (1 - p)^2 (1 - 2 p + 2 p x - x^2)  (x >= p)
  upper/lower surfaces (x -/+ yt sin th, yc +/- yt cos th), th = atan(yc'), scaled to a chord C = 40 mm, mid-chord on
  the C axis (workpiece X from -20 to +20 mm), as a vertical wall (an extruded blade) cut at the section height
  Z0 = 20 mm above the C table. Leading-edge radius 1.1019 t^2 C = 0.63 mm; the trailing edge is a sharp corner.

  Tool: ball-end D6 (R = 3 mm). The ball centre follows the section offset by R along the wall's outward normal n
  (horizontal; around the sharp trailing edge the offset is an arc of radius R about the edge, so the centre path and
  n are continuous). The tool axis u leans away from the wall by the tilt phi(s):
      u = (sin phi n_x, sin phi n_y, cos phi),   phi(s) = PHI_MEAN - PHI_AMP cos(2 pi s / L)
  (s: arc length of the centre path from the start, L its length; phi 15 deg at the start, 35 deg half way round).
  Tool tip = centre - R u (the CL point), contact point = centre - R n on the wall at Z0.

  On the Mikron UCP 710 (A tilting table carrying C) the tool axis u is reached with |A| = phi (15 to 35 deg) and the C
  table turning once as n turns once round the section: C turns fastest round the leading edge (180 deg over about
  11 mm of centre path) and the trailing-edge arc (about 165 deg over 9 mm).

  Path: one turn counter-clockwise seen from +Z, starting and ending on the upper surface at mid-chord, program points
  chosen so that the CL polyline stays within CHORD_TOL of the exact tip curve and the tool axis turns at most
  MAX_TURN_DEG between points; F = FEED (tip speed). A rapid to APPROACH mm above the first point along u, a feed move
  in, the contour, a feed move out along u.

Files written (checked in; rerun this script after changing a constant):
  blade_section.cl   the APT CL program (GOTO/x,y,z,i,j,k: tool tip and tool axis, workpiece frame, mm)
"""
import math
import os

CHORD = 40.0                 # mm
M, P, T = 0.04, 0.40, 0.12   # NACA 4412
Z0 = 20.0                    # section height above the C table, mm
R = 3.0                      # ball radius (D6), mm
PHI_MEAN, PHI_AMP = 25.0, 10.0   # tilt, deg
FEED = 1500.0                # mm/min
APPROACH = 20.0              # mm along the tool axis
CHORD_TOL = 0.0005           # mm: the CL polyline's largest distance from the exact tip curve
MAX_TURN_DEG = 1.0           # deg of tool axis between program points
N_SIDE = 6000                # dense samples per surface (cosine spacing)
N_ARC = 400                  # dense samples on the trailing-edge arc


def surfaces(beta):
    x = 0.5 * (1.0 - math.cos(beta))
    yt = 5 * T * (0.2969 * math.sqrt(x) - 0.1260 * x - 0.3516 * x ** 2 + 0.2843 * x ** 3 - 0.1036 * x ** 4)
    if x < P:
        yc, dyc = M / P ** 2 * (2 * P * x - x * x), 2 * M / P ** 2 * (P - x)
    else:
        yc, dyc = M / (1 - P) ** 2 * (1 - 2 * P + 2 * P * x - x * x), 2 * M / (1 - P) ** 2 * (P - x)
    th = math.atan(dyc)
    up = (x - yt * math.sin(th), yc + yt * math.cos(th))
    lo = (x + yt * math.sin(th), yc - yt * math.cos(th))
    return up, lo


def section():
    """The airfoil counter-clockwise from the trailing edge: upper surface to the leading edge, lower surface back."""
    pts = []
    for i in range(N_SIDE + 1):                       # upper: x from 1 to 0
        up, _ = surfaces(math.pi * (1.0 - i / N_SIDE))
        pts.append(up)
    for i in range(1, N_SIDE + 1):                    # lower: x from 0 to 1
        _, lo = surfaces(math.pi * i / N_SIDE)
        pts.append(lo)
    return [(CHORD * (x - 0.5), CHORD * y) for x, y in pts]


def normal(a, b):
    tx, ty = b[0] - a[0], b[1] - a[1]
    l = math.hypot(tx, ty)
    return (ty / l, -tx / l)                          # outward for a counter-clockwise curve


def centre_path():
    """Dense ball-centre path (x, y, nx, ny): the section offset by R, an arc of radius R round the trailing edge."""
    s = section()
    n = len(s)
    out = []
    for i in range(n - 1):                            # the last point repeats the trailing edge
        if i == 0:
            nn = normal(s[0], s[1])
        elif i == n - 2:
            nn = normal(s[n - 3], s[n - 2])
        else:
            nn = normal(s[i - 1], s[i + 1])
        out.append((s[i][0] + R * nn[0], s[i][1] + R * nn[1], nn[0], nn[1]))
    # the trailing-edge arc: from the lower surface's last normal to the upper surface's first, counter-clockwise
    n_lo = normal(s[n - 2], s[n - 1])
    n_up = normal(s[0], s[1])
    a0, a1 = math.atan2(n_lo[1], n_lo[0]), math.atan2(n_up[1], n_up[0])
    while a1 <= a0:
        a1 += 2 * math.pi
    te = s[0]
    for k in range(N_ARC + 1):
        a = a0 + (a1 - a0) * k / N_ARC
        out.append((te[0] + R * math.cos(a), te[1] + R * math.sin(a), math.cos(a), math.sin(a)))
    # start at mid-chord on the upper surface (x = 0, y > 0)
    k0 = min(range(N_SIDE), key=lambda k: abs(out[k][0]))
    loop = out[k0:] + out[:k0]
    loop.append(loop[0])
    return loop


def poses(loop):
    """Tip, tool axis and arc length along the centre path for every dense point."""
    s = [0.0]
    for i in range(1, len(loop)):
        s.append(s[-1] + math.hypot(loop[i][0] - loop[i - 1][0], loop[i][1] - loop[i - 1][1]))
    L = s[-1]
    out = []
    for (cx, cy, nx, ny), si in zip(loop, s):
        phi = math.radians(PHI_MEAN - PHI_AMP * math.cos(2 * math.pi * si / L))
        u = (math.sin(phi) * nx, math.sin(phi) * ny, math.cos(phi))
        tip = (cx - R * u[0], cy - R * u[1], Z0 - R * u[2])
        out.append((tip, u))
    return out, L


def dist_to_chord(p, a, b):
    ab = [b[i] - a[i] for i in range(3)]
    ap = [p[i] - a[i] for i in range(3)]
    l2 = sum(c * c for c in ab)
    t = 0.0 if l2 == 0 else max(0.0, min(1.0, sum(ab[i] * ap[i] for i in range(3)) / l2))
    return math.sqrt(sum((ap[i] - t * ab[i]) ** 2 for i in range(3)))


def angle_deg(u, v):
    return math.degrees(math.acos(max(-1.0, min(1.0, sum(u[i] * v[i] for i in range(3))))))


def program_points(dense):
    """Greedy: from each program point, the farthest dense point whose chord keeps every dense point in between within
    CHORD_TOL and the tool axis within MAX_TURN_DEG."""
    idx = [0]
    i = 0
    n = len(dense)
    while i < n - 1:
        j = i + 1
        while j + 1 < n:
            k = j + 1
            if angle_deg(dense[i][1], dense[k][1]) > MAX_TURN_DEG:
                break
            if any(dist_to_chord(dense[m][0], dense[i][0], dense[k][0]) > CHORD_TOL for m in range(i + 1, k)):
                break
            j = k
        idx.append(j)
        i = j
    return [dense[k] for k in idx]


def fmt(v):
    return ",".join(f"{c:.6f}" for c in v)


def main():
    dense, L = poses(centre_path())
    pts = program_points(dense)
    tip_len = sum(math.dist(pts[i][0], pts[i - 1][0]) for i in range(1, len(pts)))
    here = os.path.dirname(os.path.abspath(__file__))
    first, last = pts[0], pts[-1]
    lines = [
        "PARTNO/BLADE_SECTION_NACA4412",
        "$$ vmsim parts/blade/generate.py: NACA 4412 section, chord 40 mm, at Z 20 mm, ball-end D6 on the wall offset,",
        f"$$ tool axis tilted {PHI_MEAN - PHI_AMP:.0f}..{PHI_MEAN + PHI_AMP:.0f} deg away from the wall, "
        f"{len(pts) - 1} CL moves, {tip_len:.3f} mm of tip path (centre path {L:.3f} mm), F{FEED:.0f} mm/min",
        "UNITS/MM",
        "MULTAX/ON",
        f"CUTTER/{2 * R:.6f},{R:.6f}",
        "RAPID",
        "GOTO/" + fmt(tuple(first[0][i] + APPROACH * first[1][i] for i in range(3))) + "," + fmt(first[1]),
        f"FEDRAT/MMPM,{FEED:.1f}",
    ]
    for tip, u in pts:
        lines.append("GOTO/" + fmt(tip) + "," + fmt(u))
    lines.append("GOTO/" + fmt(tuple(last[0][i] + APPROACH * last[1][i] for i in range(3))) + "," + fmt(last[1]))
    lines.append("FINI")
    with open(os.path.join(here, "blade_section.cl"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print(f"blade_section.cl: {len(pts) - 1} CL moves, tip path {tip_len:.3f} mm, centre path {L:.3f} mm")


if __name__ == "__main__":
    main()
