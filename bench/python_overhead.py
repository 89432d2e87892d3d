#!/usr/bin/env python3
"""The Python module's overhead over the command line on a plane-cylinder run (issue 22).

    PYTHONPATH=build/python /usr/bin/python3 bench/python_overhead.py [--rounds 5] [--job parts/plane_cylinder/job_fast.toml]

Interleaved, one process per run so that each pays its own start-up: A = `vmsim run JOB --no-render --quiet --out
DIR`, B = `python3 -c "import vmsim; vmsim.load_job(JOB).run(out=DIR)"` (the same files). CPU time is the child's
user + system time (getrusage), which the other sessions on the machine do not inflate the way they do wall time;
the load average is printed before and after. Also B's import alone (what a notebook pays once).
"""
import argparse
import os
import pathlib
import resource
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = pathlib.Path(__file__).resolve().parents[1]


def child_run(cmd, env):
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
    wall = time.monotonic() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--job", default=str(ROOT / "parts" / "plane_cylinder" / "job_fast.toml"))
    p.add_argument("--cli", default=str(ROOT / "build" / "app" / "vmsim"))
    p.add_argument("--python", default="/usr/bin/python3")
    a = p.parse_args()
    env = dict(os.environ)
    env.setdefault("PYTHONPATH", str(ROOT / "build" / "python"))
    env["OMP_NUM_THREADS"] = env.get("OMP_NUM_THREADS", "1")  # one thread each: CPU time comparable, less noise
    out = pathlib.Path(tempfile.mkdtemp(prefix="vmsim-pybench-"))
    cli = [a.cli, "run", a.job, "--no-render", "--quiet", "--out", str(out / "cli")]
    py = [a.python, "-c", f"import vmsim; vmsim.load_job({a.job!r}).run(out={str(out / 'py')!r})"]
    imp = [a.python, "-c", "import vmsim"]
    print(f"load average before: {os.getloadavg()}")
    rows = {"cli": [], "python": [], "import": []}
    for _ in range(a.rounds):
        rows["cli"].append(child_run(cli, env))
        rows["python"].append(child_run(py, env))
        rows["import"].append(child_run(imp, env))
    print(f"load average after: {os.getloadavg()}")
    for k, v in rows.items():
        print(f"{k:7s} wall median {statistics.median(w for w, _ in v):7.3f} s   cpu median {statistics.median(c for _, c in v):7.3f} s"
              f"   cpu min {min(c for _, c in v):7.3f} s")
    ratio = [c_py / c_cli for (_, c_cli), (_, c_py) in zip(rows["cli"], rows["python"])]
    print(f"python/cli CPU time ratio per round: {[round(r, 4) for r in ratio]}, median {statistics.median(ratio):.4f}")


if __name__ == "__main__":
    sys.exit(main())
