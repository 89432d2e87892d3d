#include "motion/setpoint_estimate.hpp"

#include "core/units.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::motion {

SetpointEstimate estimate_setpoints(const SmoothPath& path, const core::Machine& machine, double period_s) {
  // Axis velocity limits in path units (rotary axes in degrees); axes the machine lacks do not move.
  core::Vec6 vmax = core::Vec6::Constant(INFINITY);
  for (const core::MachineAxis& ax : machine.axes)
    vmax[ax.program_axis] = ax.max_velocity * (ax.kind == core::AxisKind::Rotary ? core::units::kRadToDeg : 1.0);
  SetpointEstimate e;
  for (const PathPiece& pc : path.pieces) {
    const core::Vec6 d = pc.point_u(pc.u_end) - pc.point_u(pc.u_begin);  // chord: at most the travel of each axis
    double xyz = d.head<3>().norm(), abc = d.tail<3>().norm();
    double t = 0;
    if (pc.kind == PathPiece::Kind::Arc) {
      // The plane's two axes travel at least r |dtheta| together, at most at the speed of both limits combined.
      const double arc =
          std::min(std::abs(pc.r0), std::abs(pc.r0 + pc.dr)) * std::abs(pc.dtheta) * (pc.u_end - pc.u_begin);
      const double v12 = std::hypot(vmax[pc.arc_i1], vmax[pc.arc_i2]);
      t = std::max(t, arc / v12);
      if (pc.arc_i1 < 3 && pc.arc_i2 < 3)
        xyz = std::max(xyz, arc);
      else
        abc = std::max(abc, arc);
    }
    for (int i = 0; i < 6; ++i)
      if (std::isfinite(vmax[i]) && vmax[i] > 0) t = std::max(t, std::abs(d[i]) / vmax[i]);
    if (!pc.rapid && pc.feed_limit > 0 && std::isfinite(pc.feed_limit)) {
      const double metric = pc.feed_metric == PathPiece::FeedMetric::Path                  ? pc.length
                            : pc.feed_metric == PathPiece::FeedMetric::Abc || xyz <= 1e-12 ? abc
                                                                                           : xyz;
      t = std::max(t, metric / pc.feed_limit);
    }
    e.cycle_time_s += t;
    if (t > e.slowest_move_s) e.slowest_move_s = t, e.slowest_move = pc.move_index;
  }
  e.setpoints = e.cycle_time_s / period_s + 1;
  return e;
}

}  // namespace vmsim::motion
