#pragma once
// How many setpoints the interpolator will make for a path, before it makes them (issue 18: a typo F0.01 must be
// refused, not interpolated into gigabytes). A lower bound: each piece of the smoothed path takes at least its length
// over the lower of its programmed feed and the speed the axes' velocity limits allow along it, ignoring acceleration
// and jerk. The real count is at least this (tests/motion compare it with the interpolator's on the parts' programs).
#include "core/machine.hpp"
#include "motion/smooth_path.hpp"

namespace vmsim::motion {

struct SetpointEstimate {
  double cycle_time_s = 0;  // at least
  double setpoints = 0;     // at least: cycle_time_s / Te + 1
  int slowest_move = -1;    // the ToolPath move of the piece that takes longest (its source line names it)
  double slowest_move_s = 0;
};

// `path` in path space (smooth_path_for); the axes' velocity limits in path units (mm/s, deg/s) from `machine`.
SetpointEstimate estimate_setpoints(const SmoothPath& path, const core::Machine& machine, double period_s);

}  // namespace vmsim::motion
