"""Metrology from Python against the command line and known answers.

References: `vmsim stats` (the CLI) on the same file for the areal parameters and the grid it reads; the CLI's own
surface.npy for what read_surface gives of its surface.x3p; a real scan written by another program
(../shared/data/real/scans, skipped when absent); and constructed cases whose deviation is known (a constant offset).
"""
import json
import os
import pathlib

import numpy as np
import pytest

import vmsim
from conftest import run_cli

SHARED = pathlib.Path(os.environ.get("VMSIM_SHARED_DIR", pathlib.Path(__file__).resolve().parents[3] / "shared"))


@pytest.fixture(scope="module")
def cli_run(cli, parts, tmp_path_factory):
    out = tmp_path_factory.mktemp("cli")
    run_cli(cli, "run", parts / "plane_cylinder" / "job_fast.toml", "--out", out, "--no-render", "--quiet")
    return out


def stats(cli, path, *args):
    return json.loads(run_cli(cli, "stats", path, *args).stdout)


def test_read_surface_x3p_equals_npy(cli_run):
    g = vmsim.read_surface(cli_run / "surface.x3p")
    ref = np.load(cli_run / "surface.npy")
    assert g.format == "x3p" and g.z_mm.shape == ref.shape
    assert g.z_mm.flags.c_contiguous and g.z_mm.strides == (8 * g.nx, 8)
    assert g.mask.all() == np.isfinite(ref).all()
    # X3P holds the heights in metres as float64: mm -> m -> mm may move the last bit.
    np.testing.assert_allclose(g.z_mm, ref, rtol=0, atol=1e-12)
    assert g.x_mm[1] - g.x_mm[0] == pytest.approx(g.dx_mm) and len(g.y_mm) == g.ny


@pytest.mark.parametrize("options,level,filters", [
    (["--level", "none"], "none", None),
    (["--level", "plane", "--filter", "L:0.8mm"], "plane", [("L", 0.8)]),
])
def test_areal_equals_vmsim_stats(cli, cli_run, options, level, filters):
    path = cli_run / "surface.x3p"
    expected = stats(cli, path, *options)["areal"]
    expected.pop("reference")
    got = vmsim.areal(vmsim.read_surface(path), level=level, filters=filters)
    assert {k: got[k] for k in expected} == expected


def test_real_scan(cli):
    scan = SHARED / "data" / "real" / "scans" / "sample-land.x3p"
    if not scan.is_file():
        pytest.skip(f"{scan} is absent (../shared)")
    g = vmsim.read_surface(scan)
    s = stats(cli, scan, "--level", "none")
    assert (g.nx, g.ny) == (s["grid"]["nx"], s["grid"]["ny"])
    assert int((~g.mask).sum()) == s["grid"]["invalid_points"]
    assert vmsim.areal(g, level="none")["Sq_mm"] == s["areal"]["Sq_mm"]


def test_write_x3p_round_trip(tmp_path):
    rng = np.random.default_rng(3)
    z = rng.normal(0, 0.01, (40, 60))
    z[5, 7] = np.nan
    g = vmsim.Grid(z, 0.002, 0.003, x0_mm=1.0, y0_mm=-2.0)
    vmsim.write_x3p(tmp_path / "g.x3p", g, comment="round trip")
    back = vmsim.read_surface(tmp_path / "g.x3p")
    assert (back.dx_mm, back.dy_mm) == pytest.approx((0.002, 0.003))
    assert not back.mask[5, 7] and back.mask.sum() == z.size - 1
    np.testing.assert_allclose(back.z_mm, z, rtol=0, atol=1e-12)


def test_compare_known_offset(cli_run):
    predicted = vmsim.read_surface(cli_run / "surface.x3p")
    measured = vmsim.Grid(predicted.z_mm + 0.003, predicted.dx_mm, predicted.dy_mm, predicted.x0_mm, predicted.y0_mm)
    as_is = vmsim.compare(measured, predicted, align=False, outlier_sigma=0)
    assert as_is["stats"]["mean_mm"] == pytest.approx(0.003, abs=1e-9)
    assert as_is["stats"]["rms_mm"] == pytest.approx(0.003, abs=1e-9)
    assert as_is["deviation"].z_mm.shape == predicted.z_mm.shape
    aligned = vmsim.compare(measured, predicted)  # the registration takes the offset out
    assert abs(aligned["stats"]["mean_mm"]) < 1e-5
    assert aligned["transform"][2, 3] == pytest.approx(-0.003, abs=1e-5)


def test_grid_errors():
    with pytest.raises(vmsim.Error, match="dx_mm"):
        vmsim.Grid(np.zeros((3, 3)), 0.0)
    with pytest.raises(vmsim.Error, match="2-D"):
        vmsim.Grid(np.zeros(3), 0.1)
    with pytest.raises(vmsim.Error, match="filters"):
        vmsim.areal(vmsim.Grid(np.zeros((3, 3)), 0.1), filters=[("X", 0.8)])
