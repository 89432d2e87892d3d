// vmsim compare --measured PROFILE --predicted PRED --profile-line X0,Y0,X1,Y1: a measured profile (a stylus trace)
// held against the line across the predicted surface (metrology::compare_profile_to_surface: registration along the
// line, offset and tilt), the deviation along it, and the ISO 21920-2 parameters of both on their common samples.
#include "app/cmd_surface.hpp"
#include "app/commands.hpp"
#include "app/report.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "metrology/compare.hpp"
#include "metrology/profile.hpp"
#include "metrology/surface_io.hpp"
#include "render/chart.hpp"
#include "render/image.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <sstream>

namespace vmsim::app {

namespace {

// --profile-line X0,Y0,X1,Y1 (lengths).
std::vector<double> parse_line(const CompareArgs& a) {
  std::vector<double> v;
  std::stringstream ss(a.profile_line);
  std::string cell;
  while (std::getline(ss, cell, ',')) v.push_back(parse_length_mm(cell, "--profile-line"));
  if (v.size() != 4)
    throw core::Error(
        "--profile-line: the measured file holds a profile; give the line across the prediction it was "
        "measured along as X0,Y0,X1,Y1 (mm), found \"" +
        a.profile_line + "\"");
  return v;
}

nlohmann::json report_json(const CompareArgs& a, const metrology::SurfaceFile& ms, const metrology::SurfaceFile& ps,
                           const metrology::LineScan& measured, const std::vector<double>& v,
                           const metrology::ProfileEvaluation& how, const metrology::ProfileSurfaceComparison& r) {
  const metrology::ProfileComparison& c = r.along;
  nlohmann::json diff;
  const nlohmann::json jm = profile_json(r.measured, how), jp = profile_json(r.predicted, how);
  for (const char* k : {"Ra_mm", "Rq_mm", "Rsk", "Rku", "Rp_mm", "Rv_mm", "Rz_mm", "Rt_mm"})
    if (jm[k].is_number() && jp[k].is_number()) diff[k] = jm[k].get<double>() - jp[k].get<double>();
  nlohmann::json report = {{"vmsim", VMSIM_VERSION}, {"command", "compare"}, {"mode", "profile along a line"}};
  report["inputs"] = {{"measured", input_json(a.measured, ms.format)},
                      {"predicted", input_json(a.predicted, ps.format)}};
  report["measured"] = {{"profile", line_scan_json(measured)}};
  if (!ms.note.empty()) report["measured"]["note"] = ms.note;
  report["predicted"] = {{"grid", grid_json(ps.grid)}};
  report["line"] = {{"from_mm", {v[0], v[1]}},
                    {"to_mm", {v[2], v[3]}},
                    {"length_mm", c.line_length_mm},
                    {"sampled_every_mm", std::min(ps.grid.dx_mm, ps.grid.dy_mm) / 2}};
  report["registration"] = {
      {"method", a.align == "auto" ? "shift along the line searched (every predicted sample, then golden section to "
                                     "1/100), offset and tilt of the measured heights fitted by least squares"
                                   : "none: the profile's first sample at the line's start, heights as measured"},
      {"shift_mm", c.shift_mm},
      {"offset_mm", c.offset_mm},
      {"tilt", c.tilt},
      {"s_centre_mm", c.s_centre_mm}};
  report["deviation"] = {{"definition", "measured (registered) - predicted along the line"},
                         {"points", c.points},
                         {"mean_mm", c.mean_mm},
                         {"rms_mm", c.rms_mm},
                         {"min_mm", c.min_mm},
                         {"max_mm", c.max_mm}};
  report["profile_parameters"] = {{"area", "samples where both the measured and the predicted profile are valid"},
                                  {"measured", jm},
                                  {"predicted", jp},
                                  {"measured_minus_predicted", diff}};
  return report;
}

// images/profile_compare.png: both profiles along the line and their deviation; report.json's "pictures".
nlohmann::json write_picture(const std::filesystem::path& dir, const CompareArgs& a, const std::vector<double>& v,
                             const metrology::ProfileComparison& c) {
  try {
    core::create_result_subdir(dir / "images");
    render::Window window;
    render::ChartPicture cp;
    cp.caption = {"Measured profile along the line across the prediction",
                  fmt::format("{} vs {}: ({:.4g}, {:.4g}) - ({:.4g}, {:.4g}) mm, rms deviation {:.3f} um",
                              a.measured.filename().string(), a.predicted.filename().string(), v[0], v[1], v[2], v[3],
                              c.rms_mm * 1e3)};
    render::Chart h;
    h.title = "heights";
    h.x_title = "along the line [mm]";
    h.y_title = "z [um]";
    const auto xs = [](const metrology::LineScan& p) {
      return Eigen::ArrayXd::LinSpaced(p.size(), p.x(0), p.x(p.size() - 1)).eval();
    };
    h.series.push_back(render::make_series("predicted", xs(c.predicted), c.predicted.z_mm * 1e3, 0));
    h.series.push_back(render::make_series("measured (registered)", xs(c.measured), c.measured.z_mm * 1e3, 1));
    render::Chart d;
    d.title = "deviation";
    d.x_title = "along the line [mm]";
    d.y_title = "measured - predicted [um]";
    d.series.push_back(render::make_series("deviation", xs(c.deviation), c.deviation.z_mm * 1e3, 2));
    d.levels.push_back({"0", 0.0, {0.4, 0.4, 0.4}, true});
    cp.charts = {h, d};
    render::write_png(dir / "images" / "profile_compare.png", render::render_charts(window, cp).image);
    return {{"files", {"images/profile_compare.png"}}};
  } catch (const core::Error& e) {
    std::fprintf(stderr, "vmsim compare: no pictures: %s\n", e.what());
    return {{"error", e.what()}};
  }
}

}  // namespace

int run_compare_profile(const CompareArgs& a, const metrology::SurfaceFile& ms, core::OutputDir& out) {
  const std::vector<double> v = parse_line(a);
  if (a.align != "auto" && a.align != "none")
    throw core::Error("--align: expected auto or none, found \"" + a.align + "\"");
  if (!a.align_init.empty() || !a.align_regions.empty())
    throw core::Error(
        "--align-init and --align-region apply to surfaces; a profile is registered along its line (--align "
        "auto|none)");
  const metrology::ProfileEvaluation how = metrology::profile_evaluation(parse_processing(a.options));
  const std::filesystem::path dir = out.path();

  const metrology::SurfaceFile ps = metrology::read_surface_file(a.predicted);
  if (ps.profile) throw core::Error(a.predicted.string() + ": a profile; the prediction must be a surface");
  const metrology::LineScan measured = profile_in_range(*ms.profile, a.options.profile_range);
  metrology::ProfileAlignmentOptions ao;
  ao.align = a.align == "auto";
  const metrology::ProfileSurfaceComparison r =
      metrology::compare_profile_to_surface(measured, ps.grid, v[0], v[1], v[2], v[3], ao, how);
  const metrology::ProfileComparison& c = r.along;

  std::string csv = "s_mm,measured_mm,predicted_mm,deviation_mm\n";
  for (Eigen::Index i = 0; i < c.measured.size(); ++i)
    csv += fmt::format("{},{},{},{}\n", c.measured.x(i), c.measured.z_mm[i], c.predicted.z_mm[i], c.deviation.z_mm[i]);
  core::write_file_atomic(dir / "profile_compare.csv", csv);
  std::vector<std::string> files = {"profile_compare.csv"};
  nlohmann::json report = report_json(a, ms, ps, measured, v, how, r);
  if (!a.no_render) {
    report["pictures"] = write_picture(dir, a, v, c);
    if (report["pictures"].contains("files")) files.push_back("images/profile_compare.png");
  }
  files.push_back("report.json");
  report["files"] = files;
  write_report(dir / "report.json", report);
  out.commit();

  const metrology::ProfileParameters &em = r.measured.parameters, &ep = r.predicted.parameters;
  std::printf("measured %s (%s profile, %ld points every %.4g um), predicted %s (%s)\n",
              a.measured.filename().string().c_str(), ms.format.c_str(), static_cast<long>(measured.size()),
              measured.dx_mm * 1e3, a.predicted.filename().string().c_str(), ps.format.c_str());
  std::printf("registration along the line: shift %.4f mm, offset %.3f um, tilt %.3g\n", c.shift_mm, c.offset_mm * 1e3,
              c.tilt);
  std::printf("deviation: mean %.3f um, rms %.3f um, min %.3f um, max %.3f um over %zu points\n", c.mean_mm * 1e3,
              c.rms_mm * 1e3, c.min_mm * 1e3, c.max_mm * 1e3, c.points);
  std::printf("Ra measured %.4f um, predicted %.4f um; Rq %.4f / %.4f um; Rz %.4f / %.4f um\n", em.Ra_mm * 1e3,
              ep.Ra_mm * 1e3, em.Rq_mm * 1e3, ep.Rq_mm * 1e3, em.Rz_mm * 1e3, ep.Rz_mm * 1e3);
  std::printf("wrote %s (%zu files)\n", out.target().string().c_str(), files.size());
  return 0;
}

}  // namespace vmsim::app
