"""Python and the command line give identical results on the parts.

Reference: `vmsim run JOB --no-render` (the CLI built beside the module) on the same job. The module calls the same
library (sim::run_job) and the same writer (sim::write_run_outputs), so every file must be byte-identical (X3P: every
entry, main.xml's dates aside; report.json: every figure but times and memory), and the arrays the module hands over
must equal what the CLI wrote to surface.npy/deviation.npy, bit for bit.
"""
import json

import numpy as np
import pytest

import vmsim
from compare import differences
from conftest import run_cli

# Parts' jobs small enough for `make test` (tens of seconds each), covering a z-map with a feed reference and the
# N-buffer needles on a stock carried from another job.
JOBS = ["plane_cylinder/job_fast.toml", "corner/job_fast.toml"]


@pytest.mark.parametrize("rel", JOBS)
def test_same_files_and_marks_as_cli(cli, parts, tmp_path, rel):
    job_file = parts / rel
    if not job_file.is_file():
        pytest.skip(f"{job_file} is absent")
    cli_dir, py_dir = tmp_path / "cli", tmp_path / "py"
    run_cli(cli, "run", job_file, "--out", cli_dir, "--no-render", "--quiet")
    result = vmsim.load_job(job_file).run(out=py_dir)

    assert differences(cli_dir, py_dir) == []
    cli_report = json.loads((cli_dir / "report.json").read_text())
    assert result.marks == cli_report["marks"]
    assert result.files == cli_report["files"] + ["report.json"]
    assert result.out == py_dir

    if (cli_dir / "surface.npy").exists():
        for name in ("surface", "deviation"):
            on_disk = np.load(cli_dir / f"{name}.npy")
            grid = getattr(result, name)
            assert grid is not None
            assert grid.z_mm.shape == on_disk.shape
            # Bit for bit, NaN (invalid nodes) in the same places.
            assert np.array_equal(grid.z_mm, on_disk, equal_nan=True)
            side = json.loads((cli_dir / f"{name}.npy.json").read_text())
            assert (grid.x0_mm, grid.y0_mm, grid.dx_mm, grid.dy_mm) == (side["x0_mm"], side["y0_mm"], side["dx_mm"], side["dy_mm"])
    else:  # N-buffer: the needles' CSV holds the offsets to 7 decimals
        table = np.genfromtxt(cli_dir / "needles.csv", delimiter=",", names=True)
        assert result.surface is None
        np.testing.assert_allclose(result.needle_offset_mm, table["surface_offset_mm"], atol=5e-8, equal_nan=True)
        np.testing.assert_allclose(result.needle_deviation_mm, table["deviation_mm"], atol=5e-8, equal_nan=True)


def test_run_without_out_equals_cli_figures(cli, parts, tmp_path):
    """job.run() with no directory: the same report figures and marks, nothing written."""
    job_file = parts / "plane_cylinder" / "job_fast.toml"
    cli_dir = tmp_path / "cli"
    run_cli(cli, "run", job_file, "--out", cli_dir, "--no-render", "--quiet")
    result = vmsim.load_job(job_file).run()
    assert result.out is None and result.files == []
    cli_report = json.loads((cli_dir / "report.json").read_text())
    for key in ("marks", "removal", "contour_error", "surface", "axis_following_error", "interpolation", "reference"):
        assert result.report[key] == cli_report[key], key
    # The mark the feed-drive simulation paper reports at the fillet (about 0.02 mm at 10 m/min): an overcut.
    assert result.marks
    assert 0.010 < result.marks[0]["depth_mm"] < 0.030


def test_mesh_made_on_request_equals_the_clis_part_stl(cli, parts, tmp_path):
    """Result.mesh of a z-map run is made on first access (the run itself only counts its triangles): the same
    triangles as the part.stl the CLI wrote and as report.json's surface.mesh_triangles."""
    job_file = parts / "plane_cylinder" / "job_fast.toml"
    if not job_file.is_file():
        pytest.skip(f"{job_file} is absent")
    cli_dir = tmp_path / "cli"
    run_cli(cli, "run", job_file, "--out", cli_dir, "--no-render", "--quiet")
    result = vmsim.load_job(job_file).run()
    mesh = result.mesh
    assert mesh is not None
    stl = (cli_dir / "part.stl").read_bytes()
    stl_triangles = int.from_bytes(stl[80:84], "little")  # binary STL: the count after the 80-byte header
    report = json.loads((cli_dir / "report.json").read_text())
    assert mesh.triangles.shape[0] == stl_triangles == report["surface"]["mesh_triangles"]
