#include "methods/feedplan_job.hpp"
#include "core/units.hpp"

#include "core/error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <limits>

namespace vmsim::methods {

namespace {
using core::units::kInf;
}  // namespace

Eigen::Vector3d moving_axes(const PathSamples& samples) {
  Eigen::Vector3d moving;
  for (int r = 0; r < 3; ++r) moving[r] = samples.t_abs_max.col(r).maxCoeff() > 1e-9 ? 1.0 : 0.0;
  return moving;
}

std::vector<TransferFunction> feed_plan_transfer_functions(const core::FeedPlanSpec& spec, const core::Machine& machine,
                                                           const std::string& job_file, std::vector<bool>* given) {
  std::vector<TransferFunction> tfs;
  if (given) given->clear();
  if (spec.servo == core::FeedPlanSpec::Servo::Machine) return tfs;
  const bool pid = spec.servo == core::FeedPlanSpec::Servo::Pid;
  for (const core::MachineAxis& ax : machine.axes) {
    const core::FeedPlanSpec::Axis* a = nullptr;
    for (const auto& g : spec.axes)
      if (g.name == ax.name) a = &g;
    if (given) given->push_back(a != nullptr);
    if (!a) {
      tfs.push_back(TransferFunction{{1.0}, {1.0}});  // an axis the path holds: ideal
      continue;
    }
    try {
      if (pid) {
        const PidServoParams p{a->kp, a->ki, a->kd, a->ka, a->kt, a->inertia, a->damping, a->rg};
        tfs.push_back(pid_servo_transfer_function(p));
      } else {
        tfs.push_back(TransferFunction{a->num, a->den});
      }
    } catch (const core::Error& e) {
      throw core::Error(core::located(job_file, 0, fmt::format("[[feedplan.axis]] {}: {}", ax.name, e.what())));
    }
  }
  return tfs;
}

FeedPlanServo feed_plan_servo(const core::FeedPlanSpec& spec, const core::Machine& machine, double te_s,
                              const Eigen::Vector3d& moving, const std::string& job_file) {
  FeedPlanServo s;
  static const char* names[] = {"X", "Y", "Z"};
  if (spec.servo == core::FeedPlanSpec::Servo::Machine) {
    s.description = "the machine's cascades ([axes.drive]), linearised (drives/linear_model, sampled-data at Te)";
    for (int r = 0; r < 3; ++r) {
      if (!(moving[r] > 0)) continue;
      const int ai = machine.axis_index(r);
      if (ai < 0 || !machine.axes[static_cast<std::size_t>(ai)].drive)
        throw core::Error(core::located(machine.source_file, 0,
                                        fmt::format("axis {} moves but has no [axes.drive]: [feedplan] servo = "
                                                    "\"machine\" needs its cascade (or give servo = \"pid\")",
                                                    names[r])));
      s.responses.push_back(frequency_response(*machine.axes[static_cast<std::size_t>(ai)].drive, te_s));
    }
    return s;
  }
  const bool pid = spec.servo == core::FeedPlanSpec::Servo::Pid;
  s.description =
      pid ? "PID servo of Chen et al. 2016 eq. 2 per [[feedplan.axis]]" : "transfer functions per [[feedplan.axis]]";
  std::vector<bool> given;
  s.simulate = feed_plan_transfer_functions(spec, machine, job_file, &given);
  for (std::size_t a = 0; a < machine.axes.size(); ++a) {
    const core::MachineAxis& ax = machine.axes[a];
    const bool moves = ax.program_axis < 3 && moving[ax.program_axis] > 0;
    if (!moves) continue;
    if (!given[a])
      throw core::Error(core::located(job_file, 0,
                                      fmt::format("axis {} moves but [feedplan] has no [[feedplan.axis]] "
                                                  "with name = \"{}\"",
                                                  ax.name, ax.name)));
    try {
      s.responses.push_back(frequency_response(s.simulate[a]));
    } catch (const core::Error& e) {
      throw core::Error(core::located(job_file, 0, fmt::format("[[feedplan.axis]] {}: {}", ax.name, e.what())));
    }
  }
  return s;
}

FeedPlanLimits feed_plan_limits(const core::FeedPlanSpec& spec, const core::Machine& machine, double te_s,
                                double max_feed_mm_per_s, const Eigen::Vector3d& moving) {
  FeedPlanLimits lim;
  lim.period_s = te_s;
  lim.chord_error_mm = spec.chord_error_mm;
  lim.contour_error_mm = spec.contour_error_mm;
  lim.max_feed_mm_per_s = max_feed_mm_per_s;
  for (int r = 0; r < 3; ++r) {
    const int ai = machine.axis_index(r);
    if (ai < 0) {
      if (moving[r] > 0) throw core::Error(fmt::format("the path moves axis {}, which the machine lacks", "XYZ"[r]));
      lim.axis_velocity[r] = lim.axis_acceleration[r] = lim.axis_jerk[r] = kInf;
      continue;
    }
    const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(ai)];
    lim.axis_velocity[r] = ax.max_velocity;
    lim.axis_acceleration[r] = ax.max_acceleration;
    lim.axis_jerk[r] = spec.jerk ? ax.max_jerk : kInf;
  }
  return lim;
}

double model_contour_peak(const PathSamples& ps, const Eigen::ArrayXd& feed, const ContourErrorModel& model) {
  double m = 0.0;
  for (Eigen::Index i = 0; i < ps.size(); ++i) {
    const double k = ps.kappa_max[i];
    if (k > 1e-12) m = std::max(m, model.error_ratio(feed[i] * k) / k);
  }
  return m;
}

}  // namespace vmsim::methods
