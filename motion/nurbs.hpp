#pragma once
// NURBS curves (degree, control points, weights, knots): evaluation with derivatives, arc length and its inverse,
// and the curvature-continuous path the interpolator follows along them. Chen et al. 2016 plans feeds along NURBS paths
// (its eq. 16-23 use the curve's derivatives); core/nurbs gives those derivatives and the path, drives/feedplan
// the plan.
//
// How a NURBS reaches the interpolator (a decision, see parts/feedplan/README.md): as a chain of quintic pieces,
// each the Hermite interpolant of the curve's position, first and second derivative at its two ends, so the chain
// is exactly G2 (position, tangent and curvature vector continuous), and split until it stays within a tolerance
// (default 10 nm) of the curve. Not as a dense G1 polyline: the interpolator rounds every vertex with a G2 blend
// that turns the polyline's angle within about one segment, so its curvature ripples between 0 and ~1.9 times the
// curve's from one segment to the next (the axis acceleration, jerk and contour error with it). Not as arcs: their
// curvature is a staircase with jumps the interpolator rounds. The quintic pieces are the interpolator's own blend
// kind (core/smooth_path), given to it through InterpOptions::geometry; the ToolPath that goes with them (for
// bookkeeping: move indices, feeds, start and end) is the polyline through the pieces' joints.
#include "motion/smooth_path.hpp"
#include "core/toolpath.hpp"

#include <Eigen/Core>

#include <filesystem>
#include <string>
#include <vector>

namespace vmsim::motion {

struct NurbsCurve {
  int degree = 3;
  std::vector<Eigen::Vector3d> points;  // control points, mm (workpiece frame)
  std::vector<double> weights;          // one per control point, > 0
  std::vector<double> knots;            // non-decreasing, points.size() + degree + 1 values
  std::string source;                   // file(s) it came from, for messages

  double u_min() const { return knots[static_cast<std::size_t>(degree)]; }
  double u_max() const { return knots[knots.size() - 1 - static_cast<std::size_t>(degree)]; }
};

// Throws core::Error naming curve.source: degree < 1, too few points, sizes that do not match, a weight <= 0, knots
// that decrease, an empty parameter range, or a knot of multiplicity above the degree inside the range.
void check_nurbs(const NurbsCurve& curve);

// Reads a curve from two CSV files as ../shared/data/curves gives them: control points (columns index,x,y,z,weight;
// z and weight optional, default 0 and 1) and knots (index,knot); '#' comment lines and one header line. Throws
// core::Error naming the file and line.
NurbsCurve read_nurbs_csv(const std::filesystem::path& control_points, const std::filesystem::path& knots, int degree);

// Position and derivatives with respect to u (rational: the NURBS Book's A2.3 basis derivatives, then A4.2).
struct NurbsDerivs {
  Eigen::Vector3d p, d1, d2, d3;
};
NurbsDerivs nurbs_derivs(const NurbsCurve& curve, double u);

// Position and derivatives with respect to arc length: unit tangent t, curvature vector k = dt/ds (|k| = 1/rho),
// and dk/ds. Throws core::Error where the curve is not regular (|dP/du| = 0).
struct ArcJet {
  Eigen::Vector3d p, t, k, dk;
};
ArcJet arc_jet(const NurbsDerivs& d);

// Arc length s(u) and its inverse u(s): a table over every knot span (Gauss-Legendre, 5 points on 64 pieces per span,
// exact to round-off for these smooth integrands), then Newton on s(u) = s inside a table piece.
class NurbsArcLength {
 public:
  explicit NurbsArcLength(const NurbsCurve& curve);
  double length() const { return cum_.back(); }
  double s_at(double u) const;
  double u_at(double s) const;

 private:
  double integrate(double u0, double u1) const;
  const NurbsCurve* curve_;
  std::vector<double> u_, cum_;  // table nodes and the arc length at each
};

// The G2 path of a curve (see the top of this file).
struct NurbsPath {
  SmoothPath path;                // the quintic chain, in path space (A B C zero)
  core::ToolPath program;         // one line move per piece, joint to joint, at feed_mm_per_min
  std::vector<double> joint_u;    // curve parameter at each joint (pieces + 1)
  std::vector<double> joint_s;    // the curve's own arc length at each joint
  double max_deviation_mm = 0.0;  // largest distance found between a piece and the curve

  // The chain's arc length at the curve's arc length s (linear within each piece between the joints' values).
  double path_s(double curve_s) const;
  // The inverse: the curve's arc length at the chain's arc length s.
  double curve_s(double path_s) const;
};

struct NurbsPathOptions {
  double tolerance_mm = 1e-5;       // largest distance of the chain from the curve (checked at 32 points per piece)
  double max_piece_mm = 2.0;        // longest piece (keeps the interpolator's nodes close to the curve's features)
  double feed_mm_per_min = 3000.0;  // the program's feed on every move
};

NurbsPath nurbs_to_path(const NurbsCurve& curve, const NurbsPathOptions& options = {});

}  // namespace vmsim::motion
