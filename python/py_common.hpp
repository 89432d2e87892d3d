#pragma once
// What every part of the Python module shares: JSON <-> Python objects, the progress that forwards to a Python
// callback and turns Ctrl-C into KeyboardInterrupt, and the call wrapper that releases the GIL around long calls.
#include "core/progress.hpp"

#include <nlohmann/json.hpp>
#include <pybind11/pybind11.h>

#include <chrono>
#include <optional>
#include <string>
#include <thread>
#include <utility>

namespace vmsim::python {

namespace py = pybind11;

// A report (nlohmann::json) as Python dicts, lists, floats, ints, strings (through json.loads: doubles keep every
// digit, as report.json holds them).
py::object to_python(const nlohmann::json& j);

// Thrown out of library code when a Python exception is pending (Ctrl-C, or the progress callback raised). Not a
// std::exception, so that library code catching std::exception to add context does not swallow it.
struct Interrupted {};

// core::Progress for a call from Python: forwards each stage and its work to `callback(stage, done, total)` (None:
// no callback) and checks for signals (Ctrl-C) at every stage boundary and, within a stage, at most every ~100 ms
// with the GIL re-acquired; a pending Python exception is kept and Interrupted thrown to unwind the library call
// (keep_going() returns false instead, for loops in parallel regions). Calls from other threads than the caller's
// (OpenMP workers) do nothing: Python sees signals on its main thread only, and the callback is not thread-safe.
class PyProgress : public core::Progress {
 public:
  explicit PyProgress(py::object callback);
  void stage(const std::string& name, double total) override;
  void update(double done) override;
  void done() override;
  bool keep_going() override;
  // The kept Python exception, raised again (after the call has unwound and the GIL is held).
  [[noreturn]] void raise_pending();

 private:
  // Whether a Python exception is pending now (checks signals and calls the callback at most every ~100 ms).
  bool check(double done, bool force);
  void poll(double done, bool force);
  std::thread::id owner_;  // the thread that called from Python: signals are seen there only
  py::object callback_;
  std::string stage_;
  double total_ = 0;
  std::chrono::steady_clock::time_point last_;
  std::optional<py::error_already_set> pending_;
};

// Runs f(progress) with the GIL released; a Ctrl-C or an exception from the callback comes out as that Python
// exception, core::Error as vmsim.Error (the module's exception translator).
template <class F>
auto call_released(const py::object& callback, F&& f) {
  PyProgress progress(callback);
  try {
    const core::AmbientProgress ambient(progress);  // the drives' loops ask it whether to go on
    py::gil_scoped_release release;
    return f(static_cast<core::Progress&>(progress));
  } catch (const Interrupted&) {
    progress.raise_pending();
  }
}

// The optional `progress=` argument every long call takes, and its help text.
inline constexpr const char* kProgressDoc =
    "progress: None, or a callable progress(stage: str, done: float, total: float) called at each stage's start and "
    "end, and about every 0.1 s inside the drives' loops (total 0 when unknown); an exception it raises stops the "
    "call. Ctrl-C stops the call with "
    "KeyboardInterrupt.";

void bind_common(py::module_& m);
void bind_job(py::module_& m);
void bind_metrology(py::module_& m);
void bind_methods(py::module_& m);

}  // namespace vmsim::python
