#pragma once
// The volume a milling tool sweeps on one straight move, and where a ray crosses it: the one kernel every dexel
// field (z-map, tri-dexel, N-buffer) uses. A ray against a swept tool gives the interval of material to subtract.
//
// Tool bodies are Minkowski sums, which makes their translations exact and cheap to query:
//   body = tip + rc a + disk(R - rc, normal a) (+) ball(rc) (+) segment(0, (L - 2 rc) a)
// with R the radius, rc the corner radius (ball: rc = R; flat: 0; bull-nose: 0 < rc < R), a the unit tool axis
// from the tip towards the spindle, L the tool length counted from the tip. The flat end and the cylinder are
// exact; above the cutting edge the body closes with a rounded top at height L (a ball end's top is a hemisphere),
// which only matters if a part is engaged over the full tool length.
// A translation by d sweeps body (+) segment(0, d): exact (no sampling) for straight moves at constant orientation.
#include "core/job.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace vmsim::removal {

struct Tool {
  double radius_mm = 5.0;
  double corner_radius_mm = 5.0;  // rc
  double length_mm = 50.0;        // L, from the tip
  double disk_radius() const { return radius_mm - corner_radius_mm; }
  // Largest distance from the tip to a point of the body: hypot(L - rc, R - rc) + rc (a flat end's top rim,
  // sqrt(L^2 + R^2); a ball end's top, L). Turning the axis by an angle phi about the tip moves no point of the body
  // by more than reach() * 2 sin(phi / 2) = reach() * |a - a'| (removal/track.hpp's orientation bound).
  double reach() const;
};

Tool make_tool(const core::ToolSpec& spec);

// One straight move of a tool at constant orientation: the body at tip0 translated by d.
struct SweptTool {
  Tool tool;
  Eigen::Vector3d tip0 = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // unit
  Eigen::Vector3d d = Eigen::Vector3d::Zero();      // translation of the move

  // Axis-aligned bounding box of the swept volume.
  void bounds(Eigen::Vector3d& lo, Eigen::Vector3d& hi) const;
};

// The interval [t0, t1] of the ray o + t u (u unit) inside the swept volume, if any. Exact up to round-off for
// ball-end and flat-end tools in every direction, and for bull-nose tools on rays parallel to their axis; a
// bull-nose on other rays is bracketed by three exact flat-end sweeps and its ends refined numerically to within
// 1e-7 mm (swept_tool.cpp).
bool ray_interval(const SweptTool& sweep, const Eigen::Vector3d& o, const Eigen::Vector3d& u, double& t0, double& t1);

// ray_interval for a ray whose material lies within [w0, w1] along it: an end the kernel knows to lie beyond the
// material (on the far side of it from the other end) may be returned anywhere further out, since subtracting either
// interval leaves the ray the same. Spares a bull-nose's numerical refinement of such ends.
bool ray_interval_within(const SweptTool& sweep, const Eigen::Vector3d& o, const Eigen::Vector3d& u, double w0,
                         double w1, double& t0, double& t1);

// ray_interval with the bull-nose solver as it was before issue 24 (nested golden sections on every ray, ~100x
// slower): the reference removal/cut_reference.cpp keeps for the tests.
bool ray_interval_reference(const SweptTool& sweep, const Eigen::Vector3d& o, const Eigen::Vector3d& u, double& t0,
                            double& t1);

// Signed-distance-like inside test (reference for tests): the distance from p to the swept volume, <= 0 inside.
double distance(const SweptTool& sweep, const Eigen::Vector3d& p);

}  // namespace vmsim::removal
