#include "sim/chain.hpp"

#include "core/error.hpp"
#include "core/memory.hpp"
#include "drives/linear_model.hpp"
#include "methods/feedplan_file.hpp"
#include "methods/feedplan_job.hpp"
#include "methods/feedplan_servo.hpp"
#include "methods/oga_schedule.hpp"
#include "motion/kinematics.hpp"
#include "sim/memory_plan.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace vmsim::sim {

Chain::Chain(const core::Job& job, const ChainOptions& options)
    : job_(&job), options_(options), axis_models_(job_axis_models(job, options.axis_models_file)) {
  interp_.period_s = job.interp.period_s;
  interp_.tolerance_mm = job.interp.tolerance_mm;
  interp_.feed_scale = options.feed_scale;
  // Refuse a program before it is interpolated when it would need more setpoints than the job allows or than the
  // motion's memory (sim/memory_plan.hpp's model) that is available (issue 18).
  interp_.check_estimate = [&job](const motion::SetpointEstimate& e) {
    const std::string f = job.file.string();
    const std::string why = fmt::format(
        "the interpolation would make at least {:.3g} setpoints (a cycle time of at least {:.4g} s at period_ms = "
        "{:g}, "
        "from the program's lengths, feeds and the axes' velocity limits; the slowest move{} takes {:.4g} s)",
        e.setpoints, e.cycle_time_s, job.interp.period_s * 1e3,
        e.slowest_move >= 0 ? fmt::format(" (program move {})", e.slowest_move + 1) : std::string(), e.slowest_move_s);
    if (e.setpoints > job.interp.max_setpoints)
      throw core::Error(core::located(f, 0,
                                      fmt::format("{}, more than [interpolation] max_setpoints = {:.3g}: check "
                                                  "the program's F words and period_ms, or raise max_setpoints",
                                                  why, job.interp.max_setpoints)));
    const bool turning = job.machine.kinematics != "xyz";
    const double bytes = e.setpoints * motion_bytes_per_setpoint(static_cast<int>(job.machine.axes.size()), turning);
    const core::AvailableMemory avail = core::available_memory();
    if (bytes > avail.bytes)
      throw core::Error(core::located(
          f, 0,
          fmt::format("{}, whose motion needs at least {} while {} is available ({}): check the program's F "
                      "words and period_ms, or run on a machine with more memory",
                      why, core::format_bytes(bytes), core::format_bytes(avail.bytes), avail.source)));
  };
  // A gain schedule holds gains for the setpoints of the job's own feeds.
  if (job.gain_schedule_file && !options.ignore_gain_schedule) {
    if (options.feed_scale != 1.0)
      throw core::Error(job.file.string() +
                        ": --feed-scale changes the setpoints its gain_schedule was computed for "
                        "(run vmsim oga on a job at those feeds instead)");
    gain_schedule_file_ = job.gain_schedule_file;
  }
  if (job.feed_plan_file && !options.ignore_feed_plan) feed_plan_file_ = job.feed_plan_file;
  // A curve job: the interpolator follows the curve's quintic chain; the job's program is its bookkeeping moves.
  if (auto c = read_job_curve(job)) {
    curve_ = std::make_shared<const JobCurve>(std::move(*c));
    interp_.geometry = std::make_shared<const motion::SmoothPath>(curve_->path.path);
  }
  // Chen et al.'s servo is given in the job, not the machine file (parts/feedplan): every command runs it.
  if (job.feedplan && job.feedplan->servo != core::FeedPlanSpec::Servo::Machine) {
    const std::string f = job.file.string();
    if (axis_models_.any())
      throw core::Error(core::located(f, 0,
                                      "[feedplan] servo = \"pid\" or \"transfer_function\" models the axes "
                                      "already; identified axis models ([job] axis_models, --axis-models) "
                                      "cannot replace them too"));
    if (gain_schedule_file_)
      throw core::Error(core::located(f, 0,
                                      "[job] gain_schedule: the [feedplan] transfer-function servo has no "
                                      "position-loop gain to schedule"));
    for (const methods::TransferFunction& tf :
         methods::feed_plan_transfer_functions(*job.feedplan, job.machine, f, &servo_given_)) {
      servo_owned_.push_back(std::make_unique<methods::TransferFunctionAxis>(tf, job.interp.period_s));
      servo_per_axis_.push_back(servo_owned_.back().get());
    }
  }
  // The period must fit every cascade's loops; checked here, before any interpolation (period_ms = 0.001, us typed
  // as ms, made millions of setpoints before the drives refused it: issue 18).
  const std::vector<bool> cascade = cascade_axes();
  for (std::size_t a = 0; a < job.machine.axes.size(); ++a) {
    const core::MachineAxis& ax = job.machine.axes[a];
    if (!ax.drive || !cascade[a]) continue;
    try {
      (void)drives::LinearAxisModel(*ax.drive, job.interp.period_s);
    } catch (const core::Error& e) {
      throw core::Error(
          core::located(job.file.string(), 0,
                        fmt::format("[interpolation] period_ms = {:g} does not fit the drive of axis {} "
                                    "({}): {}",
                                    job.interp.period_s * 1e3, ax.name, job.machine.source_file, e.what())));
    }
  }
}

motion::SmoothPath Chain::smooth_path(const core::ToolPath& program) const {
  return motion::smooth_path_for(motion::toolpath_in_axis_space(program, job_->machine), job_->machine, interp_);
}

motion::FeedCeiling Chain::feed_ceiling(const core::ToolPath& program) const {
  if (!feed_plan_file_) return {};
  try {
    return methods::read_feed_plan(*feed_plan_file_, smooth_path(program), interp_.period_s);
  } catch (const core::Error& e) {
    throw core::Error(fmt::format("{}: [job] feed_plan: {}", job_->file.string(), e.what()));
  }
}

motion::InterpResult Chain::interpolate(const core::ToolPath& program) const {
  return interpolate(program, feed_ceiling(program));
}

motion::InterpResult Chain::interpolate(const core::ToolPath& program, const motion::FeedCeiling& ceiling) const {
  motion::InterpOptions o = interp_;
  o.feed_ceiling = ceiling;
  // A program that sets its own tolerance (Sinumerik CYCLE832) runs with it when the job gives none.
  if (!job_->interp.tolerance_given && program.program_tolerance_mm) o.tolerance_mm = *program.program_tolerance_mm;
  return motion::interpolate(motion::toolpath_in_axis_space(program, job_->machine), job_->machine, o);
}

std::vector<bool> Chain::cascade_axes() const {
  std::vector<bool> out(job_->machine.axes.size(), true);
  for (std::size_t a = 0; a < out.size(); ++a) {
    if (!servo_per_axis_.empty())
      out[a] = false;
    else if (axis_models_.any() && a < axis_models_.per_axis.size() && axis_models_.per_axis[a])
      out[a] = false;
  }
  return out;
}

drives::SimulateOptions Chain::simulate_options(const core::Setpoints& setpoints, bool full_rate_trace,
                                                drives::GainSchedule& schedule) const {
  drives::SimulateOptions sopt;
  sopt.settle_s = options_.settle_s;
  sopt.full_rate_trace = full_rate_trace;
  if (gain_schedule_file_) {
    schedule = methods::read_gain_schedule(*gain_schedule_file_, setpoints, job_->machine);
    sopt.gains = &schedule;
  }
  if (!servo_per_axis_.empty()) {
    for (std::size_t a = 0; a < servo_given_.size(); ++a) {
      const Eigen::Index c = static_cast<Eigen::Index>(a);
      if (!servo_given_[a] && c < setpoints.position.cols() &&
          (setpoints.position.col(c).array() != setpoints.position(0, c)).any())
        throw core::Error(core::located(job_->file.string(), 0,
                                        fmt::format("axis {} moves but [feedplan] has no [[feedplan.axis]] with name = "
                                                    "\"{}\"",
                                                    job_->machine.axes[a].name, job_->machine.axes[a].name)));
    }
    sopt.axis_models = &servo_per_axis_;
  } else if (axis_models_.any()) {
    sopt.axis_models = &axis_models_.per_axis;
  }
  return sopt;
}

drives::AxisResponse Chain::simulate(const core::Setpoints& setpoints, bool full_rate_trace,
                                     DriveChecks* checks) const {
  const std::vector<bool> cascade = cascade_axes();
  DriveChecks before = check_drives_before(job_->machine, setpoints, cascade);  // throws for an unstable loop
  drives::GainSchedule schedule;
  const drives::SimulateOptions sopt = simulate_options(setpoints, full_rate_trace, schedule);
  drives::AxisResponse response = drives::simulate_axes(setpoints, job_->machine, sopt);
  if (checks) {
    *checks = std::move(before);
    check_drives_after(job_->machine, setpoints, response, cascade, sopt.gains, *checks);
  }
  return response;
}

DriveBlocks Chain::simulate_in_blocks(const core::Setpoints& setpoints) const {
  DriveBlocks out;
  const std::vector<bool> cascade = cascade_axes();
  out.checks = check_drives_before(job_->machine, setpoints, cascade);  // throws for an unstable loop
  out.schedule = std::make_unique<drives::GainSchedule>();
  const drives::SimulateOptions sopt = simulate_options(setpoints, false, *out.schedule);
  out.sim = std::make_unique<drives::BlockSimulation>(setpoints, job_->machine, sopt);
  out.after = std::make_unique<DriveChecksAfter>(job_->machine, setpoints, cascade, sopt.gains);
  return out;
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
