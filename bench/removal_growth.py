#!/usr/bin/env python3
"""The cost-growth table of issue 21: removal CPU and peak memory of `vmsim run` as the z-map spacing halves and as
the program grows, beside what `vmsim run --plan` predicted for the same job (bench/README.md, "How removal cost
grows").

The program is the FreeCAD peer raster of bench/removal_bench.cpp (ball D10, stock 100 x 100 x 20 mm, 201 zig-zag
passes along X 0.5 mm apart, 21 points 5 mm apart on z = 15 - 3 exp(-((x - 50)/15)^2), plunge, stepovers, retract),
written as G-code and repeated `size` times: layer m is lowered by m * 0.1 mm and shifted by m * 0.5 / size mm in Y,
so every layer cuts the whole surface again (size x the moves, size x the material cut). The job cuts the programmed
path (motion = "program": no drives, the removal's cost alone dominates), writes the heights as .npy only and no part
mesh, and draws no pictures.

Per case it runs `vmsim run JOB --plan` then `vmsim run JOB --no-render` (each its own process, the load average
printed before it) and prints the run's removal CPU (report.json timings_s.removal_cpu: every thread), the whole
process's CPU (user + sys) and peak RSS (GNU time), the z-map's memory (report.json removal.memory_bytes), and the
plan's predicted removal CPU, whole-run CPU and peak memory. The cases go spacing by spacing, size by size, in
`rounds` rounds.

usage: bench/removal_growth.py VMSIM [--rounds N] [--spacings 0.2 0.1 0.05 0.025] [--sizes 1 4 16] [--threads 1]
"""
import argparse
import json
import math
import os
import subprocess
import tempfile

SRC = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def zdip(x):
    return 15.0 - 3.0 * math.exp(-((x - 50.0) / 15.0) ** 2)


def raster_gcode(size):
    """The peer raster `size` times, each layer 0.1 mm lower and shifted in Y (see the module's docstring)."""
    lines = ["G21 G90 G17", "G0 Z30"]
    for m in range(size):
        dz, dy = -0.1 * m, 0.5 * m / size
        lines.append(f"G0 X0 Y{dy:.6f}")
        lines.append(f"G1 Z{zdip(0.0) + dz:.6f} F1000")
        for j in range(201):
            y = 0.5 * j + dy
            xs = [5.0 * i for i in range(21)]
            if j % 2:
                xs.reverse()
            for k, x in enumerate(xs):
                if j == 0 and k == 0:
                    continue  # the plunge's end; for j > 0, k = 0 is the stepover move
                lines.append(f"G1 X{x:.6f} Y{y:.6f} Z{zdip(x) + dz:.6f}")
        lines.append("G0 Z30")
    lines.append("M2")
    return "\n".join(lines) + "\n"


def job_toml(program, spacing):
    return f"""[job]
name = "growth"
machine = "{SRC}/parts/machines/mikron_ucp710.toml"
program = "{program}"
[tool]
type = "ball"
diameter_mm = 10.0
flute_length_mm = 25.0
length_mm = 45.0
[stock]
type = "box"
min_mm = [0.0, 0.0, 0.0]
max_mm = [100.0, 100.0, 20.0]
[removal]
field = "zmap"
spacing_mm = {spacing}
motion = "program"
[reference]
kind = "none"
[outputs]
part_mesh = "none"
csv = "never"
x3p = false
"""


def timed(cmd, env, timef):
    subprocess.run(["/usr/bin/time", "-f", "%M %U %S", "-o", timef] + cmd, check=True, env=env,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rss_kb, user, system = open(timef).read().split()[-3:]
    return float(user) + float(system), float(rss_kb) / 1024


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("vmsim")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--spacings", type=float, nargs="+", default=[0.2, 0.1, 0.05, 0.025])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1, 4, 16])
    ap.add_argument("--threads", type=int, default=1)
    a = ap.parse_args()
    env = dict(os.environ, OMP_NUM_THREADS=str(a.threads))
    print("| spacing mm | size | moves | round | load | removal CPU s | run CPU s | peak RSS MB | z-map MB "
          "| plan: removal CPU s | plan: run CPU s | plan: peak MB |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        programs = {}
        for size in a.sizes:
            programs[size] = os.path.join(tmp, f"raster_x{size}.ngc")
            with open(programs[size], "w") as f:
                f.write(raster_gcode(size))
        for r in range(a.rounds):
            for spacing in a.spacings:
                for size in a.sizes:
                    job = os.path.join(tmp, f"job_{spacing}_{size}.toml")
                    with open(job, "w") as f:
                        f.write(job_toml(programs[size], spacing))
                    plan_out, run_out = os.path.join(tmp, "plan"), os.path.join(tmp, "run")
                    load_plan = open("/proc/loadavg").read().split()[0]
                    timed([a.vmsim, "run", job, "--plan", "--quiet", "--out", plan_out], env, job + ".plan.time")
                    load = open("/proc/loadavg").read().split()[0]
                    cpu, rss = timed([a.vmsim, "run", job, "--quiet", "--no-render", "--out", run_out], env,
                                     job + ".time")
                    rep = json.load(open(os.path.join(run_out, "report.json")))
                    plan = json.load(open(os.path.join(plan_out, "plan.json")))
                    t = rep["timings_s"]
                    rem = rep.get("removal", {})
                    pt = plan.get("time", {})
                    print(f"| {spacing} | {size}x | {rem.get('sweeps', float('nan')):.0f} | {r + 1} | {load} "
                          f"({load_plan}) | {t.get('removal_cpu', float('nan')):.2f} | {cpu:.2f} | {rss:.0f} | "
                          f"{rem.get('memory_bytes', float('nan')) / 1e6:.1f} | "
                          f"{pt.get('removal_cpu_s', float('nan')):.2f} | {pt.get('run_cpu_s', float('nan')):.2f} | "
                          f"{plan['one_process']['total_bytes'] / 1e6:.0f} |", flush=True)


if __name__ == "__main__":
    main()
