// vmsim motion JOB: program -> interpolator -> servo drives -> kinematics -> contour error.
#include "sim/axis_models.hpp"
#include "app/commands.hpp"
#include "sim/contour_stats.hpp"
#include "sim/job_program.hpp"
#include "app/report.hpp"
#include "sim/signals.hpp"
#include "core/atomic_file.hpp"
#include "motion/contour.hpp"
#include "core/error.hpp"
#include "core/timing.hpp"
#include "motion/interp.hpp"
#include "core/job.hpp"
#include "motion/kinematics.hpp"
#include "program/program.hpp"
#include "core/units.hpp"
#include "methods/oga_schedule.hpp"
#include "sysid/position_trace.hpp"
#include "drives/simulate.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <functional>
#include <cstdio>

namespace vmsim::app {

namespace {

using core::Clock;
using core::seconds_since;

// Axis units to the units written in the files (mm or deg).
double file_unit(const core::MachineAxis& ax) { return ax.kind == core::AxisKind::Rotary ? core::units::kRadToDeg : 1.0; }
const char* unit_name(const core::MachineAxis& ax) { return ax.kind == core::AxisKind::Rotary ? "deg" : "mm"; }

// Tool-tip path in the workpiece frame, sample by sample (the tool length offset of the move each sample is on).
Eigen::MatrixXd tip_path(const Eigen::MatrixXd& axes, const core::Setpoints& sp, const core::ToolPath& program,
                         const motion::Kinematics& kin) {
  Eigen::MatrixXd tip(axes.rows(), 3);
  for (Eigen::Index k = 0; k < axes.rows(); ++k) {
    const Eigen::Index ks = std::min(k, sp.samples() - 1);
    const int mi = sp.move_index[ks];
    const double tlo = mi >= 0 ? program.moves[static_cast<std::size_t>(mi)].tool_length_offset_mm : 0.0;
    tip.row(k) = kin.forward(axes.row(k).transpose(), tlo).tip_mm.transpose();
  }
  return tip;
}

void write_csv(const std::filesystem::path& file, const std::string& header,
               const std::function<void(Eigen::Index, std::string&)>& row, Eigen::Index rows) {
  core::AtomicFile out(file);
  out.stream() << header << '\n';
  std::string line;
  for (Eigen::Index k = 0; k < rows; ++k) {
    line.clear();
    row(k, line);
    line += '\n';
    out.stream() << line;
  }
  out.commit();
}

}  // namespace

int run_motion(const MotionArgs& args) {
  const auto t_start = Clock::now();
  const core::Job job = core::load_job(args.job);
  const core::Machine& machine = job.machine;
  const core::ToolPath program = sim::read_job_program(job);
  const core::ToolPath path = motion::toolpath_in_axis_space(program, machine);
  const double t_read = seconds_since(t_start);

  auto t0 = Clock::now();
  motion::InterpOptions iopt;
  iopt.period_s = job.interp.period_s;
  iopt.tolerance_mm = job.interp.tolerance_mm;
  iopt.feed_scale = args.feed_scale.value_or(1.0);
  const motion::InterpResult ir = motion::interpolate(path, machine, iopt);
  const core::Setpoints& sp = ir.setpoints;
  const double t_interp = seconds_since(t0);

  t0 = Clock::now();
  drives::SimulateOptions sopt;
  sopt.full_rate_trace = args.full_rate_trace;
  drives::GainSchedule schedule;  // [job] gain_schedule (vmsim oga): the drives run its gains
  if (job.gain_schedule_file) {
    schedule = methods::read_gain_schedule(*job.gain_schedule_file, sp, machine);
    sopt.gains = &schedule;
  }
  // [job] axis_models (vmsim identify): those axes run as their identified transfer functions.
  const sim::JobAxisModels models = sim::job_axis_models(job, std::nullopt);
  if (models.any()) sopt.axis_models = &models.per_axis;
  const drives::AxisResponse resp = drives::simulate_axes(sp, machine, sopt);
  const double t_drives = seconds_since(t0);

  // Command and actual tool tip in the workpiece frame; the command holds its last point while the axes settle.
  t0 = Clock::now();
  const auto kin = motion::make_kinematics(machine);
  const Eigen::MatrixXd cmd_tip = tip_path(sp.position, sp, program, *kin);
  const Eigen::MatrixXd act_tip = tip_path(resp.position, sp, program, *kin);
  const motion::ContourError ce = motion::contour_error(cmd_tip, act_tip);
  const double t_contour = seconds_since(t0);

  const Eigen::Index n = resp.samples(), ns = sp.samples(), na = static_cast<Eigen::Index>(machine.axes.size());
  auto setpoint = [&](Eigen::Index k, Eigen::Index a) { return sp.position(std::min(k, ns - 1), a); };

  // Figures per axis.
  nlohmann::json axes = nlohmann::json::object();
  const core::AxisPeaks sp_peaks = core::finite_difference_peaks(sp);
  bool setpoint_limits_held = true, currents_within_limit = true;
  for (Eigen::Index a = 0; a < na; ++a) {
    const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(a)];
    double max_te = 0, sum2 = 0, peak_i = 0, peak_v = 0, peak_acc = 0, peak_j = 0;
    for (Eigen::Index k = 0; k < n; ++k) {
      const double e = setpoint(k, a) - resp.position(k, a);
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
    setpoint_limits_held = setpoint_limits_held && sp_ok;
    const double i_lim = ax.drive ? ax.drive->current_limit_A : 0.0;
    const bool i_ok = !ax.drive || peak_i <= i_lim * (1 + 1e-9);
    currents_within_limit = currents_within_limit && i_ok;
    const std::string u = unit_name(ax);
    axes[ax.name] = {
        {"tracking_error_max_" + u, max_te * f},
        {"tracking_error_rms_" + u, std::sqrt(sum2 / std::max<Eigen::Index>(1, n)) * f},
        {"peak_current_A", peak_i},
        {"current_limit_A", i_lim},
        {"setpoints_within_limits", sp_ok},
        {"setpoint_peaks", {{"velocity_" + u + "_per_s", sp_peaks.velocity[a] * f},
                            {"acceleration_" + u + "_per_s2", sp_peaks.acceleration[a] * f},
                            {"jerk_" + u + "_per_s3", sp_peaks.jerk[a] * f}}},
        {"actual_peaks", {{"velocity_" + u + "_per_s", peak_v * f},
                          {"acceleration_" + u + "_per_s2", peak_acc * f},
                          {"jerk_" + u + "_per_s3", peak_j * f}}},
        {"limits", {{"velocity_" + u + "_per_s", ax.max_velocity * f},
                    {"acceleration_" + u + "_per_s2", ax.max_acceleration * f},
                    {"jerk_" + u + "_per_s3", ax.max_jerk * f}}},
    };
  }

  // Files.
  t0 = Clock::now();
  const std::filesystem::path dir = args.out_dir.value_or(std::filesystem::current_path());
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw core::Error(dir.string() + ": cannot create the output directory: " + ec.message());
  const double te = sp.period_s;
  std::string h_axes, h_sp, h_te, h_i;
  for (const auto& ax : machine.axes) {
    const std::string u = unit_name(ax);
    h_axes += fmt::format(",{0}_{1},{0}_velocity_{1}_per_s,{0}_acceleration_{1}_per_s2,{0}_jerk_{1}_per_s3", ax.name, u);
    h_sp += fmt::format(",{}_{}", ax.name, u);
    h_te += fmt::format(",{}_tracking_{}", ax.name, u == "mm" ? "mm" : "deg");
    h_i += fmt::format(",{0}_current_mean_A,{0}_current_peak_A,{0}_current_setpoint_A", ax.name);
  }
  std::vector<std::string> files;
  write_csv(dir / "setpoints.csv", "t_s" + h_sp + ",path_speed_mm_per_s", [&](Eigen::Index k, std::string& l) {
    l += fmt::format("{:.6f}", k * te);
    for (Eigen::Index a = 0; a < na; ++a)
      l += fmt::format(",{:.9f}", sp.position(k, a) * file_unit(machine.axes[static_cast<std::size_t>(a)]));
    l += fmt::format(",{:.6f}", sp.path_speed_mm_per_s[k]);
  }, ns);
  files.push_back("setpoints.csv");
  write_csv(dir / "actual.csv", "t_s" + h_axes, [&](Eigen::Index k, std::string& l) {
    l += fmt::format("{:.6f}", k * te);
    for (Eigen::Index a = 0; a < na; ++a) {
      const double f = file_unit(machine.axes[static_cast<std::size_t>(a)]);
      l += fmt::format(",{:.9f},{:.6f},{:.5f},{:.4f}", resp.position(k, a) * f, resp.velocity(k, a) * f,
                       resp.acceleration(k, a) * f, resp.jerk(k, a) * f);
    }
  }, n);
  files.push_back("actual.csv");
  write_csv(dir / "errors.csv", "t_s" + h_te + ",contour_error_mm", [&](Eigen::Index k, std::string& l) {
    l += fmt::format("{:.6f}", k * te);
    for (Eigen::Index a = 0; a < na; ++a)
      l += fmt::format(",{:.9f}", (setpoint(k, a) - resp.position(k, a)) * file_unit(machine.axes[static_cast<std::size_t>(a)]));
    l += fmt::format(",{:.9f}", ce.signed_mm[k]);
  }, n);
  files.push_back("errors.csv");
  write_csv(dir / "currents.csv", "t_s" + h_i, [&](Eigen::Index k, std::string& l) {
    l += fmt::format("{:.6f}", k * te);
    for (Eigen::Index a = 0; a < na; ++a)
      l += fmt::format(",{:.5f},{:.5f},{:.5f}", resp.current_mean_A(k, a), resp.current_peak_A(k, a),
                       resp.current_setpoint_A(k, a));
  }, n);
  files.push_back("currents.csv");
  {
    // Command and encoder position of every axis the program moves (drives/position_trace.hpp): what vmsim identify
    // reads, as an NC's trace of the same run would give it.
    sysid::PositionTrace tr;
    tr.period_s = te;
    std::vector<Eigen::Index> moved;
    for (Eigen::Index a = 0; a < na; ++a)
      if ((sp.position.col(a).array() != sp.position(0, a)).any()) moved.push_back(a);
    tr.t_s = Eigen::ArrayXd::LinSpaced(n, 0.0, static_cast<double>(n - 1) * te);
    tr.command.resize(n, static_cast<Eigen::Index>(moved.size()));
    tr.actual.resize(n, static_cast<Eigen::Index>(moved.size()));
    for (std::size_t i = 0; i < moved.size(); ++i) {
      const core::MachineAxis& ax = machine.axes[static_cast<std::size_t>(moved[i])];
      tr.axes.push_back(ax.name);
      tr.rotary.push_back(ax.kind == core::AxisKind::Rotary);
      for (Eigen::Index k = 0; k < n; ++k) tr.command(k, static_cast<Eigen::Index>(i)) = setpoint(k, moved[i]);
      tr.actual.col(static_cast<Eigen::Index>(i)) = resp.position.col(moved[i]);
    }
    if (!moved.empty()) {
      sysid::write_position_trace_csv(dir / "trace.csv", tr, {"vmsim motion " + job.file.filename().string()});
      files.push_back("trace.csv");
    }
  }
  // The same signals, binned (min/max) for charts: vmsim render DIR draws them.
  sim::write_signals(dir / "signals.csv", sim::motion_signals(job, program, sp, resp, ce, iopt.feed_scale));
  files.push_back("signals.csv");
  if (args.full_rate_trace) {
    for (std::size_t a = 0; a < resp.trace.size(); ++a) {
      const drives::FullRateTrace& tr = resp.trace[a];
      const core::MachineAxis& ax = machine.axes[a];
      const double f = file_unit(ax);
      const std::string name = "trace_" + ax.name + ".csv";
      write_csv(dir / name, fmt::format("t_s,position_{0},velocity_{0}_per_s,current_A,current_setpoint_A,voltage_V",
                                        unit_name(ax)),
                [&](Eigen::Index k, std::string& l) {
                  l += fmt::format("{:.7f},{:.9f},{:.6f},{:.5f},{:.5f},{:.4f}", k * tr.period_s, tr.position[k] * f,
                                   tr.velocity[k] * f, tr.current_A[k], tr.current_setpoint_A[k], tr.voltage_V[k]);
                },
                tr.position.size());
      files.push_back(name);
    }
  }
  const double t_write = seconds_since(t0);

  nlohmann::json report = report_header("motion", job);
  report["interpolation"] = {{"period_s", te},
                             {"tolerance_mm", iopt.tolerance_mm},
                             {"feed_scale", iopt.feed_scale},
                             {"cycle_time_s", ir.stats.cycle_time_s},
                             {"setpoints", ns},
                             {"moves", ir.stats.moves},
                             {"blends", ir.stats.blends},
                             {"exact_stops", ir.stats.exact_stops}};
  report["axes"] = axes;
  if (job.gain_schedule_file) report["gain_schedule"] = job.gain_schedule_file->string();
  if (models.any())
    report["axis_models"] = {{"path", models.file->string()}, {"identified_axes", models.identified_axes}};
  const sim::ContourStats cutting = sim::cutting_contour_stats(ce, sp, program);
  report["contour_error"] = sim::contour_json(ce, cutting);
  report["limits_held"] = {{"setpoints_velocity_acceleration_jerk", setpoint_limits_held},
                           {"currents", currents_within_limit}};
  report["files"] = files;
  report["timings_s"] = {{"read", t_read},   {"interpolate", t_interp}, {"drives", t_drives},
                         {"contour", t_contour}, {"write", t_write},     {"total", seconds_since(t_start)}};
  write_report(dir / "report.json", report);

  std::printf("job %s: cycle time %.3f s, %lld setpoints, drives simulated in %.2f s (%.0fx real time)\n",
              job.name.c_str(), ir.stats.cycle_time_s, static_cast<long long>(ns), t_drives,
              t_drives > 0 ? (n * te) / t_drives : 0.0);
  std::printf("contour error on cutting moves: max %.2f um, rms %.2f um, MSE %.3f um^2 (all moves: max %.2f um)\n",
              cutting.max_abs_mm * 1e3, cutting.rms_mm * 1e3, cutting.mse_um2, ce.max_abs_mm * 1e3);
  std::printf("axis  max tracking error   peak current / limit\n");
  for (const auto& ax : machine.axes) {
    const auto& j = axes[ax.name];
    const std::string u = unit_name(ax);
    std::printf("%-4s  %10.4f %-3s        %6.2f / %-5.1f A\n", ax.name.c_str(),
                j["tracking_error_max_" + u].get<double>(), u.c_str(), j["peak_current_A"].get<double>(),
                j["current_limit_A"].get<double>());
  }
  std::printf("limits held: setpoints %s, currents %s\n", setpoint_limits_held ? "yes" : "NO",
              currents_within_limit ? "yes" : "NO");
  std::printf("wrote %s (report.json, %zu CSV files)\n", dir.string().c_str(), files.size());
  return 0;
}

}  // namespace vmsim::app
