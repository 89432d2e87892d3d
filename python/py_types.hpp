#pragma once
// The C++ values the module hands to Python, each owned by its Python object (shared_ptr holders); arrays are numpy
// views of their Eigen members (no copy; the view keeps its owner alive), except where the C++ layout is an array
// of structs (program moves, marks): those are copied into arrays once.
#include "core/height_grid.hpp"
#include "core/job.hpp"
#include "core/mesh.hpp"
#include "core/toolpath.hpp"
#include "python/py_common.hpp"

#include <pybind11/numpy.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::python {

// A job as loaded, with the files its overrides were written to (kept while anything loaded from them lives).
struct TempDir {
  std::filesystem::path path;
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
};

struct LoadedJob {
  std::shared_ptr<TempDir> dir;  // null without overrides: the job is its own file
  core::Job job;
};

// A grid handed to Python: owned by the Python object (a run's grids are moved into it).
using GridPtr = std::shared_ptr<core::HeightGrid>;

// Grid and Mesh classes; needed by the job's results and by metrology.
void bind_values(py::module_& m);

// 1-D views of an Eigen array, kept alive by `owner` (the Python object holding it).
py::array_t<double> view_of(const Eigen::ArrayXd& a, py::handle owner);
py::array_t<int> view_of(const Eigen::ArrayXi& a, py::handle owner);

}  // namespace vmsim::python
