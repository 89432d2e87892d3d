#pragma once
// The chain vmsim runs for a job, assembled once as one visible object: the interpolator's settings (period,
// tolerance, feed override, the feed ceiling of the job's feed plan, the curve a [feedplan.nurbs] job follows) and the
// drives (the machine's cascades, the job's gain schedule, the identified axis models that replace some of them, or
// the transfer-function servo a job's [feedplan] gives). `vmsim run`, `motion`, `oga`, `compensate` and
// `plan-feed` (and the Python module) build their chain here, so they provably run the same one.
#include "core/job.hpp"
#include "core/setpoints.hpp"
#include "core/toolpath.hpp"
#include "core/warning.hpp"
#include "drives/simulate.hpp"
#include "motion/interp.hpp"
#include "sim/axis_models.hpp"
#include "sim/drive_checks.hpp"
#include "sim/job_program.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

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
  // Simulated after the last setpoint while the axes come to rest (drives::SimulateOptions::settle_s).
  double settle_s = 0.2;
};

// The drives of Chain::simulate in blocks of rows (issue 21): the checks before the run made, the gain schedule read,
// the simulation ready to step, and the checks after it, to be fed each block (`after->add`) and finished.
struct DriveBlocks {
  DriveChecks checks;                              // before the run; after->finish(checks) adds the rest
  std::unique_ptr<drives::GainSchedule> schedule;  // read against the setpoints (empty without one)
  std::unique_ptr<drives::BlockSimulation> sim;
  std::unique_ptr<DriveChecksAfter> after;
};

class Chain {
 public:
  // Throws core::Error naming the job file and key for a gain schedule used with another feed, or an axis-model or
  // feed-plan file that does not fit the job; or for a [feedplan] transfer-function servo together with identified
  // axis models or a gain schedule (each would replace the other's model of the same axes).
  explicit Chain(const core::Job& job, const ChainOptions& options = {});
  Chain(const Chain&) = delete;
  Chain& operator=(const Chain&) = delete;

  const core::Job& job() const { return *job_; }
  const ChainOptions& options() const { return options_; }
  double feed_scale() const { return options_.feed_scale; }
  // Period, tolerance, feed scale and a curve job's geometry, as motion::interpolate takes them (the feed plan's
  // ceiling is read against each program interpolated: feed_ceiling).
  const motion::InterpOptions& interp_options() const { return interp_; }
  const JobAxisModels& axis_models() const { return axis_models_; }
  // The gain schedule applied to the drives (the job's, at its own feeds), if any.
  const std::optional<std::filesystem::path>& gain_schedule_file() const { return gain_schedule_file_; }
  // The feed plan the interpolator follows ([job] feed_plan), if any.
  const std::optional<std::filesystem::path>& feed_plan_file() const { return feed_plan_file_; }
  // The job's curve when its path is a [feedplan.nurbs] NURBS (the interpolator follows its quintic chain); null for
  // a program.
  const JobCurve* curve() const { return curve_.get(); }
  // Whether the axes run as the transfer functions of the job's [feedplan] servo ("pid" or "transfer_function": Chen
  // et al.'s servo, which the machine file does not describe) instead of the machine's cascades.
  bool transfer_function_servo() const { return !servo_per_axis_.empty(); }

  // The program (workpiece frame, as sim::read_job_program gives it) to axis setpoints every Te, under the feed
  // plan's ceiling (checked against this program's path).
  motion::InterpResult interpolate(const core::ToolPath& program) const;
  // The same under another ceiling (empty: none), unchecked: vmsim plan-feed plays its candidate plans, vmsim
  // compensate re-times a corrected program under the original's plan.
  motion::InterpResult interpolate(const core::ToolPath& program, const motion::FeedCeiling& ceiling) const;
  // The job's feed plan read and checked against this program's path (its Te, length and points); empty without one.
  motion::FeedCeiling feed_ceiling(const core::ToolPath& program) const;
  // The smoothed path the interpolator follows for this program (the arc length of a feed ceiling).
  motion::SmoothPath smooth_path(const core::ToolPath& program) const;
  // The setpoints through the drives: the cascades with the gain schedule (read against these setpoints), or the
  // identified models for the axes they replace, or the job's transfer-function servo; settle_s more after the last.
  // full_rate_trace: also every current-loop sample (large). Before simulating, the cascades the setpoints move are
  // checked through their linearised models (sim/drive_checks.hpp): an unstable loop throws core::Error. `checks`:
  // also the findings before and after the run (saturation, following error) and each checked axis's figures.
  drives::AxisResponse simulate(const core::Setpoints& setpoints, bool full_rate_trace = false,
                                DriveChecks* checks = nullptr) const;
  // The same in blocks of rows; `setpoints` must outlive the result. Throws as simulate does.
  DriveBlocks simulate_in_blocks(const core::Setpoints& setpoints) const;
  // Per machine axis: whether it runs the machine's cascade ([axes.drive]) rather than an identified axis model or
  // the [feedplan] servo.
  std::vector<bool> cascade_axes() const;

 private:
  drives::SimulateOptions simulate_options(const core::Setpoints& setpoints, bool full_rate_trace,
                                           drives::GainSchedule& schedule) const;
  const core::Job* job_;
  ChainOptions options_;
  motion::InterpOptions interp_;
  JobAxisModels axis_models_;
  std::optional<std::filesystem::path> gain_schedule_file_;
  std::optional<std::filesystem::path> feed_plan_file_;
  std::shared_ptr<const JobCurve> curve_;
  std::vector<std::unique_ptr<drives::AxisModel>> servo_owned_;
  std::vector<const drives::AxisModel*> servo_per_axis_;  // the [feedplan] servo per machine axis; empty: none
  std::vector<bool> servo_given_;                         // axes [[feedplan.axis]] names
};

// The tool length offset in force at each setpoint (mm): that of the program move the setpoint belongs to (0 before
// the first move). Kinematics take it to place the tool tip.
Eigen::VectorXd tool_length_offsets(const core::ToolPath& program, const core::Setpoints& setpoints);

}  // namespace vmsim::sim
