#pragma once
// The NC interpolator: from a ToolPath and the machine's axis limits to axis setpoints every Te.
#include "core/machine.hpp"
#include "core/setpoints.hpp"
#include "core/toolpath.hpp"

namespace vmsim::core {

struct InterpOptions {
  double period_s = 1e-3;        // Te
  double tolerance_mm = 0.020;   // corner tolerance: largest distance of a setpoint from the programmed path
  double feed_scale = 1.0;       // feed override applied to every programmed feed
};

struct InterpStats {
  double cycle_time_s = 0.0;
  int moves = 0;                 // ToolPath moves interpolated
  int blends = 0;                // corners and curvature jumps smoothed within the tolerance
  int exact_stops = 0;           // corners too sharp to blend: the axes stop there
  int repair_passes = 0;         // re-plans needed to bring every finite difference within the limits
};

struct InterpResult {
  Setpoints setpoints;
  InterpStats stats;
};

// `path` is in axis coordinates (core::toolpath_in_axis_space): its moves join end to start. Setpoints start at
// path.initial_position and end exactly at the last move's end.
InterpResult interpolate(const ToolPath& path, const Machine& machine, const InterpOptions& options);

}  // namespace vmsim::core
