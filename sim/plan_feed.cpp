#include "sim/plan_feed.hpp"
#include "sim/drive_checks.hpp"

#include "core/error.hpp"
#include "core/timing.hpp"
#include "motion/kinematics.hpp"
#include "sim/chain.hpp"
#include "sim/job_program.hpp"

#include <algorithm>

namespace vmsim::sim {

namespace {

using core::Clock;
using core::seconds_since;
using Eigen::Index;

nlohmann::json check_json(const methods::FeedPlanCheck& c) {
  return {{"feed", c.feed},
          {"chord_error", c.chord},
          {"contour_error_model", c.contour},
          {"axis_velocity", c.axis_velocity},
          {"axis_acceleration", c.axis_acceleration},
          {"axis_jerk", c.axis_jerk},
          {"worst", c.worst()}};
}

nlohmann::json run_json(const methods::PlayedPlan& p) {
  return {{"cycle_time_s", p.interp.stats.cycle_time_s},
          {"setpoints", p.interp.setpoints.samples()},
          {"interpolator_repair_passes", p.interp.stats.repair_passes},
          {"simulated_contour_error_max_um", p.max_abs_mm * 1e3},
          {"simulated_contour_error_rms_um", p.contour.rms_mm * 1e3},
          {"chord_error_max_um", p.chord_error_mm.maxCoeff() * 1e3}};
}

// The job's path sampled for the plan: a curve by its parameter with arc-length correction (the plan's s is the
// curve's own arc length, mapped onto the quintic chain the interpolator follows), a program along its smoothed path.
// Sets the result's program, path, samples and f_max; returns report.json's "path".
nlohmann::json sample_job_path(const core::Job& job, const Chain& chain, methods::PlanPlayer& player,
                               PlanFeedResult& r) {
  const core::FeedPlanSpec& spec = *job.feedplan;
  r.max_feed_mm_per_s = spec.max_feed_mm_per_s.value_or(0.0);
  nlohmann::json path_json;
  if (const JobCurve* c = chain.curve()) {
    r.workpiece = c->path.program;
    r.program = motion::toolpath_in_axis_space(r.workpiece, job.machine);
    r.path = c->path.path;
    player.to_path_s = [c](double s) { return c->path.path_s(s); };
    player.to_sample_s = [c](double s) { return c->path.curve_s(s); };
    r.samples = methods::sample_nurbs(c->curve, spec.sample_spacing_mm);
    path_json = {{"kind", "nurbs"},
                 {"degree", c->curve.degree},
                 {"control_points", c->curve.points.size()},
                 {"quintic_pieces", c->path.path.pieces.size()},
                 {"quintic_chain_max_deviation_um", c->path.max_deviation_mm * 1e3}};
  } else {
    r.workpiece = read_job_program(job);
    r.program = motion::toolpath_in_axis_space(r.workpiece, job.machine);
    double programmed = 0.0;
    for (const core::Move& m : r.program.moves)
      if (!m.rapid && m.feed_mode == core::FeedMode::UnitsPerMinute)
        programmed = std::max(programmed, m.feed_mm_per_min / 60.0);
    if (!spec.max_feed_mm_per_s) r.max_feed_mm_per_s = programmed;
    if (!(r.max_feed_mm_per_s > 0))
      throw core::Error(core::located(job.file.string(), 0,
                                      "[feedplan] max_feed_mm_per_s: the program has no feed "
                                      "move to take it from; give it"));
    r.path = chain.smooth_path(r.workpiece);
    r.samples = methods::sample_path(r.path, spec.sample_spacing_mm);
    path_json = {{"kind", "program"}, {"moves", r.program.moves.size()}};
  }
  const methods::PathSamples& s = r.samples;
  path_json["length_mm"] = s.s[s.size() - 1];
  path_json["samples"] = s.size();
  path_json["sample_spacing_mm"] = s.ds;
  path_json["smallest_radius_mm"] = 1.0 / s.kappa_max.maxCoeff();
  return path_json;
}

void fill_report(const core::FeedPlanSpec& spec, const nlohmann::json& path_json, PlanFeedResult& r) {
  const methods::FeedPlanLimits& lim = r.limits;
  nlohmann::json& rep = r.report;
  rep["path"] = path_json;
  rep["servo"] = {{"model", r.servo_description},
                  {"natural_frequency_rad_s", r.natural_frequency_rad_s},
                  {"simulated_by", r.transfer_function_servo ? "methods::TransferFunctionAxis per axis"
                                                             : "drives::simulate_axes (the machine's cascades)"}};
  rep["limits"] = {
      {"period_s", lim.period_s},
      {"chord_error_um", spec.chord_error_mm * 1e3},
      {"contour_error_um", spec.contour_error_mm * 1e3},
      {"max_feed_mm_per_s", r.max_feed_mm_per_s},
      {"axis_velocity_mm_per_s", {lim.axis_velocity[0], lim.axis_velocity[1], lim.axis_velocity[2]}},
      {"axis_acceleration_mm_per_s2", {lim.axis_acceleration[0], lim.axis_acceleration[1], lim.axis_acceleration[2]}},
      {"axis_jerk_mm_per_s3",
       spec.jerk ? nlohmann::json({lim.axis_jerk[0], lim.axis_jerk[1], lim.axis_jerk[2]}) : nlohmann::json(nullptr)}};
  const methods::FeedPlan& plan = r.verified.plan;
  const auto& st = plan.stats;
  rep["lp"] = {{"solver", "COIN-OR Clp, dual simplex"},
               {"variables_per_window_max", st.lp_columns_max},
               {"rows_per_window_max", st.lp_rows_max},
               {"nonzeros_per_window_max", st.lp_nonzeros_max},
               {"windows", st.windows},
               {"window_samples", st.window_samples},
               {"overlap_samples", st.overlap_samples},
               {"solves", st.lp_solves},
               {"jerk_linearisations_max", st.jerk_iterations_max},
               {"lp_seconds", st.lp_seconds},
               {"plan_seconds", st.total_seconds},
               {"axis_acceleration_share", r.played_as_profile ? motion::kPlanAccelShare : 1.0},
               {"axis_jerk_share", r.played_as_profile ? motion::kPlanJerkShare : 1.0}};
  nlohmann::json runs;
  runs["no_plan"] = run_json(r.no_plan);
  nlohmann::json& free = runs["plan_without_contour_error"] = run_json(r.free_played);
  free["plan_time_s"] = r.free_plan.time_s;
  free["model_contour_error_max_um"] = r.model_peak_free_mm * 1e3;
  free["check"] = check_json(r.check_free);
  const methods::VerifiedPlan& ver = r.verified;
  nlohmann::json& p = runs["plan"] = run_json(ver.played);
  p["plan_time_s"] = plan.time_s;
  // A plan followed as a profile plays in its own time plus the interpolator's filter; as a ceiling, more slowly
  // (parts/feedplan/README.md says where and why).
  p["played_over_planned"] = ver.played.interp.stats.cycle_time_s / plan.time_s;
  p["played_as"] = r.played_as_profile ? "profile" : "ceiling";
  p["model_contour_error_max_um"] = r.model_peak_mm * 1e3;
  p["check"] = check_json(r.check);
  p["verification_rounds"] = ver.rounds;
  p["simulated_peak_per_round_um"] = ver.simulated_peak_mm;
  for (auto& v : p["simulated_peak_per_round_um"]) v = v.get<double>() * 1e3;
  p["plan_time_per_round_s"] = ver.model_time_s;
  p["contour_scale_min"] = ver.contour_scale.minCoeff();
  p["within_tolerance"] = ver.played.max_abs_mm <= spec.contour_error_mm;
  rep["runs"] = runs;
  rep["cycle_time_cost_of_contour_constraint"] =
      ver.played.interp.stats.cycle_time_s / r.free_played.interp.stats.cycle_time_s - 1.0;
}

}  // namespace

PlanFeedResult plan_feed(const core::Job& job, core::Progress& progress) {
  const auto t_start = Clock::now();
  if (!job.feedplan)
    throw core::Error(core::located(job.file.string(), 0, "the job has no [feedplan] table (see parts/README.md)"));
  const core::FeedPlanSpec& spec = *job.feedplan;
  const core::Machine& machine = job.machine;
  const double te = job.interp.period_s;
  // The job's chain, with three departures: the plan is computed here (the job's own is not followed), a gain
  // schedule belongs to the unplanned setpoints (the drives run their own gains), and the axes settle 0.3 s after
  // the last setpoint (the plans' verification has always measured the settling this long).
  ChainOptions copt;
  copt.ignore_feed_plan = true;
  copt.ignore_gain_schedule = true;
  copt.settle_s = 0.3;
  const Chain chain(job, copt);
  PlanFeedResult r;
  methods::PlanPlayer player;
  progress.stage(job.name + ": sampling the path");
  const nlohmann::json path_json = sample_job_path(job, chain, player, r);
  player.program = &r.program;
  player.machine = &machine;
  player.interp = chain.interp_options();
  player.settle_s = copt.settle_s;
  // The plan is followed as a profile when it keeps the axes' jerk limits (the interpolator's model) and the path has
  // no exact stop inside; otherwise it is a ceiling the interpolator plans under (slower than the plan's own time).
  player.follow = spec.jerk && r.path.exact_stops == 0;
  player.interpolate = [&](const motion::FeedCeiling& c) { return chain.interpolate(r.workpiece, c); };
  player.simulate = [&](const core::Setpoints& sp) { return chain.simulate(sp).position; };
  r.played_as_profile = player.follow;
  progress.done();
  r.timings["path"] = seconds_since(t_start);

  // Servo and limits (Chen et al. 2016 eq. 6-13, 15-23).
  r.moving = methods::moving_axes(r.samples);
  const methods::FeedPlanServo servo = methods::feed_plan_servo(spec, machine, te, r.moving, job.file.string());
  r.servo_description = servo.description;
  r.transfer_function_servo = chain.transfer_function_servo();
  const methods::ContourErrorModel model(servo.responses);
  r.natural_frequency_rad_s = model.natural_frequency();
  r.limits = methods::feed_plan_limits(spec, machine, te, r.max_feed_mm_per_s, r.moving);
  methods::FeedPlanOptions opt;
  opt.limits = r.limits;
  if (player.follow) {
    // A followed plan keeps the interpolator's own shares of the limits (what it leaves for the sampled setpoints).
    opt.limits.axis_acceleration *= motion::kPlanAccelShare;
    opt.limits.axis_jerk *= motion::kPlanJerkShare;
  }
  opt.contour_model = &model;
  opt.window_samples = spec.window_samples;
  methods::FeedPlanOptions opt_free = opt;  // the same plan without the contour-error constraint
  opt_free.limits.contour_error_mm = 0.0;

  const auto t0 = Clock::now();
  progress.stage(job.name + ": simulating the programmed feed");
  r.no_plan = methods::play_plan(player, r.samples, nullptr);
  progress.done();
  progress.stage(job.name + ": planning and simulating without the contour-error constraint");
  r.free_plan = methods::plan_feed(r.samples, opt_free);
  r.free_played = methods::play_plan(player, r.samples, &r.free_plan);
  progress.done();
  progress.stage(job.name + ": planning with the contour-error constraint, simulating, verifying");
  methods::VerifyOptions vo;
  if (!spec.verify) vo.max_rounds = 1;
  r.verified = methods::plan_feed_verified(r.samples, opt, player, vo);
  progress.done();
  r.timings["plans_and_simulations"] = seconds_since(t0);
  const methods::FeedPlan& plan = r.verified.plan;
  r.check = methods::check_feed_plan(r.samples, plan.feed, r.limits, &model);
  methods::FeedPlanLimits free_limits = r.limits;  // checked against the machine's limits, as the plan
  free_limits.contour_error_mm = 0.0;
  r.check_free = methods::check_feed_plan(r.samples, r.free_plan.feed, free_limits, &model);
  r.model_peak_free_mm = methods::model_contour_peak(r.samples, r.free_plan.feed, model);
  r.model_peak_mm = methods::model_contour_peak(r.samples, plan.feed, model);
  r.ceiling = r.verified.played.ceiling;  // the plan as it was played: a profile or a ceiling
  const core::Setpoints& sp = r.verified.played.interp.setpoints;
  r.played_sample_s.resize(sp.samples());
  for (Index k = 0; k < sp.samples(); ++k)
    r.played_sample_s[k] = player.to_sample_s ? player.to_sample_s(sp.path_length_mm[k]) : sp.path_length_mm[k];
  fill_report(spec, path_json, r);
  const DriveChecks drive_checks = check_drives_before(machine, sp, chain.cascade_axes());
  r.report["drive_checks"] = drive_checks.axes;
  add_verdict(r.report, drive_checks.warnings);
  return r;
}

}  // namespace vmsim::sim
