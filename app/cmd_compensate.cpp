// vmsim compensate JOB: seed 001's predictive contour-error compensation. The job's setpoints are predicted with its
// axis models (the machine file's cascades, or identified transfer functions: [job] axis_models or --axis-models),
// corrected by the predicted contour error (drives/compensate), and written as setpoints and as a G-code program a
// user can send to the machine. The contour errors before and after are measured with core/contour on the cutting
// moves, for the prediction and, when identified models predicted, also on the machine file's cascades.
#include "app/axis_models.hpp"
#include "app/commands_sysid.hpp"
#include "app/contour_stats.hpp"
#include "app/job_program.hpp"
#include "app/report.hpp"
#include "core/atomic_file.hpp"
#include "core/contour.hpp"
#include "core/error.hpp"
#include "core/interp.hpp"
#include "core/job.hpp"
#include "core/kinematics.hpp"
#include "core/units.hpp"
#include "drives/compensate.hpp"
#include "drives/simulate.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>

namespace vmsim::app {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

struct Figures {
  double max_mm = 0, mean_mm = 0, rms_mm = 0;
  Eigen::Index samples = 0;
  core::ContourError ce;
};

// Contour error of `actual` against the planned tip path on the cutting (feed) moves: max, mean and rms of |CE|.
Figures measure(const Eigen::MatrixXd& command_tip, const Eigen::MatrixXd& actual_tip, const core::Setpoints& sp,
                const core::ToolPath& program) {
  Figures f;
  f.ce = core::contour_error(command_tip, actual_tip);
  double sum = 0, sum2 = 0;
  for (Eigen::Index k = 0; k < f.ce.signed_mm.size(); ++k) {
    const int mi = sp.move_index[std::min(k, sp.samples() - 1)];
    if (mi < 0 || program.moves[static_cast<std::size_t>(mi)].rapid) continue;
    const double e = std::abs(f.ce.signed_mm[k]);
    f.max_mm = std::max(f.max_mm, e);
    sum += e;
    sum2 += e * e;
    ++f.samples;
  }
  if (f.samples > 0) {
    f.mean_mm = sum / static_cast<double>(f.samples);
    f.rms_mm = std::sqrt(sum2 / static_cast<double>(f.samples));
  }
  return f;
}

nlohmann::json figures_json(const Figures& before, const Figures& after) {
  auto pct = [](double b, double a) { return b > 0 ? 100.0 * (a - b) / b : 0.0; };
  return {{"before", {{"max_mm", before.max_mm}, {"mean_mm", before.mean_mm}, {"rms_mm", before.rms_mm}}},
          {"after", {{"max_mm", after.max_mm}, {"mean_mm", after.mean_mm}, {"rms_mm", after.rms_mm}}},
          {"change_percent", {{"max", pct(before.max_mm, after.max_mm)}, {"mean", pct(before.mean_mm, after.mean_mm)},
                              {"rms", pct(before.rms_mm, after.rms_mm)}}},
          {"samples", before.samples}};
}

nlohmann::json limits_json(const std::vector<drives::AxisLimitCheck>& checks, const core::Machine& m) {
  nlohmann::json j = nlohmann::json::object();
  for (std::size_t a = 0; a < checks.size(); ++a) {
    const auto& c = checks[a];
    const bool rot = m.axes[a].kind == core::AxisKind::Rotary;
    const double f = rot ? core::units::kRadToDeg : 1.0;
    const std::string u = rot ? "deg" : "mm";
    j[c.axis] = {{"within_limits", c.within()},
                 {"samples_over", c.samples_over},
                 {"first_over_s", c.first_over_s},
                 {"peak_velocity_" + u + "_per_s", c.peak_velocity * f},
                 {"peak_acceleration_" + u + "_per_s2", c.peak_acceleration * f},
                 {"peak_jerk_" + u + "_per_s3", c.peak_jerk * f},
                 {"limit_velocity_" + u + "_per_s", c.limit_velocity * f},
                 {"limit_acceleration_" + u + "_per_s2", c.limit_acceleration * f},
                 {"limit_jerk_" + u + "_per_s3", c.limit_jerk * f}};
  }
  return j;
}

}  // namespace

int run_compensate(const CompensateArgs& args) {
  const auto t_start = Clock::now();
  if (args.buffer_samples < 0 || (args.buffer_samples > 0 && args.buffer_samples % 2 == 0))
    throw core::Error(fmt::format("--buffer {}: expected an odd number of samples (or 0: automatic)", args.buffer_samples));
  if (args.max_iterations < 0 || args.max_iterations > 50)
    throw core::Error(fmt::format("--iterations {}: expected 0 to 50", args.max_iterations));
  const core::Job job = core::load_job(args.job);
  const core::Machine& machine = job.machine;
  const JobAxisModels models = job_axis_models(job, args.axis_models);
  const core::ToolPath program = read_job_program(job);
  const core::ToolPath path = core::toolpath_in_axis_space(program, machine);
  core::InterpOptions iopt;
  iopt.period_s = job.interp.period_s;
  iopt.tolerance_mm = job.interp.tolerance_mm;
  const core::InterpResult ir = core::interpolate(path, machine, iopt);
  const core::Setpoints& sp = ir.setpoints;
  const double te = sp.period_s;
  const auto kin = core::make_kinematics(machine);
  Eigen::VectorXd tlo(sp.samples());
  for (Eigen::Index k = 0; k < sp.samples(); ++k) {
    const int mi = sp.move_index[k];
    tlo[k] = mi >= 0 ? program.moves[static_cast<std::size_t>(mi)].tool_length_offset_mm : 0.0;
  }
  const double t_prepare = seconds_since(t_start);

  // Predictions: with the job's models, and with the machine file's cascades (the "machine" the program runs on).
  auto predictor = [&](const std::vector<const drives::AxisModel*>* per_axis) {
    return [&sp, &machine, per_axis](const Eigen::MatrixXd& setpoints) {
      core::Setpoints s = sp;
      s.position = setpoints;
      drives::SimulateOptions o;
      o.axis_models = per_axis;
      return drives::simulate_axes(s, machine, o).position;
    };
  };
  drives::CompensationProblem problem;
  problem.setpoints = &sp;
  problem.kinematics = kin.get();
  problem.tool_length_offset_mm = tlo;
  problem.predict = predictor(models.any() ? &models.per_axis : nullptr);
  drives::CompensateOptions copt;
  copt.buffer_samples = args.buffer_samples;
  copt.max_iterations = args.max_iterations;
  copt.limits = &machine;  // the correction is faded where it would break an axis limit the setpoints kept
  auto t0 = Clock::now();
  const drives::CompensationResult res = drives::compensate_contour(problem, copt);
  const double t_comp = seconds_since(t0);

  const Eigen::MatrixXd& cmd_tip = res.command_tip;
  const Figures pred_before = measure(cmd_tip, drives::tool_tips(*kin, res.predicted_before, tlo), sp, program);
  const Figures pred_after = measure(cmd_tip, drives::tool_tips(*kin, res.predicted_after, tlo), sp, program);
  std::optional<Figures> mach_before, mach_after;
  if (models.any()) {
    const auto on_machine = predictor(nullptr);
    mach_before = measure(cmd_tip, drives::tool_tips(*kin, on_machine(sp.position), tlo), sp, program);
    mach_after = measure(cmd_tip, drives::tool_tips(*kin, on_machine(res.setpoints), tlo), sp, program);
  }
  const auto limits_before = drives::check_axis_limits(sp.position, te, machine);
  const auto limits_after = drives::check_axis_limits(res.setpoints, te, machine);
  bool within = true;
  for (const auto& c : limits_after) within = within && c.within();

  // Files.
  t0 = Clock::now();
  const std::filesystem::path dir = args.out_dir.value_or(std::filesystem::current_path());
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw core::Error(dir.string() + ": cannot create the output directory: " + ec.message());
  const Eigen::Index ns = sp.samples(), na = static_cast<Eigen::Index>(machine.axes.size());
  {
    std::string s = "t_s";
    for (const auto& ax : machine.axes)
      s += fmt::format(",{0}_{1},{0}_compensated_{1}", ax.name, ax.kind == core::AxisKind::Rotary ? "deg" : "mm");
    s += '\n';
    for (Eigen::Index k = 0; k < ns; ++k) {
      s += fmt::format("{:.6f}", k * te);
      for (Eigen::Index a = 0; a < na; ++a) {
        const double f = machine.axes[static_cast<std::size_t>(a)].kind == core::AxisKind::Rotary ? core::units::kRadToDeg : 1.0;
        s += fmt::format(",{:.9f},{:.9f}", sp.position(k, a) * f, res.setpoints(k, a) * f);
      }
      s += '\n';
    }
    core::write_file_atomic(dir / "compensated_setpoints.csv", s);
  }
  {
    // The compensated points as the program's tool tip in the workpiece frame, one block per setpoint in inverse-time
    // feed (G93: F = 1 / block duration in minutes), so the NC replays the setpoints' timing.
    std::string s;
    s += fmt::format("(vmsim compensate: {} - seed 001 predictive contour-error compensation)\n", job.name);
    s += "(one block per interpolation period Te; X Y Z: tool tip in the workpiece frame, as the original program)\n";
    s += "(apply the original program's tool and tool length compensation before these blocks)\n";
    s += "G21 G90 G17\n";
    Eigen::VectorXd q(na);
    std::vector<int> rotary;
    for (Eigen::Index a = 0; a < na; ++a)
      if (machine.axes[static_cast<std::size_t>(a)].kind == core::AxisKind::Rotary) rotary.push_back(static_cast<int>(a));
    auto words = [&](Eigen::Index k) {
      q = res.setpoints.row(k).transpose();
      const core::ToolPose pose = kin->forward(q, tlo[k]);
      std::string w = fmt::format("X{:.6f} Y{:.6f} Z{:.6f}", pose.tip_mm.x(), pose.tip_mm.y(), pose.tip_mm.z());
      for (int a : rotary)
        if ((res.setpoints.col(a).array() != res.setpoints(0, a)).any())
          w += fmt::format(" {}{:.6f}", machine.axes[static_cast<std::size_t>(a)].name, q[a] * core::units::kRadToDeg);
      return w;
    };
    s += "G0 " + words(0) + "\nG93\n";
    const double f = 60.0 / te;
    for (Eigen::Index k = 1; k < ns; ++k) s += fmt::format("G1 {} F{:.1f}\n", words(k), f);
    s += "G94\nM2\n";
    core::write_file_atomic(dir / "compensated.ngc", s);
  }
  {
    std::string s = "t_s,contour_error_before_mm,contour_error_after_mm\n";
    const Eigen::Index rows = std::min(pred_before.ce.signed_mm.size(), pred_after.ce.signed_mm.size());
    for (Eigen::Index k = 0; k < rows; ++k)
      s += fmt::format("{:.6f},{:.9f},{:.9f}\n", k * te, pred_before.ce.signed_mm[k], pred_after.ce.signed_mm[k]);
    core::write_file_atomic(dir / "contour_errors.csv", s);
  }
  const double t_write = seconds_since(t0);

  nlohmann::json report = report_header("compensate", job);
  if (models.file)
    report["inputs"]["axis_models"] = {{"path", models.file->string()}};
  report["prediction"] = models.any() ? "identified transfer functions for " + fmt::format("{}", fmt::join(models.identified_axes, " ")) +
                                            ", the machine file's cascades for the other axes"
                                      : "the machine file's cascades ([axes.drive])";
  report["method"] = {{"foot_points", "seed 001 section 4: nearest command point in a buffer of m samples, then the adjacent segment"},
                      {"buffer_samples", res.buffer_samples},
                      {"correction", "eq. 23: each setpoint moved by the predicted contour error at its place on the path, repeated while the mean falls"},
                      {"smoothing_samples", copt.smoothing_samples},
                      {"limits", "the correction is faded out (smoothly, over +-" + std::to_string(copt.limit_window_samples) +
                                     " samples and more) where the corrected setpoints would break an axis velocity, acceleration or jerk limit"},
                      {"measured_by", "core/contour (exact foot point on the planned path), cutting moves only"}};
  nlohmann::json its = nlohmann::json::array();
  for (const auto& it : res.iterations)
    its.push_back({{"max_mm", it.max_mm}, {"mean_mm", it.mean_mm}, {"accepted", it.accepted},
                   {"faded_samples", it.faded_samples}});
  report["iterations"] = its;
  report["contour_error"]["predicted"] = figures_json(pred_before, pred_after);
  if (mach_before) report["contour_error"]["on_machine_cascades"] = figures_json(*mach_before, *mach_after);
  report["limits"] = {{"compensated_within_limits", within},
                      {"original", limits_json(limits_before, machine)},
                      {"compensated", limits_json(limits_after, machine)}};
  report["setpoints"] = ns;
  report["files"] = {"compensated_setpoints.csv", "compensated.ngc", "contour_errors.csv", "report.json"};
  report["timings_s"] = {{"prepare", t_prepare}, {"compensate", t_comp}, {"write", t_write}, {"total", seconds_since(t_start)}};
  write_report(dir / "report.json", report);

  auto line = [](const char* what, const Figures& b, const Figures& a) {
    std::printf("%-30s max %7.3f -> %7.3f um (%+.1f %%)   mean %7.3f -> %7.3f um (%+.1f %%)\n", what, b.max_mm * 1e3,
                a.max_mm * 1e3, b.max_mm > 0 ? 100 * (a.max_mm - b.max_mm) / b.max_mm : 0.0, b.mean_mm * 1e3,
                a.mean_mm * 1e3, b.mean_mm > 0 ? 100 * (a.mean_mm - b.mean_mm) / b.mean_mm : 0.0);
  };
  std::printf("job %s: %lld setpoints, %zu iterations (buffer m = %d), compensated in %.2f s\n", job.name.c_str(),
              static_cast<long long>(ns), res.iterations.size() - 1, res.buffer_samples, t_comp);
  line(models.any() ? "contour error, identified model" : "contour error, predicted", pred_before, pred_after);
  if (mach_before) line("contour error, machine cascades", *mach_before, *mach_after);
  for (const auto& c : limits_after)
    if (!c.within())
      std::printf("axis %s: compensated setpoints exceed a limit at %d samples, first at t = %.3f s\n", c.axis.c_str(),
                  c.samples_over, c.first_over_s);
  std::printf("compensated setpoints within every axis limit: %s\nwrote %s (compensated_setpoints.csv, compensated.ngc, "
              "contour_errors.csv, report.json)\n",
              within ? "yes" : "NO", dir.string().c_str());
  return 0;
}

}  // namespace vmsim::app
