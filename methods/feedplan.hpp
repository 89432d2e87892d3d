#pragma once
// Contour-error-constrained feed planning (Chen et al. 2016): the largest feed along a path that keeps the contour
// error of the axes' servos within a tolerance, the chord error within its limit, the feed below f_max and each axis
// within its velocity, acceleration and (beyond the seed) jerk limits. A linear program in the squared feed q_i = f_i^2
// at equally spaced samples along the path (Chen et al. 2016 eq. 24-25), solved by COIN-OR Clp's dual simplex.
//
// The model, with arc length s as the path parameter (Chen et al.'s psi = 1: Q_u is the unit tangent t, Q_uu the
// curvature vector k, d^2u/dt^2 the tangential acceleration (q_{i+1} - q_i) / (2 ds), eq. 20-21):
// - contour error (eq. 6-13): a circle of the local radius rho = 1/|k| run at feed f has the steady error
//   rho |1 - |G(j f/rho)||; f <= w0(kappa eps0) rho with w0 the largest admissible frequency of eq. 11
//   (ContourErrorModel);
// - chord error (eq. 14-15): rho - sqrt(rho^2 - (f T / 2)^2) <= delta, i.e. f <= 2 sqrt(rho^2 - (rho - delta)^2) / T;
// - maximum feed (eq. 17) and axis velocity (eq. 22): f <= f_max, |t_r| f <= V_r;
// - axis acceleration (eq. 23): a_r = t_r (q_{i+1} - q_i) / (2 ds) + k_r q, within +-A_r. The seed writes it at the
//   interval's first sample; q is linear in s between samples (constant tangential acceleration), so it is written
//   here at both ends of every interval (k_r q_i and k_r q_{i+1}), which makes it hold at every sample;
// - axis jerk (beyond the seed): j_r = f d a_r / ds = f (t_r q''/2 + 3/2 k_r q' + k'_r q), central differences at
//   each interior sample. It is not linear in q (the factor f = sqrt q): it is linearised about the previous
//   solution, |t_r q''/2 + 3/2 k_r q' + k'_r q| <= J_r / f_bar, and iterated (f_bar damped towards sqrt q, which
//   converges in a few solves); a last solve with q <= f_bar^2 makes the true jerk f |...| <= f_bar |...| <= J_r.
// The pointwise bounds (eq. 24's f*) are taken as the smallest over each sample's interval (sub-samples and the
// path pieces' own nodes), so a short corner blend between two samples is not missed; f* also carries the
// centripetal part of eq. 23 there (|k_r| q <= A_r).
//
// Long paths are solved in overlapping windows: each window's LP starts from the two samples the previous one fixed,
// keeps its first (window - overlap) samples, and ends below the backward acceleration envelope (the fastest feed
// from which every later sample can still be reached by braking), so the cost grows linearly with the path length.
#include "motion/interp.hpp"
#include "motion/nurbs.hpp"
#include "motion/smooth_path.hpp"
#include "methods/feedplan_servo.hpp"

#include <Eigen/Core>

#include <functional>
#include <limits>
#include <string>

namespace vmsim::methods {

// The path at equally spaced arc lengths s_i = i ds, i = 0 .. N-1, the last at the path's end.
struct PathSamples {
  double ds = 0.0;
  Eigen::ArrayXd s;             // arc length (mm)
  Eigen::ArrayXd u;             // NURBS parameter at each sample (programs: NaN)
  Eigen::MatrixXd p, t, k, dk;  // N x 3: point (mm), unit tangent, curvature vector (1/mm), dk/ds (1/mm^2)
  // Over each sample's interval [s_i - ds/2, s_i + ds/2]: the largest curvature |k|, |t_r| and |k_r| per axis.
  Eigen::ArrayXd kappa_max;
  Eigen::MatrixXd t_abs_max, k_abs_max;
  Eigen::Index size() const { return s.size(); }
};

// A NURBS sampled by parameter with arc-length correction: u_i = u(s_i) by Newton on the arc length (core/nurbs).
PathSamples sample_nurbs(const motion::NurbsCurve& curve, double ds);
// Any program's smoothed path (motion::smooth_path_for: the lines, arcs and blends the interpolator follows). Throws
// core::Error when the path moves a rotary axis (the plan is for X Y Z paths).
PathSamples sample_path(const motion::SmoothPath& path, double ds);

struct FeedPlanLimits {
  double period_s = 0.004;          // T, the interpolation period (eq. 14-15)
  double chord_error_mm = 0.0005;   // delta_max (eq. 15); <= 0: no chord constraint
  double contour_error_mm = 0.020;  // eps0 (eq. 8); <= 0: no contour-error constraint
  double max_feed_mm_per_s = 50.0;  // f_max (eq. 17), also the initial feed of Chen et al. 2016 section 4
  // Per axis X Y Z (mm/s, mm/s^2, mm/s^3; eq. 22, 23 and the jerk); infinity: no limit.
  Eigen::Vector3d axis_velocity = Eigen::Vector3d::Constant(50.0);
  Eigen::Vector3d axis_acceleration = Eigen::Vector3d::Constant(200.0);
  Eigen::Vector3d axis_jerk = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
};

struct FeedPlanOptions {
  FeedPlanLimits limits;
  const ContourErrorModel* contour_model = nullptr;  // required when limits.contour_error_mm > 0
  Eigen::ArrayXd contour_scale;  // per sample, a factor (0, 1] on eps0 (plan_feed_verified); empty: 1 everywhere
  int window_samples = 4000;     // samples per LP window (the whole path when it has fewer)
  int overlap_samples = 0;       // samples each window looks beyond what it keeps; 0: twice the braking distance
  int max_jerk_iterations = 12;  // linearisations of the jerk constraint per window (then the safe final solve)
  double jerk_tolerance = 1e-3;  // relative change of q that ends the iterations
};

struct FeedPlanStats {
  int windows = 0;
  int lp_solves = 0;
  int jerk_iterations_max = 0;  // linearisations in the window that needed the most
  Eigen::Index lp_columns_max = 0, lp_rows_max = 0, lp_nonzeros_max = 0;  // largest window's LP
  int overlap_samples = 0, window_samples = 0;
  double lp_seconds = 0.0;     // Clp's dual simplex, all solves
  double total_seconds = 0.0;  // bounds, envelope, LP building and solving
};

struct FeedPlan {
  Eigen::ArrayXd s, feed;  // per sample: arc length (mm), planned feed (mm/s)
  // Eq. 24's pointwise bound f* and its parts (mm/s; infinity where one does not apply), and eq. 11's w0 (rad/s).
  Eigen::ArrayXd f_star, bound_contour, bound_chord, bound_axis_velocity, bound_centripetal, omega0;
  double time_s = 0.0;  // the plan's own traversal time (q linear in s between samples)
  FeedPlanStats stats;
};

// Throws core::Error for limits that are not positive, a contour tolerance without a model, or an infeasible LP.
FeedPlan plan_feed(const PathSamples& path, const FeedPlanOptions& options);

// Every constraint at every sample, recomputed from the path, the feeds and the limits alone (not from the LP's
// rows or w0): value / limit per constraint, the worst sample of each. Contour error: rho |1 - |G(j f/rho)||
// (eq. 7) straight from the model's G; chord: eq. 14; acceleration at both ends of each interval (eq. 23); jerk as
// in the plan with the true f.
struct FeedPlanCheck {
  double feed = 0, chord = 0, contour = 0, axis_velocity = 0, axis_acceleration = 0, axis_jerk = 0;
  Eigen::Index feed_at = -1, chord_at = -1, contour_at = -1, velocity_at = -1, acceleration_at = -1, jerk_at = -1;
  double worst() const;
};
FeedPlanCheck check_feed_plan(const PathSamples& path, const Eigen::ArrayXd& feed, const FeedPlanLimits& limits,
                              const ContourErrorModel* model);

// The plan as the interpolator's feed ceiling (motion::FeedCeiling): the samples' arc lengths mapped by `to_path_s`
// onto the smoothed path the interpolator follows (identity for programs; motion::NurbsPath's map for NURBS). The
// ends' zero feeds take their neighbours' values (the interpolator starts and stops at rest by itself).
motion::FeedCeiling feed_ceiling(const FeedPlan& plan, const std::function<double(double)>& to_path_s = {});
// The plan as a profile the interpolator follows (motion::FeedCeiling::follow): the same points with the ends at rest
// (feed 0), the first at s 0 and the last at `path_length_mm`. The plan keeps the axes' acceleration and jerk limits
// with the interpolator's model of them (the jerk of the tangential and centripetal parts, FeedPlanLimits::axis_jerk),
// so the interpolator plays it in the plan's own time plus its filter's length.
motion::FeedCeiling feed_profile(const FeedPlan& plan, double path_length_mm,
                                 const std::function<double(double)>& to_path_s = {});

}  // namespace vmsim::methods
