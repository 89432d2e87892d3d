// vmsim compensate JOB: the predictive-compensation paper's contour-error compensation (sim/compensate.hpp). This file
// runs the library call, writes the compensated setpoints, the compensated program (and its tool-centre-point and
// dense forms), the contour errors before and after, draws the chart, writes report.json and prints the summary.
#include "app/commands_sysid.hpp"
#include "app/progress.hpp"
#include "app/report.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/job.hpp"
#include "core/timing.hpp"
#include "core/units.hpp"
#include "render/chart.hpp"
#include "render/image.hpp"
#include "render/window.hpp"
#include "sim/compensate.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <cstdio>

namespace vmsim::app {

namespace {

namespace fs = std::filesystem;
using core::Clock;
using core::seconds_since;
using Eigen::Index;

// The setpoints before and after, and the predicted contour error before and after (and, five-axis, the orientation
// error); the compensated program in its forms. Returns the files written, in order.
std::vector<std::string> write_results(const fs::path& dir, const core::Job& job, const sim::CompensateJobResult& r) {
  std::vector<std::string> files;
  const core::Setpoints& sp = r.interp.setpoints;
  const Eigen::MatrixXd& comp = r.compensation.setpoints;
  const double te = sp.period_s;
  std::string s = "t_s";
  for (const auto& ax : job.machine.axes)
    s += fmt::format(",{0}_{1},{0}_compensated_{1}", ax.name, ax.kind == core::AxisKind::Rotary ? "deg" : "mm");
  s += '\n';
  for (Index k = 0; k < sp.samples(); ++k) {
    s += fmt::format("{:.6f}", k * te);
    for (std::size_t a = 0; a < job.machine.axes.size(); ++a) {
      const double f = job.machine.axes[a].kind == core::AxisKind::Rotary ? core::units::kRadToDeg : 1.0;
      const Index c = static_cast<Index>(a);
      s += fmt::format(",{:.9f},{:.9f}", sp.position(k, c) * f, comp(k, c) * f);
    }
    s += '\n';
  }
  auto write = [&](const std::string& name, const std::string& text) {
    core::write_file_atomic(dir / name, text);
    files.push_back(name);
  };
  write("compensated_setpoints.csv", s);
  write(r.program_file, r.compensated_program.text);
  if (r.tcp_program) {
    write(r.program_accepted ? "compensated_tcp.ngc" : "compensated_tcp_rejected.ngc", r.tcp_program->text);
    write("original_tcp.ngc", *r.original_tcp_text);
  }
  if (r.dense_program_text) write("compensated_dense.ngc", *r.dense_program_text);
  const bool five = r.compensation.orientation;
  const sim::ContourFigures &b = r.predicted_before, &a = r.predicted_after;
  s = five ? "t_s,contour_error_before_mm,contour_error_after_mm,orientation_error_before_deg,"
             "orientation_error_after_deg\n"
           : "t_s,contour_error_before_mm,contour_error_after_mm\n";
  const Index rows = std::min(b.ce.signed_mm.size(), a.ce.signed_mm.size());
  for (Index k = 0; k < rows; ++k) {
    s += fmt::format("{:.6f},{:.9f},{:.9f}", k * te, b.ce.signed_mm[k], a.ce.signed_mm[k]);
    if (five)
      s += fmt::format(",{:.9f},{:.9f}", b.angle_rad[k] * core::units::kRadToDeg,
                       a.angle_rad[k] * core::units::kRadToDeg);
    s += '\n';
  }
  write("contour_errors.csv", s);
  return files;
}

// The contour error before and after (images/contour_error.png): predicted, and the programs on the machine.
void draw_chart(const fs::path& dir, const core::Job& job, const sim::CompensateJobResult& r) {
  const double te = r.interp.setpoints.period_s;
  render::Window window;
  core::create_result_subdir(dir / "images");
  auto um = [](const Eigen::VectorXd& mm) { return Eigen::ArrayXd(mm.array() * 1e3); };
  auto deg = [](const Eigen::VectorXd& rad) { return Eigen::ArrayXd(rad.array() * core::units::kRadToDeg); };
  auto time = [te](Index n) {
    return Eigen::ArrayXd(Eigen::ArrayXd::LinSpaced(n, 0.0, te * static_cast<double>(n - 1)));
  };
  auto chart = [&](const std::string& title, const std::string& y, const std::string& a, const Eigen::ArrayXd& ya,
                   const std::string& b, const Eigen::ArrayXd& yb) {
    render::Chart c;
    c.title = title;
    c.x_title = "t [s]";
    c.y_title = y;
    c.series.push_back(render::make_series(a, time(ya.size()), ya, 1, 1.4));
    c.series.push_back(render::make_series(b, time(yb.size()), yb, 0, 1.6));
    return c;
  };
  const sim::ContourFigures &pb = r.predicted_before, &pa = r.predicted_after;
  render::ChartPicture pic;
  pic.caption = {fmt::format("{}: predictive contour-error compensation, contour error on the machine max {:.2f} → "
                             "{:.2f} µm",
                             job.name, r.original_on_machine.max_mm * 1e3, r.program_on_machine.max_mm * 1e3),
                 "signed contour error against the planned path, every sample (rapid moves too)"};
  pic.charts.push_back(chart("predicted: the setpoints before and after the correction", "contour error [µm]", "before",
                             um(pb.ce.signed_mm), "after", um(pa.ce.signed_mm)));
  pic.charts.push_back(
      chart("the original and the compensated program, re-timed and run on the machine file's "
            "cascades",
            "contour error [µm]", "original program", um(r.original_on_machine.ce.signed_mm), "compensated program",
            um(r.program_on_machine.ce.signed_mm)));
  // The orientation error where the tool axis has one (a five-axis chain whose program turns the tool).
  const bool turns = r.compensation.orientation && pb.angle_rad.size() > 0 && pa.angle_rad.size() > 0 &&
                     std::max(pb.angle_rad.maxCoeff(), pa.angle_rad.maxCoeff()) > 0;
  if (turns)
    pic.charts.push_back(chart("predicted orientation error (tool axis)", "angle [deg]", "before", deg(pb.angle_rad),
                               "after", deg(pa.angle_rad)));
  pic.height = turns ? 1200 : 900;
  render::write_png(dir / "images" / "contour_error.png", render::render_charts(window, pic).image);
}

void print_summary(const core::Job& job, const sim::CompensateJobResult& r, const fs::path& dir,
                   const std::vector<std::string>& files) {
  const bool five = r.compensation.orientation;
  auto line = [five](const char* what, const sim::ContourFigures& b, const sim::ContourFigures& a) {
    std::printf("%-34s max %8.3f -> %8.3f um (%+.1f %%)   mean %8.3f -> %8.3f um (%+.1f %%)\n", what, b.max_mm * 1e3,
                a.max_mm * 1e3, b.max_mm > 0 ? 100 * (a.max_mm - b.max_mm) / b.max_mm : 0.0, b.mean_mm * 1e3,
                a.mean_mm * 1e3, b.mean_mm > 0 ? 100 * (a.mean_mm - b.mean_mm) / b.mean_mm : 0.0);
    if (five)
      std::printf("%-34s max %8.4f -> %8.4f deg          mean %8.4f -> %8.4f deg\n", "  tool axis orientation error",
                  b.orientation_max_rad * core::units::kRadToDeg, a.orientation_max_rad * core::units::kRadToDeg,
                  b.orientation_mean_rad * core::units::kRadToDeg, a.orientation_mean_rad * core::units::kRadToDeg);
  };
  std::printf("job %s: %lld setpoints, %zu iterations (buffer m = %d), compensated in %.2f s\n", job.name.c_str(),
              static_cast<long long>(r.interp.setpoints.samples()), r.compensation.iterations.size() - 1,
              r.compensation.buffer_samples, r.timings["compensate"].get<double>());
  line(r.identified ? "contour error, identified model" : "contour error, predicted", r.predicted_before,
       r.predicted_after);
  if (r.machine_before) line("contour error, machine cascades", *r.machine_before, *r.machine_after);
  const sim::ContourFigures &om = r.original_on_machine, &pm = r.program_on_machine;
  line("compensated program on the machine", om, pm);
  // A program that cuts worse is written as compensated_rejected.*, and the run's warnings say so (print_verdict).
  if (r.fade_rounds > 0 && r.program_accepted)
    std::printf(
        "compensated program: the correction faded around the places where it cut worse (%lld setpoints, %d "
        "rounds)\n",
        static_cast<long long>(r.faded_setpoints), r.fade_rounds);
  const double co = r.cycle_time_original_s, cp = r.cycle_time_program_s;
  std::printf("compensated program (%s): %d blocks for %zu moves, cycle time %.3f s (original %.3f s, %+.2f %%)\n",
              r.program_file.c_str(), r.compensated_program.blocks, r.program.moves.size(), cp, co,
              co > 0 ? 100.0 * (cp - co) / co : 0.0);
  if (r.tcp_cycle_times_s)
    std::printf("tool-centre-point G-code: compensated_tcp.ngc %.3f s, original_tcp.ngc %.3f s ([job] tcp = true)\n",
                r.tcp_cycle_times_s->second, r.tcp_cycle_times_s->first);
  for (const auto& c : r.limits_after)
    if (!c.within())
      std::printf("axis %s: compensated setpoints exceed a limit at %d samples, first at t = %.3f s\n", c.axis.c_str(),
                  c.samples_over, c.first_over_s);
  std::printf("compensated setpoints within every axis limit: %s\nwrote %s (%s)\n", r.within_limits ? "yes" : "NO",
              dir.string().c_str(), fmt::format("{}", fmt::join(files, ", ")).c_str());
}

}  // namespace

int run_compensate(const CompensateArgs& args) {
  const auto t_start = Clock::now();
  sim::CompensateJobOptions options;
  options.axis_models_file = args.axis_models;
  options.method.buffer_samples = args.buffer_samples;
  options.method.max_iterations = args.max_iterations;
  options.method.smoothing_samples = args.smoothing_samples;
  options.method.orientation = !args.tip_only;
  options.dense_program = args.dense_program;
  const core::Job job = core::load_job(args.job);
  // Locked before the run, written in staging, swapped into place whole (core/output_dir.hpp).
  core::OutputDir out(out_dir_or_default(args.out_dir, job.name, "compensate"), "vmsim compensate");
  TerminalProgress progress;
  const sim::CompensateJobResult r = sim::compensate_job(job, options, progress);

  auto t0 = Clock::now();
  const fs::path dir = out.path();
  std::vector<std::string> files = write_results(dir, job, r);
  const double t_write = seconds_since(t0);

  // The chart after every result file: a failure to draw loses no result.
  std::optional<std::string> render_error;
  double t_render = 0;
  if (!args.no_render) {
    t0 = Clock::now();
    try {
      draw_chart(dir, job, r);
      files.push_back("images/contour_error.png");
    } catch (const std::exception& e) {  // any failure (bad_alloc too): the report is written all the same
      render_error = e.what();
      std::fprintf(stderr, "vmsim compensate: no chart: %s\n", e.what());
    }
    t_render = seconds_since(t0);
  }

  nlohmann::json report = report_header("compensate", job);
  const std::optional<std::filesystem::path> models = args.axis_models ? args.axis_models : job.axis_models_file;
  if (models) report["inputs"]["axis_models"] = {{"path", models->string()}};
  report.update(r.report);
  files.push_back("report.json");
  report["files"] = files;
  if (render_error) report["render_error"] = *render_error;
  report["timings_s"] = r.timings;
  report["timings_s"]["write"] = t_write;
  report["timings_s"]["render"] = t_render;
  report["timings_s"]["total"] = seconds_since(t_start);
  write_report(dir / "report.json", report);
  out.commit();
  print_summary(job, r, out.target(), files);
  return print_verdict(report);
}

}  // namespace vmsim::app
