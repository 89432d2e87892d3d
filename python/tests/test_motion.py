"""The job's motion from Python: shapes, strides, units, and the same figures as `vmsim motion` and `vmsim interp`.

References: the CLI's report.json for the same job (figures equal), the program text (the F words), and the
arrays' own definitions (t = k Te; a view keeps the memory of its result).
"""
import json
import re

import numpy as np
import pytest

import vmsim
from conftest import run_cli


@pytest.fixture(scope="module")
def job(parts):
    return vmsim.load_job(parts / "plane_cylinder" / "job_fast.toml")


@pytest.fixture(scope="module")
def motion(job):
    return job.simulate()


def test_setpoints_shapes_strides_units(job, parts):
    sp = job.interpolate()
    n, axes = sp.position.shape
    assert axes == len(sp.axis_names) and n == len(sp) == sp.samples
    # A view of the C++ matrix (column-major): each axis's samples contiguous, no copy.
    assert sp.position.dtype == np.float64 and sp.position.flags.f_contiguous and not sp.position.flags.owndata
    assert sp.position.strides == (8, 8 * n)
    assert np.shares_memory(sp.position, sp.position)  # the same memory on every access
    assert sp.period_s == pytest.approx(1e-3)  # [interpolation] period_ms = 1.0
    assert np.allclose(np.diff(sp.t_s), sp.period_s)
    assert sp.cycle_time_s == pytest.approx((n - 1) * sp.period_s, abs=sp.period_s)
    # Units: path speed in mm/s. The program's fastest feed (F word, mm/min) / 60 bounds it, and the long pass
    # reaches it.
    text = (parts / "plane_cylinder" / "plane_cylinder_fast.ngc").read_text()
    f_max = max(float(f) for f in re.findall(r"F\s*([0-9.]+)", text))
    cutting = ~job.program().rapid[sp.move_index]  # samples on feed moves (rapids run at the axes' limits)
    assert sp.path_speed_mm_per_s[cutting].max() <= f_max / 60 * (1 + 1e-9)
    assert sp.path_speed_mm_per_s[cutting].max() > 0.9 * f_max / 60
    # feed_scale multiplies every programmed feed (as --feed-scale): the pass's top speed halves.
    job.override("feed_scale", 0.5)
    try:
        sp2 = job.interpolate()
        half = sp2.path_speed_mm_per_s[~job.program().rapid[sp2.move_index]].max()
        assert half <= 0.5 * f_max / 60 * (1 + 1e-9) and half > 0.9 * 0.5 * f_max / 60
    finally:
        job.reset()


def test_program_arrays(parts):
    program = vmsim.read_program(parts / "plane_cylinder" / "plane_cylinder_fast.ngc",
                                 tool_table=parts / "plane_cylinder" / "tools.tbl")
    n = len(program)
    assert program.start.shape == (n, 6) and program.end.shape == (n, 6)
    assert program.kind.shape == (n,) and set(program.kind) <= {"line", "arc"}
    # Moves join (no tool length offset change inside the program).
    assert np.allclose(program.start[1:, :3], program.end[:-1, :3])
    # The F words of the program text are the feeds of its cutting moves.
    text = (parts / "plane_cylinder" / "plane_cylinder_fast.ngc").read_text()
    feeds = {float(f) for f in re.findall(r"F\s*([0-9.]+)", text)}
    assert set(program.feed_mm_per_min[~program.rapid]) <= feeds
    lines = text.splitlines()
    assert all(1 <= ln <= len(lines) for ln in program.source_line)


def test_motion_same_as_cli(cli, job, motion, tmp_path):
    run_cli(cli, "motion", job.file, "--out", tmp_path)
    cli_report = json.loads((tmp_path / "report.json").read_text())
    for key in ("interpolation", "axes", "contour_error", "limits_held"):
        if key in cli_report:
            assert motion.report[key] == cli_report[key], key
    rows = motion.response.position.shape[0]
    assert motion.response.position.shape == (rows, len(motion.response.axis_names)) and rows >= motion.setpoints.samples
    assert motion.contour_error_mm.shape == (rows,)
    assert abs(motion.contour_error_mm).max() == pytest.approx(motion.contour_error_max_abs_mm)
    assert motion.response.current_A.flags.f_contiguous


def test_views_keep_their_result_alive(job):
    pos = job.interpolate().position  # the Setpoints object is dropped at once
    import gc
    gc.collect()
    assert np.isfinite(pos).all() and pos.base is not None


def test_override_and_read_keys(job):
    assert job["interpolation.tolerance_mm"] == pytest.approx(0.02)
    kv = job["machine.axes.X.drive.kv_1000_per_min"]
    job.override("machine.axes.X.drive.kv_1000_per_min", kv * 2)
    try:
        assert job["machine.axes.X.drive.kv_1000_per_min"] == pytest.approx(kv * 2)
        assert job.overrides == {"machine.axes.X.drive.kv_1000_per_min": repr(float(kv * 2))}
    finally:
        job.reset()
    assert job.overrides == {}
    assert job["machine.axes.X.drive.kv_1000_per_min"] == kv
