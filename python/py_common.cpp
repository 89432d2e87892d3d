#include "python/py_common.hpp"

#include "core/error.hpp"

#include <Python.h>

namespace vmsim::python {

py::object to_python(const nlohmann::json& j) {
  // Imported per call (sys.modules caches it): a static py::object would be released after the interpreter ends.
  return py::module_::import("json").attr("loads")(py::str(j.dump()));
}

PyProgress::PyProgress(py::object callback)
    : owner_(std::this_thread::get_id()), callback_(std::move(callback)), last_(std::chrono::steady_clock::now()) {}

void PyProgress::stage(const std::string& name, double total) {
  if (std::this_thread::get_id() != owner_) return;
  stage_ = name;
  total_ = total;
  poll(0, true);
}

void PyProgress::update(double done) { poll(done, false); }

void PyProgress::done() { poll(total_, true); }

bool PyProgress::keep_going() {
  if (std::this_thread::get_id() != owner_) return true;
  return !check(0, false);
}

void PyProgress::poll(double done, bool force) {
  if (std::this_thread::get_id() != owner_) return;
  if (check(done, force)) throw Interrupted{};
}

bool PyProgress::check(double done, bool force) {
  if (pending_) return true;
  const auto now = std::chrono::steady_clock::now();
  if (!force && now - last_ < std::chrono::milliseconds(100)) return false;
  last_ = now;
  py::gil_scoped_acquire gil;
  // Signal handlers run only in Python's main thread; called from another, this returns 0 and Ctrl-C waits.
  if (PyErr_CheckSignals() != 0) {
    pending_.emplace();  // takes the pending KeyboardInterrupt
    return true;
  }
  if (callback_.is_none()) return false;
  try {
    callback_(stage_, done, total_);
  } catch (py::error_already_set& e) {
    pending_.emplace(std::move(e));
    return true;
  }
  return false;
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
