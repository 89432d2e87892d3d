#pragma once
// All axes of a job, from the interpolator's setpoints to the positions the machine really reaches.
#include "core/machine.hpp"
#include "core/setpoints.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace vmsim::drives {

// Per-sample gains (seed 000's OGA): samples x axes; NaN keeps the drive's own value. Empty matrices: no schedule.
struct GainSchedule {
  Eigen::MatrixXd kv_per_s, kf;
};

struct SimulateOptions {
  const GainSchedule* gains = nullptr;
  bool full_rate_trace = false;   // also keep every current-loop sample of every axis
  double settle_s = 0.2;          // keep simulating this long after the last setpoint (axes come to rest)
};

// Inner-loop samples of one axis at its current-loop period.
struct FullRateTrace {
  double period_s = 0.0;
  Eigen::ArrayXd position, velocity, current_A, current_setpoint_A, voltage_V;
};

struct AxisResponse {
  double period_s = 1e-3;               // Te
  std::vector<std::string> axis_names;  // machine axes, in the machine file's order
  // samples x axes, axis units (mm, rad): one row per setpoint, then the settling samples.
  Eigen::MatrixXd position, velocity, acceleration, jerk, current_A, current_setpoint_A;
  std::vector<FullRateTrace> trace;     // per axis when full_rate_trace
  Eigen::Index samples() const { return position.rows(); }
};

// Throws core::Error naming the machine file when an axis the setpoints move has no [axes.drive].
AxisResponse simulate_axes(const core::Setpoints& setpoints, const core::Machine& machine,
                           const SimulateOptions& options = {});

}  // namespace vmsim::drives
