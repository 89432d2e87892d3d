"""python/examples run as scripts (what a user does) and write what they say, with and without matplotlib.

References: the feed-drive simulation paper's trend (the mark deepens with the feed), the analytic case the scan
example builds (after registration the deviation is the added noise, 0.5 um rms), and the examples' own CSV.
"""
import csv
import importlib.util
import os
import pathlib
import subprocess
import sys

import pytest

EXAMPLES = pathlib.Path(__file__).resolve().parents[1] / "examples"


def run_example(name, out, no_matplotlib):
    env = dict(os.environ)
    if no_matplotlib:
        env["VMSIM_NO_MATPLOTLIB"] = "1"
    p = subprocess.run([sys.executable, str(EXAMPLES / name), "--quick", "--out", str(out)], capture_output=True,
                       text=True, env=env, timeout=1200)
    assert p.returncode == 0, p.stderr
    return p.stdout


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


HAVE_MPL = importlib.util.find_spec("matplotlib") is not None


@pytest.mark.parametrize("no_mpl", [True, False] if HAVE_MPL else [True])
def test_mark_vs_feed(parts, tmp_path, no_mpl):
    run_example("mark_vs_feed.py", tmp_path, no_mpl)
    rows = read_csv(tmp_path / "mark_vs_feed.csv")
    assert [float(r["feed_m_per_min"]) for r in rows] == [2.5, 10.0]
    slow, fast = (float(r["mark_depth_mm"]) for r in rows)
    assert fast > slow and 0.010 < fast < 0.030
    assert (tmp_path / "mark_vs_feed.png").exists() == (not no_mpl)


def test_gain_study(parts, tmp_path):
    run_example("gain_study.py", tmp_path, not HAVE_MPL)
    rows = read_csv(tmp_path / "gain_study.csv")
    following = [float(r["x_following_error_max_um"]) for r in rows]
    # A stiffer position loop follows more closely (P + feedforward cascade): the following error falls with Kv.
    assert following[0] > following[1] > following[2]


def test_scan_comparison(parts, tmp_path):
    run_example("scan_comparison.py", tmp_path, not HAVE_MPL)
    values = {r["quantity"]: r["value"] for r in read_csv(tmp_path / "scan_comparison.csv")}
    assert abs(float(values["deviation_rms_mm"]) - 0.0005) < 0.0001  # the noise added (0.5 um)
    assert abs(float(values["deviation_mean_mm"])) < 0.0001          # offset and tilt taken out by the registration
    assert int(values["outliers_masked"]) >= 15                       # of the 20 spikes
