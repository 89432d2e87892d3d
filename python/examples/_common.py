"""What the examples share: where the parts are, the output folder, and matplotlib when it is there."""
import argparse
import os
import pathlib

PARTS = pathlib.Path(__file__).resolve().parents[2] / "parts"


def arguments(description):
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--out", type=pathlib.Path, default=pathlib.Path("."), help="folder for the CSV (and PNG) files")
    p.add_argument("--quick", action="store_true", help="fewer points (what `make test` runs)")
    a = p.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    return a


def pyplot():
    """matplotlib.pyplot with a file-only backend, or None when matplotlib is absent (or VMSIM_NO_MATPLOTLIB is set)."""
    if os.environ.get("VMSIM_NO_MATPLOTLIB"):
        return None
    try:
        import matplotlib
    except ImportError:
        return None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt
