#!/usr/bin/env python3
"""Time and memory of the two removal kernels (dexels, OpenVDB level set) on the test parts at matched resolution.

Runs `vmsim run` on each part's programmed path (motion = "program": the kernels' work, not the drives'), no
reference, no pictures, with the dexel fields the part uses and with removal.method = "vdb" at the same
spacing / voxel size, one after the other for each part and resolution (interleaved, so that the machine's load
hits all kernels alike), and prints a Markdown table from report.json (timings_s.stock, .removal, .write: wall
seconds; removal memory_bytes and, for vdb, the estimates printed before the run) and GNU time's process figures
(CPU seconds, user + system, and peak RSS). The load average is printed before and after.

Parts: plane_cylinder (41 ball passes), corner (flank milling), five_axis (the dome's spiral on the Mikron's A/C
chain: tri-dexel at the part's 2 um track tolerance and at the vdb default, voxel / 10 (the same sweeps as vdb),
vdb at its default, plus, with --fine-vdb, vdb at 2 um too).

usage: bench/vdb_vs_dexel.py BUILD_DIR [--part NAME] [--fine-vdb] [resolution_mm ...]   (default 0.1 0.05)
"""
import json
import os
import subprocess
import sys
import tempfile

SRC = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

FIVE_AXIS_TOOL = 'type = "ball"\ndiameter_mm = 10.0\nflute_length_mm = 6.0\nlength_mm = 6.0'

PARTS = [
    # name, folder, program, tool, stock, start, dexel field lines (the first is also the vdb job's output field)
    ("plane-cylinder (41 ball passes)", "plane_cylinder", "plane_cylinder_reference.ngc",
     'type = "ball"\ndiameter_mm = 10.0\nflute_length_mm = 25.0\nlength_mm = 50.0',
     "plane_cylinder_stock.stl", "[-8.0, 0.0, 40.0]", ['field = "zmap"', 'field = "tridexel"']),
    ("corner (flank, D10 flat)", "corner", "corner_reference.ngc",
     'type = "flat"\ndiameter_mm = 10.0\nflute_length_mm = 25.0\nlength_mm = 50.0',
     "corner_stock.stl", "[5.0, -75.0, 20.0]",
     ['field = "nbuffer"\nneedles_file = "%s/parts/corner/corner_needles.csv"\nneedle_half_length_mm = 0.5' % SRC,
      'field = "tridexel"']),
    ("five-axis dome (10-turn spiral, A/C)", "five_axis", "dome_spiral.cl", FIVE_AXIS_TOOL, "dome_stock.stl", None,
     ['field = "tridexel"\ntrack_tolerance_mm = 0.002', 'field = "tridexel"\ntrack_tolerance_mm = {h10}']),
]


def job_text(folder, program, tool, stock, start, removal):
    d = f"{SRC}/parts/{folder}/"
    head = f'[job]\nname = "bench"\nmachine = "{SRC}/parts/machines/mikron_ucp710.toml"\nprogram = "{d}{program}"\n'
    if start is not None:
        head += f'tool_table = "{d}tools.tbl"\nstart_mm = {start}\n'
    return (head + f'[tool]\n{tool}\n[stock]\ntype = "stl"\nfile = "{d}{stock}"\n[removal]\nmotion = "program"\n'
            f'{removal}\n[reference]\nkind = "none"\n')


def run(vmsim, tmp, text):
    job = os.path.join(tmp, "job.toml")
    with open(job, "w") as f:
        f.write(text)
    out = os.path.join(tmp, "out")
    timef = os.path.join(tmp, "time.txt")
    subprocess.run(["/usr/bin/time", "-f", "%M %U %S", "-o", timef, vmsim, "run", job, "--quiet", "--no-render",
                    "--out", out], check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(os.path.join(out, "report.json")) as f:
        rep = json.load(f)
    with open(timef) as f:
        rss_kb, user, sys_ = f.read().split()[-3:]
    return rep, int(rss_kb), float(user) + float(sys_)


def mb(x):
    return "" if x is None else f"{x / 1e6:.1f}"


def main():
    args = sys.argv[1:]
    build = args.pop(0) if args else os.path.join(SRC, "build")
    only = None
    fine_vdb = False
    while args and args[0].startswith("--"):
        if args[0] == "--part":
            only = args[1]
            args = args[2:]
        elif args[0] == "--fine-vdb":
            fine_vdb = True
            args = args[1:]
        else:
            sys.exit(f"unknown option {args[0]}")
    res = [float(x) for x in args] or [0.1, 0.05]
    vmsim = os.path.join(build, "app", "vmsim")
    print(f"load average before: {os.getloadavg()}", flush=True)
    print("| part | kernel | resolution mm | track tol. mm | sweeps | CPU s | stock s | removal s | surfaces + files s | "
          "kernel memory MB | estimate MB (mesh) | peak RSS MB |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, folder, program, tool, stock, start, fields in PARTS:
        if only and folder != only:
            continue
        for h in res:
            kernels = [(f.split("\n")[0].split('"')[1], f.replace("{h10}", f"{h / 10:g}") + f"\nspacing_mm = {h}")
                       for f in fields]
            out_field = fields[0].split("\ntrack_tolerance_mm")[0]
            kernels.append(("vdb", out_field + f'\nmethod = "vdb"\nspacing_mm = {h}\nvoxel_mm = {h}'))
            if fine_vdb and folder == "five_axis":
                kernels.append(("vdb", out_field + f'\nmethod = "vdb"\nspacing_mm = {h}\nvoxel_mm = {h}\n'
                                       'track_tolerance_mm = 0.002'))
            for kname, removal in kernels:
                with tempfile.TemporaryDirectory() as tmp:
                    try:
                        rep, rss, cpu = run(vmsim, tmp, job_text(folder, program, tool, stock, start, removal))
                    except subprocess.CalledProcessError as e:
                        print(f"| {name} | {kname} | {h:g} | failed: {e} |", flush=True)
                        continue
                t = rep["timings_s"]
                r = rep["removal"]
                est = r.get("memory_estimate_bytes")
                mest = r.get("mesh_memory_estimate_bytes")
                est_s = "" if est is None else f"{mb(est)} ({mb(mest)})"
                print(f"| {name} | {kname} | {h:g} | {r['track_tolerance_mm']:g} | {r['sweeps']} | {cpu:.1f} | "
                      f"{t['stock']:.2f} | {t['removal']:.2f} | {t['write']:.2f} | {mb(r['memory_bytes'])} | {est_s} | "
                      f"{rss / 1024:.0f} |", flush=True)
    print(f"load average after: {os.getloadavg()}", flush=True)


if __name__ == "__main__":
    main()
