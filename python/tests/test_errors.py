"""Bad input raises vmsim.Error (a RuntimeError) carrying vmsim's located message: the file, the line or key, and
what was expected - the same message the command line prints for the same input (the reference)."""
import shutil

import pytest

import vmsim
from conftest import run_cli


def copy_job(parts, tmp_path, edit):
    src = parts / "plane_cylinder"
    for f in src.iterdir():
        if f.is_file():
            shutil.copy(f, tmp_path / f.name)
    job = tmp_path / "job_fast.toml"
    job.write_text(edit(job.read_text()))
    # The machine file is named relative to the part's folder.
    job.write_text(job.read_text().replace('"../machines/', f'"{parts}/machines/'))
    return job


def test_error_is_runtime_error():
    assert issubclass(vmsim.Error, RuntimeError)


def test_unknown_key_names_file_and_key(cli, parts, tmp_path):
    job = copy_job(parts, tmp_path, lambda t: t.replace("tolerance_mm = 0.020", "tolerance_mm = 0.020\ntolerence = 1"))
    with pytest.raises(vmsim.Error) as e:
        vmsim.load_job(job)
    msg = str(e.value)
    assert str(job) in msg and "tolerence" in msg
    cli_out = run_cli(cli, "run", job, "--out", tmp_path / "out", "--no-render", check=False)
    assert cli_out.returncode != 0 and msg in cli_out.stderr


def test_bad_program_line_is_located(cli, parts, tmp_path):
    job = copy_job(parts, tmp_path, lambda t: t)
    ngc = tmp_path / "plane_cylinder_fast.ngc"
    lines = ngc.read_text().splitlines()
    lines.insert(3, "G1 X1 Q")  # line 4: a word without a value
    ngc.write_text("\n".join(lines) + "\n")
    with pytest.raises(vmsim.Error) as e:
        vmsim.read_program(ngc)
    assert f"{ngc}:4" in str(e.value)
    with pytest.raises(vmsim.Error) as e2:
        vmsim.load_job(job).interpolate()
    assert f"{ngc}:4" in str(e2.value)


def test_missing_file():
    with pytest.raises(vmsim.Error) as e:
        vmsim.load_job("/nonexistent/job.toml")
    assert "/nonexistent/job.toml" in str(e.value)


def test_refused_override_names_key_and_leaves_job(parts):
    job = vmsim.load_job(parts / "plane_cylinder" / "job_fast.toml")
    with pytest.raises(vmsim.Error) as e:
        job.override("interpolation.tolerance_mm", "fine")
    assert "tolerance_mm" in str(e.value)
    with pytest.raises(vmsim.Error) as e:
        job.override("machine.axes.Q.drive.kv_1000_per_min", 3)
    assert "'Q'" in str(e.value) and "X" in str(e.value)
    assert job.overrides == {}
    assert job["interpolation.tolerance_mm"] == pytest.approx(0.02)
    with pytest.raises(KeyError):
        job["interpolation.no_such_key"]
