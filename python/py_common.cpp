#include "python/py_common.hpp"

#include "core/error.hpp"

#include <Python.h>

namespace vmsim::python {

py::object to_python(const nlohmann::json& j) {
  static py::object loads = py::module_::import("json").attr("loads");
  return loads(py::str(j.dump()));
}

PyProgress::PyProgress(py::object callback) : callback_(std::move(callback)), last_(std::chrono::steady_clock::now()) {}

void PyProgress::stage(const std::string& name, double total) {
  stage_ = name;
  total_ = total;
  poll(0, true);
}

void PyProgress::update(double done) { poll(done, false); }

void PyProgress::done() { poll(total_, true); }

void PyProgress::poll(double done, bool force) {
  if (pending_) throw Interrupted{};
  const auto now = std::chrono::steady_clock::now();
  if (!force && now - last_ < std::chrono::milliseconds(100)) return;
  last_ = now;
  py::gil_scoped_acquire gil;
  // Signal handlers run only in the main thread; elsewhere this returns 0 and Ctrl-C waits for the call to end.
  if (PyErr_CheckSignals() != 0) {
    pending_.emplace();  // takes the pending KeyboardInterrupt
    throw Interrupted{};
  }
  if (callback_.is_none()) return;
  try {
    callback_(stage_, done, total_);
  } catch (py::error_already_set& e) {
    pending_.emplace(std::move(e));
    throw Interrupted{};
  }
}

void PyProgress::raise_pending() {
  if (!pending_) throw std::logic_error("vmsim: interrupted without a pending Python exception");
  py::error_already_set e = std::move(*pending_);
  pending_.reset();
  throw e;
}

void bind_common(py::module_& m) {
  py::register_exception<core::Error>(m, "Error", PyExc_RuntimeError);
  m.attr("Error").attr("__doc__") =
      "vmsim's errors: the message names the file, the line or key, and what was expected (as the CLI prints it).";
}

}  // namespace vmsim::python
