#pragma once
// The Job of the Python module and the results of its chain.
#include "python/py_types.hpp"
#include "sim/study.hpp"

#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>
#include <vector>

namespace vmsim::python {

// A job file and the overrides set on it from Python. Every override reloads the job (as a study variation does), so
// a refused key fails at once, naming it; calls in flight keep the job they started with (shared_ptr).
class PyJob {
 public:
  explicit PyJob(const std::filesystem::path& path);
  const core::Job& job() const { return loaded_->job; }
  std::shared_ptr<const LoadedJob> loaded() const { return loaded_; }
  const std::filesystem::path& file() const { return file_; }
  double feed_scale() const;
  py::object get(const std::string& key) const;
  void override_key(const std::string& key, py::handle value);
  void reset();
  nlohmann::json overrides_json() const;

 private:
  void reload();
  std::filesystem::path file_;
  std::vector<sim::StudyOverride> overrides_;
  std::shared_ptr<const LoadedJob> loaded_;
};

// Setpoints, Response, Motion, Result (py_results.cpp).
void bind_results(py::module_& m);
py::object interpolate_job(const PyJob& job, py::object progress);
py::object simulate_job(const PyJob& job, bool full_rate_trace, py::object progress);
py::object run_job(const PyJob& job, std::optional<std::filesystem::path> out, bool render, py::object progress);

}  // namespace vmsim::python
