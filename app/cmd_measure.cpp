// vmsim measure PRED --step S --spot D --noise N: the scan a confocal point sensor (STIL-style) would take of a
// predicted surface, to plan a measurement: the grid step, the spot's averaging, the noise and the dropouts on
// steep flanks, and, with the reference surface, which of the predicted marks such a scan resolves
// (metrology::plan_scan).
#include "app/cmd_surface.hpp"
#include "app/commands.hpp"
#include "app/report.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/timing.hpp"
#include "metrology/scan_plan.hpp"
#include "metrology/surface_io.hpp"
#include "metrology/x3p.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <optional>
#include <cstdio>

namespace vmsim::app {

namespace {

metrology::SensorOptions sensor_options(const MeasureArgs& a) {
  metrology::SensorOptions o;
  o.step_mm = parse_length_mm(a.step, "--step");
  o.spot_mm = parse_length_mm(a.spot, "--spot");
  o.noise_mm = parse_length_mm(a.noise, "--noise");
  o.max_slope_deg = a.max_slope_deg;
  o.dropout_probability = a.dropout;
  o.seed = a.seed;
  if (!a.area.empty()) {
    if (a.area.size() != 4) throw core::Error("--area: expected XMIN,XMAX,YMIN,YMAX (mm)");
    o.x_min_mm = a.area[0], o.x_max_mm = a.area[1], o.y_min_mm = a.area[2], o.y_max_mm = a.area[3];
  }
  return o;
}

nlohmann::json report_json(const MeasureArgs& a, const std::string& format, const metrology::SensorOptions& o,
                           const metrology::ScanPlan& plan, double threshold) {
  const metrology::SensorReport& rep = plan.sensor;
  nlohmann::json report = {{"vmsim", VMSIM_VERSION}, {"command", "measure"}};
  report["inputs"] = {{"predicted", input_json(a.predicted, format)}};
  report["sensor"] = {{"step_mm", o.step_mm},
                      {"spot_fwhm_mm", o.spot_mm},
                      {"noise_sigma_mm", o.noise_mm},
                      {"max_slope_deg", o.max_slope_deg},
                      {"dropout_probability", o.dropout_probability},
                      {"seed", o.seed},
                      {"model",
                       "Gaussian spot (heights averaged over it), bilinear sampling, Gaussian noise, no signal "
                       "on flanks steeper than max_slope_deg"}};
  report["scan"] = {
      {"grid", grid_json(plan.scan)},           {"slope_dropouts", rep.slope_dropouts},
      {"random_dropouts", rep.random_dropouts}, {"outside_prediction", rep.outside},
      {"spot_sigma_mm", rep.spot_sigma_mm},     {"half_amplitude_wavelength_mm", rep.half_amplitude_wavelength_mm}};
  report["areal"] = {{"processing", "least-squares plane removed"},
                     {"predicted", areal_json(plan.predicted_areal)},
                     {"scan", areal_json(plan.scan_areal)}};
  if (a.reference) {
    nlohmann::json seen = nlohmann::json::array();
    for (const metrology::MarkSeen& s : plan.marks) {
      const metrology::Mark& m = s.mark;
      seen.push_back({{"x_mm", m.x_mm},
                      {"y_mm", m.y_mm},
                      {"kind", m.overcut ? "overcut" : "undercut"},
                      {"predicted_depth_mm", m.depth_mm},
                      {"width_mm", m.width_mm},
                      {"scan_depth_mm", s.scan_depth_mm},
                      {"resolved", s.resolved}});
    }
    report["marks"] = {
        {"threshold_mm", threshold},
        {"resolved_when", "the scan shows at least half the predicted depth, and the depth is above 3 noise sigmas"},
        {"list", seen}};
    report["inputs"]["reference"] = input_json(*a.reference, "surface");
  }
  return report;
}

// scan.x3p and, with a reference, scan_deviation.x3p; the files written.
std::vector<std::string> write_scans(const MeasureArgs& a, const std::filesystem::path& dir,
                                     const metrology::SensorOptions& o, const metrology::ScanPlan& plan) {
  std::vector<std::string> files;
  metrology::X3pWriteOptions xo;
  xo.version = std::string("vmsim ") + VMSIM_VERSION;
  xo.probing_type = "NonContacting";
  xo.probing_id = fmt::format("simulated confocal point sensor: spot {} mm, noise {} mm, max slope {} deg", o.spot_mm,
                              o.noise_mm, o.max_slope_deg);
  xo.comment = "a simulated scan of " + a.predicted.filename().string() + " (vmsim measure)";
  metrology::write_x3p(dir / "scan.x3p", plan.scan, xo);
  files.push_back("scan.x3p");
  if (plan.scan_deviation) {
    xo.comment = "simulated scan minus the reference " + a.reference->filename().string();
    metrology::write_x3p(dir / "scan_deviation.x3p", *plan.scan_deviation, xo);
    files.push_back("scan_deviation.x3p");
  }
  return files;
}

}  // namespace

int run_measure(const MeasureArgs& a) {
  const auto t_start = core::Clock::now();
  require_utf8_input(a.predicted, "the predicted surface");
  if (a.reference) require_utf8_input(*a.reference, "--reference");
  const metrology::SensorOptions o = sensor_options(a);
  const double threshold = parse_length_mm(a.mark_threshold, "--mark-threshold");
  // Locked now, written in staging, swapped into place whole (core/output_dir.hpp).
  core::OutputDir out(out_dir_or_default(a.out_dir, a.predicted.stem().string(), "measure"), "vmsim measure");
  const std::filesystem::path dir = out.path();

  const metrology::SurfaceFile pf = metrology::read_surface_file(a.predicted);
  std::optional<core::HeightGrid> ref;
  if (a.reference) ref = metrology::read_surface(*a.reference);
  const metrology::ScanPlan plan = metrology::plan_scan(pf.grid, o, ref ? &*ref : nullptr, threshold);

  nlohmann::json report = report_json(a, pf.format, o, plan, threshold);
  std::vector<std::string> files = write_scans(a, dir, o, plan);
  files.push_back("report.json");
  report["files"] = files;
  report["timings_s"] = {{"total", core::seconds_since(t_start)}};
  write_report(dir / "report.json", report);
  out.commit();

  const metrology::SensorReport& rep = plan.sensor;
  std::printf(
      "scan of %s: %ld x %ld points every %.4g mm, spot %.4g mm (halves wavelengths of %.4g mm), noise %.3g um\n",
      a.predicted.filename().string().c_str(), static_cast<long>(plan.scan.nx()), static_cast<long>(plan.scan.ny()),
      o.step_mm, o.spot_mm, rep.half_amplitude_wavelength_mm, o.noise_mm * 1e3);
  std::printf("invalid: %zu on flanks steeper than %g deg, %zu random, %zu off the prediction (of %zu)\n",
              rep.slope_dropouts, o.max_slope_deg, rep.random_dropouts, rep.outside, rep.points);
  std::printf("Sq predicted %.3f um, seen %.3f um; Sdq %.4f, seen %.4f\n", plan.predicted_areal.Sq_mm * 1e3,
              plan.scan_areal.Sq_mm * 1e3, plan.predicted_areal.Sdq, plan.scan_areal.Sdq);
  for (std::size_t k = 0; k < plan.marks.size() && k < 5; ++k)
    std::printf("mark %zu: %s %.2f um predicted, %.2f um seen by the scan: %s\n", k + 1,
                plan.marks[k].mark.overcut ? "overcut" : "undercut", plan.marks[k].mark.depth_mm * 1e3,
                plan.marks[k].scan_depth_mm * 1e3, plan.marks[k].resolved ? "resolved" : "NOT resolved");
  std::printf("wrote %s\n", out.target().string().c_str());
  return 0;
}

}  // namespace vmsim::app
