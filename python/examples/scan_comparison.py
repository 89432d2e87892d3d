#!/usr/bin/env python3
"""A scan held against the prediction, as `vmsim compare` does. The "scan" here is made from the predicted surface
itself - tilted, shifted, with sensor noise and a few spikes, written to X3P and read back - so the answer is known:
after registration the deviation is the noise alone (a real scan: pass its file to vmsim.compare instead).

    python3 scan_comparison.py [--out DIR] [--quick]     writes DIR/scan.x3p, DIR/scan_comparison.csv (and .png)
"""
import csv

import numpy as np

import vmsim
from _common import PARTS, arguments, pyplot

args = arguments(__doc__)
result = vmsim.load_job(PARTS / "plane_cylinder" / "job_fast.toml").run()
predicted = result.surface

rng = np.random.default_rng(1)
z = predicted.z_mm.copy()
yy, xx = np.mgrid[0:z.shape[0], 0:z.shape[1]]
noise_mm = 0.0005
z += 1e-4 * xx * predicted.dx_mm + 0.002 + rng.normal(0.0, noise_mm, z.shape)  # tilt 0.1 mm/m, offset 2 um, noise
spikes = rng.integers(0, z.size, 20)
z.flat[spikes] += 0.05
scan = vmsim.Grid(z, predicted.dx_mm, predicted.dy_mm, predicted.x0_mm, predicted.y0_mm)
vmsim.write_x3p(args.out / "scan.x3p", scan, comment="synthetic scan of the plane-cylinder prediction")
scan = vmsim.read_surface(args.out / "scan.x3p")

c = vmsim.compare(scan, predicted)
s = c["stats"]
print(f"deviation after registration: rms {s['rms_mm'] * 1e3:.3f} um (noise {noise_mm * 1e3} um), "
      f"mean {s['mean_mm'] * 1e3:.3f} um, spikes masked {c.get('outliers_masked')}")
print(f"Sa measured {c['measured_areal']['Sa_mm'] * 1e3:.3f} um, predicted {c['predicted_areal']['Sa_mm'] * 1e3:.3f} um")
with open(args.out / "scan_comparison.csv", "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["quantity", "value"])
    for k, v in s.items():
        w.writerow([f"deviation_{k}", v])
    w.writerow(["outliers_masked", c.get("outliers_masked")])
    for k, v in c["measured_areal"].items():
        w.writerow([f"measured_{k}", v])
plt = pyplot()
if plt:
    d = c["deviation"]
    fig, ax = plt.subplots(figsize=(6, 4))
    im = ax.imshow(d.z_mm * 1e3, origin="lower", cmap="RdBu_r",
                   extent=[d.x0_mm, d.x0_mm + d.dx_mm * d.nx, d.y0_mm, d.y0_mm + d.dy_mm * d.ny])
    fig.colorbar(im, label="measured - predicted (µm)")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    fig.tight_layout()
    fig.savefig(args.out / "scan_comparison.png", dpi=120)
print(f"wrote {args.out / 'scan_comparison.csv'}" + (" and scan_comparison.png" if plt else " (no matplotlib: no plot)"))
