"""vmsim: virtual machining from Python.

The chain vmsim runs - program -> interpolator -> servo drives -> kinematics -> material removal -> surfaces ->
metrology - as a library, with numpy arrays. Units are in the names: mm, s, rad, feed_mm_per_min.

    import vmsim
    job = vmsim.load_job("parts/plane_cylinder/job.toml")
    job.override("feed_scale", 0.5)
    result = job.run()
    print(result.marks[0]["depth_mm"], result.deviation.z_mm.shape)

Errors are vmsim.Error (a RuntimeError) carrying vmsim's message: the file, line or key, and what was expected.
Long calls release the GIL and stop with KeyboardInterrupt on Ctrl-C.
"""
from ._vmsim import *  # noqa: F401,F403
from ._vmsim import __version__, Error  # noqa: F401

Error.__module__ = __name__  # tracebacks say vmsim.Error, the name users catch
