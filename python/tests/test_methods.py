"""The papers' methods from Python give what their commands give on the parts.

Reference: `vmsim oga`, `vmsim plan-feed`, `vmsim compensate` (the CLI) on the same job with the same options: every
figure of report.json that the library computes (not the files, images, timings or MPI ranks the command adds), and
the files the command writes from the arrays Python returns (compensated.ngc, gain_schedule.csv, feed_plan.csv).
"""
import json

import numpy as np
import pytest

import vmsim
from conftest import run_cli

ADDED_BY_COMMAND = {"files", "images", "mpi_ranks"}


def clean(j):
    """Without the times (wall-clock figures differ from run to run)."""
    if isinstance(j, dict):
        return {k: clean(v) for k, v in j.items() if "seconds" not in k and k != "timings_s"}
    if isinstance(j, list):
        return [clean(x) for x in j]
    return j


def same_figures(py_report, cli_report):
    keys = set(cli_report) - ADDED_BY_COMMAND
    assert set(py_report) == keys
    assert clean(py_report) == clean({k: cli_report[k] for k in keys})


def csv_columns(path):
    """{column: float array} of a vmsim CSV (its '#' lines are comments)."""
    lines = [ln for ln in path.read_text().splitlines() if ln and not ln.startswith("#")]
    names = lines[0].split(",")
    data = np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]])
    return {n: data[:, k] for k, n in enumerate(names)}


def test_oga(cli, parts, tmp_path):
    job = parts / "oga_profile" / "job.toml"
    run_cli(cli, "oga", job, "--kp-grid", "3:1:5", "--kf-grid", "0.8:0.2:1.2", "--no-render", "--out", tmp_path)
    r = vmsim.oga(vmsim.load_job(job), kp_grid=(3, 1, 5), kf_grid=(0.8, 0.2, 1.2))
    same_figures(r["report"], json.loads((tmp_path / "report.json").read_text()))
    table = csv_columns(tmp_path / "gain_schedule.csv")
    c2 = r["c2"]
    assert c2["kv_1000_per_min"].shape == (r["setpoints"].samples, len(c2["axis_names"]))
    for k, axis in enumerate(c2["axis_names"]):
        # The CSV holds 17 significant digits: it reads back bit for bit.
        np.testing.assert_array_equal(c2["kv_1000_per_min"][:, k], table[f"{axis}_kv_1000_per_min"])


def test_plan_feed(cli, parts, tmp_path):
    job = parts / "feedplan" / "job_fan.toml"
    run_cli(cli, "plan-feed", job, "--no-render", "--out", tmp_path)
    r = vmsim.plan_feed(vmsim.load_job(job))
    same_figures(r["report"], json.loads((tmp_path / "report.json").read_text()))
    plan = csv_columns(tmp_path / "feed_plan.csv")
    np.testing.assert_array_equal(r["ceiling_s_mm"], plan["s_mm"])
    np.testing.assert_array_equal(r["ceiling_feed_mm_per_s"], plan["feed_ceiling_mm_per_s"])
    assert r["ceiling_feed_mm_per_s"].shape == r["ceiling_s_mm"].shape


def test_compensate(cli, parts, tmp_path):
    job = parts / "starfish" / "job.toml"
    run_cli(cli, "compensate", job, "--no-render", "--out", tmp_path)
    r = vmsim.compensate(vmsim.load_job(job))
    same_figures(r["report"], json.loads((tmp_path / "report.json").read_text()))
    assert r["program_text"] == (tmp_path / f"compensated.{r['program_extension']}").read_text()
    sp = r["original_setpoints"]
    assert r["setpoints"].shape == sp.position.shape
    # The paper's claim on this part: the predicted contour error falls.
    assert r["predicted_after_max_mm"] < r["predicted_before_max_mm"]


def test_method_errors(parts):
    with pytest.raises(vmsim.Error, match="kp_grid"):
        vmsim.oga(vmsim.load_job(parts / "oga_profile" / "job.toml"), kp_grid=(5, 1, 3))
    with pytest.raises(vmsim.Error, match="feedplan"):
        vmsim.plan_feed(vmsim.load_job(parts / "starfish" / "job.toml"))


def test_identify(cli, parts, tmp_path):
    """A trace `vmsim motion` writes, identified by Python and by `vmsim identify`: the same models and figures."""
    run_cli(cli, "motion", parts / "starfish" / "job.toml", "--out", tmp_path / "motion")
    trace = tmp_path / "motion" / "trace.csv"
    run_cli(cli, "identify", "--trace", trace, "--out", tmp_path / "id")
    cli_axes = json.loads((tmp_path / "id" / "report.json").read_text())["axes"]
    py_axes = vmsim.identify([trace], save_to=tmp_path / "axis_models.toml")
    assert set(py_axes) == set(cli_axes)
    for name, a in py_axes.items():
        c = cli_axes[name]
        assert a["chosen"] == c["chosen"] and a["orders"] == c["orders"]
        for s, m in a["models"].items():
            cm = c["models"][s]
            assert m["b"].tolist() == cm["b"] and m["a"].tolist() == cm["a"]
            assert m["mse"] == cm["validation"]["mse"] and m["fit_percent"] == cm["validation"]["fit_percent"]
    # The model file Python wrote drives a job as the CLI's does.
    assert (tmp_path / "axis_models.toml").read_text().count("[[axes]]") == len(py_axes)
