// vmsim measure PRED --step S --spot D --noise N: the scan a confocal point sensor (STIL-style) would take of a
// predicted surface, to plan a measurement: the grid step, the spot's averaging, the noise and the dropouts on
// steep flanks, and, with the reference surface, which of the predicted marks such a scan resolves.
#include "app/cmd_surface.hpp"
#include "app/commands.hpp"
#include "app/report.hpp"
#include "core/error.hpp"
#include "metrology/areal.hpp"
#include "metrology/marks.hpp"
#include "metrology/register.hpp"
#include "metrology/sensor.hpp"
#include "metrology/surface_io.hpp"
#include "metrology/x3p.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

namespace vmsim::app {

int run_measure(const MeasureArgs& a) {
  const auto t_start = std::chrono::steady_clock::now();
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
  const double threshold = parse_length_mm(a.mark_threshold, "--mark-threshold");
  const std::filesystem::path dir = a.out_dir.value_or(std::filesystem::current_path());
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw core::Error(dir.string() + ": cannot create the output directory: " + ec.message());

  const metrology::SurfaceFile pf = metrology::read_surface_file(a.predicted);
  const core::HeightGrid& pred = pf.grid;
  metrology::SensorReport rep;
  const core::HeightGrid scan = metrology::simulate_scan(pred, o, &rep);

  nlohmann::json report = {{"vmsim", VMSIM_VERSION}, {"command", "measure"}};
  report["inputs"] = {{"predicted", input_json(a.predicted, pf.format)}};
  report["sensor"] = {{"step_mm", o.step_mm},
                      {"spot_fwhm_mm", o.spot_mm},
                      {"noise_sigma_mm", o.noise_mm},
                      {"max_slope_deg", o.max_slope_deg},
                      {"dropout_probability", o.dropout_probability},
                      {"seed", o.seed},
                      {"model", "Gaussian spot (heights averaged over it), bilinear sampling, Gaussian noise, no signal "
                                "on flanks steeper than max_slope_deg"}};
  report["scan"] = {{"grid", grid_json(scan)},
                    {"slope_dropouts", rep.slope_dropouts},
                    {"random_dropouts", rep.random_dropouts},
                    {"outside_prediction", rep.outside},
                    {"spot_sigma_mm", rep.spot_sigma_mm},
                    {"half_amplitude_wavelength_mm", rep.half_amplitude_wavelength_mm}};
  // Texture as the prediction has it and as the scan sees it (planes removed).
  nlohmann::json proc;
  const auto ap = metrology::areal_parameters(level_and_filter(pred, 1, {}, proc));
  const auto as = metrology::areal_parameters(level_and_filter(scan, 1, {}, proc));
  report["areal"] = {{"processing", "least-squares plane removed"}, {"predicted", areal_json(ap)}, {"scan", areal_json(as)}};

  std::vector<std::string> files;
  metrology::X3pWriteOptions xo;
  xo.version = std::string("vmsim ") + VMSIM_VERSION;
  xo.probing_type = "NonContacting";
  xo.probing_id = fmt::format("simulated confocal point sensor: spot {} mm, noise {} mm, max slope {} deg", o.spot_mm,
                              o.noise_mm, o.max_slope_deg);
  xo.comment = "a simulated scan of " + a.predicted.filename().string() + " (vmsim measure)";
  metrology::write_x3p(dir / "scan.x3p", scan, xo);
  files.push_back("scan.x3p");

  nlohmann::json seen = nlohmann::json::array();
  std::vector<std::pair<metrology::Mark, double>> table;
  if (a.reference) {
    const core::HeightGrid ref = metrology::read_surface(*a.reference);
    const core::HeightGrid dev_pred = metrology::deviation(pred, ref);
    const core::HeightGrid ref_on_scan = metrology::resample_scan(ref, metrology::RigidTransform{}, scan);
    const core::HeightGrid dev_scan = metrology::deviation(scan, ref_on_scan);
    xo.comment = "simulated scan minus the reference " + a.reference->filename().string();
    metrology::write_x3p(dir / "scan_deviation.x3p", dev_scan, xo);
    files.push_back("scan_deviation.x3p");
    const double dir_rad = metrology::lay_of(pred).direction_rad;
    for (const metrology::Mark& m : metrology::find_marks(dev_pred, threshold, 10, dir_rad, 9)) {
      // The deepest the scan sees within the predicted mark's half-depth box (and a step around it).
      double deepest = 0;
      const double rx = 0.5 * m.x_extent_mm + o.step_mm, ry = 0.5 * m.y_extent_mm + o.step_mm;
      for (Eigen::Index j = 0; j < dev_scan.ny(); ++j)
        for (Eigen::Index i = 0; i < dev_scan.nx(); ++i) {
          const double v = dev_scan.z_mm(j, i);
          if (std::isfinite(v) && std::abs(dev_scan.x(i) - m.x_mm) <= rx && std::abs(dev_scan.y(j) - m.y_mm) <= ry &&
              (v < 0) == m.overcut)
            deepest = std::max(deepest, std::abs(v));
        }
      const bool resolved = deepest >= 0.5 * m.depth_mm && m.depth_mm > 3 * o.noise_mm;
      seen.push_back({{"x_mm", m.x_mm}, {"y_mm", m.y_mm}, {"kind", m.overcut ? "overcut" : "undercut"},
                      {"predicted_depth_mm", m.depth_mm}, {"width_mm", m.width_mm}, {"scan_depth_mm", deepest},
                      {"resolved", resolved}});
      table.emplace_back(m, deepest);
    }
    report["marks"] = {{"threshold_mm", threshold},
                       {"resolved_when", "the scan shows at least half the predicted depth, and the depth is above 3 noise sigmas"},
                       {"list", seen}};
    report["inputs"]["reference"] = input_json(*a.reference, "surface");
  }
  files.push_back("report.json");
  report["files"] = files;
  report["timings_s"] = {{"total", std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count()}};
  write_report(dir / "report.json", report);

  std::printf("scan of %s: %ld x %ld points every %.4g mm, spot %.4g mm (halves wavelengths of %.4g mm), noise %.3g um\n",
              a.predicted.filename().string().c_str(), static_cast<long>(scan.nx()), static_cast<long>(scan.ny()), o.step_mm,
              o.spot_mm, rep.half_amplitude_wavelength_mm, o.noise_mm * 1e3);
  std::printf("invalid: %zu on flanks steeper than %g deg, %zu random, %zu off the prediction (of %zu)\n", rep.slope_dropouts,
              o.max_slope_deg, rep.random_dropouts, rep.outside, rep.points);
  std::printf("Sq predicted %.3f um, seen %.3f um; Sdq %.4f, seen %.4f\n", ap.Sq_mm * 1e3, as.Sq_mm * 1e3, ap.Sdq, as.Sdq);
  for (std::size_t k = 0; k < table.size() && k < 5; ++k)
    std::printf("mark %zu: %s %.2f um predicted, %.2f um seen by the scan: %s\n", k + 1, table[k].first.overcut ? "overcut" : "undercut",
                table[k].first.depth_mm * 1e3, table[k].second * 1e3,
                seen[k]["resolved"].get<bool>() ? "resolved" : "NOT resolved");
  std::printf("wrote %s\n", dir.string().c_str());
  return 0;
}

}  // namespace vmsim::app
