// The compiled part of the Python module `vmsim` (vmsim._vmsim): the chain as a library (sim/ and the modules below
// it), never the command line. python/vmsim/__init__.py re-exports it with the pure-Python helpers.
#include "python/py_common.hpp"
#include "python/py_types.hpp"
#include "sim/report.hpp"

PYBIND11_MODULE(_vmsim, m) {
  m.doc() =
      "vmsim: virtual machining (program -> interpolator -> drives -> material removal -> surfaces -> metrology) "
      "as a library. Units are in the names (mm, s, rad; feed_mm_per_min).";
  m.attr("__version__") = vmsim::sim::version();
  vmsim::python::bind_common(m);
  vmsim::python::bind_values(m);
  vmsim::python::bind_job(m);
  vmsim::python::bind_metrology(m);
  vmsim::python::bind_methods(m);
}
