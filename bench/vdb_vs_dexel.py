#!/usr/bin/env python3
"""Time and memory of the two removal kernels (dexels, OpenVDB level set) on the test parts at matched resolution.

Runs `vmsim run` on each part's programmed path (motion = "program": the kernels' work, not the drives'), no
reference, no pictures, with the dexel field the part uses and with removal.method = "vdb" at the same
spacing / voxel size, and prints a Markdown table from report.json (timings_s.stock, .removal, .write; removal
memory_bytes and, for vdb, memory_estimate_bytes) and the process' peak RSS (GNU time).

usage: bench/vdb_vs_dexel.py BUILD_DIR [--part plane_cylinder|corner] [resolution_mm ...]   (default 0.1 0.05)
"""
import json
import os
import subprocess
import sys
import tempfile

SRC = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

PARTS = [
    # name, folder, program, tool, stock, start, dexel field lines
    ("plane-cylinder (41 ball passes)", "plane_cylinder", "plane_cylinder_reference.ngc",
     'type = "ball"\ndiameter_mm = 10.0\nflute_length_mm = 25.0\nlength_mm = 50.0',
     "plane_cylinder_stock.stl", "[-8.0, 0.0, 40.0]", ['field = "zmap"', 'field = "tridexel"']),
    ("corner (flank, D10 flat)", "corner", "corner_reference.ngc",
     'type = "flat"\ndiameter_mm = 10.0\nflute_length_mm = 25.0\nlength_mm = 50.0',
     "corner_stock.stl", "[5.0, -75.0, 20.0]",
     ['field = "nbuffer"\nneedles_file = "%s/parts/corner/corner_needles.csv"\nneedle_half_length_mm = 0.5' % SRC,
      'field = "tridexel"']),
]


def job_text(folder, program, tool, stock, start, removal):
    d = f"{SRC}/parts/{folder}/"
    return (f'[job]\nname = "bench"\nmachine = "{SRC}/parts/machines/mikron_ucp710.toml"\nprogram = "{d}{program}"\n'
            f'tool_table = "{d}tools.tbl"\nstart_mm = {start}\n[tool]\n{tool}\n[stock]\ntype = "stl"\n'
            f'file = "{d}{stock}"\n[removal]\nmotion = "program"\n{removal}\n[reference]\nkind = "none"\n')


def run(vmsim, tmp, text):
    job = os.path.join(tmp, "job.toml")
    with open(job, "w") as f:
        f.write(text)
    out = os.path.join(tmp, "out")
    timef = os.path.join(tmp, "time.txt")
    subprocess.run(["/usr/bin/time", "-f", "%M", "-o", timef, vmsim, "run", job, "--quiet", "--no-render", "--out", out],
                   check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(os.path.join(out, "report.json")) as f:
        rep = json.load(f)
    with open(timef) as f:
        rss_kb = int(f.read().split()[-1])
    return rep, rss_kb


def main():
    args = sys.argv[1:]
    build = args.pop(0) if args else os.path.join(SRC, "build")
    only = None
    if args and args[0] == "--part":
        only = args[1]
        args = args[2:]
    res = [float(x) for x in args] or [0.1, 0.05]
    vmsim = os.path.join(build, "app", "vmsim")
    print("| part | kernel | resolution mm | stock s | removal s | surfaces + files s | kernel memory MB | "
          "estimate MB | peak RSS MB | sweeps |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, folder, program, tool, stock, start, fields in PARTS:
        if only and folder != only:
            continue
        for h in res:
            kernels = [(f.split("\n")[0].split('"')[1], f + f"\nspacing_mm = {h}") for f in fields]
            kernels.append(("vdb", fields[0] + f'\nmethod = "vdb"\nspacing_mm = {h}\nvoxel_mm = {h}'))
            for kname, removal in kernels:
                with tempfile.TemporaryDirectory() as tmp:
                    rep, rss = run(vmsim, tmp, job_text(folder, program, tool, stock, start, removal))
                t = rep["timings_s"]
                r = rep["removal"]
                est = r.get("memory_estimate_bytes")
                print(f"| {name} | {kname} | {h:g} | {t['stock']:.2f} | {t['removal']:.2f} | {t['write']:.2f} | "
                      f"{r['memory_bytes'] / 1e6:.1f} | {'' if est is None else f'{est / 1e6:.1f}'} | "
                      f"{rss / 1024:.0f} | {r['sweeps']} |", flush=True)


if __name__ == "__main__":
    main()
