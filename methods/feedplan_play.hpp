#pragma once
// A feed plan played as a machine would: the interpolator follows the path under the plan's feed ceiling
// (motion::interpolate with InterpOptions::feed_ceiling), the setpoints go through the axes' servos (the machine's
// cascades, drives::simulate_axes, or transfer-function servos such as Chen et al.'s PID, TransferFunctionAxis), and
// the contour error of the simulated axes is measured against the setpoints' path (motion::contour_error). Used by
// vmsim plan-feed and the tests, and by plan_feed_verified, which goes beyond Chen et al. 2016: it tightens the plan
// where the simulation, not only the steady-state circle model, exceeds the tolerance.
#include "motion/contour.hpp"
#include "motion/interp.hpp"
#include "core/machine.hpp"
#include "core/toolpath.hpp"
#include "methods/feedplan.hpp"
#include "methods/feedplan_servo.hpp"

#include <Eigen/Core>

#include <functional>
#include <vector>

namespace vmsim::methods {

struct PlanPlayer {
  const core::ToolPath* program = nullptr;  // the moves (in axis space), and for NURBS the chain's bookkeeping moves
  const core::Machine* machine = nullptr;
  motion::InterpOptions interp;  // period, tolerance, geometry (NURBS); the ceiling is set per play
  // Plan sample arc length -> the smoothed path's arc length (NURBS: motion::NurbsPath::path_s), and back. Empty: same.
  std::function<double(double)> to_path_s, to_sample_s;
  // One transfer function per machine axis (Chen et al.'s servo); empty: the machine's [axes.drive] cascades.
  std::vector<TransferFunction> servo;
  double settle_s = 0.3;  // simulated after the last setpoint
  // The plan played as a profile the interpolator follows (feed_profile, motion::FeedCeiling::follow; the path must
  // have no exact stops inside), or as a ceiling it plans its own jerk-limited profile under (feed_ceiling), which
  // takes longer than the plan's own time (parts/feedplan/README.md).
  bool follow = true;
  // The chain to play on, when given (vmsim plan-feed plays on the job's sim::Chain): the interpolator under a
  // ceiling, and the axes' positions for the setpoints (setpoint rows, then the settling rows). Empty: the members
  // above (motion::interpolate with `interp`; `servo` or the machine's cascades for settle_s).
  std::function<motion::InterpResult(const motion::FeedCeiling&)> interpolate;
  std::function<Eigen::MatrixXd(const core::Setpoints&)> simulate;
};

struct PlayedPlan {
  motion::FeedCeiling ceiling;  // what the interpolator was given (a profile to follow, a ceiling, or none)
  motion::InterpResult interp;
  Eigen::MatrixXd actual;        // simulated axis positions, setpoint rows then the settling rows (axis units)
  motion::ContourError contour;  // X Y Z, per actual row
  Eigen::ArrayXd
      chord_error_mm;         // per setpoint: the largest distance between the chord to the next setpoint and the path
  Eigen::ArrayXd sample_s;    // per actual row: the plan's arc length of its foot point
  Eigen::ArrayXd per_sample;  // per plan sample: the largest |contour error| of the rows whose foot lies in its
                              // interval (0 where none does)
  double max_abs_mm = 0.0;    // largest |contour error| while the path is followed (settling rows included)
};

// Throws core::Error from the interpolator or the servos. plan == nullptr: the program's own feed, no ceiling.
PlayedPlan play_plan(const PlanPlayer& player, const PathSamples& samples, const FeedPlan* plan);

struct VerifiedPlan {
  FeedPlan plan;                          // the last plan (the one that holds, when holds)
  Eigen::ArrayXd contour_scale;           // per sample, the factor on eps0 the plan used (1: untouched)
  std::vector<double> simulated_peak_mm;  // per round, the simulated contour error's peak
  std::vector<double> model_time_s;       // per round, the plan's own traversal time
  PlayedPlan played;                      // the last round's simulation
  int rounds = 0;
  bool holds = false;  // the last simulation is within eps0
};

struct VerifyOptions {
  int max_rounds = 8;
  // Where the simulation exceeds eps0 (a stretch of samples, peak p), eps0 is scaled by margin * eps0 / p on the
  // samples from reach_back_mm before the stretch to reach_ahead_mm after it: the servo's error at a point comes from
  // the motion just before it (its slow pole-zero pair), so the feed is lowered on the way in.
  double margin = 0.98;
  double reach_back_mm = 10.0, reach_ahead_mm = 2.0;
};

// Round 1 is plan_feed as Chen et al. 2016 has it; further rounds tighten where the simulation exceeds the tolerance.
VerifiedPlan plan_feed_verified(const PathSamples& samples, const FeedPlanOptions& options, const PlanPlayer& player,
                                const VerifyOptions& verify = {});

}  // namespace vmsim::methods
