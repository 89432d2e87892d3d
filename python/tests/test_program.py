"""Programs and machines from Python against the command line: vmsim.canon is `vmsim canon`'s output line for line
(which the program tests hold against LinuxCNC's `rs274 -g`), and a machine file reads as the job reads it."""
import pytest

import vmsim
from conftest import run_cli


def test_canon_equals_cli(cli, parts):
    ngc = parts / "plane_cylinder" / "plane_cylinder_fast.ngc"
    tbl = parts / "plane_cylinder" / "tools.tbl"
    expected = run_cli(cli, "canon", ngc, "--tool-table", tbl).stdout.splitlines()
    assert vmsim.canon(ngc, tool_table=tbl) == expected
    with pytest.raises(vmsim.Error, match=f"{ngc}:6"):
        vmsim.canon(ngc)  # G43 without the tool table: located at the line


def test_load_machine(parts):
    m = vmsim.load_machine(parts / "machines" / "mikron_ucp710.toml")
    job = vmsim.load_job(parts / "plane_cylinder" / "job_fast.toml")
    assert m.axis_names == job.machine.axis_names
    x = m.axes[m.axis_names.index("X")]
    # Units inside: mm/s (the file gives m/min: 30 m/min on the Mikron's X, Duong et al. Table I).
    assert x["max_velocity"] == pytest.approx(30e3 / 60)
    assert x["kind"] == "linear" and x["has_drive"]
