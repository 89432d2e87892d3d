// vmsim motion JOB: program -> interpolator -> servo drives -> kinematics -> contour error (sim/motion_run.hpp),
// written as CSV files and report.json.
#include "app/commands.hpp"
#include "app/report.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/timing.hpp"
#include "sim/contour_stats.hpp"
#include "sim/motion_run.hpp"
#include "sim/signals.hpp"
#include "sysid/position_trace.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <functional>

namespace vmsim::app {

namespace {

using core::Clock;
using core::seconds_since;
using sim::file_unit;
using sim::unit_name;

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

// setpoints.csv, actual.csv, errors.csv, currents.csv, trace.csv, signals.csv and the full-rate traces.
std::vector<std::string> write_motion_files(const std::filesystem::path& dir, const core::Job& job,
                                            const sim::MotionRun& r, const MotionArgs& args) {
  const core::Machine& machine = job.machine;
  const core::Setpoints& sp = r.interp.setpoints;
  const drives::AxisResponse& resp = r.response;
  const Eigen::Index n = resp.samples(), ns = sp.samples(), na = static_cast<Eigen::Index>(machine.axes.size());
  auto setpoint = [&](Eigen::Index k, Eigen::Index a) { return sp.position(std::min(k, ns - 1), a); };
  const double te = sp.period_s;
  std::string h_axes, h_sp, h_te, h_i;
  for (const auto& ax : machine.axes) {
    const std::string u = unit_name(ax);
    h_axes +=
        fmt::format(",{0}_{1},{0}_velocity_{1}_per_s,{0}_acceleration_{1}_per_s2,{0}_jerk_{1}_per_s3", ax.name, u);
    h_sp += fmt::format(",{}_{}", ax.name, u);
    h_te += fmt::format(",{}_tracking_{}", ax.name, u == "mm" ? "mm" : "deg");
    h_i += fmt::format(",{0}_current_mean_A,{0}_current_peak_A,{0}_current_setpoint_A", ax.name);
  }
  std::vector<std::string> files;
  write_csv(
      dir / "setpoints.csv", "t_s" + h_sp + ",path_speed_mm_per_s",
      [&](Eigen::Index k, std::string& l) {
        l += fmt::format("{:.6f}", k * te);
        for (Eigen::Index a = 0; a < na; ++a)
          l += fmt::format(",{:.9f}", sp.position(k, a) * file_unit(machine.axes[static_cast<std::size_t>(a)]));
        l += fmt::format(",{:.6f}", sp.path_speed_mm_per_s[k]);
      },
      ns);
  files.push_back("setpoints.csv");
  write_csv(
      dir / "actual.csv", "t_s" + h_axes,
      [&](Eigen::Index k, std::string& l) {
        l += fmt::format("{:.6f}", k * te);
        for (Eigen::Index a = 0; a < na; ++a) {
          const double f = file_unit(machine.axes[static_cast<std::size_t>(a)]);
          l += fmt::format(",{:.9f},{:.6f},{:.5f},{:.4f}", resp.position(k, a) * f, resp.velocity(k, a) * f,
                           resp.acceleration(k, a) * f, resp.jerk(k, a) * f);
        }
      },
      n);
  files.push_back("actual.csv");
  write_csv(
      dir / "errors.csv", "t_s" + h_te + ",contour_error_mm",
      [&](Eigen::Index k, std::string& l) {
        l += fmt::format("{:.6f}", k * te);
        for (Eigen::Index a = 0; a < na; ++a)
          l += fmt::format(
              ",{:.9f}", (setpoint(k, a) - resp.position(k, a)) * file_unit(machine.axes[static_cast<std::size_t>(a)]));
        l += fmt::format(",{:.9f}", r.contour.signed_mm[k]);
      },
      n);
  files.push_back("errors.csv");
  write_csv(
      dir / "currents.csv", "t_s" + h_i,
      [&](Eigen::Index k, std::string& l) {
        l += fmt::format("{:.6f}", k * te);
        for (Eigen::Index a = 0; a < na; ++a)
          l += fmt::format(",{:.5f},{:.5f},{:.5f}", resp.current_mean_A(k, a), resp.current_peak_A(k, a),
                           resp.current_setpoint_A(k, a));
      },
      n);
  files.push_back("currents.csv");
  // Command and encoder position of every axis the program moves: what vmsim identify reads.
  const sysid::PositionTrace tr = sim::position_trace(machine, sp, resp);
  if (!tr.axes.empty()) {
    sysid::write_position_trace_csv(dir / "trace.csv", tr, {"vmsim motion " + job.file.filename().string()});
    files.push_back("trace.csv");
  }
  // The same signals, binned (min/max) for charts: vmsim render DIR draws them.
  sim::write_signals(dir / "signals.csv",
                     sim::motion_signals(job, r.program, sp, resp, r.contour, args.feed_scale.value_or(1.0)));
  files.push_back("signals.csv");
  if (args.full_rate_trace) {
    for (std::size_t a = 0; a < resp.trace.size(); ++a) {
      const drives::FullRateTrace& ft = resp.trace[a];
      const core::MachineAxis& ax = machine.axes[a];
      const double f = file_unit(ax);
      const std::string name = "trace_" + ax.name + ".csv";
      write_csv(
          dir / name,
          fmt::format("t_s,position_{0},velocity_{0}_per_s,current_A,current_setpoint_A,voltage_V", unit_name(ax)),
          [&](Eigen::Index k, std::string& l) {
            l += fmt::format("{:.7f},{:.9f},{:.6f},{:.5f},{:.5f},{:.4f}", k * ft.period_s, ft.position[k] * f,
                             ft.velocity[k] * f, ft.current_A[k], ft.current_setpoint_A[k], ft.voltage_V[k]);
          },
          ft.position.size());
      files.push_back(name);
    }
  }
  return files;
}

void print_motion(const core::Job& job, const sim::MotionRun& r, double t_drives) {
  const core::Setpoints& sp = r.interp.setpoints;
  const double te = sp.period_s;
  const nlohmann::json& cut = r.report["contour_error"]["cutting_moves"];
  std::printf("job %s: cycle time %.3f s, %lld setpoints, drives simulated in %.2f s (%.0fx real time)\n",
              job.name.c_str(), r.interp.stats.cycle_time_s, static_cast<long long>(sp.samples()), t_drives,
              t_drives > 0 ? (r.response.samples() * te) / t_drives : 0.0);
  std::printf("contour error on cutting moves: max %.2f um, rms %.2f um, MSE %.3f um^2 (all moves: max %.2f um)\n",
              cut["max_abs_mm"].get<double>() * 1e3, cut["rms_mm"].get<double>() * 1e3, cut["mse_um2"].get<double>(),
              r.contour.max_abs_mm * 1e3);
  std::printf("axis  max tracking error   peak current / limit\n");
  for (const auto& ax : job.machine.axes) {
    const auto& j = r.report["axes"][ax.name];
    const std::string u = unit_name(ax);
    std::printf("%-4s  %10.4f %-3s        %6.2f / %-5.1f A\n", ax.name.c_str(),
                j["tracking_error_max_" + u].get<double>(), u.c_str(), j["peak_current_A"].get<double>(),
                j["current_limit_A"].get<double>());
  }
  std::printf("limits held: setpoints %s, currents %s\n", r.setpoint_limits_held ? "yes" : "NO",
              r.currents_within_limit ? "yes" : "NO");
}

}  // namespace

int run_motion(const MotionArgs& args) {
  const auto t_start = Clock::now();
  const core::Job job = core::load_job(args.job);
  // Locked before the run, written in staging, swapped into place whole (core/output_dir.hpp).
  core::OutputDir out(out_dir_or_default(args.out_dir, job.name, "motion"), "vmsim motion");
  sim::MotionRunOptions options;
  options.feed_scale = args.feed_scale.value_or(1.0);
  options.full_rate_trace = args.full_rate_trace;
  const sim::MotionRun r = sim::run_motion(job, options);

  const auto t0 = Clock::now();
  const std::filesystem::path dir = out.path();
  std::vector<std::string> files = write_motion_files(dir, job, r, args);

  nlohmann::json report = r.report;
  report["files"] = files;
  report["timings_s"]["write"] = seconds_since(t0);
  report["timings_s"]["total"] = seconds_since(t_start);
  write_report(dir / "report.json", report);
  out.commit();
  print_motion(job, r, report["timings_s"]["drives"].get<double>());
  std::printf("wrote %s (report.json, %zu CSV files)\n", out.target().string().c_str(), files.size());
  return print_verdict(report);
}

}  // namespace vmsim::app
