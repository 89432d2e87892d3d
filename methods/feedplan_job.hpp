#pragma once
// A job's [feedplan] (core::FeedPlanSpec) turned into what Chen et al. 2016's feed planning takes: the servo of the
// contour-error model (eq. 6-13) and of the simulation, the limits of eq. 15-23 from the machine file, and the
// circle model's own estimate of the contour error of a feed (eq. 7). vmsim plan-feed (sim/plan_feed.hpp) and
// sim::Chain (which runs a job's transfer-function servo in every command) build them here.
#include "core/job.hpp"
#include "core/machine.hpp"
#include "methods/feedplan.hpp"
#include "methods/feedplan_servo.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

namespace vmsim::methods {

// 1 for each of X Y Z the sampled path moves (its tangent has a component above 1e-9 somewhere), else 0.
Eigen::Vector3d moving_axes(const PathSamples& samples);

// The servo = "pid" or "transfer_function" of [feedplan], one transfer function per machine axis (machine-file
// order): Chen et al.'s PID (eq. 2) or the given G(s), and {1}/{1} (an ideal axis) where [[feedplan.axis]] names none
// (`given` says which were named). Empty for servo = "machine". Throws core::Error located in `job_file` for a
// transfer function that is not proper or a PID whose parameters give none.
std::vector<TransferFunction> feed_plan_transfer_functions(const core::FeedPlanSpec& spec, const core::Machine& machine,
                                                           const std::string& job_file,
                                                           std::vector<bool>* given = nullptr);

// The servo of a job's [feedplan]: frequency responses of the moving axes for the contour-error model, and for the
// simulation either transfer functions per machine axis or nothing (the machine's own cascades).
struct FeedPlanServo {
  std::vector<AxisFrequencyResponse> responses;  // the moving axes, X Y Z order
  std::vector<TransferFunction> simulate;        // per machine axis; empty: the machine's [axes.drive] cascades
  std::string description;
};
// Throws core::Error naming the machine file (servo = "machine": a moving axis without [axes.drive]) or the job file
// (a moving axis without its [[feedplan.axis]], or one whose response is not a position servo's).
FeedPlanServo feed_plan_servo(const core::FeedPlanSpec& spec, const core::Machine& machine, double te_s,
                              const Eigen::Vector3d& moving, const std::string& job_file);

// The limits of the plan: period T, chord error and contour tolerance from [feedplan], f_max, and per X Y Z the
// machine axis' velocity, acceleration and (with [feedplan] jerk = true) jerk limits; infinity for an axis the
// machine lacks. Throws core::Error when the path moves an axis the machine lacks.
FeedPlanLimits feed_plan_limits(const core::FeedPlanSpec& spec, const core::Machine& machine, double te_s,
                                double max_feed_mm_per_s, const Eigen::Vector3d& moving);

// Chen et al. 2016 eq. 7's estimate of the contour error of a feed profile: the largest rho |1 - |G(j f/rho)|| over
// the samples (rho = 1 / the sample's largest curvature; straight samples, curvature <= 1e-12, give none).
double model_contour_peak(const PathSamples& samples, const Eigen::ArrayXd& feed_mm_per_s,
                          const ContourErrorModel& model);

}  // namespace vmsim::methods
