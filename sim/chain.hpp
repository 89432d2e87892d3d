#pragma once
// The chain vmsim runs for a job, assembled once as one visible object: the interpolator's settings (period,
// tolerance, feed override, the feed ceiling of a feed plan) and the drives (the machine's cascades, the job's gain
// schedule, the identified axis models that replace some of them). `vmsim run`, `motion`, `oga`, `compensate` and
// `plan-feed` (and the Python module) build their chain here, so they provably run the same one.
#include "core/job.hpp"
#include "core/setpoints.hpp"
#include "core/toolpath.hpp"
#include "drives/simulate.hpp"
#include "motion/interp.hpp"
#include "sim/axis_models.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <optional>

namespace vmsim::sim {

struct ChainOptions {
  double feed_scale = 1.0;  // multiplies every programmed feed (the NC panel's override, --feed-scale)
  // Replaces the job's [job] axis_models (a command's --axis-models).
  std::optional<std::filesystem::path> axis_models_file;
  // Run the drives with the machine file's own gains even when the job names a gain schedule (vmsim oga computes
  // one; a feed-scaled reference runs at other feeds than the schedule's). Without it, a gain schedule with a feed
  // scale other than 1 is an error: the schedule holds gains for the setpoints of the job's own feeds.
  bool ignore_gain_schedule = false;
  // Interpolate without the job's feed plan (vmsim plan-feed computes one).
  bool ignore_feed_plan = false;
};

class Chain {
 public:
  // Throws core::Error naming the job file and key for a gain schedule used with another feed, or an axis-model or
  // feed-plan file that does not fit the job.
  explicit Chain(const core::Job& job, const ChainOptions& options = {});
  Chain(const Chain&) = delete;
  Chain& operator=(const Chain&) = delete;

  const core::Job& job() const { return *job_; }
  const ChainOptions& options() const { return options_; }
  double feed_scale() const { return options_.feed_scale; }
  // Period, tolerance, feed scale and the feed plan's ceiling, as motion::interpolate takes them.
  const motion::InterpOptions& interp_options() const { return interp_; }
  const JobAxisModels& axis_models() const { return axis_models_; }
  // The gain schedule applied to the drives (the job's, at its own feeds), if any.
  const std::optional<std::filesystem::path>& gain_schedule_file() const { return gain_schedule_file_; }

  // The program (workpiece frame, as program::read_program gives it) to axis setpoints every Te.
  motion::InterpResult interpolate(const core::ToolPath& program) const;
  // The setpoints through the drives: the cascades with the gain schedule (read against these setpoints), or the
  // identified models for the axes they replace. full_rate_trace: also every current-loop sample (large).
  drives::AxisResponse simulate(const core::Setpoints& setpoints, bool full_rate_trace = false) const;

 private:
  const core::Job* job_;
  ChainOptions options_;
  motion::InterpOptions interp_;
  JobAxisModels axis_models_;
  std::optional<std::filesystem::path> gain_schedule_file_;
};

// The tool length offset in force at each setpoint (mm): that of the program move the setpoint belongs to (0 before
// the first move). Kinematics take it to place the tool tip.
Eigen::VectorXd tool_length_offsets(const core::ToolPath& program, const core::Setpoints& setpoints);

}  // namespace vmsim::sim
