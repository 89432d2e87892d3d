#pragma once
// vmsim plan-feed as a library call: Chen et al. 2016's contour-error-constrained feed plan for a job's path (its
// program, or its [feedplan.nurbs] curve), played on the job's chain (sim::Chain: the interpolator under the plan's
// feed ceiling, the axes through the job's servo) against the same path without a plan and with a plan that leaves
// the contour error out. The command line writes the results to files and draws them; the Python module hands them
// over as arrays.
#include "core/job.hpp"
#include "core/progress.hpp"
#include "core/toolpath.hpp"
#include "methods/feedplan.hpp"
#include "methods/feedplan_job.hpp"
#include "methods/feedplan_play.hpp"
#include "motion/interp.hpp"
#include "motion/smooth_path.hpp"

#include <Eigen/Core>
#include <nlohmann/json.hpp>

namespace vmsim::sim {

struct PlanFeedResult {
  core::ToolPath workpiece;      // the job's program as read (workpiece frame; a curve's bookkeeping moves)
  core::ToolPath program;        // the same in axis space: the moves the interpolator follows
  motion::SmoothPath path;       // the smoothed path it follows: the arc length of `ceiling`
  methods::PathSamples samples;  // the plan's samples (a curve: its own arc length)
  Eigen::Vector3d moving;        // 1 for each of X Y Z the path moves
  double max_feed_mm_per_s = 0;  // f_max: [feedplan]'s, or the program's highest feed
  std::string servo_description;
  bool transfer_function_servo = false;  // simulated as [feedplan]'s transfer functions (else the chain's drives)
  double natural_frequency_rad_s = 0;    // w_n of the contour-error model (eq. 11)
  methods::FeedPlanLimits limits;
  methods::PlayedPlan no_plan;               // the programmed feed, no ceiling
  methods::FeedPlan free_plan;               // the plan without the contour-error constraint (eq. 13 left out) ...
  methods::PlayedPlan free_played;           // ... and its play
  methods::VerifiedPlan verified;            // the plan with it, verified by simulation (its last play: .played)
  methods::FeedPlanCheck check, check_free;  // every constraint at every sample, recomputed from the feeds
  double model_peak_mm = 0, model_peak_free_mm = 0;  // eq. 7's estimate of the plans' contour error
  bool played_as_profile = false;  // the plans were followed as profiles (methods::PlanPlayer::follow)
  motion::FeedCeiling ceiling;     // the verified plan as the interpolator was given it (feed_plan.csv)
  Eigen::ArrayXd played_sample_s;  // per setpoint of the verified play: its plan arc length
  // report.json's figures: path, servo, limits, lp, runs, cycle_time_cost_of_contour_constraint; and the time spent
  // (path, plans_and_simulations).
  nlohmann::json report, timings;
};

// Throws core::Error (naming the job file and key) for a job without [feedplan], a servo that cannot be modelled, a
// path the plan does not handle (rotary axes), or an infeasible plan. The chain runs without the job's own feed plan
// and gain schedule (see the .cpp).
PlanFeedResult plan_feed(const core::Job& job, core::Progress& progress = core::no_progress());

}  // namespace vmsim::sim
