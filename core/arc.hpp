#pragma once
// The geometry of a programmed arc or helix (core::Move with kind == Arc), worked out in one place: the plane's axes,
// the centre, the radii at both ends, the start angle and the signed sweep with its extra turns; points, tangents,
// length and chord counts along it. Every consumer of a Move's arc (the smooth path, the kinematics' axis-space
// conversion, pose sampling, the programmed track, the compensated-program writer) takes it from here, so they agree on
// full circles, turns, spirals and helices, as LinuxCNC computes a circle once (posemath's pmCircleInit).
//
// Conventions (LinuxCNC's ARC_FEED and pmCircleInit):
// - the arc runs in the plane of axes (axis1, axis2) about `normal` (axis1 x axis2 = normal, right-handed), by the
//   angle from the start point to the end point about the centre in the direction of Move::rotation (> 0:
//   counter-clockwise seen from +normal), in (0, 2 pi]: a whole turn when the start and end points coincide in the
//   plane (within 1e-9 of max(1 mm, the radius)) or when the end's angle is the start's within 1e-12 rad (a spiral
//   ending on its start's ray); |rotation| - 1 further turns are added;
// - the radius, the normal coordinate (helix) and the rotary axes move linearly with the swept angle (a spiral when
//   the start and end radii differ, as G-code and CL readers accept within their radius tolerance).
#include "core/toolpath.hpp"

#include <Eigen/Core>

#include <string>

namespace vmsim::core {

// Program axes (kX, kY, kZ) of an arc plane: XY: X, Y about Z; ZX: Z, X about Y; YZ: Y, Z about X.
struct PlaneAxes {
  int axis1 = kX, axis2 = kY, normal = kZ;
};
PlaneAxes plane_axes(ArcPlane plane);

struct ArcFrame {
  int axis1 = kX, axis2 = kY, normal = kZ;              // plane_axes(Move::plane)
  Eigen::Vector2d centre_mm = Eigen::Vector2d::Zero();  // (axis1, axis2) as Move::centre_mm
  double start_radius_mm = 0, end_radius_mm = 0;
  double start_angle_rad = 0;  // of the start point about the centre, from axis1 towards axis2, in [-pi, pi]
  double sweep_rad = 0;        // signed (> 0 counter-clockwise about +normal), extra turns included
  int extra_turns = 0;         // |Move::rotation| - 1
  bool full_circle = false;    // the start and end points coincide in the plane
  Vec6 start = Vec6::Zero(), end = Vec6::Zero();  // the move's ends, all six program axes

  // At a fraction f of the sweep (0 = start, 1 = end).
  double angle_at(double f) const { return start_angle_rad + f * sweep_rad; }
  double radius_at(double f) const { return start_radius_mm + f * (end_radius_mm - start_radius_mm); }
  // The radii agree to 1e-12 relative: a circle or helix (its arc length is linear in f), not a spiral.
  bool constant_radius() const;
  // All six program axes at f; the ends exactly (f <= 0: start, f >= 1: end).
  Vec6 point_at(double f) const;
  // d(X Y Z)/df at f.
  Eigen::Vector3d tangent_at(double f) const;
  // Length of the X Y Z path (mm): exact for circles and helices, to ~1e-13 relative for spirals.
  double length_mm() const;
  // Chords from f = k / n, k = 0..n, that stay within sag_mm of the arc in its plane (the larger radius counts),
  // each spanning at most max_angle_rad when that is > 0 (then the sag is not looked at). Throws core::Error when
  // more than 1e8 chords would be needed.
  int chords(double sag_mm, double max_angle_rad = 0.0) const;
};

// The frame of an arc move. Throws core::Error located at `file`:Move::source_line when the start or end point is at
// the centre (radius <= 1e-9 mm) or the move has no direction (rotation == 0).
ArcFrame arc_frame(const Move& move, const std::string& file = {});

}  // namespace vmsim::core
