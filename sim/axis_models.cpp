#include "sim/axis_models.hpp"

#include "core/error.hpp"
#include "sysid/axis_model_file.hpp"
#include "drives/discrete_tf_axis.hpp"

#include <fmt/format.h>

#include <cmath>

namespace vmsim::sim {

JobAxisModels job_axis_models(const core::Job& job, const std::optional<std::filesystem::path>& override_file) {
  JobAxisModels out;
  out.per_axis.assign(job.machine.axes.size(), nullptr);
  out.file = override_file ? override_file : job.axis_models_file;
  if (!out.file) return out;
  const sysid::AxisModelFile models = sysid::load_axis_models(*out.file);
  const std::string f = out.file->string();
  if (std::abs(models.period_s - job.interp.period_s) > 1e-9 * job.interp.period_s)
    throw core::Error(core::located(
        f, 0,
        fmt::format("[model] period_ms = {} but the job {} interpolates every {} ms: identify the axes at the "
                    "job's Te",
                    models.period_s * 1e3, job.file.string(), job.interp.period_s * 1e3)));
  for (const sysid::IdentifiedAxis& a : models.axes) {
    std::size_t i = 0;
    while (i < job.machine.axes.size() && job.machine.axes[i].name != a.name) ++i;
    if (i == job.machine.axes.size())
      throw core::Error(core::located(
          f, 0, fmt::format("axis {} is not an axis of the machine {}", a.name, job.machine.source_file)));
    try {
      out.owned.push_back(std::make_unique<drives::DiscreteTfAxis>(a.tf));
    } catch (const core::Error& e) {
      throw core::Error(core::located(f, 0, fmt::format("axis {}: {}", a.name, e.what())));
    }
    out.per_axis[i] = out.owned.back().get();
    out.identified_axes.push_back(a.name);
  }
  return out;
}

}  // namespace vmsim::sim
