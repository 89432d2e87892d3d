#include "sim/motion_run.hpp"

#include "core/timing.hpp"
#include "core/units.hpp"
#include "motion/kinematics.hpp"
#include "sim/contour_stats.hpp"
#include "sim/job_program.hpp"
#include "sim/report.hpp"

#include <algorithm>
#include <cmath>

namespace vmsim::sim {

namespace {

using core::Clock;
using core::seconds_since;

// Tool-tip path in the workpiece frame, sample by sample (rows past the setpoints: the last setpoint's offset).
// forward_rows: the same bits as forward() row by row, without a pose object per row.
Eigen::MatrixXd tip_path(const Eigen::MatrixXd& axes, const Eigen::VectorXd& tlo_mm, const motion::Kinematics& kin) {
  const Eigen::Index n = axes.rows(), given = std::min(n, tlo_mm.size());
  Eigen::VectorXd tlo(n);
  tlo.head(given) = tlo_mm.head(given);
  if (given < n) tlo.tail(n - given).setConstant(tlo_mm.size() > 0 ? tlo_mm[tlo_mm.size() - 1] : 0.0);
  Eigen::MatrixXd tip(n, 3), no_axis;
  kin.forward_rows(axes, tlo, tip, no_axis);
  return tip;
}

// Each axis's tracking error, currents and peaks against its limits.
nlohmann::json axis_figures(const core::Machine& machine, const core::Setpoints& sp, const drives::AxisResponse& resp,
                            MotionRun& r) {
  nlohmann::json axes = nlohmann::json::object();
  const core::AxisPeaks sp_peaks = core::finite_difference_peaks(sp);
  const Eigen::Index n = resp.samples(), ns = sp.samples();
  for (Eigen::Index a = 0; a < static_cast<Eigen::Index>(machine.axes.size()); ++a) {
    const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(a)];
    double max_te = 0, sum2 = 0, peak_i = 0, peak_v = 0, peak_acc = 0, peak_j = 0;
    for (Eigen::Index k = 0; k < n; ++k) {
      const double e = sp.position(std::min(k, ns - 1), a) - resp.position(k, a);
      max_te = std::max(max_te, std::abs(e));
      sum2 += e * e;
      peak_i = std::max(peak_i, resp.current_peak_A(k, a));
      peak_v = std::max(peak_v, std::abs(resp.velocity(k, a)));
      peak_acc = std::max(peak_acc, std::abs(resp.acceleration(k, a)));
      peak_j = std::max(peak_j, std::abs(resp.jerk(k, a)));
    }
    const double f = file_unit(ax);
    const bool sp_ok = sp_peaks.velocity[a] <= ax.max_velocity * (1 + 1e-6) &&
                       sp_peaks.acceleration[a] <= ax.max_acceleration * (1 + 1e-6) &&
                       sp_peaks.jerk[a] <= ax.max_jerk * (1 + 1e-6);
    r.setpoint_limits_held = r.setpoint_limits_held && sp_ok;
    const double i_lim = ax.drive ? ax.drive->current_limit_A : 0.0;
    // The velocity loop's output clipped at the limit is a drive that asked for more than it has: not "held".
    bool saturated = false;
    if (ax.drive && resp.current_setpoint_A.size())
      saturated = (resp.current_setpoint_A.col(a).array().abs() >= i_lim * (1 - 1e-9)).any();
    r.currents_within_limit = r.currents_within_limit && (!ax.drive || (peak_i <= i_lim * (1 + 1e-9) && !saturated));
    const std::string u = unit_name(ax);
    axes[ax.name] = {
        {"tracking_error_max_" + u, max_te * f},
        {"tracking_error_rms_" + u, std::sqrt(sum2 / std::max<Eigen::Index>(1, n)) * f},
        {"peak_current_A", peak_i},
        {"current_limit_A", i_lim},
        {"current_saturated", saturated},
        {"setpoints_within_limits", sp_ok},
        {"setpoint_peaks",
         {{"velocity_" + u + "_per_s", sp_peaks.velocity[a] * f},
          {"acceleration_" + u + "_per_s2", sp_peaks.acceleration[a] * f},
          {"jerk_" + u + "_per_s3", sp_peaks.jerk[a] * f}}},
        {"actual_peaks",
         {{"velocity_" + u + "_per_s", peak_v * f},
          {"acceleration_" + u + "_per_s2", peak_acc * f},
          {"jerk_" + u + "_per_s3", peak_j * f}}},
        {"limits",
         {{"velocity_" + u + "_per_s", ax.max_velocity * f},
          {"acceleration_" + u + "_per_s2", ax.max_acceleration * f},
          {"jerk_" + u + "_per_s3", ax.max_jerk * f}}},
    };
  }
  return axes;
}

}  // namespace

double file_unit(const core::MachineAxis& ax) {
  return ax.kind == core::AxisKind::Rotary ? core::units::kRadToDeg : 1.0;
}
const char* unit_name(const core::MachineAxis& ax) { return ax.kind == core::AxisKind::Rotary ? "deg" : "mm"; }

MotionRun run_motion(const core::Job& job, const MotionRunOptions& options, core::Progress& progress) {
  const auto t_start = Clock::now();
  ChainOptions copt;
  copt.feed_scale = options.feed_scale;
  const Chain chain(job, copt);
  MotionRun r;
  r.program = read_job_program(job);
  const double t_read = seconds_since(t_start);

  auto t0 = Clock::now();
  progress.stage(job.name + ": interpolation");
  r.interp = chain.interpolate(r.program);
  progress.done();
  const core::Setpoints& sp = r.interp.setpoints;
  const double t_interp = seconds_since(t0);

  t0 = Clock::now();
  progress.stage(job.name + ": servo drives");
  r.response = chain.simulate(sp, options.full_rate_trace, &r.drive_checks);
  progress.done();
  const double t_drives = seconds_since(t0);

  // Command and actual tool tip in the workpiece frame; the command holds its last point while the axes settle.
  t0 = Clock::now();
  const auto kin = motion::make_kinematics(job.machine);
  const Eigen::VectorXd tlo = tool_length_offsets(r.program, sp);
  r.contour = motion::contour_error(tip_path(sp.position, tlo, *kin), tip_path(r.response.position, tlo, *kin));
  const double t_contour = seconds_since(t0);

  nlohmann::json& report = r.report;
  report = report_header("motion", job);
  report["interpolation"] = {{"period_s", sp.period_s},          {"tolerance_mm", chain.interp_options().tolerance_mm},
                             {"feed_scale", chain.feed_scale()}, {"cycle_time_s", r.interp.stats.cycle_time_s},
                             {"setpoints", sp.samples()},        {"moves", r.interp.stats.moves},
                             {"blends", r.interp.stats.blends},  {"exact_stops", r.interp.stats.exact_stops}};
  report["axes"] = axis_figures(job.machine, sp, r.response, r);
  if (job.gain_schedule_file) report["gain_schedule"] = job.gain_schedule_file->string();
  const JobAxisModels& models = chain.axis_models();
  if (models.any())
    report["axis_models"] = {{"path", models.file->string()}, {"identified_axes", models.identified_axes}};
  report["contour_error"] = contour_json(r.contour, cutting_contour_stats(r.contour, sp, r.program));
  report["limits_held"] = {{"setpoints_velocity_acceleration_jerk", r.setpoint_limits_held},
                           {"currents", r.currents_within_limit}};
  report["drive_checks"] = r.drive_checks.axes;
  add_verdict(report, r.drive_checks.warnings);
  report["timings_s"] = {{"read", t_read}, {"interpolate", t_interp}, {"drives", t_drives}, {"contour", t_contour}};
  return r;
}

sysid::PositionTrace position_trace(const core::Machine& machine, const core::Setpoints& sp,
                                    const drives::AxisResponse& resp) {
  sysid::PositionTrace tr;
  tr.period_s = sp.period_s;
  const Eigen::Index n = resp.samples(), ns = sp.samples();
  std::vector<Eigen::Index> moved;
  for (Eigen::Index a = 0; a < static_cast<Eigen::Index>(machine.axes.size()); ++a)
    if ((sp.position.col(a).array() != sp.position(0, a)).any()) moved.push_back(a);
  tr.t_s = Eigen::ArrayXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * sp.period_s);
  tr.command.resize(n, static_cast<Eigen::Index>(moved.size()));
  tr.actual.resize(n, static_cast<Eigen::Index>(moved.size()));
  for (std::size_t i = 0; i < moved.size(); ++i) {
    const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(moved[i])];
    tr.axes.push_back(ax.name);
    tr.rotary.push_back(ax.kind == core::AxisKind::Rotary);
    for (Eigen::Index k = 0; k < n; ++k)
      tr.command(k, static_cast<Eigen::Index>(i)) = sp.position(std::min(k, ns - 1), moved[i]);
    tr.actual.col(static_cast<Eigen::Index>(i)) = resp.position.col(moved[i]);
  }
  return tr;
}

}  // namespace vmsim::sim
