"""Which tool cut where, from Python: Result.tools and Result.tool_map (what images/tools.png draws).

References: the command line on the same job (report.json's tools and every file byte-identical, as in
test_run_vs_cli.py), and the analytic shape of the two slots a CL program with two TLDATA/ flat tools cuts (the
program of tests/app/tools_png_cli_test.cpp): a D6 slot along x at y = -5 from x = -15 to 15, 1 mm deep, then a D4 slot
along y at x = 5 from y = -15 to 15, 2 mm deep. The job gives no [tool], so the program's tools cut (as `vmsim run`
takes them: sim::use_program_tool).
"""
import json

import numpy as np
import pytest

import vmsim
from compare import differences
from conftest import run_cli

MACHINE = """[machine]
name = "test mill"
kinematics = "xyz"
""" + "".join(f"""[[axes]]
name = "{a}"
type = "linear"
travel_mm = [-100.0, 100.0]
max_velocity_m_per_min = 30.0
max_acceleration_m_per_s2 = 2.5
max_jerk_m_per_s3 = 50.0
""" for a in "XYZ")

PROGRAM = (
    "UNITS/MM\nTLDATA/MILL,6.0000,0.0000,20.0000,0.0000,0.0000\nFEDRAT/MMPM,600\nGOTO/-15,-5,5\nGOTO/-15,-5,-1\n"
    "GOTO/15,-5,-1\nRAPID\nGOTO/15,-5,5\nTLDATA/MILL,4.0000,0.0000,20.0000,0.0000,0.0000\nRAPID\nGOTO/5,-15,5\n"
    "GOTO/5,-15,-2\nGOTO/5,15,-2\nRAPID\nGOTO/5,15,5\nFINI\n")

JOB = """[job]
name = "two_slots"
machine = "machine.toml"
program = "two.cl"
[stock]
type = "box"
min_mm = [-20.0, -20.0, -5.0]
max_mm = [20.0, 20.0, 0.0]
[interpolation]
period_ms = 1
tolerance_mm = 0.005
[removal]
field = "zmap"
spacing_mm = 0.2
motion = "program"
[reference]
kind = "none"
"""


def write_two_slots(d):
    (d / "machine.toml").write_text(MACHINE)
    (d / "two.cl").write_text(PROGRAM)
    (d / "two.toml").write_text(JOB)
    return d / "two.toml"


def slot_tool(x, y):
    """The analytic last tool at (x, y): 1 inside the D4 slot, 0 inside the D6 slot outside it, -1 uncut; None within
    10 um of an edge (a node there may fall either side)."""
    d4 = 2.0 - np.hypot(x - 5.0, np.clip(y, -15.0, 15.0) - y)  # a stadium of radius 2 around the segment x = 5
    d6 = 3.0 - np.hypot(np.clip(x, -15.0, 15.0) - x, y + 5.0)  # radius 3 around y = -5, x in [-15, 15]
    if min(abs(d4), abs(d6)) < 0.01:
        return None
    if d4 > 0:
        return 1
    if d6 > 0:
        return 0
    return -1


def test_tool_map_is_the_slots_and_the_cli_agrees(cli, tmp_path):
    job_file = write_two_slots(tmp_path)
    cli_dir, py_dir = tmp_path / "cli", tmp_path / "py"
    run_cli(cli, "run", job_file, "--out", cli_dir, "--no-render", "--quiet")
    result = vmsim.load_job(job_file).run(out=py_dir)

    # The same tools and files as the command line (report.json: every figure but times and memory).
    assert differences(cli_dir, py_dir) == []
    cli_tools = json.loads((cli_dir / "report.json").read_text())["tools"]["list"]
    assert result.tools == cli_tools
    assert [t["diameter_mm"] for t in result.tools] == [6.0, 4.0]

    m = result.tool_map
    g = result.surface
    assert m is not None and m.dtype == np.int8 and m.shape == g.z_mm.shape
    # tool_map.npy as numpy itself reads it (numpy.load: the reference reader of the format) is the same map.
    on_disk = np.load(py_dir / "tool_map.npy")
    assert on_disk.dtype == np.int8 and np.array_equal(on_disk, m)
    side = json.loads((py_dir / "tool_map.npy.json").read_text())
    assert (side["x0_mm"], side["dx_mm"], side["nx"], side["ny"]) == (g.x0_mm, g.dx_mm, m.shape[1], m.shape[0])
    ny, nx = m.shape
    wrong = 0
    for j in range(ny):
        for i in range(nx):
            want = slot_tool(g.x0_mm + i * g.dx_mm, g.y0_mm + j * g.dy_mm)
            if want is not None and m[j, i] != want:
                wrong += 1
    assert wrong == 0
    # Each tool's area in report.json is its nodes times a node's cell.
    for k, t in enumerate(result.tools):
        assert t["last_cut_area_mm2"] == pytest.approx(np.count_nonzero(m == k) * g.dx_mm * g.dy_mm, rel=1e-12)


def test_one_tool_has_no_map(tmp_path):
    job_file = write_two_slots(tmp_path)
    (tmp_path / "two.cl").write_text(PROGRAM.split("TLDATA/MILL,4.0000")[0] + "FINI\n")  # the D6 slot only
    result = vmsim.load_job(job_file).run()
    assert result.tool_map is None
    assert [t["diameter_mm"] for t in result.tools] == [6.0]
