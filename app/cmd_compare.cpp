// vmsim compare --measured SCAN --predicted PRED: a measured scan (confocal, STIL-style) held against the surface
// vmsim predicted, through metrology::compare_surfaces (spikes masked, registration, deviation, marks, areal
// parameters of both on their common area); here the deviation (X3P), the aligned scan, profiles across the marks
// (CSV), report.json, the pictures and a summary.
#include "app/cmd_surface.hpp"
#include "core/units.hpp"
#include "app/commands.hpp"
#include "app/report.hpp"
#include "core/atomic_file.hpp"
#include "core/error.hpp"
#include "core/output_dir.hpp"
#include "core/stl.hpp"
#include "core/timing.hpp"
#include "metrology/compare.hpp"
#include "metrology/surface_io.hpp"
#include "metrology/x3p.hpp"
#include "render/chart.hpp"
#include "render/scene.hpp"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <sstream>

namespace vmsim::app {

namespace {

using core::Clock;
using core::seconds_since;
using core::units::kPi;

std::vector<metrology::Region> parse_regions(const std::vector<std::string>& texts) {
  std::vector<metrology::Region> out;
  for (const std::string& t : texts) {
    std::vector<double> v;
    std::stringstream ss(t);
    std::string cell;
    while (std::getline(ss, cell, ',')) v.push_back(parse_length_mm(cell, "--align-region"));
    if (v.size() != 4 || !(v[1] > v[0]) || !(v[3] > v[2]))
      throw core::Error("--align-region: expected XMIN,XMAX,YMIN,YMAX with XMIN < XMAX and YMIN < YMAX (mm), found \"" +
                        t + "\"");
    out.push_back({v[0], v[1], v[2], v[3]});
  }
  return out;
}

metrology::SurfaceCompareOptions compare_options(const CompareArgs& a) {
  metrology::SurfaceCompareOptions o;
  o.processing = parse_processing(a.options);
  o.mark_threshold_mm = parse_length_mm(a.mark_threshold, "--mark-threshold");
  o.regions = parse_regions(a.align_regions);
  if (a.align != "auto" && a.align != "none")
    throw core::Error("--align: expected auto or none, found \"" + a.align + "\"");
  if (!a.align_init.empty() && a.align_init.size() != 6)
    throw core::Error("--align-init: expected X,Y,Z,RX,RY,RZ (mm, deg)");
  if (a.loss != "tukey" && a.loss != "huber")
    throw core::Error("--loss: expected tukey or huber, found \"" + a.loss + "\"");
  o.align = a.align == "auto";
  o.loss = a.loss == "huber" ? metrology::RobustLoss::Huber : metrology::RobustLoss::Tukey;
  if (!a.align_init.empty()) {
    const double d = kPi / 180;
    const auto& i = a.align_init;
    o.initial = metrology::RigidTransform::from_xyz_rxyz(i[0], i[1], i[2], i[3] * d, i[4] * d, i[5] * d);
  }
  o.outlier_sigma = a.options.outlier_sigma;
  if (a.path_direction_deg) o.path_direction_rad = *a.path_direction_deg * kPi / 180;
  return o;
}

// The prediction: a surface file, or an STL part (its top rasterised at the scan's step, for registration).
metrology::Prediction read_prediction(const std::filesystem::path& file, const core::HeightGrid& scan,
                                      std::string& format) {
  std::string ext = file.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".stl") {
    format = "stl";
    return metrology::prediction_of_mesh(core::read_stl(file), std::min(scan.dx_mm, scan.dy_mm));
  }
  metrology::SurfaceFile ps = metrology::read_surface_file(file);
  format = ps.format;
  return {std::move(ps.grid), std::nullopt};
}

nlohmann::json transform_json(const metrology::RigidTransform& T) {
  const Eigen::Vector3d rv = T.rotation_vector();
  // R = Rz Ry Rx: the angles that rebuild it (small for a fixtured part).
  const Eigen::Vector3d e = T.R.eulerAngles(2, 1, 0);
  double rz = e[0], ry = e[1], rx = e[2];
  if (std::abs(ry) > kPi / 2)
    rz -= std::copysign(kPi, rz), ry = std::copysign(kPi, ry) - ry, rx -= std::copysign(kPi, rx);
  nlohmann::json R = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) R.push_back({T.R(r, 0), T.R(r, 1), T.R(r, 2)});
  return {{"maps", "scan coordinates -> prediction coordinates: p' = R p + t"},
          {"R", R},
          {"t_mm", {T.t.x(), T.t.y(), T.t.z()}},
          {"rotation_vector_rad", {rv.x(), rv.y(), rv.z()}},
          {"angle_rad", rv.norm()},
          {"rx_ry_rz_rad", {rx, ry, rz}},
          {"convention", "R = Rz(rz) Ry(ry) Rx(rx)"}};
}

nlohmann::json registration_json(const CompareArgs& a, const metrology::SurfaceCompareOptions& o,
                                 const metrology::SurfaceComparison& c) {
  nlohmann::json reg;
  if (!c.registration) {
    reg = {
        {"method", a.align_init.empty() ? "none: the scan as it lies" : "none: the transform given by --align-init"}};
  } else {
    const metrology::RegistrationResult& r = *c.registration;
    nlohmann::json regions = nlohmann::json::array();
    for (const auto& R : o.regions) regions.push_back({R.x_min, R.x_max, R.y_min, R.y_max});
    reg = {{"method", "robust Gauss-Newton, point to surface (normal distance), 6 DoF, coarse to fine"},
           {"loss", a.loss == "huber" ? "Huber k = 1.345 sigma" : "Tukey c = 4.685 sigma (after Huber)"},
           {"regions_mm", regions},
           {"initial_guess", r.initial_guess},
           {"points", r.points},
           {"inliers", r.inliers},
           {"iterations", r.iterations},
           {"converged", r.converged},
           {"residual_rms_mm", r.rms_mm},
           {"residual_mean_mm", r.mean_mm},
           {"residual_robust_sigma_mm", r.robust_sigma_mm},
           {"weakly_constrained", r.weak_directions}};
  }
  reg["transform"] = transform_json(c.transform);
  return reg;
}

nlohmann::json marks_json(const metrology::SurfaceCompareOptions& o, const metrology::SurfaceComparison& c) {
  nlohmann::json mj = nlohmann::json::array();
  for (std::size_t k = 0; k < c.marks.size(); ++k) {
    const metrology::Mark& m = c.marks[k];
    nlohmann::json j = {{"depth_mm", m.depth_mm},
                        {"kind", m.overcut ? "overcut" : "undercut"},
                        {"x_mm", m.x_mm},
                        {"y_mm", m.y_mm},
                        {"width_mm", m.width_mm},
                        {"along_path_mm", m.along_mm},
                        {"x_extent_mm", m.x_extent_mm},
                        {"y_extent_mm", m.y_extent_mm},
                        {"area_mm2", m.area_mm2}};
    if (k < c.marks_in_part_mm.size())
      j["part_x_mm"] = c.marks_in_part_mm[k].x(), j["part_y_mm"] = c.marks_in_part_mm[k].y();
    mj.push_back(j);
  }
  const std::string from = c.path_direction_from == metrology::PathDirectionFrom::Given ? "given (--path-direction-deg)"
                           : c.path_direction_from == metrology::PathDirectionFrom::Lay
                               ? fmt::format("the lay of the prediction (anisotropy {:.2f})", c.lay_anisotropy)
                               : "+x (the prediction has no clear lay; give --path-direction-deg)";
  return {{"threshold_mm", o.mark_threshold_mm},
          {"path_direction_deg", c.path_direction_rad * 180 / kPi},
          {"path_direction_from", from},
          {"min_nodes", 9},
          {"width", "full width of the part deeper than half the depth, across the path"},
          {"list", mj}};
}

std::string deviation_definition(bool mesh) {
  return mesh ? "signed distance along the mesh normal (positive outside the part), on the scan's grid, scan frame"
              : "measured - predicted, vertical, on the prediction's grid (negative: overcut)";
}

// The figures of the comparison, into `report` (which holds the inputs and grids).
void add_comparison(nlohmann::json& report, const CompareArgs& a, const metrology::SurfaceCompareOptions& o,
                    const metrology::SurfaceComparison& c, bool mesh) {
  if (c.outliers)
    report["measured"]["outliers"] = {{"masked", c.outliers->masked},
                                      {"k_sigma", o.outlier_sigma},
                                      {"sigma_mm", c.outliers->sigma_mm},
                                      {"threshold_mm", c.outliers->threshold_mm},
                                      {"method", "median of plane-exact neighbour predictions"}};
  report["registration"] = registration_json(a, o, c);
  const metrology::DeviationStats& ds = c.stats;
  report["deviation"] = {{"definition", deviation_definition(mesh)},
                         {"points", ds.points},
                         {"min_mm", ds.min},
                         {"max_mm", ds.max},
                         {"mean_mm", ds.mean},
                         {"rms_mm", ds.rms},
                         {"mean_abs_mm", ds.mean_abs}};
  report["marks"] = marks_json(o, c);
  nlohmann::json diff;
  const nlohmann::json jm = areal_json(c.measured_areal), jp = areal_json(c.predicted_areal);
  for (const auto& [k, v] : jm.items())
    if (k != "points" && v.is_number() && jp[k].is_number()) diff[k] = v.get<double>() - jp[k].get<double>();
  report["areal"] = {{"area", "nodes where both the aligned scan and the prediction are valid"},
                     {"processing", processing_json(o.processing, c.measured_form)},
                     {"measured", jm},
                     {"predicted", jp},
                     {"measured_minus_predicted", diff}};
}

// Profiles across the marks (CSV: mark, s, measured, predicted, deviation), in the deviation's frame.
std::string profiles_csv(const metrology::SurfaceComparison& c, bool mesh) {
  std::string csv = "mark,s_mm,measured_mm,predicted_mm,deviation_mm\n";
  for (std::size_t k = 0; k < c.mark_profiles.size(); ++k) {
    const metrology::MarkProfile& p = c.mark_profiles[k];
    for (Eigen::Index i = 0; i < p.deviation.s_mm.size(); ++i)
      csv += fmt::format("{},{},{},{},{}\n", k + 1, p.deviation.s_mm[i], p.measured.z_mm[i],
                         mesh ? NAN : p.predicted.z_mm[i], p.deviation.z_mm[i]);
  }
  return csv;
}

// The chart of one mark: measured and predicted heights across the path (grid mode) and their deviation.
render::ChartPicture mark_chart(const metrology::Mark& m, std::size_t k, const metrology::MarkProfile& p,
                                double path_direction_rad, bool heights) {
  render::ChartPicture cp;
  cp.caption = {
      fmt::format("Mark {}: {} {:.2f} um deep at x {:.3f} y {:.3f} mm", k + 1, m.overcut ? "overcut" : "undercut",
                  m.depth_mm * 1e3, m.x_mm, m.y_mm),
      fmt::format("profile across the path ({:.1f} deg from +x)", (path_direction_rad + kPi / 2) * 180 / kPi)};
  if (heights) {
    render::Chart h;
    h.title = "heights";
    h.x_title = "across the path [mm]";
    h.y_title = "z - z_pred(centre) [um]";
    const double z0 = p.predicted.z_mm[p.predicted.z_mm.size() / 2];
    h.series.push_back({"predicted", p.predicted.s_mm, (p.predicted.z_mm - z0) * 1e3, render::series_colour(0)});
    h.series.push_back({"measured", p.measured.s_mm, (p.measured.z_mm - z0) * 1e3, render::series_colour(1)});
    cp.charts.push_back(h);
  }
  render::Chart dev;
  dev.title = "deviation";
  dev.x_title = "across the path [mm]";
  dev.y_title = "deviation [um]";
  dev.series.push_back({"measured - predicted", p.deviation.s_mm, p.deviation.z_mm * 1e3, render::series_colour(2)});
  dev.levels.push_back({"0", 0.0, {0.4, 0.4, 0.4}, true});
  cp.charts.push_back(dev);
  return cp;
}

// The pictures of a comparison through render/ (headless VTK): images/deviation_map.png (top view of the
// deviation, diverging colours in um) and images/profile_mark_<k>.png (measured and predicted heights and their
// deviation across the path through each of the three deepest marks). Returns the files written, or the reason
// none could be (no EGL context on this machine, say): pictures never fail a comparison.
nlohmann::json write_compare_pictures(const std::filesystem::path& dir, const CompareArgs& a,
                                      const metrology::SurfaceComparison& c, const metrology::Prediction& prediction) {
  const bool mesh = prediction.mesh.has_value();
  nlohmann::json out = {{"files", nlohmann::json::array()}};
  try {
    core::create_result_subdir(dir / "images");
    render::Window window;
    render::PartPicture pic;
    pic.view.direction = render::ViewDirection::Top;
    render::DeviationColours dc;
    dc.lit = false;
    dc.isolines = 0;  // a measured deviation carries noise: iso-lines would only draw its speckle
    dc.reference = "the prediction (" + a.predicted.filename().string() + ")";
    pic.deviation = dc;
    pic.caption = {"Deviation of the measured scan from the prediction",
                   a.measured.filename().string() + " vs " + a.predicted.filename().string() + ": " +
                       (mesh ? "distance along the mesh normal" : "vertical, measured - predicted")};
    const render::PartImage map = render::render_part(window, mesh ? c.scan : prediction.grid, &c.deviation, pic);
    render::write_png(dir / "images" / "deviation_map.png", map.image);
    out["files"].push_back("images/deviation_map.png");
    out["deviation_map_limit_um"] = map.limit_mm * 1e3;
    for (std::size_t k = 0; k < c.mark_profiles.size(); ++k) {
      const render::ChartImage ci =
          render::render_charts(window, mark_chart(c.marks[k], k, c.mark_profiles[k], c.path_direction_rad, !mesh));
      const std::string name = fmt::format("images/profile_mark_{}.png", k + 1);
      render::write_png(dir / name, ci.image);
      out["files"].push_back(name);
    }
  } catch (const core::Error& e) {
    out["error"] = e.what();
    std::fprintf(stderr, "vmsim compare: no pictures: %s\n", e.what());
  }
  return out;
}

// deviation.x3p and measured_aligned.x3p.
void write_grids(const std::filesystem::path& dir, const CompareArgs& a, const metrology::SurfaceComparison& c,
                 bool mesh) {
  metrology::X3pWriteOptions xo;
  xo.version = std::string("vmsim ") + VMSIM_VERSION;
  xo.comment = "deviation: " + deviation_definition(mesh) + "; measured " + a.measured.filename().string() +
               ", predicted " + a.predicted.filename().string();
  metrology::write_x3p(dir / "deviation.x3p", c.deviation, xo);
  xo.comment =
      "the measured scan " + a.measured.filename().string() + " aligned and resampled onto the prediction's grid";
  xo.probing_type = "NonContacting";
  metrology::write_x3p(dir / "measured_aligned.x3p", c.measured_on, xo);
}

void print_summary(const CompareArgs& a, const metrology::SurfaceFile& ms, const std::string& pred_format,
                   const metrology::SurfaceComparison& c) {
  std::printf("measured %s (%s, %ld x %ld), predicted %s (%s)\n", a.measured.filename().string().c_str(),
              ms.format.c_str(), static_cast<long>(ms.grid.nx()), static_cast<long>(ms.grid.ny()),
              a.predicted.filename().string().c_str(), pred_format.c_str());
  if (c.outliers) std::printf("spikes masked: %zu\n", c.outliers->masked);
  if (c.registration) {
    const metrology::RigidTransform& T = c.transform;
    std::printf("registration: t = (%.4f, %.4f, %.4f) mm, rotation %.3g rad; residual rms %.3f um on %zu points%s\n",
                T.t.x(), T.t.y(), T.t.z(), T.rotation_vector().norm(), c.registration->rms_mm * 1e3,
                c.registration->inliers, c.registration->converged ? "" : " (not converged)");
  }
  const metrology::DeviationStats& ds = c.stats;
  std::printf("deviation: mean %.2f um, rms %.2f um, min %.2f um, max %.2f um over %zu points\n", ds.mean * 1e3,
              ds.rms * 1e3, ds.min * 1e3, ds.max * 1e3, ds.points);
  for (std::size_t k = 0; k < c.marks.size() && k < 5; ++k) {
    const metrology::Mark& m = c.marks[k];
    std::printf("mark %zu: %s %.2f um at x %.3f y %.3f, %.3f mm wide, %.3f mm along the path\n", k + 1,
                m.overcut ? "overcut " : "undercut", m.depth_mm * 1e3, m.x_mm, m.y_mm, m.width_mm, m.along_mm);
  }
  std::printf("Sa measured %.3f um, predicted %.3f um; Sq %.3f / %.3f um\n", c.measured_areal.Sa_mm * 1e3,
              c.predicted_areal.Sa_mm * 1e3, c.measured_areal.Sq_mm * 1e3, c.predicted_areal.Sq_mm * 1e3);
}

}  // namespace

int run_compare(const CompareArgs& a) {
  const auto t_start = Clock::now();
  const metrology::SurfaceCompareOptions options = compare_options(a);
  // Inputs from a vmsim result directory must be listed in its report.json (not an earlier run's leftover).
  require_utf8_input(a.measured, "--measured");
  require_utf8_input(a.predicted, "--predicted");
  require_listed_in_report(a.measured);
  require_listed_in_report(a.predicted);
  // Locked now, written in staging, swapped into place whole (core/output_dir.hpp).
  core::OutputDir out(out_dir_or_default(a.out_dir, a.measured.stem().string(), "compare"), "vmsim compare");
  const std::filesystem::path dir = out.path();

  auto t0 = Clock::now();
  const metrology::SurfaceFile ms = metrology::read_surface_file(a.measured);
  if (!ms.note.empty())
    std::fprintf(stderr, "vmsim compare: warning: %s: %s\n", a.measured.string().c_str(), ms.note.c_str());
  if (ms.profile) return run_compare_profile(a, ms, out);
  if (!a.profile_line.empty())
    throw core::Error("--profile-line: applies to a measured profile; " + a.measured.string() + " holds a surface");
  std::string pred_format;
  const metrology::Prediction prediction = read_prediction(a.predicted, ms.grid, pred_format);
  const bool mesh = prediction.mesh.has_value();
  nlohmann::json timings = {{"read", seconds_since(t0)}};

  const metrology::SurfaceComparison c = metrology::compare_surfaces(ms.grid, prediction, options);
  if (c.registration && !c.registration->weak_directions.empty())
    std::fprintf(stderr,
                 "vmsim compare: the surfaces do not constrain %zu direction(s) of the alignment; held at the "
                 "initial guess (see report.json registration.weakly_constrained)\n",
                 c.registration->weak_directions.size());
  timings.update({{"outliers", c.seconds.outliers},
                  {"registration", c.seconds.registration},
                  {"deviation", c.seconds.deviation},
                  {"marks", c.seconds.marks},
                  {"areal", c.seconds.areal}});

  nlohmann::json report = {{"vmsim", VMSIM_VERSION}, {"command", "compare"}};
  report["inputs"] = {{"measured", input_json(a.measured, ms.format)},
                      {"predicted", input_json(a.predicted, pred_format)}};
  report["measured"] = {{"grid", grid_json(ms.grid)}};
  if (!ms.note.empty()) report["measured"]["note"] = ms.note;
  report["predicted"] = {{"grid", grid_json(prediction.grid)}};
  if (mesh) report["predicted"]["mesh_triangles"] = prediction.mesh->triangles.rows();
  add_comparison(report, a, options, c, mesh);

  t0 = Clock::now();
  core::write_file_atomic(dir / "profiles.csv", profiles_csv(c, mesh));
  write_grids(dir, a, c, mesh);
  std::vector<std::string> files = {"profiles.csv", "deviation.x3p", "measured_aligned.x3p"};
  timings["write"] = seconds_since(t0);
  if (!a.no_render) {
    t0 = Clock::now();
    report["pictures"] = write_compare_pictures(dir, a, c, prediction);
    for (const auto& f : report["pictures"]["files"]) files.push_back(f.get<std::string>());
    timings["pictures"] = seconds_since(t0);
  }
  timings["total"] = seconds_since(t_start);
  report["timings_s"] = timings;
  files.push_back("report.json");
  report["files"] = files;
  write_report(dir / "report.json", report);
  out.commit();

  print_summary(a, ms, pred_format, c);
  std::printf("wrote %s (%zu files) in %.1f s\n", out.target().string().c_str(), files.size(), seconds_since(t_start));
  return 0;
}

}  // namespace vmsim::app
