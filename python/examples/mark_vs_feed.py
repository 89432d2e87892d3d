#!/usr/bin/env python3
"""The plane-cylinder mark against the feed (the feed-drive simulation paper, section 4: about 0.02 mm deep at
10 m/min, negligible at 0.1 m/min). One job, its feeds scaled in a loop; the deepest mark of each run.

    python3 mark_vs_feed.py [--out DIR] [--quick]     writes DIR/mark_vs_feed.csv (and .png with matplotlib)
"""
import csv

import vmsim
from _common import PARTS, arguments, pyplot

args = arguments(__doc__)
job = vmsim.load_job(PARTS / "plane_cylinder" / "job_fast.toml")
scales = [0.25, 1.0] if args.quick else [0.1, 0.25, 0.5, 0.75, 1.0]
rows = []
for s in scales:
    job.override("feed_scale", s)
    result = job.run()
    deepest = result.marks[0] if result.marks else None
    rows.append({"feed_m_per_min": 10.0 * s,  # the pass is programmed at 10 m/min
                 "mark_depth_mm": deepest["depth_mm"] if deepest else 0.0,
                 "mark_kind": deepest["kind"] if deepest else "none",
                 "contour_error_max_mm": result.report["contour_error"]["cutting_moves"]["max_abs_mm"]})
    print(f"{10.0 * s:5.2f} m/min: mark {rows[-1]['mark_depth_mm'] * 1e3:6.2f} um ({rows[-1]['mark_kind']})")

with open(args.out / "mark_vs_feed.csv", "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
plt = pyplot()
if plt:
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.plot([r["feed_m_per_min"] for r in rows], [r["mark_depth_mm"] * 1e3 for r in rows], "o-")
    ax.set_xlabel("feed (m/min)")
    ax.set_ylabel("mark depth (µm)")
    ax.set_title("plane-cylinder: mark at the fillet")
    fig.tight_layout()
    fig.savefig(args.out / "mark_vs_feed.png", dpi=120)
print(f"wrote {args.out / 'mark_vs_feed.csv'}" + (" and mark_vs_feed.png" if plt else " (no matplotlib: no plot)"))
