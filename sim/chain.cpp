#include "sim/chain.hpp"

#include "core/error.hpp"
#include "methods/oga_schedule.hpp"
#include "motion/kinematics.hpp"

#include <algorithm>

namespace vmsim::sim {

Chain::Chain(const core::Job& job, const ChainOptions& options)
    : job_(&job), options_(options), axis_models_(job_axis_models(job, options.axis_models_file)) {
  interp_.period_s = job.interp.period_s;
  interp_.tolerance_mm = job.interp.tolerance_mm;
  interp_.feed_scale = options.feed_scale;
  // A gain schedule holds gains for the setpoints of the job's own feeds.
  if (job.gain_schedule_file && !options.ignore_gain_schedule) {
    if (options.feed_scale != 1.0)
      throw core::Error(job.file.string() + ": --feed-scale changes the setpoints its gain_schedule was computed for "
                        "(run vmsim oga on a job at those feeds instead)");
    gain_schedule_file_ = job.gain_schedule_file;
  }
}

motion::InterpResult Chain::interpolate(const core::ToolPath& program) const {
  return motion::interpolate(motion::toolpath_in_axis_space(program, job_->machine), job_->machine, interp_);
}

drives::AxisResponse Chain::simulate(const core::Setpoints& setpoints, bool full_rate_trace) const {
  drives::SimulateOptions sopt;
  sopt.full_rate_trace = full_rate_trace;
  drives::GainSchedule schedule;
  if (gain_schedule_file_) {
    schedule = methods::read_gain_schedule(*gain_schedule_file_, setpoints, job_->machine);
    sopt.gains = &schedule;
  }
  if (axis_models_.any()) sopt.axis_models = &axis_models_.per_axis;
  return drives::simulate_axes(setpoints, job_->machine, sopt);
}

Eigen::VectorXd tool_length_offsets(const core::ToolPath& program, const core::Setpoints& setpoints) {
  Eigen::VectorXd tlo(setpoints.samples());
  for (Eigen::Index k = 0; k < tlo.size(); ++k) {
    const int mi = setpoints.move_index[k];
    tlo[k] = mi >= 0 ? program.moves[static_cast<std::size_t>(mi)].tool_length_offset_mm : 0.0;
  }
  return tlo;
}

}  // namespace vmsim::sim
