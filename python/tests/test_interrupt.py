"""A long call releases the GIL and stops on Ctrl-C: a python3 child running a long job gets SIGINT and ends with
KeyboardInterrupt within a bound; the progress callback sees the stages, and an exception it raises stops the call.

Reference: the signal's own semantics (Python raises KeyboardInterrupt in the main thread) and wall-clock time
measured here; the bound is the longest stretch the chain runs between two progress checks on this job.
"""
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

import vmsim

CHILD = r"""
import sys, time, vmsim
job = vmsim.load_job(sys.argv[1])
job.override("feed_scale", float(sys.argv[2]))
print("start", flush=True)
t0 = time.monotonic()
try:
    job.run()
except KeyboardInterrupt:
    print("interrupted", flush=True)
    sys.exit(42)
print("finished after %.1f s" % (time.monotonic() - t0), flush=True)
"""

# Seconds from SIGINT to the child's exit: progress is checked at every stage of the chain and every ~100 ms within
# the interpolator's and the drives' loops; the removal of one job is one stage.
BOUND_S = 10.0


def test_sigint_ends_a_long_run_with_keyboard_interrupt(parts):
    job = parts / "plane_cylinder" / "job_fast.toml"
    env = dict(os.environ)
    p = subprocess.Popen([sys.executable, "-c", CHILD, str(job), "0.1"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True, env=env)
    try:
        assert p.stdout.readline().strip() == "start"
        time.sleep(3.0)  # well inside the run (tens of seconds at a tenth of the feeds)
        assert p.poll() is None, "the job ended before the signal: choose a longer one"
        t0 = time.monotonic()
        p.send_signal(signal.SIGINT)
        rc = p.wait(timeout=120)
        elapsed = time.monotonic() - t0
    finally:
        if p.poll() is None:
            p.kill()
    out, err = p.communicate()
    assert rc == 42, f"exit {rc}, stdout {out!r}, stderr {err!r}"
    assert "interrupted" in out
    assert elapsed < BOUND_S, f"{elapsed:.1f} s from SIGINT to exit"


def test_progress_callback_and_its_exception(parts):
    job = vmsim.load_job(parts / "plane_cylinder" / "job_fast.toml")
    seen = []
    job.interpolate(progress=lambda stage, done, total: seen.append((stage, done, total)))
    assert seen and seen[0][0] == "plane_cylinder_fast: interpolation"

    class Stop(Exception):
        pass

    def stop(stage, done, total):
        raise Stop(stage)

    with pytest.raises(Stop):
        job.simulate(progress=stop)


def test_gil_released_during_a_call(parts):
    """Another Python thread runs while the chain computes (the GIL is released)."""
    job = vmsim.load_job(parts / "plane_cylinder" / "job_fast.toml")
    ticks = []
    done = threading.Event()

    def ticker():
        while not done.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.01)

    t = threading.Thread(target=ticker)
    t.start()
    t0 = time.monotonic()
    job.simulate()
    t1 = time.monotonic()
    done.set()
    t.join()
    inside = [x for x in ticks if t0 < x < t1]
    assert t1 - t0 < 0.2 or len(inside) > 0.3 * (t1 - t0) / 0.01
