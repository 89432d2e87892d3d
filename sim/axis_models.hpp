#pragma once
// The axis models a job runs on: the machine file's cascades, or for the axes an identified-model file names (the
// job's [job] axis_models, or a command's --axis-models) their identified transfer functions (the
// predictive-compensation paper).
#include "core/job.hpp"
#include "drives/axis_model.hpp"

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace vmsim::sim {

struct JobAxisModels {
  std::vector<std::unique_ptr<drives::AxisModel>> owned;
  std::vector<const drives::AxisModel*> per_axis;  // machine-axis order; null: the cascade of [axes.drive]
  std::optional<std::filesystem::path> file;       // the identified-model file, when one is used
  std::vector<std::string> identified_axes;        // the axes it replaces
  bool any() const { return !identified_axes.empty(); }
};

// `override_file` wins over the job's [job] axis_models. Throws core::Error naming the model file when its period is
// not the job's Te or it names an axis the machine does not have.
JobAxisModels job_axis_models(const core::Job& job, const std::optional<std::filesystem::path>& override_file);

}  // namespace vmsim::sim
