"""Shared fixtures of the Python module's tests (python/tests, run by ctest `python` through `make test`).

The tests hold the module against the command line built beside it (VMSIM_CLI): the same job through both must
give the same files and figures. They skip with a message when the CLI or a part is absent.
"""
import os
import pathlib
import subprocess

import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("VMSIM_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))
PARTS = SOURCE_DIR / "parts"


@pytest.fixture(scope="session")
def cli():
    exe = os.environ.get("VMSIM_CLI") or str(SOURCE_DIR / "build" / "app" / "vmsim")
    if not os.access(exe, os.X_OK):
        pytest.skip(f"the vmsim command line is not built ({exe}); set VMSIM_CLI")
    return exe


@pytest.fixture(scope="session")
def parts():
    if not PARTS.is_dir():
        pytest.skip(f"{PARTS}: the parts folder is absent")
    return PARTS


def run_cli(cli, *args, cwd=None, check=True):
    """Runs `vmsim ARGS...`, returns the CompletedProcess (text)."""
    p = subprocess.run([cli, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=1200)
    if check and p.returncode != 0:
        raise AssertionError(f"vmsim {' '.join(map(str, args))} failed ({p.returncode}):\n{p.stderr}")
    return p
