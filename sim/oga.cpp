#include "sim/oga.hpp"
#include "core/units.hpp"
#include "sim/drive_checks.hpp"

#include "core/error.hpp"
#include "core/timing.hpp"
#include "sim/chain.hpp"
#include "sim/job_program.hpp"

#include <omp.h>

#include <limits>

namespace vmsim::sim {

namespace {

using Eigen::Index;
using core::units::kNaN;

// Linear axes: mm/s -> m/min, mm/s^2 -> m/s^2, mm/s^3 -> m/s^3 (the units of Duong et al. Table I and the machine
// file).
nlohmann::json peaks_json(const methods::MotionPeaks& p, double te) {
  const auto at = [&](const methods::Peak& q) { return q.row >= 0 ? q.row * te : kNaN; };
  return {{"velocity_m_per_min", p.velocity.value * 60e-3},
          {"velocity_t_s", at(p.velocity)},
          {"acceleration_m_per_s2", p.acceleration.value * 1e-3},
          {"acceleration_t_s", at(p.acceleration)},
          {"jerk_m_per_s3", p.jerk.value * 1e-3},
          {"jerk_t_s", at(p.jerk)},
          {"current_peak_A", p.current.value},
          {"current_t_s", at(p.current)}};
}

const char* reference_name(methods::OgaOptions::Reference r) {
  return r == methods::OgaOptions::Reference::Best ? "best" : "machine";
}

nlohmann::json options_json(const methods::OgaOptions& o, const methods::OgaResult& r) {
  return {{"kp_grid_1000_per_min", r.kp_grid},
          {"kf_grid", r.kf_grid},
          {"gain_step_1000_per_min", o.gain_step},
          {"frequency_hz", o.frequency_hz},
          {"sinusoid_samples", r.sinusoid_samples},
          {"reference", reference_name(o.reference)},
          {"straight_curvature_per_mm", o.windows.straight_curvature_per_mm},
          {"transition_rate_per_mm2", o.windows.transition_rate_per_mm2},
          {"min_window_rows", o.windows.min_rows},
          {"lead_in_rows", o.lead_in_rows},
          {"settle_s", o.settle_s},
          {"from_start", o.from_start},
          {"limits", methods::limit_set_name(o.limits)},
          {"threads", omp_get_max_threads()}};
}

// The search's figures: admissible configurations, the best fixed pair, C1 and C2 per axis, the windows.
void search_json(const methods::OgaOptions& o, const methods::OgaResult& r, OgaJobResult& out) {
  nlohmann::json& rep = out.report;
  const std::size_t nq = r.axes.size();
  nlohmann::json adm = nlohmann::json::object();
  for (std::size_t q = 0; q < nq; ++q) {
    int n = 0;
    for (const auto& c : r.sweep[q]) n += c.admissible;
    adm[r.axis_names[q]] = {{"admissible", n}, {"configurations", r.sweep[q].size()}};
  }
  rep["admissible"] = adm;
  nlohmann::json best = nullptr;
  if (!r.best.empty()) {
    best = {{"mse_um2", r.best_mse_um2}, {"pairs_evaluated", r.pairs_evaluated}};
    for (std::size_t q = 0; q < nq; ++q)
      best[r.axis_names[q]] = {{"kv_1000_per_min", r.best[q].kp}, {"kf", r.best[q].kf}};
  }
  rep["best_fixed_pair"] = best;
  nlohmann::json c1 = {
      {"source", o.reference == methods::OgaOptions::Reference::Best ? "best fixed pair" : "machine file"}};
  nlohmann::json c2 = nlohmann::json::object();
  for (std::size_t q = 0; q < nq; ++q) {
    const auto col = r.table.kv_1000_per_min.col(static_cast<Index>(q));
    c1[r.axis_names[q]] = {{"kv_1000_per_min", r.c1[q].kp}, {"kf", r.c1[q].kf}};
    c2[r.axis_names[q]] = {{"kv_min_1000_per_min", col.minCoeff()},
                           {"kv_max_1000_per_min", col.maxCoeff()},
                           {"range_1000_per_min", {r.range[q].first, r.range[q].second}},
                           {"kf", r.c1[q].kf}};
  }
  rep["c1"] = c1;
  rep["c2"] = c2;
  nlohmann::json wins = nlohmann::json::array();
  for (const auto& w : r.windows) {
    nlohmann::json j = {{"first_row", w.window.begin},
                        {"end_row", w.window.end},
                        {"kind", methods::window_kind_name(w.window.kind)},
                        {"mse_um2", w.mse_um2},
                        {"hold_mse_um2", w.hold_mse_um2}};
    for (std::size_t q = 0; q < nq; ++q) j[r.axis_names[q] + "_final_kv_1000_per_min"] = w.final_kp[q];
    if (!w.note.empty()) j["note"] = w.note, ++out.windows_with_note;
    wins.push_back(j);
  }
  rep["windows"] = wins;
}

// How many configurations each limit alone admits (Duong et al. Fig. 7 counts every limit at once): on the drive
// without its friction (what vmsim judges, methods/oga.hpp says why), on the full model with its Coulomb/Stribeck
// friction, and on the setpoints themselves (the same for every gain: all or none). The current is the full model's.
nlohmann::json admissible_by_limit(const core::Machine& machine, const core::Setpoints& sp,
                                   const methods::OgaResult& r) {
  const methods::LimitSet kAlone[4] = {{true, false, false, false},
                                       {false, true, false, false},
                                       {false, false, true, false},
                                       {false, false, false, true}};
  const char* kNames[4] = {"velocity", "acceleration", "jerk", "current"};
  nlohmann::json out = nlohmann::json::object();
  for (std::size_t q = 0; q < r.axes.size(); ++q) {
    const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(r.axes[q])];
    const methods::MotionPeaks sp_peaks =
        methods::finite_difference_motion_peaks(sp.position.col(r.axes[q]), r.period_s);
    nlohmann::json drive, model, setpoints;
    for (int l = 0; l < 4; ++l) {
      int n_drive = 0, n_model = 0;
      for (const methods::ConfigCheck& c : r.sweep[q]) {
        n_drive += methods::limit_violation(c.twin, ax, r.period_s, kAlone[l]).empty();
        n_model += methods::limit_violation(c.model, ax, r.period_s, kAlone[l]).empty();
      }
      drive[kNames[l]] = n_drive;
      if (l < 3) {
        model[kNames[l]] = n_model;
        setpoints[kNames[l]] = methods::limit_violation(sp_peaks, ax, r.period_s, kAlone[l]).empty()
                                   ? static_cast<int>(r.sweep[q].size())
                                   : 0;
      }
    }
    out[r.axis_names[q]] = {{"configurations", r.sweep[q].size()},
                            {"drive_without_friction", drive},
                            {"drive_with_friction", model},
                            {"setpoints", setpoints}};
  }
  return out;
}

// The verification's figures (Duong et al. Table II, Fig. 12): MSE(CE) of C1 and C2, and per axis the limits and
// the peaks of C1 and C2.
void verification_json(const core::Machine& machine, const methods::OgaOptions& o, const methods::OgaResult& r,
                       const methods::OgaVerification& v, OgaJobResult& out) {
  const double te = r.period_s;
  nlohmann::json verification = nlohmann::json::object();
  for (std::size_t q = 0; q < r.axes.size(); ++q) {
    const methods::AxisVerification& av = v.axes[q];
    const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(r.axes[q])];
    verification[r.axis_names[q]] = {
        {"limits",
         {{"velocity_m_per_min", ax.max_velocity * 60e-3},
          {"acceleration_m_per_s2", ax.max_acceleration * 1e-3},
          {"jerk_m_per_s3", ax.max_jerk * 1e-3},
          {"current_A", ax.drive->current_limit_A}}},
        {"checked_c1", peaks_json(av.twin_c1, te)},
        {"checked_c2", peaks_json(av.twin_c2, te)},
        {"model_with_friction_c1", peaks_json(av.model_c1, te)},
        {"model_with_friction_c2", peaks_json(av.model_c2, te)},
        {"violation_c1", av.violation_c1},
        {"violation_c2", av.violation_c2},
        {"current_setpoint_peak_c1_A", av.current_setpoint_peak_c1_A},
        {"current_setpoint_peak_c2_A", av.current_setpoint_peak_c2_A},
        {"current_setpoint_max_diff_A", av.current_setpoint_max_diff_A},
        {"current_setpoint_max_diff_t_s", av.current_setpoint_max_diff_row * te},
        {"current_setpoint_max_rel_diff", av.current_setpoint_max_rel_diff},
    };
  }
  out.change_percent = v.mse_c1_um2 > 0 ? (v.mse_c2_um2 - v.mse_c1_um2) / v.mse_c1_um2 * 100 : 0.0;
  nlohmann::json& rep = out.report;
  rep["mse_table"] = {{"c1_mse_um2", v.mse_c1_um2},
                      {"c2_mse_um2", v.mse_c2_um2},
                      {"change_percent", out.change_percent},
                      {"c1_max_contour_error_um", v.max_c1_mm * 1e3},
                      {"c2_max_contour_error_um", v.max_c2_mm * 1e3},
                      {"c2_mse_um2_search", r.c2_mse_um2},
                      {"rows_counted", static_cast<Index>(o.row_weight.sum())}};
  rep["verification"] = verification;
  rep["limits_held"] = v.limits_held;
  rep["advice"] = v.advice;
}

}  // namespace

OgaJobResult oga_job(const core::Job& job, const OgaJobOptions& options, core::Progress& progress) {
  // The job's chain without its gain schedule (OGA computes one). A departure: the candidates run the machine's
  // cascades with their own gains (methods::offline_gain_adjustment), not identified axis models, which have none.
  ChainOptions copt;
  copt.ignore_gain_schedule = true;
  const Chain chain(job, copt);
  OgaJobResult out;
  out.program = read_job_program(job);
  out.interp = chain.interpolate(out.program);
  const core::Setpoints& sp = out.interp.setpoints;
  // The machine's drives, checked before any candidate runs (an unstable loop is refused).
  const DriveChecks drive_checks = check_drives_before(job.machine, sp, chain.cascade_axes());
  out.report["drive_checks"] = drive_checks.axes;
  add_verdict(out.report, drive_checks.warnings);
  methods::OgaOptions& o = out.options = options.search;
  // Rows that count in MSE(CE): those on feed moves (as vmsim motion's "cutting moves").
  o.row_weight = methods::feed_move_row_weights(sp, out.program, o.settle_s);
  if (!(o.row_weight.sum() > 0))
    throw core::Error(job.file.string() + ": the program has no feed move: no contour to adjust the gains on");
  if (options.range_all) methods::set_range_of_moving_axes(sp, job.machine, *options.range_all, o.range);
  bool staged = false;
  o.progress = [&](const std::string& s) {
    if (staged) progress.done();
    progress.stage(job.name + ": " + s);
    staged = true;
  };
  out.result = methods::offline_gain_adjustment(sp, job.machine, o);
  for (const auto& [k, x] : out.result.timings_s) out.timings["search_" + k] = x;
  if (!options.verify) {
    if (staged) progress.done();
    o.progress = nullptr;  // refers to this call's locals
    return out;
  }
  o.progress("verification on the whole path (nonlinear model)");
  const auto t0 = core::Clock::now();
  out.verification = methods::verify_oga(sp, job.machine, out.result, o);
  out.verification_s = core::seconds_since(t0);
  out.timings["verification"] = out.verification_s;
  progress.done();
  out.report["interpolation"] = {{"period_s", sp.period_s},
                                 {"tolerance_mm", job.interp.tolerance_mm},
                                 {"setpoints", sp.samples()},
                                 {"cycle_time_s", out.interp.stats.cycle_time_s}};
  out.report["options"] = options_json(o, out.result);
  search_json(o, out.result, out);
  out.report["admissible_by_limit"] = admissible_by_limit(job.machine, sp, out.result);
  verification_json(job.machine, o, out.result, *out.verification, out);
  o.progress = nullptr;  // refers to this call's locals
  return out;
}

}  // namespace vmsim::sim
