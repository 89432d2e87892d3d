#pragma once
// The NC interpolator: from a ToolPath and the machine's axis limits to axis setpoints every Te.
#include "core/machine.hpp"
#include "core/setpoints.hpp"
#include "motion/setpoint_estimate.hpp"
#include "motion/smooth_path.hpp"
#include "core/toolpath.hpp"

#include <functional>
#include <memory>
#include <vector>

namespace vmsim::motion {

// A ceiling on the feed along the path, e.g. Chen et al.'s contour-error-constrained feed plan (methods/feedplan): at
// arc length s of the smoothed path the interpolator follows (smooth_path_for), the speed of the programmed point
// (X Y Z, mm/s; the path speed for moves of the rotary axes alone) is at most ceiling(s). The squared ceiling is
// linear in s between the points, as the plan's squared feed is (Chen et al. 2016 eq. 21), and constant beyond the
// ends. s_mm strictly increasing, feeds > 0 (the interpolator starts and stops at rest by itself; a followed profile's
// first and last feed are 0, and so may be any single point between, as at a cusp).
struct FeedCeiling {
  std::vector<double> s_mm, feed_mm_per_s;
  // A ceiling that is already a feed profile within the machine's limits (e.g. a plan made with the axes' own
  // velocity, acceleration and jerk limits, methods::plan_feed): the interpolator follows it as given, from rest at
  // the path's start (the first point: s 0, feed 0) to rest at its end (the last: the path's length, feed 0), instead
  // of planning its own jerk-limited profile under it (the programmed feed does not apply: the profile replaces it).
  // Only the moving average of the interpolator's jerk model (T = A / J) smooths it, and it is lowered locally where
  // a finite difference of the setpoints would still exceed a limit. Paths with exact stops inside are refused.
  bool follow = false;
  bool empty() const { return s_mm.empty(); }
  double at(double s) const;
  double min_over(double s0, double s1) const;  // smallest value on [s0, s1]
  void check() const;                           // throws core::Error for a malformed ceiling
};

// The shares of each axis' acceleration and jerk limits the interpolator's own plans use (the rest absorbs what the
// continuous model misses in the sampled setpoints' finite differences); a profile made to be followed
// (FeedCeiling::follow) keeps the same shares.
inline constexpr double kPlanAccelShare = 0.97;
inline constexpr double kPlanJerkShare = 0.97;

struct InterpOptions {
  double period_s = 1e-3;       // Te
  double tolerance_mm = 0.020;  // corner tolerance: largest distance of a setpoint from the programmed path
  double feed_scale = 1.0;      // feed override applied to every programmed feed
  FeedCeiling feed_ceiling;     // empty: none
  // The path to follow when it is not the moves' lines and arcs (a NURBS made G2 by core/nurbs): its pieces' move
  // indices name the ToolPath's moves, which then serve for bookkeeping (feeds, start and end, source lines) and
  // must join the same points. Null: the moves' lines and arcs, blended within the tolerance (core/smooth_path).
  std::shared_ptr<const SmoothPath> geometry;
  // Called with the setpoint count's lower bound (motion/setpoint_estimate.hpp) once the path is smoothed, before
  // any setpoint is made: throws to refuse a path that would need more than the caller allows (sim::Chain: the
  // job's max_setpoints and the memory available).
  std::function<void(const SetpointEstimate&)> check_estimate;
};

struct InterpStats {
  double cycle_time_s = 0.0;
  int moves = 0;          // ToolPath moves interpolated
  int blends = 0;         // corners and curvature jumps smoothed within the tolerance
  int exact_stops = 0;    // corners too sharp to blend: the axes stop there
  int repair_passes = 0;  // re-plans needed to bring every finite difference within the limits
};

struct InterpResult {
  core::Setpoints setpoints;
  InterpStats stats;
};

// `path` is in axis coordinates (motion::toolpath_in_axis_space): its moves join end to start. Setpoints start at
// path.initial_position and end exactly at the last move's end.
InterpResult interpolate(const core::ToolPath& path, const core::Machine& machine, const InterpOptions& options);

// The smoothed path interpolate() follows for these arguments (options.geometry when given): its arc length is the
// coordinate of a FeedCeiling.
SmoothPath smooth_path_for(const core::ToolPath& path, const core::Machine& machine, const InterpOptions& options);

}  // namespace vmsim::motion
