#!/usr/bin/env python3
"""Generates the five-axis test part's program (the feed-drive simulation paper section 4, third case: a 5-axis path with large A and C motion).

The feed-drive simulation paper gives no geometry for its third case: "a 5-axis trajectory which involves the rotational axes with large
displacements", on the Mikron UCP 710 (A tilting table carrying a C rotary table), where only the follow-up of the
rotary axes is considered and the measured and simulated axis deviations are about 0.001 deg. The part here is a
path of that kind with a closed-form surface, so the simulated cut can be checked against geometry written elsewhere:

  A spherical dome, centre at the workpiece zero (on the C table's surface, on the C axis), radius RS = 30 mm,
  finished by a ball-end D10 whose axis is held along the sphere's outward normal (the tool tip then touches the
  sphere: tip = contact point, ball centre = tip + R n). The path is a spiral on the sphere, from the polar angle
  THETA0 = 5 deg to THETA1 = 50 deg in TURNS = 15 turns (stepover 3 deg of latitude = 1.57 mm on the sphere per turn),
  points every DPHI = 1 deg of azimuth, at F = 5000 mm/min. On the Mikron the tool axis at polar angle theta and
  azimuth phi is reached with |A| = theta and C turning one full turn per turn of the spiral: A moves through 45 deg,
  C through 15 x 360 = 5400 deg; the C table's speed limit (120 deg/s) sets the feed near the top.

  The scallop between two turns (ball centres on the sphere of radius D = RS + R, dtheta apart): the cusp lies on
  the bisector at rho = D cos(dtheta/2) - sqrt(R^2 - D^2 sin^2(dtheta/2)) from the centre, i.e. rho - RS = 0.073 mm
  above the sphere for dtheta = 3 deg (README.md).

The program is an APT CL file (GOTO/x,y,z,i,j,k: tool tip and tool axis in the workpiece frame, mm), read through the
machine's inverse transform. The approach: a rapid to 20 mm above the first point along its normal, a feed move in.

The stock is the semi-finished dome: the sphere of radius RS + ALLOWANCE (0.05 mm of finishing allowance, as the feed-drive simulation paper's
first part) above the plane z = STOCK_Z0, a closed triangle mesh (facets every STOCK_DTHETA deg of polar angle
and STOCK_DPHI deg of azimuth, vertices on that sphere: the facets lie at most 7 um inside it).

Files written (checked in; rerun this script after changing a constant):
  dome_spiral.cl   the spiral
  dome_stock.stl   the stock (binary STL)
"""
import math
import os
import struct

RS = 30.0            # sphere radius, mm (centre at the workpiece zero)
R = 5.0              # ball radius (D10)
THETA0, THETA1 = 10.0, 40.0   # polar angle range, deg
TURNS = 10
DPHI = 1.0           # deg of azimuth between points
FEED = 5000.0        # mm/min
APPROACH = 20.0      # mm along the normal
ALLOWANCE = 0.05     # mm of stock over the sphere
STOCK_Z0 = 18.0      # the stock's flat bottom
STOCK_DTHETA, STOCK_DPHI = 2.0, 3.0


def point(theta_deg, phi_deg):
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    n = (math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t))
    return tuple(RS * c for c in n), n


def fmt(v):
    return ",".join(f"{c:.6f}" for c in v)


def write_stock(path):
    rs = RS + ALLOWANCE
    tmax = math.degrees(math.acos(STOCK_Z0 / rs))
    nt = int(math.ceil(tmax / STOCK_DTHETA))
    npf = int(round(360.0 / STOCK_DPHI))

    def v(ti, pj):
        if ti == 0:
            return (0.0, 0.0, rs)
        t = math.radians(min(ti * STOCK_DTHETA, tmax))
        p = math.radians((pj % npf) * STOCK_DPHI)
        return (rs * math.sin(t) * math.cos(p), rs * math.sin(t) * math.sin(p), rs * math.cos(t))

    tris = []
    for j in range(npf):  # pole fan, counter-clockwise seen from outside (+z)
        tris.append((v(0, 0), v(1, j), v(1, j + 1)))
    for i in range(1, nt):
        for j in range(npf):
            a, b, c, d = v(i, j), v(i, j + 1), v(i + 1, j), v(i + 1, j + 1)
            tris.append((a, c, d))
            tris.append((a, d, b))
    bottom = (0.0, 0.0, v(nt, 0)[2])
    for j in range(npf):  # flat bottom, facing -z
        tris.append((bottom, v(nt, j + 1), v(nt, j)))
    with open(path, "wb") as f:
        f.write(b"vmsim parts/five_axis/generate.py: dome stock".ljust(80, b" "))
        f.write(struct.pack("<I", len(tris)))
        for t in tris:
            ux, uy, uz = (t[1][k] - t[0][k] for k in range(3))
            wx, wy, wz = (t[2][k] - t[0][k] for k in range(3))
            n = (uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx)
            ln = math.sqrt(sum(c * c for c in n)) or 1.0
            f.write(struct.pack("<3f", *(c / ln for c in n)))
            for p in t:
                f.write(struct.pack("<3f", *p))
            f.write(b"\0\0")


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    steps = int(round(TURNS * 360.0 / DPHI))
    lines = [
        "PARTNO/FIVE_AXIS_DOME_SPIRAL",
        "$$ vmsim parts/five_axis/generate.py: spherical dome RS 30 mm, ball-end D10 along the normal,",
        f"$$ spiral theta {THETA0:g}..{THETA1:g} deg in {TURNS} turns, {DPHI:g} deg steps, F{FEED:g} mm/min",
        "UNITS/MM",
        "MULTAX/ON",
        "CUTTER/10.000000,5.000000",
    ]
    p, n = point(THETA0, 0.0)
    lines.append("RAPID")
    lines.append("GOTO/" + fmt(tuple(p[i] + APPROACH * n[i] for i in range(3))) + "," + fmt(n))
    lines.append(f"FEDRAT/MMPM,{FEED:.1f}")
    for k in range(steps + 1):
        phi = k * DPHI
        theta = THETA0 + (THETA1 - THETA0) * k / steps
        p, n = point(theta, phi)
        lines.append("GOTO/" + fmt(p) + "," + fmt(n))
    p, n = point(THETA1, steps * DPHI)
    lines.append("GOTO/" + fmt(tuple(p[i] + APPROACH * n[i] for i in range(3))) + "," + fmt(n))
    lines.append("FINI")
    with open(os.path.join(here, "dome_spiral.cl"), "w") as f:
        f.write("\n".join(lines) + "\n")
    write_stock(os.path.join(here, "dome_stock.stl"))
    write_slow_ring(os.path.join(here, "dome_ring_slow.cl"))


# The paper's own case for its 0.001 deg (job_slow.toml): the rotary table turning slowly. A type-1 position loop
# lags a ramp of w deg/s by w ((1 - KF) / Kv + Te) = w x 0.010 s on the Mikron's C drive, so 0.001 deg is C at about
# 0.1 deg/s: an arc of SLOW_DPHI deg of azimuth at the polar angle SLOW_THETA (A fixed), fed at SLOW_FEED, with the
# approach and retract along the normal at SLOW_APPROACH_FEED.
SLOW_THETA = 40.0        # deg: the spiral's outer turn (tip 19.3 mm from the C axis)
SLOW_PHI0, SLOW_DPHI = 0.0, 10.0
SLOW_STEP = 0.5          # deg of azimuth between points
SLOW_FEED = 2.0          # mm/min: C at 2 / (RS sin 40 deg) rad/min = 0.099 deg/s
SLOW_APPROACH_FEED = 500.0


def write_slow_ring(path):
    lines = [
        "PARTNO/FIVE_AXIS_DOME_SLOW_RING",
        "$$ vmsim parts/five_axis/generate.py: spherical dome RS 30 mm, ball-end D10 along the normal,",
        f"$$ arc at theta {SLOW_THETA:g} deg, phi {SLOW_PHI0:g}..{SLOW_PHI0 + SLOW_DPHI:g} deg, F{SLOW_FEED:g} mm/min "
        "(C at about 0.1 deg/s)",
        "UNITS/MM",
        "MULTAX/ON",
        "CUTTER/10.000000,5.000000",
    ]
    p, n = point(SLOW_THETA, SLOW_PHI0)
    lines.append("RAPID")
    lines.append("GOTO/" + fmt(tuple(p[i] + APPROACH * n[i] for i in range(3))) + "," + fmt(n))
    lines.append(f"FEDRAT/MMPM,{SLOW_APPROACH_FEED:.1f}")
    lines.append("GOTO/" + fmt(p) + "," + fmt(n))
    lines.append(f"FEDRAT/MMPM,{SLOW_FEED:.1f}")
    steps = int(round(SLOW_DPHI / SLOW_STEP))
    for k in range(1, steps + 1):
        p, n = point(SLOW_THETA, SLOW_PHI0 + k * SLOW_STEP)
        lines.append("GOTO/" + fmt(p) + "," + fmt(n))
    lines.append(f"FEDRAT/MMPM,{SLOW_APPROACH_FEED:.1f}")
    lines.append("GOTO/" + fmt(tuple(p[i] + APPROACH * n[i] for i in range(3))) + "," + fmt(n))
    lines.append("FINI")
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
