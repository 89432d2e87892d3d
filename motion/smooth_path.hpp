#pragma once
// The geometric path the interpolator follows: the program's lines and arcs in axis space, with every
// corner and every curvature jump replaced by a curvature-continuous (G2) quintic blend that stays within
// the corner tolerance. Setpoints are always points of this path, so their distance to the programmed
// geometry is bounded by the tolerance by construction.
//
// Path space: the six program axes X Y Z (mm) and A B C in degrees (not rad): one degree weighs like one
// millimetre in the arc length, which is how LinuxCNC measures moves of the rotary axes alone.
#include "core/toolpath.hpp"

#include <Eigen/Core>

#include <vector>

namespace vmsim::motion {

// Position and derivatives of a curve with respect to its own parameter u.
struct CurveJet {
  core::Vec6 p, pu, puu, puuu;
};

// Position and derivatives with respect to arc length s: unit tangent, curvature vector, its derivative.
struct PathJet {
  core::Vec6 p, t, k, dk;
};

// One piece of the smoothed path: a base curve restricted to [u_begin, u_end].
struct PathPiece {
  enum class Kind { Line, Arc, Quintic } kind = Kind::Line;
  // Line: p(u) = a + u * b.  Arc: see arc_* fields.  Quintic: p(u) = sum_k coef.col(k) u^k.
  core::Vec6 a = core::Vec6::Zero(), b = core::Vec6::Zero();
  Eigen::Matrix<double, 6, 6> coef = Eigen::Matrix<double, 6, 6>::Zero();
  // Quintic: the derivative's coefficients, dcoef.col(k - 1) = k * coef.col(k), so that speed_u (millions of calls
  // while the setpoints are written) runs Horner without the products. Set with coef by set_quintic.
  Eigen::Matrix<double, 6, 5> dcoef = Eigen::Matrix<double, 6, 5>::Zero();
  // Arc (helix, or a spiral when the start and end radii differ as G-code allows): in the plane of axes
  // (arc_i1, arc_i2) about centre (c1, c2): angle theta0 + u * dtheta, radius r0 + u * dr; every other
  // coordinate moves linearly: a + u * b (a, b hold zero in arc_i1, arc_i2).
  int arc_i1 = 0, arc_i2 = 1;
  double c1 = 0, c2 = 0, r0 = 0, dr = 0, theta0 = 0, dtheta = 0;

  double u_begin = 0.0, u_end = 1.0;
  double s_begin = 0.0;  // arc length from the path start to this piece's start
  double length = 0.0;   // arc length of [u_begin, u_end]
  bool uniform = true;   // |dp/du| constant: s is linear in u (lines, true helices)
  // Arc-length table for non-uniform pieces: cumulative length at u_begin + k (u_end - u_begin) / kTable.
  static constexpr int kTable = 64;
  std::vector<double> cum;

  int move_index = 0;       // ToolPath move (for a blend: the move it leaves)
  int move_index_next = 0;  // for a blend: the move it enters (== move_index otherwise)
  bool rapid = false;
  // The programmed feed limits the speed of X Y Z together (mm/s), of A B C alone for moves of the rotary axes
  // only (deg/s), or of the path parameter itself (inverse-time feed: the move's length over its duration).
  enum class FeedMetric { Xyz, Abc, Path } feed_metric = FeedMetric::Xyz;
  double feed_limit = 0.0;  // in the metric's units per s; infinity for rapids
  bool stop_after = false;  // the axes must stop at the end of this piece (a corner too sharp to blend)

  void set_quintic(const Eigen::Matrix<double, 6, 6>& c);  // kind Quintic, coef and dcoef
  CurveJet jet_u(double u) const;                          // derivatives w.r.t. u
  core::Vec6 point_u(double u) const;
  double speed_u(double u) const;  // |dp/du|
  // Local arc length (0 .. length) to the curve parameter, and back.
  double u_at(double s_local) const;
  double s_at(double u) const;
  PathJet jet_s(double s_local) const { return jet_at_u(u_at(s_local)); }  // derivatives w.r.t. arc length
  PathJet jet_at_u(double u) const;  // the same, at a curve parameter (no arc-length inversion)
  void finalize();                   // computes length (and the table for non-uniform pieces)
};

struct SmoothPathOptions {
  // Largest distance of a blend from the programmed path: in path space, divided at each corner by the moves' gains
  // (Move::tip_per_mm, tip_per_deg) so that on chain machines it holds on the tool tip in the workpiece frame (and on
  // the tool axis at 100 mm from the tip); moves with via points are followed through them, one line each.
  double tolerance_mm = 0.020;
  // Tangent junctions (a line into a tangent arc: only the curvature jumps) are rounded only as far as the jerk
  // limit needs at the programmed feed, as an NC's tangential-transition rounding does (Sinumerik G645): the
  // transition must be long enough that v^3 |dK| stays within the axis jerk. These give the jerk per axis in path
  // units (mm/s^3, deg/s^3) and the speed assumed for rapids.
  core::Vec6 axis_jerk = core::Vec6::Constant(1e300);
  core::Vec6 axis_accel = core::Vec6::Constant(1e300);
  double rapid_speed = 1e300;
  // Corners sharper than this (angle between the tangents) are not blended: the axes stop there.
  double max_blend_angle_rad = 170.0 * 3.14159265358979323846 / 180.0;
  double feed_scale = 1.0;
  // Kinks the axes take without a blend (a G20 program's last-digit rounding leaves direction changes of 1e-5 rad,
  // which a blend would turn into a crawl through a corner): a junction is passed as it is when, at the fastest speed
  // the feeds and the axis velocities allow there, the step of each axis' velocity across it (v |t_a,i - t_b,i|)
  // fits within what the interpolator's plan leaves of that axis' jerk over one period (J_i - plan share T^2) and
  // of its acceleration (A_i - plan share T). The programmed path is then followed exactly. period_s = 0: every
  // kink is blended.
  double period_s = 0.0;
  core::Vec6 axis_velocity = core::Vec6::Constant(1e300);
  double plan_accel_share = 1.0, plan_jerk_share = 1.0;  // shares of the axis limits the plan may use
  // Lines shorter than tiny_move_share x tolerance (on the tool tip) are merged into a neighbouring line of the same
  // tool: kept, each would be a corner of its own whose blends, limited to half its length, make the axes crawl
  // (a G20 program's first point 1.7 um from a start given in mm). The path moves by at most the tiny line's length,
  // which the blends beside it give up from their tolerance.
  double tiny_move_share = 0.25;
};

struct SmoothPath {
  std::vector<PathPiece> pieces;
  double length = 0.0;
  int blends = 0;
  int exact_stops = 0;
  core::Vec6 start = core::Vec6::Zero(), end = core::Vec6::Zero();  // path space (degrees for A B C)

  // Index of the piece holding arc length s (pieces are contiguous; hint speeds up monotone queries).
  std::size_t piece_at(double s, std::size_t hint = 0) const;
  core::Vec6 point(double s) const;

  // Point at arc length s for increasing queries (setpoints): Newton on the arc length starts from the previous
  // query's parameter, one or two steps over a short interval instead of a search from the table.
  struct Cursor {
    std::size_t piece = 0;
    double u = -1.0, s_local = 0.0;
  };
  core::Vec6 point(double s, Cursor& cursor) const;
};

// Program axes to path space (rad -> deg for A B C) and back.
core::Vec6 to_path_space(const core::Vec6& program);
core::Vec6 from_path_space(const core::Vec6& path);

// Builds the G2 path of a ToolPath. Throws core::Error naming the program line of a move it cannot use.
SmoothPath build_smooth_path(const core::ToolPath& path, const SmoothPathOptions& options);

}  // namespace vmsim::motion
