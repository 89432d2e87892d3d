#!/usr/bin/env python3
"""The removal stage of `vmsim run` with two builds of vmsim, interleaved (issue 21: before / after a kernel change).

For each case it runs BEFORE then AFTER (each its own process, no pictures), `rounds` times, and prints report.json's
timings_s.removal (wall) and timings_s.removal_cpu (CPU of every thread: the track, the sweeps and the cut), the
whole process's CPU (GNU time, user + system) and peak RSS, and whether the two builds wrote the same surface
(surface.npy, part.stl and, for needles, the needle CSV compared byte for byte). The load average is printed before
each run: on a shared machine the CPU columns are the ones to compare.

Cases: the test parts' programmed paths with the fields bench/vdb_vs_dexel.py uses (plane-cylinder tri-dexel, the
corner's needles and tri-dexel, the five-axis dome's tri-dexel at a 10 um track), parts/plane_cylinder/job_fast.toml as
it is (z-map, the drives' actual motion) and bench/flower_mold/job.toml (needs ../shared).

usage: bench/removal_before_after.py BEFORE_VMSIM AFTER_VMSIM [--rounds N] [--case NAME ...]
"""
import argparse
import filecmp
import json
import os
import subprocess
import tempfile

SRC = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BALL10 = 'type = "ball"\ndiameter_mm = 10.0\nflute_length_mm = 25.0\nlength_mm = 50.0'
FLAT10 = 'type = "flat"\ndiameter_mm = 10.0\nflute_length_mm = 25.0\nlength_mm = 50.0'


def program_job(folder, program, tool, stock, start, removal):
    d = f"{SRC}/parts/{folder}/"
    head = f'[job]\nname = "bench"\nmachine = "{SRC}/parts/machines/mikron_ucp710.toml"\nprogram = "{d}{program}"\n'
    if start is not None:
        head += f'tool_table = "{d}tools.tbl"\nstart_mm = {start}\n'
    return (head + f'[tool]\n{tool}\n[stock]\ntype = "stl"\nfile = "{d}{stock}"\n[removal]\nmotion = "program"\n'
            f'{removal}\n[reference]\nkind = "none"\n')


CASES = {
    "plane_cylinder_tridexel": program_job("plane_cylinder", "plane_cylinder_reference.ngc", BALL10,
                                           "plane_cylinder_stock.stl", "[-8.0, 0.0, 40.0]",
                                           'field = "tridexel"\nspacing_mm = 0.1'),
    "corner_needles": program_job("corner", "corner_reference.ngc", FLAT10, "corner_stock.stl", "[5.0, -75.0, 20.0]",
                                  f'field = "nbuffer"\nneedles_file = "{SRC}/parts/corner/corner_needles.csv"\n'
                                  'needle_half_length_mm = 0.5'),
    "corner_tridexel": program_job("corner", "corner_reference.ngc", FLAT10, "corner_stock.stl", "[5.0, -75.0, 20.0]",
                                   'field = "tridexel"\nspacing_mm = 0.1'),
    "five_axis_tridexel": program_job("five_axis", "dome_spiral.cl",
                                      'type = "ball"\ndiameter_mm = 10.0\nflute_length_mm = 6.0\nlength_mm = 6.0',
                                      "dome_stock.stl", None,
                                      'field = "tridexel"\nspacing_mm = 0.1\ntrack_tolerance_mm = 0.01'),
    "plane_cylinder_fast": f"{SRC}/parts/plane_cylinder/job_fast.toml",
    "flower_mold": f"{SRC}/bench/flower_mold/job.toml",
}


def run(vmsim, job, out):
    timef = out + ".time"
    subprocess.run(["/usr/bin/time", "-f", "%M %U %S", "-o", timef, vmsim, "run", job, "--quiet", "--no-render",
                    "--out", out], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(os.path.join(out, "report.json")) as f:
        rep = json.load(f)
    rss_kb, user, system = open(timef).read().split()[-3:]
    t = rep["timings_s"]
    return t["removal"], t.get("removal_cpu", float("nan")), float(user) + float(system), float(rss_kb) / 1024


def same(a, b):
    names = [n for n in os.listdir(a) if n in ("surface.npy", "part.stl") or n.endswith("needles.csv")]
    return all(filecmp.cmp(os.path.join(a, n), os.path.join(b, n), shallow=False) for n in names), names


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--case", action="append")
    a = ap.parse_args()
    print("| case | build | round | load | removal wall s | removal CPU s | process CPU s | peak RSS MB |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in a.case or CASES:
            spec = CASES[name]
            job = spec
            if not spec.endswith(".toml"):
                job = os.path.join(tmp, name + ".toml")
                with open(job, "w") as f:
                    f.write(spec)
            for r in range(a.rounds):
                outs = []
                for label, exe in (("before", a.before), ("after", a.after)):
                    load = open("/proc/loadavg").read().split()[0]
                    out = os.path.join(tmp, f"{name}_{label}_{r}")
                    wall, cpu, proc, rss = run(exe, job, out)
                    outs.append(out)
                    print(f"| {name} | {label} | {r + 1} | {load} | {wall:.2f} | {cpu:.2f} | {proc:.1f} | {rss:.0f} |",
                          flush=True)
                ok, names = same(*outs)
                print(f"| {name} | same {', '.join(names)}: {'yes' if ok else 'NO'} | | | | | | |", flush=True)


if __name__ == "__main__":
    main()
