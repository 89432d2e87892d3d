#!/usr/bin/env python3
"""A gain study: the X axis's position-loop gain Kv varied as `vmsim study` varies it, and the contour error of the
plane-cylinder pass (motion only: interpolator, drives, contour error; no material removal).

    python3 gain_study.py [--out DIR] [--quick]     writes DIR/gain_study.csv (and .png with matplotlib)
"""
import csv

import numpy as np

import vmsim
from _common import PARTS, arguments, pyplot

args = arguments(__doc__)
job = vmsim.load_job(PARTS / "plane_cylinder" / "job_fast.toml")
kv0 = job["machine.axes.X.drive.kv_1000_per_min"]
factors = [0.5, 1.0, 2.0] if args.quick else [0.5, 0.75, 1.0, 1.5, 2.0, 3.0]
rows = []
for k in factors:
    job.override("machine.axes.X.drive.kv_1000_per_min", kv0 * k)
    motion = job.simulate()
    ce = motion.contour_error_mm
    x = motion.response.axis_names.index("X")
    following = motion.setpoints.position[:, x] - motion.response.position[: motion.setpoints.samples, x]
    rows.append({"kv_1000_per_min": kv0 * k, "contour_error_max_um": float(np.abs(ce).max() * 1e3),
                 "contour_error_rms_um": float(np.sqrt(np.mean(ce ** 2)) * 1e3),
                 "x_following_error_max_um": float(np.abs(following).max() * 1e3)})
    print(f"Kv {kv0 * k:5.2f}: contour error max {rows[-1]['contour_error_max_um']:6.2f} um")
job.reset()

with open(args.out / "gain_study.csv", "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
plt = pyplot()
if plt:
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.plot([r["kv_1000_per_min"] for r in rows], [r["contour_error_max_um"] for r in rows], "o-", label="contour, max")
    ax.plot([r["kv_1000_per_min"] for r in rows], [r["x_following_error_max_um"] for r in rows], "s--", label="X following, max")
    ax.set_xlabel("Kv of X ((m/min)/mm)")
    ax.set_ylabel("error (µm)")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out / "gain_study.png", dpi=120)
print(f"wrote {args.out / 'gain_study.csv'}" + (" and gain_study.png" if plt else " (no matplotlib: no plot)"))
