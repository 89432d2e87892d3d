#!/usr/bin/env python3
"""Generates the corner test part's programs, stock and needles (the feed-drive simulation paper, section 4, second test part, Fig. 7).

The feed-drive simulation paper: "the finishing by flank milling of a vertical corner with a cylindrical tool which diameter is 10mm. The
reference is machined in one tool path with an axial depth of cut of 10mm and a low feedrate. Then the same tool
path is translated of about 5mm along the Z axis, and is re executed with the high feedrate; the axial depth of cut
is thus of 5mm." Section 4 calls it "the flank milling of a sharp corner using the X and Y axes". The seed gives no
dimensions; these are chosen here (README.md says why, and why the corner is an outside one).

Geometry (all mm, workpiece frame, Z up): the corner of a block, x in [-WALL_LENGTH, 0], y in [-WALL_LENGTH, 0],
z in [BOTTOM, TOP]. Its two finished vertical walls
  W2: plane x = 0 (outward normal +X), y in [-WALL_LENGTH, 0]
  W1: plane y = 0 (outward normal +Y), x in [-WALL_LENGTH, 0]
meet at the sharp vertical edge x = y = 0 (a 90 deg outside corner: the only vertical corner a cylindrical tool
can leave sharp).

Toolpath (flat-end mill D10, axis vertical, programmed point = tool tip with G43 H1): one contour pass around the
edge, the tool centre R_TOOL from the walls
  start (R_TOOL, -START) beside the block -> along W2 in +Y to (R_TOOL, 0) -> G3 arc of radius R_TOOL about the
  edge to (0, R_TOOL) (the tool rolls around the edge, touching it all the way) -> along W1 in -X to (-START, R_TOOL).
With the spindle turning clockwise (M3) the material is on the tool's left: climb milling, as finishing is done.
The path is tangent-continuous; its curvature jumps from 0 to 1/R_TOOL and back at the two ends of the arc, and on
the arc the X and Y axes turn through a quarter circle: there the interpolator rounds the path and the drives lag
inwards, into the edge.

Files written (checked in; rerun this script after changing a constant):
  corner_reference.ngc   the pass with the tip at Z_REFERENCE (axial depth 10 mm) at FEED_LOW: the reference
  corner_fast.ngc        the same pass translated Z_SHIFT up (tip at Z_REFERENCE + Z_SHIFT, axial depth 5 mm)
                         at FEED_HIGH
  corner_stock.stl       the semi-finished block: the finished corner offset ALLOWANCE outward (walls at
                         x = ALLOWANCE and y = ALLOWANCE, the edge rounded to radius ALLOWANCE), a closed solid
  corner_needles.csv     N-buffer needles: points on the two nominal walls at NEEDLE_Z levels, every NEEDLE_STEP
                         from the edge, with the walls' outward unit normals (horizontal needles)
"""
import math
import os

R_TOOL = 5.0            # flat-end (cylindrical) mill of diameter 10 mm (the feed-drive simulation paper)
WALL_LENGTH = 60.0      # length of each wall from the edge: the Y axis needs ~22 mm to reach 10 m/min with the
                        # Mikron's 10 m/s^3 jerk and as much to slow down for the arc, so the pass runs at its feed
                        # along W2 before the corner
TOP = 0.0               # top face of the block
BOTTOM = -15.0          # bottom face of the block (below the reference pass: the tool never touches a floor)
Z_REFERENCE = -10.0     # tip of the reference pass: axial depth of cut TOP - Z_REFERENCE = 10 mm (the feed-drive simulation paper)
Z_SHIFT = 5.0           # the high-feed pass is the same path this much higher: axial depth 5 mm (the feed-drive simulation paper)
CLEARANCE = 10.0        # the pass starts and ends with the tool this far clear of the block's far faces
START = WALL_LENGTH + R_TOOL + CLEARANCE   # distance of the start (and end) from the edge along the walls
SAFE_Z = 20.0           # retract height
APPROACH = 2.0          # rapid down to this above the cutting height, then feed down (beside the block)
FEED_LOW = 100.0        # mm/min = 0.1 m/min: the reference (the feed-drive simulation paper's low feed of the first part)
FEED_HIGH = 10000.0     # mm/min = 10 m/min: the high feed (the feed-drive simulation paper's high feed of the first part)
FEED_PLUNGE_HIGH = 1000.0  # mm/min: plunge of the high-feed program, beside the block
ALLOWANCE = 0.2         # radial finishing allowance left by semi-finishing on the walls (README: why 0.2)
ARC_SAGITTA = 1e-4      # largest distance between the stock's facets and its rounded edge (mm)
NEEDLE_STEP = 0.05      # needle spacing along each wall, the first one this far from the edge (mm)
NEEDLE_Z = [-9.0, -7.5, -6.0, -4.0, -2.5, -1.0]  # needle levels: 3 in [-10, -5] (reference pass only), 3 in
                                                # [-5, 0] (reference, then the high-feed pass), clear of the bands'
                                                # edges (the walls are vertical: the levels of a band agree)

HERE = os.path.dirname(os.path.abspath(__file__))


def write_text(name, text):
    path = os.path.join(HERE, name)
    with open(path + ".tmp", "w") as f:
        f.write(text)
    os.replace(path + ".tmp", path)


def program(title, z_tip, feed, plunge_feed):
    r = R_TOOL
    lines = [
        f"( {title} )",
        "( generated by parts/corner/generate.py - edit the generator, not this file )",
        "( part: outside corner of walls x=0 and y=0, sharp edge at X0 Y0, flank-milled by a flat-end D%g; tip at Z%g )"
        % (2 * r, z_tip),
        "G21 G90 G94 G17 G40 G49",
        "T1 M6",
        "G43 H1",
        "S18000 M3",
        f"G0 X{r:.4f} Y{-START:.4f} Z{SAFE_Z:.4f}",
        f"G0 Z{z_tip + APPROACH:.4f}",
        f"G1 Z{z_tip:.4f} F{plunge_feed:.1f}",
        f"G1 Y0.0000 F{feed:.1f}     ( along wall x=0 in +Y )",
        f"G3 X0.0000 Y{r:.4f} I{-r:.4f} J0.0000     ( around the edge )",
        f"G1 X{-START:.4f}     ( along wall y=0 in -X )",
        f"G0 Z{SAFE_Z:.4f}",
        "M5",
        "M30",
    ]
    return "\n".join(lines) + "\n"


def stock_profile():
    """The semi-finished block's outline seen from +Z, counter-clockwise (material on the left): the corner's walls
    offset ALLOWANCE outward, the edge rounded to radius ALLOWANCE about x = y = 0."""
    a, e = ALLOWANCE, WALL_LENGTH
    pts = [(-e, -e), (a, -e)]
    n = max(2, int(math.ceil((math.pi / 2) / (2 * math.acos(1 - ARC_SAGITTA / a)))))
    pts += [(a * math.cos(math.pi / 2 * k / n), a * math.sin(math.pi / 2 * k / n)) for k in range(n + 1)]
    pts += [(-e, a)]
    return pts


def write_stock_stl(name):
    """Closed, outward-facing triangles: the prism over the profile from BOTTOM to TOP. The caps are fans from a
    point off every regular grid (the convex profile is star-shaped about it) so that no dexel ray runs through
    the vertex the fan's triangles share."""
    prof = stock_profile()
    c = (-WALL_LENGTH / 2 + 0.3183098861837907, -WALL_LENGTH / 2 + 0.2718281828459045)
    tris = []
    n = len(prof)
    for k in range(n):
        (xa, ya), (xb, yb) = prof[k], prof[(k + 1) % n]
        tris.append(((xa, ya, BOTTOM), (xb, yb, BOTTOM), (xb, yb, TOP)))   # side, normal (dy, -dx)
        tris.append(((xa, ya, BOTTOM), (xb, yb, TOP), (xa, ya, TOP)))
        tris.append(((c[0], c[1], TOP), (xa, ya, TOP), (xb, yb, TOP)))       # top, normal +Z
        tris.append(((c[0], c[1], BOTTOM), (xb, yb, BOTTOM), (xa, ya, BOTTOM)))  # bottom, normal -Z
    out = ["solid corner_stock"]
    for t in tris:
        out.append("  facet normal 0 0 0\n    outer loop")
        for v in t:
            out.append("      vertex %.9f %.9f %.9f" % v)
        out.append("    endloop\n  endfacet")
    out.append("endsolid corner_stock")
    write_text(name, "\n".join(out) + "\n")


def write_needles(name):
    """W2 from its far end up to the edge, then W1 from the edge to its far end: the order the tool passes them.
    The edge itself has no normal; the first needle of each wall is NEEDLE_STEP from it."""
    n = int(round(WALL_LENGTH / NEEDLE_STEP))
    out = ["# corner part: N-buffer needles on the two nominal walls (generated by generate.py)",
           "# x,y,z,nx,ny,nz in mm: a point on wall x=0 (normal +X) or wall y=0 (normal +Y); the edge is at x=y=0",
           "x,y,z,nx,ny,nz"]
    for z in NEEDLE_Z:
        for k in range(n, 0, -1):
            out.append("0,%.4f,%.4f,1,0,0" % (-k * NEEDLE_STEP, z))
        for k in range(1, n + 1):
            out.append("%.4f,0,%.4f,0,1,0" % (-k * NEEDLE_STEP, z))
    write_text(name, "\n".join(out) + "\n")


def main():
    write_text("corner_reference.ngc",
               program("corner part, reference: the pass at 0.1 m/min, axial depth 10 mm", Z_REFERENCE, FEED_LOW,
                       FEED_LOW))
    write_text("corner_fast.ngc",
               program("corner part: the same pass %g mm higher at 10 m/min, axial depth 5 mm" % Z_SHIFT,
                       Z_REFERENCE + Z_SHIFT, FEED_HIGH, FEED_PLUNGE_HIGH))
    write_stock_stl("corner_stock.stl")
    write_needles("corner_needles.csv")


if __name__ == "__main__":
    main()
