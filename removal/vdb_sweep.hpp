#pragma once
// The level set of one tool sweep: the exact signed distance to the volume a tool sweeps on one straight move at
// constant orientation (removal/swept_tool.hpp's SweptTool), on both sides of its surface. The OpenVDB kernel
// (removal/vdb_part.cpp) samples it at the voxels of the stock's narrow band; moves whose orientation changes reach
// it already sub-stepped into constant-orientation sweeps by removal/track (its bound applies).
//
// The swept volume is K (+) ball(rc), K = c + disk(rho, a) (+) segment(0, hgt a) (+) segment(0, d): a convex "core"
// (a cylinder of radius rho = R - rc and height hgt = L - 2 rc, translated along the move d, from c = tip + rc a)
// grown by the corner radius rc. So sd(p) = sd_K(p) - rc, exactly, on both sides, and:
//   outside K: dist(p, K) = min over l in [0, 1] of dist(p - l d, cylinder), a convex 1-D problem. Closed forms for
//     a ball end (K is a parallelogram: its closest point), for moves perpendicular to the axis (3-axis milling in
//     the plane: the radial part is a point-segment distance) and for plunges (a longer cylinder); golden section
//     to 1e-12 of the move otherwise (oblique moves: ramps, tilted 5-axis tools).
//   inside K (flat and bull-nose ends only; a ball end's core is flat): depth = min over unit normals n of
//     h_K(n) - n.p (h_K the support function). A ball inscribed in a convex body touches it only where its surface
//     is smooth, and K's smooth pieces have normals perpendicular to a (the cylinder's sides and the planar faces
//     the move sweeps), along +-a (the end disks), or perpendicular to d (the rims swept along the move), so
//     depth = min(D1, D2, D3):
//       D1 = rho - dist(radial part of p, segment(0, radial part of d))  (a 2-D stadium),
//       D2 = distance to the two end planes,
//       D3 = the 2-D depth of p's projection along d in K's projection: an ellipse (the disk seen along d) swept
//            along the projected axis; its arcs are measured by sampling (every pi/32) and Newton's method on the
//            squared distance's derivative from the sampled minima (to 1e-10 rad, golden section if Newton leaves
//            the bracket), needed only when d is neither perpendicular nor parallel to the axis.
// Precision: round-off (1e-12 mm) for ball ends, for flat and bull-nose moves perpendicular or parallel to the
// axis; 1e-9 mm otherwise.
#include "removal/swept_tool.hpp"

#include <Eigen/Core>

namespace vmsim::removal {

class SweepDistance {
 public:
  explicit SweepDistance(const SweptTool& sweep);
  // Signed distance from p to the swept volume (mm): > 0 outside, < 0 inside.
  double operator()(const Eigen::Vector3d& p) const;
  const SweptTool& sweep() const { return s_; }

 private:
  double core_outside(const Eigen::Vector3d& w, double A, const Eigen::Vector3d& m) const;
  double core_depth(const Eigen::Vector3d& w, double A, const Eigen::Vector3d& m) const;
  double half_ellipse_distance(double x, double y) const;

  SweptTool s_;
  Eigen::Vector3d a_, c_, d_, e_;
  double rho_ = 0, rc_ = 0, hgt_ = 0, delta_ = 0, ee_ = 0;
  enum class Kind { Ball, Still, Level, Plunge, Oblique } kind_ = Kind::Ball;
  // Oblique moves: the plane perpendicular to d (axes u, v), the disk's projection (semi-axes rho along u, b_ along
  // v) and the projected axis (0, h_ along v, h_ >= 0).
  Eigen::Vector3d u_, v_;
  double b_ = 0, h_ = 0;
  // The half ellipse sampled every pi/32 (rho cos t, -b sin t): sin and cos once per sweep, not per voxel.
  static constexpr int kEllipseSamples = 32;
  double ex_[kEllipseSamples + 1] = {}, ey_[kEllipseSamples + 1] = {};
};

}  // namespace vmsim::removal
